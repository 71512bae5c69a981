"""Thermal error terms: bias and scale factor as functions of the sensor temperature T (°C, from
the context), and the heating/cooling hysteresis (polynomial, piecewise-linear, RBF: ERICCO's *Measurement Error
and Calibration of FOG IMU*; Qi et al., *Modification of MTEA-Based Temperature Drift Error Compensation Model for
MEMS-Gyros*).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from ..errors import GyrosimError
from ..lazy import lazy_module
from ..units import RAD2DEG
from .base import Effect, SignalContext, VectorEffect, diagonal_jacobian

# heavy libraries the functions below call, imported on first use (gyrosim.lazy): not at start-up
sp_signal = lazy_module("scipy.signal")
kern = lazy_module("gyrosim._kernels")

__all__ = ["TemperatureBias", "TemperatureScale", "ThermalHysteresis", "TemperaturePiecewise", "TemperatureRBF"]


def _span_c(ctx: SignalContext) -> tuple[float, float, float]:
    """(mean, min, max) of the recording's temperature (°C): where a thermal candidate is centred and valid."""
    temp = ctx.require("temperature_c", "a thermal candidate")
    return float(np.mean(temp)), float(np.min(temp)), float(np.max(temp))


def _poly(t: np.ndarray, coeffs: np.ndarray) -> np.ndarray:
    """Σ_p c[:, p] ΔT^(p+1) for coefficient matrix (3, P) → (N, 3)."""
    powers = np.stack([t ** (p + 1) for p in range(coeffs.shape[1])], axis=1)  # (N, P)
    return powers @ coeffs.T


@dataclass(frozen=True)
class TemperatureBias(Effect):
    """Bias over temperature: δ = Σ_{p=1..P} c_p (T − T_ref)^p, coefficients (3, P) in
    rad/s/°C^p or m/s²/°C^p.  Valid on ``range_c``; a temperature outside it is an error."""

    kind: ClassVar[str] = "temperature_bias"
    display_units: ClassVar[dict[str, tuple[float, str]]] = {"gyro": (RAD2DEG, "°/s/°C")}
    quantities: ClassVar[dict[str, str]] = {"gyro": "rate", "accelerometer": "acceleration"}  # per °C^p
    pointwise: ClassVar[bool] = True
    param_fields: ClassVar[tuple[str, ...]] = ("coefficients",)
    coefficients: np.ndarray = field(default_factory=lambda: np.zeros((3, 1)))
    coefficients_sigma: np.ndarray = field(default_factory=lambda: np.zeros((3, 1)))
    t_ref_c: float = 25.0
    range_c: tuple[float, float] = (-40.0, 85.0)

    def __post_init__(self) -> None:
        for name in ("coefficients", "coefficients_sigma"):
            c = np.array(getattr(self, name), dtype=float)
            c = c.reshape(3, -1) if c.size % 3 == 0 and c.ndim != 2 else c
            if c.ndim == 1:
                c = np.tile(c[:, None], (3, 1)) if c.size == 1 else c.reshape(3, -1)
            if not np.all(np.isfinite(c)):
                raise GyrosimError(f"{self.kind}: coefficients must be finite")
            object.__setattr__(self, name, c)

    @classmethod
    def candidate_prototype(cls, ctx):
        """First order about the recording's mean temperature, valid 1 °C beyond its span."""
        t_ref, lo, hi = _span_c(ctx)
        return cls(coefficients=np.zeros((3, 1)), t_ref_c=t_ref, range_c=(lo - 1.0, hi + 1.0))

    def _dT(self, ctx: SignalContext) -> np.ndarray:
        temp = ctx.require("temperature_c", self.kind)
        lo, hi = self.range_c
        if np.nanmin(temp) < lo - 1e-9 or np.nanmax(temp) > hi + 1e-9:
            raise GyrosimError(
                f"{self.kind}: temperature {np.nanmin(temp):.1f}–{np.nanmax(temp):.1f} °C leaves the model's "
                f"valid range {lo:g}–{hi:g} °C; the preset cannot extrapolate"
            )
        return temp - self.t_ref_c

    def delta(self, x, ctx, rng=None):
        return _poly(self._dT(ctx), self.coefficients)

    def add_delta(self, y, x, ctx, rng=None):
        kern.add_poly_bias(y, np.ascontiguousarray(self._dT(ctx)), self.coefficients)

    def sensitivity(self, x, ctx):
        dT = self._dT(ctx)
        P = self.coefficients.shape[1]
        out = np.zeros(x.shape + (3 * P,))
        for i in range(3):
            for p in range(P):
                out[:, i, i * P + p] = dT ** (p + 1)
        return out


@dataclass(frozen=True)
class TemperatureScale(TemperatureBias):
    """Scale factor over temperature: δ = diag(Σ_p s_p (T − T_ref)^p) x, s in 1/°C^p."""

    kind: ClassVar[str] = "temperature_scale"
    display_units: ClassVar[dict[str, tuple[float, str]]] = {"gyro": (1e6, "ppm/°C")}
    quantities: ClassVar[dict[str, str]] = {"gyro": "fraction", "accelerometer": "fraction"}  # per °C^p

    def delta(self, x, ctx, rng=None):
        return x * _poly(self._dT(ctx), self.coefficients)

    def add_delta(self, y, x, ctx, rng=None):
        kern.add_poly_scale(y, x, np.ascontiguousarray(self._dT(ctx)), self.coefficients)

    def delta_dx(self, x, ctx):
        s = _poly(self._dT(ctx), self.coefficients)
        return diagonal_jacobian(s)

    def sensitivity(self, x, ctx):
        # ∂δ_i/∂s_ip = x_i ΔT^p: the bias sensitivity times the input on that axis
        return super().sensitivity(x, ctx) * x[:, :, None]


@dataclass(frozen=True)
class ThermalHysteresis(VectorEffect):
    """Heating/cooling hysteresis: a bias proportional to the low-passed temperature rate,
    δ = h · LP_τ(dT/dt), h in (rad/s)/(°C/s) or (m/s²)/(°C/s); the bias lags differently when
    warming (dT/dt > 0) and cooling (< 0), which opens the loop of a bias-vs-T plot."""

    kind: ClassVar[str] = "thermal_hysteresis"
    display_units: ClassVar[dict[str, tuple[float, str]]] = {"gyro": (RAD2DEG, "(°/s)/(°C/s)")}
    quantities: ClassVar[dict[str, str]] = {"gyro": "rate", "accelerometer": "acceleration"}  # per (°C/s)
    labels: ClassVar[tuple[str, str]] = ("hysteresis", "hysteresis sigma")
    tau_s: float = 300.0

    def check(self) -> None:
        if not (math.isfinite(self.tau_s) and self.tau_s > 0):
            raise GyrosimError("thermal_hysteresis: tau_s must be > 0 s")

    def regressor(self, ctx: SignalContext) -> np.ndarray:
        temp = ctx.require("temperature_c", self.kind)
        rate = np.gradient(temp, ctx.t_s)
        a = math.exp(-ctx.dt_s / self.tau_s)
        return sp_signal.lfilter([1 - a], [1, -a], rate, zi=[a * rate[0]])[0]

    def delta(self, x, ctx, rng=None):
        return np.outer(self.regressor(ctx), self.value)

    def sensitivity(self, x, ctx):
        r = self.regressor(ctx)
        return np.broadcast_to(np.eye(3), x.shape + (3,)) * r[:, None, None]


def _hats(temp: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(N, K) linear-interpolation weights of each temperature on the points (held beyond the ends)."""
    t = np.clip(temp, points[0], points[-1])
    j = np.clip(np.searchsorted(points, t, side="right") - 1, 0, points.size - 2)
    w = (t - points[j]) / (points[j + 1] - points[j])
    out = np.zeros((t.size, points.size))
    rows = np.arange(t.size)
    out[rows, j] = 1.0 - w
    out[rows, j + 1] = w
    return out


@dataclass(frozen=True)
class TemperaturePiecewise(Effect):
    """Bias and scale factor interpolated linearly between calibration temperatures ("Measurement Error and Calibration
    of FOG IMU", §4, piecewise-linear interpolation compensation): δ_i = b_i(T) + s_i(T) x_i, with b_i, s_i the values
    at ``points_c`` (°C, increasing) joined linearly and held beyond the end points. ``bias`` (3, K) in rad/s or m/s²,
    ``scale`` (3, K) fraction (SI in presets too)."""

    kind: ClassVar[str] = "temperature_pwl"
    display_units: ClassVar[dict[str, tuple[float, str]]] = {"gyro": (1.0, "SI (rad/s | 1)")}
    # bias values in the preset unit; scale in SI
    quantities: ClassVar[dict[str, str]] = {"gyro": "rate", "accelerometer": "acceleration"}
    pointwise: ClassVar[bool] = True
    param_fields: ClassVar[tuple[str, ...]] = ("bias", "scale")
    points_c: np.ndarray = field(default_factory=lambda: np.array([-40.0, 85.0]))
    bias: np.ndarray = field(default_factory=lambda: np.zeros((3, 2)))
    scale: np.ndarray = field(default_factory=lambda: np.zeros((3, 2)))

    def __post_init__(self) -> None:
        pts = np.asarray(self.points_c, dtype=float).ravel()
        if pts.size < 2 or np.any(np.diff(pts) <= 0) or not np.all(np.isfinite(pts)):
            raise GyrosimError("temperature_pwl: points_c must be ≥ 2 finite, strictly increasing temperatures (°C)")
        object.__setattr__(self, "points_c", pts)
        for name in ("bias", "scale"):
            v = np.array(getattr(self, name), dtype=float)
            v = np.tile(v.reshape(1, -1), (3, 1)) if v.ndim == 1 else v
            if v.shape != (3, pts.size) or not np.all(np.isfinite(v)):
                raise GyrosimError(f"temperature_pwl: {name} must be finite with shape (3, {pts.size}), got {v.shape}")
            object.__setattr__(self, name, v)

    @classmethod
    def candidate_prototype(cls, ctx):
        """Five points spread evenly over the recording's temperature span."""
        _, lo, hi = _span_c(ctx)
        return cls(points_c=np.linspace(lo, hi, 5), bias=np.zeros((3, 5)), scale=np.zeros((3, 5)))

    def _h(self, ctx: SignalContext) -> np.ndarray:
        return _hats(ctx.require("temperature_c", self.kind), self.points_c)

    def delta(self, x, ctx, rng=None):
        h = self._h(ctx)
        return h @ self.bias.T + x * (h @ self.scale.T)

    def delta_dx(self, x, ctx):
        s = self._h(ctx) @ self.scale.T
        return diagonal_jacobian(s)

    def sensitivity(self, x, ctx):
        h = self._h(ctx)
        k = self.points_c.size
        out = np.zeros(x.shape + (6 * k,))
        for i in range(3):
            out[:, i, i * k : (i + 1) * k] = h
            out[:, i, 3 * k + i * k : 3 * k + (i + 1) * k] = h * x[:, i : i + 1]
        return out


@dataclass(frozen=True)
class TemperatureRBF(Effect):
    """Bias drift over temperature as a Gaussian radial-basis network with the inputs ΔT and ΔT² ("Modification of
    MTEA-Based Temperature Drift Error Compensation Model for MEMS-Gyros", §3.2: TDE modelled from ΔT = T − T_ref and
    ΔT²):

        δ_i = Σ_k a_ik exp(−½ [((ΔT − ΔT_k)/w)² + ((ΔT² − ΔT_k²)/(w·s))²]),   s = 2 max_k |ΔT_k|

    with centres ΔT_k = ``centres_c`` − ``t_ref_c`` and width w = ``width_c`` (°C); s puts the ΔT²
    axis on the same scale as ΔT.  The centres are fixed, so δ is linear in the weights a (3, K),
    rad/s or m/s² (an RBF network whose output layer is fitted by least squares)."""

    kind: ClassVar[str] = "temperature_rbf"
    display_units: ClassVar[dict[str, tuple[float, str]]] = {"gyro": (RAD2DEG, "°/s")}
    quantities: ClassVar[dict[str, str]] = {"gyro": "rate", "accelerometer": "acceleration"}
    pointwise: ClassVar[bool] = True
    param_fields: ClassVar[tuple[str, ...]] = ("weights",)
    centres_c: np.ndarray = field(default_factory=lambda: np.linspace(-40.0, 85.0, 6))
    width_c: float = 25.0
    t_ref_c: float = 25.0
    weights: np.ndarray = field(default_factory=lambda: np.zeros((3, 6)))

    def __post_init__(self) -> None:
        c = np.asarray(self.centres_c, dtype=float).ravel()
        if c.size < 1 or not np.all(np.isfinite(c)):
            raise GyrosimError("temperature_rbf: centres_c must be finite temperatures (°C)")
        if not (math.isfinite(self.width_c) and self.width_c > 0):
            raise GyrosimError("temperature_rbf: width_c must be > 0 °C")
        object.__setattr__(self, "centres_c", c)
        w = np.array(self.weights, dtype=float)
        w = np.tile(w.reshape(1, -1), (3, 1)) if w.ndim == 1 else w
        if w.shape != (3, c.size) or not np.all(np.isfinite(w)):
            raise GyrosimError(f"temperature_rbf: weights must be finite with shape (3, {c.size}), got {w.shape}")
        object.__setattr__(self, "weights", w)

    @classmethod
    def candidate_prototype(cls, ctx):
        """Six centres spread evenly over the recording's span, one spacing wide, about its mean."""
        t_ref, lo, hi = _span_c(ctx)
        centres = np.linspace(lo, hi, 6)
        return cls(centres_c=centres, width_c=float(centres[1] - centres[0]), t_ref_c=t_ref, weights=np.zeros((3, 6)))

    def basis(self, temp_c: np.ndarray) -> np.ndarray:
        """(N, K) Gaussian activations of the hidden layer."""
        d = np.asarray(temp_c, dtype=float)[:, None] - self.t_ref_c
        dk = self.centres_c[None, :] - self.t_ref_c
        s = 2.0 * max(float(np.max(np.abs(dk))), 1.0)
        z = ((d - dk) / self.width_c) ** 2 + ((d**2 - dk**2) / (self.width_c * s)) ** 2
        return np.exp(-0.5 * z)

    def delta(self, x, ctx, rng=None):
        return self.basis(ctx.require("temperature_c", self.kind)) @ self.weights.T

    def sensitivity(self, x, ctx):
        b = self.basis(ctx.require("temperature_c", self.kind))
        k = self.centres_c.size
        out = np.zeros(x.shape + (3 * k,))
        for i in range(3):
            out[:, i, i * k : (i + 1) * k] = b
        return out
