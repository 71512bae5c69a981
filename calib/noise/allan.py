"""Allan-deviation noise identification (IEEE Std 952 Annex C).

The overlapping Allan variance of a rate signal is fitted with the three classic terms

    σ²(τ) = N²/τ + (2 ln 2/π) B² + K² τ/3

(angle random walk N, bias instability B — the flicker floor 0.664 B — and rate random walk K)
by weighted least squares, linear in (N², B², K²).  Weights: an overlapping-ADEV estimate at τ
from a record of length T has about M = T/τ independent clusters, so its relative variance is
≈ 1/(2(M − 1)) (Lesage & Audoin 1973; overlapping estimates are somewhat better, so this is
conservative); σ²'s relative standard error is twice σ's.  Axes sharing the same noise can be
pooled (their curves are independent).

The overlapping Allan deviation is our own (:func:`overlapping_allan_deviation`, NIST SP 1065 eq. 11 on the
integrated rate), written to give the same numbers as allantools' ``oadev(..., data_type="freq")`` (the test
suite compares them), so that the runtime install does not carry allantools' run-time requirements
(numpydoc and pytest, and with them Sphinx).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

__all__ = [
    "AllanCurve",
    "NoiseTerms",
    "allan_deviation",
    "overlapping_allan_deviation",
    "paired_allan_deviation",
    "fit_noise_terms",
    "fit_allan_variance",
    "plot_allan",
]

FLICKER = math.sqrt(2 * math.log(2) / math.pi)  # 0.664


@dataclass(frozen=True)
class AllanCurve:
    """Overlapping Allan deviation of one channel: τ (s), σ(τ) (signal units), clusters T/τ."""

    tau_s: np.ndarray
    adev: np.ndarray
    clusters: np.ndarray

    @property
    def relative_error(self) -> np.ndarray:
        """≈ 1σ relative uncertainty of each σ(τ): 1/√(2(M − 1))."""
        return 1.0 / np.sqrt(2.0 * np.maximum(self.clusters - 1.0, 1.0))


@dataclass(frozen=True)
class NoiseTerms:
    """Fitted IEEE-952 coefficients with 1σ standard errors (SI: N rad/s/√Hz, B rad/s, K rad/s/√s)."""

    arw: float
    bias_instability: float
    rate_random_walk: float
    arw_std: float
    bias_instability_std: float
    rate_random_walk_std: float
    # 2σ upper bound of each term (SI, N, B, K) from its fitted variance coefficient: what a term the record does
    # not determine (fitted to 0, where its own σ is unbounded) can still be said to be below; NaN when not computed
    upper_2sigma: tuple[float, float, float] = (math.nan, math.nan, math.nan)

    def determined(self, term: str) -> bool:
        """Whether the record determines ``term`` (one of :data:`TERMS`): fitted above 2σ of its own (a term fitted
        to 0 has an unbounded σ; one within 2σ of 0 is not told apart from none)."""
        value, std = getattr(self, term), getattr(self, f"{term}_std")
        return value > 0 and math.isfinite(std) and value > 2 * std

    def model(self, tau_s: np.ndarray) -> np.ndarray:
        return np.sqrt(
            self.arw**2 / tau_s + (FLICKER * self.bias_instability) ** 2 + self.rate_random_walk**2 * tau_s / 3
        )


def allan_deviation(x: np.ndarray, rate_hz: float, taus_per_decade: int = 8) -> AllanCurve:
    """Overlapping Allan deviation of a rate signal x (N,), log-spaced τ up to T/5."""
    x = np.asarray(x, dtype=float)
    T = x.size / rate_hz
    taus = np.logspace(
        math.log10(2.0 / rate_hz), math.log10(T / 5.0), int(taus_per_decade * math.log10(T * rate_hz / 10))
    )
    t2, ad, _ = overlapping_allan_deviation(x, rate_hz, taus)
    return AllanCurve(t2, ad, T / t2)


def overlapping_allan_deviation(x: np.ndarray, rate_hz: float,
                                taus_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Overlapping Allan deviation of a rate signal ``x`` (N,) sampled at ``rate_hz`` (Hz), in x's units, at the
    cluster times ``taus_s`` (s) rounded to whole samples m = round(τ·f_s), duplicates merged, sorted; clusters
    longer than the record dropped.  Returns (τ used (s), σ(τ), number of second differences n per τ).

    NIST SP 1065 eq. 11 on the phase (the rate integrated, its mean removed first so that a large constant rate
    costs no precision, and a leading 0): σ²(mτ₀) = Σ (x_{i+2m} − 2x_{i+m} + x_i)² / (2 n (mτ₀)²) over the
    n = N + 1 − 2m overlapping second differences; τ with n < 2 are dropped.  Leading and trailing NaNs are cut.
    The same operations in the same order as allantools' ``oadev(x, rate, data_type="freq", taus=taus_s)``."""
    x = np.asarray(x, dtype=float)
    finite = np.flatnonzero(~np.isnan(x))
    x = x[finite[0]: finite[-1] + 1] if finite.size else x[:0]
    rate = float(rate_hz)
    phase = np.insert(np.cumsum(x - np.nanmean(x)) * (1.0 / rate), 0, 0)
    m = np.round(np.asarray(taus_s, dtype=float) * rate)
    m = np.unique(m[(m > 0) & (m < phase.size)]).astype(int)
    n = np.maximum(phase.size - 2 * m, 1)  # an empty difference counts as one, then dropped below with n < 2
    adev = np.zeros(m.size)
    for k, (mj, nk) in enumerate(zip(m, n)):
        if phase.size - 2 * mj <= 0:
            continue
        d = phase[2 * mj: 2 * mj + nk] - 2 * phase[mj: mj + nk] + phase[:nk]
        adev[k] = np.sqrt(np.sum(d * d) / (2.0 * nk)) / mj * rate
    keep = n > 1
    return m[keep] / rate, adev[keep], n[keep]


def paired_allan_deviation(x: np.ndarray, rate_hz: float) -> AllanCurve:
    """Allan deviation from *non-overlapping pairs* of cluster means at octave τ = 2^j/f_s (the
    Haar wavelet variance): σ²(τ) = ½ mean over disjoint pairs of (ȳ_{2p+1} − ȳ_{2p})².

    Coarser than the overlapping estimate, but its pairs are independent for white noise and
    nearly so for flicker and random walk, and its points at different octaves nearly
    uncorrelated, so a fit's covariance (:func:`fit_allan_variance`) is honest: with P pairs the
    relative σ of σ² is √(2/P), stored as ``clusters`` = P + 1 for
    :attr:`AllanCurve.relative_error`.  Octaves with ≥ 2 pairs."""
    x = np.asarray(x, dtype=float)
    taus, adev, clusters = [], [], []
    m = 1
    while x.size // m >= 4:
        nb = x.size // m
        means = x[: nb * m].reshape(nb, m).mean(axis=1)
        pairs = nb // 2
        d = means[1 : 2 * pairs : 2] - means[0 : 2 * pairs : 2]
        taus.append(m / rate_hz)
        adev.append(math.sqrt(0.5 * float(np.mean(d**2))))
        clusters.append(pairs + 1.0)
        m *= 2
    return AllanCurve(np.array(taus), np.array(adev), np.array(clusters))


TERMS = ("arw", "bias_instability", "rate_random_walk")


def fit_noise_terms(curves: list[AllanCurve], iterations: int = 5, terms: tuple[str, ...] = TERMS) -> NoiseTerms:
    """Weighted LSQ fit of σ² = a/τ + b + cτ/3 pooled over ``curves`` (see module docstring).

    Iteratively reweighted: the standard error of each σ²(τ) is 2·rel(τ)·σ²_model(τ), using the
    *model* from the previous iteration, not the observed σ² (weighting by the observation
    favours the points that happen to scatter low and biases the large-τ terms downwards).
    ``terms``: the subset of (arw, bias_instability, rate_random_walk) to fit; the others are 0
    with standard error 0 (e.g. leave out a random walk the τ range cannot show).
    """
    full, cov = fit_allan_variance(curves, iterations, terms)
    std = np.sqrt(np.diag(cov))
    upper = np.sqrt(full + 2 * std) / np.array([1.0, FLICKER, 1.0])
    return replace(_terms_from_coefficients(full, std), upper_2sigma=tuple(float(u) for u in upper))


def fit_allan_variance(curves: list[AllanCurve], iterations: int = 5,
                       terms: tuple[str, ...] = TERMS) -> tuple[np.ndarray, np.ndarray]:
    """The fit behind :func:`fit_noise_terms` as the variance coefficients (N², 0.664²B², K²)
    ≥ 0 and their 3×3 covariance (zero rows for terms left out): what a quantity derived from
    the fitted curve (e.g. its minimum) needs for its σ."""
    if not terms or set(terms) - set(TERMS):
        raise ValueError(f"terms must be a non-empty subset of {TERMS}, got {terms}")
    design = np.concatenate([np.stack([1 / c.tau_s, np.ones_like(c.tau_s), c.tau_s / 3], axis=1) for c in curves])
    keep = [TERMS.index(t) for t in TERMS if t in terms]
    coef, cov_k = _reweighted_fit(design[:, keep], curves, iterations)
    full, cov = np.zeros(3), np.zeros((3, 3))
    full[keep] = coef
    cov[np.ix_(keep, keep)] = cov_k
    return full, cov


def _reweighted_fit(design: np.ndarray, curves: list[AllanCurve], iterations: int) -> tuple[np.ndarray, np.ndarray]:
    """The reweighted fit of :func:`fit_noise_terms` on the given columns: (coefficients ≥ 0, covariance)."""
    obs = np.concatenate([c.adev**2 for c in curves])
    rel = np.concatenate([c.relative_error for c in curves])
    model = obs.copy()
    for _ in range(iterations):
        w = 1.0 / (2 * rel * model)  # 1/σ of each σ² estimate
        A = design * w[:, None]
        coef, *_ = np.linalg.lstsq(A, obs * w, rcond=None)
        model = np.maximum(design @ np.maximum(coef, 0.0), 1e-300)
    return np.maximum(coef, 0.0), np.linalg.inv(A.T @ A)


def _terms_from_coefficients(coef: np.ndarray, std: np.ndarray) -> NoiseTerms:
    """N, B, K from the fitted (N², B²·0.664², K²) with standard errors σ_√v ≈ σ_v / (2√v)
    (inf when the term fitted to 0; 0 when it was not fitted)."""
    a, b, c = coef
    sa, sb, sc = std
    N, B, K = math.sqrt(a), math.sqrt(b) / FLICKER, math.sqrt(c)

    def se(s: float, v: float, k: float = 1.0) -> float:
        return 0.0 if s == 0 else (s / (2 * math.sqrt(v) * k) if v else float("inf"))

    return NoiseTerms(N, B, K, se(sa, a), se(sb, b, FLICKER), se(sc, c))


def plot_allan(curves: list[AllanCurve], fit: NoiseTerms | None, path: str | Path, *, unit_scale: float = 1.0,
               unit: str = "rad/s", title: str = "Allan deviation") -> Path:
    """Write a log-log Allan plot (PNG) with error bars and the fitted three-term model."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 5))
    for i, c in enumerate(curves):
        ax.errorbar(c.tau_s, c.adev * unit_scale, yerr=c.adev * unit_scale * c.relative_error, fmt=".",
                    ms=4, alpha=0.7, label=f"axis {'xyz'[i] if i < 3 else i}")
    if fit is not None:
        tau = np.logspace(math.log10(curves[0].tau_s[0]), math.log10(curves[0].tau_s[-1]), 200)
        ax.loglog(tau, fit.model(tau) * unit_scale, "k-", label="fit N²/τ + 0.664²B² + K²τ/3")
        ax.loglog(tau, fit.arw / np.sqrt(tau) * unit_scale, "k:", lw=0.8)
        ax.loglog(tau, np.full_like(tau, FLICKER * fit.bias_instability) * unit_scale, "k:", lw=0.8)
        ax.loglog(tau, fit.rate_random_walk * np.sqrt(tau / 3) * unit_scale, "k:", lw=0.8)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("τ (s)")
    ax.set_ylabel(f"Allan deviation ({unit})")
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
