"""Output files get the mode the user's umask gives a new file (0644 under the usual 022, 0640 under
027), never the 0600 of a temporary file; and the CSV that ``calib apply`` writes names its units and
reads back through calib's own reader."""

from __future__ import annotations

import os
import stat

import numpy as np
import pytest
from conftest import session

from gyrosim.estimator import Estimate
from gyrosim.outputs import staged_folder, write_json_atomic, write_text_atomic
from gyrosim.recording import Recording, load_hdf5, save_csv, save_hdf5

from calib.app.cli import main as calib_main
from calib.inputs import read_recording


@pytest.fixture
def umask():
    """Set the process umask for one test and restore it (xdist runs each worker in its own process)."""
    old = os.umask(0o022)
    yield lambda m: os.umask(m)
    os.umask(old)


@pytest.fixture(scope="module")
def rec() -> Recording:
    s = session("typical")
    k = slice(1000, 1400)
    return Recording(s.t_s[k] - s.t_s[1000], s.gyro_rad_s[k], s.acc_m_s2[k], mag_ut=s.mag_ut[k])


def _mode(p) -> int:
    return stat.S_IMODE(os.stat(p).st_mode)


@pytest.mark.parametrize("mask, want", [(0o022, 0o644), (0o027, 0o640), (0o002, 0o664)])
def test_every_writer_gives_the_umasks_mode(rec, tmp_path, umask, mask, want):
    umask(mask)
    paths = [save_csv(rec, tmp_path / "r.csv"), save_hdf5(rec, tmp_path / "r.h5"),
             write_text_atomic(tmp_path / "t.txt", "x")]
    write_json_atomic(tmp_path / "j.json", {"a": 1})
    paths.append(tmp_path / "j.json")
    with staged_folder(tmp_path / "set") as stage:
        write_text_atomic(stage / "inner.txt", "y")
    paths.append(tmp_path / "set" / "inner.txt")
    assert {p.name: oct(_mode(p)) for p in paths} == {p.name: oct(want) for p in paths}
    assert _mode(tmp_path / "set") == 0o777 & ~mask


def test_calib_apply_writes_a_readable_csv_with_units_that_reads_back(rec, tmp_path, umask):
    umask(0o022)
    src = save_hdf5(rec, tmp_path / "raw.h5")
    cal = tmp_path / "cal.json"
    bias = np.array([0.01, -0.02, 0.005])            # rad/s, subtracted by apply
    cal.write_text(Estimate(bias, np.zeros(3), np.zeros(3)).to_json())   # bias only: ω − b
    out = tmp_path / "compensated.csv"
    assert calib_main(["apply", str(cal), str(src), "--out", str(out)]) == 0
    assert _mode(out) == 0o644
    assert out.read_text().splitlines()[0].startswith("t_s,gyro_x_rad_s,gyro_y_rad_s,gyro_z_rad_s,acc_x_m_s2")
    back, info = read_recording(out)
    ref = load_hdf5(src)
    np.testing.assert_array_equal(back.t_s, ref.t_s)
    np.testing.assert_allclose(back.gyro_rad_s, ref.gyro_rad_s - bias, rtol=0, atol=1e-15)   # %.17g: exact
    np.testing.assert_array_equal(back.mag_ut, ref.mag_ut)
    assert info.time_unit == "s" and not info.ignored_columns
