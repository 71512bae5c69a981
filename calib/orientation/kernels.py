"""Madgwick's and Mahony's attitude filters, compiled (numba), 6-axis and 9-axis.

Written from the papers, not from any implementation:

* Madgwick, Harrison, Vaidyanathan, "Estimation of IMU and MARG orientation using a gradient
  descent algorithm", IEEE ICORR 2011 (and Madgwick's 2010 report, eq. numbers below from it);
* Mahony, Hamel, Pflimlin, "Nonlinear complementary filters on the special orthogonal group",
  IEEE TAC 53(5), 2008 (explicit complementary filter, eqs. 32/48).

Conventions (both filters, as published): q = (w, x, y, z) rotates body vectors into the earth
frame, q̇ = ½ q ⊗ (0, ω); the earth frame has z up (the accelerometer reads +g along +z at rest)
and, for 9-axis, its x axis along the horizontal magnetic field: **North-West-Up**.  The
adapters (:mod:`calib.orientation.estimators`) turn that into body → ENU with q_EN = q_z(+90°) ⊗ q.

Why our own: the Python reference (``ahrs``) loops in the interpreter, 1.4–1.8 s per 171 s
session at 100 Hz; a campaign of 1000 sessions × raw/calibrated would spend most of its time
there.  ``tests/orientation/test_orientation.py`` checks these kernels against ``ahrs`` sample for sample.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def _normalize4(q):
    n = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    return q / n


@njit(cache=True)
def _qdot(q, gx, gy, gz):
    """½ q ⊗ (0, g): the quaternion kinematics (Madgwick 2010 eq. 12)."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    out = np.empty(4)
    out[0] = 0.5 * (-x * gx - y * gy - z * gz)
    out[1] = 0.5 * (w * gx + y * gz - z * gy)
    out[2] = 0.5 * (w * gy - x * gz + z * gx)
    out[3] = 0.5 * (w * gz + x * gy - y * gx)
    return out


@njit(cache=True)
def _rotate_to_earth(q, v):
    """R(q) v: a body vector in the earth frame."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    out = np.empty(3)
    out[0] = (1 - 2 * (y * y + z * z)) * v[0] + 2 * (x * y - w * z) * v[1] + 2 * (x * z + w * y) * v[2]
    out[1] = 2 * (x * y + w * z) * v[0] + (1 - 2 * (x * x + z * z)) * v[1] + 2 * (y * z - w * x) * v[2]
    out[2] = 2 * (x * z - w * y) * v[0] + 2 * (y * z + w * x) * v[1] + (1 - 2 * (x * x + y * y)) * v[2]
    return out


@njit(cache=True)
def madgwick(gyr, acc, mag, dt, beta, q0, field_scale=1.0):
    """Madgwick's filter over N samples (rad/s, any acc/mag unit); ``mag`` of shape (0, 3) for
    6-axis.  Per sample k: q̇_ω = ½ q ⊗ ω (eq. 12); f, J the objective and its Jacobian (eqs.
    25–26; with the field reference b = (b_x, 0, b_z), h = q ⊗ m ⊗ q*, eqs. 45–46, 31–32 for
    9-axis); q̇ = q̇_ω − β ∇f/‖∇f‖ (eq. 33); q ← (q + q̇ Δt)/‖·‖ (eq. 13).  Returns Q (N, 4).

    ``field_scale``: the field reference is b = field_scale · (‖h_xy‖, 0, h_z).  1 is the paper;
    Madgwick's 2011 C code (MadgwickAHRS.c, the implementation BROAD's published Madgwick
    numbers come from) stores ‖h_xy‖ and h_z in variables named 2b_x and 2b_z and uses them where
    the paper has 2b_x, 2b_z, i.e. a reference of half the measured field: field_scale = 0.5."""
    n = gyr.shape[0]
    use_mag = mag.shape[0] == n
    out = np.empty((n, 4))
    q = _normalize4(q0.copy())
    for k in range(n):
        qd = _qdot(q, gyr[k, 0], gyr[k, 1], gyr[k, 2])
        an = math.sqrt(acc[k, 0] ** 2 + acc[k, 1] ** 2 + acc[k, 2] ** 2)
        if an > 0.0:
            ax, ay, az = acc[k, 0] / an, acc[k, 1] / an, acc[k, 2] / an
            w, x, y, z = q[0], q[1], q[2], q[3]
            # gravity rows (eq. 25): R(q)ᵀ e_z − â
            f0 = 2.0 * (x * z - w * y) - ax
            f1 = 2.0 * (w * x + y * z) - ay
            f2 = 2.0 * (0.5 - x * x - y * y) - az
            g = np.empty(4)
            # ∇f = Jᵀ f (eq. 34), gravity part (eq. 26)
            g[0] = -2.0 * y * f0 + 2.0 * x * f1
            g[1] = 2.0 * z * f0 + 2.0 * w * f1 - 4.0 * x * f2
            g[2] = -2.0 * w * f0 + 2.0 * z * f1 - 4.0 * y * f2
            g[3] = 2.0 * x * f0 + 2.0 * y * f1
            mn = 0.0
            if use_mag:
                mn = math.sqrt(mag[k, 0] ** 2 + mag[k, 1] ** 2 + mag[k, 2] ** 2)
            if mn > 0.0:
                m = np.empty(3)
                m[0], m[1], m[2] = mag[k, 0] / mn, mag[k, 1] / mn, mag[k, 2] / mn
                h = _rotate_to_earth(q, m)                     # eq. 45
                bx = field_scale * math.sqrt(h[0] * h[0] + h[1] * h[1])     # eq. 46
                bz = field_scale * h[2]
                # field rows (eq. 31): R(q)ᵀ b − m̂
                f3 = 2.0 * bx * (0.5 - y * y - z * z) + 2.0 * bz * (x * z - w * y) - m[0]
                f4 = 2.0 * bx * (x * y - w * z) + 2.0 * bz * (w * x + y * z) - m[1]
                f5 = 2.0 * bx * (w * y + x * z) + 2.0 * bz * (0.5 - x * x - y * y) - m[2]
                # Jacobian rows of the field (eq. 32), transposed onto f
                g[0] += -2.0 * bz * y * f3 + (-2.0 * bx * z + 2.0 * bz * x) * f4 + 2.0 * bx * y * f5
                g[1] += 2.0 * bz * z * f3 + (2.0 * bx * y + 2.0 * bz * w) * f4 + (2.0 * bx * z - 4.0 * bz * x) * f5
                g[2] += ((-4.0 * bx * y - 2.0 * bz * w) * f3 + (2.0 * bx * x + 2.0 * bz * z) * f4
                         + (2.0 * bx * w - 4.0 * bz * y) * f5)
                g[3] += (-4.0 * bx * z + 2.0 * bz * x) * f3 + (-2.0 * bx * w + 2.0 * bz * y) * f4 + 2.0 * bx * x * f5
            gn = math.sqrt(g[0] ** 2 + g[1] ** 2 + g[2] ** 2 + g[3] ** 2)
            if gn > 0.0:
                qd = qd - beta * g / gn                          # eq. 33
        q = _normalize4(q + qd * dt)                             # eq. 13
        out[k] = q
    return out


@njit(cache=True)
def mahony(gyr, acc, mag, dt, kp, ki, q0, b0):
    """Mahony's explicit complementary filter over N samples; ``mag`` (0, 3) for 6-axis.
    Per sample: v̂_a = R(q)ᵀ e_z, ω_mes = â × v̂_a (+ m̂ × v̂_m with v̂_m = R(q)ᵀ (‖h_xy‖, 0, h_z),
    h = R(q) m̂) (eq. 32c/48a); ḃ = −k_I ω_mes (eq. 48c); ω = ω̃ − b + k_P ω_mes (eq. 48b);
    q ← (q + ½ q ⊗ ω Δt)/‖·‖.  Returns Q (N, 4) and the final bias b (rad/s)."""
    n = gyr.shape[0]
    use_mag = mag.shape[0] == n
    out = np.empty((n, 4))
    q = _normalize4(q0.copy())
    b = b0.copy()
    for k in range(n):
        wx, wy, wz = gyr[k, 0], gyr[k, 1], gyr[k, 2]
        an = math.sqrt(acc[k, 0] ** 2 + acc[k, 1] ** 2 + acc[k, 2] ** 2)
        if an > 0.0:
            a = acc[k] / an
            w, x, y, z = q[0], q[1], q[2], q[3]
            va = np.array([2.0 * (x * z - w * y), 2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y)])  # R(q)ᵀ e_z
            e = np.array([a[1] * va[2] - a[2] * va[1], a[2] * va[0] - a[0] * va[2], a[0] * va[1] - a[1] * va[0]])
            mn = 0.0
            if use_mag:
                mn = math.sqrt(mag[k, 0] ** 2 + mag[k, 1] ** 2 + mag[k, 2] ** 2)
            if mn > 0.0:
                m = mag[k] / mn
                h = _rotate_to_earth(q, m)
                ref = np.array([math.sqrt(h[0] * h[0] + h[1] * h[1]), 0.0, h[2]])
                # v̂_m = R(q)ᵀ ref (the transpose: rotate by q*)
                qc = np.array([q[0], -q[1], -q[2], -q[3]])
                vm = _rotate_to_earth(qc, ref)
                vm = vm / math.sqrt(vm[0] ** 2 + vm[1] ** 2 + vm[2] ** 2)
                e[0] += m[1] * vm[2] - m[2] * vm[1]
                e[1] += m[2] * vm[0] - m[0] * vm[2]
                e[2] += m[0] * vm[1] - m[1] * vm[0]
            b = b - ki * e * dt
            wx = wx - b[0] + kp * e[0]
            wy = wy - b[1] + kp * e[1]
            wz = wz - b[2] + kp * e[2]
        q = _normalize4(q + _qdot(q, wx, wy, wz) * dt)
        out[k] = q
    return out, b
