"""``kf_hand``: the gyro calibration with the hand in the model.

A hand-held session's accelerometer senses, besides gravity and its white noise (body frame RFU,
nav ENU; f the specific force, g_b gravity in the body):

    f = g_b + K(ω, ω̇) r + C(q)ᵀ a_e + v,     K(ω, ω̇) = [ω̇×] + [ω×][ω×]

* r — the lever arm from the rotation centre (wrist, elbow) to the accelerometer, body frame, m: a constant (the
  accelerometer–gyro site offset is part of it).  f − g_b = ω̇ × r + ω × (ω × r) is deterministic and correlated with
  the rotation, so the paper's filter turns it into S and G errors (0.3 % with a 6 cm wrist): it is estimated, three
  states.  K is built from the rate compensated with the pass's S, G, b (:func:`lever_regressor`), so K r̂ depends on
  them too: the update carries that dependence, ∂(K r̂)/∂(S, G, b) (:func:`lever_jacobian`) — without it a session that
  pins S, G weakly left σ ~1.4× optimistic;
* a_e — the hand's own translation, in nav: tremor (8–12 Hz) and sway (0.2–1 Hz), coloured.  The calibration's
  information lives below ~1 Hz (the rotations), so the tremor band is removed rather than modelled: the specific force
  is rotated to nav with the gyro's own attitude, low-passed there (zero-phase Butterworth, ``CUTOFF_HZ``; in nav, so
  that the slow gravity direction, not the fast wobble the gyro also sees, is what is smoothed) and rotated back — a
  whitening pre-filter — and the filter updates every D-th sample with R = σ_f²/D (the white noise averaged over D
  samples: the information per second of the raw samples, not more), D = ⌊1/ρ⌋ where ρ = Σh² is the low-pass's
  white-noise variance ratio.  The slow rest (sway) is a shaping filter per nav axis: a first-order Gauss–Markov x (σ_s,
  τ) high-passed (τ_h, order m ∈ {1, 2}): a_e = x − z (− z₂), z the low-pass of x, z₂ that of x − z — a hand's
  translation is bounded, so its acceleration has no power at 0 Hz (the one-sided PSD 4σ_s²τ/(1 + (2πfτ)²)·[(2πfτ_h)²/(1
  + (2πfτ_h)²)]^m, estimated from the data, is reported); three to nine states;
* axis wobble is real rotation: the gyro sees it, nothing to remove;
* the gyro bias b_g drifts during a session (a consumer gyro's warm-up, its g-sensitivity after a change of attitude,
  bias instability): a random-walk state, ḃ_g = w, E w² = q_b, q_b from the rests' own bias change (:func:`bias_drift`;
  0 when the rests agree within their white noise), prior the first rest's average; on a warming sensor (a temperature
  channel that moved) the warm-up's ramp in its own shape, b_g(T) = b_g + c_b (T − T₀), three states
  (``GYRO_TEMP_BIAS``, :func:`_temp_bias_prior`), and the walk then q_b/2 unless the innovations reject it
  (``QB_LADDER``).  The filter starts after that rest (its gyro samples would otherwise inform the bias twice), the tilt
  prior the rest's accelerometer mean's σ;
* the gyro's g-sensitivity (a MEMS gyro's "linear acceleration sensitivity", 0.1 °/s/g for the MPU-9250 family): b_g,i =
  b_i + k_i f_i with f the (calibrated, low-passed) specific force — a bias step after every change of attitude, which a
  random walk can only cover by inflating σ; three states, prior σ 1e-3 rad/s per m/s² (0.56 °/s/g), reported in
  ``diagnostics["gyro_g_sensitivity"]``;
* the accelerometer's delay behind the gyro, δ (s): f̃(t) = f(t − δ), to first order f = f̃ + δ ḟ̃ (ḟ̃ the derivative of
  the low-passed f̃, body) — one state for the triad (``acc_delay``, :func:`_common_delay_prior`, prior σ 10 ms).  The
  filter's attitude comes from the gyro and its levelling measurement from the accelerometer, so a skew between them
  reads as an attitude error δ ω × g_b during every turn: at 1 rad/s a 1-ms skew is 10 mm/s², the signature of a 1e-3
  scale factor error over the same turn.  Two triads' anti-alias filters of different bandwidth make such a skew
  (MPU-9250 DLPF setting 3: gyro 5.9 ms, accelerometer 4.88 ms); unmodelled it stayed in the innovations, and σ of S, G
  was inflated for it (MPU-9250 preset, ideal hand, 20 seeds: NEES(6) 4.24 → 4.85 with δ estimated: δ̂ −0.81 ms mean,
  0.16 ms spread over the seeds, reported σ 0.16–0.21 ms, against the simulated gyro's 0.82-ms low-pass delay); reported
  in ``diagnostics["acc_delay"]``;
* the scale factor's temperature dependence (``gyro_temp_scale``), when the recording has a temperature channel that
  moved ≥ ``THERMAL_MIN_SPAN_C`` (a board warming after power-on): S_i(T) = S_i(T₀) + s_T,i (T − T₀), three states with
  a vague prior.  A session spanning a degree cannot measure s_T, but it does pin S_i at the temperature where axis i's
  rotations happened (:func:`scale_at_temperature`), and that is what is reported, with the temperatures, in
  ``diagnostics["temperature"]`` — a scale factor holds at a temperature (measured on the MPU-9250 preset, zhou2020
  schedule: 25.40, 25.24, 25.62 °C for x, y, z in a session warming from 25.0 to 25.85 °C; the constant-S filter's
  estimates are S at the same temperatures, it just did not say so);
* likewise at a rate: a gyro's scale is not exactly linear (k ω|ω|, ±0.1 % of full scale on the MPU-9250), and a linear
  S learnt from the session's turns is the chord slope over ±m_i, m_i = Σ|ω_i|³/Σω_i² (:func:`scale_reference_rate`,
  reported in ``diagnostics["scale_reference_rate"]``);
* a gyro bias drift while the recorded temperature stayed flat (a flicker floor or a random walk — the rests cannot
  tell): σ is the two models' mixture (:func:`_drift_ambiguity`,
  ``diagnostics["gyro_bias_drift"]["constant_bias_check"]``);
* with the accelerometer estimated (``kf_hand_joint``) and a temperature channel that moved: the accelerometer bias's
  temperature dependence, b_a(T) = b_a(T₀) + c_a (T − T₀) (``acc_temp_bias``, three states, prior σ 0.1 m/s²/°C) — the
  "zero-g level change vs. temperature" of a MEMS accelerometer (InvenSense PS-MPU-9250A-01 rev 1.1: ±1.5 mg/°C), first
  order over a session's degree as the temperature-point compensation of an IMU's acceleration-channel zero bias is
  piecewise linear (/work/shared/seeds/001, ERICCO FOG-IMU calibration §4; polynomial temperature-drift models in T −
  T_ref: seeds/003, Qi et al. 2017 for MEMS capacitive accelerometers) — and the gyro scale's s_T as above.  Without it
  a warming board's bias drift (MPU-9250 preset: 0.5 mg/°C σ over 25.0 → 25.85 °C) sat in the filter's constant b_a and
  bent the attitude it levels, so σ of S, G was ~25 % small (Monte Carlo NEES 9.3 against [5.08, 7.00]).  b_a is
  reported at the temperatures T_a,i where it decouples from c_a (:func:`acc_bias_at_temperature`) and the compensation
  of every sample uses b_a(T(t)); the initial tilt, levelled on the first rest's mean, carries c_a's error through the
  rest's T − T₀ in P₀. Without a temperature channel nothing models the drift (measured: NEES(6) 8.3 ideal hand, 7.2
  typical on that preset with the channel removed; docs/hand.md).

Noise levels from the data, as every estimator here (:mod:`calib.session.noiselevels`), but from the first
rest's spectrum *above* the tremor band (:func:`white_density`): a hand's rest is not still, and its
standard deviation would count the tremor as sensor noise (and make σ pessimistic by that much) — or at
2–6 Hz when an output low-pass (a DLPF) rolls the band above the tremor off (:func:`white_density_check`:
the low band higher *and* the high band falling; reported in ``diagnostics["noise"]`` with a warning).

Estimation (iterated, each pass linearised at the previous pass's estimate; compiled kernel
:func:`calib.session.kernel.run_filter` with the :func:`hand_layout`: attitude, S, G, gyro bias, lever arm,
x, z, z₂ (:data:`calib.session.model.HAND_BIAS`), [c_b, s_T], [g-sensitivity], δ — 27 states, 33 with c_b and s_T (a
temperature channel that moved), 30 with the opt-in g-sensitivity alone, 36 with both; the unused z₂
(m = 1) or z (no high-pass) inert):

1. pass 1: σ_s from the session's (|f_lp| − g)² (as ``kf_session_r``), τ = 1 s, no high-pass, r̂ = 0;
2. passes 2 and 3: (σ_s, τ, τ_h, m) from the previous pass's lever arm: e = |f_lp − K r̂| − g is the
   component of a_e along gravity (attitude-free, so the gyro's own errors do not enter; for an
   isotropic a_e its variance is one axis's), fitted to e's spectrum (:func:`_gm_from_residual`).

The result's σ is the filter's P with the σ of S, G, the lever arm and the accelerometer's parameters taken from
the slow residual's own spectrum rather than the fitted model's (:func:`_spectral_sigma`,
:mod:`calib.session.spectral`: the first-order family cannot follow a hand's band-limited sway, and the filter
sees its model sampled at the updates, aliased — σ of S, G was 1.2–1.4× too large with gyrosim's typical and shaky
hands), inflated from the innovations when they still carry more low-frequency power than the model
(:func:`calib.session.consistency.innovation_inflation`).  The hand's
parameters go to ``diagnostics["hand"]``: ``lever_arm_m`` with ``lever_arm_std_m``,
``external_acc_psd`` (σ_s, τ, τ_h, m, a_e's RMS, the PSD at 0 Hz, the tremor-band RMS removed) — a
finding for the user; ``diagnostics["gyro_bias_drift"]`` the bias's random walk found.

A session whose motion cannot tell the lever arm from S or G (posterior correlation above
``CONFOUND_CORRELATION``) is refused with the parameters named and the motion that separates them:
the lever arm's acceleration grows with ω² (and ω̇), a scale factor's attitude error with ∫ω, so the
same rotation at two different speeds separates them.

Source: the lever-arm kinematics of any rigid body (e.g. Titterton & Weston, *Strapdown Inertial
Navigation Technology*, 2nd ed., §10.4, lever-arm compensation); Gauss–Markov shaping filters for
coloured measurement noise: Gelb, *Applied Optimal Estimation* (1974), §4.5; Bryson & Henrikson 1968.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy import signal as sp_signal

from gyrosim.calibration import Calibration
from gyrosim.effects import WhiteNoise
from gyrosim.errors import RecordingError
from gyrosim.recording import Recording
from gyrosim.rotations import quat_conjugate, quat_rotate, skew
from gyrosim.strapdown import integrate_gyro

from calib.session.consistency import (
    INFLATION_BLOCK_S,
    apply_inflation,
    check_estimate,
    check_innovations,
    innovation_inflation,
    rest_gravity,
    verdict,
)
from calib.session.gravityfit import GravityFit, compensate_acc, fit_gravity
from calib.session.hand.checks import check_hand_assumptions
from calib.session.kernel import LeverJacobian, regressor_half_window, run_filter
from calib.session.model import (
    ACC_DELAY_BLOCKS,
    BLOCK_LABELS,
    EXT_ACC_EXTRA_BLOCKS,
    G_SENS_BLOCKS,
    HAND_BIAS,
    HAND_JOINT,
    SENSOR_EXTRA_BLOCKS,
    FilterHistory,
    StateLayout,
    initial_covariance,
    leave_out_means,
    m_matrix,
    nonorthogonality_jacobians,
    q_matrix,
    theta_slice,
)
from calib.session.noiselevels import (  # noqa: F401 (re-exported)
    WHITE_BAND2_HZ,
    WHITE_BAND_HZ,
    WHITE_SEGMENT_S,
    white_density,
    white_density_check,
    white_variance_relative_sd,
)
from calib.session.paper import (
    _apply_observability,
    _initial_attitude,
    _observability,
    _tilt_sigma,
    prepare,
    refuse_if_nothing_observed,
    rest_mask,
)
from calib.session.rest_bias import rest_bias
from calib.session.spectral import gauss_markov_psd, spectral_correction, update_weights

__all__ = [
    "kf_hand",
    "CUTOFF_HZ",
    "CONFOUND_CORRELATION",
    "lever_regressor",
    "lever_jacobian",
    "white_density",
    "BiasDrift",
    "bias_drift",
    "THERMAL_MIN_SPAN_C",
    "session_temperature",
    "scale_at_temperature",
    "scale_reference_rate",
    "joint_layout",
    "acc_bias_at_temperature",
]

CUTOFF_HZ = 4.0            # below the tremor band (8–12 Hz), above the schedule's rotations (< 1 Hz)
ORDER = 4
CONFOUND_CORRELATION = 0.98
LOW_BAND_HZ = 0.2          # the rotations' band, where the Gauss–Markov model is fitted to the residual's PSD
PASSES = 3
SPECTRAL_SIGMA = True      # P corrected to the slow residual's measured spectrum (calib.session.spectral); False: the
#                            model's P, for the before/after measurements of docs/hand.md
# the correction's reference is the a_e model as the low-passed data can carry it (no aliases:
PREFILTER_REFERENCE = True
# calib.session.spectral); False: the filter's folded model, as before (docs/hand.md) kf_hand's a_e: "gauss_markov" (the
# high-passed Gauss–Markov family, _gm_from_residual; the default) or "band" (a Gauss–Markov floor + a Butterworth
# band-pass, _band_from_residual; opt-in, calib.session.hand.filter:kf_hand_band — docs/hand.md, "A band-limited sway
# model": not strictly closer to 6 on gyrosim, and ΣNEES 379 (10 seeds) with every seed "ok" on the independent
# generator's noise-free sensor, so not the default)
SWAY_MODELS = ("gauss_markov", "band")
LAYOUT = HAND_BIAS         # kf_hand (accelerometer calibrated); kf_hand_joint: HAND_JOINT
# the registered estimator each accelerometer mode of :func:`kf_hand` is (the label its result carries)
REGISTERED_NAME = {"calibrated": "kf_hand", "estimate": "kf_hand_joint"}
DRIFT_QUANTILE = 0.95      # the rests' bias differences must exceed their white-noise χ² quantile to be drift
LEVER_INFLATION_BLOCK_S = 1.0   # the lever arm's σ inflation test's blocks (its information: 0.1–1 Hz; see kf_hand)
# the scale factor's temperature coefficient is a state when the session's temperature moved this much
THERMAL_MIN_SPAN_C = 0.2
THERMAL_SMOOTH_S = 2.0     # the temperature channel is averaged over this window (its quantisation and noise)
# kf_hand on a warming sensor (the temperature moved ≥ THERMAL_MIN_SPAN_C): the gyro bias's temperature coefficient c_b
# is a state, b_g(T) = b_g + c_b (T − T₀) — the warm-up's ramp in its own shape, not a random walk fitted to its
# end-to-end change
GYRO_TEMP_BIAS = True
# … and the random walk keeps what c_b does not explain, which two rests cannot measure (three degrees of freedom, c_b
# has three): the last pass tries q_b = λ q̂_b for λ in this ladder and keeps the first whose innovations pass κ̂'s test
# (calib.session.consistency.innovation_inflation; the last λ when none does).  Measured (MPU-9250 preset, ideal hand,
# kf_hand, 4 × 50 seeds, NEES(6), 200-seed band [5.52, 6.48]): the random walk alone 4.75; c_b with (1,) 4.75, (0.5, 1)
# 5.75, (0.25, 1) 6.34, (1/16, 1/4, 1) 6.9 over 100 seeds; fixed λ = 0.25 6.13 with 3 of 100 seeds "inconsistent", λ = 0
# 5.3 with 45 of 100 (docs/hand.md, "The warm-up's ramp as a state")
QB_LADDER = (0.5, 1.0)


def hand_layout(temperature: bool, g_sensitivity: bool = False, band: bool = False, delay: bool = True) -> StateLayout:
    """kf_hand's states: :data:`calib.session.model.HAND_BIAS` (attitude, S, G, gyro bias, lever arm, x, z, z₂), then
    the bias's and the scale factor's temperature coefficients c_b (``GYRO_TEMP_BIAS``) and s_T when the session's
    temperature moved (``temperature``), then with ``g_sensitivity`` the gyro's g-sensitivity (diagonal: b_g,i = b_i +
    k_i f_i, f the specific force), then with ``delay`` (default) the accelerometer's delay behind the gyro
    (``acc_delay``: one δ, :func:`_common_delay_prior`) — 27 to 36 states (24 to 33 without δ).  The g-sensitivity is
    off by default: on the measured x-IMU3 hand-held session it took the lever arm's information (r̂ 5.3 → 2.0 cm, σ
    ×2.5–3); on the MPU-9250 preset it brought NEES into its band.  ``band``: the band-limited sway's extra
    shaping-filter states (:data:`calib.session.model.EXT_ACC_EXTRA_BLOCKS`; with x, z, z₂ they hold the floor and the
    band-pass's 2·``BAND_ORDER`` states per nav axis)."""
    return StateLayout(
        HAND_BIAS.blocks
        + (("gyro_temp_bias",) if temperature and GYRO_TEMP_BIAS else ())
        + (("gyro_temp_scale",) if temperature else ())
        + (G_SENS_BLOCKS if g_sensitivity else ())
        + (EXT_ACC_EXTRA_BLOCKS[: 2 * BAND_ORDER - 2] if band else ())
        + (ACC_DELAY_BLOCKS if delay else ())
    )


def _band_config(band: dict) -> dict:
    """FilterConfig fields of a fitted band-limited sway (:func:`_band_from_residual`; the floor goes in
    ``ext_acc_rms_m_s2`` / ``ext_acc_tau_s``)."""
    return {
        "ext_acc_band_hz": band["band_hz"],
        "ext_acc_band_rms_m_s2": band["band_rms_m_s2"] if band["band_hz"] else 0.0,
        "ext_acc_band_order": BAND_ORDER,
    }


def _band_report(band: dict | None) -> dict:
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


# kf_hand_joint on a warming sensor: the gyro scale's temperature coefficient s_T as well as the accelerometer
# bias's c_a (measured: docs/hand.md, "kf_hand_joint")
JOINT_GYRO_THERMAL = True
# … but not the gyro bias's c_b (GYRO_TEMP_BIAS, kf_hand's): measured (MPU-9250, 50 seeds per hand) it took
# kf_hand_joint's NEES(6) from 5.59, 5.60, 5.67, 5.88 to 6.58, 6.59, 6.70, 6.89 — in band — but its NEES(15) with the
# accelerometer from 15.85, 16.18, 16.26, 14.35 to 17.14, 17.42, 17.63, 15.74 against [13.52, 16.56]: the
# accelerometer's own σ is ~1.2× small there (z RMS of b_a, S_a,x, S_a,y 1.13–1.33, unchanged by c_b), which the gyro's
# cautious σ had hidden (docs/hand.md, "The warm-up's ramp as a state").  S_a's share was its scoring at ±g instead of
# the force the session saw (acc_scale_reference_force since: NEES(15) without c_b 14.93, 15.30, 15.56, 13.85); b_a's
# share of the accelerometer's nonlinearity remains (z RMS 1.21 on x), so c_b stays off here until that is stated too
JOINT_GYRO_TEMP_BIAS = False


def joint_layout(temperature: bool, gyro_thermal: bool | None = None, delay: bool = True,
                 gyro_temp_bias: bool | None = None) -> StateLayout:
    """kf_hand_joint's states: :data:`calib.session.model.HAND_JOINT` (33), and when the session's temperature moved
    (``temperature``) the accelerometer bias's temperature coefficient c_a (``acc_temp_bias``, 3 states) and —
    ``gyro_thermal``, default ``JOINT_GYRO_THERMAL`` — the gyro scale's s_T (``gyro_temp_scale``, as kf_hand), and with
    ``gyro_temp_bias`` (default ``JOINT_GYRO_TEMP_BIAS``, off) the gyro bias's c_b as kf_hand, and with ``delay``
    (default) the accelerometer's delay δ (as kf_hand): 36, 39 or 42 states (33, 36 or 39 without δ; 3 more with
    c_b)."""
    dl = ACC_DELAY_BLOCKS if delay else ()
    if not temperature:
        return StateLayout(HAND_JOINT.blocks + dl)
    gt = JOINT_GYRO_THERMAL if gyro_thermal is None else gyro_thermal
    cb = JOINT_GYRO_TEMP_BIAS if gyro_temp_bias is None else gyro_temp_bias
    return StateLayout(HAND_JOINT.blocks + (("gyro_temp_bias",) if cb else ())
                       + (("gyro_temp_scale",) if gt else ()) + ("acc_temp_bias",) + dl)


def _smoothed_temperature(temp_c: np.ndarray, rate_hz: float) -> np.ndarray:
    """The temperature channel averaged over ``THERMAL_SMOOTH_S`` (as :func:`session_temperature`), °C."""
    from scipy.ndimage import uniform_filter1d

    return uniform_filter1d(
        np.asarray(temp_c, float), size=max(1, int(round(THERMAL_SMOOTH_S * rate_hz))), mode="nearest"
    )


def _rest_temperature(temp_c: np.ndarray, rate_hz: float, a: int, b: int) -> float:
    """Mean of the smoothed temperature channel over the rest [a, b), °C."""
    return float(np.mean(_smoothed_temperature(temp_c, rate_hz)[a:b]))


def session_temperature(temp_c: np.ndarray | None, rate_hz: float) -> tuple[np.ndarray, float] | None:
    """(T − T₀ (N,), T₀) of a recording's temperature channel over the filtered span, or None when it has
    none or it moved less than ``THERMAL_MIN_SPAN_C`` (then S is a constant, as before).  T is averaged over
    ``THERMAL_SMOOTH_S`` (a thermometer's LSB and noise; the sensor's temperature moves over minutes), T₀ its
    mean (the filter's reference: keeps the regressor ω (T − T₀) centred)."""
    from scipy.ndimage import uniform_filter1d

    if temp_c is None:
        return None
    t = np.asarray(temp_c, float)
    if t.size < 2 or not np.all(np.isfinite(t)):
        return None
    ts = uniform_filter1d(t, size=max(1, int(round(THERMAL_SMOOTH_S * rate_hz))), mode="nearest")
    if float(ts.max() - ts.min()) < THERMAL_MIN_SPAN_C:
        return None
    t0 = float(ts.mean())
    return ts - t0, t0


def scale_at_temperature(P: np.ndarray, layout, t0_c: float) -> tuple[np.ndarray, np.ndarray]:
    """The temperatures T_r (3,) at which the session determined each axis's gyro scale factor best, and the
    map J (6, n) from the error state to [S(T_r), G]: with S_i(T) = S_i(T₀) + s_T,i (T − T₀) (the
    ``gyro_temp_scale`` block),

        Var S_i(T) = P_SS,ii + 2 (T − T₀) P_Ss,ii + (T − T₀)² P_ss,ii,   minimal at T_r,i = T₀ − P_Ss,ii / P_ss,ii

    — the temperature at which axis i's rotations happened, weighted by what they taught (the centre of the
    regressor ω_i (T − T₀)'s information, where S_i and s_T,i decouple).  A gyro's scale factor moves with
    temperature (the MPU-9250's datasheet: ±4 % over −40…85 °C) and a session that warms by a degree cannot
    measure that coefficient (its σ is tens of times the coefficient itself), so the calibration is valid at a
    temperature and says which: S_i is reported at T_r,i.  Without the block: (T₀ on every axis, the plain
    selection of S, G)."""
    n = P.shape[0]
    J = np.zeros((6, n))
    J[:, 3:9] = np.eye(6)
    o = layout.offset("gyro_temp_scale")
    if o < 0:
        return np.full(3, t0_c), J
    pss = np.diag(P[o:o + 3, o:o + 3])
    psS = np.diag(P[3:6, o:o + 3])
    d = -psS / np.where(pss > 0, pss, np.inf)
    J[0:3, o:o + 3] = np.diag(d)
    return t0_c + d, J


def _decoupling_temperature(P: np.ndarray, o_value: int, o_coef: int) -> np.ndarray:
    """d_i = −P_vc,ii / P_cc,ii (3,): the offset from T₀ at which the value v_i(T) = v_i(T₀) + c_i (T − T₀) has its
    smallest variance P_vv,ii + 2 (T − T₀) P_vc,ii + (T − T₀)² P_cc,ii (there v_i and c_i are uncorrelated)."""
    pcc = np.diag(P[o_coef:o_coef + 3, o_coef:o_coef + 3])
    pvc = np.diag(P[o_value:o_value + 3, o_coef:o_coef + 3])
    return -pvc / np.where(pcc > 0, pcc, np.inf)


def acc_bias_at_temperature(P: np.ndarray, layout, t0_c: float) -> tuple[np.ndarray, np.ndarray]:
    """The temperatures T_a (3,) at which the session determined each axis's accelerometer bias best, and the
    map J (3, n) from the error state to b_a(T_a): with the ``acc_temp_bias`` block,

        b_a(T) = b_a(T₀) + c_a (T − T₀),   T_a,i = T₀ − P_bc,ii / P_cc,ii

    (the accelerometer's "zero-g level change vs. temperature", a first-order coefficient in mg/°C: the
    MPU-9250's ±1.5 mg/°C, PS-MPU-9250A-01; linear between temperature points as in the acceleration channel's
    zero-bias temperature compensation of /work/shared/seeds/001 §4, the first term of the T − T_ref polynomial
    drift models of seeds/003).  As for the gyro's scale factor (:func:`scale_at_temperature`) a session
    warming by a degree measures c_a poorly but pins b_a where its attitudes were held, and says where.
    Without the block: (T₀ on every axis, the plain selection of b_a)."""
    n = P.shape[0]
    ob, oc = layout.offset("acc_bias"), layout.offset("acc_temp_bias")
    J = np.zeros((3, n))
    if ob < 0:
        return np.full(3, t0_c), J
    J[:, ob:ob + 3] = np.eye(3)
    if oc < 0:
        return np.full(3, t0_c), J
    d = _decoupling_temperature(P, ob, oc)
    J[:, oc:oc + 3] = np.diag(d)
    return t0_c + d, J


def _acc_temp_tilt_prior(p0: np.ndarray, layout, q0_nb: np.ndarray, acc_m_inv: np.ndarray, dt_rest_c: float,
                         gravity_m_s2: float) -> None:
    """The initial tilt levels the rest's accelerometer mean, whose bias is b_a + c_a (T_rest − T₀): the c_a part
    of φ₀ = [g_up×] Ĉ₀ M̂_a⁻¹ δb_a / g² (:func:`calib.session.model.initial_covariance`) with δb_a → δc_a (T_rest − T₀):
    P_φφ += A P_cc Aᵀ, P_φc = A P_cc."""
    oc = layout.offset("acc_temp_bias")
    if oc < 0 or dt_rest_c == 0.0:
        return
    c0 = q_matrix(np.asarray(q0_nb, float) / np.linalg.norm(q0_nb))
    A = skew(np.array([0.0, 0.0, gravity_m_s2])) @ c0 @ acc_m_inv
    A = A * (dt_rest_c / gravity_m_s2**2)
    pcc = p0[oc:oc + 3, oc:oc + 3]
    p0[0:3, 0:3] += A @ pcc @ A.T
    p0[0:3, oc:oc + 3] = A @ pcc
    p0[oc:oc + 3, 0:3] = (A @ pcc).T


# kf_hand_joint: the |f| = g fit's covariance × this is the accelerometer's prior (σ × 10): the fit is the
# linearisation point, the filter's vertical row the information (the same data would otherwise count twice,
# and the fit's white-residual covariance is optimistic with a hand's sway: its err/σ RMS 2–5 on the
# independent generator).  A vague prior (the consumer ±1 m/s², ±5 %) diverged on the MPU-9250 (4 of 8 seeds).
# From pass 2 the covariance is the fit's block sandwich (_gravity_fit_lever_free), which does not shrink with the
# sample rate: the white-residual one did (σ²/N), and with a shaky hand at 100 Hz that left σ of S, G 1.4–2.4×
# optimistic while the same hands at 200 Hz were honest (docs/hand.md, "Hands we did not tune for")
FIT_PRIOR_INFLATION = 100.0


def lever_regressor(w_rad_s: np.ndarray, t_s: np.ndarray, rate_hz: float) -> np.ndarray:
    """K(ω, ω̇) = [ω̇×] + [ω×]² (N, 3, 3) from a compensated rate (N, 3), both low-passed at ``CUTOFF_HZ``
    (the same band as the specific force they explain); ω̇ by central differences."""
    ws = _lowpass(w_rad_s, rate_hz)
    dw = np.gradient(ws, t_s, axis=0)
    sw = skew(ws)
    return skew(dw) + sw @ sw


def lever_jacobian(w_rad_s: np.ndarray, t_s: np.ndarray, rate_hz: float, m: np.ndarray) -> LeverJacobian:
    """How :func:`lever_regressor`'s K r moves with the gyro's errors, for the rate ``w_rad_s`` (N, 3, body)
    compensated with M = ``m`` (3, 3): ω = M⁻¹ (ω̃ − b) gives ∂ω/∂S = −M⁻¹ diag(ω), ∂ω/∂G = −M⁻¹ J_G(ω),
    ∂ω/∂b = −M⁻¹ (the first-order error model of Zhou 2020 eq. 9, as the attitude's propagation uses it); the
    regressor low-passes ω and differentiates it, and so are these sensitivities (the low-pass and the central
    difference are linear).  Returns :class:`calib.session.kernel.LeverJacobian`; the kernel forms ∂(K r̂)/∂θ for the
    current r̂ from it at each update."""
    n = w_rad_s.shape[0]
    mi = np.linalg.inv(m)
    d = np.empty((n, 3, 9))
    d[:, :, 0:3] = -mi[None, :, :] * w_rad_s[:, None, :]                         # −M⁻¹ diag(ω)
    d[:, :, 3:6] = -np.einsum("ij,njk->nik", mi, nonorthogonality_jacobians(w_rad_s))   # −M⁻¹ J_G(ω): N(G) ω = J_G(ω) G
    d[:, :, 6:9] = -mi[None]                                                      # −M⁻¹
    ld = _lowpass(d.reshape(n, 27), rate_hz).reshape(n, 3, 9)
    return LeverJacobian(_lowpass(w_rad_s, rate_hz), ld, np.gradient(ld, t_s, axis=0))


def _lowpass_design(rate_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """The tremor low-pass's Butterworth (b, a): ``ORDER`` poles at ``CUTOFF_HZ`` (capped at 0.9 of Nyquist)."""
    return sp_signal.butter(ORDER, min(CUTOFF_HZ / (rate_hz / 2), 0.9))


def _lowpass(x: np.ndarray, rate_hz: float) -> np.ndarray:
    b, a = _lowpass_design(rate_hz)
    return sp_signal.filtfilt(b, a, x, axis=0)


def _lowpass_gain2(f_hz: np.ndarray, rate_hz: float) -> np.ndarray:
    """|H(f)|² of :func:`_lowpass` (zero-phase: the Butterworth's |H_b|², squared), at any f (periodic in
    ``rate_hz``)."""
    b, a = _lowpass_design(rate_hz)
    return np.abs(sp_signal.freqz(b, a, worN=np.asarray(f_hz, float), fs=rate_hz)[1]) ** 4


def _variance_ratio(rate_hz: float) -> float:
    """ρ = Σh² of the zero-phase low-pass's impulse response: its white-noise variance ratio."""
    n = int(40 * rate_hz / CUTOFF_HZ) + 64
    imp = np.zeros(n)
    imp[n // 2] = 1.0
    return float(np.sum(_lowpass(imp, rate_hz) ** 2))


def _gm_from_residual(e: np.ndarray, dt_s: float, white_var: float,
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


def _band_shape(f_hz: np.ndarray, f1: np.ndarray, f2: np.ndarray, order: int = BAND_ORDER) -> np.ndarray:
    """|H(f)|² of the analog Butterworth band-pass f₁ … f₂ with ``order`` poles per edge (low-pass prototype
    1/(1 + Ω^{2N}), Ω = (f² − f₁f₂)/(f (f₂ − f₁)))."""
    om = (f_hz**2 - f1 * f2) / (f_hz * (f2 - f1))
    return 1.0 / (1.0 + om ** (2 * order))


def _band_from_residual(e: np.ndarray, dt_s: float, white_var: float, white_psd: float) -> dict:
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
    shp = _band_shape(fb[None, None, :], F1[..., None], F2[..., None]) * df          # (41, 41, bins)
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
    band_var = A_b * float(np.trapezoid(_band_shape(fi, f1, f2), fi))
    floor_var = A_0 / (4.0 * tau0)
    return {"floor_rms_m_s2": math.sqrt(floor_var), "floor_tau_s": tau0,
            "band_hz": (f1, f2) if A_b > 0 else None, "band_rms_m_s2": math.sqrt(band_var)}


@dataclass(frozen=True)
class BiasDrift:
    """The gyro bias's drift seen between the session's rests (:func:`bias_drift`): the random-walk
    intensity q_b (rad²/s³ per axis; √q_b in rad/s/√s is IEEE 952's rate random walk K), the statistic
    X = Σ|Δb̄|²/(s_i² + s_j²) with its degrees of freedom and the threshold it had to pass, and the rest
    means (rad/s, body) at their mid times (s)."""

    q_rad2_s3: float
    chi2: float
    dof: int
    threshold: float
    rest_bias_rad_s: tuple[tuple[float, float, float], ...]
    rest_mid_s: tuple[float, ...]

    @property
    def rrw_rad_s_sqrt_s(self) -> float:
        return math.sqrt(self.q_rad2_s3)

    def to_dict(self) -> dict:
        return {"rate_random_walk_rad_s_sqrt_s": self.rrw_rad_s_sqrt_s, "q_rad2_s3": self.q_rad2_s3,
                "chi2": self.chi2, "dof": self.dof, "threshold_95": self.threshold,
                "rest_bias_rad_s": [list(b) for b in self.rest_bias_rad_s], "rest_mid_s": list(self.rest_mid_s)}


def bias_drift(gyro_rad_s: np.ndarray, t_s: np.ndarray, rests: tuple[tuple[int, int], ...],
               arw_rad_s_sqrt_hz: float, min_rest_s: float = 2.0) -> BiasDrift:
    """The gyro bias's random-walk intensity q_b from the recording's own rests (never from a sensor model).

    At a rest the gyro reads its bias (plus white noise): the mean b̄_i over rest i (length L_i) has
    white-noise variance s_i² = N_g²/L_i per axis.  For a bias that is a random walk ḃ = w,
    E[w²] = q_b, the mean over a window of length L differs from the walk's value at the window's
    edge by a variance q_b L/3 (∫₀ᴸ (s/L)² ds · q_b), so consecutive rests separated by a gap g_ij
    give  E|b̄_j − b̄_i|² = 3 [q_b (g_ij + (L_i + L_j)/3) + s_i² + s_j²]  (three axes).  The
    method-of-moments estimate over the k consecutive pairs:

        q̂_b = Σ (|Δb̄|² − 3(s_i² + s_j²)) / (3 Σ (g_ij + (L_i + L_j)/3)),

    applied only when X = Σ |Δb̄|² / (s_i² + s_j²) exceeds χ²(3k)'s 95 % quantile (no drift is
    modelled that the rests' white noise explains), else 0.  A deterministic drift (a warm-up ramp,
    the bias's g-sensitivity after a change of attitude) enters as its end-to-end change: the random
    walk fitted to it predicts a variance ∝ τ over a sub-interval τ where the ramp gives ∝ τ², so the
    model is conservative inside the session.  Sources: the random walk's structure function
    (IEEE Std 952-1997 Annex C, rate random walk: σ²(τ) = K²τ/3 for the Allan variance, the same
    window-mean argument); Brown & Hwang, *Introduction to Random Signals and Applied Kalman
    Filtering*, 4th ed., §2.10 (Wiener process), §9 (a gyro bias as a random-walk state).
    """
    from scipy import stats

    means, mids, lengths, s2 = [], [], [], []
    for a, b in rests:
        if b - a < 2 or t_s[b - 1] - t_s[a] < min_rest_s:
            continue
        L = float(t_s[b - 1] - t_s[a])
        means.append(np.mean(gyro_rad_s[a:b], axis=0))
        mids.append(0.5 * float(t_s[a] + t_s[b - 1]))
        lengths.append(L)
        s2.append(arw_rad_s_sqrt_hz**2 / L)
    k = len(means) - 1
    if k < 1:
        return BiasDrift(0.0, 0.0, 0, float("inf"), tuple(tuple(m) for m in means), tuple(mids))
    num, den, x = 0.0, 0.0, 0.0
    for i in range(k):
        d2 = float(np.sum((means[i + 1] - means[i]) ** 2))
        gap = (mids[i + 1] - lengths[i + 1] / 2) - (mids[i] + lengths[i] / 2)
        num += d2 - 3.0 * (s2[i] + s2[i + 1])
        den += 3.0 * (max(gap, 0.0) + (lengths[i] + lengths[i + 1]) / 3.0)
        x += d2 / (s2[i] + s2[i + 1])
    thr = float(stats.chi2.ppf(DRIFT_QUANTILE, 3 * k))
    q = max(num, 0.0) / den if x > thr else 0.0
    return BiasDrift(q, x, 3 * k, thr, tuple(tuple(float(v) for v in m) for m in means), tuple(mids))


def _acc_theta(theta: np.ndarray) -> np.ndarray:
    """θ_a = [b_a, S_a, G_a] (9,) of an 18-vector θ (``THETA`` order)."""
    return np.concatenate([theta[theta_slice("acc_bias")], theta[theta_slice("acc_scale")],
                           theta[theta_slice("acc_nonorth")]])


def kf_hand(rec: Recording, accelerometer: str = "calibrated", gravity_m_s2: float | None = None,
            g_sensitivity: bool = False, sway: str = "gauss_markov", keep_history: bool = False,
            delay: bool = True) -> Calibration:
    """The hand-aware gyro calibration (module docstring).  ``accelerometer``: "calibrated" (Zhou §3.3.2,
    the registered ``kf_hand``: 27 states, 33 when the recording's temperature moved (c_b, s_T), 36 with the opt-in
    ``g_sensitivity`` too — :func:`hand_layout`) or "estimate" (the registered ``kf_hand_joint``: + the
    accelerometer's bias, scale factor and non-orthogonality, 36 states, 42 when the recording's temperature moved
    (s_T and the accelerometer bias's c_a — :func:`joint_layout`) — what ``calib run`` estimates by
    default).  ``delay``: the accelerometer's delay behind the gyro is a state (default; three fewer states without
    it).  With the accelerometer estimated, every pass applies its error model at the current
    estimate, f̂ = M̂_a⁻¹(f̃ − b̂_a), *before* the nav-frame tremor low-pass (the low-pass of a rotated
    body-frame bias is not the bias), and hands the kernel the low-passed f̂ mapped back through
    f̃_lp = M̂_a f̂_lp + b̂_a, so the kernel's own compensation at the nominal gives f̂_lp again; the prior of
    the accelerometer states is the |f| = g fit's (mean and covariance, as ``kf_session``), the initial
    tilt's dependence on them in P₀ (:func:`calib.session.model.initial_covariance`), re-linearised each pass
    as ``iterated_session`` does.  ``sway``: the a_e family fitted from pass 2 on — "gauss_markov" (the
    high-passed Gauss–Markov, :func:`_gm_from_residual`) or "band" (opt-in, calibrated accelerometer only: a
    Gauss–Markov floor + a Butterworth band-pass fitted to band powers, :func:`_band_from_residual`, filtered
    through the general shaping-filter states of :meth:`calib.session.model.FilterConfig.ext_acc_model`)."""
    if sway not in SWAY_MODELS:
        raise ValueError(f"sway must be one of {SWAY_MODELS}, got {sway!r}")
    estimate = accelerometer == "estimate"
    if estimate and sway != "gauss_markov":
        raise ValueError("the band-limited sway model is implemented for kf_hand (accelerometer calibrated) only")
    layout = HAND_JOINT if estimate else HAND_BIAS
    # the levelling rows; with the accelerometer estimated also the vertical one, which carries the |f| = g
    # information with the hand in the model (a_e's vertical component, the lever arm) — kf_session leaves it
    # to its |f| = g fit, whose white-residual covariance is optimistic with a hand (below)
    rows = 3 if estimate else 2
    prep = prepare(rec, accelerometer=accelerometer, gravity_m_s2=gravity_m_s2)
    ra, rb = prep.rest_range
    nz = prep.noise
    # the densities from the rest's spectrum above the tremor, or at 2–6 Hz when an output low-pass rolls it off
    # (prepare's, on the same rest: calib.session.noiselevels.estimate_noise)
    wd_g, wd_a = nz.gyro_white, nz.acc_white
    arw, vrw = nz.gyro_density_rad_s_sqrt_hz, nz.acc_density_m_s2_sqrt_hz
    rolloff_notes = [n for n in (wd_g.note("gyro", "rad/s") if wd_g else None,
                                 wd_a.note("accelerometer", "m/s²") if wd_a else None) if n]
    # the bias state's prior: the batch means' σ, as before calib.session.rest_bias (Prepared.bias_batch_std_rad_s)
    cfg0 = replace(prep.config, prior_gyro_bias_rad_s=tuple(prep.bias_batch_std_rad_s))
    if arw is not None and vrw is not None:   # never below the quantisation / discretisation floors
        cfg0 = type(cfg0)(**{**cfg0.__dict__,
                             "arw_rad_s_sqrt_hz": max(arw, nz.gyro_floor_rad_s / math.sqrt(rec.rate_hz)),
                             "vrw_m_s2_sqrt_hz": max(vrw, nz.acc_floor_m_s2 / math.sqrt(rec.rate_hz))})
    fs = rec.rate_hz
    # the gyro bias is a state (a random walk, q_b from the rests: bias_drift): the filter starts after
    # the rest that gave the bias's prior, whose gyro samples would otherwise inform the bias twice
    drift = bias_drift(rec.gyro_rad_s, rec.t_s, prep.rest.index_ranges, cfg0.arw_rad_s_sqrt_hz)
    cfg0 = replace(cfg0, gyro_bias_rw_rad_s_sqrt_s=drift.rrw_rad_s_sqrt_s)
    tilt = _tilt_sigma(rec, ra, rb, cfg0.gravity_m_s2)
    prep = replace(prep, start=max(rb - 1, prep.start))
    a = prep.start
    refuse_if_nothing_observed(rec, prep.bias.value_rad_s, ra, rb, a)
    t = rec.t_s[a:]
    n = t.size
    sigma_f2 = cfg0.vrw_m_s2_sqrt_hz**2 * fs
    rho = _variance_ratio(fs)
    dec = max(1, int(math.floor(1.0 / rho)))
    upd = np.zeros(n, bool)
    upd[::dec] = True
    if prep.saturated is not None:
        upd &= ~prep.saturated[a:]
    r_var = sigma_f2 / dec
    theta = prep.theta0.copy()
    hand0 = np.zeros(6)
    # extra blocks' nominals: c_b, s_T, k, c_a (calib.session.model.SENSOR_EXTRA_BLOCKS)
    sens0 = np.zeros(3 * len(SENSOR_EXTRA_BLOCKS))
    f_rest = np.mean(rec.acc_m_s2[ra:rb], axis=0)    # the specific force during the rest that gave the bias's prior
    # pass 1's external acceleration: the session's (|f_lp| − g)² (kf_session_r's allowance, low-passed),
    # with the accelerometer compensated by the |f| = g fit when it is estimated
    acc0 = compensate_acc(rec.acc_m_s2[a:], _acc_theta(theta)) if estimate else rec.acc_m_s2[a:]
    f_lp0 = _lowpass(acc0, fs)
    along = float(np.mean((np.linalg.norm(f_lp0, axis=1) - cfg0.gravity_m_s2) ** 2)) - sigma_f2 * rho
    sigma_s, tau, tau_hp, hp_order = math.sqrt(max(3.0 * along, r_var)), 1.0, math.inf, 1
    tremor_rms = math.sqrt(max(float(np.mean(np.sum((acc0 - f_lp0) ** 2, axis=1))) - 3 * sigma_f2 * (1 - rho), 0.0))
    # what that subtraction resolves: 2σ of the white-noise variance removed (its N² measured on the first rest), as an
    # RMS — on a noisy sensor the "tremor" is the noise estimate's error (the paper's preset, VRW 15 mg/√Hz: 0.67 m/s²
    # reported, the hand's 0.09)
    rel_n2 = (
        white_variance_relative_sd(rec.acc_m_s2[ra:rb], fs)
        if vrw is not None and cfg0.vrw_m_s2_sqrt_hz == vrw
        else None
    )
    tremor_resolution = math.sqrt(2.0 * 3 * sigma_f2 * (1 - rho) * rel_n2) if rel_n2 is not None else 0.0
    tremor_resolved = tremor_rms > tremor_resolution
    still = rest_mask(prep, n)
    # the gyro's g-sensitivity and (a warming sensor) the scale's temperature coefficient: kf_hand (calibrated
    # accelerometer); kf_hand_joint on a warming sensor: + the accelerometer bias's temperature coefficient c_a
    # (and the gyro scale's s_T, JOINT_GYRO_THERMAL)
    thermal = session_temperature(None if rec.temp_c is None else rec.temp_c[a:], fs)
    layout = (joint_layout(thermal is not None, delay=delay) if estimate
              else hand_layout(thermal is not None, g_sensitivity, band=sway == "band", delay=delay))
    band = None
    # the rest's mean temperature − T₀: its accelerometer mean levels the initial attitude (c_a) and its gyro mean is
    # the bias's prior (c_b)
    dt_rest = _rest_temperature(rec.temp_c, fs, ra, rb) - thermal[1] if thermal is not None else 0.0
    q0 = prep.quat0_nb
    obs_notes: list[str] = []
    # the last pass with a constant gyro bias, when the rests saw a drift the temperature does not explain
    out_const = None
    # a recorded temperature that stayed flat: the drift is not a warm-up (_drift_ambiguity); without a channel it may
    # be
    flat_temperature = thermal is None and rec.temp_c is not None and bool(np.all(np.isfinite(rec.temp_c[a:])))
    for p in range(PASSES):
        theta[theta_slice("gyro_bias")] = prep.theta0[theta_slice("gyro_bias")]   # each pass starts at the rest's bias
        m = m_matrix(theta[theta_slice("gyro_scale")], theta[theta_slice("gyro_nonorth")])
        w = (rec.gyro_rad_s[a:] - theta[theta_slice("gyro_bias")]) @ np.linalg.inv(m).T
        # the accelerometer bias's temperature part at its nominal, c_a (T − T₀) (N, 3); zero without the block
        acc_temp = (np.outer(thermal[0], sens0[9:12]) if layout.has("acc_temp_bias") else np.zeros((n, 3)))
        if estimate:   # the rest attitude and P₀'s tilt–accelerometer terms at this pass's θ̂_a (pass 1: prepare's)
            th_rest = theta.copy()
            th_rest[theta_slice("acc_bias")] += sens0[9:12] * dt_rest     # b_a at the rest's temperature
            q0, f0, mi_a = _initial_attitude(rec, th_rest, ra, rb)
        th_a = _acc_theta(theta)
        acc = compensate_acc(rec.acc_m_s2[a:] - acc_temp, th_a) if estimate else rec.acc_m_s2[a:]
        q = integrate_gyro(t, w, q0)
        f_nav = quat_rotate(q, acc)
        f_lp = quat_rotate(quat_conjugate(q), _lowpass(f_nav, fs))       # whitening pre-filter (nav low-pass)
        kreg = lever_regressor(w, t, fs)
        ljac = lever_jacobian(w, t, fs, m)
        if p > 0:   # Gauss–Markov σ_s, τ from the previous pass's lever arm (module docstring, step 2)
            e = np.linalg.norm(f_lp - np.einsum("nij,j->ni", kreg, hand0[:3]), axis=1) - cfg0.gravity_m_s2
            if layout.has(EXT_ACC_EXTRA_BLOCKS[0]):   # the band-limited sway (_band_from_residual)
                band = _band_from_residual(e, 1.0 / fs, sigma_f2 * rho, 2.0 * cfg0.vrw_m_s2_sqrt_hz**2)
                sigma_s, tau, tau_hp, hp_order = band["floor_rms_m_s2"], band["floor_tau_s"], math.inf, 1
            else:
                sigma_s, tau, tau_hp, hp_order = _gm_from_residual(
                    e, 1.0 / fs, sigma_f2 * rho, 2.0 * cfg0.vrw_m_s2_sqrt_hz**2
                )
            sigma_s = max(sigma_s, 1e-3 * math.sqrt(r_var))
        cfg = type(cfg0)(**{**cfg0.__dict__, "external_acc_allowance_m_s2": 0.0, "ext_acc_rms_m_s2": sigma_s,
                            "ext_acc_tau_s": tau, "ext_acc_highpass_tau_s": tau_hp, "ext_acc_highpass_order": hp_order,
                            **(_band_config(band) if band is not None else {})})
        x0 = np.zeros(layout.n)
        x0[3:9] = -theta[0:6]                                     # prior S = G = 0 seen from the linearisation point
        x0[layout.offset("lever_arm"):layout.offset("lever_arm") + 3] = -hand0[:3]   # prior r = 0
        if estimate:   # the accelerometer's weak prior: the |f| = g fit (kf_session's) without the lever arm's K r̂,
            gfit = prep.gravity_fit if p == 0 else _gravity_fit_lever_free(rec, prep, a, kreg, hand0[:3], th_a)
            oa = layout.offset("acc_bias")
            x0[oa:oa + 9] = gfit.theta - th_a
            p0 = initial_covariance(layout, cfg, q0, f0, mi_a, gfit.covariance * FIT_PRIOR_INFLATION, tilt)
            _acc_temp_tilt_prior(p0, layout, q0, mi_a, dt_rest, cfg.gravity_m_s2)
        else:
            p0 = initial_covariance(layout, cfg, tilt_sigma_rad=tilt)
        _g_sensitivity_prior(p0, layout, f_rest)                # no-ops without those blocks
        _temp_bias_prior(p0, layout, dt_rest)
        _common_delay_prior(p0, layout)
        _sensor_extra_prior(x0, layout, sens0)
        # the kernel compensates at θ̂_a again
        f_kernel = f_lp @ m_matrix(th_a[3:6], th_a[6:9]).T + th_a[0:3] + acc_temp if estimate else f_lp
        h0 = np.concatenate([hand0[:3], np.zeros(9)])

        def _run(cfg_, keep: bool, record: bool = False):
            return run_filter(rec.gyro_rad_s[None, a:], f_kernel[None], t, q0[None], theta[None], p0,
                              layout, cfg_, fs, r_var_per_sample=np.full(n, r_var), update_mask=upd, rest_mask=still,
                              x0=x0[None], lever_regressor=kreg, lever_jacobian=ljac, hand0=h0, rows=rows,
                              temperature_rel_c=None if not layout.models_temperature else thermal[0],
                              specific_force_m_s2=f_lp if layout.models_g_sensitivity else None, sensor0=sens0,
                              acc_rate_m_s3=np.gradient(f_lp, t, axis=0) if layout.models_acc_delay else None,
                              keep_history=keep, record=record)
        if p == PASSES - 1 and drift.q_rad2_s3 > 0 and flat_temperature:
            # the bias-drift ambiguity (_drift_ambiguity): the last pass once more with a constant bias
            out_const = _run(replace(cfg, gyro_bias_rw_rad_s_sqrt_s=0.0), False)
        # with c_b a state the random walk keeps only what c_b does not explain (QB_LADDER); passes 1–2 at q̂_b
        ladder = QB_LADDER if p == PASSES - 1 and layout.has("gyro_temp_bias") and drift.q_rad2_s3 > 0 else (1.0,)
        for qb_factor in ladder:
            out = _run(replace(cfg, gyro_bias_rw_rad_s_sqrt_s=cfg.gyro_bias_rw_rad_s_sqrt_s * math.sqrt(qb_factor)),
                       keep_history and p == PASSES - 1,
                       record=SPECTRAL_SIGMA and p == PASSES - 1 and sway != "band" and not prep.noise.noise_free
                       and cfg.ext_acc_rms_m_s2**2 > r_var)
            if qb_factor == ladder[-1] or innovation_inflation(out.whitened[0], t[1:]).factor == 1.0:
                break
        theta = out.theta[0].copy()
        hand0 = out.hand[0].copy()
        if out.sensor_extra is not None:
            sens0 = out.sensor_extra[0].copy()
        if p == 0:   # calib run's observability check: gyro warnings, an undetermined accelerometer refused
            _apply_observability(prep, _observability(replace(prep, layout=layout), out, p0), obs_notes)
    P = p_model = out.p[0]
    spectral = None
    # P under the slow residual's own spectrum, not the fitted model's (calib.session.spectral), when the fitted a_e
    # carries more than the white noise per update (a hand seen; without one the model is R alone, whose σ the
    # ideal-hand cells validate, and what the residual shows beyond it is the filter's own estimation error: on the
    # independent generator without a hand it moved σ of G by up to ×1.2 at random); not for the band model's general
    # shaping filter (the adjoint follows the Gauss–Markov states), nor for a noise-free sensor (its S, G errors come
    # from the filter's linearisation, not from a_e: measured 7e-5 against the linear prediction's 1e-5) (the gate is
    # the last pass's record= above: the record exists exactly when it applies) the slow residual, f_lp − K r̂ (N, 3,
    # body) and e = |f_lp − K r̂| − g (attitude-free): the spectral σ's data and the hand-assumption check's
    # displacement data
    slow_f = f_lp - np.einsum("nij,j->ni", kreg, hand0[:3])
    slow_resid = np.linalg.norm(slow_f, axis=1) - cfg0.gravity_m_s2
    if out.record is not None:
        P, spectral = _spectral_sigma(P, out, layout, cfg, f_lp, slow_f, slow_resid, kreg, fs, dec, r_var, estimate)
    global _LAST
    _LAST = (out, t, upd)
    ol = layout.offset("lever_arm")
    _confounding(P, ol, layout)
    infl_test = innovation_inflation(out.whitened[0], t[1:])
    # one-sided (κ̂ applied only above its χ² 95 % quantile), as for every method: the two-sided factor
    # (_sandwich_factor) brought gyrosim's hand cells into their NEES band but, on the measured x-IMU3 hand-held
    # session, κ̂ = 0.027 shrank σ ×0.16 and left an "ok" G_y 19 σ from the factory calibration (3.2 σ one-sided)
    infl = infl_test
    blocks = ["gyro_scale", "gyro_nonorth"] + (["acc_bias", "acc_scale", "acc_nonorth"] if estimate else [])
    idx = np.concatenate([np.arange(layout.offset(b), layout.offset(b) + 3) for b in blocks])
    cov = np.zeros((3 + idx.size, 3 + idx.size))
    # the first rest's mean at its stated reference (time, temperature, specific force), σ without the hand's
    # rotation that cancels in the mean (calib.session.rest_bias); uncorrelated with the filter's states
    # N for the rest mean's σ: the 2–6 Hz density when that band is higher, roll-off found or not (cautious)
    n_rest = max(cfg0.arw_rad_s_sqrt_hz, wd_g.rest_mean_density if wd_g is not None else 0.0)
    rbias = rest_bias(rec.gyro_rad_s, rec.t_s, (ra, rb), n_rest,
                      compensate_acc(rec.acc_m_s2, _acc_theta(theta)) if estimate else rec.acc_m_s2, rec.temp_c)
    cov[:3, :3] = np.diag(rbias.std_rad_s**2)
    # the temperature block (thermal is not None): S is reported at the temperature the session pinned it best
    # (the temperatures where S and b_a decouple from their coefficients come from the filter's own P: the spectral
    # correction scales variances, not where the information lies — scaling S but not s_T moved T_r towards T₀ and
    # took S_z's RMS error on the MPU-9250's shaky hand from 9.6e-5 to 1.2e-4)
    t_ref, jt = scale_at_temperature(p_model, layout, thermal[1] if thermal is not None else float("nan"))
    jsel = np.zeros((idx.size, P.shape[0]))
    jsel[np.arange(idx.size), idx] = 1.0
    jsel[:6] = jt                                      # S (at T_r), G
    # the accelerometer's bias likewise at the temperatures T_a,i where b_a and c_a decouple (acc_temp_bias)
    t_ref_a, ja = acc_bias_at_temperature(p_model, layout, thermal[1] if thermal is not None else float("nan"))
    if layout.has("acc_temp_bias"):
        jsel[6:9] = ja
    cov[3:, 3:] = (jsel @ P @ jsel.T) * infl.factor
    ambiguity = None
    if out_const is not None:
        cov[3:, 3:], ambiguity = _drift_ambiguity(cov[3:, 3:], jsel @ out_const.p[0] @ jsel.T,
                                                  innovation_inflation(out_const.whitened[0], t[1:]))
    temperature = _temperature_report(thermal, t_ref, sens0, P, layout, infl.factor, t_ref_a)
    m_final = m_matrix(theta[theta_slice("gyro_scale")], theta[theta_slice("gyro_nonorth")])
    rate_ref = scale_reference_rate((rec.gyro_rad_s[a:] - theta[theta_slice("gyro_bias")]) @ np.linalg.inv(m_final).T)
    # the accelerometer's S likewise at the specific force its updates saw (the compensated, low-passed f̂ there)
    force_ref = acc_scale_reference_force(f_lp[upd]) if estimate else None
    if layout.has("gyro_temp_scale"):
        # S_i(T_r,i) = S_i(T₀) + s_T,i (T_r,i − T₀)
        theta[theta_slice("gyro_scale")] += sens0[3:6] * (t_ref - thermal[1])
    if layout.has("acc_temp_bias"):
        # b_a,i(T_a,i) = b_a,i(T₀) + c_a,i (T_a,i − T₀)
        theta[theta_slice("acc_bias")] += sens0[9:12] * (t_ref_a - thermal[1])
    values = {BLOCK_LABELS[b]: theta[theta_slice(b)] for b in blocks}
    checks = [check_innovations(out.nis[0][upd[1:]], rows, fs / dec), check_estimate(values, cov, cfg0.gravity_m_s2)]
    if estimate:   # |f̂| = g at the rests, as calib run's joint filter checks its accelerometer
        acc_all = rec.acc_m_s2
        if layout.has("acc_temp_bias"):   # b_a(T(t)) = b_a(T_a) + c_a (T(t) − T_a): the rests sit at other temperatures
            acc_all = acc_all - (_smoothed_temperature(rec.temp_c, fs)[:, None] - t_ref_a[None, :]) * sens0[9:12]
        f_hat = compensate_acc(acc_all, _acc_theta(theta))
        checks.append(rest_gravity(f_hat, rec.t_s, prep.rest.index_ranges, cfg0.gravity_m_s2,
                                   math.sqrt(prep.config.r_var(fs))))
    status, notes = verdict(checks[0], checks[1], checks[2] if estimate else None, accelerometer, hand_aware=True,
                            noise_free=prep.noise.noise_free)
    if thermal is not None:
        notes = notes + [temperature["note"]]
    status = apply_inflation(status, notes, infl_test, can_fail=not prep.noise.noise_free, hand_aware=True)
    if prep.noise.noise_free and status != "ok":
        # noise-free input: the innovations are the gyro integration's deterministic error, which the
        # floor-level noise cannot cover (measured on the independent generator at 100 Hz: error 2.4e-6,
        # 5.8 σ) — refused, but the advice about a hand's acceleration would mislead, so say what it is
        notes.append("noise-free input: the sensor noise at rest sits at its numerical floor, so σ comes from that "
                     "floor "
                     "and does not cover the estimate's discretisation error (the rate integration of the motion, "
                     "typically ~1e-6 in S, G at 100 Hz): the estimate is close but its σ is not honest, hence "
                     f"'{status}'. Real data has noise; for a simulated check compare against the truth directly")
    if drift.q_rad2_s3 > 0:
        modelled = (
            f"modelled as the bias's temperature coefficient c_b (diagnostics.temperature) and a random walk of "
            f"{math.sqrt(qb_factor) * drift.rrw_rad_s_sqrt_s:.2e} rad/s/√s ({qb_factor:g} × the rests' q_b for what "
            "c_b leaves: ½ unless the innovations reject it, QB_LADDER)"
            if layout.has("gyro_temp_bias")
            else f"modelled as a random walk of {drift.rrw_rad_s_sqrt_s:.2e} rad/s/√s (from the rests, bias_drift)"
        )
        notes.append(f"gyro bias drift: the rests' bias moved beyond their noise (χ² {drift.chi2:.0f} on {drift.dof}, "
                     f"95 % bound {drift.threshold:.1f}); {modelled}; a longer warm-up before the session or a "
                     "temperature-stable sensor gives a smaller σ")
        if ambiguity is not None:
            notes.append("gyro bias drift without a temperature change: the two rests cannot tell a random walk from "
                         "a bias-instability (flicker) floor, which moves the bias more inside the session; σ of the "
                         "reported parameters is the two models' mixture (× up to "
                         f"{max(ambiguity['sigma_factor']):.2f} on the random walk's alone, _drift_ambiguity)")
        elif thermal is None:
            notes.append("gyro bias drift and no temperature channel: a warm-up (a ramp, which the random walk covers) "
                         "cannot be told from a warmed-up gyro's bias-instability floor, under which σ of S, G is "
                         "~15 % small (measured on a warmed-up MPU-9250); record the temperature — a flat one lets the "
                         "filter model the floor (_drift_ambiguity)")
        if estimate and thermal is None:
            # the drift is most often a warming board, whose accelerometer bias drifts too, and without a
            # temperature channel no state models that (measured on the MPU-9250 preset with its channel removed:
            # σ of S, G ~1.2× small, NEES(6) 8.3 ideal hand; docs/hand.md)
            notes.append("accelerometer bias drift not modelled: the gyro bias drifted (a warming sensor?) and the "
                         "recording has no temperature channel (or it moved < "
                         f"{THERMAL_MIN_SPAN_C} °C), so the accelerometer bias is taken as constant; if the board was "
                         "warming, σ of S, G may be ~20 % small — record the temperature (kf_hand_joint then models "
                         "b_a(T)) or warm the sensor up first")
    dly = _delay_report(sens0, P, layout, infl.factor) if layout.models_acc_delay else None
    if dly is not None:
        notes.append(
            f"timing: the accelerometer samples {dly['delay_s'] * 1e3:+.2f} ± {dly['std_s'] * 1e3:.2f} ms after the "
            "gyro "
            "(estimated; negative: before) — a skew between the triads or their low-pass filters' different delays, "
            "modelled so that it does not enter S and G"
        )
    r_hat = hand0[:3]
    # the lever arm's σ: its information sits at the turns' ω̇ and ω² (0.1–1 Hz, inside the sway band, where the
    # fitted model understates the power), above the < 0.125 Hz that κ̂'s 4-s blocks measure; the same one-sided
    # test on LEVER_INFLATION_BLOCK_S blocks (< 0.5 Hz) measures the innovations' excess there, and σ_r takes the
    # larger factor (independent generator, 20 sessions: err/σ RMS per axis 1.29, 1.31, 1.06 → 1.13, 1.20, 0.91,
    # pooled 1.23 → 1.09 against the 95 % band [0.82, 1.18]; 2-s blocks 1.28, 1.29, 0.99). Deflating by κ̂ < 1
    # made it more optimistic (10 sessions: err/σ RMS 1.4–1.7 per axis against 1.3–1.5 one-sided)
    infl_r = innovation_inflation(out.whitened[0], t[1:], block_s=LEVER_INFLATION_BLOCK_S)
    r_sd = np.sqrt(np.diag(P[ol:ol + 3, ol:ol + 3]) * max(infl_test.factor, infl_r.factor))
    # kf_hand's own assumptions on this recording (calibrated accelerometer, a hand's tremor and lever arm)
    assumptions = check_hand_assumptions(rec.acc_m_s2, rec.t_s, prep.rest.index_ranges, np.sqrt(np.diag(cov[3:9, 3:9])),
                                         tremor_rms, r_hat, r_sd, check_accelerometer=not estimate,
                                         slow_residual_m_s2=slow_resid, slow_residual_t_s=t, rate_hz=fs)
    notes.extend(assumptions.warnings)
    notes.extend(rolloff_notes)
    if not assumptions.trustworthy and status == "ok":
        status = "inconsistent"
    if sway == "band" and status == "ok":
        # the band-limited sway model is a research variant: on the independent generator's noise-free sensor
        # (tests/session/test_hand_sway_model.py, slow) its σ was 3–5× small with every seed passing its checks
        # (ΣNEES 379 over 10 seeds, χ²₆₀ 99.9 % bound 102.7) — a wrong answer must not exit 0, so it never says ok
        status = "inconsistent"
        notes.append("experimental sway model (sway='band', kf_hand_band): its σ failed the independent generator's "
                     "consistency test (3–5× small on a noise-free sensor with a line-spectrum sway; docs/hand.md, "
                     "'A band-limited sway model'), so its result is never 'ok'. Use kf_hand (calib run --method hand "
                     "--accelerometer calibrated) for an answer whose σ has been validated")
    hand = {
        "lever_arm_m": r_hat.tolist(),
        "lever_arm_std_m": r_sd.tolist(),
        "lever_arm_sigma_inflation": {
            **infl_r.to_dict(),
            "block_s": LEVER_INFLATION_BLOCK_S,
            "covariance_factor": max(infl_test.factor, infl_r.factor),
        },
        "external_acc_psd": {
            "model": "a_e = a first-order Gauss–Markov x (rms_m_s2, tau_s) per nav axis after the tremor "
            "low-pass, high-passed (highpass_tau_s, highpass_order m; null: none): "
            "one-sided PSD 4σ²τ/(1 + (2πfτ)²)·[(2πfτ_h)²/(1 + (2πfτ_h)²)]^m",
            "rms_m_s2": sigma_s,
            "tau_s": tau,
            "highpass_tau_s": tau_hp if math.isfinite(tau_hp) else None,
            "highpass_order": hp_order,
            "acc_rms_m_s2": cfg.ext_acc_rms_a_m_s2,
            "psd_one_sided_0hz_m2_s4_per_hz": 4 * sigma_s**2 * tau if not math.isfinite(tau_hp) else 0.0,
            "tremor_band_rms_m_s2": tremor_rms,
            "tremor_band_resolution_m_s2": tremor_resolution,
            "tremor_band_resolved": tremor_resolved,
            "lowpass_hz": CUTOFF_HZ,
            "update_every_samples": dec,
            **_band_report(band),
        },
    }
    if spectral is not None:
        fsg = [v for k, v in spectral["sigma_factor"].items() if k.startswith(("gyro_scale", "gyro_nonorth"))]
        notes.append(f"σ of S, G follows the slow residual's own spectrum, not the fitted a_e model's: ×{min(fsg):.2f}–"
                     f"{max(fsg):.2f} (the model's shape and its aliasing at the updates; calib.session.spectral, "
                     "diagnostics.consistency.spectral_covariance)")
    notes.append(f"hand: lever arm r̂ = {np.array2string(r_hat * 100, precision=1)} ± "
                 f"{np.array2string(r_sd * 100, precision=1)} cm (body); slow external acceleration "
                 f"{cfg.ext_acc_rms_a_m_s2:.3f} m/s² RMS (τ {tau:.2f} s, high-pass "
                 f"{'none' if not math.isfinite(tau_hp) else f'order {hp_order}, {tau_hp:.1f} s'}); "
                 + (f"tremor-band acceleration {tremor_rms:.3f} m/s² RMS removed" if tremor_resolved else
                    f"tremor-band acceleration not resolved: {tremor_rms:.3f} m/s² RMS is within what the sensor's "
                    f"noise, measured on the first rest, leaves uncertain ({tremor_resolution:.3f} m/s²)"))
    gyro = {"bias": rbias.value_rad_s, "scale_factor": theta[theta_slice("gyro_scale")],
            "nonorthogonality": np.clip(np.nan_to_num(theta[theta_slice("gyro_nonorth")]), -0.45, 0.45)}
    acc_params = None
    extra: dict = {}
    if estimate:   # the accelerometer's parameters as calib run's joint filter reports them
        acc_params = {"bias": theta[theta_slice("acc_bias")], "scale_factor": theta[theta_slice("acc_scale")],
                      "nonorthogonality": np.clip(np.nan_to_num(theta[theta_slice("acc_nonorth")]), -0.45, 0.45)}
        gf = gfit   # the last pass's prior (lever-arm-free from pass 2 on)
        extra = {"accelerometer_mode": "estimate", "rest_gravity": checks[2].to_dict(),
                 "gravity_fit": {"bias_m_s2": gf.bias_m_s2, "scale_factor": gf.scale_factor,
                                 "nonorthogonality": gf.nonorthogonality, "std": np.sqrt(np.diag(gf.covariance)),
                                 "residual_rms_m_s2": gf.residual_rms_m_s2, "samples": gf.samples}}
    cal = Calibration.from_linear(
        gyro=gyro,
        accelerometer=acc_params,
        covariance=cov,
        status=status,
        warnings=prep.warnings + tuple(obs_notes + notes),
        method=REGISTERED_NAME[accelerometer],
        diagnostics={
            "hand": hand,
            "consistency": {
                **checks[0].to_dict(),
                "sigma_inflation": {
                    **infl_test.to_dict(),
                    "covariance_factor": infl.factor,
                    "sigma_factor": infl.sigma_factor,
                    "applied": "one-sided",
                },
                "spectral_covariance": spectral,
            },
            "noise": {
                "arw_rad_s_sqrt_hz": cfg0.arw_rad_s_sqrt_hz,
                "vrw_m_s2_sqrt_hz": cfg0.vrw_m_s2_sqrt_hz,
                # the hand-blind filters' R allowance (calib run's JSON key):
                # none here, a_e is modelled (diagnostics.hand)
                "external_acc_allowance_m_s2": 0.0,
                "gravity_m_s2": cfg0.gravity_m_s2,
                # the rest's spectrum: the density above the tremor and at
                # 2–6 Hz, and whether an output low-pass rolled it off
                "gyro_white_density_check": wd_g.to_dict() if wd_g else None,
                "acc_white_density_check": wd_a.to_dict() if wd_a else None,
            },
            "rest_segments": prep.rest.to_list(),
            "gyro_bias_drift": {
                **drift.to_dict(),
                # the random walk the last pass used: q_b × this
                "random_walk_factor_used": qb_factor,
                **({"constant_bias_check": ambiguity} if ambiguity is not None else {}),
            },
            "gyro_bias": rbias.to_dict(),
            "temperature": {k: v for k, v in temperature.items() if k != "note"},
            "scale_reference_rate": rate_ref,
            **({"acc_scale_reference_force": force_ref} if force_ref is not None else {}),
            **(
                {"gyro_g_sensitivity": _g_sensitivity_report(sens0, P, layout, infl.factor)}
                if layout.models_g_sensitivity
                else {}
            ),
            **({"acc_delay": dly} if dly is not None else {}),
            "assumptions": assumptions.to_dict(),
            **extra,
            "filter": {
                "states": list(layout.names),
                "passes": PASSES,
                "samples": int(n),
                "rate_hz": fs,
                "start_s": float(rec.t_s[a]),
            },
        },
    )
    if keep_history:   # the last pass's √P, θ̂, innovations and NIS per step (calib run --rrd shows P converge)
        cal = replace(cal, history=FilterHistory(rec.t_s[a + 1:], out.sd_history[0], out.theta_history[0],
                                                 out.innovation[0], out.nis[0], layout.names))
    if estimate:   # the noise densities among the effects too, as calib run's joint filter (calib export reads them)
        cal = replace(cal, gyro=cal.gyro + (WhiteNoise(density=np.full(3, cfg0.arw_rad_s_sqrt_hz)),),
                      accelerometer=cal.accelerometer + (WhiteNoise(density=np.full(3, cfg0.vrw_m_s2_sqrt_hz)),))
    return cal


# the states whose σ the slow residual's spectrum corrects (calib.session.spectral): those the turns inform, at
# 0.03–0.5 Hz; not the attitude, the bias's random walk, a_e's own states or the temperature coefficients, whose
# information lies at the session's own scale, below what a 40-s Welch segment resolves
SPECTRAL_BLOCKS = ("gyro_scale", "gyro_nonorth", "lever_arm", "acc_bias", "acc_scale", "acc_nonorth", "acc_delay",
                   "gyro_g_sens")


def _spectral_sigma(P: np.ndarray, out, layout: StateLayout, cfg, f_lp: np.ndarray, slow_f: np.ndarray,
                    slow_resid: np.ndarray, kreg: np.ndarray, fs: float, dec: int, r_var: float, estimate: bool):
    """P with the σ of :data:`SPECTRAL_BLOCKS` from the slow residual's own spectrum (calib.session.spectral): P_D = P +
    ΔP gives each state's variance, and P → D P D, D = diag(σ_D/σ) on those states (1 elsewhere), keeps the model's
    correlations, so P stays positive definite (the temperatures where S and b_a are stated still come from the filter's
    own P: kf_hand).  ``slow_f`` = f_lp − K r̂ (N, 3) and ``slow_resid`` = |slow_f| − g (N,): kf_hand's slow residual.
    Returns (P, the correction's report)."""
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
                               prefilter_gain2=(lambda f: _lowpass_gain2(f, fs)) if PREFILTER_REFERENCE else None)
    var = np.diag(P)[sel]
    var_d = var + np.diag(corr.delta)
    factor = np.sqrt(np.maximum(var_d, 1e-4 * var) / var)
    d = np.ones(P.shape[0])
    d[sel] = factor
    names = [n for b in SPECTRAL_BLOCKS if layout.has(b) for n in (f"{b}_{a}" for a in "xyz")]
    report = {"sigma_factor": dict(zip(names, factor.tolist())), **corr.to_dict()}
    return P * np.outer(d, d), report


def kf_hand_band(rec: Recording) -> Calibration:
    """``kf_hand`` with the band-limited sway model (``sway="band"``: a Gauss–Markov floor + a Butterworth band-pass,
    :func:`_band_from_residual`); by import path ``calib.session.hand.filter:kf_hand_band`` (``calib montecarlo
    --methods``). Opt-in: docs/hand.md, "A band-limited sway model"."""
    return kf_hand(rec, sway="band")


def kf_hand_g_sensitivity(rec: Recording) -> Calibration:
    """``kf_hand`` with the gyro's g-sensitivity block on (:func:`hand_layout`); by import path
    ``calib.session.hand.filter:kf_hand_g_sensitivity`` (``calib montecarlo --methods``,
    benchmarks/mpu9250_ablation.py)."""
    return kf_hand(rec, g_sensitivity=True)


def _drift_ambiguity(cov_rw: np.ndarray, cov_const: np.ndarray, infl_const) -> tuple[np.ndarray, dict]:
    """σ of the reported parameters when the rests saw a gyro bias drift that the temperature does not explain.

    Two rests (3 degrees of freedom) measure how far the bias moved, not how it moved: a random walk (the
    model, q_b from :func:`bias_drift`) and a flicker floor (a warmed-up MEMS gyro's bias instability, PSD
    B²/(2πf), IEEE Std 952 Annex C) fitted to the same end-to-end change differ inside the session, where S
    and G are learnt (the flicker has more power at 0.01–0.1 Hz).  The random-walk filter absorbs that power
    into its bias state, so its innovations show no excess and κ̂ stays 1, while S, G take the error
    (measured, warmed-up MPU-9250 — its preset without warm-up and g-sensitivity — ideal hand, 200 seeds:
    NEES(6) 8.04, σ ~1.16× small, every seed ``ok``).  The last pass run with a constant bias (q_b = 0) leaves
    the drift in its innovations, where κ̂₀ (one-sided, :func:`calib.session.consistency.innovation_inflation`) sees
    it.  The session cannot tell the two models apart, so they are given equal weight — a two-model mixture's
    variance (Bar-Shalom, Li & Kirubarajan, *Estimation with Applications to Tracking and Navigation*, 2001,
    §11.6, the multiple-model estimate's covariance), here without its spread-of-means term and never below
    the random-walk model's:

        σ_i² = max(σ_i,rw², (σ_i,rw² + κ̂₀ σ_i,const²) / 2),   C ← D C_rw D,   D_ii = σ_i / σ_i,rw

    (the random-walk model's correlations and estimate kept — its S error is 7 % smaller on the same seeds).
    Applied when the recording's temperature channel stayed flat (< ``THERMAL_MIN_SPAN_C``): then the drift is not
    a warm-up.  Without a channel a warm-up's ramp is as likely, and on it the constant-bias pass's κ̂₀ is 5–38
    (flicker: 1.9–3.3): the mixture took the MPU-9250 preset with its channel removed from NEES(6) 5.93 to 2.2
    (kf_hand, 50 seeds) — so there the random walk stays alone, with a warning.
    Measured (200 seeds, ideal hand, NEES(6), band [5.52, 6.48]): the warmed-up MPU-9250 8.04 → 6.75; with its
    g-sensitivity (a bias step at each change of attitude, which the constant-bias pass reads as drift) 7.25 →
    5.21; the larger of the two σ instead of the mixture gave 5.96 and 4.21.  ``cov_rw``: the reported block
    with its own κ̂ applied; ``cov_const``: the same block of the constant-bias pass, before κ̂₀."""
    ratio = np.sqrt(np.diag(cov_const) * infl_const.factor / np.diag(cov_rw))
    d = np.sqrt(np.maximum((1.0 + ratio**2) / 2.0, 1.0))
    return cov_rw * np.outer(d, d), {"kappa_constant_bias": float(infl_const.factor),
                                     "sigma_ratio_constant_over_random_walk": ratio.tolist(),
                                     "sigma_factor": d.tolist()}


def _g_sensitivity_prior(p0: np.ndarray, layout, f_rest_m_s2: np.ndarray) -> None:
    """The bias's prior comes from a rest, where the gyro read b + diag(k) f̄ (f̄ that rest's specific force): so
    b = b̄ − diag(f̄) k, and with k ~ N(0, P_k) the prior of (b, k) is correlated,

        P_bb = s² + F P_k F,   P_bk = −F P_k,   F = diag(f̄).

    Independent priors would pin b at the rest's reading and misread every change of attitude afterwards
    (measured on the independent generator with 0.3 °/s/g: innovations ×15 their model, "diverged")."""
    _rest_reading_prior(p0, layout, "gyro_g_sens", np.asarray(f_rest_m_s2, float))


def _rest_reading_prior(p0: np.ndarray, layout, block: str, f: np.ndarray) -> None:
    """The gyro bias's prior when the rest that gave it read b + diag(f) x, x the 3-state ``block`` with prior P_x: b =
    b̄ − F x, so P_bb += F P_x F, P_bx = −F P_x, F = diag(f) (:func:`_g_sensitivity_prior`, :func:`_temp_bias_prior`;
    several such blocks add).  A no-op without ``block`` or the bias."""
    ox, ob = layout.offset(block), layout.offset("gyro_bias")
    if ox < 0 or ob < 0:
        return
    F = np.diag(f)
    px = p0[ox:ox + 3, ox:ox + 3].copy()
    p0[ob:ob + 3, ob:ob + 3] += F @ px @ F
    p0[ob:ob + 3, ox:ox + 3] = -F @ px
    p0[ox:ox + 3, ob:ob + 3] = -px @ F


def _temp_bias_prior(p0: np.ndarray, layout, dt_rest_c: float) -> None:
    """The bias's prior comes from a rest at T_rest, where the gyro read b + c_b ΔT (ΔT = T_rest − T₀, the filter's
    reference T₀): so b = b̄ − c_b ΔT, and with c_b ~ N(0, P_c) the prior of (b, c_b) is correlated,

        P_bb = s² + ΔT² P_c,   P_bc = −ΔT P_c

    (as :func:`_g_sensitivity_prior` for the specific force; the two add when both blocks are on).  A no-op without
    the block."""
    _rest_reading_prior(p0, layout, "gyro_temp_bias", np.full(3, dt_rest_c))


def _common_delay_prior(p0: np.ndarray, layout) -> None:
    """One delay for the whole accelerometer triad: the three ``acc_delay`` states' prior is σ² 𝟙𝟙ᵀ (rank one), so
    with no process noise every update moves them together and they stay one number δ.  Two chips' (or two dies')
    anti-alias filters and sampling set one offset between the triads; a per-axis δ_i took other misfits instead
    (measured on the x-IMU3 hand-held session: δ = +5.4, −3.6, −15.3 ms per axis, and G_y moved 36 σ from the factory
    calibration)."""
    o = layout.offset("acc_delay")
    if o < 0:
        return
    v = float(np.mean(np.diag(p0)[o:o + 3]))
    p0[o:o + 3, :] = 0.0
    p0[:, o:o + 3] = 0.0
    p0[o:o + 3, o:o + 3] = v


def _sensor_extra_prior(x0: np.ndarray, layout, sens: np.ndarray) -> None:
    """Prior mean 0 of the gyro's extra blocks (c_b, s_T, k) seen from the linearisation point ``sens`` (9,)."""
    for i, blk in enumerate(SENSOR_EXTRA_BLOCKS):
        o = layout.offset(blk)
        if o >= 0:
            x0[o:o + 3] = -sens[3 * i:3 * i + 3]


def scale_reference_rate(omega_rad_s: np.ndarray) -> dict:
    """The rate (rad/s, per body axis) at which the session's linear scale factor holds: m_i = Σ|ω_i|³ / Σω_i²
    over the calibrated rates ω (N, 3) the filter saw.

    A gyro's scale is not exactly linear (the MPU-9250's datasheet: ±0.1 % of its 500 °/s full scale).  With an
    odd-symmetric nonlinearity δ_i = k_i ω_i|ω_i| (gyrosim's ``scale_nonlinearity``), the least-squares linear
    slope over the session's rates is S_i + k_i Σ ω_i²|ω_i| / Σ ω_i² = S_i + k_i m_i (each sample's information
    on S_i ∝ ω_i²) — the chord slope (δ_i(m_i) − δ_i(−m_i)) / 2m_i, the scale at ±m_i, as an accelerometer
    calibrated on the |f| = g sphere holds at ±g.  So S is stated at m_i, as it is stated at a temperature
    (:func:`scale_at_temperature`): applied at other rates it carries the nonlinearity's difference.  Measured
    (warmed-up MPU-9250, ideal hand, 200 seeds): the S error's regression on k_i gives m_eff 0.79, 0.94, 0.96 rad/s
    against m_i 0.92, 1.03, 1.10; scoring S at m_i takes NEES(6) 6.77 → 6.21 (band [5.52, 6.48]).  Also
    reported: the largest |ω_i| and the RMS of ω_i (rad/s), the span over which the statement was learnt."""
    return {
        "rate_rad_s": _chord_point(omega_rad_s).tolist(),
        "max_abs_rate_rad_s": np.max(np.abs(omega_rad_s), axis=0).tolist(),
        "rms_rate_rad_s": np.sqrt(np.mean(omega_rad_s**2, axis=0)).tolist(),
        "rule": "m_i = Σ|ω_i|³/Σω_i²: S_i is the chord slope of the gyro's response over ±m_i",
    }


def acc_scale_reference_force(f_m_s2: np.ndarray) -> dict:
    """The specific force (m/s², per body axis) at which ``kf_hand_joint``'s accelerometer scale factor holds:
    m_i = Σ|f_i|³ / Σf_i² over the compensated specific force f (N, 3) at the filter's updates — the rule of
    :func:`scale_reference_rate`, whose argument holds here too: an odd-symmetric nonlinearity k_i f_i|f_i| (the
    MPU-9250's ±0.5 % of 4 g) reads as S_a,i + k_i m_i, the chord slope over ±m_i, and the session's attitudes decide
    m_i (≤ g; g only when every update saw axis i vertical).  Scoring S_a at ±g instead (the |f| = g sphere's chord)
    counted k_i (g − m_i) as error: measured, the MPU-9250 joint's z RMS of S_a,x, S_a,y 1.32, 1.26, and 1.10, 1.11
    with the nonlinearity neutralised (ideal hand, 50 paired seeds)."""
    f = np.asarray(f_m_s2, float)
    return {
        "specific_force_m_s2": _chord_point(f).tolist(),
        "max_abs_specific_force_m_s2": np.max(np.abs(f), axis=0).tolist(),
        "rule": "m_i = Σ|f_i|³/Σf_i²: S_a,i is the chord slope of the accelerometer's response over ±m_i",
    }


def _chord_point(x: np.ndarray) -> np.ndarray:
    """m_i = Σ|x_i|³ / Σx_i² per column of x (N, 3): where a linear fit's slope equals the chord of x|x| (0 without
    signal)."""
    x2 = np.sum(x**2, axis=0)
    return np.sum(np.abs(x) ** 3, axis=0) / np.where(x2 > 0, x2, np.inf)


def _temperature_report(thermal: tuple[np.ndarray, float] | None, t_ref_c: np.ndarray, sens: np.ndarray, P: np.ndarray,
                        layout, inflation: float, t_ref_acc_c: np.ndarray | None = None) -> dict:
    """``diagnostics["temperature"]``: the temperature S is reported at and the scale factor's temperature
    coefficient found (a finding for the user: it says how far from this temperature the calibration holds); with
    the accelerometer estimated (``acc_temp_bias``) the same for its bias: ``acc_bias_reference_temperature_c`` and
    ``acc_bias_temperature_coefficient_m_s2_per_c``.  ``modelled``: a temperature block is in the filter;
    ``scale_reference_temperature_c`` is present only when the gyro scale's is (Monte Carlo scores S there)."""
    if thermal is None:
        return {"modelled": False, "reason": f"no temperature channel, or it moved less than {THERMAL_MIN_SPAN_C} °C"}
    dT, t0 = thermal
    out: dict = {"modelled": True, "filter_reference_temperature_c": t0,
                 "span_c": [t0 + float(dT.min()), t0 + float(dT.max())]}
    note = (f"temperature: the session warmed {float(dT.max() - dT.min()):.2f} °C ({t0 + float(dT.min()):.2f}–"
            f"{t0 + float(dT.max()):.2f} °C)")
    ob = layout.offset("gyro_temp_bias")
    if ob >= 0:
        c_b = sens[0:3]
        cb_sd = np.sqrt(np.diag(P[ob:ob + 3, ob:ob + 3]) * inflation)
        out.update({"bias_temperature_coefficient_rad_s_per_c": c_b.tolist(),
                    "bias_temperature_coefficient_std_rad_s_per_c": cb_sd.tolist()})
        note += ("; the gyro bias is modelled as b_g + c_b (T − T₀): c_b = "
                 f"{np.array2string(np.degrees(c_b), precision=3)}"
                 f" ± {np.array2string(np.degrees(cb_sd), precision=3)} °/s/°C")
    o = layout.offset("gyro_temp_scale")
    if o >= 0:
        s_t = sens[3:6]
        s_sd = np.sqrt(np.diag(P[o:o + 3, o:o + 3]) * inflation)
        out.update({"scale_reference_temperature_c": np.asarray(t_ref_c).tolist(),
                    "scale_temperature_coefficient_per_c": s_t.tolist(),
                    "scale_temperature_coefficient_std_per_c": s_sd.tolist()})
        note += (
            f"; the gyro scale factor is modelled as S + s_T (T − T₀) and reported at "
            f"{np.array2string(np.asarray(t_ref_c), precision=2)} °C (x, y, z: where this session's rotations about "
            "each axis determined it; a scale factor holds at a temperature); s_T = "
            f"{np.array2string(s_t * 1e6, precision=0)} ± {np.array2string(s_sd * 1e6, precision=0)} ppm/°C (a session "
            "spanning a degree cannot measure it: a calibration at two temperatures can)"
        )
    oc = layout.offset("acc_temp_bias")
    if oc >= 0 and t_ref_acc_c is not None:
        c_a = sens[9:12]
        c_sd = np.sqrt(np.diag(P[oc:oc + 3, oc:oc + 3]) * inflation)
        out.update({"acc_bias_reference_temperature_c": np.asarray(t_ref_acc_c).tolist(),
                    "acc_bias_temperature_coefficient_m_s2_per_c": c_a.tolist(),
                    "acc_bias_temperature_coefficient_std_m_s2_per_c": c_sd.tolist()})
        mg = 1e3 / 9.80665
        note += (
            f"; the accelerometer bias is modelled as b_a + c_a (T − T₀) and reported at "
            f"{np.array2string(np.asarray(t_ref_acc_c), precision=2)} °C (x, y, z: where this session's attitudes "
            f"determined it); c_a = {np.array2string(c_a * mg, precision=2)} ± "
            f"{np.array2string(c_sd * mg, precision=2)} mg/°C"
        )
    out["note"] = note
    return out


def _g_sensitivity_report(sens: np.ndarray, P: np.ndarray, layout, inflation: float) -> dict:
    """``diagnostics["gyro_g_sensitivity"]``: the gyro's sensitivity to specific force along its own axis k_i
    (b_g,i = b_i + k_i f_i) with its σ, in rad/s per m/s² and °/s/g (a datasheet's "linear acceleration
    sensitivity").  The common part k_x = k_y = k_z is a bias along gravity — a rate about the vertical, which a
    levelling measurement cannot see — so it stays near its prior σ; the differences are what the session
    measured."""
    o = layout.offset("gyro_g_sens")
    k = sens[6:9]
    sd = np.sqrt(np.clip(np.diag(P)[o:o + 3], 0.0, None) * inflation)
    to_deg_g = math.degrees(1.0) * 9.80665
    cov = P[o:o + 3, o:o + 3] * inflation
    return {
        "model": "b_g,i = b_i + k_i f_i (f the specific force, body; diagonal g-sensitivity)",
        "k_rad_s_per_m_s2": k.tolist(),
        "std_rad_s_per_m_s2": sd.tolist(),
        "covariance_rad2_s2_per_m2_s4": cov.tolist(),
        "k_deg_s_per_g": (k * to_deg_g).tolist(),
        "std_deg_s_per_g": (sd * to_deg_g).tolist(),
    }


def _delay_report(sens: np.ndarray, P: np.ndarray, layout, inflation: float) -> dict:
    """``diagnostics["acc_delay"]``: the accelerometer's delay behind the gyro δ (s; f̃(t) = f(t − δ), positive: the
    accelerometer lags; one number for the triad, :func:`_common_delay_prior`) with its σ — a finding for the user: a
    timing skew between the two triads, or their anti-alias filters' different group delays (the MPU-9250's DLPF
    setting 3: gyro 5.9 ms, accelerometer 4.88 ms — InvenSense RM-MPU-9250A-00 register map, CONFIG and ACCEL_CONFIG 2
    — so δ ≈ −1 ms)."""
    o = layout.offset("acc_delay")
    d = float(np.mean(sens[12:15]))
    sd = math.sqrt(max(float(P[o, o]), 0.0) * inflation)
    return {"model": "f̃(t) = f(t − δ): the accelerometer samples δ after the gyro (first order in δ; one δ for the "
                     "triad)",
            "delay_s": d, "std_s": sd}


def _gravity_fit_lever_free(rec: Recording, prep, start: int, kreg: np.ndarray, r_m: np.ndarray,
                            theta_a: np.ndarray) -> GravityFit:
    """The |f| = g fit of :func:`calib.session.paper.prepare` (same samples from the first rest on, weights, prior) on
    f̃ − K(ω, ω̇) r̂ (the rest itself uncorrected: ω = 0 there): a hand's steady turn about a pivot adds a constant
    centripetal ω × (ω × r) that a quasi-static |f| = g fit reads as accelerometer bias (measured: b_y off by 0.05 m/s²,
    27 of its σ, with the typical hand's 6 cm).  The lever arm's acceleration in raw units is M_a K r̂ ≈ K r̂ (the
    difference is second order: S_a · K r̂).  The hand's sway and tremor stay in the residuals, correlated over seconds:
    the covariance is the fit's block-sum sandwich over ``INFLATION_BLOCK_S`` blocks (Newey & West 1987's batch means;
    :func:`calib.session.gravityfit.fit_gravity`, ``block_samples``), not the white-residual (Jᵀ W J)⁻¹, which was ~2×
    optimistic in σ for the accelerometer on the independent generator's hand and, scaling as 1/N, made the joint's
    prior depend on the sample rate."""
    ra, _ = prep.rest_range
    cfg = prep.config
    fs = rec.rate_hz
    f = rec.acc_m_s2[ra:].copy()
    f[start - ra:] -= np.einsum("nij,j->ni", kreg, r_m)
    f_reg = leave_out_means(f, regressor_half_window(fs), midpoint=False)
    prior = np.concatenate([cfg.prior_sigma("acc_bias"), cfg.prior_sigma("acc_scale"), cfg.prior_sigma("acc_nonorth")])
    sigma_f2 = cfg.vrw_m_s2_sqrt_hz**2 * fs
    return fit_gravity(f, f_reg, sigma_f2 + cfg.external_acc_allowance_m_s2**2, sigma_f2, cfg.gravity_m_s2, prior,
                       theta_a, block_samples=max(1, int(round(INFLATION_BLOCK_S * fs))))


def _confounding(P: np.ndarray, ol: int, layout: StateLayout = HAND_BIAS) -> None:
    """Refuse a session whose motion cannot tell the lever arm from S, G (module docstring)."""
    sd = np.sqrt(np.clip(np.diag(P), 1e-300, None))
    corr = P / np.outer(sd, sd)
    names = layout.names
    bad = []
    for i in range(ol, ol + 3):
        for j in range(3, 9):
            if abs(corr[i, j]) > CONFOUND_CORRELATION:
                bad.append(f"lever arm {names[i]} with {names[j]} (correlation {corr[i, j]:+.3f})")
    if bad:
        raise RecordingError(
            "this session's motion cannot separate the hand's lever arm from the gyro errors: "
            + "; ".join(bad)
            + ". The lever arm's acceleration grows with ω² and ω̇, a scale or axis error's attitude error with the "
            "angle turned: repeat the rotations about each axis at two clearly different speeds (one at least "
            "twice the other), including rotations about horizontal axes — or use --method kf_session if the device "
            "turned about its own sensor (no lever arm)"
        )


CROSS_CHECK_TAIL = 0.001


def hand_cross_check(rec: Recording, gyro_params: np.ndarray, cov_sg: np.ndarray,
                     acc_m_s2: np.ndarray | None = None, accelerometer: str = "calibrated") -> tuple[list[str], dict]:
    """Does a hand-blind estimate of S, G (``gyro_params`` (6,), covariance ``cov_sg`` (6, 6)) agree with
    ``kf_hand``'s on the same recording?  The lever arm's acceleration is correlated with the rotation,
    so what a model without it aliases into S and G does not show in its residuals — no test of its own
    innovations can see it.  The difference δ to the hand-aware estimate can: under both models'
    claims δ ~ N(0, C_δ), C_δ ≤ C + C_hand (conservative: the estimates' positive correlation ignored),
    and δᵀC_δ⁻¹δ above χ²₆'s 99.9 % quantile means the hand-blind σ is understated — by at least
    max_i |δ_i|/σ_i / 3 (the factor a 3σ error would need).  ``acc_m_s2``: the accelerometer already
    compensated, else the recording's.  ``accelerometer="estimate"`` (the hand-blind estimate came from a
    joint calibration, the accelerometer estimated too): the peer is ``kf_hand_joint`` on the raw
    recording (``acc_m_s2`` ignored) — kf_hand on the joint calibration's own compensated accelerometer
    inherits its hand-biased |f| = g fit and agreed with wrong S, G (docs/hand.md, "Honest σ") — and the
    test is the one that defines a wrong answer, with kf_hand_joint as the reference: δᵀC⁻¹δ above χ²₆'s
    99.9 % quantile *or* any |δ_i| + 2σ_peer,i > 3σ_i (C = the hand-blind covariance alone; the hand-blind
    error is δ plus the peer's own, |e_peer,i| ≤ 2σ_peer,i at 95 %, and must stay within 3σ_i — without
    the peer's margin two borderline wrong answers of 50 shaky-hand mpu9250 seeds passed).  The two filters read the
    same samples, so their errors share the noise's part: without a hand δ's spread is ~1 % of C + C_hand
    (measured, mean δᵀ(C + C_hand)⁻¹δ / 6 = 0.006–0.01 on the independent generator; docs/hand.md), and
    C + C_hand let wrong "ok" answers pass (17 and 15 of 45 shaky-hand "ok" seeds).  δ is then the hand-caused
    error of the hand-blind answer up to a small fraction of its σ.

    Returns (warnings — empty when consistent or when ``kf_hand`` cannot run on this recording —,
    diagnostics)."""
    from scipy import stats

    joint = accelerometer == "estimate"
    r = rec if acc_m_s2 is None or joint else rec.with_signals(acc_m_s2=acc_m_s2)
    try:
        h = kf_hand(r, accelerometer="estimate") if joint else kf_hand(r)
    except RecordingError as exc:
        return [], {"skipped": str(exc)}
    items = [("gyro", "scale_factor"), ("gyro", "nonorthogonality")]
    th = np.concatenate([h.value(t, k) for t, k in items])
    ch = h.block_covariance(items)
    d = np.asarray(gyro_params, float) - th
    c = np.asarray(cov_sg, float) + (0.0 if joint else ch)
    stat = float(d @ np.linalg.solve(c, d))
    thr = float(stats.chi2.ppf(1 - CROSS_CHECK_TAIL, 6))
    sd = np.sqrt(np.diag(cov_sg))
    under = float(np.max(np.abs(d) / sd) / 3.0)
    # joint: the hand-blind error is e = δ + e_peer with |e_peer,i| ≤ 2σ_peer,i (95 %); the answer stands
    # only if that bound on |e_i| stays within its own 3σ_i
    bound = float(np.max((np.abs(d) + 2.0 * np.sqrt(np.diag(ch))) / sd))
    bad = stat > thr or (joint and bound > 3.0)
    diag = {"chi2": stat, "threshold_99_9": thr, "kf_hand_minus_this": (-d).tolist(),
            "covariance": "this" if joint else "this + kf_hand", "max_abs_delta_over_sigma": 3 * under,
            "max_error_bound_over_sigma": bound if joint else None,
            "sigma_understated_at_least": max(under, 1.0) if bad else 1.0, "peer": h.method,
            "lever_arm_m": h.diagnostics["hand"]["lever_arm_m"]}
    if not bad:
        return [], diag
    r_cm = np.array(h.diagnostics["hand"]["lever_arm_m"]) * 100
    return [
        f"inconsistent: the hand-aware estimate ({h.method}) differs from this one by χ² {stat:.0f} on 6 S, G "
        f"(99.9 % bound {thr:.1f}), up to {3 * under:.1f} σ"
        + (
            f" (with {h.method}'s own 2σ the error may reach {bound:.1f} σ, beyond 3 σ)"
            if joint and bound > 3.0
            else ""
        )
        + (f": σ is understated at least ×{under:.1f}" if under > 1.0 else "")
        + ". The hand "
        f"turned the device about a point {np.array2string(r_cm, precision=1)} cm away (lever arm, body frame), "
        f"whose acceleration this model reads as gravity; use {h.method} (calib run --method hand)"
    ], diag
