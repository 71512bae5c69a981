"""The HDF5 recording format, determinism, the CLI and its bad-input errors."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import h5py
import numpy as np
import pytest

from gyrosim import recording as recording_module
from gyrosim.cli import main as gyrosim_main
from gyrosim.errors import GyrosimError, PresetError, ReachError, RecordingError
from gyrosim.hand import load_hand
from gyrosim.recording import Recording, load_hdf5, save_hdf5
from gyrosim.simulate import simulate_truth


def _sha(p: Path) -> str:
    return hashlib.sha256(p.read_bytes()).hexdigest()


def test_simulate_cli_writes_the_documented_layout(tmp_path):
    out = tmp_path / "rec.h5"
    assert gyrosim_main(["simulate", "--schedule", "zhou2020", "--hand", "typical", "--rate", "100",
                         "--seed", "1", "--out", str(out), "--quiet"]) == 0
    with h5py.File(out, "r") as f:
        for key in ("t", "gyro", "acc", "truth/omega", "truth/specific_force", "truth/quat", "truth/position"):
            assert key in f, key
        n = f["t"].shape[0]
        assert n == 17101 and f["gyro"].shape == (n, 3) and f["truth/quat"].shape == (n, 4)
        for attr in ("rate_hz", "frames", "schedule", "hand", "sensor_model", "seed", "version"):
            assert attr in f.attrs, attr
        assert f.attrs["frames"] == "body RFU, navigation ENU"
        assert f.attrs["rate_hz"] == 100.0 and f.attrs["seed"] == 1
        assert json.loads(f.attrs["hand"])["name"] == "typical"
    rec = load_hdf5(out)
    assert isinstance(rec, Recording) and rec.truth is not None
    np.testing.assert_allclose(np.diff(rec.t_s), 0.01, atol=1e-12)


def test_same_seed_same_bytes_different_seed_differs(tmp_path):
    paths = []
    for name, seed in (("a", 3), ("b", 3), ("c", 4)):
        p = tmp_path / f"{name}.h5"
        gyrosim_main(["simulate", "--schedule", "static", "--hand", "shaky", "--rate", "50",
                      "--seed", str(seed), "--out", str(p), "--quiet"])
        paths.append(p)
    assert _sha(paths[0]) == _sha(paths[1])
    assert _sha(paths[0]) != _sha(paths[2])


def test_round_trip_and_inputs_are_not_mutated(tmp_path):
    t = np.arange(5) * 0.1
    g = np.ones((5, 3))
    rec = Recording(t, g, g * 2, temp_c=np.full(5, 25.0), meta={"rate_hz": 10.0, "note": {"a": 1}})
    g[0, 0] = 99.0  # the caller's array changes; the recording keeps its copy
    assert rec.gyro_rad_s[0, 0] == 1.0
    with pytest.raises(ValueError):
        rec.gyro_rad_s[0, 0] = 5.0  # read-only
    back = load_hdf5(save_hdf5(rec, tmp_path / "r.h5"))
    np.testing.assert_array_equal(back.acc_m_s2, rec.acc_m_s2)
    np.testing.assert_array_equal(back.temp_c, rec.temp_c)
    assert back.meta["note"] == {"a": 1}


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(t_s=[0.0, 0.1, 0.1]), "not strictly increasing"),
        (dict(t_s=[0.0, 0.2, 0.1]), "not strictly increasing"),
        (dict(gyro_rad_s=[[0, 0, 0], [np.nan, 0, 0], [0, 0, 0]]), "NaN"),
        (dict(acc_m_s2=[[0, 0, 0], [0, 0, 0]]), "shape"),
    ],
)
def test_bad_recordings_are_rejected(kwargs, message):
    base = dict(t_s=[0.0, 0.1, 0.2], gyro_rad_s=np.zeros((3, 3)), acc_m_s2=np.zeros((3, 3)))
    base.update(kwargs)
    with pytest.raises(RecordingError, match=message):
        Recording(**base)


def test_unknown_preset_and_unknown_hand_key(tmp_path, capsys):
    assert gyrosim_main(["simulate", "--hand", "wobbly", "--out", str(tmp_path / "x.h5")]) == 2
    assert "unknown hand preset 'wobbly'" in capsys.readouterr().err
    bad = tmp_path / "h.toml"
    bad.write_text("tremor_rms = 1.0\n")
    with pytest.raises(PresetError, match="unknown hand key"):
        load_hand(bad)
    neg = tmp_path / "n.toml"
    neg.write_text("tremor_acc_rms_m_s2 = -1.0\n")
    with pytest.raises(PresetError, match=">= 0"):
        load_hand(neg)
    assert not (tmp_path / "x.h5").exists()


def test_rate_above_physics_rate(tmp_path, capsys):
    assert gyrosim_main(["simulate", "--rate", "2000", "--out", str(tmp_path / "x.h5")]) == 2
    assert "above the physics rate" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())


def test_unwritable_output_fails_before_simulating(tmp_path, capsys):
    assert gyrosim_main(["simulate", "--out", str(tmp_path / "no_such_dir" / "x.h5")]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert gyrosim_main(["simulate", "--out", "/proc/x.h5"]) == 2  # not writable, even for root
    assert "cannot write" in capsys.readouterr().err


def test_failed_write_leaves_nothing_half_written(tmp_path, monkeypatch):
    rec = Recording(np.arange(3) * 0.1, np.zeros((3, 3)), np.zeros((3, 3)))
    target = tmp_path / "r.h5"
    target.write_bytes(b"previous content")
    real = h5py.Group.create_dataset

    def failing(self, name, *a, **k):
        if name == "acc":
            raise OSError("disk full")
        return real(self, name, *a, **k)

    monkeypatch.setattr(recording_module.h5py.Group, "create_dataset", failing)
    with pytest.raises(OSError, match="disk full"):
        save_hdf5(rec, target)
    assert target.read_bytes() == b"previous content"  # the user's file is untouched
    assert [p.name for p in tmp_path.iterdir()] == ["r.h5"]  # no temporary left behind


def test_schedule_beyond_the_arms_reach_is_refused(tmp_path):
    p = tmp_path / "reach.toml"
    p.write_text('[[segments]]\nkind = "translate"\ndisplacement_m = [0.0, 0.5, 0.0]\nduration_s = 2\n')
    with pytest.raises(ReachError, match="reach"):
        simulate_truth(str(p), "ideal", 100)
    p.write_text('[[segments]]\nkind = "translate"\ndisplacement_m = [0.0, -0.25, 0.2]\nduration_s = 2\n')
    with pytest.raises(ReachError, match="elbow"):
        simulate_truth(str(p), "ideal", 100)


def test_hands_and_schedules_listing(capsys):
    assert gyrosim_main(["hands"]) == 0
    out = capsys.readouterr().out
    assert "typical" in out and "shaky" in out
    assert gyrosim_main(["schedules"]) == 0
    assert "zhou2020" in capsys.readouterr().out


def test_gyrosim_error_is_a_valueerror():
    assert issubclass(GyrosimError, ValueError)
