"""Attitude error definitions: BROAD's, and the campaign's scores built on them.

BROAD (Laidig, Caruso, Cereatti, Seel, "BROAD — A Benchmark for Robust Inertial Orientation
Estimation", Data 6(7):72, 2021, §4 and its example_code/broad_utils.py) defines the error in the
**earth frame**: with q̂ the estimate and q the reference, both body → ENU,

    q_e = q̂ ⊗ q*                        (the rotation that takes the true attitude to the estimate)
    total       = 2 arccos |w_e|
    heading     = 2 arctan |z_e / w_e|    (the part about the vertical)
    inclination = 2 arccos √(w_e² + z_e²) (the rest: the tilt error)

and scores their RMS over the trial's ``movement`` samples (samples without reference skipped).
The campaign uses the same decomposition: tilt error = inclination; the heading error signed,
ψ_e = 2 atan2(z_e, w_e).  A 6-axis estimate has no absolute heading, so its heading offset is
removed (the circular mean of ψ_e over an alignment window) and what is scored is the heading
*drift*: the RMS of ψ_e after the offset and its least-squares slope (°/min).  A 9-axis estimate
is scored on its absolute heading.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .rotations import quat_conjugate, quat_multiply

__all__ = ["error_quat_earth", "total_error_rad", "heading_error_rad", "inclination_error_rad", "broad_rmse_deg",
           "remove_heading_offset", "convergence_time_s", "SessionScore", "score_session"]


def error_quat_earth(q_est: np.ndarray, q_ref: np.ndarray) -> np.ndarray:
    """q_e = q̂ ⊗ q* for (N, 4) (w, x, y, z) body → ENU quaternions (both normalised first)."""
    q_est = np.asarray(q_est, float) / np.linalg.norm(q_est, axis=-1, keepdims=True)
    q_ref = np.asarray(q_ref, float) / np.linalg.norm(q_ref, axis=-1, keepdims=True)
    return quat_multiply(q_est, quat_conjugate(q_ref))


def total_error_rad(q_e: np.ndarray) -> np.ndarray:
    """BROAD's total error 2 arccos|w_e| (rad, in [0, π]) of the error quaternions ``q_e`` (…, 4)."""
    return 2.0 * np.arccos(np.clip(np.abs(q_e[..., 0]), 0.0, 1.0))


def heading_error_rad(q_e: np.ndarray, signed: bool = False) -> np.ndarray:
    """BROAD's heading error 2 arctan|z/w| (rad, in [0, π]); ``signed``: 2 atan2(z, w) wrapped to (−π, π]."""
    if not signed:
        with np.errstate(divide="ignore", invalid="ignore"):
            return 2.0 * np.arctan(np.abs(q_e[..., 3] / q_e[..., 0]))
    s = np.where(q_e[..., 0] < 0, -1.0, 1.0)  # q and −q are one rotation
    return 2.0 * np.arctan2(s * q_e[..., 3], s * q_e[..., 0])


def inclination_error_rad(q_e: np.ndarray) -> np.ndarray:
    """BROAD's inclination (tilt) error 2 arccos √(w_e² + z_e²) (rad, in [0, π]) of the error
    quaternions ``q_e`` (…, 4): the part of the error that is not about the vertical."""
    return 2.0 * np.arccos(np.clip(np.sqrt(q_e[..., 0] ** 2 + q_e[..., 3] ** 2), 0.0, 1.0))


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.nanmean(np.asarray(x) ** 2))) if np.isfinite(x).any() else float("nan")


def broad_rmse_deg(q_est: np.ndarray, q_ref: np.ndarray, movement: np.ndarray) -> dict[str, float]:
    """BROAD's three RMSEs (°) over the movement samples; reference NaNs (occlusions) are skipped
    (BROAD's ``rmse`` is a nanmean)."""
    m = np.asarray(movement).astype(bool)
    q_e = error_quat_earth(q_est[m], q_ref[m])
    return {"total_rmse_deg": math.degrees(_rms(total_error_rad(q_e))),
            "heading_rmse_deg": math.degrees(_rms(heading_error_rad(q_e))),
            "inclination_rmse_deg": math.degrees(_rms(inclination_error_rad(q_e)))}


def remove_heading_offset(q_est: np.ndarray, q_ref: np.ndarray, window: np.ndarray) -> np.ndarray:
    """q̂ turned about the vertical by −ψ₀, ψ₀ the circular mean of the signed heading error over
    ``window`` (a boolean mask): the 6-axis estimate aligned to the truth's heading there."""
    psi = heading_error_rad(error_quat_earth(q_est[window], q_ref[window]), signed=True)
    psi0 = math.atan2(float(np.mean(np.sin(psi))), float(np.mean(np.cos(psi))))
    rot = np.array([math.cos(-psi0 / 2), 0.0, 0.0, math.sin(-psi0 / 2)])
    return quat_multiply(rot, q_est)


def convergence_time_s(t_s: np.ndarray, tilt_rad: np.ndarray, t_start_s: float, threshold_rad: float,
                       hold_s: float = 2.0) -> float:
    """Seconds from ``t_start_s`` until the tilt error falls below ``threshold_rad`` and stays below
    for ``hold_s``; ``inf`` if it never does before the end."""
    after = t_s >= t_start_s
    t, e = t_s[after], tilt_rad[after]
    if t.size == 0:
        return float("inf")
    above = e > threshold_rad
    if not above.any():
        return 0.0
    # the last sample above the threshold; converged if the remaining record below it lasts hold_s
    dt = float(np.median(np.diff(t_s))) if t_s.size > 1 else 0.0
    idx = np.flatnonzero(above)
    # scan candidate re-entries in order: the first below-run of at least hold_s
    below_start = np.flatnonzero(np.diff(above.astype(np.int8)) == -1) + 1
    if not above[0]:
        below_start = np.concatenate([[0], below_start])
    for s in below_start:
        nxt = idx[idx > s]
        end_t = t[nxt[0]] if nxt.size else t[-1] + dt
        if end_t - t[s] >= hold_s - 1e-9:
            return float(t[s] - t_start_s)
    return float("inf")


@dataclass(frozen=True)
class SessionScore:
    """One estimate of one session against the truth (° and s; NaN where not applicable).

    ``tilt_rms_deg``, ``heading_rms_deg``: RMS over the scored window (after the settle time,
    before the disturbance); 6-axis heading after removing the offset of the alignment window.
    ``heading_drift_deg_min``: least-squares slope of the signed heading error over the window.
    ``tilt_peak_after_disturbance_deg``: the largest tilt error the disturbance caused;
    ``convergence_s``: from the end of the disturbance until the tilt error is back below
    max(2°, 2 × its RMS over the 5 s before the disturbance) and stays there for 2 s (inf: never,
    before the record ends).
    """

    tilt_rms_deg: float
    heading_rms_deg: float
    heading_drift_deg_min: float
    tilt_max_deg: float
    tilt_peak_after_disturbance_deg: float
    convergence_s: float


def score_session(t_s: np.ndarray, q_est: np.ndarray, q_true: np.ndarray, *, magnetometer: bool, settle_s: float,
                  align_s: float, disturbance_start_s: float | None, disturbance_end_s: float | None) -> SessionScore:
    """Scores of one estimate (see :class:`SessionScore`).  Windows: alignment [t₀ + settle,
    t₀ + settle + align) for the 6-axis heading offset; scored [t₀ + settle, disturbance start)."""
    t0 = float(t_s[0])
    end = disturbance_start_s if disturbance_start_s is not None else float(t_s[-1]) + 1.0
    win = (t_s >= t0 + settle_s) & (t_s < end)
    if not magnetometer:
        align = (t_s >= t0 + settle_s) & (t_s < t0 + settle_s + align_s)
        q_est = remove_heading_offset(q_est, q_true, align)
    q_e = error_quat_earth(q_est, q_true)
    tilt = inclination_error_rad(q_e)
    psi = np.unwrap(heading_error_rad(q_e, signed=True)[win])
    tw = t_s[win]
    slope = float(np.polyfit(tw - tw.mean(), psi, 1)[0]) if tw.size > 2 else float("nan")
    tilt_rms = _rms(tilt[win])
    peak = conv = float("nan")
    if disturbance_start_s is not None and disturbance_end_s is not None:
        after = t_s >= disturbance_start_s
        peak = math.degrees(float(np.max(tilt[after]))) if after.any() else float("nan")
        before = (t_s >= disturbance_start_s - 5.0) & (t_s < disturbance_start_s)
        level = _rms(tilt[before]) if before.any() else tilt_rms
        conv = convergence_time_s(t_s, tilt, disturbance_end_s, max(math.radians(2.0), 2.0 * level))
    return SessionScore(tilt_rms_deg=math.degrees(tilt_rms), heading_rms_deg=math.degrees(_rms(psi)),
                        heading_drift_deg_min=math.degrees(slope) * 60.0,
                        tilt_max_deg=math.degrees(float(np.max(tilt[win]))) if win.any() else float("nan"),
                        tilt_peak_after_disturbance_deg=peak, convergence_s=conv)
