"""kf_hand's general shaping-filter a_e and the opt-in band-limited sway model (calib.session.hand.filter:kf_hand_band).

The sway of gyrosim's hands is flat over 0.2–1 Hz and ~30 dB lower outside; the high-passed Gauss–Markov family of
kf_hand cannot follow such a spectrum (docs/hand.md, "A band-limited sway model").  What is tested here:
* the exact discretisation (Van Loan) against the Gauss–Markov closed form;
* the band model's state space against the PSD the fit assumes (one model, two places);
* the general kernel path against the x, z, z₂ code it generalises (same Gauss–Markov model, exact vs first-order
  discretisation of the low-passes);
* the band-power fit on synthetic residuals: a band is found where it is, and power outside it goes to the floor;
* kf_hand_band's report keys, beside the promised ones.
The band model is NOT kf_hand's default: on the independent generator's noise-free sensor it answered "ok" with
NEES 0.1–105 per seed, ΣNEES 379 over 10 (the slow xfail below keeps that measured fact visible).
"""

from __future__ import annotations

import math

import independent_generator as ig
import numpy as np
import pytest
from scipy import signal as sps
from scipy import stats

from gyrosim.recording import Recording

from calib.session.hand import filter as hk
from calib.session.hand import sway
from calib.session.kernel import run_filter
from calib.session.model import (
    EXT_ACC_EXTRA_BLOCKS,
    HAND,
    FilterConfig,
    StateLayout,
    ext_acc_discrete,
    initial_covariance,
)

ITEMS = [("gyro", "scale_factor"), ("gyro", "nonorthogonality")]


def test_exact_discretisation_is_the_gauss_markov_closed_form():
    """ẋ = −x/τ + w, E w² = 2σ²/τ: Φ = e^{−Δt/τ}, Q_d = σ²(1 − e^{−2Δt/τ}) (Gelb 1974 §4.4) — exact, so to
    rounding (1e-12 relative)."""
    tau, s2 = 0.7, 0.03**2
    dts = np.array([0.01, 1 / 119.7, 0.25])
    phi, q = ext_acc_discrete(np.array([[-1 / tau]]), np.array([[2 * s2 / tau]]), dts)
    np.testing.assert_allclose(phi[:, 0, 0], np.exp(-dts / tau), rtol=1e-12)
    np.testing.assert_allclose(q[:, 0, 0], s2 * (1 - np.exp(-2 * dts / tau)), rtol=1e-10)


def test_band_model_state_space_has_the_psd_the_fit_assumes():
    """FilterConfig.ext_acc_model's band-pass (balanced modal form) has |H(f)|² = the fit's Butterworth shape
    (calib.session.hand.sway.band_shape) to 1e-8, and the stationary RMS of a_e is √(σ₀² + σ_b²) (independent
    components)."""
    cfg = FilterConfig(1e-3, 1e-3, ext_acc_rms_m_s2=0.004, ext_acc_tau_s=3.0, ext_acc_band_hz=(0.21, 0.93),
                       ext_acc_band_rms_m_s2=0.02, ext_acc_band_order=sway.BAND_ORDER)
    a, qc, c = cfg.ext_acc_model()
    f = np.array([0.02, 0.1, 0.21, 0.45, 0.93, 2.0])
    ab, cb = a[1:, 1:], c[1:]
    lam, vec = np.linalg.eigh(qc[1:, 1:])                      # rank one: Q_c = b bᵀ
    bb = vec[:, -1:] * math.sqrt(lam[-1])
    h = np.array([cb @ np.linalg.solve(2j * np.pi * fi * np.eye(ab.shape[0]) - ab, bb)[:, 0] for fi in f])
    shape = sway.band_shape(f, 0.21, 0.93)
    np.testing.assert_allclose(np.abs(h) ** 2 / np.abs(h[3]) ** 2, shape / shape[3], rtol=1e-8, atol=1e-12)
    assert cfg.ext_acc_rms_a_m_s2 == pytest.approx(math.hypot(0.004, 0.02), rel=1e-9)


def _session(seed=0, **hand):
    d = ig.generate_arrays(rate_hz=100.0, seed=seed, gyro_noise_deg_s=0.05, acc_noise_g=0.001, **hand)
    return d, Recording(d["t_s"], d["gyro_rad_s"], d["acc_m_s2"], meta={"rate_hz": 100.0})


def test_general_kernel_path_reproduces_the_gauss_markov_code():
    """The same high-passed Gauss–Markov a_e run through the general shaping-filter states (a layout with the
    extra blocks) and through the x, z, z₂ code: S, G agree within 2 % of their σ and σ within 1 % (the only
    difference is the low-passes' discretisation, exact vs first order: O(Δt/τ_h) = 0.5 % per step, averaging out)."""
    d, rec = _session(lever_arm_m=(0.01, 0.07, 0.02), sway_acc_rms_m_s2=0.02)
    t, fs = d["t_s"], 100.0
    cfg = FilterConfig(1.5e-4, 1.5e-3, ext_acc_rms_m_s2=0.02, ext_acc_tau_s=0.3, ext_acc_highpass_tau_s=2.0,
                       ext_acc_highpass_order=2)
    kreg = hk.lever_regressor(d["omega_rad_s"], t, fs)
    theta = np.zeros(18)
    theta[6:9] = d["bias_rad_s"]                      # the static bias in its slot (the layout does not estimate it)
    q0 = d["quat_nb"][0]
    runs = []
    for layout in (HAND, StateLayout(HAND.blocks + EXT_ACC_EXTRA_BLOCKS[:1])):
        out = run_filter(d["gyro_rad_s"][None], d["acc_m_s2"][None], t, q0[None], theta[None],
                         initial_covariance(layout, cfg), layout, cfg, fs, lever_regressor=kreg)
        runs.append((out.theta[0, :6], np.sqrt(np.diag(out.p[0])[3:9])))
    (th1, sd1), (th2, sd2) = runs
    assert np.all(np.abs(th1 - th2) < 0.02 * sd1), (th1 - th2) / sd1
    np.testing.assert_allclose(sd2, sd1, rtol=0.01)


def _coloured(rng, n, fs, sos, rms):
    x = sps.sosfilt(sos, rng.standard_normal(n + 20 * int(fs)))[20 * int(fs):]
    return x * rms / x.std()


def test_band_fit_finds_the_band_and_gives_the_outside_power_to_the_floor():
    """A residual of white noise (the sensor's, PSD W) + a 0.2–1 Hz band (RMS 0.02, 8-pole Butterworth, much steeper
    than the model's) + a 0.05-Hz line (RMS 0.002, outside the band): the fitted edges lie within a 1/3 octave of
    the truth, the band RMS within 15 % (the model's skirts hold a few % more power than the truth's), and the
    model's power in the line's Welch bin is at least what Welch's estimate puts there (the floor must take it: a line
    left unmodelled went into S, G on the independent generator)."""
    fs, n = 100.0, 18000
    rng = np.random.default_rng(3)
    sos = sps.butter(4, [0.2, 1.0], btype="bandpass", fs=fs, output="sos")
    white_psd = 2 * (1.5e-3) ** 2                     # one-sided PSD of a 1.5e-3 m/s²/√Hz sensor
    t = np.arange(n) / fs
    e = (_coloured(rng, n, fs, sos, 0.02) + 0.002 * math.sqrt(2) * np.sin(2 * np.pi * 0.05 * t + 0.3)
         + rng.standard_normal(n) * math.sqrt(white_psd * fs / 2))
    fit = sway.fit_band(e, 1 / fs, white_psd * fs / 2, white_psd)
    f1, f2 = fit["band_hz"]
    assert 0.2 / 2 ** (1 / 3) < f1 < 0.2 * 2 ** (1 / 3) and 1.0 / 2 ** (1 / 3) < f2 < 1.0 * 2 ** (1 / 3), fit
    assert fit["band_rms_m_s2"] == pytest.approx(0.02, rel=0.15)
    a0 = 4 * fit["floor_rms_m_s2"] ** 2 * fit["floor_tau_s"]
    fi_all = np.geomspace(1e-4, 50, 4000)
    ab = fit["band_rms_m_s2"] ** 2 / np.trapezoid(sway.band_shape(fi_all, f1, f2), fi_all)
    density = a0 / (1 + (2 * np.pi * 0.05 * fit["floor_tau_s"]) ** 2) + ab * sway.band_shape(0.05, f1, f2)
    # × Welch's bin width (40-s segments): the power the model puts in the line's bin
    model = density * fs / int(40 * fs)
    f, pxx = sps.welch(e - e.mean(), fs=fs, nperseg=int(40 * fs))
    k = int(np.argmin(np.abs(f - 0.05)))
    nseg = 2 * n / int(40 * fs) - 1
    # the line's power as Welch's estimate shows it in its bin, less the fit's 2σ margin on the white floor's share
    seen = (pxx[k] - white_psd * (1 + 2 / math.sqrt(nseg))) * (f[1] - f[0])
    assert model >= 0.99 * seen, (model, seen, fit)


def test_band_fit_without_excess_power_is_empty_and_deterministic():
    """White noise at the stated level only: no band, no floor (the 2σ margin on the white floor) — and the same
    input gives the same fit."""
    fs, n = 100.0, 18000
    rng = np.random.default_rng(5)
    e = rng.standard_normal(n) * 1e-3
    w = 1e-6
    fit = sway.fit_band(e, 1 / fs, w, 2 * w / fs)
    assert fit == sway.fit_band(e.copy(), 1 / fs, w, 2 * w / fs)
    # variance in the fitted model is at most a few % of the white noise's own in 0.02–3 Hz
    assert fit["band_rms_m_s2"] ** 2 + fit["floor_rms_m_s2"] ** 2 < 0.05 * (2 * w / fs) * 3.0, fit


def test_kf_hand_band_reports_its_model_beside_the_promised_keys():
    """kf_hand_band on an independent-generator session with a hand: the promised external_acc_psd keys are all
    there, the band's are added (psd_model, band_hz, band_rms_m_s2, band_order, floor_*), the fitted band contains
    most of the generator's 0.2–1 Hz sway band, and its S, G error is within 4.5σ (χ²-free sanity bound: one seed)."""
    d, rec = _session(lever_arm_m=(0.01, 0.07, 0.02), tremor_acc_rms_m_s2=0.07, sway_acc_rms_m_s2=0.02)
    cal = hk.kf_hand_band(rec)
    psd = cal.diagnostics["hand"]["external_acc_psd"]
    for k in ("rms_m_s2", "tau_s", "highpass_tau_s", "highpass_order", "acc_rms_m_s2", "psd_one_sided_0hz_m2_s4_per_hz",
              "tremor_band_rms_m_s2", "lowpass_hz", "update_every_samples", "psd_model", "band_hz", "band_rms_m_s2",
              "band_order", "floor_rms_m_s2", "floor_tau_s"):
        assert k in psd, k
    assert psd["psd_model"] == "gauss_markov_floor_plus_butterworth_band"
    f1, f2 = psd["band_hz"]
    assert f1 < 0.3 and f2 > 0.7, psd
    e = np.concatenate([cal.value(t, k) for t, k in ITEMS]) - np.concatenate([d["scale_factor"], d["nonorthogonality"]])
    z = e / np.sqrt(np.diag(cal.block_covariance(ITEMS)))
    assert np.all(np.abs(z) < 4.5), z
    assert hk.kf_hand(rec).diagnostics["hand"]["external_acc_psd"]["psd_model"] == "gauss_markov_highpass"
    # the experimental model's σ failed the noise-free consistency test (below): its answer must never exit 0
    assert cal.status == "inconsistent" and any("experimental sway model" in w for w in cal.warnings), cal.status


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="band model over-confident on a noise-free sensor (measured ΣNEES 379 > 102.7 "
                                       "over 10 seeds, every seed ok): why it is not kf_hand's default")
def test_kf_hand_band_is_honest_on_the_noise_free_independent_generator():
    """Ten seeds of tests/session/test_hand_conditions.py's noise-free sensor with a hand: ΣNEES inside χ²(60)'s 99.9 %
    interval — what the default kf_hand passes.  Measured with the band model: ΣNEES 379 (seeds 0–9: 36, 56, 33, 26,
    2.5, 105, 42, 0.7, 78, 0.1), every seed "ok"."""
    total = 0.0
    hand = dict(lever_arm_m=(0.01, 0.07, 0.02), tremor_acc_rms_m_s2=0.07, sway_acc_rms_m_s2=0.02)
    for seed in range(10):
        d = ig.generate_arrays(rate_hz=100.0, seed=seed, gyro_noise_deg_s=0.0, acc_noise_g=0.0,
                               kin=ig.kinematics(100.0, ig.STEPS), **hand)
        cal = hk.kf_hand_band(Recording(d["t_s"], d["gyro_rad_s"], d["acc_m_s2"], meta={"rate_hz": 100.0}))
        e = np.concatenate([cal.value(t, k) for t, k in ITEMS]) - np.concatenate(
            [d["scale_factor"], d["nonorthogonality"]]
        )
        total += float(e @ np.linalg.solve(cal.block_covariance(ITEMS), e))
    lo, hi = stats.chi2.ppf([0.0005, 0.9995], 60)
    assert lo < total < hi, total
