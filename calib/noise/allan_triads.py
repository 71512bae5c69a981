"""``calib allan``'s result: the IEEE-952 terms of both triads of a static record, in SI and the usual display
units, what the record does not determine, and whether the temperature drifted during it.

:func:`allan_triads` pools the three axes of each triad (gyro, accelerometer) into one Allan fit
(:func:`calib.noise.allan.fit_noise_terms`) and returns an :class:`AllanResult`:

* per triad, N (white noise density: Kalibr's ``*_noise_density``), B (bias instability) and K (bias random walk:
  Kalibr's ``*_random_walk``), each with its 1σ, or — when the record does not determine it (fitted to 0 or
  within 2σ of 0: too short for K, or a term below the others at every τ) — marked undetermined with a 2σ upper
  bound instead of a σ;
* the temperature: a static record whose temperature changed by more than :data:`TEMPERATURE_DRIFT_C` is flagged,
  with the bias change the temperature explains (least squares of block means on temperature, per axis): a drift
  with temperature reads as bias instability and random walk, so B and K are then upper bounds of the noise.

SI units: N rad/s/√Hz, m/s²/√Hz; B rad/s, m/s²; K rad/s²/√Hz, m/s³/√Hz (Kalibr's units; ``calib export --noise``
reads :meth:`AllanResult.to_dict`'s JSON).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from gyrosim.errors import GyrosimError
from gyrosim.recording import Recording

from calib.noise.allan import TERMS, AllanCurve, NoiseTerms, allan_deviation, fit_noise_terms
from calib.noise.units import datasheet_unit, representations, si_unit

__all__ = ["ALLAN_FORMAT", "TEMPERATURE_DRIFT_C", "TRIAD_KEYS", "TriadAllan", "TemperatureDrift", "AllanResult",
           "allan_triads", "display", "read_kalibr_noise"]

ALLAN_FORMAT = "calib.allan"
# a static record's temperature span (°C, 1st–99th percentile) above which its B and K are flagged: MEMS gyro
# biases move by 0.01–0.1 °/s per °C, hundreds of °/h over a few °C, far above their bias instability
TEMPERATURE_DRIFT_C = 1.0
# the term → (effect kind, field) of the vocabulary, for the units (calib.noise.units)
_KIND = {"arw": ("white_noise", "density"), "bias_instability": ("bias_instability", "value"),
         "rate_random_walk": ("random_walk", "value")}
# the JSON keys of the terms (Kalibr's names for N and K)
TRIAD_KEYS = {"arw": "noise_density", "bias_instability": "bias_instability", "rate_random_walk": "random_walk"}
_SIGNAL = {"gyro": "gyro_rad_s", "accelerometer": "acc_m_s2"}


@dataclass(frozen=True)
class TriadAllan:
    """One triad's Allan curves (x, y, z) and their pooled fit; ``note`` says why a triad was not measured."""

    triad: str
    curves: tuple[AllanCurve, ...]
    terms: NoiseTerms | None
    note: str = ""

    def term_dict(self, term: str, rate_hz: float) -> dict[str, Any]:
        """One term as JSON: value and σ (SI, None when undetermined), determined, 2σ upper bound, units."""
        kind, fld = _KIND[term]
        t = self.terms
        determined = bool(t is not None and t.determined(term))
        value = getattr(t, term) if determined else None
        return {"value": value, "std": getattr(t, f"{term}_std") if determined else None, "determined": determined,
                "upper_2sigma": t.upper_2sigma[TERMS.index(term)] if t is not None else None,
                "unit": si_unit(kind, fld, self.triad),
                "display": (representations(kind, fld, value, rate_hz, self.triad) if determined else None)}


@dataclass(frozen=True)
class TemperatureDrift:
    """The temperature during a static record: span (°C, 1st–99th percentile) and, per triad, the largest bias
    change over that span the temperature explains (SI: rad/s, m/s²), from a least-squares line of block means."""

    span_c: float
    bias_change: dict[str, float] = field(default_factory=dict)

    @property
    def flagged(self) -> bool:
        return self.span_c > TEMPERATURE_DRIFT_C

    def to_dict(self) -> dict[str, Any]:
        return {"span_c": self.span_c, "flagged": self.flagged, "threshold_c": TEMPERATURE_DRIFT_C,
                "bias_change_si": dict(self.bias_change)}


@dataclass(frozen=True)
class AllanResult:
    """Both triads' Allan fits of one static record, its temperature, and the warnings a person should read."""

    duration_s: float
    rate_hz: float
    triads: dict[str, TriadAllan]
    temperature: TemperatureDrift | None
    warnings: tuple[str, ...] = ()

    def kalibr(self) -> dict[str, float | None]:
        """Kalibr's four noise numbers (SI; None where this record does not determine them)."""
        out: dict[str, float | None] = {}
        for triad, prefix in (("gyro", "gyroscope"), ("accelerometer", "accelerometer")):
            tr = self.triads.get(triad)
            for term, key in (("arw", "noise_density"), ("rate_random_walk", "random_walk")):
                ok = tr is not None and tr.terms is not None and tr.terms.determined(term)
                out[f"{prefix}_{key}"] = getattr(tr.terms, term) if ok else None
        return out

    def to_dict(self) -> dict[str, Any]:
        triads = {}
        for name, tr in self.triads.items():
            triads[name] = {"note": tr.note or None, **{TRIAD_KEYS[t]: tr.term_dict(t, self.rate_hz) for t in TERMS}}
        return {"format": ALLAN_FORMAT, "version": 1, "duration_s": self.duration_s, "rate_hz": self.rate_hz,
                "triads": triads, "kalibr": self.kalibr(),
                "temperature": self.temperature.to_dict() if self.temperature is not None else None,
                "warnings": list(self.warnings)}



def allan_triads(rec: Recording, triads: tuple[str, ...] = ("gyro", "accelerometer")) -> AllanResult:
    """The Allan fits of ``triads`` of the static recording ``rec`` (module docstring)."""
    out: dict[str, TriadAllan] = {}
    for triad in triads:
        x = getattr(rec, _SIGNAL[triad])
        if x is None or not np.all(np.ptp(x, axis=0) > 0):
            out[triad] = TriadAllan(triad, (), None, "constant on at least one axis: not measured")
            continue
        curves = tuple(allan_deviation(x[:, i], rec.rate_hz) for i in range(3))
        out[triad] = TriadAllan(triad, curves, fit_noise_terms(list(curves)))
    drift = temperature_drift(rec, triads)
    warnings = []
    if drift is not None and drift.flagged:
        g = drift.bias_change.get("gyro")
        explained = f" (the gyro bias follows it by up to {math.degrees(g) * 3600:.3g} °/h)" if g else ""
        warnings.append(f"the temperature changed by {drift.span_c:.1f} °C during this static record{explained}: "
                        "drift with temperature reads as bias instability and random walk, so B and K are upper "
                        "bounds, not the noise; record at a steady temperature after warm-up, or model the drift "
                        "first (calib temperature)")
    return AllanResult(rec.duration_s, rec.rate_hz, out, drift, tuple(warnings))


def temperature_drift(rec: Recording, triads: tuple[str, ...], blocks: int = 50) -> TemperatureDrift | None:
    """The temperature span of ``rec`` and, per triad, the largest bias change over it that a straight line of
    ``blocks`` block means on temperature explains (None without a temperature channel)."""
    if rec.temp_c is None or not np.all(np.isfinite(rec.temp_c)):
        return None
    lo, hi = np.percentile(rec.temp_c, [1, 99])
    span = float(hi - lo)
    change: dict[str, float] = {}
    n = rec.n // blocks * blocks
    if span > 0 and n >= blocks:
        temp = rec.temp_c[:n].reshape(blocks, -1).mean(axis=1)
        for triad in triads:
            x = getattr(rec, _SIGNAL[triad])
            if x is None:
                continue
            means = x[:n].reshape(blocks, -1, 3).mean(axis=1)
            slope = np.polyfit(temp, means, 1)[0] if np.ptp(temp) > 0 else np.zeros(3)
            change[triad] = float(np.max(np.abs(slope)) * span)
    return TemperatureDrift(span, change)


def display(term: str, triad: str, rate_hz: float) -> tuple[str, float]:
    """(unit, factor from SI) of the datasheet unit ``calib allan`` prints ``term`` of ``triad`` in, e.g. ``°/√h``
    for the gyro's N (:mod:`calib.noise.units`)."""
    kind, fld = _KIND[term]
    unit = datasheet_unit(kind, fld, triad)
    factor = representations(kind, fld, 1.0, rate_hz, triad)[unit]  # every representation is linear in the value
    pretty = unit.replace(" (two-sided)", "").replace("sqrt(", "√").replace(")", "").replace("deg", "°")
    return pretty.replace("ug", "µg"), factor


def read_kalibr_noise(path: str | Path) -> dict[str, float | None]:
    """Kalibr's four noise numbers (SI; None where not determined) from a ``calib allan --json`` file."""
    path = Path(path)
    try:
        d = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise GyrosimError(f"no such noise file: {path}") from None
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise GyrosimError(f"{path} is not a calib allan JSON ({exc}); write one with calib allan REC --json PATH") \
            from None
    if not isinstance(d, Mapping) or d.get("format") != ALLAN_FORMAT or not isinstance(d.get("kalibr"), Mapping):
        raise GyrosimError(f"{path} is not a calib allan JSON; write one with calib allan REC --json PATH")
    return {key: (float(v) if isinstance(v, (int, float)) and math.isfinite(v) and v >= 0 else None)
            for key, v in d["kalibr"].items()}
