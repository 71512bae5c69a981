"""Turns of a known angle as measurements of the gyro's parameters (calib.session.known_turns): what gravity cannot
see — a turn about the vertical — pins that axis's scale factor.

Synthetic and exact: a gyro with S_z = +0.02 turns −360° about z (a Ferraris turn) in 8 s at 100 Hz, with white noise
of 0.005 rad/s per sample.  The calibration before the turns holds S_z at its prior, 0 ± 0.05 (as a session of
vertical-axis turns leaves it).  The turn's measurement: σ_turn = 0.5° ⊕ the noise integrated over the turn
(N_g √T = 0.005/√100 · √8 = 1.4e-3 rad = 0.08°), so σ(S_z) after = σ_angle / 2π ≈ 0.507° / 360° = 1.4e-3, and the
estimate lands within 3 σ of 0.02 (the angle error of one draw of the noise and none of the protocol's).
"""

from __future__ import annotations

import math

import numpy as np

from gyrosim.calibration import Calibration
from gyrosim.recording import Recording

from calib.inputs.turns import Turn, Turns
from calib.session.known_turns import apply_known_turns

RATE, T_TURN, S_Z, NOISE = 100.0, 8.0, 0.02, 0.005


def _session(seed: int = 0):
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 12.0, 1.0 / RATE)
    w = np.zeros((t.size, 3))
    on = (t >= 2.0) & (t < 2.0 + T_TURN)
    w[on, 2] = -2 * math.pi / T_TURN                       # −360° about z in 8 s
    gyro = w * (1.0 + np.array([0.0, 0.0, S_Z])) + rng.normal(size=w.shape) * NOISE
    acc = np.tile([0.0, 0.0, 9.80665], (t.size, 1))
    rec = Recording(t, gyro, acc, meta={"rate_hz": RATE})
    turns = Turns((Turn(2.0, 2.0 + T_TURN, (0.0, 0.0, 1.0), math.radians(-360.0), math.radians(0.5), "z_rot"),),
                  "test")
    return rec, turns


def _prior() -> Calibration:
    cov = np.diag(np.r_[np.full(3, 1e-8), np.full(3, 0.05**2), np.full(3, 0.05**2)])
    return Calibration.from_linear(gyro={"bias": np.zeros(3), "scale_factor": np.zeros(3),
                                         "nonorthogonality": np.zeros(3)}, covariance=cov, status="ok")


def test_a_turn_of_known_angle_pins_the_vertical_axis_scale_factor():
    rec, turns = _session()
    arw = NOISE / math.sqrt(RATE)                          # rad/s/√Hz of the white noise per sample
    cal = apply_known_turns(_prior(), rec, turns, arw)
    s, sd = cal.value("gyro", "scale_factor"), cal.std("gyro", "scale_factor")
    expected_sd = math.sqrt(math.radians(0.5) ** 2 + arw**2 * T_TURN) / (2 * math.pi)
    assert abs(sd[2] - expected_sd) < 0.05 * expected_sd, (sd, expected_sd)
    assert abs(s[2] - S_Z) < 3 * sd[2], (s, sd)
    assert np.allclose(s[:2], 0.0, atol=1e-9) and np.allclose(sd[:2], 0.05)   # the other axes: no information
    rep = cal.diagnostics["known_turns"]["turns"][0]
    assert rep["label"] == "z_rot" and abs(rep["integrated_after_deg"] + 360.0) < 3 * math.degrees(expected_sd) * 6.3


def test_without_turns_or_covariance_nothing_changes():
    rec, turns = _session()
    prior = _prior()
    assert apply_known_turns(prior, rec, Turns((), "none"), 1e-3) is prior
    bare = Calibration.from_linear(gyro={"bias": np.zeros(3), "scale_factor": np.zeros(3),
                                         "nonorthogonality": np.zeros(3)}, status="ok")
    assert apply_known_turns(bare, rec, turns, 1e-3) is bare


def test_calib_run_refuses_turns_it_cannot_use(tmp_path, capsys):
    """Before any filter runs: both --turns and --protocol, and a protocol whose section list is not beside the
    recording, exit 2 with one line saying what to give instead."""
    import independent_generator as ig

    from calib.app.cli import main as calib_main

    path = tmp_path / "s.csv"
    ig.generate(path, gyro_noise_deg_s=0.05, acc_noise_g=0.001)
    turns = tmp_path / "turns.csv"
    turns.write_text("start_s,end_s,axis,angle_deg,sigma_deg\n10,15,z,90,1\n")
    base = ["run", str(path), "--gyro-unit", "deg/s", "--acc-unit", "g"]
    assert calib_main(base + ["--turns", str(turns), "--protocol", "ferraris"]) == 2
    assert "either as --turns FILE or by --protocol" in capsys.readouterr().err
    assert calib_main(base + ["--protocol", "ferraris"]) == 2
    assert "s_list.json" in capsys.readouterr().err


def test_the_terminal_names_a_turn_the_calibration_misses_by_more_than_three_sigma():
    """A turn 2.27° off with σ 0.5° (imucal's z turn after calib run's calibration) is named with what it means; one
    0.9° off (1.8σ) is only listed."""
    from calib.session.known_turns import TURN_OFF_SIGMA, known_turns_lines

    def report(after_deg):
        return {"source": "protocol ferraris", "turns": [
            {"label": lab, "stated_deg": -360.0, "integrated_after_deg": a, "sigma_deg": 0.5}
            for lab, a in zip(("x_rot", "z_rot"), after_deg)]}

    lines = known_turns_lines(report([-360.89, -362.27]))
    assert len(lines) == 2 and "z_rot -362.27° of -360°" in lines[0]
    assert lines[1].startswith("z_rot -4.5σ off") and "x_rot" not in lines[1]
    assert len(known_turns_lines(report([-360.89, -360.0 + 0.5 * TURN_OFF_SIGMA * 0.99]))) == 1   # just inside
    assert known_turns_lines({}) == []
