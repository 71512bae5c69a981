"""Static intervals and the figures scored on them, as imu_tk computes them (for :mod:`calib.scoring.measured`).

imu_tk (Tedaldi, Pretto, Menegatti, "A Robust and Easy to Implement Method for IMU Calibration without
External Equipments", ICRA 2014; its C++ library, github.com/Kyle-ak/imu_tk, a mirror of
bitbucket.org/alberto_pretto/imu_tk) judges a calibration by two figures, reproduced here:

* **static intervals** (its ``staticIntervalsDetector``): for every sample i with a full window, the variance
  (n − 1 normalised) of each accelerometer axis over the ``window`` samples centred on i; i is static
  while the norm of the three variances is below ``multiplier`` × the norm of the variances over the first
  ``init`` + 1 samples (the initial rest).  An interval starts at the first static i and ends at the first
  non-static one after it (a run that lasts to the end closes at the last full window); intervals shorter
  than ``min_samples`` (end − start) are dropped.  imu_tk's test program on its Xsens session: window 101,
  initial rest 5,000 samples (50 s), ``min_samples`` 100; of the multipliers 2…10 it tries it keeps the one
  with the smallest accelerometer cost, 6 on that session.  The variances are invariant to the
  accelerometer's scale and offset, so raw counts and the loader's nominal m/s² give the same intervals.
* **accelerometer figure** (``acc_use_means false``): the RMS over the first ``min_samples`` samples of
  every interval of |f| − g (m/s²).
* **gyro figure**: pose i's gravity direction (mean specific force over interval i, normalised) carried
  by the gyro's rotation from the end of interval i to the sample before the start of i + 1 — RK4 on
  the quaternion with the midpoint rate, Δt from the timestamps (imu_tk's ``integrateGyroInterval``) —
  and compared, as an angle, with pose i + 1's direction; the RMS over the moves (°).

The same two figures serve as a held-out check on recordings without a reference (the x-io sessions,
imucal's Ferraris session): a calibration that is right carries gravity from one rest to the next.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["StaticDetector", "static_intervals", "rest_norm_rms", "carried_gravity_errors_deg",
           "integrate_rk4"]


@dataclass(frozen=True)
class StaticDetector:
    """imu_tk's static-interval detector (module docstring); sizes in samples."""

    window: int = 101
    multiplier: float = 6.0
    init: int = 5000
    min_samples: int = 100

    @classmethod
    def imu_tk(cls) -> "StaticDetector":
        """The settings of imu_tk's test program on its Xsens session (100 Hz), multiplier 6."""
        return cls()

    @classmethod
    def for_rate(cls, rate_hz: float, init_s: float = 2.0, window_s: float = 1.0,
                 min_s: float = 1.0) -> "StaticDetector":
        """The same detector in seconds at ``rate_hz``: a ``window_s`` window (odd), the threshold from
        the first ``init_s`` (a rest), intervals of at least ``min_s``."""
        return cls(window=int(round(window_s * rate_hz)) | 1, init=int(round(init_s * rate_hz)),
                   min_samples=int(round(min_s * rate_hz)))


def _rolling_variance(x: np.ndarray, window: int) -> np.ndarray:
    """Variance (n − 1) of each column over the ``window`` samples centred on h … n − h − 1, h = window // 2."""
    h = window // 2
    c = x - x.mean(axis=0)
    s1 = np.vstack([np.zeros(x.shape[1]), np.cumsum(c, axis=0)])
    s2 = np.vstack([np.zeros(x.shape[1]), np.cumsum(c * c, axis=0)])
    i = np.arange(h, x.shape[0] - h)
    s, ss = s1[i + h + 1] - s1[i - h], s2[i + h + 1] - s2[i - h]
    return np.maximum(ss - s * s / window, 0.0) / (window - 1)


def static_intervals(acc: np.ndarray, detector: StaticDetector) -> list[tuple[int, int]]:
    """The static intervals (start, end) of the accelerometer samples ``acc`` (N, 3), indices as imu_tk's
    (``end`` the first non-static sample), those of at least ``detector.min_samples``."""
    acc = np.asarray(acc, dtype=float)
    h = detector.window // 2
    if acc.shape[0] <= detector.window:
        return []
    init = acc[: detector.init + 1]
    threshold = detector.multiplier * float(np.linalg.norm(init.var(axis=0, ddof=1)))
    static = np.linalg.norm(_rolling_variance(acc, detector.window), axis=1) < threshold
    edges = np.diff(np.r_[0, static.astype(np.int8), 0])
    starts, ends = np.flatnonzero(edges == 1) + h, np.flatnonzero(edges == -1) + h
    ends = np.minimum(ends, acc.shape[0] - h - 1)  # a run to the end closes at the last full window
    return [(int(s), int(e)) for s, e in zip(starts, ends) if e - s >= detector.min_samples]


def rest_norm_rms(acc: np.ndarray, intervals: list[tuple[int, int]], n: int, gravity_m_s2: float) -> float:
    """imu_tk's accelerometer figure: RMS of |f| − g over the first ``n`` samples of every interval (m/s²)."""
    if not intervals:
        return math.nan
    f = np.concatenate([np.asarray(acc)[s:s + n] for s, _ in intervals])
    return float(np.sqrt(np.mean((np.linalg.norm(f, axis=1) - gravity_m_s2) ** 2)))


def _omega(w: np.ndarray) -> np.ndarray:
    """½Ω(ω) (…, 4, 4): q̇ = ½Ω(ω) q for (w, x, y, z) quaternions, ω in the body frame (rad/s)."""
    x, y, z = w[..., 0], w[..., 1], w[..., 2]
    o = np.zeros_like(x)
    rows = [(o, -x, -y, -z), (x, o, z, -y), (y, -z, o, x), (z, y, -x, o)]
    return 0.5 * np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)


def integrate_rk4(gyro_rad_s: np.ndarray, t_s: np.ndarray, i0: int, i1: int) -> np.ndarray:
    """The rotation (3×3, body at ``i1`` → body at ``i0``) the gyro integrates from sample ``i0`` to ``i1``:
    imu_tk's RK4 step (rates at both ends and their mean at the midpoint).  Each step is linear in q, so
    its matrix is formed for all steps at once and the product normalised at the end (the same result
    as normalising after every step)."""
    if i1 <= i0:
        return np.eye(3)
    w0, w1 = np.asarray(gyro_rad_s[i0:i1], float), np.asarray(gyro_rad_s[i0 + 1:i1 + 1], float)
    dt = np.diff(np.asarray(t_s, float)[i0:i1 + 1])[:, None, None]
    a0, am, a1 = _omega(w0), _omega(0.5 * (w0 + w1)), _omega(w1)
    eye = np.eye(4)
    m1 = a0                                   # k1 = A0 q
    m2 = am @ (eye + 0.5 * dt * m1)           # k2 = Am (q + dt/2 k1)
    m3 = am @ (eye + 0.5 * dt * m2)           # k3 = Am (q + dt/2 k2)
    m4 = a1 @ (eye + dt * m3)                 # k4 = A1 (q + dt k3)
    steps = eye + dt * (m1 / 6 + m2 / 3 + m3 / 3 + m4 / 6)
    q = np.array([1.0, 0.0, 0.0, 0.0])
    for m in steps:
        q = m @ q
        q /= np.linalg.norm(q)
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def carried_gravity_errors_deg(acc: np.ndarray, gyro_rad_s: np.ndarray, t_s: np.ndarray,
                               intervals: list[tuple[int, int]]) -> np.ndarray:
    """imu_tk's gyro figure per move: the angle (°) between pose i + 1's gravity direction and pose i's
    carried by the gyro from the end of interval i to the sample before interval i + 1 starts."""
    acc = np.asarray(acc, dtype=float)
    out = []
    for (s0, e0), (s1, e1) in zip(intervals[:-1], intervals[1:]):
        g0, g1 = acc[s0:e0 + 1].mean(axis=0), acc[s1:e1 + 1].mean(axis=0)
        g0, g1 = g0 / np.linalg.norm(g0), g1 / np.linalg.norm(g1)
        carried = integrate_rk4(gyro_rad_s, t_s, e0, s1 - 1).T @ g0
        out.append(math.degrees(math.acos(float(np.clip(carried @ g1, -1.0, 1.0)))))
    return np.array(out)
