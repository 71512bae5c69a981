"""Tilt-compensated compass heading, heading errors against a reference, and its noise floor.

Frames: body Right-Forward-Up, navigation East-North-Up; quaternions (w, x, y, z) body → nav.

* **Compass attitude** (TRIAD of gravity and field): with u the unit 'up' and B the field, both in
  the body frame, magnetic north n = normalise(B − (B·u) u), east e = n × u, and the body→nav
  matrix has the rows e, n, u (``compass_quaternion``).  It is defined at every attitude (not
  only near level), as long as B is not vertical.
* **Heading error** of an attitude q against a reference q_ref: the vertical component of the
  rotation vector of q ⊗ q_ref* (nav frame) — exactly the heading difference when both share
  the same tilt, and free of the ±90° pitch singularity of Euler angles (``heading_error_rad``).
* **Heading** (a scalar to filter): the twist of q about the nav vertical, ψ = 2 atan2(q_z, q_w)
  — the yaw when level, undefined only upside down (``twist_heading_rad``).
* **Magnetic reference**: the true attitude turned into the magnetic frame, q_mag = q_z(D) ⊗ q,
  D the declination (east positive): a compass measures heading from magnetic north.
* **Noise floor**: white noise ε (σ µT per axis) on m moves the horizontal field's direction by
  ε_⊥/H (rad), ε_⊥ its component across the field in the horizontal plane; through the
  calibration B = A⁻¹(m − h) the noise on B is A⁻¹ε, so per sample
  σ_ψ,k² = σ² e_kᵀ A⁻¹ A⁻ᵀ e_k / H_k², e_k the body-frame unit vector horizontal and across the
  field, H_k the horizontal field (with the true tilt; an accelerometer's tilt error adds to it).
"""

from __future__ import annotations

import math

import numpy as np

from gyrosim.rotations import quat_conjugate, quat_multiply, quat_to_rotvec

__all__ = [
    "compass_quaternion",
    "twist_heading_rad",
    "heading_error_rad",
    "magnetic_reference",
    "heading_noise_floor_rad",
    "up_from_quat",
    "wrap_pi",
]


def wrap_pi(a: np.ndarray) -> np.ndarray:
    """The angles ``a`` (rad) wrapped into [−π, π)."""
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def up_from_quat(q_nb: np.ndarray) -> np.ndarray:
    """The nav 'up' (0, 0, 1) in body coordinates: the third row of C_nb (body→nav)."""
    w, x, y, z = np.moveaxis(np.asarray(q_nb, dtype=float), -1, 0)
    return np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=-1)


def _quat_from_matrix(c: np.ndarray) -> np.ndarray:
    """(N, 4) quaternions of (N, 3, 3) rotation matrices (Shepperd's method, branch by trace)."""
    n = c.shape[0]
    q = np.empty((n, 4))
    tr = np.trace(c, axis1=1, axis2=2)
    cases = np.stack([tr, c[:, 0, 0], c[:, 1, 1], c[:, 2, 2]], axis=1).argmax(axis=1)
    for k in range(4):
        s = cases == k
        if not s.any():
            continue
        m = c[s]
        if k == 0:
            r = np.sqrt(1 + tr[s]) * 2
            q[s] = np.stack(
                [r / 4, (m[:, 2, 1] - m[:, 1, 2]) / r, (m[:, 0, 2] - m[:, 2, 0]) / r, (m[:, 1, 0] - m[:, 0, 1]) / r], 1
            )
        else:
            i = k - 1
            j, kk = (i + 1) % 3, (i + 2) % 3
            r = np.sqrt(1 + m[:, i, i] - m[:, j, j] - m[:, kk, kk]) * 2
            v = np.empty((m.shape[0], 4))
            v[:, 0] = (m[:, kk, j] - m[:, j, kk]) / r
            v[:, 1 + i] = r / 4
            v[:, 1 + j] = (m[:, j, i] + m[:, i, j]) / r
            v[:, 1 + kk] = (m[:, kk, i] + m[:, i, kk]) / r
            q[s] = v
    return q * np.where(q[:, :1] < 0, -1.0, 1.0)


def compass_quaternion(up_body: np.ndarray, field_body: np.ndarray) -> np.ndarray:
    """Body→(magnetic) nav quaternion from the up direction and the field, both body frame (N, 3)."""
    u = up_body / np.linalg.norm(up_body, axis=1, keepdims=True)
    b = np.asarray(field_body, dtype=float)
    n = b - np.sum(b * u, axis=1, keepdims=True) * u
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    e = np.cross(n, u)
    return _quat_from_matrix(np.stack([e, n, u], axis=1))


def twist_heading_rad(q_nb: np.ndarray) -> np.ndarray:
    """Heading ψ (rad, clockwise from north, in (−π, π]) of the body's forward axis when level: the
    twist of q about the nav vertical, ψ = −2 atan2(q_z, q_w) (a positive rotation about Up turns
    the heading anticlockwise, i.e. decreases the compass heading)."""
    q = np.asarray(q_nb, dtype=float)
    return wrap_pi(-2.0 * np.arctan2(q[:, 3], q[:, 0]))


def heading_error_rad(q_est: np.ndarray, q_ref: np.ndarray) -> np.ndarray:
    """Heading error (rad) of q_est against q_ref: the compass heading difference ψ_est − ψ_ref,
    from the vertical (nav) component of rotvec(q_est ⊗ q_ref*) (sign: compass heading grows
    clockwise, a rotation about Up is anticlockwise)."""
    d = quat_multiply(q_est, quat_conjugate(q_ref))
    return -quat_to_rotvec(d)[:, 2]


def magnetic_reference(q_true_nb: np.ndarray, earth_enu_ut: np.ndarray) -> np.ndarray:
    """The true attitude in the magnetic frame: q_z(D) ⊗ q, D = atan2(B_E, B_N) the declination."""
    d = math.atan2(float(earth_enu_ut[0]), float(earth_enu_ut[1]))
    qz = np.array([math.cos(d / 2), 0.0, 0.0, math.sin(d / 2)])
    return quat_multiply(np.broadcast_to(qz, np.shape(q_true_nb)), q_true_nb)


def heading_noise_floor_rad(field_body_ut: np.ndarray, up_body: np.ndarray, noise_ut: float,
                            soft_iron: np.ndarray | None = None) -> float:
    """RMS heading noise (rad) a white field noise of σ = ``noise_ut`` per axis gives through the
    calibration B = A⁻¹(m − h) (module docstring); ``field_body_ut`` the true field (N, 3)."""
    u = up_body / np.linalg.norm(up_body, axis=1, keepdims=True)
    b = np.asarray(field_body_ut, dtype=float)
    bh = b - np.sum(b * u, axis=1, keepdims=True) * u
    hmag = np.linalg.norm(bh, axis=1)
    e = np.cross(u, bh / hmag[:, None])  # horizontal, across the field
    ainv = np.eye(3) if soft_iron is None else np.linalg.inv(soft_iron)
    g = e @ ainv  # e_kᵀ A⁻¹
    var = noise_ut**2 * np.sum(g * g, axis=1) / hmag**2
    return float(np.sqrt(np.mean(var)))
