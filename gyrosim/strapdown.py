"""Strapdown attitude integration of gyro samples (body rate → body→navigation quaternion).

Between samples k and k+1 (Δt = t_{k+1} − t_k) the rotation increment is

    Φ_k = ½ (ω_k + ω_{k+1}) Δt + (1/12) (ω_k × ω_{k+1}) Δt²,

the trapezoidal rate plus the two-sample coning correction (Savage, "Strapdown Inertial Navigation
Integration Algorithm Design Part 1", JGCD 21(1), 1998, eq. 39 for a linearly varying rate), and
q_{k+1} = q_k ⊗ Exp(Φ_k).  Frames: ω in the body frame (RFU), q body → navigation (ENU).
The Earth's rotation is not removed (negligible for consumer gyros; see the effect vocabulary).
"""

from __future__ import annotations

import numpy as np

from .rotations import cross3, quat_cumulative_product, quat_from_rotvec, quat_normalize

__all__ = ["integrate_gyro"]


def integrate_gyro(t_s: np.ndarray, omega_body_rad_s: np.ndarray, quat0_nb: np.ndarray) -> np.ndarray:
    """Attitude (N, 4) from rate samples (N, 3) at times ``t_s`` (N,), starting at ``quat0_nb``."""
    t = np.asarray(t_s, dtype=float)
    w = np.asarray(omega_body_rad_s, dtype=float)
    if w.shape != (t.size, 3):
        raise ValueError(f"omega must have shape ({t.size}, 3), got {w.shape}")
    dt = np.diff(t)[:, None]
    phi = 0.5 * (w[:-1] + w[1:]) * dt + cross3(w[:-1], w[1:]) * dt**2 / 12.0
    steps = np.concatenate([np.asarray(quat0_nb, dtype=float)[None], quat_from_rotvec(phi)])
    return quat_normalize(quat_cumulative_product(steps))
