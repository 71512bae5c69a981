"""The attitude-aided fit: hard iron, the full soft-iron matrix **and the magnetometer-to-IMU
misalignment**, using the gravity direction the gyro and accelerometer give.

The Earth field is constant in the navigation frame, so besides its magnitude its angle to the
vertical — the inclination I — is constant too (the dot-product invariant: Li & Li, "Integrated
calibration of a three-axis magnetometer and accelerometer", IEEE Sensors J. 2012; Kok & Schön
2016 use the full attitude).  With u_k the unit 'up' direction in the body frame
(:mod:`calib.mag.gravity`) and L = A⁻¹ a **general** 3×3 (9 parameters):

    r1_k = |L (m_k − h)| − 1                       every valid sample
    r2_k = u_kᵀ L (m_k − h) + sin I                 quasi-static samples      (B·up = −|B| sin I)

13 parameters θ = (L row-major, h, sin I); the unit-radius normalisation fixes the scale, and the
field magnitude is F = |det L|^(−1/3) (det A = 1).  The magnitude residual alone is unchanged by
L → Q L (Q orthogonal): the ellipsoid fit's blind spot.  The inclination residual is not, as soon
as the board turns about two axes (u_k then has no fixed body direction), so the rotation part R of
A = P R (polar decomposition, P symmetric) becomes observable: R = R(θ)ᵀ, θ the misalignment
(:class:`gyrosim.effects.FrameRotation`).

Weights: 1/σ₁, 1/σ₂ from the residuals of the previous iteration (variance components; the
gravity reference's tilt error makes σ₂ larger than σ₁); covariance from the block sandwich
(:mod:`calib.mag.lsq`), which also absorbs the time correlation of the tilt error.

Noise in m is noise in the *regressor* of r2, which is linear in L: least squares then shrinks L
along u (E Σ r2² = Σ r2*² + σ² Σ |Lᵀu_k|²) and biases the inclination low by ~5 σ²/F² rad
(0.11° at the AK8963's 0.6 µT, 1.1° at 2 µT; measured).  The adjusted least squares of Kukush,
Markovsky & Van Huffel (2004) subtracts that expectation: the cost is Σ r1² + Σ r2² − θᵀMθ with
M = σ² Σ_k (w₁² n_k n_kᵀ + w₂² u_k u_kᵀ) ⊗ I₃ over the L entries (n_k = L d_k/|L d_k|: the same
shrinkage acts through the magnitude residual), σ² the magnetometer's white-noise variance per
axis from its second differences (var Δ²m = 6σ² for white noise; the signal's curvature ω²Δt²|B|
is ~0.002 µT at 100 Hz).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib.mag.ellipsoid import PRIOR_REL, noise_bias, white_noise_variance
from calib.mag.lsq import levenberg_marquardt, sandwich_covariance, with_prior

__all__ = ["AidedFit", "fit_aided"]


@dataclass(frozen=True)
class AidedFit:
    """The attitude-aided fit (module docstring): L = A⁻¹ at unit radius, the hard iron h (µT) and sin I,
    the block-sandwich covariance of θ = (L row-major, h, sin I), the two residuals with their noise
    levels σ₁, σ₂, and the L entries the data leave weak."""

    l_matrix: np.ndarray  # general L = A⁻¹ (unit radius)
    centre: np.ndarray
    sin_incl: float
    cov: np.ndarray  # 13×13 over (L row-major, h, sin I)
    sigma_magnitude: float  # σ₁ (dimensionless, ≈ noise/F)
    sigma_inclination: float  # σ₂
    correlation_ratio: float
    residual_magnitude: np.ndarray
    residual_inclination: np.ndarray
    jacobian: np.ndarray | None = None  # weighted, rows: every sample's r1, then the static samples' r2
    residual: np.ndarray | None = None  # weighted, same rows
    weak: tuple[int, ...] = ()  # L entries (row-major) whose posterior σ stays above half the prior's
    prior_info: np.ndarray | None = None

    @property
    def theta(self) -> np.ndarray:
        return np.concatenate([self.l_matrix.ravel(), self.centre, [self.sin_incl]])


def _residual(m: np.ndarray, up: np.ndarray, static: np.ndarray, w1: float, w2: float, sigma2: float):
    ms, us = m[static], up[static]
    n1 = m.shape[0]

    def fun(theta: np.ndarray):
        lm = theta[:9].reshape(3, 3)
        h, s = theta[9:12], theta[12]
        d = m - h
        v = d @ lm.T
        nv = np.linalg.norm(v, axis=1)
        n = v / nv[:, None]
        j1 = np.zeros((m.shape[0], 13))
        j1[:, :9] = (n[:, :, None] * d[:, None, :]).reshape(-1, 9)  # ∂|Ld|/∂L_ij = n_i d_j
        j1[:, 9:12] = -(n @ lm)  # −Lᵀn
        ds = ms - h
        r2 = np.sum(us * (ds @ lm.T), axis=1) + s
        jac = np.empty((n1 + ms.shape[0], 13))
        jac[:n1] = j1
        j2 = jac[n1:]
        j2[:, :9] = (us[:, :, None] * ds[:, None, :]).reshape(-1, 9)  # ∂(uᵀLd)/∂L_ij = u_i d_j
        j2[:, 9:12] = -(us @ lm)
        j2[:, 12] = 1.0
        jac[:n1] *= w1
        jac[n1:] *= w2
        r = np.concatenate([(nv - 1.0 - noise_bias(lm, nv, n, sigma2)) * w1, r2 * w2])
        return r, jac

    return fun


def _correction(m: np.ndarray, up_static: np.ndarray, theta: np.ndarray, sigma2: float, w1: float,
                w2: float) -> np.ndarray:
    """ALS term θᵀMθ = E[noise part of Σ w₁² r1² + Σ w₂² r2²] to first order: σ² Σ |Lᵀn_k|² (n_k the
    unit direction of L d_k, held at the current θ) and σ² Σ |Lᵀu_k|²."""
    lm = theta[:9].reshape(3, 3)
    v = (m - theta[9:12]) @ lm.T
    n = v / np.linalg.norm(v, axis=1, keepdims=True)
    mc = np.zeros((13, 13))
    mc[:9, :9] = (np.kron(n.T @ n, np.eye(3)) * w1**2 + np.kron(up_static.T @ up_static, np.eye(3)) * w2**2) * sigma2
    return mc


def fit_aided(m: np.ndarray, up: np.ndarray, static: np.ndarray, blocks: np.ndarray,
              l0: np.ndarray, h0: np.ndarray, noise_var_ut2: float | None = None) -> AidedFit:
    """The fit of the module docstring from the start (L₀, h₀) (the ellipsoid fit's).

    ``noise_var_ut2``: the magnetometer's white-noise variance per axis (µT²) for the bias
    correction; default from the samples' second differences."""
    sigma2 = white_noise_variance(m) if noise_var_ut2 is None else float(noise_var_ut2)
    us = up[static]
    d0 = m[static] - h0
    s0 = float(-np.median(np.sum(us * (d0 @ l0.T), axis=1)))
    theta = np.concatenate([l0.ravel(), h0, [s0]])
    w1 = w2 = 1.0
    # prior on L: the ellipsoid fit's L ± PRIOR_REL of its scale per entry (rows already at unit noise)
    radius = 3.0 / np.trace(l0)
    sig_p = PRIOR_REL / radius
    idx = np.arange(9)
    n1 = m.shape[0]
    n_rows = n1 + int(static.sum())

    def model(w1: float, w2: float):
        return with_prior(_residual(m, up, static, w1, w2, sigma2), idx, l0.ravel(), np.full(9, 1.0 / sig_p))

    for _ in range(3):  # variance components: refit with the weights of the last residuals (warm starts)
        res = levenberg_marquardt(model(w1, w2), theta, correction=_correction(m, us, theta, sigma2, w1, w2),
                                  max_iter=15, tol=1e-9)
        theta = res.theta
        r1, r2 = res.residual[:n1] / w1, res.residual[n1:n_rows] / w2
        s1 = float(np.sqrt(np.mean(r1**2)))
        s2 = float(np.sqrt(np.mean(r2**2)))
        if s1 <= 0 or s2 <= 0:
            break
        new = (1.0 / s1, 1.0 / s2)
        if abs(new[0] / w1 - 1) < 0.01 and abs(new[1] / w2 - 1) < 0.01:
            break
        w1, w2 = new
    res = levenberg_marquardt(model(w1, w2), theta, correction=_correction(m, us, theta, sigma2, w1, w2), tol=1e-10)
    rows_blocks = np.concatenate([blocks, blocks[static]])
    jd, rd = res.jacobian[:n_rows], res.residual[:n_rows]
    prior_info = np.zeros((13, 13))
    prior_info[idx, idx] = 1.0 / sig_p**2
    cov, ratio = sandwich_covariance(jd, rd, rows_blocks, prior_info)  # data rows at unit noise
    th = res.theta
    weak = tuple(int(i) for i in idx if np.sqrt(cov[i, i]) > 0.5 * sig_p)
    return AidedFit(th[:9].reshape(3, 3), th[9:12], float(th[12]), cov, float(np.std(rd[:n1] / w1)),
                    float(np.std(rd[n1:] / w2)), ratio, rd[:n1] / w1, rd[n1:] / w2, jd, rd, weak, prior_info)
