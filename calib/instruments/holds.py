"""Holds of a static test: is the board still, and what noise do its holds show.

Shared by the north-finder (:mod:`calib.instruments.northfind`) and the tilt test (:mod:`calib.instruments.tilt`): both
reduce a record to the means of holds, so both must know which holds are still and what the
noise of a hold mean is (:mod:`calib.noise.window_means` from the fitted IEEE-952 terms).
"""

from __future__ import annotations

import numpy as np

from gyrosim.errors import RecordingError
from gyrosim.lazy import lazy_module
from gyrosim.recording import Recording

from calib.noise.allan import NoiseTerms, allan_deviation, fit_noise_terms

# imported on first use (gyrosim.lazy), so that start-up and a refused file do not pay for it
ndimage = lazy_module("scipy.ndimage")
stats = lazy_module("scipy.stats")

__all__ = ["still_holds", "fit_hold_noise"]


def _window_means(x: np.ndarray, w: int) -> np.ndarray:
    n = (x.shape[0] // w) * w
    return x[:n].reshape(-1, w, x.shape[1]).mean(axis=1)


def _running_median(m: np.ndarray, half: int) -> np.ndarray:
    """Median of each window's neighbours within ±``half`` windows, the window itself left out (so
    that its deviation is the sum of two independent errors, Gaussian with the scale the MAD
    measures; with itself included the MAD under-read the spread by 7 % and the false alarms were
    15× the design) and the neighbourhood cut at the hold's ends (padding would weigh the end
    windows twice)."""
    foot = np.ones((2 * half + 1, 1), bool)
    foot[half] = False
    out = ndimage.median_filter(m, footprint=foot, mode="nearest")
    n = m.shape[0]
    for k in list(range(min(half, n))) + list(range(max(half, n - half), n)):
        nb = np.concatenate([m[max(0, k - half) : k], m[k + 1 : k + half + 1]])
        out[k] = np.median(nb, axis=0) if nb.shape[0] else m[k]
    return out


def still_holds(rec: Recording, ranges: list[tuple[int, int]], window_s: float = 1.0,
                channels: str = "gyro+acc", local: int = 10) -> list[str | None]:
    """Motion check of each hold: the means of ``window_s`` windows of each channel must stay at
    the hold's local level (the median of the windows within ±``local``) within the noise.  Robust
    σ per channel: 1.4826 × the median absolute deviation of all windows from their local level
    (local, so that the slow drift of a long hold does not hide a knock in a short one);
    a window beyond z = Φ⁻¹(1 − p/2), p = 1e-3 / (windows × channels) (Bonferroni), marks its
    hold as moving.  A channel without noise (σ = 0) that moves at all is motion.  ``channels``:
    ``gyro+acc``, or ``acc`` for a tilt sensor (its recording's gyro is no measurement).
    Returns per hold None (still) or the reason."""
    fs = rec.rate_hz
    w = max(2, int(round(window_s * fs)))
    if channels not in ("gyro+acc", "acc"):
        raise ValueError("channels must be 'gyro+acc' or 'acc'")
    sig = np.hstack([rec.gyro_rad_s, rec.acc_m_s2]) if channels == "gyro+acc" else rec.acc_m_s2
    names = (("gyro x", "gyro y", "gyro z") if channels == "gyro+acc" else ()) + ("acc x", "acc y", "acc z")
    dev = []
    for a, b in ranges:
        m = _window_means(sig[a:b], w)
        dev.append(m - _running_median(m, local) if m.shape[0] else np.zeros((0, sig.shape[1])))
    alld = np.concatenate(dev) if dev else np.zeros((0, sig.shape[1]))
    if alld.shape[0] < 3:
        return [None] * len(ranges)
    scale = 1.4826 * np.median(np.abs(alld), axis=0)
    z_lim = float(stats.norm.isf(1e-3 / (2 * alld.size)))
    out: list[str | None] = []
    for (a, _), d in zip(ranges, dev):
        if d.shape[0] == 0:
            out.append(None)
            continue
        with np.errstate(divide="ignore", invalid="ignore"):
            z = np.where(scale > 0, np.abs(d) / np.where(scale > 0, scale, 1.0), np.where(np.abs(d) > 0, np.inf, 0.0))
        k, c = np.unravel_index(int(np.argmax(z)), z.shape)
        if z[k, c] > z_lim:
            t0 = rec.t_s[a + k * w]
            out.append(f"motion: the {names[c]} mean over {window_s:g} s at t = {t0:.1f} s is {z[k, c]:.0f}σ from the "
                       f"hold's level (limit {z_lim:.1f}σ)")
        else:
            out.append(None)
    return out


def fit_hold_noise(rec: Recording, ranges: list[tuple[int, int]], channel: str = "gyro",
                   keep_random_walk: bool = False) -> tuple[NoiseTerms, ...]:
    """N, B, K of the three axes from the Allan deviation of the holds (each hold and axis its own
    curve, all pooled: the axes of one triad are taken to share their noise, as ``calib allan``
    does; the constant level of a hold does not enter the Allan deviation).

    The holds show τ ≤ T_hold/5 only, and the σ of a north-finding depends on the noise at the
    hold time and beyond, so a term is kept only where the data show it: a random walk whose K²
    is below 3σ of its own estimate would be extrapolated from noise (in a Monte Carlo of
    fog_tactical, which has none, such fits doubled σ_ψ in a third of the seeds); it is then left
    out and N, B refitted — unless ``keep_random_walk``: a figure that is not a contrast of holds
    (the tilt test's zero offset) carries the random walk's level since power-on, and leaving out
    a walk the holds merely fail to prove made its σ 2× too small in a Monte Carlo of tilt_001 with
    a 20-minute level hold; the unproven K² ≥ 0 then errs on the safe side."""
    x = rec.gyro_rad_s if channel == "gyro" else rec.acc_m_s2
    usable = [(a, b) for a, b in ranges if b - a >= 20]
    if not usable:
        raise RecordingError("no hold of ≥ 20 samples to measure the noise on")
    curves = [allan_deviation(x[a:b, i], rec.rate_hz) for a, b in usable for i in range(3)]
    curves = [c for c in curves if c.tau_s.size >= 2]
    if not curves:
        raise RecordingError("the holds are too short for an Allan deviation (need ≥ 20 samples and two τ values)")
    fit = fit_noise_terms(curves)
    k2, k2_std = fit.rate_random_walk**2, 2 * fit.rate_random_walk * fit.rate_random_walk_std
    if not keep_random_walk and not k2 > 3 * k2_std:
        fit = fit_noise_terms(curves, terms=("arw", "bias_instability"))
    return (fit, fit, fit)


