"""Small nonlinear least squares for the magnetometer fits: Levenberg–Marquardt on a residual
with an analytic Jacobian, and a covariance that stays honest when the residuals are correlated.

Covariance: the block (cluster-robust) sandwich estimator

    Cov(θ) = (JᵀWJ)⁻¹ (Σ_b s_b s_bᵀ) (JᵀWJ)⁻¹ · B/(B − P),    s_b = Σ_{k ∈ b} J_kᵀ w_k r_k

over B contiguous time blocks (Liang & Zeger 1986; the cluster-robust form of White 1980), with the
small-sample factor B/(B − P).  With white residuals it equals the classic σ̂²(JᵀWJ)⁻¹ in
expectation; when hand motion, an unmodelled effect or filtered noise make neighbouring residuals
correlate, it grows with the correlation instead of claiming the white-noise precision.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

__all__ = ["LsqResult", "levenberg_marquardt", "sandwich_covariance", "block_index", "cluster_jackknife", "with_prior"]


@dataclass(frozen=True)
class LsqResult:
    """Where :func:`levenberg_marquardt` stopped: θ, the weighted residual and Jacobian there, the
    iterations taken and whether the cost decrease fell below the tolerance."""

    theta: np.ndarray
    residual: np.ndarray  # weighted residual at θ (M,)
    jacobian: np.ndarray  # weighted Jacobian at θ (M, P)
    iterations: int
    converged: bool


def levenberg_marquardt(fun: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]], theta0: np.ndarray, *,
                        max_iter: int = 50, tol: float = 1e-12, correction: np.ndarray | None = None) -> LsqResult:
    """Minimise ‖r(θ)‖² − θᵀMθ with ``fun(θ) → (r, J)``: Gauss–Newton steps with Marquardt's
    scaled damping (JᵀJ − M + λ diag(JᵀJ)) δ = −(Jᵀr − Mθ), λ divided by 3 after a successful step
    and multiplied by 4 after a failed one; stops when the relative cost decrease is below ``tol``.

    ``correction`` M (P×P, default 0) is the adjusted-least-squares term that removes the bias a
    noisy regressor puts into a residual linear in the parameters (E‖r‖² = ‖r*‖² + θᵀMθ; Kukush,
    Markovsky & Van Huffel, "Consistent least squares fitting of ellipsoids", Numer. Math. 98, 2004)."""
    theta = np.asarray(theta0, dtype=float).copy()
    mcor = np.zeros((theta.size, theta.size)) if correction is None else np.asarray(correction, dtype=float)

    def total(r: np.ndarray, th: np.ndarray) -> float:
        return float(r @ r) - float(th @ mcor @ th)

    r, jac = fun(theta)
    cost = total(r, theta)
    lam = 1e-6
    converged = False
    it = 0
    for it in range(1, max_iter + 1):
        jtj = jac.T @ jac - mcor
        g = jac.T @ r - mcor @ theta
        d = np.diag(jtj).copy()
        d[d <= 0] = 1.0
        improved = False
        for _ in range(12):
            try:
                step = -np.linalg.solve(jtj + lam * np.diag(d), g)
            except np.linalg.LinAlgError:
                lam *= 4
                continue
            # predicted decrease of the cost below rounding: θ is a minimum to working precision
            if -(2 * g @ step + step @ jtj @ step) <= 1e-14 * abs(cost):
                break
            r_new, jac_new = fun(theta + step)
            cost_new = total(r_new, theta + step)
            if np.isfinite(cost_new) and cost_new <= cost:
                improved = True
                break
            lam *= 4
        if not improved:
            converged = True  # no step lowers the cost: a minimum to working precision
            break
        theta = theta + step
        rel = (cost - cost_new) / max(abs(cost), 1e-300)
        r, jac, cost = r_new, jac_new, cost_new
        lam = max(lam / 3, 1e-12)
        if rel < tol:
            converged = True
            break
    return LsqResult(theta, r, jac, it, converged)


def with_prior(fun: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]], idx: np.ndarray, centre: np.ndarray,
               weight: np.ndarray) -> Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]:
    """``fun`` with Gaussian prior rows w_i (θ_i − c_i) appended for the parameters ``idx``: the
    posterior mode, and a fit that cannot wander off along a direction the data do not see (a
    partly covered ellipsoid grows without bound along its unseen axis).  The data rows must be
    scaled to unit noise for w = 1/σ_prior to mean what it says; the caller passes w = σ_data/σ_prior."""
    idx = np.asarray(idx)

    def aug(theta: np.ndarray):
        r, j = fun(theta)
        jp = np.zeros((idx.size, theta.size))
        jp[np.arange(idx.size), idx] = weight
        return np.concatenate([r, weight * (theta[idx] - centre)]), np.vstack([j, jp])

    return aug


def block_index(n: int, block: int, min_blocks: int = 30) -> np.ndarray:
    """Block number of each of n consecutive samples: blocks of ``block`` samples, shortened so
    that there are at least ``min_blocks`` of them (the sandwich needs many more blocks than
    parameters)."""
    block = max(1, min(block, n // min_blocks if n >= min_blocks else 1))
    return np.arange(n) // block


def sandwich_covariance(jac: np.ndarray, resid: np.ndarray, blocks: np.ndarray,
                        prior_info: np.ndarray | None = None) -> tuple[np.ndarray, float]:
    """Block-robust covariance of the LS estimate (module docstring) and the median ratio of its
    variances to the classic white-residual ones (≈ 1 for white residuals, larger when correlated).

    ``jac`` and ``resid`` are the weighted Jacobian and residual of the data rows at the solution
    (``prior_info`` = the prior rows' JᵀJ in the same units: with it the result is the posterior
    covariance, which tends to the prior's where the data see nothing); ``blocks`` the
    block number of each row (a block = a stretch of time; rows of several residual kinds that
    share a time block are summed together, since their errors may correlate)."""
    m, p = jac.shape
    info = jac.T @ jac + (0.0 if prior_info is None else prior_info)
    inv = np.linalg.pinv(info)
    scores = jac * resid[:, None]
    if np.any(np.diff(blocks) < 0):  # rows of several residual kinds: gather each block's rows
        order = np.argsort(blocks, kind="stable")
        scores, blocks = scores[order], blocks[order]
    starts = np.flatnonzero(np.r_[True, blocks[1:] != blocks[:-1]])
    s = np.add.reduceat(scores, starts, axis=0)
    nb = s.shape[0]
    factor = nb / max(nb - p, 1)
    meat = s.T @ s * factor
    if prior_info is not None:  # prior rows act as data rows of the residual's variance (posterior)
        meat = meat + prior_info * float(resid @ resid) / m
    cov = inv @ meat @ inv
    sigma2 = float(resid @ resid) / max(m - p, 1)
    classic = inv * sigma2
    dc = np.diag(classic)
    ok = dc > 0
    ratio = float(np.median(np.diag(cov)[ok] / dc[ok])) if ok.any() else float("nan")
    return 0.5 * (cov + cov.T), ratio


def cluster_jackknife(jac: np.ndarray, resid: np.ndarray, clusters: np.ndarray) -> np.ndarray:
    """Delete-one-cluster jackknife covariance of the LS estimate, one-step (Gauss–Newton) form:
    θ₍₋g₎ − θ̂ ≈ (JᵀJ − J_gᵀJ_g)⁻¹ J_gᵀ r_g, Cov = (G − 1)/G Σ_g (θ₍₋g₎ − θ̂)(θ₍₋g₎ − θ̂)ᵀ
    (Efron & Stein 1981; MacKinnon & White 1985 "HC3" for clusters).  With long clusters (10 s) it
    sees residual correlations that the 1 s blocks of :func:`sandwich_covariance` cannot."""
    order = np.argsort(clusters, kind="stable")
    j, r, c = jac[order], resid[order], clusters[order]
    starts = np.flatnonzero(np.r_[True, c[1:] != c[:-1]])
    ends = np.r_[starts[1:], c.size]
    info = j.T @ j
    deltas = []
    for a, b in zip(starts, ends):
        jg = j[a:b]
        try:
            deltas.append(np.linalg.solve(info - jg.T @ jg, jg.T @ r[a:b]))
        except np.linalg.LinAlgError:
            deltas.append(np.linalg.lstsq(info - jg.T @ jg, jg.T @ r[a:b], rcond=None)[0])
    d = np.array(deltas)
    g = d.shape[0]
    return (g - 1) / g * d.T @ d
