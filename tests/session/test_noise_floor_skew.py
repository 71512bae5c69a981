"""Noise at its floor: a noise-free session whose gyro sample stands for its whole interval (the independent
generator's ``gyro_held``: the gyro leads the accelerometer by half a sample, 5 ms at 100 Hz), Zhou's schedule, the
accelerometer calibrated.  Either the estimate is exact to the discretisation or the command refuses before the
filter runs, in one line — never a diverged filter that looks like an answer.

* ``calib run`` (the hand-aware default) carries the skew as a state: exact.  Bound 1e-4 on S, G (the brief's
  discretisation bound; measured 8e-6, the rate integration's second-order error at the turns' 1.57 rad/s), the
  skew within 1 µs of Δt/2 (its σ at the floor, measured 1.4 µs·…, 0.2 µs off), the lever arm below 1 mm (none is
  simulated; measured 15 µm), and not ``ok`` (σ at the numerical floor is not honest for noise-free input,
  tests/session/test_hand_conditions.py).
* ``--method kf_session`` / ``iterated_session`` have no timing state (measured before: S off by 1.1 and 3e4,
  ``diverged``): refused with exit code 2 before the filter, naming the skew measured from the kinematics
  (calib.session.skew), which is exact on noise-free input (±0.1 µs here).
* without the skew the hand-blind filter still runs and is exact (tests/session/test_accelerometer.py).
"""

from __future__ import annotations

import json

import independent_generator as ig
import numpy as np
import pytest

from gyrosim.recording import Recording

from calib.app.cli import main as calib_main
from calib.session.skew import measure_skew

NOISE_FREE = dict(gyro_noise_deg_s=0.0, acc_noise_g=0.0)


@pytest.fixture(scope="module")
def held_csv(tmp_path_factory):
    path = tmp_path_factory.mktemp("skew") / "held.csv"
    truth = ig.generate(path, gyro_held=True, **NOISE_FREE)
    return path, truth


def test_the_skew_is_measured_exactly_from_the_kinematics_of_noise_free_data():
    """The kinematic fit (calib.session.skew) with a raw accelerometer and both triads' errors unknown: τ = Δt/2
    to 1e-7 s (the fit is exact up to the central differences' O(Δt²) on a smooth record), 0 without the hold."""
    raw = dict(acc_bias_g=(0.06, -0.055, 0.07), acc_scale=(0.02, -0.025, 0.03), acc_nonortho=(0.01, -0.012, 0.015))
    for held, tau in ((True, 0.005), (False, 0.0)):
        d = ig.generate_arrays(gyro_held=held, **NOISE_FREE, **raw)
        sk = measure_skew(d["gyro_rad_s"], d["acc_m_s2"], d["t_s"], 5e-5)
        assert abs(sk.tau_s - tau) < 1e-7, sk
        assert sk.residual_rms_m_s3 < 1e-4 * sk.signal_rms_m_s3


def test_calib_run_is_exact_on_the_held_gyro(held_csv, tmp_path, capsys):
    path, truth = held_csv
    out = tmp_path / "cal.json"
    code = calib_main(["run", str(path), "--gyro-unit", "deg/s", "--acc-unit", "g", "--json", str(out)])
    capsys.readouterr()
    d = json.loads(out.read_text())
    err = np.r_[np.asarray(d["gyro"]["scale_factor"]) - truth["scale_factor"],
                np.asarray(d["gyro"]["nonorthogonality"]) - truth["nonorthogonality"]]
    assert np.abs(err).max() < 1e-4, err
    assert abs(d["acc_delay"]["delay_s"] - 0.005) < 1e-6, d["acc_delay"]
    assert np.abs(d["hand"]["lever_arm_m"]).max() < 1e-3
    assert code == 1 and d["status"] == "inconsistent"
    assert any(w.startswith("noise-free input") for w in d["warnings"])


@pytest.mark.parametrize("method", ["kf_session", "iterated_session"])
def test_hand_blind_filters_refuse_the_skew_before_running(held_csv, method, capsys):
    path, _ = held_csv
    code = calib_main(["run", str(path), "--gyro-unit", "deg/s", "--acc-unit", "g", "--method", method])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    line = next(ln for ln in err if "noise-free input" in ln)
    assert "+5.00 ms after the gyro" in line and "--method hand" in line


def test_the_skew_check_leaves_noisy_and_hand_held_data_alone():
    """The refusal needs noise-free input *and* a kinematic fit that explains the record: with a lever arm its
    residual is 1 % of ḟ̃ (the lever arm's own acceleration), so nothing is claimed; with noise the floor is not
    the issue and the check does not run (calib.session.paper.calibrate)."""
    from calib.session.skew import refuse_skew_at_floor

    d = ig.generate_arrays(gyro_held=True, lever_arm_m=(0.01, 0.07, 0.02), **NOISE_FREE)
    rec = Recording(d["t_s"], d["gyro_rad_s"], d["acc_m_s2"], meta={"rate_hz": 100.0})
    sk = refuse_skew_at_floor(rec, 5e-5, 9.80665, "--method kf_session")
    assert sk is not None and sk.residual_rms_m_s3 > 1e-3 * sk.signal_rms_m_s3
