"""Input checks of a magnetometer channel: its unit, saturated samples, and attitude coverage.

* **Unit.**  The Earth's field is 22–67 µT everywhere (WMM); a magnetometer's ellipsoid radius —
  the field magnitude in the sensor's scale — is therefore 10–150 µT even with ±50 % scale
  errors and a building's own field.  A radius of 0.1–1.5 is the field in gauss (1 G = 100 µT),
  100–1500 is milligauss, 10 000–150 000 nanotesla: such a channel declared as µT is refused
  with the unit to pass, never rescaled silently.  The median |m| is checked first (it contains the
  hard iron, so only gauss and nT are told apart there), then the radius of a sphere fit.
* **Saturation.**  Samples at the range the user passes (``range_ut``, ``calib mag --range-ut``:
  the datasheet's full scale) or, without one, runs of ≥ 3 equal samples at a channel's extreme
  where that extreme is beyond 200 µT (no working compass reads that much from the Earth and its
  board; common rails are 400 µT–4.9 mT): excluded, counted.  Nothing is read from a simulated
  file's stored sensor model (an estimator sees what a user's file carries): a rail below 200 µT is
  found only when passed.
* **Coverage.**  :func:`calib.mag.gravity.direction_coverage` of the field samples (1 = the field
  seen evenly from every direction, 0 = in one plane only): a soft-iron fit needs the field to
  vary along all three body axes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gyrosim.errors import RecordingError
from gyrosim.recording import Recording
from gyrosim.units import to_si

__all__ = ["MagInput", "prepare_magnetometer", "detect_unit", "EARTH_FIELD_RANGE_UT", "PLAUSIBLE_RADIUS_UT",
           "rotations_to_add", "check_unit", "unit_from_median"]

EARTH_FIELD_RANGE_UT = (22.0, 67.0)  # WMM: weakest (South Atlantic anomaly) to strongest (poles)
PLAUSIBLE_RADIUS_UT = (10.0, 150.0)
_OTHER_UNITS = (("gauss", 0.01), ("mgauss", 10.0), ("nT", 1000.0))  # what a µT-sized field reads in them
_AXES = ("x", "y", "z")


@dataclass(frozen=True)
class MagInput:
    """The magnetometer channel ready for fitting: µT, body frame, with the masks the checks found."""

    mag_ut: np.ndarray
    valid: np.ndarray  # finite and not saturated
    saturated: np.ndarray
    warnings: tuple[str, ...]

    @property
    def saturated_samples(self) -> int:
        return int(self.saturated.sum())


def detect_unit(radius: float, *, from_radius: bool) -> str | None:
    """The unit a field of this magnitude is in, if not µT (None when µT is plausible)."""
    lo, hi = PLAUSIBLE_RADIUS_UT
    if lo <= radius <= hi:
        return None
    for unit, factor in _OTHER_UNITS:
        if not from_radius and unit == "mgauss":
            continue  # the median |m| includes the hard iron: 100–1500 can be µT
        if lo * factor <= radius <= hi * factor:
            return unit
    return "unknown"


def _rail_runs(x: np.ndarray, threshold_ut: float = 200.0, run: int = 3) -> np.ndarray:
    bad = np.zeros(x.shape[0], dtype=bool)
    for i in range(3):
        c = x[:, i]
        peak = float(np.max(np.abs(c)))
        if peak < threshold_ut:
            continue
        at = np.abs(c) >= peak * (1 - 1e-12)
        if at.sum() >= run:
            bad |= at
    return bad


def prepare_magnetometer(rec: Recording, *, unit: str = "uT", range_ut: float | None = None) -> MagInput:
    """The checks of the module docstring; raises :class:`RecordingError` naming what is wrong."""
    if rec.mag_ut is None:
        raise RecordingError("the recording has no magnetometer channel (/mag, or mag_x,mag_y,mag_z columns); "
                             "a 6-axis recording cannot be magnetically calibrated")
    scale = to_si(1.0, unit, "magnetic_field")
    m = np.asarray(rec.mag_ut, dtype=float) * scale
    unit_from_median(m, unit)  # before the range: a field in nT sits beyond every µT rail
    rail = range_ut
    if rail is not None:
        sat = np.any(np.abs(m) >= rail * (1 - 1e-9), axis=1)
    else:
        sat = _rail_runs(m)
    valid = ~sat
    warnings = []
    if sat.any():
        where = f"±{rail:g} µT" if rail is not None else "a channel's extreme (a flat top beyond 200 µT)"
        warnings.append(f"saturated: {int(sat.sum())} of {sat.size} samples sit at {where} and are excluded")
    if valid.sum() < 50:
        raise RecordingError(f"only {int(valid.sum())} unsaturated magnetometer samples: too few to calibrate")
    return MagInput(m, valid, sat, tuple(warnings))


def _refuse(value: float, what: str, declared: str, unit: str) -> None:
    if unit == "unknown":
        raise RecordingError(
            f"the magnetometer's {what} is {value:.4g} in the declared unit ({declared}), which is not the Earth's "
            f"field (22–67 µT) in µT, G, mG or nT: check the channel, or a strong permanent field near the sensor")
    raise RecordingError(
        f"the magnetometer's {what} is {value:.4g} {declared}, but the Earth's field is 22–67 µT: the channel is "
        f"in {unit}, not {declared}; pass --mag-unit {unit} (mag_unit='{unit}')")


def unit_from_median(m: np.ndarray, declared: str) -> None:
    """First check, before any fit: a median |m| that can only be the Earth's field in gauss
    (< 1.5, even with a hard iron of that size) or in nT (> 10 000) is refused.  Between 1.5 and
    10 it may be gauss plus a hard iron; milligauss cannot be told from µT plus a hard iron at all:
    the sphere radius decides those (:func:`check_unit`)."""
    value = float(np.median(np.linalg.norm(m, axis=1)))
    lo, hi = PLAUSIBLE_RADIUS_UT
    if value < lo * 0.15:
        _refuse(value, "median |m|", declared, "gauss" if value >= lo * 0.01 else "unknown")
    if value > hi * 100:
        _refuse(value, "median |m|", declared, "nT" if value <= hi * 1000 else "unknown")


def check_unit(m: np.ndarray, radius: float, declared: str) -> None:
    """Second check, on the radius of a sphere fit (the field magnitude without the hard iron)."""
    unit = detect_unit(radius, from_radius=True)
    if unit is not None:
        _refuse(radius, "sphere radius (the field magnitude)", declared, unit)


def rotations_to_add(weak_axis_body: np.ndarray) -> str:
    """Plain advice from the direction (body frame) along which the field never varied."""
    a = np.abs(np.asarray(weak_axis_body, dtype=float))
    k = int(np.argmax(a))
    others = [_AXES[i] for i in range(3) if i != k]
    return (f"the field was never seen along the body ±{_AXES[k]} axis (weakest direction "
            f"{np.round(weak_axis_body, 2).tolist()}): add rotations about the body {others[0]} and {others[1]} axes "
            f"(tip the board onto its sides and upside down) so that ±{_AXES[k]} points along and against the field")


