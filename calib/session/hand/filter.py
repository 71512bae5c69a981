"""``kf_hand``: the gyro calibration with the hand in the model (and ``kf_hand_joint``, the accelerometer with it).

A hand-held session's accelerometer senses, besides gravity and its white noise (body frame RFU, nav ENU; f the
specific force, g_b gravity in the body):

    f = g_b + K(ω, ω̇) r + C(q)ᵀ a_e + v,     K(ω, ω̇) = [ω̇×] + [ω×][ω×]

This module runs the method; each part of the model lives in its own module of this folder:

* the lever arm r and its regressor K (:mod:`.lever`);
* the tremor pre-filter — the specific force rotated to nav, low-passed there, rotated back — and the decimated
  update it allows (:mod:`.lowpass`);
* the slow external acceleration a_e as a fitted shaping filter, and σ under the residual's own spectrum
  (:mod:`.sway`);
* the gyro bias as a random walk fitted to the rests' drift (:mod:`calib.session.drift`), on a warming sensor its
  temperature coefficient, the scale factor's, and with the accelerometer estimated its bias's (:mod:`.thermal`);
* the priors that tie the extra blocks to the rest that gave the bias, and the accelerometer's delay as one number
  (:mod:`.priors`); what the result states besides the parameters (:mod:`.reports`); the checks of the method's
  assumptions on a recording (:mod:`.checks`);
* the parameters of the method, one frozen dataclass (:class:`~calib.session.hand.params.HandParams`).

Noise levels from the data, as every estimator here (:mod:`calib.session.noiselevels`), but from the first rest's
spectrum *above* the tremor band (a hand's rest is not still, and its standard deviation would count the tremor as
sensor noise) — or at 2–6 Hz when an output low-pass (a DLPF) rolls the band above the tremor off (reported in
``diagnostics["noise"]`` with a warning).

Estimation (iterated, each pass linearised at the previous pass's estimate; compiled kernel
:func:`calib.session.kernel.run_filter` with :func:`~calib.session.hand.params.hand_layout`: attitude, S, G, gyro bias,
lever arm, x, z, z₂ (:data:`calib.session.model.HAND_BIAS`), [c_b, s_T], [g-sensitivity], δ — 27 states, 33 with c_b
and s_T (a temperature channel that moved), 30 with the opt-in g-sensitivity alone, 36 with both; the unused z₂
(m = 1) or z (no high-pass) inert):

1. :func:`_session`: prepare the recording (:func:`calib.session.prepare.prepare`), the noise floors, the rests'
   drift, the filter's start after the rest that gave the bias, the decimated updates, the temperature;
2. :func:`_passes`: pass 1 with σ_s from the session's (|f_lp| − g)², passes 2 and 3 with the a_e model fitted to the
   previous pass's residual; the last pass tries the random walk's ladder and, on a flat temperature, runs once
   more with a constant bias;
3. :func:`_covariance`: P corrected to the slow residual's spectrum, inflated from the innovations, S and b_a at
   the temperatures the session pinned them;
4. :func:`_verdict` and :func:`_calibration`: the checks, the notes for the user, the diagnostics.

A session whose motion cannot tell the lever arm from S or G is refused (:func:`.checks.refuse_confounded`).
Sources: Titterton & Weston, *Strapdown Inertial Navigation Technology*, 2nd ed., §10.4 (lever-arm compensation);
Gelb, *Applied Optimal Estimation* (1974), §4.5 (shaping filters for coloured measurement noise).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from gyrosim.calibration import Calibration
from gyrosim.effects import GyroAccMisalignment, WhiteNoise
from gyrosim.recording import Recording
from gyrosim.rotations import quat_conjugate, quat_rotate
from gyrosim.strapdown import integrate_gyro

from calib.compat import moved_attribute
from calib.inputs.turns import Turns
from calib.session.consistency import (
    Inflation,
    apply_inflation,
    check_estimate,
    check_innovations,
    innovation_inflation,
    rest_gravity,
    verdict,
)
from calib.session.drift import DRIFT_QUANTILE, BiasDrift, bias_drift, drift_ambiguity  # noqa: F401 (old home)
from calib.session.gravityfit import GravityFit, compensate_acc
from calib.session.hand.checks import CONFOUND_CORRELATION, check_hand_assumptions, refuse_confounded
from calib.session.hand.lever import lever_jacobian, lever_regressor
from calib.session.hand.lowpass import CUTOFF_HZ, ORDER, lowpass, lowpass_gain2, variance_ratio  # noqa: F401
from calib.session.hand.params import HandParams, hand_layout, joint_layout
from calib.session.hand.priors import (
    FIT_PRIOR_INFLATION,
    acc_temp_tilt_prior,
    common_delay_prior,
    g_sensitivity_prior,
    gravity_fit_lever_free,
    sensor_extra_prior,
    temp_bias_prior,
)
from calib.session.hand.reports import (
    acc_scale_reference_force,
    delay_report,
    g_sensitivity_report,
    scale_reference_rate,
)
from calib.session.hand.sway import (  # noqa: F401 (the constants re-exported: their old home)
    BAND_FIT_HI_HZ,
    BAND_FIT_LO_HZ,
    BAND_ORDER,
    SPECTRAL_BLOCKS,
    SWAY_MODELS,
    UNDER_WEIGHT,
    band_config,
    band_report,
    fit_band,
    fit_gauss_markov,
    spectral_sigma,
)
from calib.session.hand.thermal import (  # noqa: F401 (THERMAL_SMOOTH_S re-exported: its old home)
    THERMAL_MIN_SPAN_C,
    THERMAL_SMOOTH_S,
    acc_bias_at_temperature,
    rest_temperature,
    scale_at_temperature,
    session_temperature,
    smoothed_temperature,
    temperature_report,
)
from calib.session.kernel import SENSOR_NOMINALS, FilterRun, LeverJacobian, run_filter
from calib.session.known_turns import apply_known_turns
from calib.session.model import (
    BLOCK_LABELS,
    EXT_ACC_EXTRA_BLOCKS,
    HAND_BIAS,
    MISALIGN_BLOCKS,
    FilterConfig,
    FilterHistory,
    StateLayout,
    acc_theta,
    gyro_axis_matrix,
    initial_covariance,
    m_matrix,
    theta_slice,
)
from calib.session.noiselevels import (  # noqa: F401 (re-exported: their old home)
    WHITE_BAND2_HZ,
    WHITE_BAND_HZ,
    WHITE_SEGMENT_S,
    white_density,
    white_density_check,
    white_variance_relative_sd,
)
from calib.session.observability import check_observability, filter_observability
from calib.session.prepare import Prepared, initial_attitude, prepare, refuse_if_nothing_observed, rest_mask, tilt_sigma
from calib.session.rest_bias import rest_bias

__all__ = [
    "kf_hand",
    "kf_hand_band",
    "kf_hand_g_sensitivity",
    "HandParams",
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
    "hand_layout",
    "joint_layout",
    "acc_bias_at_temperature",
    "acc_scale_reference_force",
]

__getattr__ = moved_attribute(__name__)   # hand_cross_check, CROSS_CHECK_TAIL: calib.session.crosscheck

# the gyro's misalignment α is estimated when the motion takes its σ below this on every axis: a fifth of an
# assembly's typical 0.5° (measured: imu_tk's Xsens 0.026°, the independent hand 0.005°; BROAD's slow rotation, trial
# 02, 0.09–0.17°, where the α it fitted, −0.4° about z, made the orientation filters' heading worse: Madgwick 0.63° →
# 0.84°)
MISALIGNMENT_OBSERVED_RAD = math.radians(0.1)
LAYOUT = HAND_BIAS         # kf_hand's base layout (accelerometer calibrated); kf_hand_joint's: HAND_JOINT
# the registered estimator each accelerometer mode of :func:`kf_hand` is (the label its result carries)
REGISTERED_NAME = {"calibrated": "kf_hand", "estimate": "kf_hand_joint"}
LEVER_INFLATION_BLOCK_S = 1.0   # the lever arm's σ inflation test's blocks (its information: 0.1–1 Hz; _covariance)


@dataclass(frozen=True)
class _Session:
    """What every pass shares: the recording prepared (``prep.start`` after the rest that gave the bias), the
    filter's fixed settings and the session's temperature (:func:`_session`)."""

    rec: Recording
    params: HandParams
    accelerometer: str
    prep: Prepared
    cfg0: FilterConfig        # noise floors applied, the bias's prior and random walk set
    drift: BiasDrift
    tilt: float               # σ of the initial roll, pitch (rad)
    layout: StateLayout
    rows: int                 # 2; 3 with the accelerometer estimated
    upd: np.ndarray           # (n,) decimated updates, saturated samples out
    still: np.ndarray         # (n,) steps inside a rest
    rho: float                # the pre-filter's white-noise variance ratio
    dec: int                  # update every dec-th sample
    sigma_f2: float           # σ_f² per sample, (m/s²)²
    r_var: float              # R per update: σ_f²/dec
    thermal: tuple[np.ndarray, float] | None   # (T − T₀ (n,), T₀) of a temperature channel that moved
    dt_rest: float            # the first rest's T − T₀ (°C)
    f_rest: np.ndarray        # the first rest's mean specific force (body, m/s²)
    flat_temperature: bool    # a recorded temperature that stayed flat
    rolloff_notes: tuple[str, ...]

    @property
    def estimate(self) -> bool:
        return self.accelerometer == "estimate"

    @property
    def fs(self) -> float:
        return self.rec.rate_hz

    @property
    def a(self) -> int:
        return self.prep.start

    @property
    def t(self) -> np.ndarray:
        return self.rec.t_s[self.prep.start:]

    def lowpass(self, x: np.ndarray) -> np.ndarray:
        """The tremor pre-filter of :class:`HandParams` at this session's rate."""
        return lowpass(x, self.fs, self.params.cutoff_hz, self.params.order)


@dataclass(frozen=True)
class _Sway:
    """A pass's a_e model: the Gauss–Markov σ_s, τ, high-pass τ_h and order (the band model's floor), the band."""

    sigma_s: float
    tau: float
    tau_hp: float
    hp_order: int
    band: dict | None = None


@dataclass(frozen=True)
class _Tremor:
    """The tremor band's RMS the pre-filter removed, what the rest's noise estimate resolves of it (m/s²)."""

    rms: float
    resolution: float

    @property
    def resolved(self) -> bool:
        return self.rms > self.resolution


@dataclass(frozen=True)
class _Fit:
    """The last pass: its run (and the constant-bias run), nominals, a_e model, config and the data it saw."""

    out: FilterRun
    out_const: FilterRun | None
    theta: np.ndarray
    hand0: np.ndarray
    sens0: np.ndarray
    sway: _Sway
    cfg: FilterConfig
    gfit: GravityFit | None
    f_lp: np.ndarray          # the tremor-free specific force (body; compensated with the accelerometer estimated)
    kreg: np.ndarray          # K(ω, ω̇) (n, 3, 3)
    qb_factor: float
    obs_notes: tuple[str, ...]


def kf_hand(rec: Recording, accelerometer: str = "calibrated", gravity_m_s2: float | None = None, *,
            params: HandParams | None = None, keep_history: bool = False, g_sensitivity: bool | None = None,
            sway: str | None = None, delay: bool | None = None, prepared: Prepared | None = None,
            turns: Turns | None = None) -> Calibration:
    """The hand-aware gyro calibration (module docstring).  ``accelerometer``: "calibrated" (Zhou §3.3.2,
    the registered ``kf_hand``: 27 states, 33 when the recording's temperature moved (c_b, s_T), 36 with the opt-in
    ``g_sensitivity`` too — :func:`~calib.session.hand.params.hand_layout`) or "estimate" (the registered
    ``kf_hand_joint``: + the accelerometer's bias, scale factor and non-orthogonality, 36 states, 42 when the
    recording's temperature moved (s_T and the accelerometer bias's c_a —
    :func:`~calib.session.hand.params.joint_layout`) — what ``calib run`` estimates by default), each 3 more with the
    gyro's misalignment α against the accelerometer when the motion determines it (``HandParams.misalignment``).
    ``params``: the method's parameters (:class:`~calib.session.hand.params.HandParams`; default the validated method);
    ``g_sensitivity``, ``sway``, ``delay``: shorthands for those fields of ``params``.  With the accelerometer
    estimated, every pass applies its error model at the current estimate, f̂ = M̂_a⁻¹(f̃ − b̂_a), *before* the
    nav-frame tremor low-pass (the low-pass of a rotated body-frame bias is not the bias), and hands the kernel the
    low-passed f̂ mapped back through f̃_lp = M̂_a f̂_lp + b̂_a, so the kernel's own compensation at the nominal gives
    f̂_lp again; the prior of the accelerometer states is the |f| = g fit's (mean and covariance, as ``kf_session``),
    the initial tilt's dependence on them in P₀ (:func:`calib.session.model.initial_covariance`), re-linearised each
    pass as ``iterated_session`` does.  ``keep_history``: the last pass's √P, θ̂, innovations and NIS per step.
    ``prepared``: :func:`calib.session.prepare.prepare` of ``rec`` with the same ``accelerometer`` and
    ``gravity_m_s2``, when the caller has it already (``calib run`` uses it again for the coaching).  ``turns``: turns
    of a known angle (:mod:`calib.inputs.turns`), measurements of the gyro's parameters after the last pass
    (:func:`calib.session.known_turns.apply_known_turns`: what gravity cannot see, a turn about the vertical)."""
    p = params or HandParams()
    p = replace(p, **{k: v for k, v in (("g_sensitivity", g_sensitivity), ("sway", sway), ("delay", delay))
                      if v is not None})
    if accelerometer == "estimate" and p.sway != "gauss_markov":
        raise ValueError("the band-limited sway model is implemented for kf_hand (accelerometer calibrated) only")
    if prepared is not None and prepared.accelerometer != accelerometer:
        raise ValueError(f"prepared for the accelerometer {prepared.accelerometer}, asked: {accelerometer}")
    ses = _session(rec, accelerometer, gravity_m_s2, p, prepared)
    sway0, tremor = _first_sway(ses)
    fit = _passes(ses, sway0, keep_history)
    cov, cov_parts = _covariance(ses, fit)
    seen = _misalignment_seen(ses, fit, cov)
    if seen is not None and not seen["estimated"]:   # the motion does not determine α: the model without it
        ses = replace(ses, layout=StateLayout(tuple(b for b in ses.layout.blocks if b not in MISALIGN_BLOCKS)))
        fit = _passes(ses, sway0, keep_history)
        cov, cov_parts = _covariance(ses, fit)
    cal = _calibration(ses, fit, cov, cov_parts, tremor, keep_history)
    if seen is not None:
        cal = replace(cal, diagnostics={**cal.diagnostics, "gyro_misalignment": seen})
    return cal if turns is None else apply_known_turns(cal, rec, turns, ses.cfg0.arw_rad_s_sqrt_hz)


def _misalignment_seen(ses: _Session, fit: _Fit, cov: np.ndarray) -> dict | None:
    """Whether the session's motion determines the gyro's rotation against the accelerometer (None: not modelled):
    its reported σ (``cov``, :func:`_covariance`: the slow residual's spectrum and the innovations' inflation applied;
    α's rows follow the bias's, S's and G's) at most ``MISALIGNMENT_OBSERVED_RAD`` on every axis.  A motion that does
    not (turns about one axis only; a slow rotation) would leave α near its prior, where it trades with G (the same
    column of the gyro's axis matrix): the model without α is run instead, and the JSON says so."""
    o = ses.layout.offset("gyro_misalign")
    if o < 0:
        return None
    prior = ses.cfg0.prior_sigma("gyro_misalign")
    reported = np.sqrt(np.diag(cov)[9:12])
    return {"estimated": bool(np.all(reported <= MISALIGNMENT_OBSERVED_RAD)), "prior_std_rad": prior.tolist(),
            "filter_std_rad": np.sqrt(np.diag(fit.out.p[0])[o:o + 3]).tolist(), "reported_std_rad": reported.tolist(),
            "observed_below_rad": MISALIGNMENT_OBSERVED_RAD}


def kf_hand_band(rec: Recording) -> Calibration:
    """``kf_hand`` with the band-limited sway model (``sway="band"``: a Gauss–Markov floor + a Butterworth band-pass,
    :func:`calib.session.hand.sway.fit_band`); by import path ``calib.session.hand.filter:kf_hand_band`` (``calib
    montecarlo --methods``). Opt-in: docs/hand.md, "A band-limited sway model"."""
    return kf_hand(rec, params=HandParams(sway="band"))


def kf_hand_g_sensitivity(rec: Recording) -> Calibration:
    """``kf_hand`` with the gyro's g-sensitivity block on (:func:`~calib.session.hand.params.hand_layout`); by import
    path ``calib.session.hand.filter:kf_hand_g_sensitivity`` (``calib montecarlo --methods``,
    benchmarks/mpu9250_ablation.py)."""
    return kf_hand(rec, params=HandParams(g_sensitivity=True))


# ---------------------------------------------------------------------------------------------------------------------
# 1. the session


def _session(rec: Recording, accelerometer: str, gravity_m_s2: float | None, params: HandParams,
             prepared: Prepared | None = None) -> _Session:
    """The recording prepared for every pass (module docstring, step 1); ``prepared``: the caller's own."""
    estimate = accelerometer == "estimate"
    prep = prepared or prepare(rec, accelerometer=accelerometer, gravity_m_s2=gravity_m_s2)
    ra, rb = prep.rest_range
    nz = prep.noise
    # the densities from the rest's spectrum above the tremor, or at 2–6 Hz when an output low-pass rolls it off
    # (prepare's, on the same rest: calib.session.noiselevels.estimate_noise)
    wd_g, wd_a = nz.gyro_white, nz.acc_white
    arw, vrw = nz.gyro_density_rad_s_sqrt_hz, nz.acc_density_m_s2_sqrt_hz
    rolloff_notes = tuple(n for n in (wd_g.note("gyro", "rad/s") if wd_g else None,
                                      wd_a.note("accelerometer", "m/s²") if wd_a else None) if n)
    # the bias state's prior: the batch means' σ, as before calib.session.rest_bias (Prepared.bias_batch_std_rad_s)
    cfg0 = replace(prep.config, prior_gyro_bias_rad_s=tuple(prep.bias_batch_std_rad_s))
    if arw is not None and vrw is not None:   # never below the quantisation / discretisation floors
        cfg0 = replace(cfg0, arw_rad_s_sqrt_hz=max(arw, nz.gyro_floor_rad_s / math.sqrt(rec.rate_hz)),
                       vrw_m_s2_sqrt_hz=max(vrw, nz.acc_floor_m_s2 / math.sqrt(rec.rate_hz)))
    fs = rec.rate_hz
    # the gyro bias is a state (a random walk, q_b from the rests: bias_drift): the filter starts after
    # the rest that gave the bias's prior, whose gyro samples would otherwise inform the bias twice
    drift = bias_drift(rec.gyro_rad_s, rec.t_s, prep.rest.index_ranges, cfg0.arw_rad_s_sqrt_hz,
                       quantile=params.drift_quantile)
    cfg0 = replace(cfg0, gyro_bias_rw_rad_s_sqrt_s=drift.rrw_rad_s_sqrt_s)
    tilt = tilt_sigma(rec, ra, rb, cfg0.gravity_m_s2)
    prep = replace(prep, start=max(rb - 1, prep.start))
    a = prep.start
    refuse_if_nothing_observed(rec, prep.bias.value_rad_s, ra, rb, a)
    n = rec.t_s.size - a
    sigma_f2 = cfg0.vrw_m_s2_sqrt_hz**2 * fs
    rho = variance_ratio(fs, params.cutoff_hz, params.order)
    dec = max(1, int(math.floor(1.0 / rho)))
    upd = np.zeros(n, bool)
    upd[::dec] = True
    if prep.saturated is not None:
        upd &= ~prep.saturated[a:]
    # the gyro's g-sensitivity and (a warming sensor) the scale's temperature coefficient: kf_hand (calibrated
    # accelerometer); kf_hand_joint on a warming sensor: + the accelerometer bias's temperature coefficient c_a
    # (and the gyro scale's s_T, HandParams.joint_gyro_thermal)
    thermal = session_temperature(None if rec.temp_c is None else rec.temp_c[a:], fs)
    warming = thermal is not None
    # the gyro's misalignment α by default with the accelerometer estimated — not on noise-free input, where the noise
    # floor lets α take the rate integration's discretisation error (measured on the independent generator's held
    # gyro: α̂ 0.7° with σ 1e-7 rad, S off by 1e-2, against 5e-6 without α)
    misalign = (estimate and not prep.noise.noise_free) if params.misalignment is None else params.misalignment
    layout = (joint_layout(warming, params.joint_gyro_thermal, params.delay, params.joint_gyro_temp_bias,
                           misalignment=misalign) if estimate
              else hand_layout(warming, params.g_sensitivity, band=params.sway == "band", delay=params.delay,
                               gyro_temp_bias=params.gyro_temp_bias, misalignment=misalign))
    # the rest's mean temperature − T₀: its accelerometer mean levels the initial attitude (c_a) and its gyro mean is
    # the bias's prior (c_b)
    dt_rest = rest_temperature(rec.temp_c, fs, ra, rb) - thermal[1] if thermal is not None else 0.0
    # a recorded temperature that stayed flat: the drift is not a warm-up (drift_ambiguity); without a channel it may be
    flat_temperature = thermal is None and rec.temp_c is not None and bool(np.all(np.isfinite(rec.temp_c[a:])))
    # the levelling rows; with the accelerometer estimated also the vertical one, which carries the |f| = g
    # information with the hand in the model (a_e's vertical component, the lever arm) — kf_session leaves it
    # to its |f| = g fit, whose white-residual covariance is optimistic with a hand
    return _Session(rec, params, accelerometer, prep, cfg0, drift, tilt, layout, 3 if estimate else 2, upd,
                    rest_mask(prep, n), rho, dec, sigma_f2, sigma_f2 / dec, thermal, dt_rest,
                    np.mean(rec.acc_m_s2[ra:rb], axis=0),   # the specific force during the rest that gave the prior
                    flat_temperature, rolloff_notes)


def _first_sway(ses: _Session) -> tuple[_Sway, _Tremor]:
    """Pass 1's external acceleration — the session's (|f_lp| − g)² (kf_session_r's allowance, low-passed), with the
    accelerometer compensated by the |f| = g fit when it is estimated — and the tremor band the pre-filter removes."""
    rec, a, cfg0, sigma_f2, rho = ses.rec, ses.a, ses.cfg0, ses.sigma_f2, ses.rho
    ra, rb = ses.prep.rest_range
    acc0 = compensate_acc(rec.acc_m_s2[a:], acc_theta(ses.prep.theta0)) if ses.estimate else rec.acc_m_s2[a:]
    f_lp0 = ses.lowpass(acc0)
    along = float(np.mean((np.linalg.norm(f_lp0, axis=1) - cfg0.gravity_m_s2) ** 2)) - sigma_f2 * rho
    sway = _Sway(math.sqrt(max(3.0 * along, ses.r_var)), 1.0, math.inf, 1)
    tremor_rms = math.sqrt(max(float(np.mean(np.sum((acc0 - f_lp0) ** 2, axis=1))) - 3 * sigma_f2 * (1 - rho), 0.0))
    # what that subtraction resolves: 2σ of the white-noise variance removed (its N² measured on the first rest), as an
    # RMS — on a noisy sensor the "tremor" is the noise estimate's error (the paper's preset, VRW 15 mg/√Hz: 0.67 m/s²
    # reported, the hand's 0.09)
    vrw = ses.prep.noise.acc_density_m_s2_sqrt_hz
    rel_n2 = (
        white_variance_relative_sd(rec.acc_m_s2[ra:rb], ses.fs)
        if vrw is not None and cfg0.vrw_m_s2_sqrt_hz == vrw
        else None
    )
    resolution = math.sqrt(2.0 * 3 * sigma_f2 * (1 - rho) * rel_n2) if rel_n2 is not None else 0.0
    return sway, _Tremor(tremor_rms, resolution)


# ---------------------------------------------------------------------------------------------------------------------
# 2. the passes


@dataclass(frozen=True)
class _PassInputs:
    """One pass's linearisation: the compensated rate's regressors, the tremor-free force, the prior."""

    q0: np.ndarray                 # the initial attitude (body → ENU)
    f0: np.ndarray | None          # the rest's compensated specific force and M̂_a⁻¹ (accelerometer estimated)
    mi_a: np.ndarray | None
    f_lp: np.ndarray               # the tremor-free specific force (n, 3, body)
    f_kernel: np.ndarray           # … mapped back through the accelerometer's model for the kernel
    kreg: np.ndarray               # K(ω, ω̇) (n, 3, 3)
    ljac: LeverJacobian
    x0: np.ndarray                 # the prior's mean as an error state (n_states,)
    p0: np.ndarray                 # P₀
    gfit: GravityFit | None        # the accelerometer's prior (the |f| = g fit)


def _passes(ses: _Session, sway: _Sway, keep_history: bool) -> _Fit:
    """``params.passes`` filter passes, each linearised at the previous one's estimate (module docstring, step 2)."""
    prep, layout, params = ses.prep, ses.layout, ses.params
    theta = prep.theta0.copy()
    hand0 = np.zeros(6)
    sens0 = np.zeros(SENSOR_NOMINALS)   # the extra blocks' nominals: c_b, s_T, k, c_a, δ (SENSOR_EXTRA_BLOCKS)
    q0 = prep.quat0_nb
    obs_notes: list[str] = []
    out_const = None                    # the last pass with a constant gyro bias (drift_ambiguity)
    for p in range(params.passes):
        last = p == params.passes - 1
        theta[theta_slice("gyro_bias")] = prep.theta0[theta_slice("gyro_bias")]   # each pass starts at the rest's bias
        inp = _pass_inputs(ses, p, theta, hand0, sens0, q0, sway)
        q0 = inp.q0
        if p > 0:   # the a_e model from the previous pass's lever arm (module docstring, step 2)
            sway = _fitted_sway(ses, inp.f_lp, inp.kreg, hand0)
        cfg = replace(ses.cfg0, external_acc_allowance_m_s2=0.0, ext_acc_rms_m_s2=sway.sigma_s, ext_acc_tau_s=sway.tau,
                      ext_acc_highpass_tau_s=sway.tau_hp, ext_acc_highpass_order=sway.hp_order,
                      **(band_config(sway.band) if sway.band is not None else {}))
        inp = _with_prior(ses, inp, p, cfg, theta, hand0, sens0)

        def run(cfg_: FilterConfig, keep: bool, record: bool = False) -> FilterRun:
            return _run(ses, inp, cfg_, theta, hand0, sens0, keep, record)

        if last and ses.drift.q_rad2_s3 > 0 and ses.flat_temperature:
            # the bias-drift ambiguity (drift_ambiguity): the last pass once more with a constant bias
            out_const = run(replace(cfg, gyro_bias_rw_rad_s_sqrt_s=0.0), False)
        # with c_b a state the random walk keeps only what c_b does not explain (HandParams.qb_ladder); passes 1–2 at
        # q̂_b
        ladder = params.qb_ladder if last and layout.has("gyro_temp_bias") and ses.drift.q_rad2_s3 > 0 else (1.0,)
        for qb_factor in ladder:
            out = run(replace(cfg, gyro_bias_rw_rad_s_sqrt_s=cfg.gyro_bias_rw_rad_s_sqrt_s * math.sqrt(qb_factor)),
                      keep_history and last,
                      record=params.spectral_sigma and last and params.sway != "band" and not prep.noise.noise_free
                      and cfg.ext_acc_rms_m_s2**2 > ses.r_var)
            if qb_factor == ladder[-1] or innovation_inflation(out.whitened[0], ses.t[1:]).factor == 1.0:
                break
        theta = out.theta[0].copy()
        hand0 = out.hand[0].copy()
        if out.sensor_extra is not None:
            sens0 = out.sensor_extra[0].copy()
        if p == 0:   # calib run's observability check: gyro warnings, an undetermined accelerometer refused
            check_observability(filter_observability(layout, out.p[0], inp.p0, prep.gravity_fit),
                                prep.windows_f_hat, obs_notes)
    return _Fit(out, out_const, theta, hand0, sens0, sway, cfg, inp.gfit, inp.f_lp, inp.kreg, qb_factor,
                tuple(obs_notes))


def _pass_inputs(ses: _Session, p: int, theta: np.ndarray, hand0: np.ndarray, sens0: np.ndarray, q0: np.ndarray,
                 sway: _Sway) -> _PassInputs:
    """The rate compensated at θ̂, the rest attitude (with the accelerometer estimated, at this pass's θ̂_a), the
    whitening pre-filter (nav low-pass) of the compensated specific force, and the lever arm's regressors."""
    rec, a, t, layout = ses.rec, ses.a, ses.t, ses.layout
    ra, rb = ses.prep.rest_range
    m = gyro_axis_matrix(theta[theta_slice("gyro_scale")], theta[theta_slice("gyro_nonorth")],
                         sens0[15:18] if layout.models_misalignment else None)
    w = (rec.gyro_rad_s[a:] - theta[theta_slice("gyro_bias")]) @ np.linalg.inv(m).T
    # the accelerometer bias's temperature part at its nominal, c_a (T − T₀) (N, 3); zero without the block
    acc_temp = (np.outer(ses.thermal[0], sens0[9:12]) if layout.has("acc_temp_bias") else np.zeros((t.size, 3)))
    f0 = mi_a = None
    if ses.estimate:   # the rest attitude and P₀'s tilt–accelerometer terms at this pass's θ̂_a (pass 1: prepare's)
        th_rest = theta.copy()
        th_rest[theta_slice("acc_bias")] += sens0[9:12] * ses.dt_rest     # b_a at the rest's temperature
        q0, f0, mi_a = initial_attitude(rec, th_rest, ra, rb)
    th_a = acc_theta(theta)
    acc = compensate_acc(rec.acc_m_s2[a:] - acc_temp, th_a) if ses.estimate else rec.acc_m_s2[a:]
    q = integrate_gyro(t, w, q0)
    f_nav = quat_rotate(q, acc)
    f_lp = quat_rotate(quat_conjugate(q), ses.lowpass(f_nav))       # whitening pre-filter (nav low-pass)
    pr = ses.params
    kreg = lever_regressor(w, t, ses.fs, pr.cutoff_hz, pr.order)
    ljac = lever_jacobian(w, t, ses.fs, m, pr.cutoff_hz, pr.order, misalignment=layout.models_misalignment)
    # the kernel compensates at θ̂_a again
    f_kernel = f_lp @ m_matrix(th_a[3:6], th_a[6:9]).T + th_a[0:3] + acc_temp if ses.estimate else f_lp
    return _PassInputs(q0, f0, mi_a, f_lp, f_kernel, kreg, ljac, np.zeros(0), np.zeros(0), None)


def _fitted_sway(ses: _Session, f_lp: np.ndarray, kreg: np.ndarray, hand0: np.ndarray) -> _Sway:
    """The a_e model fitted to the previous pass's residual e = |f_lp − K r̂| − g (:mod:`calib.session.hand.sway`)."""
    cfg0 = ses.cfg0
    e = np.linalg.norm(f_lp - np.einsum("nij,j->ni", kreg, hand0[:3]), axis=1) - cfg0.gravity_m_s2
    if ses.layout.has(EXT_ACC_EXTRA_BLOCKS[0]):   # the band-limited sway (fit_band)
        band = fit_band(e, 1.0 / ses.fs, ses.sigma_f2 * ses.rho, 2.0 * cfg0.vrw_m_s2_sqrt_hz**2)
        sway = _Sway(band["floor_rms_m_s2"], band["floor_tau_s"], math.inf, 1, band)
    else:
        sway = _Sway(*fit_gauss_markov(e, 1.0 / ses.fs, ses.sigma_f2 * ses.rho, 2.0 * cfg0.vrw_m_s2_sqrt_hz**2))
    return replace(sway, sigma_s=max(sway.sigma_s, 1e-3 * math.sqrt(ses.r_var)))


def _with_prior(ses: _Session, inp: _PassInputs, p: int, cfg: FilterConfig, theta: np.ndarray, hand0: np.ndarray,
                sens0: np.ndarray) -> _PassInputs:
    """The pass's prior seen from its linearisation point: x₀ = θ_prior − θ̂ (S = G = 0, r = 0, the extra blocks 0,
    the accelerometer at the |f| = g fit) and P₀ with the rest's ties (:mod:`calib.session.hand.priors`)."""
    layout, rec, prep = ses.layout, ses.rec, ses.prep
    x0 = np.zeros(layout.n)
    x0[3:9] = -theta[0:6]                                     # prior S = G = 0 seen from the linearisation point
    x0[layout.offset("lever_arm"):layout.offset("lever_arm") + 3] = -hand0[:3]   # prior r = 0
    gfit = None
    if ses.estimate:   # the accelerometer's weak prior: the |f| = g fit (kf_session's) without the lever arm's K r̂,
        th_a = acc_theta(theta)
        gfit = prep.gravity_fit if p == 0 else gravity_fit_lever_free(rec, prep, ses.a, inp.kreg, hand0[:3], th_a)
        oa = layout.offset("acc_bias")
        x0[oa:oa + 9] = gfit.theta - th_a
        p0 = initial_covariance(layout, cfg, inp.q0, inp.f0, inp.mi_a, gfit.covariance * FIT_PRIOR_INFLATION, ses.tilt)
        acc_temp_tilt_prior(p0, layout, inp.q0, inp.mi_a, ses.dt_rest, cfg.gravity_m_s2)
    else:
        p0 = initial_covariance(layout, cfg, tilt_sigma_rad=ses.tilt)
    g_sensitivity_prior(p0, layout, ses.f_rest)               # no-ops without those blocks
    temp_bias_prior(p0, layout, ses.dt_rest)
    common_delay_prior(p0, layout)
    sensor_extra_prior(x0, layout, sens0)
    return replace(inp, x0=x0, p0=p0, gfit=gfit)


def _run(ses: _Session, inp: _PassInputs, cfg: FilterConfig, theta: np.ndarray, hand0: np.ndarray,
         sens0: np.ndarray, keep: bool, record: bool) -> FilterRun:
    """One run of the compiled filter over the session from ``prep.start``, linearised at θ̂, r̂ (a_e's nominal 0)."""
    layout, t, n = ses.layout, ses.t, ses.t.size
    h0 = np.concatenate([hand0[:3], np.zeros(9)])
    return run_filter(ses.rec.gyro_rad_s[None, ses.a:], inp.f_kernel[None], t, inp.q0[None], theta[None], inp.p0,
                      layout, cfg, ses.fs, r_var_per_sample=np.full(n, ses.r_var), update_mask=ses.upd,
                      rest_mask=ses.still, x0=inp.x0[None], lever_regressor=inp.kreg, lever_jacobian=inp.ljac,
                      hand0=h0, rows=ses.rows,
                      temperature_rel_c=None if not layout.models_temperature else ses.thermal[0],
                      specific_force_m_s2=inp.f_lp if layout.models_g_sensitivity else None, sensor0=sens0,
                      acc_rate_m_s3=np.gradient(inp.f_lp, t, axis=0) if layout.models_acc_delay else None,
                      keep_history=keep, record=record)


# ---------------------------------------------------------------------------------------------------------------------
# 3. the covariance


@dataclass(frozen=True)
class _Sigma:
    """How the reported covariance was built (:func:`_covariance`): P after the spectral correction and the model's,
    the innovations' inflation, the drift's mixture, the rest's bias, where S and b_a hold, the slow residual."""

    P: np.ndarray
    p_model: np.ndarray
    spectral: dict | None
    infl: Inflation
    ambiguity: dict | None
    rbias: object
    t_ref: np.ndarray
    t_ref_a: np.ndarray
    temperature: dict
    slow_resid: np.ndarray
    blocks: tuple[str, ...]


def _covariance(ses: _Session, fit: _Fit) -> tuple[np.ndarray, _Sigma]:
    """The reported covariance over the rest's bias, S, G (and the accelerometer's b, S, G): module docstring, step
    3."""
    rec, layout, out, cfg0, thermal = ses.rec, ses.layout, fit.out, ses.cfg0, ses.thermal
    P = p_model = out.p[0]
    spectral = None
    # P under the slow residual's own spectrum, not the fitted model's (calib.session.spectral), when the fitted a_e
    # carries more than the white noise per update (a hand seen; without one the model is R alone, whose σ the
    # ideal-hand cells validate, and what the residual shows beyond it is the filter's own estimation error: on the
    # independent generator without a hand it moved σ of G by up to ×1.2 at random); not for the band model's general
    # shaping filter (the adjoint follows the Gauss–Markov states), nor for a noise-free sensor (its S, G errors come
    # from the filter's linearisation, not from a_e: measured 7e-5 against the linear prediction's 1e-5) (the gate is
    # the last pass's record= in _passes: the record exists exactly when it applies) the slow residual, f_lp − K r̂
    # (N, 3, body) and e = |f_lp − K r̂| − g (attitude-free): the spectral σ's data and the hand-assumption check's
    # displacement data
    slow_f = fit.f_lp - np.einsum("nij,j->ni", fit.kreg, fit.hand0[:3])
    slow_resid = np.linalg.norm(slow_f, axis=1) - cfg0.gravity_m_s2
    if out.record is not None:
        pr = ses.params
        gain2 = (lambda f: lowpass_gain2(f, ses.fs, pr.cutoff_hz, pr.order)) if pr.prefilter_reference else None
        P, spectral = spectral_sigma(P, out, layout, fit.cfg, fit.f_lp, slow_f, slow_resid, fit.kreg, ses.fs, ses.dec,
                                     ses.r_var, ses.estimate, prefilter_gain2=gain2)
    refuse_confounded(P, layout)
    # one-sided (κ̂ applied only above its χ² 95 % quantile), as for every method: the two-sided factor
    # (_sandwich_factor) brought gyrosim's hand cells into their NEES band but, on the measured x-IMU3 hand-held
    # session, κ̂ = 0.027 shrank σ ×0.16 and left an "ok" G_y 19 σ from the factory calibration (3.2 σ one-sided)
    infl = innovation_inflation(out.whitened[0], ses.t[1:])
    blocks = ("gyro_scale", "gyro_nonorth") + (("acc_bias", "acc_scale", "acc_nonorth") if ses.estimate else ())
    # the covariance's order is the result's effects': the gyro's S, G (and its misalignment α), then the accelerometer
    rows = blocks[:2] + MISALIGN_BLOCKS * layout.models_misalignment + blocks[2:]
    idx = np.concatenate([np.arange(layout.offset(b), layout.offset(b) + 3) for b in rows])
    cov = np.zeros((3 + idx.size, 3 + idx.size))
    # the first rest's mean at its stated reference (time, temperature, specific force), σ without the hand's
    # rotation that cancels in the mean (calib.session.rest_bias); uncorrelated with the filter's states
    # N for the rest mean's σ: the 2–6 Hz density when that band is higher, roll-off found or not (cautious)
    wd_g = ses.prep.noise.gyro_white
    n_rest = max(cfg0.arw_rad_s_sqrt_hz, wd_g.rest_mean_density if wd_g is not None else 0.0)
    rbias = rest_bias(rec.gyro_rad_s, rec.t_s, ses.prep.rest_range, n_rest,
                      compensate_acc(rec.acc_m_s2, acc_theta(fit.theta)) if ses.estimate else rec.acc_m_s2, rec.temp_c)
    cov[:3, :3] = np.diag(rbias.std_rad_s**2)
    # the temperature block (thermal is not None): S is reported at the temperature the session pinned it best
    # (the temperatures where S and b_a decouple from their coefficients come from the filter's own P: the spectral
    # correction scales variances, not where the information lies — scaling S but not s_T moved T_r towards T₀ and
    # took S_z's RMS error on the MPU-9250's shaky hand from 9.6e-5 to 1.2e-4)
    t0 = thermal[1] if thermal is not None else float("nan")
    t_ref, jt = scale_at_temperature(p_model, layout, t0)
    jsel = np.zeros((idx.size, P.shape[0]))
    jsel[np.arange(idx.size), idx] = 1.0
    jsel[:6] = jt                                      # S (at T_r), G
    # the accelerometer's bias likewise at the temperatures T_a,i where b_a and c_a decouple (acc_temp_bias)
    t_ref_a, ja = acc_bias_at_temperature(p_model, layout, t0)
    if layout.has("acc_temp_bias"):
        ia = rows.index("acc_bias") * 3
        jsel[ia:ia + 3] = ja
    cov[3:, 3:] = (jsel @ P @ jsel.T) * infl.factor
    ambiguity = None
    if fit.out_const is not None:
        cov[3:, 3:], ambiguity = drift_ambiguity(cov[3:, 3:], jsel @ fit.out_const.p[0] @ jsel.T,
                                                 innovation_inflation(fit.out_const.whitened[0], ses.t[1:]))
    temperature = temperature_report(thermal, t_ref, fit.sens0, P, layout, infl.factor, t_ref_a)
    return cov, _Sigma(P, p_model, spectral, infl, ambiguity, rbias, t_ref, t_ref_a, temperature, slow_resid, blocks)


def _reported_theta(ses: _Session, fit: _Fit, sig: _Sigma) -> np.ndarray:
    """θ̂ with S at the temperatures T_r and b_a at T_a where the session pinned them (the temperature blocks)."""
    theta = fit.theta.copy()
    if ses.layout.has("gyro_temp_scale"):
        # S_i(T_r,i) = S_i(T₀) + s_T,i (T_r,i − T₀)
        theta[theta_slice("gyro_scale")] += fit.sens0[3:6] * (sig.t_ref - ses.thermal[1])
    if ses.layout.has("acc_temp_bias"):
        # b_a,i(T_a,i) = b_a,i(T₀) + c_a,i (T_a,i − T₀)
        theta[theta_slice("acc_bias")] += fit.sens0[9:12] * (sig.t_ref_a - ses.thermal[1])
    return theta


# ---------------------------------------------------------------------------------------------------------------------
# 4. the verdict and the result


def _checks(ses: _Session, fit: _Fit, cov: np.ndarray, sig: _Sigma, theta: np.ndarray) -> tuple[str, list, list[str]]:
    """The innovations' and the estimate's checks (and |f̂| = g at the rests with the accelerometer estimated), the
    verdict, the temperature note and the innovations' inflation: (status, checks, notes)."""
    rec, prep, cfg0 = ses.rec, ses.prep, ses.cfg0
    values = {BLOCK_LABELS[b]: theta[theta_slice(b)] for b in sig.blocks}
    checks = [check_innovations(fit.out.nis[0][ses.upd[1:]], ses.rows, ses.fs / ses.dec),
              check_estimate(values, cov, cfg0.gravity_m_s2)]
    if ses.estimate:   # |f̂| = g at the rests, as calib run's joint filter checks its accelerometer
        acc_all = rec.acc_m_s2
        if ses.layout.has("acc_temp_bias"):   # b_a(T(t)) = b_a(T_a) + c_a (T(t) − T_a): the rests sit at other T
            acc_all = acc_all - (smoothed_temperature(rec.temp_c, ses.fs)[:, None] - sig.t_ref_a[None, :]) * fit.sens0[
                9:12]
        f_hat = compensate_acc(acc_all, acc_theta(theta))
        checks.append(rest_gravity(f_hat, rec.t_s, prep.rest.index_ranges, cfg0.gravity_m_s2,
                                   math.sqrt(prep.config.r_var(ses.fs))))
    status, notes = verdict(checks[0], checks[1], checks[2] if ses.estimate else None, ses.accelerometer,
                            hand_aware=True, noise_free=prep.noise.noise_free)
    if ses.thermal is not None:
        notes = notes + [sig.temperature["note"]]
    status = apply_inflation(status, notes, sig.infl, can_fail=not prep.noise.noise_free, hand_aware=True,
                             accelerometer=ses.accelerometer)
    if prep.noise.noise_free and status != "ok":
        # noise-free input: the innovations are the gyro integration's deterministic error, which the
        # floor-level noise cannot cover (measured on the independent generator at 100 Hz: error 2.4e-6,
        # 5.8 σ) — refused, but the advice about a hand's acceleration would mislead, so say what it is
        notes.append("noise-free input: the sensor noise at rest sits at its numerical floor, so σ comes from that "
                     "floor "
                     "and does not cover the estimate's discretisation error (the rate integration of the motion, "
                     "typically ~1e-6 in S, G at 100 Hz): the estimate is close but its σ is not honest, hence "
                     f"'{status}'. Real data has noise; for a simulated check compare against the truth directly")
    return status, checks, notes


def _drift_notes(ses: _Session, fit: _Fit, sig: _Sigma) -> list[str]:
    """What the user should know about the gyro bias's drift the rests showed (none when they agreed)."""
    drift, qb_factor = ses.drift, fit.qb_factor
    if drift.q_rad2_s3 <= 0:
        return []
    modelled = (
        f"modelled as the bias's temperature coefficient c_b (diagnostics.temperature) and a random walk of "
        f"{math.sqrt(qb_factor) * drift.rrw_rad_s_sqrt_s:.2e} rad/s/√s ({qb_factor:g} × the rests' q_b for what "
        "c_b leaves: ½ unless the innovations reject it)"
        if ses.layout.has("gyro_temp_bias")
        else f"modelled as a random walk of {drift.rrw_rad_s_sqrt_s:.2e} rad/s/√s (from the rests, bias_drift)"
    )
    notes = [f"gyro bias drift: the rests' bias moved beyond their noise (χ² {drift.chi2:.0f} on {drift.dof}, "
             f"95 % bound {drift.threshold:.1f}); {modelled}; a longer warm-up before the session or a "
             "temperature-stable sensor gives a smaller σ"]
    if sig.ambiguity is not None:
        notes.append("gyro bias drift without a temperature change: the two rests cannot tell a random walk from "
                     "a bias-instability (flicker) floor, which moves the bias more inside the session; σ of the "
                     "reported parameters is the two models' mixture (× up to "
                     f"{max(sig.ambiguity['sigma_factor']):.2f} on the random walk's alone)")
    elif ses.thermal is None:
        notes.append("gyro bias drift and no temperature channel: a warm-up (a ramp, which the random walk covers) "
                     "cannot be told from a warmed-up gyro's bias-instability floor, under which σ of S, G is "
                     "~15 % small (measured on a warmed-up MPU-9250); record the temperature — a flat one lets the "
                     "filter model the floor")
    if ses.estimate and ses.thermal is None:
        # the drift is most often a warming board, whose accelerometer bias drifts too, and without a
        # temperature channel no state models that (measured on the MPU-9250 preset with its channel removed:
        # σ of S, G ~1.2× small, NEES(6) 8.3 ideal hand; docs/hand.md)
        notes.append("accelerometer bias drift not modelled: the gyro bias drifted (a warming sensor?) and the "
                     "recording has no temperature channel (or it moved < "
                     f"{THERMAL_MIN_SPAN_C} °C), so the accelerometer bias is taken as constant; if the board was "
                     "warming, σ of S, G may be ~20 % small — record the temperature (kf_hand_joint then models "
                     "b_a(T)) or warm the sensor up first")
    return notes


def _hand(ses: _Session, fit: _Fit, cov: np.ndarray, sig: _Sigma, tremor: _Tremor) -> tuple[dict, object, str]:
    """``diagnostics["hand"]``, the check of kf_hand's assumptions on this recording, and the note for the user."""
    rec, layout, sw, cfg = ses.rec, ses.layout, fit.sway, fit.cfg
    ol = layout.offset("lever_arm")
    r_hat = fit.hand0[:3]
    # the lever arm's σ: its information sits at the turns' ω̇ and ω² (0.1–1 Hz, inside the sway band, where the
    # fitted model understates the power), above the < 0.125 Hz that κ̂'s 4-s blocks measure; the same one-sided
    # test on LEVER_INFLATION_BLOCK_S blocks (< 0.5 Hz) measures the innovations' excess there, and σ_r takes the
    # larger factor (independent generator, 20 sessions: err/σ RMS per axis 1.29, 1.31, 1.06 → 1.13, 1.20, 0.91,
    # pooled 1.23 → 1.09 against the 95 % band [0.82, 1.18]; 2-s blocks 1.28, 1.29, 0.99). Deflating by κ̂ < 1
    # made it more optimistic (10 sessions: err/σ RMS 1.4–1.7 per axis against 1.3–1.5 one-sided)
    infl_r = innovation_inflation(fit.out.whitened[0], ses.t[1:], block_s=LEVER_INFLATION_BLOCK_S)
    r_sd = np.sqrt(np.diag(sig.P[ol:ol + 3, ol:ol + 3]) * max(sig.infl.factor, infl_r.factor))
    # kf_hand's own assumptions on this recording (calibrated accelerometer, a hand's tremor and lever arm)
    assumptions = check_hand_assumptions(rec.acc_m_s2, rec.t_s, ses.prep.rest.index_ranges,
                                         np.sqrt(np.diag(cov[3:9, 3:9])), tremor.rms, r_hat, r_sd,
                                         check_accelerometer=not ses.estimate, slow_residual_m_s2=sig.slow_resid,
                                         slow_residual_t_s=ses.t, rate_hz=ses.fs,
                                         accelerometer_source=ses.params.accelerometer_source,
                                         acc_noise_density_m_s2_sqrt_hz=ses.prep.noise.acc_density_m_s2_sqrt_hz)
    hand = {
        "lever_arm_m": r_hat.tolist(),
        "lever_arm_std_m": r_sd.tolist(),
        "lever_arm_sigma_inflation": {
            **infl_r.to_dict(),
            "block_s": LEVER_INFLATION_BLOCK_S,
            "covariance_factor": max(sig.infl.factor, infl_r.factor),
        },
        "external_acc_psd": {
            "model": "a_e = a first-order Gauss–Markov x (rms_m_s2, tau_s) per nav axis after the tremor "
            "low-pass, high-passed (highpass_tau_s, highpass_order m; null: none): "
            "one-sided PSD 4σ²τ/(1 + (2πfτ)²)·[(2πfτ_h)²/(1 + (2πfτ_h)²)]^m",
            "rms_m_s2": sw.sigma_s,
            "tau_s": sw.tau,
            "highpass_tau_s": sw.tau_hp if math.isfinite(sw.tau_hp) else None,
            "highpass_order": sw.hp_order,
            "acc_rms_m_s2": cfg.ext_acc_rms_a_m_s2,
            "psd_one_sided_0hz_m2_s4_per_hz": 4 * sw.sigma_s**2 * sw.tau if not math.isfinite(sw.tau_hp) else 0.0,
            "tremor_band_rms_m_s2": tremor.rms,
            "tremor_band_resolution_m_s2": tremor.resolution,
            "tremor_band_resolved": tremor.resolved,
            "lowpass_hz": ses.params.cutoff_hz,
            "update_every_samples": ses.dec,
            **band_report(sw.band),
        },
    }
    note = (f"hand: lever arm r̂ = {np.array2string(r_hat * 100, precision=1)} ± "
            f"{np.array2string(r_sd * 100, precision=1)} cm (body); slow external acceleration "
            f"{cfg.ext_acc_rms_a_m_s2:.3f} m/s² RMS (τ {sw.tau:.2f} s, high-pass "
            f"{'none' if not math.isfinite(sw.tau_hp) else f'order {sw.hp_order}, {sw.tau_hp:.1f} s'}); "
            + (f"tremor-band acceleration {tremor.rms:.3f} m/s² RMS removed" if tremor.resolved else
               f"tremor-band acceleration not resolved: {tremor.rms:.3f} m/s² RMS is within what the sensor's "
               f"noise, measured on the first rest, leaves uncertain ({tremor.resolution:.3f} m/s²)"))
    return hand, assumptions, note


def _status_and_notes(ses: _Session, fit: _Fit, cov: np.ndarray, sig: _Sigma, theta: np.ndarray,
                      tremor: _Tremor) -> tuple[str, list, list[str], dict, object, dict | None]:
    """The verdict and every note for the user, in the order they are printed: (status, checks, notes, hand
    diagnostics, assumptions, delay report)."""
    status, checks, notes = _checks(ses, fit, cov, sig, theta)
    notes.extend(_drift_notes(ses, fit, sig))
    dly = delay_report(fit.sens0, sig.P, ses.layout, sig.infl.factor) if ses.layout.models_acc_delay else None
    if dly is not None:
        notes.append(
            f"timing: the accelerometer samples {dly['delay_s'] * 1e3:+.2f} ± {dly['std_s'] * 1e3:.2f} ms after the "
            "gyro "
            "(estimated; negative: before) — a skew between the triads or their low-pass filters' different delays, "
            "modelled so that it does not enter S and G"
        )
    hand, assumptions, hand_note = _hand(ses, fit, cov, sig, tremor)
    notes.extend(assumptions.warnings)
    notes.extend(ses.rolloff_notes)
    if not assumptions.trustworthy and status == "ok":
        status = "inconsistent"
    if ses.params.sway == "band" and status == "ok":
        # the band-limited sway model is a research variant: on the independent generator's noise-free sensor
        # (tests/session/test_hand_sway_model.py, slow) its σ was 3–5× small with every seed passing its checks
        # (ΣNEES 379 over 10 seeds, χ²₆₀ 99.9 % bound 102.7) — a wrong answer must not exit 0, so it never says ok
        status = "inconsistent"
        notes.append("experimental sway model (sway='band', kf_hand_band): its σ failed the independent generator's "
                     "consistency test (3–5× small on a noise-free sensor with a line-spectrum sway; docs/hand.md, "
                     "'A band-limited sway model'), so its result is never 'ok'. Use kf_hand (calib run --method "
                     "kf_hand) for an answer whose σ has been validated")
    if sig.spectral is not None:
        fsg = [v for k, v in sig.spectral["sigma_factor"].items() if k.startswith(("gyro_scale", "gyro_nonorth"))]
        notes.append(f"σ of S, G follows the slow residual's own spectrum, not the fitted a_e model's: ×{min(fsg):.2f}–"
                     f"{max(fsg):.2f} (the model's shape and its aliasing at the updates; calib.session.spectral, "
                     "diagnostics.consistency.spectral_covariance)")
    notes.append(hand_note)
    return status, checks, notes, hand, assumptions, dly


def _calibration(ses: _Session, fit: _Fit, cov: np.ndarray, sig: _Sigma, tremor: _Tremor,
                 keep_history: bool) -> Calibration:
    """The result (module docstring, step 4)."""
    rec, layout, cfg0, prep = ses.rec, ses.layout, ses.cfg0, ses.prep
    alpha = fit.sens0[15:18] if layout.models_misalignment else None   # the gyro's rotation against the accelerometer
    m_final = gyro_axis_matrix(fit.theta[theta_slice("gyro_scale")], fit.theta[theta_slice("gyro_nonorth")], alpha)
    rate_ref = scale_reference_rate((rec.gyro_rad_s[ses.a:] - fit.theta[theta_slice("gyro_bias")])
                                    @ np.linalg.inv(m_final).T)
    # the accelerometer's S likewise at the specific force its updates saw (the compensated, low-passed f̂ there)
    force_ref = acc_scale_reference_force(fit.f_lp[ses.upd]) if ses.estimate else None
    theta = _reported_theta(ses, fit, sig)
    status, checks, notes, hand, assumptions, dly = _status_and_notes(ses, fit, cov, sig, theta, tremor)
    gyro = {"bias": sig.rbias.value_rad_s, "scale_factor": theta[theta_slice("gyro_scale")],
            "nonorthogonality": np.clip(np.nan_to_num(theta[theta_slice("gyro_nonorth")]), -0.45, 0.45)}
    acc_params = None
    if ses.estimate:   # the accelerometer's parameters as calib run's joint filter reports them
        acc_params = {"bias": theta[theta_slice("acc_bias")], "scale_factor": theta[theta_slice("acc_scale")],
                      "nonorthogonality": np.clip(np.nan_to_num(theta[theta_slice("acc_nonorth")]), -0.45, 0.45)}
    effects = Calibration.from_linear(gyro=gyro, accelerometer=acc_params)   # the linear model's effects
    extra = () if alpha is None else (GyroAccMisalignment(value=alpha.copy()),)   # after G: _covariance's order
    cal = Calibration(
        gyro=effects.gyro + extra, accelerometer=effects.accelerometer, covariance=cov, status=status,
        warnings=prep.warnings + fit.obs_notes + tuple(notes), method=REGISTERED_NAME[ses.accelerometer],
        diagnostics=_diagnostics(ses, fit, sig, checks, hand, assumptions, dly, rate_ref, force_ref))
    if keep_history:   # the last pass's √P, θ̂, innovations and NIS per step (calib run --rrd shows P converge)
        out = fit.out
        cal = replace(cal, history=FilterHistory(rec.t_s[ses.a + 1:], out.sd_history[0], out.theta_history[0],
                                                 out.innovation[0], out.nis[0], layout.names))
    if ses.estimate:   # the noise densities among the effects too, as calib run's joint filter (calib export reads)
        cal = replace(cal, gyro=cal.gyro + (WhiteNoise(density=np.full(3, cfg0.arw_rad_s_sqrt_hz)),),
                      accelerometer=cal.accelerometer + (WhiteNoise(density=np.full(3, cfg0.vrw_m_s2_sqrt_hz)),))
    return cal


def _diagnostics(ses: _Session, fit: _Fit, sig: _Sigma, checks: list, hand: dict, assumptions, dly: dict | None,
                 rate_ref: dict, force_ref: dict | None) -> dict:
    """``Calibration.diagnostics`` of kf_hand (the JSON keys users read)."""
    rec, layout, cfg0, prep, infl = ses.rec, ses.layout, ses.cfg0, ses.prep, sig.infl
    wd_g, wd_a = prep.noise.gyro_white, prep.noise.acc_white
    extra: dict = {}
    if ses.estimate:
        gf = fit.gfit   # the last pass's prior (lever-arm-free from pass 2 on)
        extra = {"accelerometer_mode": "estimate", "rest_gravity": checks[2].to_dict(),
                 "gravity_fit": {"bias_m_s2": gf.bias_m_s2, "scale_factor": gf.scale_factor,
                                 "nonorthogonality": gf.nonorthogonality, "std": np.sqrt(np.diag(gf.covariance)),
                                 "residual_rms_m_s2": gf.residual_rms_m_s2, "samples": gf.samples}}
    return {
        "hand": hand,
        "consistency": {
            **checks[0].to_dict(),
            "sigma_inflation": {**infl.to_dict(), "covariance_factor": infl.factor, "sigma_factor": infl.sigma_factor,
                                "applied": "one-sided"},
            "spectral_covariance": sig.spectral,
        },
        "noise": {
            "arw_rad_s_sqrt_hz": cfg0.arw_rad_s_sqrt_hz,
            "vrw_m_s2_sqrt_hz": cfg0.vrw_m_s2_sqrt_hz,
            # the hand-blind filters' R allowance (calib run's JSON key): none here, a_e is modelled (diagnostics.hand)
            "external_acc_allowance_m_s2": 0.0,
            "gravity_m_s2": cfg0.gravity_m_s2,
            # the rest's spectrum: the density above the tremor and at 2–6 Hz, and whether an output low-pass rolled
            # it off
            "gyro_white_density_check": wd_g.to_dict() if wd_g else None,
            "acc_white_density_check": wd_a.to_dict() if wd_a else None,
        },
        "rest_segments": prep.rest.to_list(),
        "gyro_bias_drift": {
            **ses.drift.to_dict(),
            # the random walk the last pass used: q_b × this
            "random_walk_factor_used": fit.qb_factor,
            **({"constant_bias_check": sig.ambiguity} if sig.ambiguity is not None else {}),
        },
        "gyro_bias": sig.rbias.to_dict(),
        "temperature": {k: v for k, v in sig.temperature.items() if k != "note"},
        "scale_reference_rate": rate_ref,
        **({"acc_scale_reference_force": force_ref} if force_ref is not None else {}),
        **(
            {"gyro_g_sensitivity": g_sensitivity_report(fit.sens0, sig.P, layout, infl.factor)}
            if layout.models_g_sensitivity
            else {}
        ),
        **({"acc_delay": dly} if dly is not None else {}),
        "assumptions": assumptions.to_dict(),
        **extra,
        "filter": {
            "states": list(layout.names),
            "passes": ses.params.passes,
            "samples": int(ses.t.size),
            "rate_hz": ses.fs,
            "start_s": float(rec.t_s[ses.a]),
        },
    }
