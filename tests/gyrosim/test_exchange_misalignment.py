"""The gyro's rotation against the accelerometer in a calibration's JSON and in the exports: Kalibr's C_gyro_i
(a comment: its imu.yaml has no key for it) and imucal's R_g (a general matrix, so the rotation is in it)."""

from __future__ import annotations

import re

import numpy as np
import pytest

from gyrosim import effects as E
from gyrosim.calibration import Calibration
from gyrosim.exchange import imucal_json, kalibr_imu_yaml
from gyrosim.recording import Recording

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
    pytest.importorskip("imucal", reason="imucal is the optional 'peers' extra (pip install .[peers])")
    import json
    import tempfile
    from pathlib import Path

    from imucal.management import load_calibration_info

    cal = _cal()
    rng = np.random.default_rng(3)
    t = np.arange(200) / 100.0
    rec = Recording(t, rng.normal(size=(200, 3)), rng.normal(size=(200, 3)) + [0, 0, 9.8], meta={"rate_hz": 100.0})
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "imucal.json"
        path.write_text(imucal_json(cal))
        info = load_calibration_info(path)
        assert json.loads(path.read_text())["cal_type"] == "Ferraris"
    acc, gyr = info.calibrate(acc=rec.acc_m_s2, gyr=np.degrees(rec.gyro_rad_s), acc_unit="m/s^2", gyr_unit="deg/s")
    ours = cal.compensate(rec)
    np.testing.assert_allclose(np.radians(gyr), ours.gyro_rad_s, atol=1e-11)
    np.testing.assert_allclose(acc, ours.acc_m_s2, atol=1e-9)
