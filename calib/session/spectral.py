"""The covariance of a filter's estimate under the disturbance spectrum the data show, not the one it modelled.

A Kalman filter's P is the covariance of its estimate only when its noise model is right.  ``kf_hand`` models the hand's
slow acceleration a_e (nav frame ENU, after the tremor low-pass) as a high-passed first-order Gauss–Markov process
fitted to the data (:func:`calib.session.hand.sway.fit_gauss_markov`); a real hand's spectrum has another shape
(gyrosim's sway is flat over 0.2–1 Hz and ~30 dB lower outside, which no first-order family follows), and then P is not
the estimate's covariance — with gyrosim's shaky hand σ of S, G was 1.2–1.4× too large (NEES(6) 3.2 against [5.08,
7.00]).

The filter is linear in its measurements (the error-state form at the last pass's linearisation), so its final
estimate of the parameters β (p of them) is

    β̂ = Σ_k W_k z_k + (terms of the prior and the gyro noise),    W_k = Λ_k K_k,
    Λ_N = S (the selector of β's rows),   Λ_{k−1} = Λ_k (I − K_k H_k) Φ_k              (the adjoint recursion)

with z_k the levelling innovation of update k (nav E, N: m/s²), K_k its gain, H_k its measurement matrix and
Φ_k the error state's transition into step k — recorded by the compiled kernel
(:class:`calib.session.kernel.FilterRecord`).  The disturbance a_e + v enters z_k in the nav frame; for a stationary
disturbance, independent between the nav axes (E, N; and U where the filter uses the vertical row), with
one-sided PSD S(f) on the updates' grid (spacing Δ, aliasing included),

    Cov(β̂)_a = Σ_i ∫₀^{1/2Δ} Re[V_i(f) V_i(f)ᴴ] S(f) df,    V_i(f) = Σ_k W_k[:, i] e^{−i2πfkΔ},

the Wiener–Khinchin form of Σ_{k,l} W_k C(k − l) W_lᵀ.  The filter's own P contains this term with the
model's spectrum S_M (its Gauss–Markov a_e + its white R); the estimate's actual covariance has the data's
S_D instead, so

    P_D = P + Σ_i ∫ Re[V_i V_iᴴ] (S_D − S_M) df,

the covariance analysis of a sub-optimal filter (gains from one model, errors under another: Gelb, *Applied
Optimal Estimation*, 1974, §7.2; the "sandwich" form of a mis-specified estimator's covariance: Huber 1967,
White 1982) with the true model replaced by the disturbance's measured spectrum.  S_D is the spectrum of
e = |f_lp − K r̂| − g, the slow acceleration along gravity, free of the attitude (the a_e fit's own data; one
axis of an isotropic a_e), Welch-estimated and folded onto the updates' grid; S_M is the model's continuous
PSD folded the same way plus R's white level.  S_D replaces S_M only in the octave bands where their ratio
lies outside Welch's own scatter (a model the data do not contradict keeps its smooth spectrum), and not below
Welch's first bin (1/40 s), where the data cannot resolve the disturbance from the session's slowest terms (a
temperature coefficient's information lies there).

**What the data can have, known without them.**  The filter propagates a_e at every sample and updates every
D-th, so its S_M is the continuous PSD folded at the update rate — its power above the updates' Nyquist
aliased onto every band, 0 Hz included.  The data were low-passed (the zero-phase pre-filter |H(f)|², 4 Hz)
before they were decimated and have none of it.  The reference the data are tested against, and the spectrum
kept where they cannot speak (below the first bin, in the bands inside Welch's scatter), is therefore the
model *as the data can carry it*, S_M' = fold(S_c |H|²) + R, not fold(S_c) + R:

    P_D = P + Σ_i ∫ Re[V_i V_iᴴ] (ρ S_M' − S_M) df,    ρ = the band's S_D/S_M' (1 inside Welch's scatter).

Measured (consumer sensor, accelerometer estimated, steady hand): the aliased floor is ~5× the accelerometer's
own white level, and 75–80 % of the accelerometer bias's and scale's modelled variance was a_e's — a third of it
below 0.025 Hz, where the ratio could not act (err/σ RMS of b_a, S_a 0.52–0.78).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from scipy import signal as sp_signal

from calib.session.kernel import FilterRecord
from calib.session.model import EXT_ACC_EXTRA_BLOCKS, StateLayout

__all__ = ["update_weights", "SpectralCorrection", "spectral_correction", "gauss_markov_psd"]

# e's spectrum: the segments of the a_e fit's own (calib.session.hand.sway.fit_gauss_markov)
WELCH_SEGMENT_S = 40.0
# an octave band's S_D/S_M replaces the model's there when outside Welch's own scatter at this level
BAND_TEST = 0.95


@njit(cache=True)
def _adjoint(sel, K, H, hcols, nh, E, ecols, ne, decay, updated, m, o_ea, o_el, o_e2):  # pragma: no cover
    N = K.shape[0]
    p = sel.size
    n = K.shape[1]
    lam = np.zeros((p, n))
    for a in range(p):
        lam[a, sel[a]] = 1.0                                  # Λ_N = S
    V = np.zeros((N, p, m))
    W = np.zeros((p, m))
    tmp = np.zeros((p, 3))
    for k in range(N - 1, 0, -1):
        if updated[k]:
            for a in range(p):                                # W_k = Λ K_k
                for i in range(m):
                    s = 0.0
                    for r in range(n):
                        s += lam[a, r] * K[k, r, i]
                    W[a, i] = s
                    V[k, a, i] = s
            for e in range(nh[k]):                            # Λ ← Λ (I − K_k H_k) = Λ − W H_k
                c = hcols[k, e]
                for a in range(p):
                    s = 0.0
                    for i in range(m):
                        s += W[a, i] * H[k, i, e]
                    lam[a, c] -= s
        for a in range(p):                                    # Λ ← Λ (I + Ê_k): Ê in the φ rows 0–2
            for i in range(3):
                tmp[a, i] = lam[a, i]
        for e in range(ne[k]):
            c = ecols[k, e]
            for a in range(p):
                s = 0.0
                for i in range(3):
                    s += tmp[a, i] * E[k, i, e]
                lam[a, c] += s
        # Λ ← Λ Φ_ae (x ← αx; z ← βz + (1−β)x; z₂ ← βz₂ + (1−β)(x − z))
        if o_ea >= 0:
            al = decay[k, 0]
            be = decay[k, 1]
            for j in range(3):
                cx = o_ea + j
                cz = o_el + j
                for a in range(p):
                    lx = lam[a, cx]
                    lz = lam[a, cz] if o_el >= 0 else 0.0
                    l2 = lam[a, o_e2 + j] if o_e2 >= 0 else 0.0
                    lam[a, cx] = al * lx + (1.0 - be) * lz + (1.0 - be) * l2
                    if o_el >= 0:
                        lam[a, cz] = be * lz - (1.0 - be) * l2
                    if o_e2 >= 0:
                        lam[a, o_e2 + j] = be * l2
    return V, lam


def update_weights(record: FilterRecord, layout: StateLayout, states: np.ndarray, highpass_order: int) -> np.ndarray:
    """W_k (N, p, rows) of the module docstring: the weight of update k's nav innovation (rows E, N[, U]) on the
    final estimate of the error states ``states`` (p indices of ``layout``); zero where no update was made.
    ``highpass_order``: the Gauss–Markov a_e's (the kernel propagates z₂ for order 2 only)."""
    if any(layout.has(b) for b in EXT_ACC_EXTRA_BLOCKS):
        raise ValueError("the adjoint follows the Gauss–Markov a_e (x, z, z₂); the general shaping filter is not "
                         "supported")
    o_ea = layout.offset("ext_acc") if layout.has("ext_acc") else -1
    o_el = layout.offset("ext_acc_lp") if layout.has("ext_acc_lp") else -1
    o_e2 = layout.offset("ext_acc_lp2") if layout.has("ext_acc_lp2") and highpass_order >= 2 else -1
    r = record
    return _adjoint(np.asarray(states, np.int64), r.gain, r.h, r.hcols, r.nh, r.e, r.ecols, r.ne, r.decay, r.updated,
                    int(r.rows), o_ea, o_el, o_e2)[0]


def gauss_markov_psd(
    f_hz: np.ndarray, rms_m_s2: float, tau_s: float, highpass_tau_s: float, highpass_order: int
) -> np.ndarray:
    """One-sided PSD of the high-passed Gauss–Markov a_e, (m/s²)²/Hz:
    4σ²τ/(1 + (2πfτ)²)·[(2πfτ_h)²/(1 + (2πfτ_h)²)]^m (:func:`calib.session.hand.sway.fit_gauss_markov`)."""
    w2 = (2 * np.pi * np.asarray(f_hz, float)) ** 2
    hp = 1.0
    if math.isfinite(highpass_tau_s):
        hp = (w2 * highpass_tau_s**2 / (1.0 + w2 * highpass_tau_s**2)) ** highpass_order
    return 4.0 * rms_m_s2**2 * tau_s / (1.0 + w2 * tau_s**2) * hp


@dataclass(frozen=True)
class SpectralCorrection:
    """ΔP = Σ_i ∫ Re[V_i V_iᴴ](S_D − S_M) df (p, p) of the module docstring, with the spectra it compared on
    Welch's bins up to the updates' Nyquist: ``f_hz``, ``data_psd`` (e's, the estimated terms' expected part
    removed), ``model_psd`` (the model as the data can carry it, S_M', the ratio's reference; one-sided, (m/s²)²/Hz,
    all folded onto the updates' grid), ``ratio`` the S_D/S_M' used (1 where the octave band's ratio lies inside
    Welch's scatter, and below the first bin) and ``filter_psd`` (S_M, what the filter assumed, aliases included)."""

    delta: np.ndarray
    f_hz: np.ndarray
    data_psd: np.ndarray
    model_psd: np.ndarray
    ratio: np.ndarray
    filter_psd: np.ndarray

    def to_dict(self) -> dict:
        return {"f_hz": self.f_hz.tolist(), "data_psd_m2_s4_per_hz": self.data_psd.tolist(),
                "model_psd_m2_s4_per_hz": self.model_psd.tolist(), "ratio_used": self.ratio.tolist(),
                "filter_psd_m2_s4_per_hz": self.filter_psd.tolist()}


def _fold(f_fine: np.ndarray, psd_fine: np.ndarray, f_out: np.ndarray, f_rep: float, n_alias: int) -> np.ndarray:
    """Σ_k S(|f + k f_rep|) of a one-sided PSD tabulated on ``f_fine`` (zero outside it): the spectrum of the
    process sampled at f_rep, on ``f_out`` ≤ f_rep/2."""
    out = np.zeros_like(f_out)
    for k in range(-n_alias, n_alias + 1):
        out += np.interp(np.abs(f_out + k * f_rep), f_fine, psd_fine, right=0.0)
    return out


def _band_ratio(f: np.ndarray, data: np.ndarray, model: np.ndarray, segments: int) -> np.ndarray:
    """S_D/S_M per octave band (from Welch's first non-zero bin up), 1 where the band's ratio lies inside Welch's own
    scatter — the χ²_ν two-sided ``BAND_TEST`` interval, ν = 2·segments/1.06 per bin (Hann, 50 % overlap: Welch
    1967) × bins / 1.5 (neighbouring Hann bins correlate) — so that a model the data do not contradict keeps its
    smooth spectrum and the correction adds no estimation noise; (len(f),) on Welch's bins (bin 0: 1)."""
    from scipy import stats

    out = np.ones_like(f)
    if f.size < 2:
        return out
    lo = f[1]
    while lo <= f[-1]:
        k = (f >= lo) & (f < 2 * lo)
        lo *= 2
        nb = int(k.sum())
        if nb == 0:
            continue
        r = float(np.sum(data[k]) / max(float(np.sum(model[k])), 1e-300))
        nu = 2.0 * segments / 1.06 * nb / 1.5
        a, b = stats.chi2.ppf([0.5 * (1 - BAND_TEST), 0.5 * (1 + BAND_TEST)], nu) / nu
        out[k] = r if not (a <= r <= b) else 1.0
    return out


def spectral_correction(weights: np.ndarray, updated: np.ndarray, residual_m_s2: np.ndarray, rate_hz: float,
                        every: int, model_psd, r_var_m2_s4: float, residual_jacobian: np.ndarray | None = None,
                        jacobian_cov: np.ndarray | None = None, prefilter_gain2=None) -> SpectralCorrection:
    """ΔP (module docstring) from the update weights ``weights`` (N, p, rows; :func:`update_weights`: nav E, N and, with
    the vertical row, U — every axis with the same spectrum, a_e isotropic as its fit assumes) at the samples
    ``updated`` (N,), the slow residual ``residual_m_s2`` (N,) (e = |f_lp − K r̂| − g, at every sample, ``rate_hz``),
    the updates' spacing ``every`` samples, the model's continuous one-sided PSD ``model_psd(f_hz)`` and its white
    measurement variance per update ``r_var_m2_s4``.  ``residual_jacobian`` (N, q) ∂e/∂β of states β the filter
    estimates (the lever arm; the accelerometer's b, S, G) with their covariance ``jacobian_cov`` (q, q): e is computed
    at their estimates, so their error is in it, and the filter's P already carries it — its expected Welch PSD Σ_ij
    C_ij Re CSD(J_i, J_j) is removed from e's before the test (without it a session with no hand read the
    accelerometer's estimation error, stepping with each attitude, as a disturbance ×1.6–2.4 its white level at 0.03–0.2
    Hz).  ``prefilter_gain2(f_hz)``: |H(f)|² of the zero-phase pre-filter the data passed before the updates (periodic
    in ``rate_hz``; None: no pre-filter) — the reference spectrum is then the model as the data can carry it (module
    docstring)."""
    fs = float(rate_hz)
    dt_u = every / fs
    f_rep = 1.0 / dt_u
    w = np.asarray(weights, float)
    idx = np.flatnonzero(np.asarray(updated, bool))
    if idx.size < 8:
        p = w.shape[1]
        return SpectralCorrection(np.zeros((p, p)), np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0))
    slot = np.round((idx - idx[0]) / every).astype(np.int64)   # the updates' grid (a skipped update: a zero weight)
    m_u = int(slot[-1]) + 1
    grid = np.zeros((m_u,) + w.shape[1:])
    np.add.at(grid, slot, w[idx])
    length = int(2 ** math.ceil(math.log2(4 * m_u)))
    spec = np.fft.rfft(grid, n=length, axis=0)                   # (L/2+1, p, 2)
    f = np.fft.rfftfreq(length, dt_u)
    # the model's: the continuous a_e PSD folded (a Gauss–Markov τ of 0.02 s is white well past the update rate)
    f_fine = np.linspace(0.0, 10 * fs, 200001)
    # (aliases beyond the table's 10 f_s add zero: fold only those inside it)
    n_alias = int(math.ceil(10 * fs / f_rep)) + 1
    s_fine = model_psd(f_fine)
    # S_M: what the filter assumed
    model = _fold(f_fine, s_fine, f, f_rep, n_alias) + 2.0 * r_var_m2_s4 * dt_u
    # S_M': what the data can carry
    reference = model
    if prefilter_gain2 is not None:
        reference = _fold(f_fine, s_fine * prefilter_gain2(f_fine), f, f_rep, n_alias) + 2.0 * r_var_m2_s4 * dt_u
    # the data's: e's Welch PSD (one-sided, at fs; the record's mean removed once, not each segment's, which
    # would bias the first bins low), folded onto the updates' grid and compared with the model's band by band
    e = np.asarray(residual_m_s2, float)
    e = e - e.mean()
    nseg = int(min(e.size, WELCH_SEGMENT_S * fs))
    fw, pw = sp_signal.welch(e, fs=fs, nperseg=nseg, detrend=False)
    if residual_jacobian is not None and jacobian_cov is not None and np.asarray(jacobian_cov).size:
        j = np.asarray(residual_jacobian, float)
        lam, vec = np.linalg.eigh(0.5 * (jacobian_cov + np.transpose(jacobian_cov)))
        y = (j - j.mean(axis=0)) @ (vec * np.sqrt(np.maximum(lam, 0.0)))     # J L, C = L Lᵀ: Welch is quadratic
        known = sp_signal.welch(y, fs=fs, nperseg=nseg, detrend=False, axis=0)[1].sum(axis=1)
        pw = np.maximum(pw - known, 0.0)
    data_w = _fold(fw, pw, fw[fw <= 0.5 * f_rep], f_rep, int(math.ceil(0.5 * fs / f_rep)) + 1)
    fw = fw[fw <= 0.5 * f_rep]
    model_w = np.interp(fw, f, reference)
    segments = max(1, 1 + 2 * (e.size - nseg) // nseg)          # Welch's 50 %-overlap segments
    ratio = _band_ratio(fw, data_w, model_w, segments)
    # below Welch's first non-zero bin the data cannot tell the disturbance from the session's own slow terms: the
    # model as the data can carry it is kept there (ratio 1), as above the last band
    data = reference * np.where(f < fw[1], 1.0, np.interp(f, fw, ratio))
    ds = data - model
    wt = np.full(f.size, 1.0)
    wt[0] = 0.5
    if length % 2 == 0:
        wt[-1] = 0.5
    df = 1.0 / (length * dt_u)
    delta = np.einsum("f,fai,fbi->ab", wt * ds * df, spec, spec.conj()).real
    return SpectralCorrection(0.5 * (delta + delta.T), fw, data_w, model_w, np.where(fw < fw[1], 1.0, ratio),
                              np.interp(fw, f, model))
