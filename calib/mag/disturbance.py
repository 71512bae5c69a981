"""Local magnetic disturbances: stretches where the calibrated field leaves the Earth's.

A calibration explains everything that turns with the board (hard and soft iron).  A field that
changes with where the board *is* — a magnet or a steel object in the room — cannot be
explained: after the fit it shows as a magnitude (and inclination) that wanders away from the
constant values for a while.  Absorbing it would bend the calibration; it is detected, excluded
and reported instead:

* the residuals e₁ = |B_k| − F (µT) and, with a gravity reference, e₂ = I_k − I (°) are reduced
  to a mean and a standard deviation per window of ``window_s`` (a changed hard iron shifts the
  mean; near a dipole a turning board sees |B| rise and fall, which only the spread shows);
* a window is disturbed when either leaves the session's typical value (median over windows) by
  ``k`` robust standard deviations (median absolute deviation × 1.4826; the medians make the
  threshold immune to the disturbance itself) and by at least ``floor_ut`` / ``floor_deg`` (what
  model error and tremor leave in an undisturbed session);
* disturbed windows at most 3 windows apart merge into one :class:`Disturbance`, widened by one
  window on each side (the field near an object changes smoothly; its tails bend a fit too).

The caller refits without the disturbed samples and runs the detector again until the set stops
changing (:func:`calib.mag.calibrate.calibrate_magnetometer`).
"""

from __future__ import annotations

import numpy as np

from calib.mag.result import Disturbance

__all__ = ["find_disturbances"]

BRIDGE = 3  # quiet windows between two disturbed ones that are taken as disturbed too


def _window_stats(x: np.ndarray, valid: np.ndarray, w: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per window of w samples: mean and standard deviation of x over the valid samples, and their
    count.  Both: a changed hard iron shifts the mean; a dipole's field adds to |B| in some
    attitudes and subtracts in others, so while the board turns near it the mean can stay near
    zero and only the spread shows it."""
    nwin = int(np.ceil(x.size / w))
    pad = nwin * w - x.size
    xs = np.concatenate([np.where(valid, x, 0.0), np.zeros(pad)]).reshape(nwin, w)
    cnt = np.concatenate([valid.astype(float), np.zeros(pad)]).reshape(nwin, w).sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = xs.sum(axis=1) / cnt
        var = (xs**2).sum(axis=1) / cnt - mean**2
    return mean, np.sqrt(np.maximum(var, 0.0)), cnt


def _outliers(stat: np.ndarray, k: float, floor: float, two_sided: bool) -> np.ndarray:
    ok = np.isfinite(stat)
    if ok.sum() < 3:
        return np.zeros(stat.size, dtype=bool)
    dev = stat - np.nanmedian(stat)
    thr = max(k * _robust_sigma(stat), floor)
    return ok & ((np.abs(dev) if two_sided else dev) > thr)


def _robust_sigma(v: np.ndarray) -> float:
    v = v[np.isfinite(v)]
    if v.size < 3:
        return float("inf")
    return float(1.4826 * np.median(np.abs(v - np.median(v))))


def find_disturbances(t_s: np.ndarray, field_dev_ut: np.ndarray, incl_dev_deg: np.ndarray | None,
                      valid: np.ndarray, *, window_s: float = 1.0, k: float = 6.0, floor_ut: float = 0.8,
                      floor_deg: float = 1.5, position_nav_m: np.ndarray | None = None
                      ) -> tuple[np.ndarray, tuple[Disturbance, ...]]:
    """(per-sample disturbed mask, disturbances) from the residuals of a fit (module docstring).

    ``field_dev_ut`` (N,) |B| − F in µT; ``incl_dev_deg`` (N,) inclination − I in ° (NaN where the
    board was not quasi-static) or None; ``valid`` (N,) samples that may be judged."""
    n = t_s.size
    rate = (n - 1) / max(t_s[-1] - t_s[0], 1e-12)
    w = max(5, int(round(window_s * rate)))
    m1, s1, c1 = _window_stats(field_dev_ut, valid & np.isfinite(field_dev_ut), w)
    bad = _outliers(m1, k, floor_ut, True) | _outliers(s1, k, floor_ut, False)
    if incl_dev_deg is not None:
        ok2 = valid & np.isfinite(incl_dev_deg)
        m2, s2, c2 = _window_stats(np.nan_to_num(incl_dev_deg), ok2, w)
        few = c2 < w / 4  # too few quasi-static samples in the window to judge the inclination
        m2[few] = s2[few] = np.nan
        bad |= _outliers(m2, k, floor_deg, True) | _outliers(s2, k, floor_deg, False)
    bad &= c1 > 0
    mask = np.zeros(n, dtype=bool)
    # merge disturbed windows separated by up to BRIDGE quiet ones, and widen each stretch by one
    # window on either side: near an object the field changes smoothly, and a fit that still holds
    # the weaker middle or the tails of a pass bends towards them and hides them (measured: a turn
    # next to a steel sphere between two flagged windows stayed in the fit and kept 0.5 µT of error)
    runs: list[list[int]] = []
    for i in np.flatnonzero(bad):
        if runs and i - runs[-1][1] <= BRIDGE + 1:
            runs[-1][1] = i
        else:
            runs.append([int(i), int(i)])
    runs = [[max(a - 1, 0), min(b + 1, bad.size - 1)] for a, b in runs]
    out = []
    for a, b in runs:
        lo, hi = a * w, min((b + 1) * w, n)
        mask[lo:hi] |= valid[lo:hi]
        seg1 = np.abs(np.nan_to_num(field_dev_ut[lo:hi]))
        seg2 = np.abs(incl_dev_deg[lo:hi]) if incl_dev_deg is not None else np.array([np.nan])
        pos = None
        if position_nav_m is not None:
            kmax = lo + int(np.nanargmax(np.abs(np.nan_to_num(field_dev_ut[lo:hi]))))
            p = position_nav_m[kmax]
            pos = tuple(float(x) for x in p) if np.all(np.isfinite(p)) else None
        out.append(Disturbance(float(t_s[lo]), float(t_s[hi - 1]), int(hi - lo), float(np.nanmax(seg1)),
                               float(np.nanmax(seg2)) if np.isfinite(seg2).any() else float("nan"), pos))
    return mask, tuple(out)
