"""Quaternion and rotation helpers, vectorised over leading axes.

Convention used throughout gyrosim/calib: quaternions are (w, x, y, z), Hamilton product, and a
quaternion ``q_nb`` rotates a vector from the body frame (Right-Forward-Up) into the navigation
frame (East-North-Up): ``v_n = q_nb ⊗ v_b ⊗ q_nb*``.  Rotation vectors are axis * angle in rad.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "quat_multiply",
    "quat_conjugate",
    "quat_from_rotvec",
    "quat_to_rotvec",
    "quat_to_matrix",
    "quat_rotate",
    "quat_normalize",
    "quat_angle_between",
    "quat_cumulative_product",
    "quat_from_two_vectors",
    "skew",
    "right_jacobian_apply",
    "cross3",
]


def cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a × b for (..., 3) arrays by column arithmetic (np.cross spends most of its time on axis
    bookkeeping for such small last axes)."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = a1 * b2 - a2 * b1
    out[..., 1] = a2 * b0 - a0 * b2
    out[..., 2] = a0 * b1 - a1 * b0
    return out


def quat_multiply(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product p ⊗ q for arrays of shape (..., 4) in (w, x, y, z) order."""
    p = np.asarray(p, dtype=float)
    q = np.asarray(q, dtype=float)
    pw, px, py, pz = np.moveaxis(p, -1, 0)
    qw, qx, qy, qz = np.moveaxis(q, -1, 0)
    out = np.empty(np.broadcast_shapes(p.shape, q.shape))  # written per component: no np.stack copy
    out[..., 0] = pw * qw - px * qx - py * qy - pz * qz
    out[..., 1] = pw * qx + px * qw + py * qz - pz * qy
    out[..., 2] = pw * qy - px * qz + py * qw + pz * qx
    out[..., 3] = pw * qz + px * qy - py * qx + pz * qw
    return out


def quat_conjugate(q: np.ndarray) -> np.ndarray:
    """Conjugate (= inverse for unit quaternions) of (w, x, y, z) quaternions."""
    q = np.asarray(q, dtype=float)
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def quat_normalize(q: np.ndarray) -> np.ndarray:
    """Scale quaternions to unit norm and make w >= 0 (same rotation)."""
    q = np.asarray(q, dtype=float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., :1] < 0.0, -q, q)


def quat_from_rotvec(rotvec: np.ndarray) -> np.ndarray:
    """Exponential map: rotation vector (rad, shape (..., 3)) -> unit quaternion (w, x, y, z).

    q = [cos(θ/2), sin(θ/2) · r/θ] with θ = |r|; the small-angle branch uses the Taylor series
    sin(θ/2)/θ = 1/2 − θ²/48 so that the map stays accurate to machine precision near θ = 0.
    """
    r = np.asarray(rotvec, dtype=float)
    theta = np.linalg.norm(r, axis=-1, keepdims=True)
    half = 0.5 * theta
    small = theta < 1e-6
    safe_theta = np.where(small, 1.0, theta)
    k = np.where(small, 0.5 - theta**2 / 48.0, np.sin(half) / safe_theta)
    return np.concatenate([np.cos(half), k * r], axis=-1)


def quat_to_rotvec(q: np.ndarray) -> np.ndarray:
    """Logarithm map: unit quaternion -> rotation vector (rad) with angle in [0, π]."""
    q = quat_normalize(q)
    w = np.clip(q[..., :1], -1.0, 1.0)
    v = q[..., 1:]
    s = np.linalg.norm(v, axis=-1, keepdims=True)
    angle = 2.0 * np.arctan2(s, w)
    small = s < 1e-9
    k = np.where(small, 2.0 / np.where(small, w, 1.0), angle / np.where(small, 1.0, s))
    return k * v


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """Direction cosine matrix C (..., 3, 3) of unit quaternions; ``v_n = C @ v_b`` for q_nb."""
    q = np.asarray(q, dtype=float)
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        axis=-2,
    )


def quat_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vectors v (..., 3) by quaternions q (..., 4): returns C(q) @ v.

    Uses v' = v + 2w (u × v) + 2 u × (u × v) with q = (w, u), cheaper than forming C(q).
    """
    q = np.asarray(q, dtype=float)
    v = np.asarray(v, dtype=float)
    u = q[..., 1:]
    t = 2.0 * cross3(u, v)
    return v + q[..., :1] * t + cross3(u, t)


def quat_angle_between(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Rotation angle (rad, in [0, π]) of p* ⊗ q, i.e. the attitude difference of p and q."""
    d = quat_multiply(quat_conjugate(p), q)
    return np.linalg.norm(quat_to_rotvec(d), axis=-1)


def quat_cumulative_product(steps: np.ndarray) -> np.ndarray:
    """Running product out[k] = steps[0] ⊗ steps[1] ⊗ … ⊗ steps[k] along axis 0.

    Evaluated as a Hillis–Steele parallel prefix scan (⌈log2 N⌉ passes, pass s: out[i] ←
    out[i − s] ⊗ out[i]); quaternion multiplication is associative, so the result equals the
    sequential product up to rounding (renormalised at the end).  The passes run compiled and in
    place (:func:`gyrosim._rotation_kernels.prefix_product_inplace`, the same products in the same
    order as :func:`quat_multiply`, so bit-identical to the whole-array numpy passes).
    """
    from ._rotation_kernels import prefix_product_inplace

    out = np.array(steps, dtype=float, copy=True, order="C")
    if out.shape[0] > 1:
        prefix_product_inplace(out.reshape(out.shape[0], -1, 4))
    return out / np.linalg.norm(out, axis=-1, keepdims=True)


def quat_from_two_vectors(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Shortest-arc unit quaternion that rotates direction a onto direction b (both (..., 3))."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    a = a / np.linalg.norm(a, axis=-1, keepdims=True)
    b = b / np.linalg.norm(b, axis=-1, keepdims=True)
    w = 1.0 + np.sum(a * b, axis=-1, keepdims=True)
    v = np.cross(a, b)
    antiparallel = w[..., 0] < 1e-12
    if np.any(antiparallel):
        # any axis perpendicular to a works for a 180° turn
        helper = np.where(np.abs(a[..., :1]) < 0.9, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
        perp = np.cross(a, helper)
        perp /= np.linalg.norm(perp, axis=-1, keepdims=True)
        v = np.where(antiparallel[..., None], perp, v)
        w = np.where(antiparallel[..., None], 0.0, w)
    q = np.concatenate([w, v], axis=-1)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def skew(v: np.ndarray) -> np.ndarray:
    """Skew-symmetric cross-product matrix [v×] (..., 3, 3) such that [v×] u = v × u."""
    v = np.asarray(v, dtype=float)
    x, y, z = np.moveaxis(v, -1, 0)
    o = np.zeros_like(x)
    return np.stack(
        [np.stack([o, -z, y], -1), np.stack([z, o, -x], -1), np.stack([-y, x, o], -1)], axis=-2
    )


def right_jacobian_apply(phi: np.ndarray, v: np.ndarray) -> np.ndarray:
    """J_r(φ) v for the right Jacobian of SO(3), vectorised over (..., 3).

    J_r(φ) = I − (1 − cos θ)/θ² [φ×] + (θ − sin θ)/θ³ [φ×]²,  θ = |φ|; for q(t) = q₀ ⊗ Exp(φ(t))
    the body rate is ω = J_r(φ) φ̇ (Barfoot, State Estimation for Robotics, §7.1.5).
    Taylor branches for θ < 1e-4 keep it accurate at small angles.
    """
    phi = np.asarray(phi, dtype=float)
    v = np.asarray(v, dtype=float)
    th = np.linalg.norm(phi, axis=-1, keepdims=True)
    small = th < 1e-4
    ts = np.where(small, 1.0, th)
    a = np.where(small, 0.5 - th**2 / 24.0, (1.0 - np.cos(ts)) / ts**2)
    b = np.where(small, 1.0 / 6.0 - th**2 / 120.0, (ts - np.sin(ts)) / ts**3)
    c1 = cross3(phi, v)
    return v - a * c1 + b * cross3(phi, c1)
