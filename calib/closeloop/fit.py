"""Least-squares fit of a linear-in-θ gyro model against a reference, and its held-out score.

Model: y = ω + Σ_i R_i θ_i + ε (see :mod:`calib.closeloop.reference`).  The fit solves the
Gauss–Newton normal equations of the reference's residual rows r(θ) (one step when the
reference is linear), on the columns scaled to unit norm so that parameters of very different
units (rad/s, 1/°C, s) are conditioned alike; the rank is counted with a relative singular-value
tolerance, so a column the data cannot excite does not count as a parameter.

Held-out score of adding columns (the information criterion of issue 5, step c): fit both the
current model and the extended one on the *fit* rows (even held-out groups), evaluate both on the
*held-out* rows (odd groups), and compute

    G = n_eff · ln(RSS₀ / RSS₁) − Δp · ln(n_eff),          n_eff = n_held / τ_int,

the held-out log-likelihood gain of a Gaussian residual minus the BIC penalty of the Δp new
identifiable parameters (Schwarz 1978).  τ_int is the integrated autocorrelation time of the
current held-out residual (Sokal's window, summed until the autocorrelation first turns
negative), so correlated residuals (optical noise, drift) do not count as more independent
samples than they are.  Adding a column that explains nothing cannot raise RSS₀/RSS₁ on
held-out rows on average, so G > 0 requires explained structure worth about √(ln n_eff) ≈ 3σ
per parameter.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .reference import Reference

__all__ = ["FitResult", "fit_model", "integrated_time", "HeldOutScore", "held_out_score"]


@dataclass(frozen=True)
class FitResult:
    theta: np.ndarray        # (P,) parameters in the candidates' units
    cov: np.ndarray          # (P, P) covariance, inflated by τ_int
    residual: np.ndarray     # (M,) residual rows of all rows at θ
    rank: int                # identifiable columns on the fit rows
    tau_int: float           # autocorrelation time of the fit-row residual (rows)


def integrated_time(r: np.ndarray, axes: np.ndarray | None = None, max_lag: int = 2000) -> float:
    """Integrated autocorrelation time τ = 1 + 2 Σ_{k≥1} ρ_k (summed while ρ_k > 0), averaged over axes."""
    series = [r] if axes is None else [r[axes == a] for a in np.unique(axes) if (axes == a).sum() > 8]
    taus = []
    for s in series:
        s = s - s.mean()
        n = s.size
        if n < 8 or not np.any(s):
            continue
        nfft = 1 << (2 * n - 1).bit_length()
        f = np.fft.rfft(s, nfft)
        acf = np.fft.irfft(f * np.conj(f), nfft)[: min(n, max_lag)]
        acf = acf / acf[0]
        neg = np.nonzero(acf[1:] <= 0)[0]
        stop = neg[0] + 1 if neg.size else acf.size
        taus.append(max(1.0, 1.0 + 2.0 * float(np.sum(acf[1:stop]))))
    return float(np.mean(taus)) if taus else 1.0


def _solve(j: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """δ minimising ‖r − J δ‖ (scaled columns), its unscaled (JᵀJ)⁻¹ and the numerical rank."""
    scale = np.linalg.norm(j, axis=0)
    scale[scale == 0] = 1.0
    js = j / scale
    u, s, vt = np.linalg.svd(js, full_matrices=False)
    keep = s > s[0] * 1e-8 if s.size and s[0] > 0 else np.zeros(s.size, bool)
    inv = np.where(keep, 1.0 / np.where(keep, s, 1.0), 0.0)
    delta = (vt.T * inv) @ (u.T @ r)
    cov = (vt.T * inv**2) @ vt
    return delta / scale, cov / np.outer(scale, scale), int(keep.sum())


def fit_model(ref: Reference, regressors: np.ndarray, rows: np.ndarray | None = None,
              iterations: int = 4, theta0: np.ndarray | None = None,
              bounds: tuple[np.ndarray, np.ndarray] | None = None) -> FitResult:
    """Fit θ of the stacked regressors (N, 3, P) on the selected residual rows (bool mask, default all).

    ``theta0``: start of a nonlinear fit (a model fitted before, extended by zeros), so that an
    extended or all-rows refit stays in the basin of the solution already found."""
    y = _measured(ref)
    p = regressors.shape[2]
    sel = slice(None) if rows is None else rows
    theta = np.zeros(p)
    if p == 0:
        r = ref.residual(y, np.zeros_like(y))
        cov, rank = np.zeros((0, 0)), 0
    elif ref.linear:
        delta, cov, rank = _solve(ref.jacobian(regressors, y, 0.0)[sel], ref.residual(y, np.zeros_like(y))[sel])
        theta = delta
    else:
        # trust-region least squares with the analytic Jacobian: plain Gauss–Newton steps along weakly
        # determined directions leave the linear range of the pose-to-pose rotation (measured on the
        # Ferraris session: one full step took the tilt error from 10° to 38°)
        from scipy import optimize

        def fun(th):
            return ref.residual(y, regressors @ th)[sel]

        def jac(th):
            return -ref.jacobian(regressors, y, regressors @ th)[sel]

        if theta0 is not None:
            theta = np.asarray(theta0, dtype=float).copy()
        col = np.linalg.norm(jac(theta), axis=0)
        lb, ub = bounds if bounds is not None else (np.full(p, -np.inf), np.full(p, np.inf))
        theta = np.clip(theta, lb + 1e-12, ub - 1e-12)
        sol = optimize.least_squares(fun, theta, jac=jac, method="trf", x_scale=1.0 / np.where(col > 0, col, 1.0),
                                     bounds=(lb, ub), max_nfev=5 * iterations)
        theta = sol.x
        _, cov, rank = _solve(-jac(theta), fun(theta))
    r = ref.residual(y, regressors @ theta)
    sel = np.ones(r.size, bool) if rows is None else rows
    tau = integrated_time(r[sel], ref.row_axis[sel] if ref.kind != "gravity" else None)
    dof = max(1, int(sel.sum()) - rank)
    s2 = float(r[sel] @ r[sel]) / dof
    return FitResult(theta, cov * s2 * tau, r, rank, tau)


def _measured(ref: Reference) -> np.ndarray:
    y = getattr(ref, "y_rad_s", None)
    return ref.ctx.omega_true_rad_s if y is None else y


@dataclass(frozen=True)
class HeldOutScore:
    gain: float            # G (see module docstring); > 0: worth adding
    rms_before: float      # held-out residual RMS of the current model (row units)
    rms_after: float       # ... with the new columns
    added_rank: int        # Δp
    n_eff: float
    theta_new: np.ndarray  # the new columns' parameters fitted on the fit rows


def held_out_split(ref: Reference) -> tuple[np.ndarray, np.ndarray]:
    """(fit rows, held-out rows): even and odd held-out groups."""
    even = ref.groups % 2 == 0
    return even, ~even


def held_out_score(ref: Reference, base: np.ndarray, extra: np.ndarray, base_fit: FitResult | None = None,
                   bounds: tuple[np.ndarray, np.ndarray] | None = None) -> HeldOutScore:
    """Score of adding the columns ``extra`` (N, 3, P') to ``base`` (N, 3, P) on held-out rows
    (``bounds``: the box of base and extra parameters together, for nonlinear references)."""
    fit_rows, held = held_out_split(ref)
    f0 = base_fit or fit_model(ref, base, fit_rows)
    f1 = fit_model(ref, np.concatenate([base, extra], axis=2), fit_rows,
                   theta0=np.concatenate([f0.theta, np.zeros(extra.shape[2])]), bounds=bounds)
    r0, r1 = f0.residual[held], f1.residual[held]
    rss0, rss1 = float(r0 @ r0), float(r1 @ r1)
    # τ of the *extended* model's residual: the current one still holds the structure under test,
    # which would count as correlation and shrink n_eff exactly when the candidate is right
    tau = integrated_time(r1, ref.row_axis[held] if ref.kind != "gravity" else None)
    n_eff = max(2.0, held.sum() / tau)
    dp = max(0, f1.rank - f0.rank)
    gain = n_eff * math.log(rss0 / rss1) - dp * math.log(n_eff) if rss1 > 0 and dp > 0 else -math.inf
    p0 = base.shape[2]
    return HeldOutScore(gain, math.sqrt(rss0 / held.sum()), math.sqrt(rss1 / held.sum()), dp, n_eff, f1.theta[p0:])
