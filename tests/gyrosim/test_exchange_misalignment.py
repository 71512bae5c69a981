"""The gyro's rotation against the accelerometer in a calibration's JSON and in the exports: Kalibr's C_gyro_i
(a comment: its imu.yaml has no key for it) and imucal's R_g (a general matrix, so the rotation is in it)."""

from __future__ import annotations

import re

import numpy as np
from imucal_reference import assert_imucal_applies_as_calib_apply

from gyrosim import effects as E
from gyrosim.calibration import Calibration
from gyrosim.exchange import kalibr_imu_yaml

ALPHA = np.radians([0.85, -0.43, -0.02])   # imu_tk's Xsens gyro against its accelerometer (°, about x, y, z)


def _cal() -> Calibration:
    gyro = (E.Bias(value=[0.01, -0.02, 0.005]), E.ScaleFactor(value=[0.02, -0.01, 0.03]),
            E.NonOrthogonality(value=[0.004, -0.002, 0.001]), E.GyroAccMisalignment(value=ALPHA),
            E.WhiteNoise(density=[2e-4] * 3))
    acc = (E.Bias(value=[0.1, -0.2, 0.05]), E.ScaleFactor(value=[0.01, 0.02, -0.01]),
           E.NonOrthogonality(value=[0.002, 0.0, -0.003]), E.WhiteNoise(density=[3e-3] * 3))
    n = 21
    return Calibration(gyro=gyro, accelerometer=acc, covariance=np.diag(np.full(n, 1e-8)), method="test")


def test_json_states_the_misalignment_with_its_std_and_round_trips():
    cal = _cal()
    d = cal.to_dict()
    np.testing.assert_allclose(d["gyro"]["misalignment_rad"], ALPHA)
    np.testing.assert_allclose(d["gyro"]["std"]["misalignment_rad"], [1e-4] * 3)
    back = Calibration.from_dict(d)
    np.testing.assert_array_equal(back.value("gyro", "gyro_acc_misalignment"), ALPHA)
    # without the effect the key is absent: no zeros that look measured
    plain = Calibration.from_linear(gyro={"bias": np.zeros(3), "scale_factor": np.zeros(3),
                                          "nonorthogonality": np.zeros(3)})
    assert "misalignment_rad" not in plain.to_dict()["gyro"]


def test_kalibr_comment_holds_c_gyro_i_as_the_gyros_rotation():
    """C_gyro_i maps the IMU (accelerometer) frame to the gyro's: R(α)ᵀ, which to first order is I − [α×]."""
    text = kalibr_imu_yaml(_cal(), 100.0, gyro_random_walk=1e-5, acc_random_walk=1e-4)
    line = next(ln for ln in text.splitlines() if "C_gyro_i" in ln)
    c = np.array([float(x) for x in re.findall(r"[-+]?\d\.\d+(?:e[-+]\d+)?", line.split(":", 1)[1])]).reshape(3, 3)
    np.testing.assert_allclose(c, E.rotation_matrix(ALPHA).T, atol=1e-8)
    np.testing.assert_allclose(c, np.eye(3) + E.GyroAccMisalignment(value=ALPHA).matrix(), atol=float(ALPHA @ ALPHA))
    import yaml

    assert "C_gyro_i" not in yaml.safe_load(text)        # a comment: the file stays one Kalibr reads


def test_imucal_export_compensates_the_rotation_as_we_do():
    assert_imucal_applies_as_calib_apply(_cal(), seed=3)
