"""The unit of the time column, found from the data when the file does not say it.

A time column is read in seconds unless that is implausible.  With Δ the median step and T the
span of the raw values, the reading in unit u ∈ {s, ms, µs, ns} (factor f_u to seconds) gives the
rate 1/(Δ f_u) and the duration T f_u.  In order:

1. a unit given by the user (``--time-unit``) or in the column name (``t_ms``) is used as given;
2. a stated rate (HDF5 attribute ``rate_hz``) that exactly one unit reproduces (±2 %) decides;
3. the units that give a plausible rate for the method (``Requirements.plausible_rate_hz``, e.g.
   0.5 Hz – 100 kHz for hand-held sessions, 0.01 Hz – 100 kHz for static ones) and a plausible
   duration (seconds: at most 30 days; the others: at least 1 s), and whose values are a clock at all
   (at most 4.2e9 s: Unix time in 2100).  One → that unit (a ms column of a
   100 Hz session: 0.1 Hz in s, 100 Hz in ms, 100 kHz over 0.17 s in µs → ms), named in a warning
   unless it is seconds;
4. several → a Unix epoch decides if exactly one unit puts the first value between 2000 and 2100;
   else seconds if the values are not all whole numbers (a float time column in s);
5. otherwise, for a moving record, the motion decides: the one candidate unit under which the gyro's
   integrated rotation agrees with the gravity direction the accelerometer sees
   (:func:`calib.inputs.motion.rotation_consistency`; a 1 kHz millisecond counter read as 1 Hz has no
   calm pairs 3 s apart that agree), named in a warning;
6. otherwise the time base is refused with the rates each unit would give: whole-number time
   steps of 10 are 0.1 Hz in s or 100 Hz in ms, and a still record does not tell which.

Unix epochs (first value between 2000 and 2100 in the chosen unit) are shifted to start at 0 (so
float64 keeps sub-µs resolution) and the origin is kept in ``meta['time_origin_unix_s']``.
"""

from __future__ import annotations

import datetime as _dt
import math
from dataclasses import dataclass

import numpy as np

from calib.inputs.errors import TimeBaseError
from calib.inputs.requirements import Requirements

__all__ = ["TIME_UNITS", "TimeBase", "AmbiguousTimeUnit", "detect_time_unit", "to_seconds", "time_base"]

TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
_SPELLINGS = {"s": "s", "sec": "s", "ms": "ms", "us": "us", "µs": "us", "μs": "us", "ns": "ns", "auto": "auto"}
_UNIT_NAME = {"s": "s", "ms": "ms", "us": "µs", "ns": "ns"}
EPOCH_RANGE_S = (946684800.0, 4102444800.0)  # 2000-01-01 … 2100-01-01 UTC
MAX_DURATION_S = 30 * 86400.0
MAX_CLOCK_S = 4.2e9  # no clock counts more than ~133 years of seconds (Unix time reaches 4.1e9 s in 2100)


class AmbiguousTimeUnit(TimeBaseError):
    """Several units fit the time column; ``candidates`` lists them (the motion may decide)."""

    def __init__(self, candidates: list[str], message: str) -> None:
        super().__init__(message)
        self.candidates = tuple(candidates)


@dataclass(frozen=True)
class TimeBase:
    """How the raw time values become seconds: t_s = (t − origin) · factor."""

    unit: str                      # s, ms, us, ns
    how: str                       # declared | stated rate | seconds | detected
    origin: float                  # raw value subtracted first (0 unless a Unix epoch)
    origin_unix_s: float | None
    warning: str | None

    @property
    def factor(self) -> float:
        return TIME_UNITS[self.unit]


def normalise_time_unit(unit: str | None) -> str | None:
    """'auto'/None → None; a spelling of s, ms, µs, ns → its key; anything else is refused."""
    if unit is None:
        return None
    key = _SPELLINGS.get(unit.strip().lower())
    if key is None:
        raise TimeBaseError(f"time unit {unit!r} is not one of: auto, s, ms, us, ns")
    return None if key == "auto" else key


def _epoch(t0: float, unit: str) -> float | None:
    v = t0 * TIME_UNITS[unit]
    return v if EPOCH_RANGE_S[0] <= v <= EPOCH_RANGE_S[1] else None


def _iso(unix_s: float) -> str:
    return _dt.datetime.fromtimestamp(unix_s, _dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")


def detect_time_unit(t: np.ndarray, req: Requirements, declared: str | None = None,
                     stated_rate_hz: float | None = None, where: str = "the recording") -> TimeBase:
    """Decide the unit of the raw time values ``t`` (strictly increasing) — module docstring."""
    declared = normalise_time_unit(declared)
    t = np.asarray(t, dtype=float)
    step = float(np.median(np.diff(t)))
    span = float(t[-1] - t[0])
    lo, hi = req.plausible_rate_hz
    rate = {u: 1.0 / (step * f) for u, f in TIME_UNITS.items()}
    dur = {u: span * f for u, f in TIME_UNITS.items()}

    def base(unit: str, how: str, warning: str | None = None) -> TimeBase:
        return time_base(t, unit, how, warning)

    if declared:
        return base(declared, "declared")
    if stated_rate_hz and math.isfinite(stated_rate_hz) and stated_rate_hz > 0:
        match = [u for u in TIME_UNITS if abs(rate[u] / stated_rate_hz - 1) < 0.02]
        if len(match) == 1:
            u = match[0]
            return base(u, "stated rate", None if u == "s" else
                        f"time converted from {_UNIT_NAME[u]} to s: the file states {stated_rate_hz:g} Hz and the time "
                        f"steps by {step:g} (pass --time-unit to override)")
    clock = [u for u in TIME_UNITS if max(abs(float(t[0])), abs(float(t[-1]))) * TIME_UNITS[u] <= MAX_CLOCK_S]
    plausible = [u for u in clock if lo <= rate[u] <= hi
                 and (dur[u] <= MAX_DURATION_S if u == "s" else dur[u] >= 1.0)]
    if not plausible:  # a record shorter than a second: the rate alone (its length is judged later)
        plausible = [u for u in clock if lo <= rate[u] <= hi]
    options = ", ".join(f"{_UNIT_NAME[u]} → {rate[u]:.4g} Hz over {dur[u]:.4g} s" for u in TIME_UNITS)
    if len(plausible) > 1:
        epoch = [u for u in plausible if _epoch(float(t[0]), u) is not None]
        whole = bool(np.all(t == np.round(t)))
        if len(epoch) == 1:
            plausible = epoch
        elif "s" in plausible and not whole:
            plausible = ["s"]
        else:
            raise AmbiguousTimeUnit(
                plausible,
                f"{where}: the time column counts whole units (median step {step:g}), and more than one unit gives a "
                f"plausible rate for {req.name}: "
                f"{', '.join(f'{_UNIT_NAME[u]} → {rate[u]:.4g} Hz over {dur[u]:.4g} s' for u in plausible)}; "
                f"pass --time-unit {' or '.join(plausible)}",
            )
    if plausible == ["s"]:
        return base("s", "seconds")
    if len(plausible) == 1:
        u = plausible[0]
        return base(u, "detected",
                    f"time converted from {_UNIT_NAME[u]} to s: read as seconds the median step {step:g} would mean "
                    f"{rate['s']:.3g} Hz over {dur['s']:.4g} s; in {_UNIT_NAME[u]} it is {rate[u]:.4g} Hz over "
                    f"{dur[u]:.4g} s (pass --time-unit to override)")
    raise TimeBaseError(
        f"{where}: no time unit gives a plausible sample rate for {req.name} ({lo:g}–{hi:g} Hz, at least 1 s): median "
        f"step {step:g}, read as {options}; check the time column or pass --time-unit")


def time_base(t: np.ndarray, unit: str, how: str, warning: str | None = None) -> TimeBase:
    """The TimeBase of ``unit`` for the raw values ``t`` (Unix epoch origin detected)."""
    e = _epoch(float(t[0]), unit)
    if e is not None:
        note = f"timestamps are Unix time in {_UNIT_NAME[unit]} (first sample {_iso(e)}); times are counted from it"
        warning = f"{warning}; {note}" if warning else note
    return TimeBase(unit, how, float(t[0]) if e is not None else 0.0, e, warning)


def to_seconds(t: np.ndarray, tb: TimeBase) -> np.ndarray:
    """Raw time values → seconds (origin removed first, so an epoch keeps its resolution)."""
    return (np.asarray(t, dtype=float) - tb.origin) * tb.factor
