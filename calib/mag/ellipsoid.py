"""The classic ellipsoid fit of a magnetometer (hard and soft iron from the field magnitude alone).

Model (Ozyagcilar, Freescale AN4246 eq. 8; Vasconcelos et al., IEEE TIM 60(6) 2011):

    m = A B + h,  |B| = F   ⇔   |L (m − h)| = F,  L = A⁻¹

so the samples lie on the ellipsoid (m − h)ᵀ Q (m − h) = 1, Q = LᵀL / F².  Only Q is seen: A is
determined up to a rotation on the right (A → A Rᵀ keeps every |B|), so the fit reports the
**symmetric** A (L = Q^½ F), and the rotation between the magnetometer and the IMU frame (the
misalignment) stays invisible — :mod:`calib.mag.aided` recovers it from the attitude.  The scale
of A and F is one more gauge: F is the field magnitude in the sensor's own average scale, fixed
by **det A = 1**, unless the true field magnitude is given (World Magnetic Model), which fixes A
absolutely.

Two steps:

1. **Algebraic, ellipsoid-specific** (Li & Griffiths, "Least squares ellipsoid specific fitting",
   GMP 2004): the quadric a x² + b y² + c z² + 2f yz + 2g xz + 2h xy + 2p x + 2q y + 2r z + d = 0
   fitted by minimising ‖D v‖² subject to the **constraint 4J − I² = 1** (I = a + b + c,
   J = ab + bc + ca − f² − g² − h²), which admits only ellipsoids (whose short axis is at least
   half the long one: any magnetometer); a generalised eigenproblem, no iteration.  Data are
   centred and scaled first for conditioning.
2. **Geometric refinement** (Levenberg–Marquardt) of r_k = |L (m_k − h)| − 1 over the symmetric
   L (6) and h (3): the maximum-likelihood fit for isotropic white sensor noise to first order
   (the algebraic residual weights points by their distance and is biased), and the source of
   the covariance (block sandwich, :mod:`calib.mag.lsq`).  Its second-order noise bias (it grows
   where the coverage is uneven: a session spends half its time at rest in one pose) is removed:
   the residual's noise mean is subtracted (:func:`noise_bias`) and the adjusted-least-squares
   term of Kukush, Markovsky & Van Huffel (Numer. Math. 98, 2004) is taken off the cost.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib.mag.lsq import levenberg_marquardt, sandwich_covariance, with_prior

__all__ = ["EllipsoidFit", "algebraic_ellipsoid", "fit_ellipsoid", "fit_sphere", "sym", "SYM_IDX", "sqrtm_psd",
           "white_noise_variance", "noise_bias"]

SYM_IDX = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))
PRIOR_REL = 0.3  # prior σ of the soft iron, relative


def sym(v: np.ndarray) -> np.ndarray:
    """Symmetric 3×3 from (s11, s22, s33, s12, s13, s23)."""
    a, b, c, d, e, f = v
    return np.array([[a, d, e], [d, b, f], [e, f, c]])


def sqrtm_psd(q: np.ndarray) -> np.ndarray:
    """Symmetric square root of a symmetric positive-definite matrix (eigendecomposition)."""
    w, v = np.linalg.eigh(0.5 * (q + q.T))
    if np.any(w <= 0):
        raise np.linalg.LinAlgError("matrix is not positive definite")
    return (v * np.sqrt(w)) @ v.T


def algebraic_ellipsoid(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(centre h, Q) with (x − h)ᵀ Q (x − h) = 1, Li & Griffiths' ellipsoid-specific fit (k = 4).

    Falls back to the unconstrained algebraic fit (smallest singular vector) if the constrained
    one does not give a positive-definite Q (data far from an ellipsoid)."""
    c0 = x.mean(axis=0)
    s = float(np.sqrt(np.mean(np.sum((x - c0) ** 2, axis=1)))) or 1.0
    u = (x - c0) / s
    X, Y, Z = u[:, 0], u[:, 1], u[:, 2]
    D = np.column_stack([X * X, Y * Y, Z * Z, 2 * Y * Z, 2 * X * Z, 2 * X * Y, 2 * X, 2 * Y, 2 * Z, np.ones_like(X)])
    S = D.T @ D
    s11, s12, s22 = S[:6, :6], S[:6, 6:], S[6:, 6:]
    k = 4.0
    c1 = np.zeros((6, 6))
    c1[:3, :3] = k / 2 - 1
    np.fill_diagonal(c1[:3, :3], -1.0)
    c1[3:, 3:] = -k * np.eye(3)
    try:
        s22_inv_s21 = np.linalg.solve(s22, s12.T)
        m = np.linalg.solve(c1, s11 - s12 @ s22_inv_s21)
        w, vecs = np.linalg.eig(m)
        w, vecs = w.real, vecs.real
        v1 = vecs[:, int(np.argmax(w))]
        v = np.concatenate([v1, -s22_inv_s21 @ v1])
        h, q = _quadric_to_ellipsoid(v)
    except np.linalg.LinAlgError:
        h = q = None
    if q is None or np.any(np.linalg.eigvalsh(q) <= 0):
        _, _, vt = np.linalg.svd(D, full_matrices=False)
        h, q = _quadric_to_ellipsoid(vt[-1])
    return c0 + s * h, q / s**2


def _quadric_to_ellipsoid(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    a, b, c, f, g, hh, p, q, r, d = v
    m3 = np.array([[a, hh, g], [hh, b, f], [g, f, c]])
    uvec = np.array([p, q, r])
    centre = -np.linalg.solve(m3, uvec)
    scale = float(centre @ m3 @ centre - d)
    return centre, m3 / scale


@dataclass(frozen=True)
class EllipsoidFit:
    """|L (m − h)| = 1 with L symmetric: parameters θ = (L11, L22, L33, L12, L13, L23, h), their
    block-sandwich covariance, and the fit's residual (dimensionless, ≈ noise/F)."""

    l_matrix: np.ndarray
    centre: np.ndarray
    cov: np.ndarray
    residual: np.ndarray
    correlation_ratio: float
    iterations: int
    jacobian: np.ndarray | None = None  # at the solution (data rows), for the jackknife
    weak: tuple[int, ...] = ()  # L entries (SYM_IDX order) the data did not decide (posterior σ > ½ prior σ)
    prior_info: np.ndarray | None = None

    @property
    def theta(self) -> np.ndarray:
        return np.concatenate([[self.l_matrix[i, j] for i, j in SYM_IDX], self.centre])


def noise_bias(lm: np.ndarray, v_norm: np.ndarray, n: np.ndarray, sigma2: float) -> np.ndarray:
    """Mean of the noisy magnitude residual to second order: with m = m* + ε, ε ~ N(0, σ²I),
    E|L(d* + ε)| = |v| + σ²(‖L‖²_F − |Lᵀn|²)/(2|v|) (v = L d*, n = v/|v|).  Subtracted from the
    residual it removes the bias that makes a geometric fit of a partly covered ellipsoid pull its
    centre away from the arcs it saw (0.04 µT, 2σ, on zhou2020 at the AK8963's noise; measured)."""
    lt_n = n @ lm
    return sigma2 * (np.sum(lm * lm) - np.sum(lt_n * lt_n, axis=1)) / (2 * v_norm)


def white_noise_variance(m: np.ndarray) -> float:
    """Per-axis white-noise variance (µT²) of field samples from second differences: var(Δ²m) = 6σ²
    for white noise (the signal's curvature ω²Δt²|B| is ~0.002 µT at 100 Hz); median-based
    (× 1.4826² on the MAD) so that fast turns do not inflate it; rows that repeat the previous one
    (a magnetometer read slower than the log) are dropped first."""
    fresh = np.r_[True, np.any(np.diff(m, axis=0) != 0, axis=1)]  # a sensor read slower than the log repeats rows
    d2 = np.diff(m[fresh], n=2, axis=0)
    if d2.shape[0] < 10:
        return 0.0
    mad = np.median(np.abs(d2 - np.median(d2, axis=0)), axis=0) * 1.4826
    return float(np.mean(mad**2) / 6.0)


def _g_matrix(n: np.ndarray) -> np.ndarray:
    """G(n) (N, 3, 6) with L n = G(n) θ_L for symmetric L (θ_L = L11, L22, L33, L12, L13, L23)."""
    g = np.zeros((n.shape[0], 3, 6))
    g[:, 0, 0], g[:, 0, 3], g[:, 0, 4] = n[:, 0], n[:, 1], n[:, 2]
    g[:, 1, 1], g[:, 1, 3], g[:, 1, 5] = n[:, 1], n[:, 0], n[:, 2]
    g[:, 2, 2], g[:, 2, 4], g[:, 2, 5] = n[:, 2], n[:, 0], n[:, 1]
    return g


def _sym_residual(x: np.ndarray, sigma2: float):
    def fun(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        lm = sym(theta[:6])
        d = x - theta[6:]
        v = d @ lm.T
        nv = np.linalg.norm(v, axis=1)
        n = v / nv[:, None]
        jac = np.empty((x.shape[0], 9))
        for k, (i, j) in enumerate(SYM_IDX):
            jac[:, k] = n[:, i] * d[:, j] if i == j else n[:, i] * d[:, j] + n[:, j] * d[:, i]
        jac[:, 6:] = -(n @ lm)  # ∂r/∂h = −Lᵀn  (L symmetric)
        return nv - 1.0 - noise_bias(lm, nv, n, sigma2), jac

    return fun


def _sym_correction(x: np.ndarray, theta: np.ndarray, sigma2: float) -> np.ndarray:
    """ALS term: E[noise part of Σ r²] = σ² Σ |L n_k|² = θ_Lᵀ (σ² Σ G_kᵀG_k) θ_L (n_k at θ)."""
    lm = sym(theta[:6])
    v = (x - theta[6:]) @ lm.T
    g = _g_matrix(v / np.linalg.norm(v, axis=1, keepdims=True))
    mc = np.zeros((9, 9))
    mc[:6, :6] = sigma2 * np.einsum("nki,nkj->ij", g, g)
    return mc


def fit_ellipsoid(x: np.ndarray, blocks: np.ndarray, start: tuple[np.ndarray, np.ndarray] | None = None,
                  noise_var: float | None = None, prior_rel: float = PRIOR_REL) -> EllipsoidFit:
    """Algebraic start (unless ``start`` = (L, h) is given) and geometric refinement (module docstring).

    ``x`` (N, 3) field samples (µT); ``blocks`` (N,) block numbers for the sandwich covariance;
    ``noise_var`` the per-axis white-noise variance of x for the second-order bias correction
    (default: from second differences, :func:`white_noise_variance`; 0 switches it off);
    ``prior_rel`` the prior's σ of the soft iron, relative (A ~ I ± 30 %: no magnetometer on a
    working board is further off), centred on a sphere of the start's size.  The prior bounds the
    fit where the data leave a direction unseen; :attr:`EllipsoidFit.weak` names the L entries
    whose posterior σ stays above half the prior's (the data did not decide them)."""
    if start is None:
        h0, q0 = algebraic_ellipsoid(x)
        try:
            l0 = sqrtm_psd(q0)
            ax = 1 / np.linalg.eigvalsh(l0)
            if ax.max() > 2 * ax.min():  # not a magnetometer's ellipsoid: start from a sphere
                raise np.linalg.LinAlgError
        except np.linalg.LinAlgError:
            h0, f0, _, _ = fit_sphere(x, blocks)
            l0 = np.eye(3) / f0
    else:
        l0, h0 = start
    radius = 3.0 / np.trace(l0)
    sigma2 = white_noise_variance(x) if noise_var is None else float(noise_var)
    theta0 = np.concatenate([[l0[i, j] for i, j in SYM_IDX], h0])
    idx = np.arange(6)
    centre = np.array([1.0, 1.0, 1.0, 0.0, 0.0, 0.0]) / radius
    sig_p = prior_rel / radius
    r0, _ = _sym_residual(x, sigma2)(theta0)
    sig_r = float(np.sqrt(np.mean(r0**2)))
    res = None
    for _ in range(2):  # prior weight from the residual's level, then from the fit's
        w = np.full(6, sig_r / sig_p)
        fun = with_prior(_sym_residual(x, sigma2), idx, centre, w)
        res = levenberg_marquardt(fun, theta0 if res is None else res.theta,
                                  correction=_sym_correction(x, theta0 if res is None else res.theta, sigma2),
                                  max_iter=30, tol=1e-10)
        sig_r = float(np.sqrt(np.mean(res.residual[: x.shape[0]] ** 2)))
    n = x.shape[0]
    jd, rd = res.jacobian[:n], res.residual[:n]
    prior_info = np.zeros((9, 9))
    prior_info[idx, idx] = w**2
    cov, ratio = sandwich_covariance(jd, rd, blocks, prior_info)
    weak = tuple(int(i) for i in idx if np.sqrt(cov[i, i]) > 0.5 * sig_p)
    return EllipsoidFit(sym(res.theta[:6]), res.theta[6:], cov, rd, ratio, res.iterations, jd, weak, prior_info)


def fit_sphere(x: np.ndarray, blocks: np.ndarray) -> tuple[np.ndarray, float, np.ndarray, np.ndarray]:
    """Hard iron only: |m − h| = F.  Linear start |m|² = 2hᵀm + (F² − |h|²), then the geometric
    fit of r = |m − h| − F; returns (h, F, covariance of (h, F), residual)."""
    a = np.column_stack([2 * x, np.ones(x.shape[0])])
    sol, *_ = np.linalg.lstsq(a, np.sum(x * x, axis=1), rcond=None)
    h0 = sol[:3]
    f0 = float(np.sqrt(max(sol[3] + h0 @ h0, 1e-12)))

    def fun(theta):
        d = x - theta[:3]
        nd = np.linalg.norm(d, axis=1)
        jac = np.column_stack([-d / nd[:, None], -np.ones_like(nd)])
        return nd - theta[3], jac

    res = levenberg_marquardt(fun, np.concatenate([h0, [f0]]))
    cov, _ = sandwich_covariance(res.jacobian, res.residual, blocks)
    return res.theta[:3], float(res.theta[3]), cov, res.residual
