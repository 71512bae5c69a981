"""The paper family: ``calibrate()`` (one hand-held session → a :class:`~gyrosim.calibration.Calibration` of the gyro
and, by default, the accelerometer) and the paper's 9-state filter's variants the registry names.

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

``accelerometer="calibrated"`` is the paper's 9-state filter with the static bias (Zhou §3.3.2
assumes a calibrated accelerometer).

**Steps.**

1–5. the session prepared (:func:`calib.session.prepare.prepare`): input checks, rests and the static bias,
   noise levels, the |f| = g fit and the initial attitude, the external-acceleration allowance;
6. the filter (compiled, :func:`calib.session.kernel.run_filter`): ``kf_session`` one pass, ``iterated_session``
   three, each re-linearised at the previous pass's estimate with the prior kept where it was (the prior mean
   enters as the initial error state x₀ = θ_prior − θ̂: Gauss–Newton on the batch posterior);
7. observability from the filter's own information (:func:`calib.session.observability.filter_observability`):
   gyro combinations the motion left undetermined are named in ``warnings``; an accelerometer that
   this session cannot separate from the gyro errors is an error naming the parameters and the rest
   poses to add;
8. the verdict (:mod:`calib.session.consistency`): ``status`` ok / diverged / inconsistent, with warnings
   saying what to try;
9. an "ok" result is compared with the hand-aware estimate (:func:`calib.session.crosscheck.hand_checked`): the
   public :func:`calibrate` and :func:`paper_filter` call it on their own result, so the method's verdict above
   never runs another method.

**Names.** One name per algorithm, the same in ``calib run``, campaigns and Monte Carlo: the registered
estimator names (:data:`REGISTERED_NAME`).  This function's filter, with its session-wide external-acceleration
allowance (step 5), is ``kf_joint`` with the accelerometer estimated and ``kf_session_r`` with it calibrated
(``iterated_joint`` / ``iterated_session_r``: three passes); ``calibrate(rec, "kf_session_r")`` takes the
accelerometer mode from the name.  ``kf`` is the paper's filter (R from the accelerometer noise alone,
:func:`paper_filter` with :class:`PaperParams`), which :func:`calibrate` does not run.  The former spellings —
the algorithm's own ``kf_session`` / ``iterated_session`` with ``accelerometer=``, and before them ``kf`` /
``iterated`` — still work and warn (DeprecationWarning) naming the registered name.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from warnings import warn

import numpy as np
from scipy import signal as sp_signal
from scipy import stats

from gyrosim.calibration import Calibration, truth_calibration
from gyrosim.effects import Bias, NonOrthogonality, ScaleFactor, WhiteNoise, nonortho_matrix
from gyrosim.recording import Recording
from gyrosim.rotations import quat_conjugate, quat_rotate, skew
from gyrosim.strapdown import integrate_gyro

from calib.session.consistency import (
    FixedParameterEffect,
    Inflation,
    apply_inflation,
    check_estimate,
    check_innovations,
    fixed_parameter_effect,
    innovation_inflation,
    rest_gravity,
    verdict,
)
from calib.session.crosscheck import hand_checked
from calib.session.defaults import HAND_AWARE_METHODS, default_method
from calib.session.drift import bias_drift_note
from calib.session.gravityfit import compensate_acc
from calib.session.hand.filter import kf_hand
from calib.session.kernel import FilterRun, regressor_half_window, run_filter
from calib.session.model import (
    BLOCK_LABELS,
    PAPER,
    FilterHistory,
    acc_theta,
    initial_covariance,
    leave_out_means,
    theta_slice,
)
from calib.session.observability import JointObservability, check_observability, filter_observability
from calib.session.prepare import (  # noqa: F401 (re-exported: their old home)
    ACCELEROMETER_MODES,
    Prepared,
    initial_attitude,
    motion_unobservable,
    prepare,
    refuse_if_nothing_observed,
    rest_mask,
    tilt_sigma,
)
from calib.session.reference import ZhouFilter
from calib.session.skew import refuse_skew_at_floor

__all__ = ["calibrate", "prepare", "Prepared", "METHODS", "ACCELEROMETER_MODES", "REGISTERED_NAME", "resolve_method",
           "true_gyro_parameters", "PaperParams", "paper_filter", "session_filter_run", "prior_offset",
           "lever_arm_two_pass", "GATE_NIS"]

METHODS = ("kf_session", "iterated_session")   # the algorithms: one pass, three re-linearised passes
ENGINES = ("compiled", "filterpy")
# the former spellings → the algorithm, accepted with a DeprecationWarning naming the registered name: the
# algorithm's own names, and "kf"/"iterated", which now name the paper's filter everywhere (registered ``kf``:
# R from the accelerometer noise only) — this function never ran that
DEPRECATED_METHODS = {"kf_session": "kf_session", "iterated_session": "iterated_session", "kf": "kf_session",
                      "iterated": "iterated_session"}
# the registered estimator name (``gyrosim.estimators``) of each (method, accelerometer) pair: the
# label a result carries, the same in ``calib run``, a campaign and a Monte Carlo
REGISTERED_NAME = {
    ("kf_session", "estimate"): "kf_joint",
    ("iterated_session", "estimate"): "iterated_joint",
    ("kf_session", "calibrated"): "kf_session_r",
    ("iterated_session", "calibrated"): "iterated_session_r",
}
# innovation gating of the paper filter's gated variants: χ²₂(0.999) = 13.8
GATE_NIS = float(stats.chi2.ppf(0.999, 2))


def resolve_method(method: str | None, accelerometer: str | None = None, *, stacklevel: int = 3) -> tuple[str, str]:
    """(algorithm of :data:`METHODS`, accelerometer mode) of ``method``, a registered name (None: ``kf_joint``, or
    ``kf_session_r`` with ``accelerometer="calibrated"``) whose mode an ``accelerometer`` may not contradict; a former
    spelling (:data:`DEPRECATED_METHODS`) takes the mode asked (default estimate) and warns (DeprecationWarning)."""
    by_name = {name: key for key, name in REGISTERED_NAME.items()}
    if method is None:
        return "kf_session", accelerometer or "estimate"
    if method in by_name:
        algorithm, mode = by_name[method]
        if accelerometer not in (None, mode):
            other = REGISTERED_NAME[algorithm, accelerometer] if accelerometer in ACCELEROMETER_MODES else None
            raise ValueError(f"method {method!r} is the filter with the accelerometer {mode}, not {accelerometer!r}"
                             + (f"; use {other!r}" if other else ""))
        return algorithm, mode
    if method in DEPRECATED_METHODS:
        algorithm, mode = DEPRECATED_METHODS[method], accelerometer or "estimate"
        name = REGISTERED_NAME.get((algorithm, mode), algorithm)   # an unknown mode: prepare() says so
        why = ("its registered name" if method in METHODS else "this function's filter (session-wide "
               "external-acceleration allowance) by its registered name; 'kf' names the paper's filter (R from the "
               "accelerometer noise only) in every command")
        warn(f"method {method!r} is deprecated: use {name!r}, {why}", DeprecationWarning, stacklevel=stacklevel)
        return algorithm, mode
    raise ValueError(f"unknown method {method!r}; use one of {', '.join(by_name)}")


# ---------------------------------------------------------------------------------------------------------------------
# calibrate(): kf_session / iterated_session


def calibrate(
    rec: Recording,
    method: str | None = None,
    *,
    accelerometer: str | None = None,
    external_acc_allowance_m_s2: float | None = None,
    arw_rad_s_sqrt_hz: float | None = None,
    vrw_m_s2_sqrt_hz: float | None = None,
    gravity_m_s2: float | None = None,
    min_rest_s: float = 2.0,
    iterations: int = 3,
    keep_history: bool = True,
    engine: str = "compiled",
    hand_check: bool = True,
    prepared: Prepared | None = None,
) -> Calibration:
    """Calibrate ``rec`` (module docstring); ``rec`` is not modified.

    ``method``: a registered name (module docstring, "Names").  Default: the one default of ``calib run`` and ``calib
    demo`` (:func:`calib.session.defaults.default_method`): the hand-aware ``kf_hand_joint`` (``kf_hand`` with
    ``accelerometer="calibrated"``; :func:`calib.session.hand.filter.kf_hand` with ``gravity_m_s2``,
    ``keep_history`` and ``prepared``), or ``kf_joint`` / ``kf_session_r`` when ``external_acc_allowance_m_s2`` is
    given.  The default was ``kf_joint`` before: ``calibrate(rec, "kf_joint")`` is that call; a call without a
    method that sets an option of this family's filter alone (``arw_rad_s_sqrt_hz``, ``vrw_m_s2_sqrt_hz``,
    ``min_rest_s``, ``iterations``, ``engine``, ``hand_check``) still runs ``kf_joint`` / ``kf_session_r``, with a
    DeprecationWarning saying to name it.  ``prepared``: steps 1–5 already run by :func:`prepare` with the same options
    (a caller that needs them too, e.g. :func:`calib.session.run.run_session` for the coaching, prepares once).

    Raises :class:`~gyrosim.errors.RecordingError` for input the method cannot use (no rest, gaps,
    wrong units, an accelerometer the motion cannot separate from the gyro errors).  A run that fails
    its own consistency check is returned with ``status`` "diverged" or "inconsistent".
    ``engine``: "compiled" (:func:`calib.session.kernel.run_filter`) or "filterpy" (the readable reference,
    :class:`calib.session.reference.ZhouFilter`; ~40× slower, the same numbers to rounding).
    ``hand_check``: an "ok" result is compared with the hand-aware estimate (``kf_hand``; with the
    accelerometer estimated ``kf_hand_joint`` on the raw recording) and becomes "inconsistent" when they
    differ beyond both σ (:func:`calib.session.crosscheck.hand_cross_check`: a lever arm's error hides from the
    innovations).
    """
    family_options = {"arw_rad_s_sqrt_hz": arw_rad_s_sqrt_hz is not None,
                      "vrw_m_s2_sqrt_hz": vrw_m_s2_sqrt_hz is not None, "min_rest_s": min_rest_s != 2.0,
                      "iterations": iterations != 3, "engine": engine != "compiled", "hand_check": not hand_check}
    method = _default_or_named(method, accelerometer, external_acc_allowance_m_s2,
                               [k for k, given in family_options.items() if given])
    if method in HAND_AWARE_METHODS:
        mode = HAND_AWARE_METHODS[method]
        if accelerometer not in (None, *ACCELEROMETER_MODES):
            raise ValueError(f"accelerometer {accelerometer!r}: use one of {', '.join(ACCELEROMETER_MODES)}")
        if accelerometer not in (None, mode):
            other = {m: n for n, m in HAND_AWARE_METHODS.items()}[accelerometer]
            raise ValueError(f"method {method!r} is the filter with the accelerometer {mode}, not {accelerometer!r}; "
                             f"use {other!r}")
        if external_acc_allowance_m_s2 is not None or any(family_options.values()):
            given = ["external_acc_allowance_m_s2"] * (external_acc_allowance_m_s2 is not None) + [
                k for k, v in family_options.items() if v]
            raise ValueError(f"{', '.join(given)}: option(s) of the hand-blind filter (kf_joint, kf_session_r); "
                             f"{method} estimates the hand's acceleration and the noise from the data")
        return kf_hand(rec, accelerometer=mode, gravity_m_s2=gravity_m_s2, keep_history=keep_history,
                       prepared=prepared)
    method, accelerometer = resolve_method(method, accelerometer)
    if engine not in ENGINES:
        raise ValueError(f"unknown engine {engine!r}; use one of {', '.join(ENGINES)}")
    if prepared is not None and prepared.accelerometer != accelerometer:
        raise ValueError(f"prepared for the accelerometer {prepared.accelerometer}, asked: {accelerometer}")
    prep = prepared or prepare(rec, accelerometer=accelerometer,
                               external_acc_allowance_m_s2=external_acc_allowance_m_s2,
                               arw_rad_s_sqrt_hz=arw_rad_s_sqrt_hz, vrw_m_s2_sqrt_hz=vrw_m_s2_sqrt_hz,
                               gravity_m_s2=gravity_m_s2, min_rest_s=min_rest_s)
    cal = _calibrate_session(prep, rec, method, iterations, keep_history, engine)
    if not hand_check:
        return cal
    return hand_checked(cal, rec, noise_free=prep.noise.noise_free, accelerometer=prep.accelerometer)


def _default_or_named(method: str | None, accelerometer: str | None, external_acc_allowance_m_s2: float | None,
                      family_options: list[str]) -> str | None:
    """``method``, or the default (:func:`calib.session.defaults.default_method`) when None — except that a call
    setting an option only this family's filter has keeps the former default (``kf_joint`` / ``kf_session_r``) and
    warns that the default changed."""
    if method is not None:
        return method
    name = default_method(accelerometer, external_acc_allowance_m_s2)
    if name in HAND_AWARE_METHODS and family_options:
        former = default_method(accelerometer, 0.0)   # the hand-blind filter of this accelerometer mode
        warn(f"calibrate() without a method now runs {name}; {', '.join(family_options)} "
             f"{'is an option' if len(family_options) == 1 else 'are options'} of the hand-blind filter, so this call "
             f"runs {former} as before: name it (method={former!r}) to keep it without this warning",
             DeprecationWarning, stacklevel=3)
        return former
    return name


def _calibrate_session(prep: Prepared, rec: Recording, method: str, iterations: int, keep_history: bool,
                       engine: str) -> Calibration:
    """Steps 6–8 of the module docstring on a prepared session (no hand cross-check)."""
    warnings = list(prep.warnings)
    a, b = prep.bias.index_range
    refuse_if_nothing_observed(rec, prep.bias.value_rad_s, a, b, prep.start)
    if prep.noise.noise_free:   # a timing skew the numerical floor cannot absorb diverges a filter without its state
        refuse_skew_at_floor(rec, prep.noise.acc_floor_m_s2, prep.config.gravity_m_s2, f"--method {method}")
    passes = 1 if method == "kf_session" else max(1, iterations)
    theta0, q0, p0 = prep.theta0, prep.quat0_nb, prep.p0
    obs = None
    for i in range(passes):
        last = i == passes - 1
        run = session_filter_run(prep, rec, theta0, q0, p0, engine, keep_history and last)
        if i == 0:
            obs = filter_observability(prep.layout, run.p[0], p0, prep.gravity_fit)
            check_observability(obs, prep.windows_f_hat, warnings)
        if not last:
            theta0 = run.theta[0].copy()
            if prep.layout.estimates_accelerometer:
                q0, f0, mi_a = initial_attitude(rec, theta0, a, b)
                p0 = initial_covariance(prep.layout, prep.config, q0, f0, mi_a, prep.gravity_fit.covariance,
                                        tilt_sigma(rec, a, b, prep.config.gravity_m_s2))
    fixed = None
    if not prep.layout.has("gyro_bias") and run.whitened is not None:
        # the static bias is held fixed (the paper's 9 states): its error is part of the model, in the
        # innovation test and in σ of S, G (calib.session.consistency, "Parameters the filter holds fixed")
        # compiled either engine: equal to 1e-9, ×40 faster
        def rerun(th: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            r = session_filter_run(prep, rec, th, q0, p0, "compiled", False)
            return r.whitened[0], r.theta[0][0:6]

        fixed = fixed_parameter_effect(rerun, theta0, theta_slice("gyro_bias"), prep.bias_std_rad_s, run.whitened[0],
                                       run.theta[0][0:6])
    return _result(prep, rec, run, obs, warnings, REGISTERED_NAME[method, prep.accelerometer], passes, fixed)


def prior_offset(prep: Prepared, theta: np.ndarray) -> np.ndarray:
    """x₀ = θ_prior − θ̂ over the layout's states: the prior mean seen from the linearisation point θ̂
    (the prior is the first pass's: S, G = 0, the static gyro bias, the |f| = g fit)."""
    x0 = np.zeros(prep.layout.n)
    for blk in prep.layout.blocks[1:]:
        o = prep.layout.offset(blk)
        x0[o:o + 3] = prep.theta0[theta_slice(blk)] - theta[theta_slice(blk)]
    return x0


def session_filter_run(prep: Prepared, rec: Recording, theta0: np.ndarray, q0: np.ndarray, p0: np.ndarray,
                       engine: str, keep_history: bool) -> FilterRun:
    """One pass of ``calibrate()``'s filter over the session from ``prep.start``, linearised at ``theta0``:
    compiled (:func:`calib.session.kernel.run_filter`) or the readable reference (``engine="filterpy"``)."""
    a, fs = prep.start, rec.rate_hz
    mask = None if prep.saturated is None else ~prep.saturated[a:]
    x0 = prior_offset(prep, theta0)
    if engine == "filterpy":
        return _reference_run(prep, rec, theta0, q0, p0, mask, x0)
    return run_filter(rec.gyro_rad_s[None, a:], rec.acc_m_s2[None, a:], rec.t_s[a:], q0[None], theta0[None], p0,
                      prep.layout, prep.config, fs, update_mask=mask, keep_history=keep_history,
                      rest_mask=rest_mask(prep, rec.n - a), x0=x0[None])


def _reference_run(prep: Prepared, rec: Recording, theta0: np.ndarray, q0: np.ndarray, p0: np.ndarray,
                   mask: np.ndarray | None, x0: np.ndarray | None = None) -> FilterRun:
    """The readable filter (:class:`calib.session.reference.ZhouFilter`) over the session, as a FilterRun."""
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


def _session_covariance(prep: Prepared, rec: Recording, run: FilterRun, fixed: FixedParameterEffect | None
                        ) -> tuple[np.ndarray, list[str], Inflation | None]:
    """The reported covariance over (b_g, S, G[, b_a, S_a, G_a]): the filter's P, inflated from the innovations
    (coloured residuals; the filter's states only), with the static bias's own variance and its effect on S, G when
    the filter held it fixed.  Returns (covariance, its blocks, the inflation)."""
    lay = prep.layout
    blocks = ["gyro_bias", "gyro_scale", "gyro_nonorth"] + (
        ["acc_bias", "acc_scale", "acc_nonorth"] if lay.estimates_accelerometer else []
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
    return cov, blocks, infl


def _result(prep: Prepared, rec: Recording, run: FilterRun, obs: JointObservability | None, warnings: list[str],
            method: str, passes: int, fixed: FixedParameterEffect | None = None) -> Calibration:
    """The Calibration of a ``calibrate()`` run: effects, covariance, the verdict (step 8) and the diagnostics."""
    lay, cfg = prep.layout, prep.config
    estimate = lay.estimates_accelerometer
    cov, blocks, infl = _session_covariance(prep, rec, run, fixed)
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
    f_hat = compensate_acc(rec.acc_m_s2, acc_theta(th)) if estimate else rec.acc_m_s2
    rest_g = rest_gravity(f_hat, rec.t_s, prep.rest.index_ranges, cfg.gravity_m_s2, math.sqrt(cfg.r_var(rec.rate_hz)),
                          fitted_g=not estimate)
    mode = "estimate" if estimate else "calibrated"
    status, notes = verdict(cons, sanity, rest_g, mode, method=method)
    if infl is not None:
        status = apply_inflation(status, notes, infl, can_fail=not prep.noise.noise_free, accelerometer=mode)
        if infl.factor > 1 and not lay.has("gyro_bias") and (note := bias_drift_note(rec, prep)) is not None:
            notes.append(note)
    diagnostics = {
        "accelerometer_mode": "estimate" if estimate else "calibrated",
        "rest_segments": prep.rest.to_list(),
        "noise": {"arw_rad_s_sqrt_hz": cfg.arw_rad_s_sqrt_hz, "vrw_m_s2_sqrt_hz": cfg.vrw_m_s2_sqrt_hz,
                  "external_acc_allowance_m_s2": cfg.external_acc_allowance_m_s2, "gravity_m_s2": cfg.gravity_m_s2,
                  **prep.noise.to_dict()},
        "consistency": {**cons.to_dict(), **({"sigma_inflation": infl.to_dict()} if infl is not None else {})},
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
    return Calibration(gyro=gyro, accelerometer=acc, covariance=cov, status=status, warnings=tuple(warnings + notes),
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


# ---------------------------------------------------------------------------------------------------------------------
# the paper's 9-state filter and its variants (registry: kf, iterated, kf_session_r, kf_adaptive, kf_gated, …)


@dataclass(frozen=True)
class PaperParams:
    """How the paper's 9-state filter (after the static bias, the accelerometer calibrated) trusts the
    accelerometer's gravity measurement when a hand adds external acceleration a_e (calib.session.registry's table).

    ``session_allowance``: R = σ_f² + the session's allowance max(rest excess, 3⟨(|f| − g)²⟩), one constant for the
    session (``kf_session_r``); False: R = σ_f² = VRW²·f_s, the paper (only gravity is sensed).  ``adaptive``: R per
    sample, + 3·LP₀.₂ₛ[(|f| − g)²] (``kf_adaptive``).  ``gate_nis`` > 0: skip an update whose NIS exceeds it
    (``kf_gated``: :data:`GATE_NIS`).  ``passes``: each re-linearised at the previous pass's estimate (``iterated``).
    """

    session_allowance: bool = False
    adaptive: bool = False
    gate_nis: float = 0.0
    passes: int = 1


def paper_filter(rec: Recording, params: PaperParams | None = None, *, name: str = "kf",
                 prep: Prepared | None = None, hand_check: bool = True) -> Calibration:
    """The paper's filter on ``rec`` in the variant ``params`` (:class:`PaperParams`), its result labelled ``name``;
    ``prep`` (from :func:`calib.session.prepare.prepare` with the matching allowance) when the caller already has it.
    ``hand_check``: an "ok" result is compared with ``kf_hand`` (:func:`calib.session.crosscheck.hand_checked`)."""
    params = params or PaperParams()
    prep = prep or prepare(rec, accelerometer="calibrated",
                           external_acc_allowance_m_s2=None if params.session_allowance else 0.0)
    cal = _paper_filter(rec, params, name, prep)
    return hand_checked(cal, rec, noise_free=prep.noise.noise_free) if hand_check else cal


def _adaptive_r(rec: Recording, prep: Prepared) -> np.ndarray:
    """R per sample (N − start,): σ_f² + a_ext² + 3·LP₀.₂ₛ[(|f| − g)²] (a one-pole low-pass over 0.2 s)."""
    a, fs, c = prep.start, rec.rate_hz, prep.config
    excess = (np.linalg.norm(rec.acc_m_s2[a:], axis=1) - c.gravity_m_s2) ** 2
    alpha = math.exp(-1.0 / (0.2 * fs))
    lp = sp_signal.lfilter([1 - alpha], [1, -alpha], excess, zi=[alpha * excess[0]])[0]
    return c.vrw_m_s2_sqrt_hz**2 * fs + c.external_acc_allowance_m_s2**2 + 3.0 * lp


def _paper_filter(rec: Recording, params: PaperParams, name: str, prep: Prepared) -> Calibration:
    """:func:`paper_filter` without the hand cross-check."""
    a, fs = prep.start, rec.rate_hz
    acc = rec.acc_m_s2[None, a:]
    r_var = _adaptive_r(rec, prep) if params.adaptive else None
    theta = prep.theta0.copy()
    p0 = initial_covariance(PAPER, prep.config)
    mask = None if prep.saturated is None else ~prep.saturated[a:]
    rmask = rest_mask(prep, rec.n - a)

    def one_pass(th: np.ndarray, x0: np.ndarray):
        return run_filter(rec.gyro_rad_s[None, a:], acc, rec.t_s[a:], prep.quat0_nb[None], th[None], p0, PAPER,
                          prep.config, fs, r_var_per_sample=r_var, gate_nis=params.gate_nis, update_mask=mask,
                          rest_mask=rmask, x0=x0[None])

    for _ in range(params.passes):
        x0 = np.zeros(PAPER.n)
        x0[3:9] = -theta[0:6]  # the prior (S = G = 0) seen from the linearisation point
        theta_in = theta
        out = one_pass(theta_in, x0)
        theta = out.theta[0].copy()

    def rerun(th: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        o = one_pass(th, x0)
        return o.whitened[0], o.theta[0][0:6]

    # the static bias b̂ is held fixed by the paper's filter: its error is part of the model, in the
    # innovation test and in σ of S, G (calib.session.consistency, "Parameters the filter holds fixed")
    fx = fixed_parameter_effect(rerun, theta_in, theta_slice("gyro_bias"), prep.bias_std_rad_s, out.whitened[0],
                                theta[0:6])
    infl = innovation_inflation(out.whitened[0], rec.t_s[a + 1:], sensitivity=fx.sensitivity,
                                sensitivity_cov=fx.cov)
    cov = np.zeros((9, 9))
    cov[:3, :3] = fx.cov
    cov[3:, 3:] = out.p[0, 3:9, 3:9] * infl.factor + fx.added_covariance
    cov[3:, :3] = fx.jacobian @ fx.cov
    cov[:3, 3:] = cov[3:, :3].T
    values = {"gyro scale factor": theta[theta_slice("gyro_scale")],
              "gyro non-orthogonality": theta[theta_slice("gyro_nonorth")]}
    status, notes = verdict(check_innovations(out.nis[0], 2, fs), check_estimate(values, cov, prep.config.gravity_m_s2),
                            accelerometer="calibrated", method=name)
    status = apply_inflation(status, notes, infl, can_fail=not prep.noise.noise_free)
    if infl.factor > 1 and (note := bias_drift_note(rec, prep)) is not None:
        notes.append(note)
    diag: dict = {"consistency": {"sigma_inflation": infl.to_dict()}}
    # the reported bias is the first rest's mean, at its reference (calib.session.rest_bias)
    if prep.rest_bias is not None:
        diag["gyro_bias"] = prep.rest_bias.to_dict()
    gyro = {"bias": prep.bias.value_rad_s, "scale_factor": theta[theta_slice("gyro_scale")],
            "nonorthogonality": np.clip(np.nan_to_num(theta[theta_slice("gyro_nonorth")]), -0.45, 0.45)}
    return Calibration.from_linear(gyro=gyro, covariance=cov, status=status, warnings=prep.warnings + tuple(notes),
                                   method=name, diagnostics=diag)


def lever_arm_two_pass(rec: Recording) -> Calibration:
    """The former ``kf_lever_arm`` (kept importable, ``calib.session.registry:lever_arm_two_pass``, to reproduce
    docs/campaigns.md's rows; not registered: its σ is not honest with a hand —
    :data:`calib.session.registry.LEVER_ARM_RETIRED`).

    The hand turns about a pivot (wrist, elbow) away from the accelerometer, so the sensor
    sees f = g_b + ω̇ × r + ω × (ω × r) with r the lever arm (body frame, constant): a
    deterministic acceleration correlated with the rotation, which no choice of R removes
    (the campaign measured a 0.23–0.28 % non-orthogonality bias from it).  It is linear in r:

        f − g_b = K(ω, ω̇) r,   K = [ω̇×] + [ω×][ω×]

    Pass 1 (``kf_session_r``) calibrates the gyro; its compensated rate, integrated from the
    rest attitude, gives g_b(t); least squares over the motion gives r̂; pass 2 runs on
    f − K r̂.  ω̇ from the compensated rate, zero-phase low-passed at 5 Hz (above the schedule,
    below the tremor).  σ includes r̂'s own error carried into S, G (J C_r Jᵀ; without it NEES was 7.6
    against [5.1, 7.0] with the ideal hand, G_y's error 1.9 σ RMS).  ``kf_hand`` estimates r inside the
    filter instead and supersedes this method (docs/hand.md)."""
    # the session-R preparation of pass 1, used again for the rest attitude
    session_r = PaperParams(session_allowance=True)
    prep = prepare(rec, accelerometer="calibrated")
    first = paper_filter(rec, session_r, prep=prep, name="lever_arm_two_pass", hand_check=False)
    a, fs = prep.start, rec.rate_hz
    m = np.eye(3) + np.diag(first.scale_factor) + nonortho_matrix(first.nonorthogonality)
    w = (rec.gyro_rad_s - first.bias_rad_s) @ np.linalg.inv(m).T
    b, c = sp_signal.butter(2, min(5.0 / (fs / 2), 0.9))
    w_s = sp_signal.filtfilt(b, c, w, axis=0)
    dw = np.gradient(w_s, rec.t_s, axis=0)
    q = integrate_gyro(rec.t_s[a:], w[a:], prep.quat0_nb)
    g_b = quat_rotate(quat_conjugate(q), np.array([0.0, 0.0, prep.config.gravity_m_s2]))
    k = skew(dw[a:]) + skew(w_s[a:]) @ skew(w_s[a:])          # (N, 3, 3)
    f_s = sp_signal.filtfilt(b, c, rec.acc_m_s2[a:], axis=0)  # the tremor is not the lever arm
    moving = np.linalg.norm(w_s[a:], axis=1) > 0.2
    if moving.sum() < 10:
        return first
    y = f_s - g_b
    r, *_ = np.linalg.lstsq(k[moving].reshape(-1, 3), y[moving].reshape(-1), rcond=None)
    kk = skew(dw) + skew(w_s) @ skew(w_s)

    def pass2(r_m: np.ndarray) -> Calibration:
        corrected = rec.acc_m_s2 - np.einsum("nij,j->ni", kk, r_m)
        return paper_filter(rec.with_signals(acc_m_s2=corrected), session_r, name="lever_arm_two_pass",
                            hand_check=False)

    second = pass2(r)
    # r̂'s own error goes into S, G through pass 2: Cov += J C_r Jᵀ, J = ∂(S, G)/∂r by finite differences
    # (1 mm), C_r the least squares' sandwich with block sums over 4 s (the residual — sway, the pass-1
    # attitude error — is correlated in time; Newey & West 1987)
    e = (y - np.einsum("nij,j->ni", k, r)) * moving[:, None]
    g_k = np.einsum("nji,nj->ni", k, e)                                      # Kᵀ e per sample
    blk = np.floor((rec.t_s[a:] - rec.t_s[a]) / 4.0).astype(int)
    sums = np.stack([np.bincount(blk, g_k[:, i]) for i in range(3)], axis=1)
    a_inv = np.linalg.inv(np.einsum("nji,njk->ik", k[moving], k[moving]))
    c_r = a_inv @ (sums.T @ sums) @ a_inv
    items = [("gyro", "scale_factor"), ("gyro", "nonorthogonality")]
    base = np.concatenate([second.value(t, kd) for t, kd in items])
    jac = np.stack([(np.concatenate([pass2(r + 1e-3 * np.eye(3)[i]).value(t, kd) for t, kd in items]) - base) / 1e-3
                    for i in range(3)], axis=1)
    cov2 = np.array(second.covariance, float)
    cov2[3:9, 3:9] += jac @ c_r @ jac.T
    second = Calibration(gyro=second.gyro, accelerometer=second.accelerometer, covariance=cov2, status=second.status,
                         method="lever_arm_two_pass", warnings=second.warnings, diagnostics=second.diagnostics)
    second = hand_checked(second, rec, noise_free=prep.noise.noise_free)   # the check on the recording as given
    return Calibration(
        gyro=second.gyro,
        accelerometer=second.accelerometer,
        covariance=second.covariance,
        status=second.status,
        method="lever_arm_two_pass",
        warnings=second.warnings + (f"lever arm r̂ = {np.array2string(r * 100, precision=1)} cm (body frame)",),
        diagnostics={**second.diagnostics, "hand": {"lever_arm_m": r.tolist()}},
    )
