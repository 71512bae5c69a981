"""The hand's slow external acceleration a_e (the sway): its shaping-filter model fitted to the data, and the
covariance of the estimate under the spectrum the data show.

A hand-held session's accelerometer senses, besides gravity, the lever arm's K r (:mod:`calib.session.hand.lever`)
and the hand's own translation a_e, in nav: tremor (8–12 Hz) and sway (0.2–1 Hz), coloured.  The calibration's
information lives below ~1 Hz (the rotations), so the tremor band is removed by the pre-filter
(:mod:`calib.session.hand.lowpass`) rather than modelled.  The slow rest (sway) is a shaping filter per nav axis: a
first-order Gauss–Markov x (σ_s, τ) high-passed (τ_h, order m ∈ {1, 2}): a_e = x − z (− z₂), z the low-pass of x,
z₂ that of x − z — a hand's translation is bounded, so its acceleration has no power at 0 Hz (the one-sided PSD
4σ_s²τ/(1 + (2πfτ)²)·[(2πfτ_h)²/(1 + (2πfτ_h)²)]^m, estimated from the data, is reported); three to nine states
(:class:`calib.session.model.FilterConfig`).

``kf_hand``'s passes: pass 1 takes σ_s from the session's (|f_lp| − g)² (as ``kf_session_r``), τ = 1 s, no high-pass,
r̂ = 0; passes 2 and 3 fit (σ_s, τ, τ_h, m) to the previous pass's residual e = |f_lp − K r̂| − g, the component of
a_e along gravity (attitude-free, so the gyro's own errors do not enter; for an isotropic a_e its variance is one
axis's): :func:`fit_gauss_markov`.  The opt-in band-limited model (a Gauss–Markov floor + a Butterworth band-pass,
:func:`fit_band`; ``kf_hand_band``) runs through the general shaping-filter states.

The result's σ is the filter's P with the σ of S, G, the lever arm and the accelerometer's parameters taken from the
slow residual's own spectrum rather than the fitted model's (:func:`spectral_sigma`, :mod:`calib.session.spectral`:
the first-order family cannot follow a hand's band-limited sway, and the filter sees its model sampled at the
updates, aliased — σ of S, G was 1.2–1.4× too large with gyrosim's typical and shaky hands).

Sources: Gauss–Markov shaping filters for coloured measurement noise: Gelb, *Applied Optimal Estimation* (1974),
§4.5; Bryson & Henrikson 1968; Brown & Hwang, *Introduction to Random Signals and Applied Kalman Filtering*, 4th ed.,
§3.9.
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np
from scipy import signal as sp_signal

from calib.session.kernel import FilterRun
from calib.session.model import FilterConfig, StateLayout, nonorthogonality_jacobians
from calib.session.spectral import gauss_markov_psd, spectral_correction, update_weights

__all__ = ["fit_gauss_markov", "fit_band", "band_shape", "band_config", "band_report", "spectral_sigma",
           "SWAY_MODELS", "BAND_ORDER", "SPECTRAL_BLOCKS"]

# kf_hand's a_e: "gauss_markov" (the high-passed Gauss–Markov family, fit_gauss_markov; the default) or "band" (a
# Gauss–Markov floor + a Butterworth band-pass, fit_band; opt-in, calib.session.hand.filter:kf_hand_band — docs/hand.md,
# "A band-limited sway model": not strictly closer to 6 on gyrosim, and ΣNEES 379 (10 seeds) with every seed "ok" on
# the independent generator's noise-free sensor, so not the default)
SWAY_MODELS = ("gauss_markov", "band")


def fit_gauss_markov(e: np.ndarray, dt_s: float, white_var: float,
                      white_psd: float) -> tuple[float, float, float, int]:
    """(σ_x, τ, τ_h, m) of the high-passed Gauss–Markov a_e (:class:`calib.session.model.FilterConfig`) fitted to a
    residual ``e`` (N,), whose one-sided PSD is

        S_a(f) = 4σ_x²τ / (1 + (2πfτ)²) · [(2πfτ_h)² / (1 + (2πfτ_h)²)]^m,    m ∈ {1, 2}.

    A hand's translation is bounded (mm), so its acceleration's PSD falls towards 0 Hz — as f⁴ times the
    displacement's, the second-order high-pass (m = 2); a first-order Gauss–Markov process (τ_h = ∞) stays
    flat there and over-weights the band the rotations' information lives in (< 0.2 Hz): σ of S was
    pessimistic ×2–3 with a hand (measured).  The fit: Var a = ∫S_a df = var e − ``white_var`` fixes σ_x
    for each (τ, τ_h, m) of a log grid (τ_h = ∞ included; the integral numerically on a log frequency
    grid); the triple minimising Σ_f w_f (ln(S_a + W) − ln Ŝ_e)², Ŝ_e Welch's estimate with 40-s segments
    over 0.02–2.5 Hz (below the 4-Hz pre-filter), W = ``white_psd``, w_f = 1/f (each octave weighs the
    same, rather than the many high bins), is kept.  (0, 1, ∞, 1) when e has no excess variance.
    Source: the shaping-filter construction of coloured noise (Gelb, *Applied Optimal Estimation*, 1974,
    §4.5; Brown & Hwang, *Introduction to Random Signals and Applied Kalman Filtering*, 4th ed., §3.9)."""
    e = e - e.mean()
    s2 = max(float(np.mean(e**2)) - white_var, 0.0)
    if s2 <= 0.0:
        return 0.0, 1.0, math.inf, 1
    fs = 1.0 / dt_s
    f, pxx = sp_signal.welch(e, fs=fs, nperseg=int(min(e.size, 40 * fs)))
    band = (f >= 0.02) & (f <= 2.5) & (pxx > 0)
    if band.sum() < 5:
        return math.sqrt(s2), 1.0, math.inf, 1
    f, lp, w = f[band], np.log(pxx[band]), 1.0 / f[band]
    taus = np.geomspace(2 * dt_s, 10.0, 28)[:, None, None]
    ths = np.concatenate([np.geomspace(0.1, 30.0, 24), [np.inf]])[None, :, None]
    fi = np.geomspace(1e-4, 0.5 * fs, 2000)                            # for ∫ S df (σ_x = 1)
    best = (math.inf, 1.0, math.inf, 1, s2)
    for m in (1, 2):
        def shape(fr):
            w2 = (2 * np.pi * fr) ** 2
            with np.errstate(divide="ignore", invalid="ignore"):
                hp = (1.0 / (1.0 + 1.0 / (w2 * ths**2))) ** m           # 1 for τ_h = ∞
            return 4.0 * taus / (1.0 + w2 * taus**2) * hp
        var1 = np.trapezoid(shape(fi[None, None, :]), fi, axis=-1)      # (τ, τ_h): Var a for σ_x = 1
        var1 = var1 + 4.0 * taus[..., 0] * fi[0] * (ths[..., 0] == np.inf)  # the flat PSD below fi[0]
        sx2 = s2 / np.maximum(var1, 1e-300)
        model = sx2[..., None] * shape(f[None, None, :])
        cost = np.sum(w * (np.log(model + white_psd) - lp) ** 2, axis=-1)
        k = np.unravel_index(int(np.argmin(cost)), cost.shape)
        if cost[k] < best[0]:
            best = (float(cost[k]), float(taus[k[0], 0, 0]), float(ths[0, k[1], 0]), m, float(sx2[k]))
    _, tau, th, m, sx2 = best
    return math.sqrt(sx2), tau, th, (m if math.isfinite(th) else 1)


BAND_ORDER = 2             # Butterworth poles per band edge of the sway model (FilterConfig.ext_acc_band_hz)


BAND_FIT_LO_HZ = 0.02      # the band powers fitted: 1/3-octave bands from here …


BAND_FIT_HI_HZ = 3.2       # … to here (below the 4-Hz tremor pre-filter)


# the fit's cost of a band's power under-modelled, relative to the same log-ratio over-modelled
UNDER_WEIGHT = 100.0


def band_shape(f_hz: np.ndarray, f1: np.ndarray, f2: np.ndarray, order: int = BAND_ORDER) -> np.ndarray:
    """|H(f)|² of the analog Butterworth band-pass f₁ … f₂ with ``order`` poles per edge (low-pass prototype
    1/(1 + Ω^{2N}), Ω = (f² − f₁f₂)/(f (f₂ − f₁)))."""
    om = (f_hz**2 - f1 * f2) / (f_hz * (f2 - f1))
    return 1.0 / (1.0 + om ** (2 * order))


def fit_band(e: np.ndarray, dt_s: float, white_var: float, white_psd: float) -> dict:
    """The band-limited sway model of a_e (:meth:`calib.session.model.FilterConfig.ext_acc_model`) fitted to the
    residual ``e`` (N,): a Gauss–Markov floor (σ₀, τ₀) plus a Butterworth band-pass (f₁, f₂, RMS σ_b),
    one-sided PSD S_a(f) = A₀/(1 + (2πfτ₀)²) + A_b |H(f)|², A₀ = 4σ₀²τ₀.

    Fitted to BAND POWERS, not to per-bin log-PSD: Welch's estimate of e (40-s Hann segments) integrated over
    1/3-octave bands k from ``BAND_FIT_LO_HZ`` to ``BAND_FIT_HI_HZ``, the white floor's share W_k = ``white_psd``
    × width subtracted, d_k = max(P_k − W_k, 0) — so a line spectrum (a sum of sines) counts with its power
    wherever it falls, and the floor has to take what lies outside the band.  For each (f₁, f₂, τ₀) of a log
    grid the amplitudes (A_b, A₀) ≥ 0 minimise Σ_k ((m_k − d_k)/(d_k + W_k))² (linear: the model's band
    powers m_k are linear in them; a relative error, so the quiet bands where S's information lies weigh as
    much as the loud ones), and the triple with the least Σ_k (ln(m_k + W_k) − ln(d_k + W_k))² is kept.
    Deterministic, ~20 ms.  Returns {"floor_rms_m_s2", "floor_tau_s", "band_hz" (f₁, f₂) or None,
    "band_rms_m_s2"}; no excess variance → a zero floor and no band.
    Source: shaping filters for coloured noise (Gelb 1974 §4.5; Brown & Hwang 4th ed. §3.9); band powers as
    in fractional-octave analysis (ANSI S1.11)."""
    e = e - e.mean()
    s2 = max(float(np.mean(e**2)) - white_var, 0.0)
    none = {"floor_rms_m_s2": 0.0, "floor_tau_s": 1.0, "band_hz": None, "band_rms_m_s2": 0.0}
    if s2 <= 0.0:
        return none
    fs = 1.0 / dt_s
    f, pxx = sp_signal.welch(e, fs=fs, nperseg=int(min(e.size, 40 * fs)))
    df = f[1] - f[0]
    hi = min(BAND_FIT_HI_HZ, 0.4 * fs)
    edges = BAND_FIT_LO_HZ * 2.0 ** (np.arange(0, 40) / 3.0)
    edges = edges[edges <= hi * 1.0001]
    k_of = np.searchsorted(edges, f, side="right") - 1
    ok = (k_of >= 0) & (k_of < edges.size - 1) & (f > 0)
    nb = edges.size - 1
    cnt = np.bincount(k_of[ok], minlength=nb)
    use = cnt > 0
    if use.sum() < 5:
        return {**none, "floor_rms_m_s2": math.sqrt(s2)}
    pk = np.bincount(k_of[ok], weights=pxx[ok] * df, minlength=nb)[use]
    wk = white_psd * df * cnt[use]
    # the excess over the white floor, less twice the floor's own scatter (a band of c bins from Welch's n_s
    # segments is a χ² of ~2·c·n_s degrees of freedom: relative σ 1/√(c n_s)), so that the fit does not chase the
    # estimate's noise — with an ideal hand (no sway) it did, and σ grew ×1.1 (NEES 5.35 → 4.15, consumer)
    nseg = max(1.0, 2.0 * e.size / int(min(e.size, 40 * fs)) - 1.0)
    dk = np.maximum(pk - wk * (1.0 + 2.0 / np.sqrt(cnt[use] * nseg)), 0.0)
    # the model's band powers on the same bins (the bins' frequencies, as Welch's estimate has them)
    fb, kb = f[ok], k_of[ok]
    remap = -np.ones(nb, np.int64)
    remap[use] = np.arange(int(use.sum()))
    kb = remap[kb]
    f1s = np.geomspace(0.03, 1.5, 41)
    f2s = np.geomspace(0.12, 3.5, 41)
    taus = np.geomspace(0.05, 20.0, 12)
    F1, F2 = np.meshgrid(f1s, f2s, indexing="ij")
    valid = F2 > 1.5 * F1
    shp = band_shape(fb[None, None, :], F1[..., None], F2[..., None]) * df          # (41, 41, bins)
    U = np.zeros(F1.shape + (kb.max() + 1,))
    for i in range(U.shape[-1]):
        U[..., i] = shp[..., kb == i].sum(axis=-1)
    lor = df / (1.0 + (2 * np.pi * fb[None, :] * taus[:, None]) ** 2)                # (12, bins)
    V = np.stack([lor[:, kb == i].sum(axis=-1) for i in range(U.shape[-1])], axis=-1)  # (12, K)
    w = 1.0 / (dk + wk)
    hbar = U / (df * cnt[use])                                  # the band-pass's mean |H|² in each band
    inb = (hbar > 0.5)[:, :, None, :]                           # the band's own bands …
    outb = (hbar < 0.01)[:, :, None, :]                         # … and those the floor must explain
    Uw = U[:, :, None, :] * w
    Vw = V[None, None, :, :] * w
    dw = dk * w
    with np.errstate(divide="ignore", invalid="ignore"):
        # the floor covers every band outside the band-pass (there the band contributes < 1 %): what power lies
        # there is the floor's, never left unmodelled
        a0 = np.max(np.where(outb, dk / V[None, None, :, :], 0.0), -1)
        a0 = np.where(np.isfinite(a0), np.maximum(a0, 0.0), 0.0)
        rest = dw - a0[..., None] * Vw
        ab = np.sum(np.where(inb, Uw * rest, 0.0), -1) / np.sum(np.where(inb, Uw * Uw, 0.0), -1)
        ab = np.where(np.isfinite(ab), np.maximum(ab, 0.0), 0.0)
    model = ab[..., None] * U[:, :, None, :] + a0[..., None] * V[None, None, :, :]
    r = np.log(model + wk) - np.log(dk + wk)
    # under-modelled power (r < 0) is the optimistic side: it weighs UNDER_WEIGHT times an excess
    cost = np.sum(np.where(r < 0, UNDER_WEIGHT * r**2, r**2), -1)
    cost = np.where(valid[..., None], cost, np.inf)
    i, j, t = np.unravel_index(int(np.argmin(cost)), cost.shape)
    A_b, A_0, tau0 = float(ab[i, j, t]), float(a0[i, j, t]), float(taus[t])
    f1, f2 = float(F1[i, j]), float(F2[i, j])
    # RMS of each component: ∫ S df (the band-pass's exactly, its equivalent noise bandwidth, on a fine grid)
    fi = np.geomspace(1e-4, 0.5 * fs, 4000)
    band_var = A_b * float(np.trapezoid(band_shape(fi, f1, f2), fi))
    floor_var = A_0 / (4.0 * tau0)
    return {"floor_rms_m_s2": math.sqrt(floor_var), "floor_tau_s": tau0,
            "band_hz": (f1, f2) if A_b > 0 else None, "band_rms_m_s2": math.sqrt(band_var)}


def band_config(band: dict) -> dict:
    """FilterConfig fields of a fitted band-limited sway (:func:`fit_band`; the floor goes in
    ``ext_acc_rms_m_s2`` / ``ext_acc_tau_s``)."""
    return {
        "ext_acc_band_hz": band["band_hz"],
        "ext_acc_band_rms_m_s2": band["band_rms_m_s2"] if band["band_hz"] else 0.0,
        "ext_acc_band_order": BAND_ORDER,
    }


def band_report(band: dict | None) -> dict:
    """The band-limited sway's keys of ``hand.external_acc_psd`` (beside the Gauss–Markov ones, which then
    describe its floor)."""
    if band is None:
        return {"psd_model": "gauss_markov_highpass"}
    return {
        "psd_model": "gauss_markov_floor_plus_butterworth_band",
        "band_model": (
            "a_e = a Gauss–Markov floor (rms_m_s2, tau_s; no high-pass) + white noise through an analog "
            f"Butterworth band-pass band_hz of {BAND_ORDER} poles per edge with RMS band_rms_m_s2: one-sided "
            "PSD 4σ²τ/(1 + (2πfτ)²) + S_b/(1 + ((f² − f₁f₂)/(f(f₂ − f₁)))^(2N))"
        ),
        "band_hz": list(band["band_hz"]) if band["band_hz"] else None,
        "band_rms_m_s2": band["band_rms_m_s2"],
        "band_order": BAND_ORDER,
        "floor_rms_m_s2": band["floor_rms_m_s2"],
        "floor_tau_s": band["floor_tau_s"],
    }


# the states whose σ the slow residual's spectrum corrects (calib.session.spectral): those the turns inform, at
# 0.03–0.5 Hz; not the attitude, the bias's random walk, a_e's own states or the temperature coefficients, whose
# information lies at the session's own scale, below what a 40-s Welch segment resolves
SPECTRAL_BLOCKS = ("gyro_scale", "gyro_nonorth", "lever_arm", "acc_bias", "acc_scale", "acc_nonorth", "acc_delay",
                   "gyro_g_sens", "gyro_misalign")


def spectral_sigma(P: np.ndarray, out: FilterRun, layout: StateLayout, cfg: FilterConfig, f_lp: np.ndarray,
                   slow_f: np.ndarray, slow_resid: np.ndarray, kreg: np.ndarray, fs: float, dec: int, r_var: float,
                   estimate: bool, prefilter_gain2: Callable[[np.ndarray], np.ndarray] | None = None):
    """P with the σ of :data:`SPECTRAL_BLOCKS` from the slow residual's own spectrum (calib.session.spectral): P_D = P +
    ΔP gives each state's variance, and P → D P D, D = diag(σ_D/σ) on those states (1 elsewhere), keeps the model's
    correlations, so P stays positive definite (the temperatures where S and b_a are stated still come from the filter's
    own P: kf_hand).  ``slow_f`` = f_lp − K r̂ (N, 3) and ``slow_resid`` = |slow_f| − g (N,): kf_hand's slow residual.
    ``prefilter_gain2``: |H(f)|² of the tremor pre-filter the data went through (the a_e model as the low-passed data
    can carry it, :mod:`calib.session.spectral`), None for the filter's folded model.  Returns (P, the correction's
    report)."""
    sel = np.concatenate([np.arange(layout.offset(b), layout.offset(b) + 3) for b in SPECTRAL_BLOCKS if layout.has(b)])
    wts = update_weights(out.record, layout, sel, cfg.ext_acc_highpass_order)
    u = slow_f / np.linalg.norm(slow_f, axis=1)[:, None]
    # ∂e/∂β of the estimated terms in e: the lever arm (−uᵀK) and, estimated, the accelerometer's b, S, G (−uᵀ[I, diag
    # f, J_G(f)])
    jac = [-np.einsum("ni,nij->nj", u, kreg)]
    blocks = [layout.offset("lever_arm")]
    if estimate:
        jac += [-u, -u * f_lp, -np.einsum("ni,nij->nj", u, nonorthogonality_jacobians(f_lp))]
        blocks += [layout.offset(b) for b in ("acc_bias", "acc_scale", "acc_nonorth")]
    jidx = np.concatenate([np.arange(o, o + 3) for o in blocks])
    corr = spectral_correction(wts, out.record.updated, slow_resid, fs, dec,
                               lambda f: gauss_markov_psd(f, cfg.ext_acc_rms_m_s2, cfg.ext_acc_tau_s,
                                                          cfg.ext_acc_highpass_tau_s, cfg.ext_acc_highpass_order),
                               r_var, np.concatenate(jac, axis=1), P[np.ix_(jidx, jidx)],
                               prefilter_gain2=prefilter_gain2)
    var = np.diag(P)[sel]
    var_d = var + np.diag(corr.delta)
    factor = np.sqrt(np.maximum(var_d, 1e-4 * var) / var)
    d = np.ones(P.shape[0])
    d[sel] = factor
    names = [n for b in SPECTRAL_BLOCKS if layout.has(b) for n in (f"{b}_{a}" for a in "xyz")]
    report = {"sigma_factor": dict(zip(names, factor.tolist())), **corr.to_dict()}
    return P * np.outer(d, d), report
