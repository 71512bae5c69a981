"""Degenerate data, named as such: a dead (constant) axis, a constant sensor, raw integer counts.

* constant: an axis whose every sample is the same number (peak-to-peak 0) is a dead axis or an
  unconnected channel — a live MEMS axis always shows noise or quantisation steps;
* integer counts: values that are all whole numbers (in the unit the file was read in) and larger
  than any physical reading in that unit (gyro > 35 rad/s or > 2000 °/s; accelerometer median
  magnitude > 20 m/s² or > 20 g) are raw ADC counts: they need the datasheet's sensitivity (LSB per
  unit) before anything can be calibrated.  The message names the usual sensitivity that fits.
"""

from __future__ import annotations

import numpy as np

from gyrosim.recording import Recording
from gyrosim.units import to_si

from calib.inputs.errors import DegenerateError

__all__ = ["degenerate_problems", "check_degenerate"]

_ACC_LSB_PER_G = (16384, 8192, 4096, 2048, 1024, 1000, 512, 256)


def _raw(x: np.ndarray, unit: str | None, quantity: str) -> np.ndarray:
    try:
        f = float(to_si(1.0, unit, quantity)) if unit else 1.0
    except Exception:  # noqa: BLE001 - an unknown unit was refused earlier; judge the values as given
        f = 1.0
    return np.asarray(x, dtype=float) / f


def _is_integer(x: np.ndarray) -> bool:
    r = np.round(x)
    return bool(np.all(np.abs(x - r) <= 1e-9 * np.maximum(1.0, np.abs(r))))


def degenerate_problems(rec: Recording, sensors: tuple[str, ...] = ("gyro", "acc")) -> list[str]:
    """Messages for each degenerate channel of the triads in ``sensors`` (empty: none)."""
    out = []
    n = rec.n
    for name, x in (("gyro", rec.gyro_rad_s), ("acc", rec.acc_m_s2)):
        if name not in sensors:
            continue
        xt = np.ascontiguousarray(np.asarray(x, dtype=float).T)  # channel-major: column passes are slow
        ptp = xt.max(axis=1) - xt.min(axis=1)
        dead = [f"{name}_{a}" for a, p in zip("xyz", ptp) if p == 0]
        if len(dead) == 3:
            vals = ", ".join(f"{v:.6g}" for v in x[0])
            what = "gyroscope" if name == "gyro" else "accelerometer"
            out.append(
                f"the {what} is constant: every one of the {n} samples reads ({vals}); that is a dead sensor, an "
                "unconnected channel or the wrong columns, not a measurement"
            )
        elif dead:
            values = ", ".join(f"{x[0, 'xyz'.index(d[-1])]:.6g}" for d in dead)
            out.append(f"{', '.join(dead)} {'is' if len(dead) == 1 else 'are'} constant over all {n} samples "
                       f"({values}): a dead axis or an unconnected channel; every axis must measure")
    gyro_unit = rec.meta.get("gyro_unit", "rad/s")
    acc_unit = rec.meta.get("acc_unit", "m/s^2")
    g_raw = _raw(rec.gyro_rad_s, gyro_unit, "rate")
    g_peak = float(np.max(np.abs(g_raw)))
    g_limit = 35.0 if float(to_si(1.0, gyro_unit, "rate")) > 0.5 else 2000.0
    if "gyro" in sensors and g_peak > g_limit and _is_integer(g_raw) and np.unique(g_raw[:, 0]).size > 3:
        out.append(f"the gyro values are whole numbers up to {g_peak:.0f}, beyond any rate in {gyro_unit}: raw ADC "
                   "counts "
                   "without a scale; multiply by the datasheet's sensitivity (e.g. 1/131 °/s per count at ±250 °/s for "
                   "an MPU-class part) and pass --gyro-unit deg/s")
    a_raw = _raw(rec.acc_m_s2, acc_unit, "acceleration")
    a_med = float(np.median(np.sqrt(np.einsum("ij,ij->i", a_raw, a_raw))))
    if "acc" in sensors and a_med > 20.0 and _is_integer(a_raw):
        lsb = min(_ACC_LSB_PER_G, key=lambda v: abs(np.log(a_med / v)))
        guess = f" (≈ {lsb} counts per g)" if abs(a_med / lsb - 1) < 0.15 else ""
        out.append(f"the accelerometer values are whole numbers with a median magnitude of {a_med:.0f}{guess}: raw ADC "
                   "counts without a scale; divide by the counts per g from the datasheet and pass --acc-unit g")
    return out


def check_degenerate(rec: Recording) -> None:
    """Raise :class:`DegenerateError` with every degenerate finding."""
    problems = degenerate_problems(rec)
    if problems:
        raise DegenerateError("; ".join(problems))
