"""Covariance of window means of a sensor's noise: what a static multi-position test can resolve.

A static test (north-finding positions, tilt-table holds) reduces each hold to the mean of the
sensor output over a window of samples [a_i, b_i).  The errors of those means are correlated by
the slow noise terms, and every σ a static test reports follows from their covariance, per axis,
for the IEEE Std 952 three-term model (N, B, K; :class:`calib.noise.allan.NoiseTerms`):

* white (ARW/VRW N, two-sided PSD N²): per-sample variance N² f_s, so
      Cov(ȳ_i, ȳ_j) = δ_ij N² f_s / n_i;
* flicker (bias instability B, two-sided PSD S(f) = B²/(2πf), Allan floor 0.664 B), as gyrosim
  synthesises it over a record of n samples (rFFT bins f_k = k f_s/n, k ≥ 1; DC belongs to the
  bias, :func:`gyrosim.effects.spectral_noise`): each bin adds 2 S(f_k) Δf cos(2π f_k τ) to the
  autocovariance, so
      Cov(ȳ_i, ȳ_j) = Σ_k 2 S(f_k) Δf · Re[H_i(f_k) H_j(f_k)*],
      H_i(f) = (1/n_i) Σ_{m=a_i}^{b_i−1} e^{i2πf m/f_s}       (the window's transfer function);
  for a real flicker process this is the power within the record's band, 1/T ≤ f ≤ f_s/2 —
  the power below 1/T is a constant over the record and indistinguishable from bias;
* random walk (RRW/AcRW K, b(t) = K W(t) from power-on at the first sample, Cov(b(s), b(t)) =
  K² min(s, t)):
      Cov(ȳ_i, ȳ_j) = K²/(T_i T_j) ∫_{a_i}^{b_i} ∫_{a_j}^{b_j} min(s, t) ds dt,
  with ∫_0^x ∫_0^y min = m² M/2 − m³/6 (m = min(x, y), M = max(x, y)).

Different axes are independent (gyrosim draws each axis's noise on its own).  Sources: IEEE Std
952-1997 Annex C (the three terms and their PSDs); Barnes et al. 1971, NBS TN 394 (variances of
averages from the PSD).
"""

from __future__ import annotations

import math

import numpy as np

from gyrosim.sensor_model import SensorModel

from calib.noise.allan import NoiseTerms

__all__ = ["window_mean_covariance", "expected_sample_variance", "sample_variance_moments", "noise_terms_from_model",
           "combine_terms"]


def _flicker(b: float, windows: np.ndarray, rate_hz: float, n_record: int) -> np.ndarray:
    """Flicker covariance of window means, computed in the time domain: the autocovariance
    R(d) = Σ_k 2 S(f_k) Δf cos(2π k d/n) of the record's bins (one inverse FFT; periodic over the
    record, as synthesised), then Σ_{m∈I} Σ_{l∈J} R(m − l) from its double cumulative sum C₂:
    Σ = C₂(b₁−1−a₂) − C₂(a₁−1−a₂) − C₂(b₁−1−b₂) + C₂(a₁−1−b₂).  Equals the bin sum
    Σ_k 2SΔf Re[H_I H_J*] (module docstring) in O(n log n + W²)."""
    n = n_record
    k = np.arange(1, n // 2 + 1)
    w = 2.0 * b**2 / (2 * math.pi * (k * rate_hz / n)) * (rate_hz / n)      # 2 S(f_k) Δf
    spec = np.zeros(n // 2 + 1)
    spec[1:] = n * w / 2
    if n % 2 == 0:
        spec[-1] = n * w[-1] / 2                   # the real Nyquist bin counts once: R gets w/2·(−1)^d
    r = np.fft.irfft(spec, n=n)                    # R(d), d = 0 … n−1 (periodic, even)
    lags = np.arange(-n, n)                        # every difference m − l of two samples in the record
    c2 = np.cumsum(np.cumsum(r[lags % n]))         # C₂(x) at index x + n

    def c2_at(x: np.ndarray) -> np.ndarray:
        return np.where(x >= -n, c2[np.clip(x + n, 0, 2 * n - 1)], 0.0)

    a, e = windows[:, 0][:, None], windows[:, 1][:, None]
    a2, e2 = windows[:, 0][None, :], windows[:, 1][None, :]
    total = c2_at(e - 1 - a2) - c2_at(a - 1 - a2) - c2_at(e - 1 - e2) + c2_at(a - 1 - e2)
    return total / np.outer(e - a, e - a).reshape(len(windows), len(windows))


def _random_walk(k: float, windows: np.ndarray, rate_hz: float) -> np.ndarray:
    t = windows / rate_hz

    def g(x, y):
        m, big = np.minimum(x, y), np.maximum(x, y)
        return m**2 * big / 2 - m**3 / 6

    a, b = t[:, 0], t[:, 1]
    A1, A2 = np.meshgrid(a, a, indexing="ij")
    B1, B2 = np.meshgrid(b, b, indexing="ij")
    num = g(B1, B2) - g(A1, B2) - g(B1, A2) + g(A1, A2)
    return k**2 * num / np.outer(b - a, b - a)


def window_mean_covariance(terms: NoiseTerms, windows: np.ndarray, rate_hz: float, n_record: int) -> np.ndarray:
    """(W, W) covariance of the means of one axis over ``windows`` (W, 2) sample index ranges
    [start, stop) counted from the record's first sample, for noise ``terms`` (SI), sampled at
    ``rate_hz`` over a record of ``n_record`` samples (module docstring)."""
    win = np.asarray(windows, dtype=int).reshape(-1, 2)
    n_i = win[:, 1] - win[:, 0]
    if np.any(n_i < 1) or np.any(win[:, 0] < 0) or np.any(win[:, 1] > n_record):
        raise ValueError("windows must be non-empty sample ranges inside the record")
    cov = np.diag(terms.arw**2 * rate_hz / n_i.astype(float))
    if terms.bias_instability > 0:
        cov = cov + _flicker(terms.bias_instability, win, rate_hz, n_record)
    if terms.rate_random_walk > 0:
        cov = cov + _random_walk(terms.rate_random_walk, win.astype(float), rate_hz)
    return cov


def expected_sample_variance(terms: NoiseTerms, window: tuple[int, int], rate_hz: float, n_record: int) -> float:
    """E[s²] of the samples in one window [a, b) (the spread of the readings around their mean, seed
    001's zero-stability formula 4.7):  E[Σ(x_m − x̄)²]/(n − 1) = (Σ_m Var x_m − n Var x̄)/(n − 1), with
    Var x_m = N² f_s (white) + Σ_k 2 S(f_k) Δf (flicker, the record's bins) + K² m/f_s (random walk)."""
    a, b = int(window[0]), int(window[1])
    n = b - a
    if n < 2:
        raise ValueError("a window of at least two samples")
    k = np.arange(1, n_record // 2 + 1)
    f = k * rate_hz / n_record
    flick = 2.0 * terms.bias_instability**2 / (2 * math.pi * f) * (rate_hz / n_record)
    if n_record % 2 == 0:
        flick[-1] *= 0.5
    var_each = terms.arw**2 * rate_hz + float(flick.sum()) if terms.bias_instability > 0 else terms.arw**2 * rate_hz
    sum_var = n * var_each + terms.rate_random_walk**2 / rate_hz * float(np.arange(a, b).sum())
    var_mean = float(window_mean_covariance(terms, np.array([[a, b]]), rate_hz, n_record)[0, 0])
    return (sum_var - n * var_mean) / (n - 1)


def sample_variance_moments(terms: NoiseTerms, window: tuple[int, int], rate_hz: float, n_record: int,
                            blocks: int = 200) -> tuple[float, float]:
    """(E[s²], Var[s²]) of the readings' sample variance over one window (Gaussian noise).

    For a Gaussian vector with covariance C, s² = xᵀAx, A = P/(n − 1) (P centres), so
    Var s² = 2 tr(ACAC).  Split C = σ_w² I (white) + C_s (flicker + random walk, slow):
    Var s² = 2σ_w⁴/(n − 1) + 4σ_w² tr(AC_sA) + 2 tr(AC_sAC_s); the slow part is evaluated on
    ``blocks`` block means (the slow processes barely change within a block; their power inside
    a block adds to the many-degrees-of-freedom part, whose spread is negligible).  For a random
    walk alone this gives the Brownian-bridge result Var s² = K⁴T²/45."""
    a, b = int(window[0]), int(window[1])
    n = b - a
    mean = expected_sample_variance(terms, (a, b), rate_hz, n_record)
    var_w = terms.arw**2 * rate_hz
    m = min(blocks, n)
    edges = a + np.round(np.linspace(0, n, m + 1)).astype(int)
    slow = NoiseTerms(0.0, terms.bias_instability, terms.rate_random_walk, 0.0, 0.0, 0.0)
    c_s = window_mean_covariance(slow, np.stack([edges[:-1], edges[1:]], axis=1), rate_hz, n_record)
    # A C_s on block means (each block ≈ n/m equal samples), P C P by centring rows and columns
    pcp = (c_s - c_s.mean(axis=0) - c_s.mean(axis=1)[:, None] + c_s.mean()) / m
    var = 2 * var_w**2 / (n - 1) + 4 * var_w * float(np.trace(pcp)) / n + 2 * float(np.sum(pcp * pcp))  # tr(X²), X sym.
    return mean, var


def combine_terms(parts: list[dict[str, np.ndarray]], axis: int) -> NoiseTerms:
    """One axis's N, B, K from effects' :meth:`~gyrosim.effects.Effect.ieee952_terms` (independent
    processes of one kind add in variance)."""
    tot = {"arw": 0.0, "bias_instability": 0.0, "rate_random_walk": 0.0}
    for p in parts:
        for key, v in p.items():
            tot[key] += float(np.asarray(v).reshape(-1)[axis]) ** 2
    return NoiseTerms(math.sqrt(tot["arw"]), math.sqrt(tot["bias_instability"]), math.sqrt(tot["rate_random_walk"]),
                      0.0, 0.0, 0.0)


def noise_terms_from_model(model: SensorModel, triad: str) -> tuple[NoiseTerms, NoiseTerms, NoiseTerms]:
    """Per-axis N, B, K of a sensor model's triad (a preset's or a drawn device's values): the
    noise a static test of that device is limited by."""
    parts = [e.ieee952_terms() for e in model.effects(triad)]
    return tuple(combine_terms(parts, i) for i in range(3))  # type: ignore[return-value]
