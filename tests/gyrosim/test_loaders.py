"""Measured recordings load into the shared Recording type (needs ../shared/data or $GYROSIM_DATA)."""

from __future__ import annotations

import numpy as np
import pytest

from gyrosim.loaders import available_datasets, data_root, load_dataset

DATA = available_datasets()
needs_data = pytest.mark.skipif(not DATA, reason=f"measured data not found under {data_root()} (set GYROSIM_DATA)")


@needs_data
@pytest.mark.parametrize("name", DATA)
def test_every_dataset_loads_in_si_units(name):
    rec = load_dataset(name)
    f = np.linalg.norm(rec.acc_m_s2, axis=1)
    # gravity in m/s² (not g) within the ±6 % an uncalibrated consumer accelerometer allows
    assert 9.2 < np.median(f) < 10.4, (name, np.median(f))
    # rates in rad/s: hand motion stays below 35 rad/s (2000 °/s)
    assert np.abs(rec.gyro_rad_s).max() < 35.0
    assert rec.meta["source"] and rec.meta["licence"] and rec.meta.get("conversion")


@needs_data
def test_broad_truth_is_the_optical_reference():
    name = next(n for n in DATA if n.startswith("broad/"))
    rec = load_dataset(name)
    q = rec.truth.quat_nb
    ok = np.all(np.isfinite(q), axis=1)
    np.testing.assert_allclose(np.linalg.norm(q[ok], axis=1), 1.0, atol=1e-6)
    assert rec.rate_hz == pytest.approx(285.714, rel=1e-4)
    assert 0 < rec.truth.extra["movement"].mean() < 1  # a movement phase and rest phases


@needs_data
def test_thermometer_is_resampled_onto_the_inertial_clock():
    if "xio_ximu_thermometer" not in DATA:
        pytest.skip("xio_ximu_thermometer not in the data folder")
    rec = load_dataset("xio_ximu_thermometer")
    assert rec.rate_hz == 256.0 and rec.temp_c.shape == (rec.n,)
    # 31.0–31.9 °C as the source says; resampled values stay within the readings' range
    assert 30.9 < rec.temp_c.min() and rec.temp_c.max() < 32.0
    assert "resampled" in rec.meta["conversion"]
