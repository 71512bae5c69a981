"""Error terms the gyro picks up from its surroundings: the Earth's rotation (through the
attitude) and the magnetic field (Faraday effect in a fibre coil).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from ..errors import GyrosimError
from ..lazy import lazy_module
from ..rotations import quat_conjugate, quat_rotate
from ..units import RAD2DEG, to_si
from .base import Effect

# heavy libraries the functions below call, imported on first use (gyrosim.lazy): not at start-up
kern = lazy_module("gyrosim._kernels")

__all__ = ["EARTH_RATE_RAD_S", "EarthRate", "MagneticSensitivity"]

EARTH_RATE_RAD_S = 7.2921150e-5  # WGS-84 ω_ie


@dataclass(frozen=True)
class EarthRate(Effect):
    """Earth rotation seen by the gyro: δ = C_nᵇ ω_ieⁿ, ω_ieⁿ = Ω (0, cos L, sin L) in ENU,
    Ω = 7.2921150e-5 rad/s (15.04 °/h), L = latitude.  Needs the attitude; gyro only."""

    kind: ClassVar[str] = "earth_rate"
    display_units: ClassVar[dict[str, tuple[float, str]]] = {"gyro": (RAD2DEG, "°")}
    quantities: ClassVar[dict[str, str]] = {"gyro": "angle"}
    pointwise: ClassVar[bool] = True
    param_fields: ClassVar[tuple[str, ...]] = ("latitude_rad",)
    latitude_rad: float = 0.0

    @classmethod
    def preset_to_si(cls, raw: dict[str, Any], unit: str, quantity: str) -> dict[str, Any]:
        """A preset may give ``latitude`` in its ``unit`` (an angle) instead of ``latitude_rad``."""
        raw = super().preset_to_si(raw, unit, quantity)
        if "latitude" in raw:
            raw["latitude_rad"] = float(np.asarray(to_si(raw.pop("latitude"), unit, "angle")))
        return raw

    def __post_init__(self) -> None:
        if not (math.isfinite(self.latitude_rad) and abs(self.latitude_rad) <= math.pi / 2):
            raise GyrosimError("earth_rate: latitude must be within ±90°")

    def delta(self, x, ctx, rng=None):
        q = ctx.require("quat_nb", self.kind)
        w_n = EARTH_RATE_RAD_S * np.array([0.0, math.cos(self.latitude_rad), math.sin(self.latitude_rad)])
        return quat_rotate(quat_conjugate(q), np.broadcast_to(w_n, x.shape))


@dataclass(frozen=True)
class MagneticSensitivity(Effect):
    """Gyro bias from the magnetic field (Faraday effect in FOG coils, "Magnetic Sensitivity of FOG IMU"): δ = K B_b,
    K 3×3 in (rad/s)/µT; unshielded FOG ~1e4 °/(h·T), POS grade 1–10 °/(h·T).  Gyro only."""

    kind: ClassVar[str] = "magnetic_sensitivity"
    display_units: ClassVar[dict[str, tuple[float, str]]] = {"gyro": (RAD2DEG * 3600, "°/h/µT")}
    quantities: ClassVar[dict[str, str]] = {"gyro": "rate_per_tesla"}
    pointwise: ClassVar[bool] = True
    param_fields: ClassVar[tuple[str, ...]] = ("value",)
    value: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))

    def __post_init__(self) -> None:
        v = np.array(self.value, dtype=float)
        v = np.diag(v) if v.shape == (3,) else v.reshape(3, 3)
        if not np.all(np.isfinite(v)):
            raise GyrosimError("magnetic_sensitivity has NaN/inf values")
        object.__setattr__(self, "value", v)

    def delta(self, x, ctx, rng=None):
        return ctx.require("mag_body_ut", self.kind) @ self.value.T

    def add_delta(self, y, x, ctx, rng=None):
        kern.add_matvec(y, np.ascontiguousarray(ctx.require("mag_body_ut", self.kind)), self.value)

    def sensitivity(self, x, ctx):
        b = ctx.require("mag_body_ut", self.kind)
        out = np.zeros(x.shape + (9,))
        for i in range(3):
            out[:, i, 3 * i : 3 * i + 3] = b
        return out
