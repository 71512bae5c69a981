"""Every identified noise parameter in the units users need.

Conventions (stated in every output):

* **continuous** (what Kalibr's ``imu.yaml`` wants): the white-noise density N with two-sided PSD
  N² — Kalibr's ``*_noise_density`` σ_g, rad/s/√Hz or m/s²/√Hz, discrete σ_d = N/√Δt — and the
  bias random walk K, two-sided PSD of the bias derivative K² — Kalibr's ``*_random_walk`` σ_bg,
  rad/s²/√Hz or m/s³/√Hz, discrete σ_bd = K√Δt (Kalibr wiki "IMU Noise Model"; IEEE Std 952 N, K).
  A **one-sided** density (datasheets often quote it) is √2 times the two-sided one.
* **discrete**: the standard deviation of the term per sample at the recording's rate.
* **datasheet**: °/√h, °/h, °/h/√h, arcsec (gyro); µg/√Hz, µg, µg/√h, m/s (accelerometer).

Each noise term's conversions live on its effect class (``Effect.noise_units``, ``noise_unit``);
this module looks the class up by kind.
"""

from __future__ import annotations

from gyrosim.effects import EFFECTS

__all__ = ["representations", "si_unit", "datasheet_unit", "CONVENTION"]

CONVENTION = ("continuous values are two-sided: white-noise PSD N² (Kalibr noise_density = N, per-sample σ = N·√f_s), "
              "bias random-walk PSD K² (Kalibr random_walk = K, per-sample σ = K/√f_s); a one-sided density is √2·N")


def representations(kind: str, field: str, value: float, rate_hz: float, triad: str) -> dict[str, float]:
    """{unit label: value} for one parameter (SI ``value``); gyro units for ``triad == 'gyro'``."""
    cls = EFFECTS.get(kind)
    return cls.noise_units(field, value, rate_hz, triad) if cls is not None else {"si": value}


def si_unit(kind: str, field: str, triad: str) -> str:
    """SI unit of a noise parameter (``"SI"`` when the term states none for ``triad``)."""
    cls = EFFECTS.get(kind)
    return cls.noise_unit(field, triad) if cls is not None else ("s" if field == "tau_s" else "SI")


def datasheet_unit(kind: str, field: str, triad: str) -> str:
    """The datasheet unit a summary shows a noise parameter in (a key of :func:`representations`)."""
    return EFFECTS[kind].noise_unit(field, triad, datasheet=True)
