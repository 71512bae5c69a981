"""The exports write what ``calib apply`` applies: a calibration's ``applied`` block (the parameters the session
determined, the prior's for the rest), not the estimate of a parameter the motion left undetermined."""

from __future__ import annotations

import json

import numpy as np
import pytest
from imucal_reference import assert_imucal_applies_as_calib_apply

from gyrosim import effects as E
from gyrosim.calibration import Applied, Calibration
from gyrosim.exchange import imucal_json, kalibr_imu_yaml


def _cal() -> Calibration:
    """An estimate whose gyro S_z and whole accelerometer the session did not determine: applied at the prior (0)."""
    est = np.array([0.01, -0.02, 0.005, 0.02, -0.01, 0.03, 0.004, -0.002, 0.001,     # gyro b (rad/s), S, G
                    0.1, -0.2, 0.05, 0.01, 0.02, -0.01, 0.002, 0.0, -0.003])         # accelerometer b (m/s²), S, G
    session = np.ones(18, bool)
    session[5] = False
    session[9:] = False
    values = np.where(session, est, 0.0)
    applied = Applied(values, np.full(18, 1e-4), session, session, prior="a maker-calibrated sensor")
    gyro = (E.Bias(value=est[0:3]), E.ScaleFactor(value=est[3:6]), E.NonOrthogonality(value=est[6:9]),
            E.WhiteNoise(density=[2e-4] * 3))
    acc = (E.Bias(value=est[9:12]), E.ScaleFactor(value=est[12:15]), E.NonOrthogonality(value=est[15:18]),
           E.WhiteNoise(density=[3e-3] * 3))
    return Calibration(gyro=gyro, accelerometer=acc, covariance=np.diag(np.full(18, 1e-8)), method="test",
                       applied=applied)


def test_as_applied_holds_the_applied_values_and_the_noise():
    cal = _cal()
    a = cal.as_applied()
    np.testing.assert_array_equal(a.vector("gyro"), cal.applied.values[:9])
    np.testing.assert_array_equal(a.vector("accelerometer"), cal.applied.values[9:])
    assert a.applied is None and a.has("gyro", "white_noise") and a.has("accelerometer", "white_noise")
    np.testing.assert_allclose(np.sqrt(np.diag(a.covariance)), 1e-4)


def test_imucal_export_holds_the_applied_values():
    d = json.loads(imucal_json(_cal()))
    np.testing.assert_allclose(d["b_a"], 0.0)                         # the accelerometer at its prior
    np.testing.assert_allclose(np.radians(d["b_g"]), [0.01, -0.02, 0.005])
    # K_g's z: the norm of M's third row, 1 + S_z + O(G²) — the prior's S_z = 0, not the undetermined estimate's 0.03
    assert d["K_g"][2][2] == pytest.approx(1.0, abs=1e-4)


def test_kalibr_comments_hold_the_applied_values():
    text = kalibr_imu_yaml(_cal(), 100.0, gyro_random_walk=1e-5, acc_random_walk=1e-4)
    line = next(ln for ln in text.splitlines() if "gyro scale factor" in ln)
    s = np.array([float(x) for x in line.split("[", 1)[1].rstrip("]").split(",")])
    np.testing.assert_allclose(s, [0.02, -0.01, 0.0])
    assert "calib apply" in text


def test_imucal_applies_the_export_as_calib_apply_does():
    """imucal's own calibrate() on the export equals calib apply, which compensates with the applied block."""
    assert_imucal_applies_as_calib_apply(_cal(), seed=5)
