"""Structure in a residual that no candidate explains.

Three tests on the final rate residual r (body frame, rad/s, one series per axis):

* **Spectral lines** – Welch PSD with K averaged segments (Hann, 50 % overlap); the background
  is a running median over ±``median_bins`` bins.  Under a smooth spectrum, PSD/background is
  distributed as χ²_ν/ν with ν ≈ 2K·(9/11)·... (Welch's equivalent dof, approximated by 1.8 K for
  50 % Hann overlap); a bin is a line when it exceeds the χ²_ν quantile at false-alarm
  ``alpha`` / (bins × axes) (Bonferroni).  The line's amplitude is √(2·excess power·Δf).
* **Correlation with every channel** – Pearson ρ of each residual axis with each channel the
  recording has (gyro, specific force, |f| − g, |ω|, dω/dt, temperature, dT/dt, magnetic field,
  time); significant when |ρ|·√n_eff exceeds the normal quantile at ``alpha``/(tests) (Fisher).
* **Whiteness** – τ_int of the residual (1 for white noise) and the Ljung–Box statistic over the
  first 20 lags, reported, not gated: measured residuals are never white, the question is where.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
from scipy import ndimage, stats
from scipy import signal as sp_signal

from calib.closeloop.fit import integrated_time

__all__ = ["SpectralLine", "ChannelCorrelation", "JitterGrowth", "spectral_lines", "channel_correlations", "whiteness",
           "variance_growth"]

AXES = "xyz"


@dataclass(frozen=True)
class SpectralLine:
    """A narrow line in one residual axis's PSD: its frequency (Hz), sinusoid amplitude (rad/s) and
    PSD-to-background ratio against the false-alarm threshold (module docstring)."""

    axis: str
    frequency_hz: float
    amplitude_rad_s: float    # sinusoid amplitude (rad/s)
    ratio: float              # PSD / background
    threshold: float


@dataclass(frozen=True)
class ChannelCorrelation:
    """A significant correlation ρ of one residual axis with a channel of the recording, with its
    statistic z = |ρ|·√n_eff and the threshold it exceeds (module docstring)."""

    axis: str
    channel: str
    rho: float
    z: float                  # |ρ|·√n_eff
    threshold: float


def spectral_lines(r: np.ndarray, fs_hz: float, *, alpha: float = 1e-3, segments: int = 16,
                   median_bins: int = 25, max_lines: int = 10) -> list[SpectralLine]:
    """Narrow lines in the PSD of each axis of r (N, 3) sampled at ``fs_hz`` (see module docstring)."""
    n = r.shape[0]
    nper = int(2 ** math.floor(math.log2(max(64, 2 * n // (segments + 1)))))
    if n < 2 * nper:
        return []
    f, pxx = sp_signal.welch(r, fs=fs_hz, nperseg=nper, noverlap=0, axis=0, detrend="constant")
    k = n // nper
    nu = 2.0 * k
    lines = []
    bins = f.size - 2
    thr = stats.chi2.ppf(1 - alpha / (bins * r.shape[1]), nu) / nu
    df = f[1] - f[0]
    for a in range(r.shape[1]):
        p = pxx[:, a].copy()
        p[0], p[-1] = p[1], p[-2]  # DC (detrended away) and Nyquist (not doubled) bins are not spectrum levels
        # mirror at the edges: padding with the edge value would bias the running median there
        bg = ndimage.median_filter(p, size=2 * median_bins + 1, mode="mirror") / (1 - 2 / (9 * nu)) ** 3
        ratio = p / np.maximum(bg, 1e-300)
        hits = np.nonzero(ratio[1:-1] > thr)[0] + 1
        # keep local maxima only (one line per peak)
        for h in hits:
            if ratio[h] >= ratio[h - 1] and ratio[h] >= ratio[h + 1]:
                power = max(0.0, (p[h] - bg[h])) * df * 1.5  # Hann: the line spreads over ~1.5 bins
                lines.append(SpectralLine(AXES[a], float(f[h]), math.sqrt(2 * power), float(ratio[h]), float(thr)))
    lines.sort(key=lambda l: -l.ratio)
    return lines[:max_lines]


def channel_correlations(
    r: np.ndarray, channels: dict[str, np.ndarray], *, alpha: float = 1e-3
) -> list[ChannelCorrelation]:
    """Significant correlations of each residual axis (N, 3) with each channel (N,) (see module docstring)."""
    out = []
    tests = max(1, r.shape[1] * len(channels))
    thr = stats.norm.ppf(1 - alpha / (2 * tests))
    for a in range(r.shape[1]):
        ra = r[:, a] - r[:, a].mean()
        tau_r = integrated_time(ra)
        for name, c in channels.items():
            c = c - c.mean()
            den = math.sqrt(float(ra @ ra) * float(c @ c))
            if den == 0:
                continue
            rho = float(ra @ c) / den
            # Bartlett: var ρ̂ ≈ (1 + 2 Σ ρ_r(k) ρ_c(k)) / n ≤ min(τ_r, τ_c) / n
            n_eff = r.shape[0] / min(tau_r, integrated_time(c))
            z = abs(rho) * math.sqrt(n_eff)
            if z > thr:
                out.append(ChannelCorrelation(AXES[a], name, rho, z, float(thr)))
    out.sort(key=lambda c: -c.z)
    return out


def whiteness(r: np.ndarray, lags: int = 20) -> dict[str, float]:
    """τ_int and the Ljung–Box Q over ``lags`` lags, per axis (white: τ ≈ 1, Q ≈ lags)."""
    out: dict[str, float] = {}
    for a in range(r.shape[1]):
        s = r[:, a] - r[:, a].mean()
        n = s.size
        acf = np.array([float(s[:-k] @ s[k:]) for k in range(1, lags + 1)]) / float(s @ s)
        q = n * (n + 2) * float(np.sum(acf**2 / (n - np.arange(1, lags + 1))))
        out[f"tau_int_{AXES[a]}"] = integrated_time(s)
        out[f"ljung_box_q_{AXES[a]}"] = q
    out["ljung_box_lags"] = lags
    return out


@dataclass(frozen=True)
class JitterGrowth:
    """Residual variance growing with (dω/dt)² as sampling-time jitter of σ_j = ``jitter_s`` would
    (``report.json`` ``unexplained.variance_growth``)."""

    jitter_s: float
    z: float                  # the slope's z
    threshold: float          # the one-sided normal quantile it exceeds

    def to_json(self) -> dict:
        return asdict(self)


def variance_growth(r: np.ndarray, domega_dt: np.ndarray, *, alpha: float = 1e-3) -> JitterGrowth | None:
    """Sampling-time jitter σ_j makes the residual variance grow with the angular acceleration:
    E[r_a²] = σ_a² + σ_j² (dω_a/dt)².  Regress r_a² on (dω_a/dt)² pooled over axes; significant
    when the slope's z exceeds the normal quantile at ``alpha`` (one-sided).  Returns σ_j = √slope
    when significant, else None."""
    x = (domega_dt**2).ravel()
    y = (r**2).ravel()
    x = x - x.mean()
    sxx = float(x @ x)
    if sxx == 0:
        return None
    slope = float(x @ (y - y.mean())) / sxx
    resid = y - y.mean() - slope * x
    tau = integrated_time(resid)
    se = math.sqrt(float(resid @ resid) / max(1, y.size - 2) / sxx * tau)
    z = slope / se if se > 0 else 0.0
    thr = float(stats.norm.ppf(1 - alpha))
    if z > thr and slope > 0:
        return JitterGrowth(math.sqrt(slope), z, thr)
    return None
