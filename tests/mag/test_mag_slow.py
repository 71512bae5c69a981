"""Long statistical runs of the magnetometer calibration (``python -m pytest -q -m slow``): they
back the numbers in docs/magnetometer.md.  Tolerances: for honest σ the mean of z²
over n values is χ²(n)/n; its 99.9 % upper bound is 1.4 for n = 150, 1.6 for n = 60."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import session
from test_mag_calibration import MAG_9, _heading_rms_and_floor, _symmetric_unit_det, _with_mag

from gyrosim.sensor_model import load_sensor
from gyrosim.simulate import apply_sensor, simulate_truth

from calib.mag import calibrate_magnetometer, true_magnetometer
from calib.mag.compare import simulated_comparison

pytestmark = pytest.mark.slow


@pytest.mark.parametrize("schedule, sensor", [("zhou2020", "mpu9250_9axis"), ("multiposition", "mpu9250_9axis"),
                                              ("multiposition", "phone")])
def test_ellipsoid_fifty_devices(schedule, sensor):
    """50 devices on one truth: mean z² of the hard iron (150 values) ≤ 1.6 and of the symmetric
    soft iron (300) ≤ 1.6 — σ honest within ~25 % (the χ² 99.9 % bound is 1.4; measured 1.0–1.4 on
    zhou2020, where the one truth's uneven coverage leaves a little second-order error)."""
    truth = session("typical", schedule=schedule)
    model = load_sensor(sensor)
    zh, za = [], []
    for seed in range(200, 250):
        rec = _with_mag(truth, seed, model)
        tm = true_magnetometer(rec)
        res = calibrate_magnetometer(rec, "ellipsoid", consistency_check=False)
        assert res.status == "ok", res.warnings
        zh.append((res.hard_iron_ut - tm["hard_iron_uT"]) / res.hard_iron_std_ut)
        za.append(((res.soft_iron - _symmetric_unit_det(tm["soft_iron"])) / res.soft_iron_std)[np.triu_indices(3)])
    assert np.mean(np.square(zh)) <= 1.6, np.mean(np.square(zh), axis=0)
    assert np.mean(np.square(za)) <= 1.6, np.mean(np.square(za), axis=0)


def test_aided_over_hands_and_devices():
    """10 hand sessions (zhou2020, typical hand) × 2 full mpu9250_9axis devices: the aided fit's
    hard iron, misalignment and inclination have mean z² ≤ 2.0 (the hand's sway, common to a
    session, is in the gravity reference; measured 1.2–1.8) and the heading with the true tilt is
    ≤ 1.5 × the noise floor in every session."""
    zh, zm, zi, ratios = [], [], [], []
    incl_true = math.degrees(math.atan2(44.0, math.hypot(1.5, 20.0)))
    for k in range(10):
        truth = simulate_truth("zhou2020", "typical", 100.0, seed=300 + k)
        for j in range(2):
            rec = apply_sensor(truth, MAG_9, np.random.default_rng(1000 * k + j))
            tm = true_magnetometer(rec)
            res = calibrate_magnetometer(rec, "aided")
            assert res.status == "ok", res.warnings
            zh.append((res.hard_iron_ut - tm["hard_iron_uT"]) / res.hard_iron_std_ut)
            zm.append((res.misalignment_deg - tm["misalignment_deg"]) / res.misalignment_std_deg)
            zi.append((res.inclination_deg - incl_true) / res.inclination_std_deg)
            rms, floor = _heading_rms_and_floor(truth, rec, res)
            ratios.append(rms / floor)
    for z in (zh, zm, zi):
        assert np.mean(np.square(z)) <= 2.0, np.mean(np.square(z), axis=0)
    assert max(ratios) <= 1.5, max(ratios)


def test_seed_001_comparison_verdict():
    """docs/magnetometer.md's verdict on a phone (strong soft iron): the seed's filters in its own form (a
    random walk: smoothing only) leave the heading error within 10 % of the uncompensated soft
    iron's; calibration with the true tilt reaches the noise floor (≤ 1.2×); the gyro-aided KF beats
    the seed-form KF."""
    for seed in (7, 8):
        c = simulated_comparison("phone", seed=seed)
        rows = {r.name: r for r in c.rows}
        base = rows["hard iron only (soft iron left)"].rms_deg
        for f in ("KF", "AKF", "PF"):
            assert rows[f"hard iron only + {f} (seed)"].rms_deg > 0.9 * base
        assert rows["hard iron only + KF (gyro)"].rms_deg < rows["hard iron only + KF (seed)"].rms_deg
        tt = {r.name: r for r in c.rows_true_tilt}
        assert tt["calibrated (true tilt)"].rms_deg <= 1.2 * c.noise_floor_deg
