"""Datasheet units → SI, exactly, with the accepted spellings listed in every error.

Conventions (stated once, used everywhere):

* g₀ = 9.80665 m/s² (standard gravity) for every "g", "mg", "µg".
* Noise densities: a gyro "°/s/√Hz" figure is read as the IEEE Std 952 angle-random-walk
  coefficient N, i.e. the square root of the *two-sided* PSD: the Allan deviation is N/√τ and a
  white sequence at f_s has per-sample σ = N √f_s.  Hence 1 °/s/√Hz = 1 °/√s = 60 °/√h, the
  conversion every MEMS datasheet and application note uses (likewise 1 m/s²/√Hz = 60 m/s/√h).
  A datasheet that quotes a *one-sided* density ND has N = ND/√2: pass
  ``convention = "one-sided"`` to the white-noise effect.
* Rate random walk K: σ_A(τ) = K √(τ/3); 1 °/h/√h = (π/180)/3600/60 rad/s/√s.
* Bias instability B (flicker floor): σ_A = √(2 ln 2 / π) B ≈ 0.664 B (IEEE Std 952 Annex C).
"""

from __future__ import annotations

import math
import re
from typing import Iterable

from .errors import GyrosimError

__all__ = ["G0", "DEG", "RAD2DEG", "HOUR", "RAD_S_TO_DEG_H", "to_si", "accepted_units", "QUANTITIES"]

G0 = 9.80665
DEG = math.pi / 180.0  # one degree in rad: x_deg * DEG is rad
RAD2DEG = 180.0 / math.pi  # one rad in degrees: x_rad * RAD2DEG is °
HOUR = 3600.0  # s
RAD_S_TO_DEG_H = RAD2DEG * HOUR  # x_rad_s * RAD_S_TO_DEG_H is °/h

# quantity -> {normalised unit spelling: factor to SI}
QUANTITIES: dict[str, dict[str, float]] = {
    "rate": {"rad/s": 1.0, "deg/s": DEG, "deg/h": DEG / HOUR, "mdeg/s": 1e-3 * DEG, "rad/h": 1 / HOUR},
    "acceleration": {"m/s^2": 1.0, "g": G0, "mg": 1e-3 * G0, "ug": 1e-6 * G0},
    "rate_density": {
        "rad/s/sqrt(hz)": 1.0,
        "rad/sqrt(s)": 1.0,
        "deg/s/sqrt(hz)": DEG,
        "deg/sqrt(s)": DEG,
        "deg/sqrt(h)": DEG / 60.0,
        "mdeg/s/sqrt(hz)": 1e-3 * DEG,
        "deg/h/sqrt(hz)": DEG / HOUR,
    },
    "acceleration_density": {
        "m/s^2/sqrt(hz)": 1.0,
        "m/s/sqrt(s)": 1.0,
        "m/s/sqrt(h)": 1 / 60.0,
        "g/sqrt(hz)": G0,
        "mg/sqrt(hz)": 1e-3 * G0,
        "ug/sqrt(hz)": 1e-6 * G0,
    },
    "rate_random_walk": {
        "rad/s/sqrt(s)": 1.0,
        "rad/s^2/sqrt(hz)": 1.0,
        "deg/s/sqrt(s)": DEG,
        "deg/s/sqrt(h)": DEG / 60.0,
        "deg/h/sqrt(h)": DEG / HOUR / 60.0,
        "deg/h^2/sqrt(hz)": DEG / HOUR**2,
    },
    "acceleration_random_walk": {
        "m/s^2/sqrt(s)": 1.0,
        "m/s^3/sqrt(hz)": 1.0,
        "m/s/h/sqrt(h)": 1 / HOUR / 60.0,
        "ug/sqrt(s)": 1e-6 * G0,
        "mg/sqrt(h)": 1e-3 * G0 / 60.0,
        "ug/sqrt(h)": 1e-6 * G0 / 60.0,
    },
    # IEEE 952 quantization noise Q: the integrated signal's (angle, velocity) white quantization error
    "velocity": {"m/s": 1.0, "mm/s": 1e-3, "ug*s": 1e-6 * G0},
    # a rate ramp (IEEE 952 R, σ_A = Rτ/√2): the rate's deterministic drift per second
    "rate_ramp": {"rad/s^2": 1.0, "deg/s^2": DEG, "deg/h^2": DEG / HOUR**2, "deg/h/h": DEG / HOUR**2},
    "acceleration_ramp": {"m/s^3": 1.0, "mg/s": 1e-3 * G0, "ug/s": 1e-6 * G0, "ug/h": 1e-6 * G0 / HOUR},
    "fraction": {"1": 1.0, "%": 1e-2, "ppm": 1e-6},
    "fraction_per_degc": {"1/degc": 1.0, "%/degc": 1e-2, "ppm/degc": 1e-6},
    "rate_per_degc": {"rad/s/degc": 1.0, "deg/s/degc": DEG, "deg/h/degc": DEG / HOUR},
    "acceleration_per_degc": {"m/s^2/degc": 1.0, "mg/degc": 1e-3 * G0, "ug/degc": 1e-6 * G0},
    "rate_per_acceleration": {
        "(rad/s)/(m/s^2)": 1.0,
        "rad/s/(m/s^2)": 1.0,
        "deg/s/g": DEG / G0,
        "deg/h/g": DEG / HOUR / G0,
    },
    "rate_per_tesla": {
        "(rad/s)/ut": 1.0,
        "rad/s/ut": 1.0,
        "deg/h/t": DEG / HOUR * 1e-6,
        "deg/h/g_mag": DEG / HOUR * 1e-2,
        "deg/h/ut": DEG / HOUR,
    },
    "per_rate": {"1/(rad/s)": 1.0, "1/(deg/s)": 1 / DEG},
    "per_acceleration": {"1/(m/s^2)": 1.0, "1/g": 1 / G0},
    "time": {"s": 1.0, "ms": 1e-3, "us": 1e-6},
    "frequency": {"hz": 1.0, "khz": 1e3},
    "angle": {"rad": 1.0, "deg": DEG, "mrad": 1e-3, "arcsec": DEG / 3600},
    "temperature": {"degc": 1.0},
    "rate_per_degc_per_s": {"(rad/s)/(degc/s)": 1.0, "(deg/s)/(degc/s)": DEG},
    "acceleration_per_degc_per_s": {"(m/s^2)/(degc/s)": 1.0, "mg/(degc/s)": 1e-3 * G0},
    # magnetometer quantities are in µT (the Recording's unit), not tesla
    "magnetic_field": {"ut": 1.0, "nt": 1e-3, "mt": 1e3, "t": 1e6, "gauss": 100.0, "mgauss": 0.1, "milligauss": 0.1},
    "magnetic_field_density": {"ut/sqrt(hz)": 1.0, "nt/sqrt(hz)": 1e-3, "mgauss/sqrt(hz)": 0.1},
    "magnetic_field_random_walk": {"ut/sqrt(s)": 1.0, "nt/sqrt(s)": 1e-3, "ut/sqrt(h)": 1 / 60.0},
}


def _normalise(unit: str) -> str:
    u = unit.strip().lower().replace(" ", "")
    for a, b in (("°c", "degc"), ("℃", "degc"), ("°", "deg"), ("√", "sqrt"), ("²", "^2"), ("³", "^3"),
                 ("µ", "u"), ("μ", "u"), ("dps", "deg/s"), ("/hr", "/h"), ("hour", "h"), ("sec", "s"),
                 ("m/s2", "m/s^2"), ("m/s3", "m/s^3")):
        u = u.replace(a, b)
    u = re.sub(r"sqrt\(?(hz|h|s)\)?", lambda m: f"sqrt({m.group(1)})", u)
    return u


def accepted_units(quantity: str) -> list[str]:
    """Unit spellings accepted for ``quantity`` (normalised: deg for °, sqrt for √, u for µ)."""
    return list(QUANTITIES[quantity])


def to_si(value: float | Iterable[float], unit: str, quantity: str) -> float | list[float]:
    """Convert ``value`` given in ``unit`` to SI for ``quantity``.

    Raises GyrosimError naming the accepted units when ``unit`` is not one of them (so deg/s
    given for an acceleration, or a typo, is caught, never silently scaled).
    """
    if quantity not in QUANTITIES:
        raise GyrosimError(f"unknown quantity {quantity!r}; known: {sorted(QUANTITIES)}")
    table = QUANTITIES[quantity]
    key = _normalise(unit)
    if key not in table:
        raise GyrosimError(
            f"unit {unit!r} is not accepted for {quantity.replace('_', ' ')}; use one of: "
            + ", ".join(table)
        )
    f = table[key]
    if isinstance(value, (int, float)):
        return float(value) * f
    return [float(v) * f for v in value]
