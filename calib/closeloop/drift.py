"""Random-walk coefficient of a slow bias drift by restricted maximum likelihood.

Residual block means m_b (block length T s, per axis) = drift + white noise:
    Cov(m_i, m_j) = K² W_ij + σ² δ_ij,   W_ij = T·(min(i, j) + ½) for i ≠ j,  W_ii = T·(i + ⅓),
the covariance of block means of a Wiener process started at 0 (∫∫ min(s, u) over the two
blocks / T²).  The unknown start value (the bias) is removed by projecting onto the contrasts
orthogonal to a constant (REML, Patterson & Thompson 1971).  K (rad/s/√s) and σ are found by
maximising the likelihood pooled over the axes; the standard error of K from the observed
information (numerical second derivative of the log-likelihood in ln K²).
"""

from __future__ import annotations

import math

import numpy as np
from scipy import optimize

__all__ = ["random_walk_mle"]


def _wiener_block_cov(n: int, block_s: float) -> np.ndarray:
    i = np.arange(n)
    w = block_s * (np.minimum.outer(i, i) + 0.5)
    w[i, i] = block_s * (i + 1.0 / 3.0)
    return w


def random_walk_mle(series: list[np.ndarray], block_s: float) -> tuple[float, float]:
    """(K, σ_K) in units/√s from per-axis residual block means (each (B,)) of length ``block_s`` s."""
    n = min(s.size for s in series)
    if n < 8:
        return float("nan"), float("nan")
    w = _wiener_block_cov(n, block_s)
    q, _ = np.linalg.qr(np.column_stack([np.ones(n), np.eye(n)[:, : n - 1]]))
    c = q[:, 1:]                       # contrasts ⟂ constant
    wc = c.T @ w @ c
    ys = [c.T @ s[:n] for s in series]
    evals, evecs = np.linalg.eigh(wc)
    zs = [evecs.T @ y for y in ys]

    def nll(p: np.ndarray) -> float:
        k2, s2 = math.exp(p[0]), math.exp(p[1])
        lam = k2 * evals + s2
        return 0.5 * sum(float(np.sum(np.log(lam) + z**2 / lam)) for z in zs)

    s2_0 = float(np.mean([np.var(np.diff(s[:n])) / 2 for s in series])) + 1e-300
    best = min(
        (
            optimize.minimize(
                nll,
                [math.log(max(s2_0 * f / block_s, 1e-300)), math.log(s2_0)],
                method="Nelder-Mead",
                options={"xatol": 1e-6, "fatol": 1e-6, "maxiter": 2000},
            )
            for f in (1e-3, 1e-1, 10.0)
        ),
        key=lambda r: r.fun,
    )
    h = 1e-3
    p = best.x
    d2 = (nll(p + [h, 0]) - 2 * nll(p) + nll(p - [h, 0])) / h**2
    k = math.exp(0.5 * p[0])
    sig_lnk2 = 1.0 / math.sqrt(d2) if d2 > 0 else float("inf")
    return k, 0.5 * k * sig_lnk2
