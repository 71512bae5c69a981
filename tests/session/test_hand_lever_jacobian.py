"""The lever arm term's Jacobian (calib.session.hand.lever.lever_jacobian, the kernel's lever_jacobian_columns):
kf_hand builds K(ω̂, ω̂̇) from the rate compensated at the pass's S, G, b, so K r̂ depends on those errors; the update's
H carries ∂(K r̂)/∂(S, G, b) (docs/hand.md, "The lever arm term's Jacobian").  Without it a session that pins S, G only
weakly left the regressor's error in the innovations and σ of S, G ~1.4× optimistic."""

from __future__ import annotations

import numpy as np

from calib.session.hand.filter import lever_jacobian, lever_regressor
from calib.session.kernel import lever_jacobian_columns
from calib.session.model import m_matrix

FS = 100.0
T = np.arange(0.0, 12.0, 1.0 / FS)
R_M = np.array([0.01, 0.07, 0.02])


def _rates() -> np.ndarray:
    """A hand's turns: sums of 0.2–1.5 Hz sines, ~1–2 rad/s per axis (deterministic)."""
    f = np.array([[0.23, 0.61, 1.4], [0.31, 0.77, 1.1], [0.19, 0.52, 1.3]])
    a = np.array([[1.2, 0.6, 0.2], [0.9, 0.8, 0.3], [1.5, 0.4, 0.25]])
    return np.stack([np.sum(a[i, :, None] * np.sin(2 * np.pi * f[i, :, None] * T + i), axis=0) for i in range(3)], 1)


def _k_r(theta: np.ndarray, gyro: np.ndarray) -> np.ndarray:
    """K(ω(θ)) r with ω(θ) = M(S, G)⁻¹ (ω̃ − b): what the filter subtracts, at the parameters θ = (S, G, b)."""
    w = (gyro - theta[6:9]) @ np.linalg.inv(m_matrix(theta[0:3], theta[3:6])).T
    return np.einsum("nij,j->ni", lever_regressor(w, T, FS), R_M)


def test_the_lever_jacobian_matches_central_differences():
    """∂(K r)/∂(S, G, b) per sample against central differences of K(ω(θ)) r with a step of 1e-5 in each parameter.
    Measured disagreement, relative to the largest entry (0.93 m/s² per unit θ here): 2.0e-7, 3.1e-8, 1.9e-8 at steps
    1e-6, 1e-5, 1e-4 — round-off of the differenced low-pass (∝ 1/h) down to a floor of ~2e-8 — so 1e-6 is a 30×
    margin; a wrong sign, a missing cross product or the low-pass left out of one factor is an error of the size of
    the entries themselves."""
    theta = np.array([0.03, -0.02, 0.04, 0.015, -0.01, 0.02, 0.01, -0.02, 0.005])
    omega = _rates()
    gyro = omega @ m_matrix(theta[0:3], theta[3:6]).T + theta[6:9]
    w = (gyro - theta[6:9]) @ np.linalg.inv(m_matrix(theta[0:3], theta[3:6])).T
    lj = lever_jacobian(w, T, FS, m_matrix(theta[0:3], theta[3:6]))
    jac = np.zeros((T.size, 3, 9))
    out = np.zeros((3, 9))
    for k in range(T.size):
        lever_jacobian_columns(lj.rate_rad_s[k], lj.d_rate[k], lj.d_rate_dot[k], R_M, out)
        jac[k] = out
    h = 1e-5
    fd = np.zeros_like(jac)
    for i in range(9):
        e = np.zeros(9)
        e[i] = h
        fd[:, :, i] = (_k_r(theta + e, gyro) - _k_r(theta - e, gyro)) / (2 * h)
    inner = slice(200, -200)     # away from the zero-phase low-pass's edge transients (identical in both anyway)
    scale = np.max(np.abs(fd[inner]))
    assert scale > 0.1, scale
    assert np.max(np.abs(jac[inner] - fd[inner])) < 1e-6 * scale, np.max(np.abs(jac[inner] - fd[inner])) / scale
    for i in range(9):          # every column is exercised (none is identically zero at these rates)
        assert np.max(np.abs(fd[inner, :, i])) > 1e-3 * scale, i
