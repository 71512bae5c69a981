"""The measured recordings' magnetometers (``../shared/data``): what calibration does to them.

For every recording with a magnetometer (:func:`gyrosim.loaders.available_datasets`): the
calibration's status, the spread (standard deviation) of the field magnitude before and after,
and — where there is an optical reference (BROAD) — the compass heading error against it before
and after, computed with the optical tilt (so that only the magnetometer is judged) on the
samples BROAD marks as movement, after removing the constant offset between the optical frame's
arbitrary yaw and magnetic north.  BROAD's 34 (a magnet attached for part of the trial) is also
calibrated on its attached stretch alone, where the magnet is a hard iron like any other.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from gyrosim.errors import GyrosimError
from gyrosim.loaders import available_datasets, load_dataset
from gyrosim.recording import Recording

from calib.mag.calibrate import calibrate_magnetometer
from calib.mag.heading import compass_quaternion, heading_error_rad, up_from_quat, wrap_pi
from calib.mag.result import MagCalibration

__all__ = ["MeasuredRow", "measured_rows", "measured_table", "optical_heading_errors"]


@dataclass(frozen=True)
class MeasuredRow:
    """One row of the measured recordings' table: a data set and stretch, the calibration's status and
    samples (used, disturbed), the spread of |B| (µT) and the heading RMS against the optical attitude
    (°), each before and after the calibration."""

    dataset: str
    window: str
    status: str
    used: int
    disturbed: int
    spread_before_ut: float
    spread_after_ut: float
    heading_before_deg: float
    heading_after_deg: float
    notes: str


def optical_heading_errors(rec: Recording, field_body_ut: np.ndarray, mask: np.ndarray) -> float:
    """RMS (°) of the compass heading error against the optical attitude on ``mask`` (constant
    offset removed), tilt from the optical attitude; NaN without an optical reference."""
    t = rec.truth
    if t is None or t.quat_nb is None:
        return float("nan")
    q = np.asarray(t.quat_nb)
    ok = mask & np.all(np.isfinite(q), axis=1)
    if "movement" in t.extra:
        ok &= t.extra["movement"] > 0.5
    if ok.sum() < 10:
        return float("nan")
    e = heading_error_rad(compass_quaternion(up_from_quat(q[ok]), field_body_ut[ok]), q[ok])
    e = wrap_pi(e - math.atan2(float(np.mean(np.sin(e))), float(np.mean(np.cos(e)))))
    return math.degrees(math.sqrt(float(np.mean(e**2))))


def _row(name: str, rec: Recording, res: MagCalibration, window: np.ndarray, label: str, notes: str) -> MeasuredRow:
    m = np.asarray(rec.mag_ut, dtype=float)
    b = res.compensate(m, rec.t_s)
    dist = np.zeros(rec.n, dtype=bool)
    for d in res.disturbances:
        if d.kind == "attached":  # calibrated as a regime of its own: judged, not left out
            continue
        dist |= (rec.t_s >= d.t_start_s) & (rec.t_s <= d.t_end_s)
    judge = window & ~dist
    return MeasuredRow(name, label, res.status, res.samples.get("used", 0), res.samples.get("disturbed", 0),
                       float(np.std(np.linalg.norm(m[judge], axis=1))), float(np.std(np.linalg.norm(b[judge], axis=1))),
                       optical_heading_errors(rec, m, judge), optical_heading_errors(rec, b, judge), notes)


def _optical_position(rec: Recording) -> np.ndarray | None:
    t = rec.truth
    return None if t is None or t.position_nav_m is None else np.asarray(t.position_nav_m, dtype=float)


def measured_rows(method: str = "ellipsoid") -> list[MeasuredRow]:
    """Calibrate every available measured recording with a magnetometer by ``method`` and judge it (module
    docstring): one row per recording (a refused one included), plus one for the disturbed stretches of a
    stationary recording and one per attached regime (a magnet on the board)."""
    rows = []
    for name in available_datasets():
        rec = load_dataset(name)
        if rec.mag_ut is None:
            continue
        everything = np.ones(rec.n, dtype=bool)
        try:
            # the optical position labels the disturbances (the fit reads only the samples)
            res = calibrate_magnetometer(rec, method, position_nav_m=_optical_position(rec))
        except GyrosimError as exc:
            rows.append(MeasuredRow(name, "all", "refused", 0, 0, float("nan"), float("nan"), float("nan"),
                                    float("nan"), str(exc)[:120]))
            continue
        notes = "; ".join(w.split(":")[0] for w in res.warnings)
        rows.append(_row(name, rec, res, everything, "all", notes))
        if any(d.kind != "attached" for d in res.disturbances) and "stationary" in name:
            # the disturbed stretches themselves: a field that depends on where the board is cannot be
            # calibrated away (the row's "after" keeps the calibration of the undisturbed samples)
            win = np.zeros(rec.n, dtype=bool)
            for d in res.disturbances:
                if d.kind != "attached":
                    win |= (rec.t_s >= d.t_start_s) & (rec.t_s <= d.t_end_s)
            rows.append(
                _row(
                    name,
                    rec,
                    replace(res, disturbances=()),
                    win,
                    " + ".join(f"{d.t_start_s:.0f}–{d.t_end_s:.0f} s" for d in res.disturbances if d.kind != "attached")
                    + " (disturbed)",
                    "reported as a local disturbance, not calibrated",
                )
            )
        for r in res.regimes:
            if r.kind != "attached":
                continue
            # the attached magnet turns with the board: a hard iron of its own on its stretch
            win = (rec.t_s >= r.start_s) & (rec.t_s <= r.end_s)
            rows.append(_row(name, rec, res, win, f"{r.start_s:.0f}–{r.end_s:.0f} s (attached regime)",
                             f"calibrated as its own hard iron, status {r.status}"))
    return rows


def measured_table(method: str = "ellipsoid") -> str:
    """:func:`measured_rows` as a Markdown table."""
    rows = measured_rows(method)
    out = ["| recording | stretch | status | samples used / disturbed | std |B| µT before → after | "
           "heading RMS vs optical ° before → after | notes |", "|---|---|---|---|---|---|---|"]
    for r in rows:
        out.append(f"| {r.dataset} | {r.window} | {r.status} | {r.used} / {r.disturbed} | "
                   f"{r.spread_before_ut:.2f} → {r.spread_after_ut:.2f} | {r.heading_before_deg:.2f} → "
                   f"{r.heading_after_deg:.2f} | {r.notes} |")
    return "\n".join(out)
