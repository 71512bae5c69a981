"""Least-squares fit of a linear-in-θ gyro model against a reference, and its held-out score.

Model: y = ω + Σ_i R_i θ_i + ε (see :mod:`calib.closeloop.reference`).  The fit solves the
Gauss–Newton normal equations of the reference's residual rows r(θ) (one step when the reference is
linear), on the columns scaled to unit norm so that parameters of very different units (rad/s,
1/°C, s) are conditioned alike; the rank is counted with a relative singular-value tolerance, so a
column the data cannot excite does not count as a parameter.

Bounded work: the rows [J | r] are first reduced chunk by chunk to their (P+1)×(P+1) triangular
factor (a tall-skinny QR: QR of each chunk, then QR of the stacked factors), and the SVD runs on
that.  Memory and time are O(M P²) with chunks of ≤ 20 000 rows, and the SVD no longer sees the
M rows at all — a 10-hour record costs what its row count says, not a full M×P SVD.

Held-out score of adding columns (the information criterion): fit both the current model and the
extended one on the *fit* rows (even held-out groups), evaluate both on the *held-out* rows (odd
groups), and compute

    G = n_eff · ln(RSS₀ / RSS₁) − Δp · ln(n_eff),          n_eff = n_held / τ_int,

the held-out log-likelihood gain of a Gaussian residual minus the BIC penalty of the Δp new
identifiable parameters (Schwarz 1978).  τ_int is the integrated autocorrelation time of the
extended model's held-out residual (Sokal's window, summed until the autocorrelation first turns
negative), so correlated residuals (optical noise, drift) do not count as more independent samples
than they are.  G > 0 requires explained structure worth about √(ln n_eff) ≈ 3σ per parameter.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from calib.closeloop.candidates import Candidate
from calib.closeloop.reference import Reference

__all__ = [
    "FitResult",
    "fit_model",
    "integrated_time",
    "HeldOutScore",
    "held_out_score",
    "held_out_split",
    "noise_tau",
    "UnionDesign",
    "cluster_robust",
    "reduce_rows",
    "design_rows",
    "stack_bounds",
]

CHUNK_ROWS = 20_000


@dataclass(frozen=True)
class FitResult:
    """A model fitted on the reference's residual rows: θ and its covariance, the residual of all rows at
    θ, and the fit rows' rank, autocorrelation time and residual σ (plus the reduced factor of a linear
    reference, kept for the gate)."""

    theta: np.ndarray        # (P,) parameters in the candidates' units
    cov: np.ndarray          # (P, P) covariance, inflated by τ_int (see also cluster_robust)
    residual: np.ndarray     # (M,) residual rows of all rows at θ
    rank: int                # identifiable columns on the fit rows
    tau_int: float           # autocorrelation time of the fit-row residual (rows)
    sigma: float             # RMS of the fit-row residual per degree of freedom (row units)
    factor: np.ndarray | None = None   # linear references: R of [J/scale | r] on the fitted rows (P+1, P+1)
    scale: np.ndarray | None = None    # the column norms of J that scaled it


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


def reduce_rows(a: np.ndarray) -> np.ndarray:
    """Upper-triangular R (≤ K×K) with RᵀR = AᵀA for A (M, K), by chunked QR (bounded memory)."""
    m, k = a.shape
    if m <= CHUNK_ROWS:
        red = np.linalg.qr(a, mode="r") if m else np.zeros((0, k))
    else:
        parts = [np.linalg.qr(a[i : i + CHUNK_ROWS], mode="r") for i in range(0, m, CHUNK_ROWS)]
        red = np.linalg.qr(np.vstack(parts), mode="r")
    if red.shape[0] < k:  # fewer rows than columns: pad the factor with zero rows
        red = np.vstack([red, np.zeros((k - red.shape[0], k))])
    return red


def _solve(j: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """δ minimising ‖r − J δ‖ (scaled columns), its unscaled (JᵀJ)⁻¹ and the numerical rank."""
    delta, cov, rank, _, _ = _solve_factored(j, r)
    return delta, cov, rank


def _col_norms(j: np.ndarray) -> np.ndarray:
    return np.sqrt(np.einsum("ij,ij->j", j, j))


def _solve_factored(j: np.ndarray, r: np.ndarray):
    """:func:`_solve` plus the reduced factor of [J/scale | r] and the scale (kept for the gate)."""
    p = j.shape[1]
    scale = _col_norms(j)
    scale[scale == 0] = 1.0
    red = reduce_rows(np.column_stack([j / scale, r]))          # [[R_JJ, R_Jr], [0, ρ]]
    rjj, rjr = red[:p, :p], red[:p, p]
    u, s, vt = np.linalg.svd(rjj)
    keep = s > s[0] * 1e-8 if s.size and s[0] > 0 else np.zeros(s.size, bool)
    inv = np.where(keep, 1.0 / np.where(keep, s, 1.0), 0.0)
    delta = (vt.T * inv) @ (u.T @ rjr)
    cov = (vt.T * inv**2) @ vt
    return delta / scale, cov / np.outer(scale, scale), int(keep.sum()), red, scale


def design_rows(ref: Reference, terms: Sequence[Candidate], gyro_rad_s: np.ndarray,
                theta: np.ndarray | None = None) -> np.ndarray:
    """J (M, P): the residual rows' derivative −∂r/∂θ of the stacked terms (at θ for a nonlinear reference)."""
    if not terms:
        return np.zeros((ref.groups.size, 0))
    if ref.linear:
        return np.concatenate([t.rows for t in terms], axis=1)
    reg = stack_regressors(terms)
    corr = reg @ theta if theta is not None else np.zeros_like(gyro_rad_s)
    return ref.jacobian(reg, gyro_rad_s, corr)


def stack_regressors(terms: Sequence[Candidate]) -> np.ndarray:
    """(N, 3, P) ∂y/∂θ per sample of the stacked terms (rad/s per parameter unit), in the terms' order."""
    return np.concatenate([t.sample_regressors() for t in terms], axis=2)


def stack_bounds(terms: Sequence[Candidate]) -> tuple[np.ndarray, np.ndarray]:
    """(lower, upper) box of the stacked terms' parameters for a nonlinear fit (±the families' bound)."""
    if not terms:
        return np.zeros(0), np.zeros(0)
    lo, hi = zip(*(t.bounds() for t in terms))
    return np.concatenate(lo), np.concatenate(hi)


def _finish(ref: Reference, theta: np.ndarray, cov: np.ndarray, r: np.ndarray, rank: int,
            rows: np.ndarray | None, factor: np.ndarray | None = None, scale: np.ndarray | None = None) -> FitResult:
    sel = np.ones(r.size, bool) if rows is None else rows
    tau = integrated_time(r[sel], ref.row_axis[sel] if ref.kind != "gravity" else None)
    dof = max(1, int(sel.sum()) - rank)
    s2 = float(r[sel] @ r[sel]) / dof
    return FitResult(theta, cov * s2 * tau, r, rank, tau, math.sqrt(s2), factor, scale)


def fit_model(ref: Reference, terms: Sequence[Candidate], gyro_rad_s: np.ndarray, rows: np.ndarray | None = None,
              iterations: int = 4, theta0: np.ndarray | None = None) -> FitResult:
    """Fit θ of the stacked terms on the selected residual rows (bool mask, default all).

    ``gyro_rad_s``: the measured gyro (N, 3) with any output stage found so far undone.
    ``theta0``: start of a nonlinear fit (a model fitted before, extended by zeros), so that an
    extended or all-rows refit stays in the basin of the solution already found."""
    p = sum(t.n_params for t in terms)
    sel = slice(None) if rows is None else rows
    theta = np.zeros(p)
    if p == 0:
        r = ref.residual(gyro_rad_s, np.zeros_like(gyro_rad_s))
        return _finish(ref, theta, np.zeros((0, 0)), r, 0, rows)
    if ref.linear:
        j = design_rows(ref, terms, gyro_rad_s)
        r0 = ref.residual(gyro_rad_s, np.zeros_like(gyro_rad_s))
        theta, cov, rank, red, scale = _solve_factored(j[sel], r0[sel])
        return _finish(ref, theta, cov, r0 - j @ theta, rank, rows, red, scale)
    # trust-region least squares with the analytic Jacobian: plain Gauss–Newton steps along weakly
    # determined directions leave the linear range of the pose-to-pose rotation (measured on the
    # Ferraris session: one full step took the tilt error from 10° to 38°)
    from scipy import optimize

    reg = stack_regressors(terms)

    def fun(th):
        return ref.residual(gyro_rad_s, reg @ th)[sel]

    def jac(th):
        return -ref.jacobian(reg, gyro_rad_s, reg @ th)[sel]

    if theta0 is not None:
        theta = np.asarray(theta0, dtype=float).copy()
    col = np.linalg.norm(jac(theta), axis=0)
    lb, ub = stack_bounds(terms)
    theta = np.clip(theta, lb + 1e-12, ub - 1e-12)
    sol = optimize.least_squares(fun, theta, jac=jac, method="trf", x_scale=1.0 / np.where(col > 0, col, 1.0),
                                 bounds=(lb, ub), max_nfev=5 * iterations)
    theta = sol.x
    _, cov, rank = _solve(-jac(theta), fun(theta))
    return _finish(ref, theta, cov, ref.residual(gyro_rad_s, reg @ theta), rank, rows)


@dataclass(frozen=True)
class HeldOutScore:
    """What adding terms to the current model gains on the held-out rows: G (module docstring), the
    held-out residual sums of squares before and after, and the extended model fitted on the fit rows."""

    gain: float            # G (see module docstring); > 0: worth adding
    rss_before: float      # held-out residual sum of squares of the current model (row units²)
    rss_after: float       # ... with the new terms
    n_held: int
    added_rank: int        # Δp
    n_eff: float
    theta_new: np.ndarray  # the new terms' parameters fitted on the fit rows
    fit: FitResult         # the extended model fitted on the fit rows

    @property
    def rms_before(self) -> float:
        return math.sqrt(self.rss_before / self.n_held)

    @property
    def rms_after(self) -> float:
        return math.sqrt(self.rss_after / self.n_held)


def cluster_robust(ref: Reference, fit: FitResult, j: np.ndarray) -> FitResult:
    """``fit`` with each parameter's variance raised to its cluster-robust value where that is larger.

    θ̂ = U r with U = (JᵀJ)⁺Jᵀ, so var θ̂_j = Σ_{t,s} U_jt U_js Cov(r_t, r_s).  With the residual
    correlated within a held-out stretch (4 s) and not across stretches, the sandwich estimate is

        var θ̂_j = G/(G − 1) · Σ_g (Σ_{t ∈ g} U_jt r_t)²,      g the stretches (clusters),

    which weighs the residual's correlation with parameter j's own influence U_j: a slow regressor
    (a misalignment acting over a 9 s turn) sees a slow residual (a drift between spline knots)
    that τ_int — Sokal's window stops at the first negative autocorrelation — misses; a fast one
    (a time offset on tremor) does not.  Measured: next to a bias drift, the misalignment's σ from
    τ_int alone was 1.5–2× too small over 10 seeds.  The larger of the two variances is kept (the
    sandwich over ~40 stretches is itself ±11 % in σ); correlations keep their τ_int structure.
    Linear references only (the gravity reference's rows are per pose)."""
    if not ref.linear or fit.theta.size == 0:
        return fit
    groups = ref.groups
    g = np.unique(groups)
    if g.size < 8:
        return fit
    cov0 = fit.cov / (fit.sigma**2 * fit.tau_int) if fit.sigma > 0 else fit.cov
    u = cov0 @ j.T                                   # (P, M) influence of each row on θ̂
    z = u * fit.residual[None, :]
    _, inv = np.unique(groups, return_inverse=True)
    per = np.stack([np.bincount(inv, zi, minlength=g.size) for zi in z])   # (P, G)
    var_robust = g.size / (g.size - 1) * np.sum(per**2, axis=1)
    var_now = np.diag(fit.cov)
    scale = np.sqrt(np.maximum(var_robust, var_now) / np.where(var_now > 0, var_now, 1.0))
    return FitResult(fit.theta, fit.cov * np.outer(scale, scale), fit.residual, fit.rank, fit.tau_int, fit.sigma,
                     fit.factor, fit.scale)


class UnionDesign:
    """All fits of one round on a linear reference from one reduction.

    The round fits the current model plus each candidate, pairs of candidates and the richest model,
    always on the same fit rows.  The columns of all of them, [J_model | J_cands… | r₀] scaled to unit
    norm on the fit rows, are reduced once to R (chunked QR).  Any subset S of columns has
    R[:, S]ᵀR[:, S] = J_Sᵀ J_S, so the QR of the small R[:, S ∪ {r₀}] is the factor of that sub-model's
    least squares, without squaring the condition number — each fit then costs O(K³) plus one
    product for its residual rows, instead of a pass over the M rows."""

    def __init__(self, ref: Reference, base: Sequence[Candidate], cands: dict[str, Candidate], gyro_rad_s: np.ndarray):
        if not ref.linear:
            raise ValueError("UnionDesign needs a linear reference")
        self.ref = ref
        self.rows, _ = held_out_split(ref)
        self.base = list(base)
        self.index: dict[str, slice] = {}
        blocks = [t.rows for t in self.base]
        i = sum(t.n_params for t in self.base)
        for k, c in cands.items():
            self.index[k] = slice(i, i + c.n_params)
            blocks.append(c.rows)
            i += c.n_params
        self.p_base = sum(t.n_params for t in self.base)
        self.j = np.concatenate(blocks, axis=1) if blocks else np.zeros((ref.groups.size, 0))
        self.r0 = ref.residual(gyro_rad_s, np.zeros_like(gyro_rad_s))
        jf = self.j[self.rows]
        scale = _col_norms(jf)
        scale[scale == 0] = 1.0
        self.scale = scale
        jf /= scale
        self.red = reduce_rows(np.column_stack([jf, self.r0[self.rows]]))

    def fit(self, kinds: Sequence[str] = ()) -> FitResult:
        """The current model plus the candidates ``kinds``, fitted on the fit rows."""
        blocks = [slice(0, self.p_base)] + [self.index[k] for k in kinds]
        idx = np.concatenate([np.arange(b.start, b.stop) for b in blocks]).astype(int)
        p = idx.size
        sub = reduce_rows(self.red[:, np.append(idx, self.j.shape[1])])
        rjj, rjr = sub[:p, :p], sub[:p, p]
        u, sv, vt = np.linalg.svd(rjj)
        keep = sv > sv[0] * 1e-8 if sv.size and sv[0] > 0 else np.zeros(sv.size, bool)
        inv = np.where(keep, 1.0 / np.where(keep, sv, 1.0), 0.0)
        sc = self.scale[idx]
        theta = ((vt.T * inv) @ (u.T @ rjr)) / sc
        cov = ((vt.T * inv**2) @ vt) / np.outer(sc, sc)
        r = self.r0.copy()
        i = 0
        for b in blocks:   # contiguous column blocks: views, no copy of the M rows
            n = b.stop - b.start
            if n:
                r -= self.j[:, b] @ theta[i : i + n]
            i += n
        return _finish(self.ref, theta, cov, r, int(keep.sum()), self.rows, sub, sc)


def noise_tau(union: UnionDesign) -> float:
    """τ_int (rows) of the held-out residual of the richest model: the current model and every
    candidate of the round fitted together on the fit rows — the residual with the least structure
    left, whose correlation is the noise's own."""
    _, held = held_out_split(union.ref)
    rich = union.fit(list(union.index))
    return integrated_time(rich.residual[held], union.ref.row_axis[held])


def held_out_split(ref: Reference) -> tuple[np.ndarray, np.ndarray]:
    """(fit rows, held-out rows): even and odd held-out groups."""
    even = ref.groups % 2 == 0
    return even, ~even


def held_out_score(ref: Reference, base: Sequence[Candidate], base_fit: FitResult, extra: Sequence[Candidate],
                   gyro_rad_s: np.ndarray, tau: float | None = None, union: UnionDesign | None = None) -> HeldOutScore:
    """Score of adding the terms ``extra`` to ``base`` (fitted as ``base_fit`` on the fit rows) on held-out rows.

    ``tau``: the noise's autocorrelation time (rows) to count n_eff with; default that of the extended
    model's held-out residual.  When several effects are missing, each candidate's own residual still
    holds the others' structure, whose long correlation would crush every n_eff (measured: a warm-up
    and a g-sensitivity together left both with G < 0); the loop passes the τ of its richest model
    (:func:`noise_tau`)."""
    fit_rows, held = held_out_split(ref)
    p_new = sum(t.n_params for t in extra)
    if union is not None:
        f1 = union.fit([t.kind for t in extra])
    else:
        f1 = fit_model(ref, list(base) + list(extra), gyro_rad_s, fit_rows,
                       theta0=np.concatenate([base_fit.theta, np.zeros(p_new)]))
    r0, r1 = base_fit.residual[held], f1.residual[held]
    rss0, rss1 = float(r0 @ r0), float(r1 @ r1)
    # τ of the *extended* model's residual: the current one still holds the structure under test,
    # which would count as correlation and shrink n_eff exactly when the candidate is right
    if tau is None:
        tau = integrated_time(r1, ref.row_axis[held] if ref.kind != "gravity" else None)
    n_eff = max(2.0, held.sum() / tau)
    dp = max(0, f1.rank - base_fit.rank)
    gain = n_eff * math.log(rss0 / rss1) - dp * math.log(n_eff) if rss1 > 0 and dp > 0 else -math.inf
    p0 = base_fit.theta.size
    return HeldOutScore(gain, rss0, rss1, int(held.sum()), dp, n_eff, f1.theta[p0:], f1)
