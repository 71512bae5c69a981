"""What a calibration leaves unexplained on measured data, where there is no truth: checks built from
the physics of a hand session alone (the tables of docs/real_imu.md).

* :func:`pose_gravity_residuals` — at every rest pose the compensated accelerometer should read
  |f̂| = g: the residual |f̂| − g (m/s², mean over the pose) and the gravity direction there;
* :func:`gravity_direction_errors` — between two rest poses the compensated gyro, integrated with
  the strapdown rule (:func:`gyrosim.strapdown.integrate_gyro`), must carry the gravity direction of
  the first pose into that of the second: u₂ ≈ R₁₂ᵀ u₁ with R₁₂ the body rotation from pose 1 to pose
  2 (u the measured gravity direction in the body frame, RFU).  The angle between prediction and
  measurement (degrees) tests the gyro's scale and axis errors (and the accelerometer's, through u)
  on the motion between the poses — independent of the attitude frame, no reference needed;
* :func:`integrated_turns` — the angle the compensated gyro integrates over a segment (Σ ω Δt, the
  measure imucal's Ferraris calibration uses for its 360° turns), degrees per axis.

A "calibration" here is any :class:`gyrosim.calibration.Calibration`; ``None`` means the raw data
with only the gyro's static bias removed (the "before" of a before/after table).
"""

from __future__ import annotations

import numpy as np

from gyrosim.calibration import Calibration
from gyrosim.recording import Recording
from gyrosim.rotations import quat_to_matrix
from gyrosim.strapdown import integrate_gyro

__all__ = ["pose_gravity_residuals", "gravity_direction_errors", "integrated_turns", "compensated"]


def compensated(rec: Recording, cal: Calibration | None, static_bias_rad_s: np.ndarray | None = None) -> Recording:
    """``cal.compensate(rec)``, or for ``None`` the raw recording with the static gyro bias removed."""
    if cal is not None:
        return cal.compensate(rec)
    b = np.zeros(3) if static_bias_rad_s is None else np.asarray(static_bias_rad_s, float)
    return rec.with_signals(gyro_rad_s=rec.gyro_rad_s - b)


def pose_gravity_residuals(rec: Recording, ranges: list[tuple[int, int]], gravity_m_s2: float) -> np.ndarray:
    """(P, 4): |f̂| − g (m/s²) and the unit gravity direction (body) at each pose [a, b) of ``rec``."""
    out = []
    for a, b in ranges:
        f = rec.acc_m_s2[a:b]
        m = f.mean(axis=0)
        out.append([float(np.linalg.norm(f, axis=1).mean() - gravity_m_s2), *(m / np.linalg.norm(m))])
    return np.array(out).reshape(-1, 4)


def gravity_direction_errors(rec: Recording, ranges: list[tuple[int, int]]) -> np.ndarray:
    """(P−1,): angle (deg) between the gravity direction predicted at pose i+1 (pose i's, carried by
    the integrated gyro from the middle of pose i to the middle of pose i+1) and the measured one."""
    mids = [(a + b) // 2 for a, b in ranges]
    dirs = [rec.acc_m_s2[a:b].mean(axis=0) for a, b in ranges]
    dirs = [d / np.linalg.norm(d) for d in dirs]
    out = []
    for i in range(len(ranges) - 1):
        k0, k1 = mids[i], mids[i + 1]
        q = integrate_gyro(rec.t_s[k0:k1 + 1], rec.gyro_rad_s[k0:k1 + 1], np.array([1.0, 0.0, 0.0, 0.0]))[-1]
        r = quat_to_matrix(q)                   # body at k1 → body at k0 (q maps the later body frame)
        pred = r.T @ dirs[i]                    # pose i's gravity direction, seen from the body at k1
        out.append(float(np.degrees(np.arccos(np.clip(pred @ dirs[i + 1], -1.0, 1.0)))))
    return np.array(out)


def integrated_turns(rec: Recording, segments: list[tuple[int, int]]) -> np.ndarray:
    """(S, 3): Σ ω Δt over each segment [a, b) (degrees per body axis)."""
    return np.array([np.degrees(rec.gyro_rad_s[a:b].sum(axis=0) / rec.rate_hz) for a, b in segments]).reshape(-1, 3)
