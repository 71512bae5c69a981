"""bias(T) fitted only as far as the data support it (groundwork of the thermal compensation)."""

from __future__ import annotations

import numpy as np
import pytest

from gyrosim.effects import SignalContext
from gyrosim.errors import RecordingError
from gyrosim.loaders import available_datasets, data_root, load_dataset
from gyrosim.recording import Recording
from gyrosim.sensor_model import SensorModel, load_sensor

from calib.temperature.bias_model import fit_bias_temperature


def _warm_up(seed: int) -> tuple[Recording, np.ndarray]:
    preset = load_sensor("mpu9250")
    kinds = ("bias", "temperature_bias", "white_noise", "bias_instability", "random_walk")
    dev = SensorModel("warm-up", gyro=tuple(e for e in preset.gyro if e.kind in kinds), thermal=preset.thermal)
    dev = dev.realize(np.random.default_rng(seed))
    fs, n = 50.0, 50 * 1800
    t = np.arange(n) / fs
    temp = dev.thermal.temperature(t)
    ctx = SignalContext(t, np.zeros((n, 3)), np.tile([0.0, 0.0, 9.80665], (n, 1)), temperature_c=temp)
    g, a = dev.apply(ctx, np.random.default_rng(seed + 1))
    a = a + np.random.default_rng(seed + 2).normal(size=a.shape) * 0.003
    true = [e for e in dev.gyro if e.kind == "temperature_bias"][0].coefficients[:, 0]
    return Recording(t, g, a, temp_c=temp), true


def test_warm_up_recovers_the_linear_bias_of_temperature():
    rec, true = _warm_up(11)
    fit = fit_bias_temperature(rec)
    assert fit.degree == 1 and fit.span_c > 4.0
    # |error| < 4σ, σ inflated by batch means for the MPU's flicker and random-walk drift
    assert np.all(np.abs(fit.coefficients[:, 1] - true) < 4 * fit.coefficient_std[:, 1])
    assert any("degree 2 rejected" in m for m in fit.messages)


def test_constant_temperature_says_so_instead_of_fitting():
    rec, _ = _warm_up(11)
    flat = rec.with_signals(temp_c=np.full(rec.n, 25.0))
    fit = fit_bias_temperature(flat)
    assert fit.degree == 0 and any("too small to fit" in m for m in fit.messages)


def test_bad_temperature_channels():
    rec, _ = _warm_up(11)
    with pytest.raises(RecordingError, match="no temperature channel"):
        fit_bias_temperature(rec.with_signals(temp_c=None))
    temp = rec.temp_c.copy()
    temp[100] = np.nan
    bad = Recording.__new__(Recording)  # bypass validation to hand the fit a NaN channel
    object.__setattr__(bad, "__dict__", {**rec.__dict__, "temp_c": temp})
    with pytest.raises(RecordingError, match="NaN"):
        fit_bias_temperature(bad)


@pytest.mark.skipif("xio_ximu_thermometer" not in available_datasets(), reason=f"x-io data not under {data_root()}")
def test_xio_thermometer_span_is_too_small_and_the_fit_says_so():
    fit = fit_bias_temperature(load_dataset("xio_ximu_thermometer"))
    assert fit.degree == 0
    assert any("too small to fit" in m for m in fit.messages)
