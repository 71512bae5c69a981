"""Thermal state of the sensor: ambient temperature, self-heating after power-on, first-order lag.

Model (°C, s):

    T_target(t) = T_amb(t) + ΔT_self · (1 − e^{−t/τ_self})      (power on at t = 0)
    dT/dt       = (T_target − T) / τ_case,   T(0) = T_amb(0)

discretised exactly for a piecewise-constant target (T_k+1 = a T_k + (1 − a) T_target,k,
a = e^{−Δt/τ_case}).  ``ambient_c`` may be a constant or a callable t ↦ °C (a chamber profile).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from .errors import GyrosimError
from .lazy import lazy_module

# imported on first use (gyrosim.lazy), so that start-up and a refused file do not pay for it
sp_signal = lazy_module("scipy.signal")

__all__ = ["ThermalModel"]


@dataclass(frozen=True)
class ThermalModel:
    """Sensor temperature from ambient and self-heating (see module docstring)."""

    ambient_c: float = 25.0
    self_heating_c: float = 0.0
    self_heating_tau_s: float = 300.0
    case_tau_s: float = 60.0

    def __post_init__(self) -> None:
        for name in ("ambient_c", "self_heating_c", "self_heating_tau_s", "case_tau_s"):
            v = getattr(self, name)
            if not math.isfinite(v):
                raise GyrosimError(f"thermal model: {name} must be finite")
        if self.self_heating_tau_s <= 0 or self.case_tau_s <= 0:
            raise GyrosimError("thermal model: time constants must be > 0 s")

    def temperature(self, t_s: np.ndarray, ambient: Callable[[np.ndarray], np.ndarray] | None = None) -> np.ndarray:
        """Sensor temperature (°C) at times ``t_s`` (s), power-on at t = 0."""
        t = np.asarray(t_s, dtype=float)
        amb = np.full_like(t, self.ambient_c) if ambient is None else np.asarray(ambient(t), dtype=float)
        target = amb + self.self_heating_c * (1.0 - np.exp(-(t - t[0]) / self.self_heating_tau_s))
        dt = float(np.median(np.diff(t)))
        a = math.exp(-dt / self.case_tau_s)
        return sp_signal.lfilter([1 - a], [1, -a], target, zi=[a * amb[0]])[0]

    def to_dict(self) -> dict[str, Any]:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}
