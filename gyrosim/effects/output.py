"""Output stage: transforms of the sensor's output y applied in list order after the error terms,
y ← T_j(y) (bandwidth, latency, jitter, quantization, saturation), with their inverses.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from ..errors import GyrosimError
from ..lazy import lazy_module
from .base import ANY_TRIAD, Effect, SignalContext, _need_rng, _vec

# heavy libraries the functions below call, imported on first use (gyrosim.lazy): not at start-up
kern = lazy_module("gyrosim._kernels")

__all__ = ["Bandwidth", "TimeOffset", "Jitter", "Quantization", "Saturation"]


@dataclass(frozen=True)
class Bandwidth(Effect):
    """First-order low-pass of the sensor output (its digital low-pass filter), exact
    discretisation y_k = a y_{k−1} + (1 − a) u_k, a = exp(−2π f_c Δt), started at steady state
    (y_0 = u_0).  Inverse: u_k = (y_k − a y_{k−1}) / (1 − a), exact."""

    kind: ClassVar[str] = "bandwidth"
    closeloop_reason: ClassVar[str] = (
        "a first-order low-pass equals a time offset d = 1/(2π f_c) to first order in f/f_c; tested as "
        "time_offset, whose equivalent cutoff is reported")
    quantities: ClassVar[dict[str, str]] = {"gyro": "frequency", "accelerometer": "frequency",
                                            "magnetometer": "frequency"}
    stage: ClassVar[str] = "output"
    param_fields: ClassVar[tuple[str, ...]] = ("cutoff_hz",)
    cutoff_hz: float = 50.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.cutoff_hz) and self.cutoff_hz > 0):
            raise GyrosimError("bandwidth cutoff_hz must be > 0 Hz")

    def _a(self, ctx: SignalContext) -> float:
        return math.exp(-2 * math.pi * self.cutoff_hz * ctx.dt_s)

    def transform(self, y, ctx, rng=None):
        return kern.lowpass(np.ascontiguousarray(y), self._a(ctx))

    def inverse(self, y, ctx):
        a = self._a(ctx)
        u = np.empty_like(y)
        u[0] = y[0]
        u[1:] = (y[1:] - a * y[:-1]) / (1 - a)
        return u


@dataclass(frozen=True)
class TimeOffset(Effect):
    """Latency: the output at t is the input at t − d (d in s, may be fractional and negative),
    applied as a Fourier phase shift (band-limited interpolation; the record is treated as
    periodic, so start and end should be at rest).  Inverse: the shift by −d, exact.
    Linearised sensitivity ∂y/∂d = −ẋ."""

    kind: ClassVar[str] = "time_offset"
    display_units: ClassVar[dict[str, tuple[float, str]]] = {"gyro": (1e3, "ms")}
    quantities: ClassVar[dict[str, str]] = {"gyro": "time", "accelerometer": "time", "magnetometer": "time"}
    stage: ClassVar[str] = "output"
    param_fields: ClassVar[tuple[str, ...]] = ("delay_s",)
    delay_s: float = 0.0

    def __post_init__(self) -> None:
        if not math.isfinite(self.delay_s):
            raise GyrosimError("time_offset delay_s must be finite")

    @staticmethod
    def _shift(y: np.ndarray, d: float, dt: float) -> np.ndarray:
        """y(t − d) by multiplying the spectrum with e^{−i2πfd}.  For an even length the Nyquist
        bin cannot carry a phase in a real signal (irfft keeps its real part), so signals with
        energy at f_s/2 are not shifted exactly there; physical IMU signals have none."""
        n = y.shape[0]
        f = np.fft.rfftfreq(n, dt)
        spec = np.fft.rfft(y, axis=0) * np.exp(-2j * np.pi * f * d)[:, None]
        return np.fft.irfft(spec, n=n, axis=0)

    def transform(self, y, ctx, rng=None):
        return self._shift(y, self.delay_s, ctx.dt_s)

    def inverse(self, y, ctx):
        return self._shift(y, -self.delay_s, ctx.dt_s)

    def sensitivity(self, x, ctx):
        """∂y/∂d = −ẋ(t − d): the spectral derivative of the shifted input, (N, 3, 1)."""
        n = x.shape[0]
        f = np.fft.rfftfreq(n, ctx.dt_s)
        spec = np.fft.rfft(x, axis=0) * (-2j * np.pi * f * np.exp(-2j * np.pi * f * self.delay_s))[:, None]
        if n % 2 == 0:
            spec[-1] = 0.0  # the Nyquist bin has no real derivative
        return np.fft.irfft(spec, n=n, axis=0)[:, :, None]


@dataclass(frozen=True)
class Jitter(Effect):
    """Sample-time jitter: the sensor samples at t_k + ε_k, ε_k ~ N(0, σ²) (σ in s); the output
    is the signal interpolated there (cubic spline).  Random, not invertible."""

    kind: ClassVar[str] = "jitter"
    closeloop_reason: ClassVar[str] = (
        "random sampling-time error: checked as residual variance growing with |dω/dt|² (structure tests)")
    quantities: ClassVar[dict[str, str]] = {"gyro": "time", "accelerometer": "time", "magnetometer": "time"}
    stage: ClassVar[str] = "output"
    stochastic: ClassVar[bool] = True
    invertible: ClassVar[bool] = False
    param_fields: ClassVar[tuple[str, ...]] = ("sigma_s",)
    sigma_s: float = 0.0

    def transform(self, y, ctx, rng=None):
        rng = _need_rng(rng, self.kind)
        t = ctx.t_s
        eps = rng.standard_normal(t.shape) * self.sigma_s
        from scipy.interpolate import CubicSpline

        return CubicSpline(t, y, axis=0)(np.clip(t + eps, t[0], t[-1]))


@dataclass(frozen=True)
class Quantization(Effect):
    """Quantization to a least significant bit: y = LSB · round(y / LSB).  Deterministic but
    information-losing: compensation leaves it (error ≤ LSB/2, RMS LSB/√12)."""

    kind: ClassVar[str] = "quantization"
    closeloop_reason: ClassVar[str] = (
        "not a residual term (RMS LSB/√12): detected from the output's granularity (checks)")
    quantities: ClassVar[dict[str, str]] = ANY_TRIAD
    pointwise: ClassVar[bool] = True
    stage: ClassVar[str] = "output"
    invertible: ClassVar[bool] = False
    param_fields: ClassVar[tuple[str, ...]] = ("lsb",)
    lsb: np.ndarray = field(default_factory=lambda: np.full(3, 1e-6))

    def __post_init__(self) -> None:
        v = _vec(self.lsb, name="LSB")
        if np.any(v <= 0):
            raise GyrosimError("quantization lsb must be > 0")
        object.__setattr__(self, "lsb", v)

    def transform(self, y, ctx, rng=None):
        return kern.quantize(np.ascontiguousarray(y), self.lsb)

    def sample_noise_variance(self, rate_hz):
        # rounding error uniform on ±LSB/2: variance LSB²/12
        return self.lsb**2 / 12

    def inverse(self, y, ctx):
        return y


@dataclass(frozen=True)
class Saturation(Effect):
    """Output clipped to ±range.  Compensation cannot recover clipped samples: it raises
    (:meth:`check`) naming how many samples sit at the rails."""

    kind: ClassVar[str] = "saturation"
    closeloop_reason: ClassVar[str] = (
        "not a residual term: detected as samples at the rails (checks)")
    quantities: ClassVar[dict[str, str]] = ANY_TRIAD
    pointwise: ClassVar[bool] = True
    stage: ClassVar[str] = "output"
    invertible: ClassVar[bool] = False
    param_fields: ClassVar[tuple[str, ...]] = ("range",)
    range: np.ndarray = field(default_factory=lambda: np.full(3, np.inf))

    def __post_init__(self) -> None:
        v = np.array(self.range, dtype=float).reshape(-1)
        v = np.full(3, v[0]) if v.size == 1 else v
        if v.size != 3 or np.any(np.isnan(v)) or np.any(v <= 0):
            raise GyrosimError("saturation range must be 3 positive values")
        object.__setattr__(self, "range", v)

    def transform(self, y, ctx, rng=None):
        return kern.saturate(np.ascontiguousarray(y), self.range)

    def saturated(self, y: np.ndarray) -> np.ndarray:
        return np.abs(y) >= self.range * (1 - 1e-12)

    def inverse(self, y, ctx):
        bad = self.saturated(y)
        if bad.any():
            raise GyrosimError(
                f"{int(bad.any(axis=1).sum())} sample(s) sit at the ±{self.range.tolist()} rails (saturated): "
                "their true value is unknown; exclude them before calibrating"
            )
        return y
