"""Generalized Method of Wavelet Moments (GMWM) fit of a composite stochastic model, and model
selection by an estimate of out-of-sample fit.

Model: a sum of independent terms of the effect vocabulary that declare ``noise_parameters``
(white noise, quantization noise, flicker bias instability, random walk, Gauss–Markov, rate ramp);
its Haar wavelet variance is the sum of theirs, ν(θ) = Σ_i ν_i(θ_i) (each effect's
``haar_wavelet_variance``).  All parameters are > 0:

    θ̂ = argmin (ν̂ − ν(θ))ᵀ Ω (ν̂ − ν(θ)),  Ω = diag(Σ)⁻¹                    (Guerrier et al. 2013, eq. 3)

with Σ the covariance of ν̂ (:func:`calib.noise.wavelet.wv_covariance`) evaluated at a fitted
model (iterated: observed-value weights first, then model-based, as in :mod:`calib.noise.allan`).  Each
term's ν is linear in its variance parameter, so for fixed Gauss–Markov τ's the fit is a
non-negative least-squares problem (:func:`fit_model`); intervals are on log θ.

Covariance of θ̂ (sandwich, delta method; D = ∂ν/∂log θ at θ̂, B = DᵀΩD):

    Cov(log θ̂) = B⁻¹ Dᵀ Ω Σ Ω D B⁻¹                                        (Guerrier et al. 2013, Prop. 2)

Model selection: WIC (Zhang 2008; Guerrier, Stebler, Skaloud & Victoria-Feser 2016) estimates the
expected objective on a *new* record of the same length, E‖ν̂_new − ν(θ̂)‖²_Ω = objective + optimism,
with the optimism 2 tr(Ω Cov(ν̂, ν(θ̂))) = 2 tr(Ω D B⁻¹ Dᵀ Ω Σ) from the same linearisation (analytic
rather than bootstrapped: the bootstrap needs hundreds of refits, ~100× the time, for the same
first-order quantity).  Why an out-of-sample criterion and not a held-out split: a split halves the
record, and the slow terms (random walk, flicker) are seen only at the largest scales, which a
half-length record does not have.  Among models whose WIC is within the noise of the best one,
the one with fewest parameters is kept (see :func:`select`).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import numpy as np

from gyrosim.effects import EFFECTS, Effect

from calib.noise.wavelet import WaveletVariance, wv_covariance

__all__ = [
    "NOISE_TERMS",
    "canonical_order",
    "WaveletModel",
    "sandwich_covariance",
    "ModelFit",
    "candidate_models",
    "fit_model",
    "identify_axis",
    "AxisSelection",
    "model_name",
    "parse_model",
]

# the vocabulary's noise terms, discovered (each effect says which of its fields a fit estimates)
NOISE_TERMS: dict[str, type[Effect]] = {k: c for k, c in EFFECTS.items() if c.noise_parameters}
# kind → short name, in the canonical order of a model's terms (each class's noise_rank)
SHORT = {k: c.noise_short_name for k, c in sorted(NOISE_TERMS.items(), key=lambda kc: kc[1].noise_rank)}
LONG = {v: k for k, v in SHORT.items()}


def model_name(kinds: tuple[str, ...]) -> str:
    """'white+gm+gm+rw' style name of a composite model."""
    return "+".join(SHORT.get(k, k) for k in kinds)


def parse_model(text: str) -> tuple[str, ...]:
    """Inverse of :func:`model_name`; also accepts effect kinds and '2gm'."""
    out: list[str] = []
    for part in text.replace(" ", "").lower().split("+"):
        count = 1
        if part[:1].isdigit():
            count, part = int(part[0]), part[1:]
        kind = LONG.get(part, part)
        if kind not in NOISE_TERMS:
            raise ValueError(f"unknown noise term {part!r}; use {', '.join(SHORT.values())} (e.g. white+flicker+rw, "
                             "white+2gm)")
        out += [kind] * count
    return canonical_order(tuple(out))


def canonical_order(kinds: tuple[str, ...]) -> tuple[str, ...]:
    """The noise terms' kinds in the vocabulary's order (white first, the rate ramp last)."""
    order = list(SHORT)
    return tuple(sorted(kinds, key=order.index))


def candidate_models() -> list[tuple[str, ...]]:
    """White noise plus: quantization noise or not; no slow term, flicker, one or two Gauss–Markov;
    random walk or not; a rate ramp or not (32 models)."""
    out = []
    for qn, slow, rw, dr in itertools.product((0, 1), ((), ("bias_instability",), ("gauss_markov",),
                                                        ("gauss_markov", "gauss_markov")), (0, 1), (0, 1)):
        kinds = ("white_noise",) + (("quantization_noise",) if qn else ()) + slow + (("random_walk",) if rw else ()) \
            + (("rate_ramp",) if dr else ())
        out.append(canonical_order(kinds))
    return out


# ------------------------------------------------------------------ the model's wavelet variance
class WaveletModel:
    """ν(θ) and ∂ν/∂log θ for a composite model at fixed scales (one axis).  Terms whose ν is
    quadratic in their single parameter (all but Gauss–Markov) use a basis computed once."""

    def __init__(self, kinds: tuple[str, ...], m: np.ndarray, dt_s: float):
        self.kinds, self.m, self.dt = kinds, np.asarray(m, float), dt_s
        self.slices, self.names, i = [], [], 0
        self.basis: list[np.ndarray | None] = []
        for k in kinds:
            cls = NOISE_TERMS[k]
            p = len(cls.noise_parameters)
            self.slices.append(slice(i, i + p))
            self.names += [(k, f) for f in cls.noise_parameters]
            i += p
            self.basis.append(self._unit(cls) if p == 1 else None)
        self.p = i

    def _unit(self, cls: type[Effect]) -> np.ndarray:
        f = cls.noise_parameters[0]
        return cls(**{f: np.ones(3)}).haar_wavelet_variance(self.m, self.dt)[0]

    def effect(self, j: int, values: np.ndarray) -> Effect:
        cls = NOISE_TERMS[self.kinds[j]]
        return cls(**{f: np.full(3, float(v)) for f, v in zip(cls.noise_parameters, values)})

    def terms(self, logp: np.ndarray) -> list[np.ndarray]:
        out = []
        for j, sl in enumerate(self.slices):
            v = np.exp(logp[sl])
            out.append(v[0] ** 2 * self.basis[j] if self.basis[j] is not None
                       else self.effect(j, v).haar_wavelet_variance(self.m, self.dt)[0])
        return out

    def nu(self, logp: np.ndarray) -> np.ndarray:
        return np.sum(self.terms(logp), axis=0)

    def jac(self, logp: np.ndarray) -> np.ndarray:
        """∂ν/∂log θ (J, p): 2ν_i for a quadratic term; Gauss–Markov σ likewise, τ by a central difference."""
        out = np.empty((self.m.size, self.p))
        for j, (sl, t) in enumerate(zip(self.slices, self.terms(logp))):
            out[:, sl.start] = 2 * t
            if sl.stop - sl.start == 2:  # (σ, τ)
                h = 1e-4
                up, dn = logp[sl].copy(), logp[sl].copy()
                up[1] += h
                dn[1] -= h
                out[:, sl.start + 1] = (
                    self.effect(j, np.exp(up)).haar_wavelet_variance(self.m, self.dt)[0]
                    - self.effect(j, np.exp(dn)).haar_wavelet_variance(self.m, self.dt)[0]
                ) / (2 * h)
        return out

    def psd(self, logp: np.ndarray):
        effs = [self.effect(j, np.exp(logp[sl])) for j, sl in enumerate(self.slices)]

        def s(f: np.ndarray) -> np.ndarray:
            return np.sum([e.discrete_psd(f, self.dt)[0] for e in effs], axis=0)
        return s


@dataclass(frozen=True)
class ModelFit:
    """One candidate fitted to one axis: log-parameters (order of ``names``), the weighted objective,
    the WIC optimism and WIC = objective + optimism, and Cov(log θ̂) (sandwich)."""

    kinds: tuple[str, ...]
    names: tuple[tuple[str, str], ...]
    log_params: np.ndarray
    objective: float
    optimism: float = float("nan")
    cov_log: np.ndarray | None = None
    nu2_model: np.ndarray | None = None
    degenerate: bool = False   # a term fitted to 0: the same as a smaller candidate

    @property
    def wic(self) -> float:
        return self.objective + self.optimism

    @property
    def p(self) -> int:
        return len(self.names)

    @property
    def name(self) -> str:
        return model_name(self.kinds)


def _columns(model: WaveletModel, taus: dict[int, float]) -> np.ndarray:
    """(J, q) basis: ν of each term at unit variance parameter (a Gauss–Markov term at its τ)."""
    cols = []
    for j, k in enumerate(model.kinds):
        if model.basis[j] is not None:
            cols.append(model.basis[j])
        else:
            cols.append(model.effect(j, np.array([1.0, taus[j]])).haar_wavelet_variance(model.m, model.dt)[0])
    return np.stack(cols, axis=1)


def _gm_table(model: WaveletModel, tau_grid: np.ndarray) -> np.ndarray:
    """(T, J) Gauss–Markov wavelet variance at unit σ for each τ of the grid."""
    cls = NOISE_TERMS["gauss_markov"]
    out = []
    for i in range(0, tau_grid.size, 3):
        t = np.resize(tau_grid[i:i + 3], 3)
        out.append(cls(sigma=np.ones(3), tau_s=t).haar_wavelet_variance(model.m, model.dt)[: min(3, tau_grid.size - i)])
    return np.concatenate(out)


def fit_model(kinds: tuple[str, ...], wv: WaveletVariance, sd: np.ndarray) -> ModelFit:
    """Weighted GMWM fit of one candidate (weights 1/sd²).

    Every term's ν is linear in its variance parameter (N², K², B², Q², R², σ²), so for given
    Gauss–Markov correlation times the fit is a non-negative least-squares problem (exact); the
    τ's are found by a grid over the record's scales and a Nelder–Mead refinement of that
    profile.  A term fitted to exactly 0 makes the candidate the smaller model (``degenerate``)."""
    from scipy.optimize import minimize, nnls

    model = WaveletModel(kinds, wv.m, wv.dt_s)
    gm = [j for j, k in enumerate(kinds) if "tau_s" in NOISE_TERMS[k].noise_parameters]  # terms with a correlation time
    w = 1.0 / sd

    def solve(cols: np.ndarray) -> tuple[np.ndarray, float]:
        c, rnorm = nnls(cols * w[:, None], wv.nu2 * w)
        return c, rnorm**2

    if not gm:
        c, obj = solve(_columns(model, {}))
        taus: dict[int, float] = {}
    else:
        lo, hi = math.log(wv.dt_s), math.log(wv.tau_s[-1] * 2)
        grid = np.exp(np.linspace(lo, hi, 24 if len(gm) == 1 else 14))
        table = _gm_table(model, grid)
        base = _columns(model, {j: 1.0 for j in gm})
        best = (None, float("inf"))
        combos = [(i,) for i in range(grid.size)] if len(gm) == 1 else list(itertools.combinations(range(grid.size), 2))
        for combo in combos:
            cols = base.copy()
            for j, i in zip(gm, combo):
                cols[:, j] = table[i]
            _, obj = solve(cols)
            if obj < best[1]:
                best = (np.log(grid[list(combo)]), obj)

        def profile(lt: np.ndarray) -> float:
            if np.any(lt < lo - 1) or np.any(lt > hi + 1):
                return 1e300
            return solve(_columns(model, {j: float(math.exp(v)) for j, v in zip(gm, lt)}))[1]
        r = minimize(profile, best[0], method="Nelder-Mead", options={"xatol": 1e-3, "fatol": 1e-6, "maxiter": 200})
        lt = np.sort(r.x) if r.fun <= best[1] else np.sort(best[0])
        taus = {j: float(math.exp(v)) for j, v in zip(gm, lt)}
        c, obj = solve(_columns(model, taus))
    logp = np.empty(model.p)
    for j, sl in enumerate(model.slices):
        logp[sl.start] = 0.5 * math.log(c[j]) if c[j] > 0 else -np.inf
        if j in taus:
            logp[sl.start + 1] = math.log(taus[j])
    degenerate = bool(np.any(c <= 0))
    return ModelFit(kinds, tuple(model.names), logp, obj,
                    nu2_model=None if degenerate else model.nu(logp), degenerate=degenerate)


def sandwich_covariance(
    kinds: tuple[str, ...], wv: WaveletVariance, logp: np.ndarray, sigma: np.ndarray
) -> tuple[np.ndarray, float]:
    """(Cov(log θ̂), optimism) for Ω = diag(Σ)⁻¹; see the module docstring."""
    model = WaveletModel(kinds, wv.m, wv.dt_s)
    d = model.jac(logp)
    omega = 1.0 / np.diag(sigma)
    b = d.T @ (d * omega[:, None])
    b_inv = np.linalg.pinv(b)
    od = d * omega[:, None]                     # Ω D
    cov = b_inv @ (od.T @ sigma @ od) @ b_inv
    optimism = 2.0 * float(np.trace(od @ b_inv @ od.T @ sigma))
    return cov, optimism


@dataclass(frozen=True)
class AxisSelection:
    """Every candidate fitted to one axis (WIC with Σ at the reference model), the chosen one with
    its covariance, and the Σ used."""

    wv: WaveletVariance
    candidates: tuple[ModelFit, ...]
    chosen: ModelFit
    sigma: np.ndarray = field(repr=False)


SE_RULE = 3.0  # standard errors of the WIC difference a larger model must win by (select's docstring)


def select(fits: list[ModelFit], sigma: np.ndarray) -> ModelFit:
    """The fewest-parameter model whose WIC is within ``SE_RULE`` standard deviations of the best
    WIC's difference (Breiman et al. 1984's one-standard-error rule, applied to the WIC estimate):
    the WIC difference of two nested models fitted to the same data scatters, under the smaller
    model, like a χ² with Δp degrees of freedom (sd √(2Δp)), so a smaller WIC by less than that is
    noise.  3 rather than 1: with 32 candidates the best of ~20 supersets beats the true model by
    chance often; on 45 records per true model (seeds 500–514) the true model was chosen in
    87–96 % at 2 SE and 96–100 % at 3 SE (docs/noise.md)."""
    best = min(fits, key=lambda f: f.wic)
    ok = [f for f in fits if f.wic <= best.wic + SE_RULE * math.sqrt(2 * max(best.p - f.p, 1))]
    return min(ok, key=lambda f: (f.p, f.wic))


# the few models fitted with observed-value weights to choose the Σ every candidate is then weighted with
_SCOUTS = {("white_noise",), ("white_noise", "random_walk"), ("white_noise", "bias_instability", "random_walk"),
           ("white_noise", "gauss_markov", "random_walk"), ("white_noise", "gauss_markov", "gauss_markov"),
           ("white_noise", "quantization_noise", "bias_instability", "random_walk", "rate_ramp")}


def identify_axis(x: np.ndarray, dt_s: float, models: list[tuple[str, ...]] | None = None,
                  wv: WaveletVariance | None = None) -> AxisSelection:
    """Fit every candidate to one axis' record ``x``, select by WIC, and give the chosen model's
    covariance.  Iteration: a few scout models (``_SCOUTS``) with observed-value weights → Σ at the
    best of them (objective + 2p) → every candidate refitted with that Σ, WIC → select → Σ at the
    chosen model → its final fit and sandwich covariance.  ``models``: the candidates (default all
    32); those with more parameters than the scales allow (p > J − 2) are left out."""
    from calib.noise.wavelet import wavelet_variance

    wv = wv if wv is not None else wavelet_variance(x, dt_s)
    models = models or candidate_models()
    models = [k for k in models if WaveletModel(k, wv.m, wv.dt_s).p <= wv.m.size - 2]
    if not models:
        raise ValueError("too few scales for any candidate model")
    eta = np.maximum(wv.coefficients / (2 * wv.m), 1.0)          # P&W 2000 EDOF (approximation 3)
    sd0 = wv.nu2 * np.sqrt(2.0 / eta)
    scout = [k for k in models if k in _SCOUTS] or models[:1]
    first = [f for f in (fit_model(k, wv, sd0) for k in scout) if not f.degenerate]
    ref = min(first, key=lambda f: f.objective + 2 * f.p)
    sigma = wv_covariance(WaveletModel(ref.kinds, wv.m, wv.dt_s).psd(ref.log_params), wv.m, wv.coefficients)
    sd1 = np.sqrt(np.diag(sigma))
    fits = []
    for k in models:
        f = fit_model(k, wv, sd1)
        if f.degenerate:
            continue
        _, opt = sandwich_covariance(k, wv, f.log_params, sigma)
        fits.append(ModelFit(f.kinds, f.names, f.log_params, f.objective, opt, nu2_model=f.nu2_model))
    chosen = select(fits, sigma)
    sigma2 = sigma if chosen.kinds == ref.kinds else \
        wv_covariance(WaveletModel(chosen.kinds, wv.m, wv.dt_s).psd(chosen.log_params), wv.m, wv.coefficients)
    f = fit_model(chosen.kinds, wv, np.sqrt(np.diag(sigma2)))
    if f.degenerate:
        f = chosen
    cov, opt = sandwich_covariance(chosen.kinds, wv, f.log_params, sigma2)
    final = ModelFit(f.kinds, f.names, f.log_params, f.objective, opt, cov, f.nu2_model)
    return AxisSelection(wv, tuple(fits), final, sigma2)
