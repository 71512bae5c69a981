"""S stated at the rates it was learnt at (calib.session.hand.reports.scale_reference_rate): a gyro whose scale is not
linear, δ_i = k_i ω_i|ω_i|, on the independent generator (tests/independent_generator.py adds k ω|ω| its own way).

A linear fit over the session's rates reads S_i + k_i m_i, m_i = Σ|ω_i|³/Σω_i² — the chord slope over ±m_i.  kf_hand
reports m_i (``diagnostics["scale_reference_rate"]``); its S must then be honest against S + k m and is not against
the slope at 0 rad/s.  Measured (12 sessions, k = ±1e-4 per rad/s — 0.09 % of a 500 °/s full scale, the MPU-9250
datasheet's order — m ≈ 1.2–1.3 rad/s): NEES(6) 4.91 against S + k m (4.90 with k = 0 on the same seeds), 61 against
S.  Tolerance: under an honest σ the summed NEES over N sessions is χ²(6N), two-sided 99.9 % interval (scipy).

The Monte Carlo scorer's side (calib.scoring.montecarlo.truth_gyro_scale_at_rate) is checked against the effect's own
form on a gyrosim recording: a nonlinearity reads k m, a temperature-dependent scale (linear in the rate) nothing.
"""

from __future__ import annotations

import independent_generator as ig
import numpy as np
import pytest
from scipy import stats

from gyrosim.recording import Recording

from calib.session.hand.filter import kf_hand, scale_reference_rate

ITEMS = [("gyro", "scale_factor"), ("gyro", "nonorthogonality")]
K = np.array([1e-4, -1e-4, 1e-4])    # 1/(rad/s)


def test_s_is_honest_at_the_stated_rate_and_not_at_zero_rate():
    kin = ig.kinematics(100.0)
    at_m, at_0 = [], []
    for seed in range(12):
        d = ig.generate_arrays(seed=seed, kin=kin, scale_nonlinearity_per_rad_s=K)
        cal = kf_hand(Recording(d["t_s"], d["gyro_rad_s"], d["acc_m_s2"], meta={"rate_hz": 100.0}))
        ref = cal.diagnostics["scale_reference_rate"]
        m = np.asarray(ref["rate_rad_s"])
        assert np.all(np.asarray(ref["rms_rate_rad_s"]) < m) and np.all(m < np.asarray(ref["max_abs_rate_rad_s"]))
        est = np.concatenate([cal.value(t, k) for t, k in ITEMS])
        c = cal.block_covariance(ITEMS)
        t0 = np.concatenate([d["scale_factor"], d["nonorthogonality"]])
        tm = t0.copy()
        tm[:3] += K * m
        at_m.append(float((est - tm) @ np.linalg.solve(c, est - tm)))
        at_0.append(float((est - t0) @ np.linalg.solve(c, est - t0)))
    lo, hi = stats.chi2.ppf([0.0005, 0.9995], 6 * len(at_m))
    assert lo < sum(at_m) < hi, at_m
    assert sum(at_0) > hi, at_0


def test_the_reference_rate_is_the_chord_rule():
    """m_i = Σ|ω_i|³/Σω_i² by hand: a rate that is ±a half of the time and 0 otherwise reads a; a rest reads 0."""
    w = np.zeros((400, 3))
    w[:100, 0], w[100:200, 0] = 0.8, -0.8
    w[:, 1] = np.linspace(-2.0, 2.0, 400)
    m = np.asarray(scale_reference_rate(w)["rate_rad_s"])
    x = np.linspace(-2.0, 2.0, 400)
    assert m[0] == pytest.approx(0.8) and m[2] == 0.0
    assert m[1] == pytest.approx(np.sum(np.abs(x) ** 3) / np.sum(x**2))


def test_the_scorer_reads_k_m_for_a_nonlinearity_and_nothing_for_a_temperature_scale():
    from dataclasses import replace

    from gyrosim.hand import load_hand
    from gyrosim.schedule import load_schedule
    from gyrosim.sensor_model import load_sensor, stored_sensor_model
    from gyrosim.simulate import apply_sensor, simulate_truth

    from calib.scoring.montecarlo import truth_gyro_scale_at_rate

    truth = simulate_truth(load_schedule("static"), load_hand("ideal"), 100.0, seed=0)
    model = load_sensor("mpu9250")
    rec = apply_sensor(truth, model, np.random.default_rng(3))
    k = sum(e.value for e in stored_sensor_model(rec.meta).gyro if e.kind == "scale_nonlinearity")
    m = np.array([0.5, 1.0, 2.0])
    got = truth_gyro_scale_at_rate(rec, m, np.full(3, 40.0))     # 15 °C from the temperature scale's reference
    assert np.allclose(got, k * m, rtol=1e-9, atol=1e-15)
    linear = replace(model, gyro=tuple(e for e in model.gyro if e.kind != "scale_nonlinearity"))
    rec2 = apply_sensor(truth, linear, np.random.default_rng(3))
    assert np.allclose(truth_gyro_scale_at_rate(rec2, m, np.full(3, 40.0)), 0.0, atol=1e-15)


def test_the_accelerometer_scale_is_stated_and_scored_at_the_force_its_updates_saw():
    """kf_hand_joint's accelerometer counterpart (calib.session.hand.reports.acc_scale_reference_force, ``diagnostics[
    "acc_scale_reference_force"]``): the same chord rule on the specific force — an axis that is ±g half of the time and
    0 otherwise reads g, a tilt sweep its Σ|f|³/Σf² — and the scorer
    (calib.scoring.montecarlo.truth_acc_scale_at_gravity with ``force_m_s2``) reads k m for the MPU-9250 preset's
    accelerometer nonlinearity k f|f| (its temperature scale taken at the preset's reference, where it is 0), k g
    without it."""
    from gyrosim.hand import load_hand
    from gyrosim.schedule import load_schedule
    from gyrosim.sensor_model import load_sensor, stored_sensor_model
    from gyrosim.simulate import apply_sensor, simulate_truth

    from calib.scoring.montecarlo import truth_acc_scale_at_gravity
    from calib.session.hand.filter import acc_scale_reference_force

    g = 9.80665
    f = np.zeros((400, 3))
    f[:100, 0], f[100:200, 0] = g, -g
    f[:, 1] = g * np.cos(np.linspace(0.0, np.pi, 400))
    m = np.asarray(acc_scale_reference_force(f)["specific_force_m_s2"])
    assert m[0] == pytest.approx(g) and m[2] == 0.0
    assert m[1] == pytest.approx(np.sum(np.abs(f[:, 1]) ** 3) / np.sum(f[:, 1] ** 2)) and m[1] < g
    truth = simulate_truth(load_schedule("static"), load_hand("ideal"), 100.0, seed=0)
    rec = apply_sensor(truth, load_sensor("mpu9250"), np.random.default_rng(3))
    k = sum(e.value for e in stored_sensor_model(rec.meta).accelerometer if e.kind == "scale_nonlinearity")
    at = np.array([4.0, 7.0, 9.0])
    assert np.allclose(truth_acc_scale_at_gravity(rec, np.full(3, 25.0), force_m_s2=at), k * at, rtol=1e-9, atol=1e-15)
    assert np.allclose(truth_acc_scale_at_gravity(rec, np.full(3, 25.0)), k * g, rtol=1e-9, atol=1e-15)
