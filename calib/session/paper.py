"""calibrate(): one hand-held session → a :class:`~gyrosim.calibration.Calibration` of the gyro and,
by default, the accelerometer.

**Method** (``accelerometer="estimate"``, the default): one augmented error-state filter,
Zhou 2020's 9 states plus the gyro bias and the accelerometer's bias, scale factor and
non-orthogonality (21 states, equations in :mod:`calib.session.model`).  Why this and not a separate
multi-position accelerometer calibration feeding Zhou's filter:

* |f| = g (Ferraris 1995, Tedaldi 2014) needs ≥ 9 well-spread rest poses; Zhou's own Table 6 session
  rests in two.  In the filter the gyro carries the attitude between poses, so every quasi-static
  sample of every rotation tells the filter where gravity is *and* what the accelerometer read
  there: gravity sweeps each body plane during the rotations, and all 21 states are observable
  from the zhou2020 schedule (checked per session, below);
* the gyro and accelerometer errors are estimated *jointly*, so their correlations (an
  accelerometer bias tilts the gravity reference exactly like an attitude error) are in the
  covariance, and σ stays honest for both (Monte Carlo in docs/real_imu.md);
* the same structure takes further states (a lever arm, coloured external acceleration):
  a block of :class:`calib.session.model.StateLayout`, its F/H columns and its prior.

A Tedaldi-style |f| = g fit over the session's quasi-static windows (:mod:`calib.session.gravityfit`) runs
first; it is not the answer but the filter's starting point (linearisation), the source of the
external-acceleration allowance (the residual |f̂| − g after it) and of the pose advice.
``accelerometer="calibrated"`` is the paper's 9-state filter with the static bias (Zhou §3.3.2
assumes a calibrated accelerometer), today's behaviour.

**Steps.**

1. input checks (gaps, units, saturation: :mod:`calib.inputs`);
2. rest detection and the static gyro bias (Zhou §3.2, :mod:`calib.session.rest`);
3. noise levels from the first rest segment with floors (:mod:`calib.session.noiselevels`) — never from a
   simulator's stored sensor model;  gravity: ``gravity_m_s2`` (default standard gravity
   9.80665 m/s² when the accelerometer is estimated: the scale factors are relative to it, so a
   local g off by 0.1 % shifts S_a by 0.1 %; with a calibrated accelerometer the mean |f| at rest);
4. the |f| = g fit (estimate mode) and the initial attitude from gravity at rest (roll, pitch;
   heading unobservable, set to 0), P₀ with the tilt's dependence on the accelerometer errors;
5. external-acceleration allowance a_ext, unless given: the larger of the accelerometer's rest
   variance beyond its white noise and √(3 (⟨(|f̂| − g)²⟩ − σ_f²)) over the session (|f| − g sees only
   the component of the external acceleration along gravity, a third of an isotropic one's variance);
6. the filter (compiled, :func:`calib.session.kernel.run_filter`): ``kf_session`` one pass, ``iterated_session``
   three, each re-linearised at the previous pass's estimate with the prior kept where it was (the prior mean
   enters as the initial error state x₀ = θ_prior − θ̂: Gauss–Newton on the batch posterior);
7. observability from the filter's own information (:func:`calib.session.observability.joint_observability`):
   gyro combinations the motion left undetermined are named in ``warnings``; an accelerometer that
   this session cannot separate from the gyro errors is an error naming the parameters and the rest
   poses to add;
8. the verdict (:mod:`calib.session.consistency`): ``status`` ok / diverged / inconsistent, with warnings
   saying what to try.

**Names.** One name per algorithm, the same in ``calib run``, campaigns and Monte Carlo: this
function's filter, with its session-wide external-acceleration allowance (step 5), is ``kf_session``
(``iterated_session``: three passes), and its result is labelled with the registered estimator that
runs it (:data:`REGISTERED_NAME`: ``kf_joint``, ``iterated_joint`` with the accelerometer estimated;
``kf_session_r``, ``iterated_session_r`` with it calibrated).  ``kf`` is the paper's filter (R from the
accelerometer noise alone, :func:`calib.session.registry.kf`), which this function does not run; the former
spellings ``calibrate(rec, "kf")`` / ``"iterated"`` still work and warn (DeprecationWarning).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from warnings import warn

import numpy as np

from gyrosim.calibration import Calibration, truth_calibration
from gyrosim.effects import Bias, NonOrthogonality, ScaleFactor, WhiteNoise
from gyrosim.errors import RecordingError
from gyrosim.recording import Recording
from gyrosim.rotations import quat_from_two_vectors
from gyrosim.units import G0

from calib.inputs import KF, check_recording
from calib.session.consistency import (
    FixedParameterEffect,
    apply_inflation,
    check_estimate,
    check_innovations,
    fixed_parameter_effect,
    innovation_inflation,
    rest_gravity,
    verdict,
)
from calib.session.gravityfit import GravityFit, compensate_acc, fit_gravity, quasi_static_windows
from calib.session.kernel import FilterRun, regressor_half_window, run_filter
from calib.session.model import (
    BLOCK_LABELS,
    JOINT,
    PAPER,
    FilterConfig,
    FilterHistory,
    StateLayout,
    initial_covariance,
    leave_out_means,
    m_matrix,
    theta_slice,
)
from calib.session.noiselevels import NoiseLevels, estimate_noise
from calib.session.observability import JointObservability, joint_observability, missing_poses
from calib.session.reference import ZhouFilter
from calib.session.rest import BiasEstimate, RestSegments, detect_rest, static_bias
from calib.session.rest_bias import RestBias, rest_bias

__all__ = ["calibrate", "prepare", "Prepared", "METHODS", "ACCELEROMETER_MODES", "REGISTERED_NAME", "resolve_method",
           "true_gyro_parameters"]

METHODS = ("kf_session", "iterated_session")
ACCELEROMETER_MODES = ("estimate", "calibrated")
ENGINES = ("compiled", "filterpy")
# the former spellings: "kf" now names the paper's filter everywhere (registered ``kf``: R from the
# accelerometer noise only), which this function never ran; accepted here with a DeprecationWarning
DEPRECATED_METHODS = {"kf": "kf_session", "iterated": "iterated_session"}
# the registered estimator name (``gyrosim.estimators``) of each (method, accelerometer) pair: the
# label a result carries, the same in ``calib run``, a campaign and a Monte Carlo
REGISTERED_NAME = {
    ("kf_session", "estimate"): "kf_joint",
    ("iterated_session", "estimate"): "iterated_joint",
    ("kf_session", "calibrated"): "kf_session_r",
    ("iterated_session", "calibrated"): "iterated_session_r",
}


def resolve_method(method: str, *, stacklevel: int = 3) -> str:
    """``method`` as one of :data:`METHODS`; a deprecated spelling warns (DeprecationWarning) and maps."""
    if method in DEPRECATED_METHODS:
        new = DEPRECATED_METHODS[method]
        warn(f"method {method!r} is deprecated: this filter (session-wide external-acceleration "
                      f"allowance) is {new!r}; 'kf' names the paper's filter (R from the accelerometer noise "
                      "only) in every command", DeprecationWarning, stacklevel=stacklevel)
        return new
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; use one of {', '.join(METHODS)}")
    return method


@dataclass(frozen=True)
class Prepared:
    """Everything the filter needs from a recording, before it runs (steps 1–5)."""

    bias: BiasEstimate
    rest: RestSegments
    noise: NoiseLevels
    config: FilterConfig
    layout: StateLayout
    quat0_nb: np.ndarray
    theta0: np.ndarray
    p0: np.ndarray
    start: int
    saturated: np.ndarray | None
    warnings: tuple[str, ...]
    gravity_fit: GravityFit | None
    windows_f_hat: np.ndarray | None
    bias_std_rad_s: np.ndarray
    rest_range: tuple[int, int] = (0, 0)
    # the first rest's mean at its stated reference with σ = white noise ⊕ the hand's rotation
    # (calib.session.rest_bias); bias_std_rad_s is its σ
    rest_bias: RestBias | None = None
    bias_batch_std_rad_s: np.ndarray | None = None

    @property
    def accelerometer(self) -> str:
        return "estimate" if self.layout.estimates_accelerometer else "calibrated"


def _allowance(rec: Recording, theta_a: np.ndarray | None, a: int, b: int, g: float, sigma_f2: float) -> float:
    """a_ext (m/s² RMS, step 5): √max(rest excess, 3 (⟨(|f̂| − g)²⟩ − σ_f²), 0) over the session from ``a``."""
    f_hat = rec.acc_m_s2 if theta_a is None else compensate_acc(rec.acc_m_s2, theta_a)
    rest_excess = float(np.mean(np.var(rec.acc_m_s2[a:b], axis=0))) - sigma_f2
    along_g = float(np.mean((np.linalg.norm(f_hat[a:], axis=1) - g - sigma_f2 / g) ** 2)) - sigma_f2
    return math.sqrt(max(rest_excess, 3.0 * along_g, 0.0))


def _tilt_sigma(rec: Recording, a: int, b: int, g: float) -> float:
    """σ (rad) of roll and pitch from the accelerometer's mean over the rest [a, b): its standard
    error from 10 batch means (honest when tremor correlates the samples) over g."""
    means = np.array([m.mean(axis=0) for m in np.array_split(rec.acc_m_s2[a:b], 10)])
    return float(np.mean(means.std(axis=0, ddof=1)) / math.sqrt(10) / g) + 1e-9


def _initial_attitude(rec: Recording, theta: np.ndarray, a: int, b: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """q₀ (body→ENU, heading 0) from the compensated accelerometer mean over the rest [a, b), that
    mean f̂₀ and M̂_a⁻¹."""
    th_a = np.concatenate([theta[theta_slice("acc_bias")], theta[theta_slice("acc_scale")],
                           theta[theta_slice("acc_nonorth")]])
    f0 = compensate_acc(rec.acc_m_s2[a:b], th_a).mean(axis=0)
    q0 = quat_from_two_vectors(f0, np.array([0.0, 0.0, 1.0]))
    return q0, f0, np.linalg.inv(m_matrix(th_a[3:6], th_a[6:9]))


def prepare(
    rec: Recording,
    *,
    accelerometer: str = "estimate",
    external_acc_allowance_m_s2: float | None = None,
    arw_rad_s_sqrt_hz: float | None = None,
    vrw_m_s2_sqrt_hz: float | None = None,
    gravity_m_s2: float | None = None,
    min_rest_s: float = 2.0,
) -> Prepared:
    """Steps 1–5 of the module docstring: checks, rest, bias, noise levels, |f| = g fit, allowance, P₀."""
    if accelerometer not in ACCELEROMETER_MODES:
        raise ValueError(f"accelerometer must be one of {ACCELEROMETER_MODES}, got {accelerometer!r}")
    estimate = accelerometer == "estimate"
    check = check_recording(rec, requirements=KF)
    rest = detect_rest(rec)
    bias = static_bias(rec, rest, min_rest_s=min_rest_s)
    a, b = bias.index_range
    fs = rec.rate_hz
    g = gravity_m_s2 or (G0 if estimate else float(np.mean(np.linalg.norm(rec.acc_m_s2[a:b], axis=1))))
    noise = estimate_noise(rec.gyro_rad_s, rec.acc_m_s2, (a, b), fs, g)
    arw = arw_rad_s_sqrt_hz or noise.arw_rad_s_sqrt_hz
    vrw = vrw_m_s2_sqrt_hz or noise.vrw_m_s2_sqrt_hz
    sigma_f2 = vrw**2 * fs
    warnings = list(check.warnings) + noise.notes()
    # the bias's σ: white noise over the rest ⊕ the hand's rotation during it, which the 10 batch means of
    # static_bias count as noise although it cancels in the whole mean (calib.session.rest_bias; measured: the batch
    # means' σ was 4–14× too large with a hand). Its reference (time, temperature, specific force) is finished
    # below, once the accelerometer's calibration is known.
    # N_g from the rest's spectrum above the tremor band (a hand's tremor is not sensor noise), else the spread
    # (at 2–6 Hz when that band is higher: an output low-pass, or a hand's motion that averages out of the mean)
    wd = noise.gyro_white
    n_g = (wd.rest_mean_density if wd is not None else 0.0) or arw    # 0 (noise-free): the floored σ
    rbias = rest_bias(rec.gyro_rad_s, rec.t_s, (a, b), n_g, rec.acc_m_s2, rec.temp_c)
    bias_std = rbias.std_rad_s
    # the 10 batch means' standard error (floored at the white noise): the prior kf_hand's random-walk bias state
    # still starts from (measured on the x-IMU3 hand-held recording: the honest σ above moves its lever arm
    # 5.3 → 2.8 ± 1.5 cm; not yet understood, so kf_hand keeps this prior)
    batch_std = np.maximum(bias.std_rad_s, arw * math.sqrt(fs) / math.sqrt(b - a))
    layout = JOINT if estimate else PAPER
    base = FilterConfig(arw, vrw, 0.0, gravity_m_s2=g, prior_gyro_bias_rad_s=tuple(bias_std))
    theta0 = np.zeros(18)
    theta0[theta_slice("gyro_bias")] = bias.value_rad_s
    gfit, f_windows = None, None
    if estimate:
        f = rec.acc_m_s2[a:]
        f_reg = leave_out_means(f, regressor_half_window(fs), midpoint=False)
        prior = np.concatenate([base.prior_sigma("acc_bias"), base.prior_sigma("acc_scale"),
                                base.prior_sigma("acc_nonorth")])
        gfit = fit_gravity(f, f_reg, sigma_f2, sigma_f2, g, prior)
        if external_acc_allowance_m_s2 is None:
            external_acc_allowance_m_s2 = _allowance(rec, gfit.theta, a, b, g, sigma_f2)
        if external_acc_allowance_m_s2 > 0:  # refit with the hand's allowance in the weights (honest P_a)
            gfit = fit_gravity(f, f_reg, sigma_f2 + external_acc_allowance_m_s2**2, sigma_f2, g, prior, gfit.theta)
        theta0[theta_slice("acc_bias")] = gfit.bias_m_s2
        theta0[theta_slice("acc_scale")] = gfit.scale_factor
        theta0[theta_slice("acc_nonorth")] = gfit.nonorthogonality
        wins, _ = quasi_static_windows(f, fs, 0.1)
        f_windows = compensate_acc(wins, gfit.theta)
        rbias = replace(rbias, specific_force_m_s2=compensate_acc(rec.acc_m_s2[a:b], gfit.theta).mean(axis=0))
    elif external_acc_allowance_m_s2 is None:
        external_acc_allowance_m_s2 = _allowance(rec, None, a, b, g, sigma_f2)
    config = FilterConfig(arw, vrw, external_acc_allowance_m_s2, gravity_m_s2=g, prior_gyro_bias_rad_s=tuple(bias_std))
    q0, f0, mi_a = _initial_attitude(rec, theta0, a, b)
    tilt = _tilt_sigma(rec, a, b, g) if estimate else None
    p0 = initial_covariance(layout, config, q0, f0, mi_a, None if gfit is None else gfit.covariance, tilt)
    saturated = check.excluded if check.excluded_samples else None  # at a rail, bridged or spike-repaired
    # with the gyro bias a state the filter starts after the rest that gave its prior: the same gyro
    # samples would otherwise inform the bias twice (the static average, and the tilt drift at rest)
    start = b - 1 if estimate else a
    return Prepared(bias, rest, noise, config, layout, q0, theta0, p0, start, saturated, tuple(warnings), gfit,
                    f_windows, bias_std, (a, b), rbias, batch_std)


def rest_mask(prep: Prepared, n: int) -> np.ndarray:
    """(n,) True at the steps k−1 → k that lie inside a detected rest segment (samples from ``start``)."""
    mask = np.zeros(n, dtype=bool)
    for a, b in prep.rest.index_ranges:
        lo, hi = max(a - prep.start + 1, 0), min(b - prep.start, n)
        if hi > lo:
            mask[lo:hi] = True
    return mask


def _run_reference(prep: Prepared, rec: Recording, theta0: np.ndarray, q0: np.ndarray, p0: np.ndarray,
                   mask: np.ndarray | None, x0: np.ndarray | None = None) -> FilterRun:
    """The filterpy filter (:class:`calib.session.reference.ZhouFilter`) over the session, as a FilterRun."""
    a, fs = prep.start, rec.rate_hz
    g, acc, t = rec.gyro_rad_s[a:], rec.acc_m_s2[a:], rec.t_s[a:]
    greg = leave_out_means(g, regressor_half_window(fs), midpoint=True)
    still = rest_mask(prep, t.size)
    filt = ZhouFilter(prep.config, q0, fs, prep.layout, theta0, p0, x0)
    for k in range(1, t.size):
        filt.step(float(t[k]), float(t[k] - t[k - 1]), g[k - 1], g[k], acc[k], update=mask is None or bool(mask[k]),
                  w_reg=greg[k], still=bool(still[k]))
    h = filt.history
    return FilterRun(prep.layout, filt.theta[None].copy(), np.asarray(filt.kf.P)[None].copy(), filt.quat[None],
                     h.nis[None], h.innovation[None], h.sd[None], h.theta[None], whitened=filt.whitened[None])


def prior_offset(prep: Prepared, theta: np.ndarray) -> np.ndarray:
    """x₀ = θ_prior − θ̂ over the layout's states: the prior mean seen from the linearisation point θ̂
    (the prior is the first pass's: S, G = 0, the static gyro bias, the |f| = g fit)."""
    x0 = np.zeros(prep.layout.n)
    for blk in prep.layout.blocks[1:]:
        o = prep.layout.offset(blk)
        x0[o:o + 3] = prep.theta0[theta_slice(blk)] - theta[theta_slice(blk)]
    return x0


def _run(prep: Prepared, rec: Recording, theta0: np.ndarray, q0: np.ndarray, p0: np.ndarray, engine: str,
         keep_history: bool) -> FilterRun:
    a, fs = prep.start, rec.rate_hz
    mask = None if prep.saturated is None else ~prep.saturated[a:]
    x0 = prior_offset(prep, theta0)
    if engine == "filterpy":
        return _run_reference(prep, rec, theta0, q0, p0, mask, x0)
    return run_filter(rec.gyro_rad_s[None, a:], rec.acc_m_s2[None, a:], rec.t_s[a:], q0[None], theta0[None], p0,
                      prep.layout, prep.config, fs, update_mask=mask, keep_history=keep_history,
                      rest_mask=rest_mask(prep, rec.n - a), x0=x0[None])


def _observability(prep: Prepared, run: FilterRun, p0: np.ndarray) -> JointObservability:
    """Gyro S, G from the filter's information; the accelerometer from the |f| = g stage's (module
    docstring, step 7: a session whose gravity directions do not determine the accelerometer is refused,
    whatever the filter's horizontal rows would add — the criterion of Ferraris and Tedaldi)."""
    lay = prep.layout
    keep = np.array([blk in ("gyro_scale", "gyro_nonorth") for blk in lay.blocks for _ in range(3)])
    gyro = joint_observability(run.p[0], p0, lay.names, keep)
    if prep.gravity_fit is None:
        return gyro
    gf = prep.gravity_fit
    names = tuple(f"{blk}_{ax}" for blk in ("ba", "Sa", "Ga") for ax in "xyz")
    acc = joint_observability(gf.covariance, np.diag(gf.prior_sigma**2), names, np.ones(9, bool))
    return JointObservability(gyro.names + acc.names, np.concatenate([gyro.ratio, acc.ratio]),
                              gyro.unobservable + acc.unobservable, gyro.weak + acc.weak,
                              gyro.directions + acc.directions)


def _label(name: str) -> str:
    """'Sa_x' → 'accelerometer S_x'; the gyro's names stay the paper's ('S_x', 'G_y')."""
    block, ax = name.split("_")
    return {"S": f"S_{ax}", "G": f"G_{ax}", "ba": f"accelerometer b_{ax}", "Sa": f"accelerometer S_{ax}",
            "Ga": f"accelerometer G_{ax}"}[block]


def calibrate(
    rec: Recording,
    method: str = "kf_session",
    *,
    accelerometer: str = "estimate",
    external_acc_allowance_m_s2: float | None = None,
    arw_rad_s_sqrt_hz: float | None = None,
    vrw_m_s2_sqrt_hz: float | None = None,
    gravity_m_s2: float | None = None,
    min_rest_s: float = 2.0,
    iterations: int = 3,
    keep_history: bool = True,
    engine: str = "compiled",
    hand_check: bool = True,
) -> Calibration:
    """Calibrate ``rec`` (module docstring); ``rec`` is not modified.

    Raises :class:`~gyrosim.errors.RecordingError` for input the method cannot use (no rest, gaps,
    wrong units, an accelerometer the motion cannot separate from the gyro errors).  A run that fails
    its own consistency check is returned with ``status`` "diverged" or "inconsistent".
    ``hand_check``: an "ok" result is compared with the hand-aware estimate (``kf_hand``; with the
    accelerometer estimated ``kf_hand_joint`` on the raw recording) and becomes "inconsistent" when they
    differ beyond both σ (:func:`calib.session.hand.filter.hand_cross_check`: a lever arm's error hides from the
    innovations).
    """
    method = resolve_method(method)
    if engine not in ENGINES:
        raise ValueError(f"unknown engine {engine!r}; use one of {', '.join(ENGINES)}")
    prep = prepare(rec, accelerometer=accelerometer, external_acc_allowance_m_s2=external_acc_allowance_m_s2,
                   arw_rad_s_sqrt_hz=arw_rad_s_sqrt_hz, vrw_m_s2_sqrt_hz=vrw_m_s2_sqrt_hz, gravity_m_s2=gravity_m_s2,
                   min_rest_s=min_rest_s)
    warnings = list(prep.warnings)
    a, b = prep.bias.index_range
    refuse_if_nothing_observed(rec, prep.bias.value_rad_s, a, b, prep.start)
    passes = 1 if method == "kf_session" else max(1, iterations)
    theta0, q0, p0 = prep.theta0, prep.quat0_nb, prep.p0
    obs = None
    for i in range(passes):
        last = i == passes - 1
        run = _run(prep, rec, theta0, q0, p0, engine, keep_history and last)
        if i == 0:
            obs = _observability(prep, run, p0)
            _apply_observability(prep, obs, warnings)
        if not last:
            theta0 = run.theta[0].copy()
            if prep.layout.estimates_accelerometer:
                q0, f0, mi_a = _initial_attitude(rec, theta0, a, b)
                p0 = initial_covariance(prep.layout, prep.config, q0, f0, mi_a, prep.gravity_fit.covariance,
                                        _tilt_sigma(rec, a, b, prep.config.gravity_m_s2))
    fixed = None
    if not prep.layout.has("gyro_bias") and run.whitened is not None:
        # the static bias is held fixed (the paper's 9 states): its error is part of the model, in the
        # innovation test and in σ of S, G (calib.session.consistency, "Parameters the filter holds fixed")
        # compiled either engine: equal to 1e-9, ×40 faster
        def rerun(th: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            r = _run(prep, rec, th, q0, p0, "compiled", False)
            return r.whitened[0], r.theta[0][0:6]

        fixed = fixed_parameter_effect(rerun, theta0, theta_slice("gyro_bias"), prep.bias_std_rad_s, run.whitened[0],
                                       run.theta[0][0:6])
    return _result(prep, rec, run, obs, warnings, REGISTERED_NAME[method, prep.accelerometer], passes, hand_check,
                   fixed)


def _apply_observability(prep: Prepared, obs: JointObservability, warnings: list[str]) -> None:
    acc_names = [n for n in obs.unobservable + obs.weak if n.split("_")[0] in ("ba", "Sa", "Ga")]
    if acc_names:
        poses = missing_poses(acc_names, prep.windows_f_hat)
        raise RecordingError(
            "this session cannot separate the accelerometer from the gyro errors: "
            f"{', '.join(_label(n) for n in acc_names)} "
            "stay undetermined (posterior σ above half the prior). Add rest poses of ≥ 2 s with gravity along: "
            f"{'; '.join(poses) if poses else 'more distinct directions (Tedaldi 2014: ≥ 9, well spread)'} — or slow "
            "rotations through them — or pass --accelerometer calibrated if the accelerometer is calibrated already"
        )
    gyro_unobs = [n for n in obs.unobservable if n.split("_")[0] in ("S", "G")]
    gyro_weak = [n for n in obs.weak if n.split("_")[0] in ("S", "G")]
    if gyro_unobs:
        warnings.append(
            f"unobservable: {', '.join(gyro_unobs)}: the recording's motion leaves them undetermined (posterior σ "
            "within 90 % of the prior; Zhou 2020 §4); add rotations about horizontal axes (scale factors) and about "
            "the vertical (non-orthogonality), Zhou 2020 Table 5")
    if gyro_weak:
        warnings.append(
            f"weakly observable: {', '.join(gyro_weak)} (posterior σ > half the prior): the motion barely excited "
            "them for this noise level; rotate longer or faster about the axes Zhou 2020 Table 5 names")


def bias_drift_note(rec: Recording, prep: Prepared) -> str | None:
    """Why a constant-bias filter's innovations may carry low-frequency power without any hand: the gyro
    bias moved between the session's rests beyond their white noise (:func:`calib.session.hand.filter.bias_drift`,
    χ² of the rests' mean differences above its 95 % quantile).  The paper's filter holds the bias at the
    first rest's average (Zhou 2020 §3.2), so a drifting bias tilts its attitude like an unmodelled
    disturbance — the inflation is then right to fire, and this says why."""
    from calib.session.hand.filter import bias_drift

    d = bias_drift(rec.gyro_rad_s, rec.t_s, prep.rest.index_ranges, prep.config.arw_rad_s_sqrt_hz)
    if d.q_rad2_s3 <= 0 or len(d.rest_bias_rad_s) < 2:
        return None
    b = np.asarray(d.rest_bias_rad_s)
    change = float(np.max(np.linalg.norm(b[1:] - b[:-1], axis=1)))
    return (f"the gyro bias drifts: the rests' mean gyro readings differ by up to {change:.2e} rad/s (χ² {d.chi2:.0f} "
            f"against its 95 % quantile {d.threshold:.1f}, {d.dof} dof; rate random walk ≈ {d.rrw_rad_s_sqrt_s:.1e} "
            "rad/s/√s): this method holds the bias at the first rest's average, so the drift tilts its attitude like "
            "an unmodelled disturbance and its σ cannot be trusted; the hand-aware method (kf_hand) models the "
            "bias as a random walk fitted to the rests")


def _result(
    prep: Prepared,
    rec: Recording,
    run: FilterRun,
    obs: JointObservability | None,
    warnings: list[str],
    method: str,
    passes: int,
    hand_check: bool = False,
    fixed: FixedParameterEffect | None = None,
) -> Calibration:
    lay, cfg = prep.layout, prep.config
    estimate = lay.estimates_accelerometer
    blocks = ["gyro_bias", "gyro_scale", "gyro_nonorth"] + (
        ["acc_bias", "acc_scale", "acc_nonorth"] if estimate else []
    )
    n = 3 * len(blocks)
    cov = np.zeros((n, n))
    p = run.p[0]
    for i, bi in enumerate(blocks):
        for j, bj in enumerate(blocks):
            oi, oj = lay.offset(bi), lay.offset(bj)
            if oi >= 0 and oj >= 0:
                cov[3 * i:3 * i + 3, 3 * j:3 * j + 3] = p[oi:oi + 3, oj:oj + 3]
    infl = None
    if run.whitened is not None:
        infl = innovation_inflation(run.whitened[0], rec.t_s[prep.start + 1:],
                                    sensitivity=None if fixed is None else fixed.sensitivity,
                                    sensitivity_cov=None if fixed is None else fixed.cov)
    if infl is not None:
        cov = cov * infl.factor  # coloured residuals (consistency module docstring); the filter's states only
    if not lay.has("gyro_bias"):  # the static average: its own variance, and its effect on S, G (J C_b Jᵀ)
        cov[0:3, 0:3] = np.diag(prep.bias_std_rad_s**2)
        if fixed is not None:
            cov[3:9, 3:9] += fixed.added_covariance
            cov[3:9, 0:3] = fixed.jacobian @ fixed.cov
            cov[0:3, 3:9] = cov[3:9, 0:3].T
    th = run.theta[0]
    values = {BLOCK_LABELS[blk]: th[theta_slice(blk)] for blk in blocks}
    gyro = (Bias(value=th[theta_slice("gyro_bias")]), ScaleFactor(value=th[theta_slice("gyro_scale")]),
            NonOrthogonality(value=_safe_nonortho(th[theta_slice("gyro_nonorth")])),
            WhiteNoise(density=np.full(3, cfg.arw_rad_s_sqrt_hz)))
    acc: tuple = (WhiteNoise(density=np.full(3, cfg.vrw_m_s2_sqrt_hz)),)
    if estimate:
        acc = (Bias(value=th[theta_slice("acc_bias")]), ScaleFactor(value=th[theta_slice("acc_scale")]),
               NonOrthogonality(value=_safe_nonortho(th[theta_slice("acc_nonorth")]))) + acc
    cons = check_innovations(run.nis[0], 2, rec.rate_hz)
    sanity = check_estimate(values, cov, cfg.gravity_m_s2)
    th_a = np.concatenate([th[theta_slice("acc_bias")], th[theta_slice("acc_scale")], th[theta_slice("acc_nonorth")]])
    f_hat = compensate_acc(rec.acc_m_s2, th_a) if estimate else rec.acc_m_s2
    rest_g = rest_gravity(f_hat, rec.t_s, prep.rest.index_ranges, cfg.gravity_m_s2, math.sqrt(cfg.r_var(rec.rate_hz)),
                          fitted_g=not estimate)
    status, notes = verdict(cons, sanity, rest_g, "estimate" if estimate else "calibrated")
    if infl is not None:
        status = apply_inflation(status, notes, infl, can_fail=not prep.noise.noise_free)
        if infl.factor > 1 and not lay.has("gyro_bias") and (note := bias_drift_note(rec, prep)) is not None:
            notes.append(note)
    cross = None
    if hand_check and status == "ok" and not prep.noise.noise_free:   # noise-free: methods differ by discretisation
        from calib.session.hand.filter import hand_cross_check

        sg = np.concatenate([th[theta_slice("gyro_scale")], th[theta_slice("gyro_nonorth")]])
        warn, cross = hand_cross_check(rec, sg, cov[3:9, 3:9], accelerometer="estimate" if estimate else "calibrated")
        if warn:
            notes.extend(warn)
            status = "inconsistent"
    warnings = warnings + notes
    diagnostics = {
        "accelerometer_mode": "estimate" if estimate else "calibrated",
        "rest_segments": prep.rest.to_list(),
        "noise": {"arw_rad_s_sqrt_hz": cfg.arw_rad_s_sqrt_hz, "vrw_m_s2_sqrt_hz": cfg.vrw_m_s2_sqrt_hz,
                  "external_acc_allowance_m_s2": cfg.external_acc_allowance_m_s2, "gravity_m_s2": cfg.gravity_m_s2,
                  **prep.noise.to_dict()},
        "consistency": {**cons.to_dict(), **({"sigma_inflation": infl.to_dict()} if infl is not None else {}),
                        **({"hand_cross_check": cross} if cross is not None else {})},
        "rest_gravity": rest_g.to_dict(),
        "filter": {"states": list(lay.names), "passes": passes, "samples": int(rec.n - prep.start),
                   "rate_hz": rec.rate_hz, "start_s": float(rec.t_s[prep.start])},
    }
    if not lay.has("gyro_bias") and prep.rest_bias is not None:   # the reported bias is the first rest's mean
        diagnostics["gyro_bias"] = prep.rest_bias.to_dict()
    if obs is not None:
        diagnostics["observability"] = {"posterior_over_prior_sigma": dict(zip(obs.names, obs.ratio.round(6).tolist())),
                                        "unobservable": list(obs.unobservable), "weakly_observable": list(obs.weak)}
    if prep.gravity_fit is not None:
        gf = prep.gravity_fit
        diagnostics["gravity_fit"] = {"bias_m_s2": gf.bias_m_s2, "scale_factor": gf.scale_factor,
                                      "nonorthogonality": gf.nonorthogonality,
                                      "std": np.sqrt(np.diag(gf.covariance)),
                                      "residual_rms_m_s2": gf.residual_rms_m_s2, "samples": gf.samples}
    history = None
    if run.sd_history is not None:
        history = FilterHistory(rec.t_s[prep.start + 1:], run.sd_history[0], run.theta_history[0],
                                run.innovation[0], run.nis[0], lay.names)
    return Calibration(gyro=gyro, accelerometer=acc, covariance=cov, status=status, warnings=tuple(warnings),
                       method=method, diagnostics=diagnostics, history=history)


def _safe_nonortho(g: np.ndarray) -> np.ndarray:
    """A diverged run can leave a non-orthogonality the vocabulary refuses (singular axes); keep the
    numbers (status says diverged) but make the effect constructible by clipping to ±0.45."""
    g = np.asarray(g, float)
    if not np.all(np.isfinite(g)):
        return np.zeros(3)
    return np.clip(g, -0.45, 0.45)


def true_gyro_parameters(rec: Recording) -> dict[str, np.ndarray] | None:
    """The simulated device's gyro bias, scale factor and non-orthogonality (SI), if the file has them
    (the oracle :func:`gyrosim.calibration.truth_calibration`; for scoring, never for estimating)."""
    truth = truth_calibration(rec)
    if truth is None:
        return None
    return {"bias_rad_s": truth.value("gyro", "bias"), "scale_factor": truth.value("gyro", "scale_factor"),
            "nonorthogonality": truth.value("gyro", "nonorthogonality")}


def refuse_if_nothing_observed(rec: Recording, bias_rad_s: np.ndarray, ra: int, rb: int, start: int) -> None:
    """Every gyro S, G unobservable from the motion after ``start`` (:func:`motion_unobservable`, the parameter Gram of
    Zhou §4): the filter, which starts at the rest that gave the bias (the first one ≥ 2 s), would see no rotation that
    determines them — a session whose early rests came out shorter (a hand that never held still 2 s before turning;
    rests cut by correlated noise, as an output low-pass did before :func:`calib.session.rest.detect_rest` scaled its
    test) or that does not turn.  Its S, G would be the prior, 0 ± 5 %, with status "ok" (kf_hand, the last rest ending
    the file: a crash in its low-pass): refused instead, saying where the filter starts and how much rotation comes
    before it."""
    names = {f"{b}_{ax}" for b in "SG" for ax in "xyz"}
    enough = rec.n - start >= int(2.0 * rec.rate_hz) + 32
    if enough and not names <= set(motion_unobservable(rec, bias_rad_s, start)):
        return
    w2 = np.sum((rec.gyro_rad_s - np.mean(rec.gyro_rad_s[ra:rb], axis=0)) ** 2, axis=1)
    before = float(np.sum(w2[:start]) / max(float(np.sum(w2)), 1e-300))
    raise RecordingError(
        f"no gyro scale factor or non-orthogonality is determined by this session: the filter starts at the first rest "
        f"of ≥ 2 s (t = {rec.t_s[ra]:.2f}–{rec.t_s[rb - 1]:.2f} s, which gives the bias) and {100 * before:.0f} % of "
        "the "
        "session's rotation comes before it. Hold the sensor still for ≥ 2 s before the turns, then turn about each "
        "axis (Zhou 2020 Table 5); if the rests are there, check the rest segments calib reports"
    )


def motion_unobservable(rec: Recording, bias_rad_s: np.ndarray, start: int) -> list[str]:
    """Gyro filter parameters the recording's motion cannot observe, from the stripped observability
    matrix's parameter Gram (:func:`calib.session.observability.parameter_gram`, attitude-free, Zhou §4).

    Rates and accelerometer averaged over 2 s (calibration rotations live below 1 Hz), sampled at
    ~10 Hz; null space = less excitation than a 0.01 rad/s rotation gives.
    """
    from calib.session.observability import parameter_gram, unobservable_parameters

    step = max(1, int(round(rec.rate_hz / 10.0)))
    win = max(1, int(round(2.0 * rec.rate_hz)))
    kernel = np.ones(win) / win

    def smooth(x: np.ndarray) -> np.ndarray:
        return np.stack([np.convolve(x[:, i], kernel, mode="same") for i in range(3)], axis=1)[::step]

    w = smooth(rec.gyro_rad_s[start:] - bias_rad_s)
    f = smooth(rec.acc_m_s2[start:])
    return unobservable_parameters(parameter_gram(w, f), float(np.median(np.linalg.norm(f, axis=1))))

