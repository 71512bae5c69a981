"""imucal, the peer, in the tests that compare with it: its FerrarisCalibration of its own example session in our
frame, and the check that imucal applies our imucal export as ``calib apply`` does."""

import json
import tempfile
from pathlib import Path

import numpy as np
import pytest

from gyrosim.exchange import imucal_json
from gyrosim.recording import Recording

#: imucal 2.6.0 on its example session, the symmetric part of its gyro matrix (docs/real_imu.md, computed by
#: benchmarks/real_imu.py): S_x, S_y, S_z, G_x, G_y, G_z
IMUCAL_SG = np.array([0.02785, -0.01765, -0.00172, 0.00244, 0.00166, -0.00006])


def assert_imucal_applies_as_calib_apply(cal, seed: int) -> None:
    """Write ``cal`` in imucal's format, load it with imucal and calibrate 2 s of random readings (seed ``seed``)
    with it: equal to ``cal.compensate`` (what ``calib apply`` does) to rounding.  Skips without imucal."""
    pytest.importorskip("imucal", reason="imucal is the optional 'peers' extra (pip install .[peers])")
    from imucal.management import load_calibration_info

    rng = np.random.default_rng(seed)
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
