"""Cramér–Rao bounds of the calibration: what any unbiased estimator could reach on a trajectory.

For the linear-Gaussian error model linearised at the *true* trajectory (true attitude, true rate, true S and
G), the Kalman covariance with a vague prior on the constants is the Cramér–Rao bound of any unbiased estimator
of them from the whole record (for constant parameters the final filtered covariance equals the smoothed one):

* :func:`crlb` — the paper's 9 states (Zhou 2020), a plain Riccati recursion here;
* :func:`crlb_joint` — any layout's states, the compiled filter (:func:`calib.session.kernel.run_filter`) fed the
  noise-free readings of the true device, with all three measurement rows.
"""

from __future__ import annotations

import numpy as np

from gyrosim.rotations import quat_to_matrix

from calib.session.kernel import run_filter
from calib.session.model import FilterConfig, StateLayout, nonorthogonality_jacobians

__all__ = ["crlb", "crlb_joint"]


def crlb(
    omega_true_rad_s: np.ndarray,
    quat_true_nb: np.ndarray,
    t_s: np.ndarray,
    config: FilterConfig,
    rate_hz: float,
    scale_true: np.ndarray,
    nonortho_true: np.ndarray,
    vague: float = 10.0,
) -> np.ndarray:
    """Cramér–Rao bound (9, 9) of [φ₀-tracked attitude, S, G] for one trajectory (module docstring).

    The Riccati recursion of the error model at the true attitude and true rate (the
    compensated rate equals the true one), with the true M⁻¹, a vague prior σ = ``vague`` on S
    and G and the config's attitude prior; the measurement noise and ARW are the config's.
    """
    m_inv = np.linalg.inv(_m_hat(np.asarray(scale_true, float), np.asarray(nonortho_true, float)))
    c = config
    p = np.diag([c.prior_attitude_rad**2] * 3 + [vague**2] * 6)
    gz = c.gravity_m_s2
    h = np.zeros((3, 9))
    h[0, 1], h[1, 0] = -gz, gz
    r = np.eye(3) * c.r_var(rate_hz)
    cmats = quat_to_matrix(quat_true_nb)
    w = np.asarray(omega_true_rad_s, float)
    for k in range(1, t_s.size):
        dt = float(t_s[k] - t_s[k - 1])
        w_bar = 0.5 * (w[k - 1] + w[k])
        c_mid = 0.5 * (cmats[k - 1] + cmats[k])
        cm = -dt * c_mid @ m_inv
        f = np.eye(9)
        f[0:3, 3:6] = cm * w_bar[None, :]
        f[0:3, 6:9] = cm @ nonorthogonality_jacobians(w_bar[None])[0]
        p = f @ p @ f.T
        p[0:3, 0:3] += np.eye(3) * c.arw_rad_s_sqrt_hz**2 * dt
        ph = p @ h.T
        s = h @ ph + r
        kg = ph @ np.linalg.inv(s)
        p = p - kg @ ph.T
        p = 0.5 * (p + p.T)
    return p


def crlb_joint(omega_true_rad_s: np.ndarray, specific_force_true_m_s2: np.ndarray, quat_true_nb: np.ndarray,
               t_s: np.ndarray, theta_true: np.ndarray, layout: StateLayout, config: FilterConfig, rate_hz: float,
               vague: float = 10.0) -> np.ndarray:
    """Cramér–Rao bound (n, n) of a layout's states for one trajectory: the filter's Riccati recursion
    fed the noise-free readings of the true device (so its nominal stays on the truth and the
    covariance is the information of the linearised model there), with all three measurement rows
    and a vague prior (σ = ``vague`` in the parameters' units) on every parameter block."""
    th = np.asarray(theta_true, float)
    def m(s, g):
        return np.eye(3) + np.diag(s) + np.array([[0, g[2], g[1]], [g[2], 0, g[0]], [g[1], g[0], 0]])
    gyro = np.asarray(omega_true_rad_s) @ m(th[0:3], th[3:6]).T + th[6:9]
    acc = np.asarray(specific_force_true_m_s2) @ m(th[12:15], th[15:18]).T + th[9:12]
    p0 = np.eye(layout.n) * vague**2
    p0[0:3, 0:3] = np.eye(3) * config.prior_attitude_rad**2
    run = run_filter(gyro[None], acc[None], t_s, np.asarray(quat_true_nb[0], float)[None], th[None], p0, layout,
                     config, rate_hz, rows=3)
    return run.p[0]


def _m_hat(scale: np.ndarray, nonortho: np.ndarray) -> np.ndarray:
    """M = I + diag(S) + N(G), built as the compiled kernel's cofactor inverse expects (N(G) has J_G's pattern)."""
    m = nonorthogonality_jacobians(np.asarray(nonortho, float)[None])[0]
    m[0, 0] += 1 + scale[0]
    m[1, 1] += 1 + scale[1]
    m[2, 2] += 1 + scale[2]
    return m
