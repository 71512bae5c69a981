"""calib temperature's labels: a --train recording holding the scored data is in-sample, never "held out"; a
refusal names the option to use, not an internal key."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from gyrosim.chamber import simulate_chamber
from gyrosim.recording import Recording, save_hdf5

from calib.app.cli import main as calib_main


@pytest.fixture(scope="module")
def chamber_file(tmp_path_factory):
    folder = tmp_path_factory.mktemp("chamber")
    return save_hdf5(simulate_chamber("tde_cycles_003", "consumer_thermal", 1.0, seed=1), folder / "chamber.h5")


def test_training_on_the_scored_data_is_labelled_in_sample(chamber_file, tmp_path, capsys):
    copy = shutil.copy(chamber_file, tmp_path / "copy.h5")  # a copy: another path, the same data
    for train in (str(chamber_file), str(copy)):
        out_json = tmp_path / "t.json"
        assert calib_main(["temperature", str(chamber_file), "--train", train, "--methods", "none,polynomial",
                           "--json", str(out_json)]) == 0
        out = capsys.readouterr().out
        assert "IN-SAMPLE" in out and "held out:" not in out
        assert {r["evaluation"] for r in json.loads(out_json.read_text(encoding="utf-8"))} == {"in_sample"}
    # held-out cycles of the same file stay "held out"
    assert calib_main(["temperature", str(chamber_file), "--methods", "none,polynomial",
                       "--json", str(tmp_path / "h.json")]) == 0
    assert "held out: " in capsys.readouterr().out
    assert {r["evaluation"] for r in json.loads((tmp_path / "h.json").read_text(encoding="utf-8"))} == {"held_out"}


def test_a_record_without_cycles_is_refused_naming_the_option(tmp_path, capsys):
    n = 2000
    t = np.arange(n) / 10.0
    rng = np.random.default_rng(0)
    rec = Recording(t_s=t, gyro_rad_s=1e-3 * rng.normal(size=(n, 3)),
                    acc_m_s2=np.array([0.0, 0.0, 9.81]) + 1e-2 * rng.normal(size=(n, 3)),
                    temp_c=20.0 + 10.0 * t / t[-1])
    path = save_hdf5(rec, tmp_path / "ramp.h5")
    assert calib_main(["temperature", str(path)]) == 2
    err = capsys.readouterr().err
    assert "--train RECORDING" in err and "meta" not in err and "[" not in err.split("error:", 1)[1]
