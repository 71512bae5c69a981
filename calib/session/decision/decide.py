"""What a session's result applies, and whether it is ``ok``: the caller-level step above every session method.

:func:`decide` takes a method's :class:`~gyrosim.calibration.Calibration` of a recording and returns a
:class:`Decision`: the :class:`~gyrosim.calibration.Applied` block that ``calib apply`` and
:meth:`~gyrosim.calibration.Calibration.compensate` use, the status, and the lines that say why.

1. **The motion** (:mod:`calib.session.decision.motion`), classified before the estimate on the recording the
   method saw.  When it reads as a path, it is read once more with the session's estimate applied: an
   uncalibrated gyro or accelerometer turns gravity into apparent acceleration (imu_tk's raw counts: S = −24 %),
   and a "path" that disappears with the estimate applied was the sensor's own error.  A motion that breaks the
   model undetermines S, G and the accelerometer the method estimated from it; the accelerometer may still be
   determined by the rests' |f| = g (:func:`rest_pose_accelerometer`).
2. **Determined** (:func:`calib.session.decision.prior.determine`): σ at most half the prior's, and no gate — the
   motion, a diverged estimate, an accelerometer the method took as calibrated.
3. **The held-out check** (:mod:`calib.session.decision.heldout`): the method again on one half, its
   determined parameters predicting the other (with a motion that breaks the model the method is not run again:
   only the rests' accelerometer is at stake).  S, G are applied when the ``gyro`` variant agrees — or, the
   accelerometer's agreeing, when S, G on top of that accelerometer predict better than it alone (a raw
   accelerometer sets the gravity the pairs are scored against and can hide what S, G do) —, the
   accelerometer when the ``accelerometer`` variant agrees (and not when S, G alone agree and ``full``
   disagrees).  A part the check rejects is left at the prior and the status is not ``ok``; a part it could not
   test (no half determined it) is left at the prior too, with a line saying so, and does not change the status —
   nor does a part that needs no correction: the session's estimate of it lies within ``null_z`` σ of the prior's
   values on every parameter.  A sensor already calibrated (an accelerometer with only noise) cannot be improved
   on, and an estimate of nothing applied to held-out data only adds its own error, so the check finds it no
   better or even worse than raw — the expected outcome, no inconsistency —
   except the accelerometer of a session with ≥ 6 rest poses (a designed protocol puts its poses in one stretch,
   so neither half determines it): each pose is left out of the |f| = g fit in turn and predicted by the others
   (:func:`rest_pose_check`); the fit is applied when it predicts the held-out poses better than raw by two
   standard errors, rejected otherwise (unless, as above, it needs no correction).
4. **Status**: ``ok`` only when the method's own check passed, the motion is the model's, and the held-out
   check rejected nothing the session determined; otherwise the method's status, or ``inconsistent`` with the
   reason.  The bias is applied whatever the status (diverged included: its rests measure it).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np

from gyrosim.calibration import Applied, Calibration
from gyrosim.errors import GyrosimError
from gyrosim.recording import Recording

from calib.session.decision.heldout import (
    GYRO_GIVEN_ACC,
    CrossCheck,
    HeldOutCheck,
    HeldOutParams,
    held_out_check,
    split_point,
    split_recording,
)
from calib.session.decision.motion import MotionClassification, MotionParams, classify_motion
from calib.session.decision.prior import (
    ACC,
    DETERMINED_RATIO,
    MISALIGNMENT_PRIOR_RAD,
    SG,
    Determination,
    Gate,
    Prior,
    combine,
    compose,
    determine,
)

# the beginnings of the warnings this layer adds (the terminal shows their reason on the status line)
MOTION_WARNING = "inconsistent: the motion is not a hand turning the device"
CHECK_WARNING = "inconsistent: calibrated on one half,"
# a sequence of static poses whose |f| = g fit then measures the accelerometer alone: one pose per parameter at the
# least (imu_tk's protocol takes 36–50, Tedaldi et al. 2014)
REST_FIT_MIN_POSES = 9

__all__ = ["MOTION_WARNING", "CHECK_WARNING", "DecisionParams", "Decision", "decide", "estimate_vector",
           "rest_pose_accelerometer", "compensate_prior", "determined_misalignment"]


@dataclass(frozen=True)
class DecisionParams:
    """Settings of :func:`decide`: the determination's σ ratio, the motion's and the check's parameters;
    ``check``: run the held-out check (off: S, G and the accelerometer are never applied beyond the bias)."""

    ratio: float = DETERMINED_RATIO
    motion: MotionParams = MotionParams()
    held_out: HeldOutParams = HeldOutParams()
    check: bool = True
    null_z: float = 3.0   # a part within this many σ of the prior's values on every parameter needs no correction


@dataclass(frozen=True)
class Decision:
    """:func:`decide`'s result: what is applied, the status, and why."""

    applied: Applied
    status: str
    determination: Determination
    motion: MotionClassification
    check: CrossCheck | None
    warnings: tuple[str, ...] = ()
    lines: tuple[str, ...] = ()
    motion_note: str = ""
    report: dict = field(default_factory=dict)


def _mask(part: slice) -> np.ndarray:
    """(18,) True over ``part`` of θ (:data:`~calib.session.decision.prior.SG`, ``ACC``)."""
    m = np.zeros(18, bool)
    m[part] = True
    return m


def estimate_vector(cal: Calibration) -> tuple[np.ndarray, np.ndarray]:
    """θ (18,) and σ (18,) of a calibration (an accelerometer it did not estimate: NaN)."""
    theta = np.concatenate([cal.vector("gyro"), cal.vector("accelerometer")])
    sigma = np.concatenate([np.sqrt(np.clip(np.diag(cal.linear_covariance(t)), 0, None)) for t in
                            ("gyro", "accelerometer")])
    if not cal.has("accelerometer", "bias"):
        theta[ACC], sigma[ACC] = np.nan, np.nan
    return theta, sigma


def determined_misalignment(cal: Calibration, motion: MotionClassification, ratio: float = DETERMINED_RATIO
                            ) -> tuple[np.ndarray, np.ndarray] | None:
    """α (3,) and σ (3,) of the gyro's rotation against the accelerometer (rad) when ``cal`` estimated it and the
    recording determined it: finite, σ ≤ ``ratio`` of :data:`~calib.session.decision.prior.MISALIGNMENT_PRIOR_RAD`
    on every axis, a motion that is the model's, an estimate that did not diverge; None otherwise.  It is applied
    with S, G (a part of the same gyro axis matrix), when their held-out check agrees."""
    kind = "gyro_acc_misalignment"
    if not cal.has("gyro", kind) or cal.status == "diverged" or not motion.model_holds:
        return None
    alpha, sigma = cal.value("gyro", kind), cal.std("gyro", kind)
    if not (np.all(np.isfinite(alpha)) and np.all(np.isfinite(sigma))
            and np.all(sigma <= ratio * MISALIGNMENT_PRIOR_RAD)):
        return None
    return alpha, sigma


def compensate_prior(rec: Recording, prior: Prior) -> Recording:
    """``rec`` read through a previous calibration (its S, G and accelerometer; not its gyro bias, which each
    session measures at its own rest), for the session to find what is left; unchanged for a maker prior."""
    if not prior.previous:
        return rec
    from calib.session.decision.heldout import linear_compensate

    g = prior.mean[0:9].copy()
    g[0:3] = 0.0
    return rec.with_signals(gyro_rad_s=linear_compensate(rec.gyro_rad_s, g),
                            acc_m_s2=linear_compensate(rec.acc_m_s2, prior.mean[9:18]))


def _rest_means(rec: Recording, rests: list) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per rest ((t0, t1), s) of at least 10 samples: its 0.1-s window means (K, 3) and their σ (K,)."""
    from calib.session.gravityfit import quasi_static_windows

    out = []
    for t0, t1 in rests:
        a, b = np.searchsorted(rec.t_s, [t0, t1])
        if b - a >= 10:
            out.append(quasi_static_windows(rec.acc_m_s2[a:b], rec.rate_hz))
    return out


def _fit_rest_means(poses: list, prior: Prior, gravity_m_s2: float) -> tuple[np.ndarray, np.ndarray]:
    from calib.session.gravityfit import fit_gravity

    f = np.concatenate([m for m, _ in poses])
    sd = np.concatenate([s for _, s in poses])
    fit = fit_gravity(f, f, np.maximum(sd**2, 1e-8), 0.0, gravity_m_s2, np.minimum(prior.sigma[ACC], 10.0),
                      block_samples=10)
    return fit.theta, np.sqrt(np.clip(np.diag(fit.covariance), 0, None))


def rest_pose_check(rec: Recording, rests: list, prior: Prior, gravity_m_s2: float, z: float = 2.0,
                    min_poses: int = 6) -> dict | None:
    """The accelerometer's own held-out check, for sessions whose halves cannot test it (a designed protocol puts
    its poses in one stretch): leave each rest pose out of the |f| = g fit (:func:`rest_pose_accelerometer`) and
    predict |f̂| − g there.  ``agrees`` when the fit's error at the held-out poses is below the raw accelerometer's
    (the prior's) by more than ``z`` standard errors (paired over the poses); the fit on every pose is what is
    then applied.  ``worse``: the fit's error is above raw's by more than ``z`` standard errors.  None with fewer
    than ``min_poses`` rests (the nine parameters need poses to spare)."""
    poses = _rest_means(rec, rests)
    if len(poses) < min_poses:
        return None
    err_fit, err_raw = [], []
    for i, (m, _) in enumerate(poses):
        theta, _ = _fit_rest_means(poses[:i] + poses[i + 1:], prior, gravity_m_s2)
        from calib.session.decision.heldout import linear_compensate

        f = m.mean(axis=0)
        err_fit.append(abs(float(np.linalg.norm(linear_compensate(f[None, :], theta)[0])) - gravity_m_s2))
        err_raw.append(abs(float(np.linalg.norm(f)) - gravity_m_s2))
    d = np.array(err_fit) - np.array(err_raw)
    se = float(d.std(ddof=1) / np.sqrt(d.size))
    verdict = "agrees" if float(d.mean()) < -z * se else "disagrees"
    theta, sigma = _fit_rest_means(poses, prior, gravity_m_s2)
    rms = {"raw": float(np.sqrt(np.mean(np.square(err_raw)))), "fit": float(np.sqrt(np.mean(np.square(err_fit))))}
    return {"verdict": verdict, "worse": bool(float(d.mean()) > z * se), "poses": len(poses), "rms_m_s2": rms,
            "mean_difference_m_s2": [float(d.mean()), se], "theta": theta, "sigma": sigma,
            "rule": f"leave one rest pose out of the |f| = g fit, predict |f| − g there: better than raw by {z:g} "
                    "standard errors"}


def rest_pose_accelerometer(rec: Recording, rests: list, prior: Prior, gravity_m_s2: float
                            ) -> tuple[np.ndarray, np.ndarray] | None:
    """The accelerometer from its rest poses alone: the |f| = g fit (:func:`calib.session.gravityfit.fit_gravity`,
    Ferraris/Tedaldi) over the rests' 0.1-s means with the prior as its ridge; (θ_a (9,), σ (9,)) or None
    without a rest.  What a motion that breaks the model still determines of the accelerometer."""
    from calib.session.gravityfit import fit_gravity, quasi_static_windows

    means, sds = [], []
    for t0, t1 in rests:
        a, b = np.searchsorted(rec.t_s, [t0, t1])
        if b - a < 10:
            continue
        m, s = quasi_static_windows(rec.acc_m_s2[a:b], rec.rate_hz)
        means.append(m)
        sds.append(s)
    if not means:
        return None
    f = np.concatenate(means)
    sd = np.concatenate(sds)
    fit = fit_gravity(f, f, np.maximum(sd**2, 1e-8), 0.0, gravity_m_s2, np.minimum(prior.sigma[ACC], 10.0),
                      block_samples=max(1, int(round(1.0 / 0.1))))
    return fit.theta, np.sqrt(np.clip(np.diag(fit.covariance), 0, None))


def _motion(rec: Recording, cal: Calibration, before: MotionClassification, params: DecisionParams
            ) -> tuple[MotionClassification, str]:
    """The motion to judge by (module docstring, step 1) and a note when the estimate changed the reading."""
    if before.model_holds or before.moving_fraction("carried") <= params.motion.max_carried_fraction:
        return before, ""
    theta, _ = estimate_vector(cal)
    theta = np.where(np.isfinite(theta), theta, 0.0)
    from calib.session.decision.heldout import linear_compensate

    rec_c = rec.with_signals(gyro_rad_s=linear_compensate(rec.gyro_rad_s, theta[0:9]),
                             acc_m_s2=linear_compensate(rec.acc_m_s2, theta[9:18]))
    after = classify_motion(rec_c, np.zeros(3), params.motion, before.acc_noise_density_m_s2_sqrt_hz)
    if after.model_holds:
        return after, ("motion: the path seen in the raw signals was the sensor's own error (an uncalibrated gyro or "
                       "accelerometer turns gravity into apparent acceleration); with the estimate applied it is a "
                       "hand turning the device")
    return before, ""


def _gates(cal: Calibration, motion: MotionClassification, acc_from_rests: bool) -> tuple[Gate, ...]:
    gates = []
    acc, sg = _mask(ACC), _mask(SG)
    if not cal.has("accelerometer", "bias") and not acc_from_rests:
        gates.append(Gate(acc, "the accelerometer was taken as calibrated: left at the prior"))
    if cal.status == "diverged":
        gates.append(Gate(sg | (acc if not acc_from_rests else np.zeros(18, bool)),
                          "the estimate diverged: its numbers are no calibration"))
    if not motion.model_holds:
        gates.append(Gate(sg, f"the motion breaks the model: {motion.reason}"))
    return tuple(gates)


def _session_values(theta: np.ndarray, sigma: np.ndarray, prior: Prior, det: Determination
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Applied values (18,) and σ: determined → the estimate combined with the prior's residual (0 ± σ_prior on
    the prior-compensated recording), then read through the prior; undetermined → the prior's."""
    resid, rsig = combine(np.where(np.isfinite(theta), theta, 0.0), np.where(np.isfinite(sigma), sigma, np.inf),
                          np.zeros(18), prior.sigma)
    resid = np.where(det.determined, resid, 0.0)
    out = np.concatenate([compose(np.r_[0.0, 0.0, 0.0, prior.mean[3:9]], resid[0:9]),
                          compose(prior.mean[9:18], resid[9:18])])
    sig = np.where(det.determined, rsig, prior.sigma)
    return out, sig


def _variants(theta: np.ndarray, sigma: np.ndarray, prior: Prior, det: Determination,
              alpha: np.ndarray | None = None) -> dict:
    """The first half's variants for the held-out check: gyro θ (9,; 12 with the half's determined rotation
    ``alpha``) and accelerometer θ (9,) or None."""
    values, _ = _session_values(theta, sigma, prior, det)
    bias = np.r_[values[0:3], np.zeros(6)]
    out = {"raw": (None, None), "bias": (bias, None)}
    has_g, has_a = bool(det.determined[SG].any()), bool(det.determined[ACC].any())
    gyro = np.r_[values[0:3], values[3:9]] if alpha is None else np.r_[values[0:3], values[3:9], alpha]
    if has_g:   # a variant the first half did not determine is not scored: its verdict is "inconclusive"
        out["gyro"] = (gyro, None)
    if has_a:
        out["accelerometer"] = (bias, values[9:18])
    if has_g and has_a:
        out["full"] = (gyro, values[9:18])
    return out


def _parameters(rec: Recording, cal: Calibration, prior: Prior, motion: MotionClassification, gravity_m_s2: float,
                rests: list | None = None) -> tuple[np.ndarray, np.ndarray, tuple[Gate, ...]]:
    """θ, σ (18,) and the gates of a method's result on ``rec``: with a motion that breaks the model, the
    accelerometer from the rests' |f| = g instead of the method's estimate (module docstring, step 1; an
    accelerometer the method took as calibrated stays so); ``rests``: ``rec``'s rests ((t0, t1), s), default the
    result's own."""
    theta, sigma = estimate_vector(cal)
    acc_from_rests = False
    if not motion.model_holds and cal.has("accelerometer", "bias"):   # taken as calibrated: it stays so
        rests = (cal.diagnostics or {}).get("rest_segments") or [] if rests is None else rests
        fit = rest_pose_accelerometer(rec, rests, prior, gravity_m_s2)
        if fit is not None:
            theta[ACC], sigma[ACC] = fit
            acc_from_rests = True
    return theta, sigma, _gates(cal, motion, acc_from_rests)


def _rests_within(rests: list, t_from: float, t_to: float, rec: Recording) -> tuple[tuple[int, int], ...]:
    """The parts of ``rests`` ((t0, t1), s, the whole recording's clock) inside [t_from, t_to), as sample ranges of
    ``rec`` (that span, its clock from 0)."""
    out = []
    for t0, t1 in rests:
        a, b = max(t0, t_from), min(t1, t_to)
        if b > a:
            i, j = np.searchsorted(rec.t_s, [a - t_from, b - t_from])
            if j - i >= 2:
                out.append((int(i), int(j)))
    return tuple(out)


def _rests_as_times(rests: list, t_from: float, t_to: float) -> list:
    """The parts of ``rests`` ((t0, t1), s) inside [t_from, t_to), on that span's clock (from 0)."""
    return [(max(a, t_from) - t_from, min(b, t_to) - t_from) for a, b in rests if min(b, t_to) > max(a, t_from)]


def _fold(train: Recording, predict: Recording, spans: tuple, rests_train: list, rests_predict: tuple,
          estimate: Callable[[Recording], Calibration], whole: Calibration, prior: Prior,
          motion: MotionClassification, gravity_m_s2: float, params: DecisionParams) -> HeldOutCheck:
    """One fold: the method on ``train``, its determined parameters predicting ``predict``.  With a motion that
    breaks the model the method is not run again: S and G are not determined whatever it finds, and the
    accelerometer comes from ``train``'s rests (``rests_train``, its clock) with ``whole``'s gyro bias."""
    if motion.model_holds:
        try:
            cal = estimate(train)
        except GyrosimError as exc:
            return HeldOutCheck(spans[0], spans[1], (), {}, params.held_out,
                                (f"the method refused the part {spans[0][0]:.0f}–{spans[0][1]:.0f} s: "
                                 f"{str(exc)[:160]}",))
        theta, sigma, gates = _parameters(train, cal, prior, motion, gravity_m_s2)
        alpha = determined_misalignment(cal, motion, params.ratio)
    else:
        theta, sigma, gates = _parameters(train, whole, prior, motion, gravity_m_s2, rests_train)
        alpha = None
    det = determine(theta, sigma, prior, gates, params.ratio)
    variants = _variants(theta, sigma, prior, det, None if alpha is None else alpha[0])
    return held_out_check(predict, variants, rests_predict, gravity_m_s2, spans[0], spans[1], params.held_out)


def _check(rec: Recording, cal: Calibration, estimate: Callable[[Recording], Calibration], prior: Prior,
           motion: MotionClassification, rests: list, gravity_m_s2: float, params: DecisionParams) -> CrossCheck:
    """The held-out check (module docstring, step 3): first half → second, and second → first when the cut lies in
    a rest (:func:`calib.session.decision.heldout.split_point`)."""
    k, both = split_point(rec, rests, params.held_out.split)
    first, second = split_recording(rec, k)
    t0, t_cut, t_end = float(rec.t_s[0]), float(rec.t_s[k]), float(rec.t_s[-1])
    a_span, b_span = (0.0, t_cut - t0), (t_cut - t0, t_end - t0)
    rests_a, rests_b = _rests_as_times(rests, t0, t_cut), _rests_as_times(rests, t_cut, t_end + 1.0)
    folds = [_fold(first, second, (a_span, b_span), rests_a, _rests_within(rests, t_cut, t_end + 1.0, second),
                   estimate, cal, prior, motion, gravity_m_s2, params)]
    if both:
        folds.append(_fold(second, first, (b_span, a_span), rests_b, _rests_within(rests, t0, t_cut, first),
                           estimate, cal, prior, motion, gravity_m_s2, params))
    return CrossCheck(tuple(folds), params.held_out)


def _permitted(det: Determination, check: CrossCheck | None, theta: np.ndarray, sigma: np.ndarray,
               null_z: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """After the held-out check: (may be applied, rejected by the check, needs no correction), masks (18,) over the
    determined parameters beyond the bias.  A part (S, G; the accelerometer) is applied when its variant agrees,
    rejected when it disagrees (the accelerometer too when S, G alone agree and everything together disagrees) —
    unless its estimate is within ``null_z`` σ of the prior's values (:func:`_no_correction`: nothing to correct)
    — and held back, untested, when the check could not judge it (no half determined it, or no source had enough
    items)."""
    sg, acc = _mask(SG), _mask(ACC)
    allowed, rejected, unneeded = np.zeros(18, bool), np.zeros(18, bool), np.zeros(18, bool)
    if check is None:
        return allowed, rejected, unneeded
    g, a = _sg_verdict(check), check.verdict("accelerometer")
    if g == "agrees" and a == "agrees" and check.verdict("full") == "disagrees":
        a = "disagrees"
    for part, verdict in ((sg, g), (acc, a)):
        concerned = part & det.determined
        allowed |= concerned & (verdict == "agrees")
        if verdict == "disagrees" and _no_correction(theta[concerned], sigma[concerned], null_z):
            unneeded |= concerned
        elif verdict == "disagrees":
            rejected |= concerned
    return allowed, rejected, unneeded


def _no_correction(theta: np.ndarray, sigma: np.ndarray, null_z: float) -> bool:
    """Whether the estimates θ (corrections on the recording read through the prior: 0 is the prior's value) lie
    within ``null_z`` σ of 0, every one of them (none given: False) — the session then finds nothing to correct."""
    theta, sigma = np.asarray(theta, float), np.asarray(sigma, float)
    if theta.size == 0:
        return False
    z = np.abs(theta) / np.where(sigma > 0, sigma, np.inf)
    return bool(np.all(np.isfinite(theta)) and np.all(z <= null_z))


def _sg_verdict(check: CrossCheck) -> str:
    """S, G's verdict: the ``gyro`` variant's (S, G with the raw accelerometer), or — when that does not agree and the
    accelerometer's does — S, G judged on top of the accelerometer they are applied with
    (:data:`~calib.session.decision.heldout.GYRO_GIVEN_ACC`): a raw accelerometer sets the gravity the pairs are
    scored against and can hide what S, G do."""
    g = check.verdict("gyro")
    if g != "agrees" and check.verdict("accelerometer") == "agrees" and check.verdict(GYRO_GIVEN_ACC) == "agrees":
        return "agrees"
    return g


def decide(rec: Recording, cal: Calibration, estimate: Callable[[Recording], Calibration], prior: Prior,
           motion: MotionClassification, gravity_m_s2: float = 9.80665,
           params: DecisionParams = DecisionParams()) -> Decision:
    """What ``cal`` (a method's result on ``rec``, the recording already read through ``prior`` by
    :func:`compensate_prior`) applies, its status and why (module docstring).  ``estimate``: the same method on
    another recording (the held-out check's first half); ``motion``: :func:`classify_motion` of ``rec`` before the
    estimate."""
    motion, motion_note = _motion(rec, cal, motion, params)
    rests = (cal.diagnostics or {}).get("rest_segments") or []
    theta, sigma, gates = _parameters(rec, cal, prior, motion, gravity_m_s2)
    det = determine(theta, sigma, prior, gates, params.ratio)
    beyond_bias = bool(det.determined[3:].any())
    check = None
    if params.check and beyond_bias:
        check = _check(rec, cal, estimate, prior, motion, rests, gravity_m_s2, params)
    allowed, rejected, unneeded = _permitted(det, check, theta, sigma, params.null_z)
    poses = _pose_check(rec, rests, prior, gravity_m_s2, params, det, allowed, rejected, unneeded, theta, sigma)
    session = det.determined.copy()
    session[3:] &= allowed[3:]
    values, sig = _session_values(theta, sigma, prior, replace(det, determined=session))
    untested = det.determined & ~session & ~rejected & ~unneeded
    status, why = _status(cal.status, motion, det, rejected)
    alpha = determined_misalignment(cal, motion, params.ratio) if session[SG].any() else None
    summary = _summary(det, session, prior, ("its misalignment to the accelerometer",) if alpha is not None else ())
    by_poses = rejected & _mask(ACC) if poses is not None and poses["verdict"] == "disagrees" else np.zeros(18, bool)
    lines = _lines(motion, motion_note, det, (rejected & ~by_poses, by_poses, unneeded, untested), check, prior,
                   summary, params.null_z)
    if poses is not None:
        lines.insert(next(i for i, line in enumerate(lines) if line.startswith("applied:")), _pose_line(poses))
    applied = Applied(values, sig, session, det.determined, prior.source, summary, tuple(lines),
                      *(alpha if alpha is not None else (None, None)))
    warnings = tuple(w for w in (why,) if w)
    report = {"motion": {**motion.to_dict(), **({"note": motion_note} if motion_note else {})},
              "prior": {**prior.to_dict(), "determination": det.to_dict()},
              "held_out_check": None if check is None else check.to_dict()}
    if poses is not None and report["held_out_check"] is not None:
        report["held_out_check"]["rest_poses"] = {k: v for k, v in poses.items() if k not in ("theta", "sigma")}
    if report["held_out_check"] is not None:
        report["held_out_check"]["no_correction"] = det.grouped(unneeded)
    return Decision(applied, status, det, motion, check, warnings, tuple(lines), motion_note, report)


def _pose_check(rec: Recording, rests: list, prior: Prior, gravity_m_s2: float, params: DecisionParams,
                det: Determination, allowed: np.ndarray, rejected: np.ndarray, unneeded: np.ndarray, theta: np.ndarray,
                sigma: np.ndarray) -> dict | None:
    """The accelerometer by its rest poses (:func:`rest_pose_check`, each pose left out and predicted by the
    others), in two cases: the halves could not test it (a designed protocol puts its poses in one stretch); or
    the session is a sequence of static poses (≥ :data:`REST_FIT_MIN_POSES`) whose |f| = g fit has a smaller σ
    than the method's estimate on every one of the nine parameters — a motion filter weighs the moves as well,
    where the hand's acceleration and the gyro's errors enter; the rests measure the accelerometer alone (imu_tk's
    and Tedaldi's method).  Agrees → the fit on every pose is applied (``theta``, ``sigma``, ``allowed`` updated in
    place); disagrees → rejected, or needs no correction (``unneeded``, in place) when the fit lies within
    ``null_z`` σ of the prior's values (a 9-parameter fit left without one pose predicts it worse than a perfect
    raw accelerometer: it only adds its own scatter).  None when there was nothing to check or too few poses."""
    acc = _mask(ACC)
    untested = det.determined & ~allowed & ~rejected & ~unneeded & acc
    if not params.check or not (det.determined & acc).any():
        return None
    poses = rest_pose_check(rec, rests, prior, gravity_m_s2, params.held_out.z,
                            min_poses=6 if untested.any() else REST_FIT_MIN_POSES)
    if poses is None:
        return None
    sharper = bool(np.all(np.asarray(poses["sigma"]) < np.where(np.isfinite(sigma[ACC]), sigma[ACC], np.inf)))
    if not untested.any() and not sharper:
        return None
    concerned = det.determined & acc if sharper else untested
    poses["replaces_method"] = sharper
    if poses["verdict"] == "agrees":
        theta[ACC], sigma[ACC] = poses["theta"], poses["sigma"]
        allowed |= concerned
        rejected &= ~concerned
        unneeded &= ~concerned
        return poses
    allowed &= ~concerned
    part = concerned[ACC]                                   # the concerned parameters among the fit's nine
    if _no_correction(np.asarray(poses["theta"])[part], np.asarray(poses["sigma"])[part], params.null_z):
        unneeded |= concerned
        rejected &= ~concerned
    else:
        rejected |= concerned
        unneeded &= ~concerned
    return poses


def _pose_line(poses: dict) -> str:
    r = poses["rms_m_s2"]
    if poses.get("replaces_method"):
        head = (f"accelerometer from its {poses['poses']} rest poses (|f| = g; a smaller σ than the filter's), held "
                "out, each pose predicted by the others")
    else:
        head = f"accelerometer held out by rest pose ({poses['poses']} poses, each predicted by the others)"
    verdict = ("agrees" if poses["verdict"] == "agrees" else "worse than raw" if poses.get("worse")
               else "no better than raw")
    return f"{head}: |f| − g RMS raw {r['raw']:.3f}, calibrated {r['fit']:.3f} m/s² — {verdict}"


def _status(method_status: str, motion: MotionClassification, det: Determination, rejected: np.ndarray
            ) -> tuple[str, str]:
    """The status and, when it is not the method's, the warning that says why."""
    if method_status != "ok":
        return method_status, ""
    if not motion.model_holds:
        return "inconsistent", (f"{MOTION_WARNING}, so the method's model does not hold; only the bias (and what "
                                "the rests determine) is applied")
    if rejected.any():
        return "inconsistent", (f"{CHECK_WARNING} the result did not predict the other half better than the bias "
                                f"alone ({det.grouped(rejected)} not applied)")
    return "ok", ""


def _summary(det: Determination, session: np.ndarray, prior: Prior, gyro_also: tuple[str, ...] = ()) -> str:
    """One line: what comes from this session (``gyro_also``: beyond the 18, e.g. the gyro's rotation) and what
    stays at the prior."""
    rest = np.ones(18, bool) & ~session
    rest[0:3] &= False   # the bias is always the session's
    tail = f"; at the prior ({prior.source}): {det.grouped(rest)}" if rest.any() else ""
    return f"from this session: gyro {det.grouped(session, gyro_also)}" + tail


def _lines(motion: MotionClassification, motion_note: str, det: Determination, held_back: tuple,
           check: CrossCheck | None, prior: Prior, summary: str, null_z: float) -> list[str]:
    """The terminal's lines of the decision, one each: the motion, the check, what is applied, and why the rest
    is not (``held_back``: masks (18,) rejected by the halves, rejected by the rest poses, needing no correction,
    untested)."""
    rejected, by_poses, unneeded, untested = held_back
    out = motion.lines() + ([motion_note] if motion_note else [])
    if check is not None:
        out.append(_check_line(check))
    out.append(f"applied: {summary}")
    if rejected.any():
        out.append(f"not applied: {det.grouped(rejected)} — calibrated on one half, they predicted the other half "
                   "no better than the bias alone; this file leaves them at the prior")
    if by_poses.any():
        out.append(f"not applied: {det.grouped(by_poses)} — fitted without each rest pose, they predicted it no better "
                   "than the raw accelerometer; this file leaves them at the prior")
    if unneeded.any():
        out.append(f"not applied: {det.grouped(unneeded)} — nothing to correct: the estimate is within {null_z:g}σ of "
                   "the prior's values, and applying it did not predict the held-out data better; this file leaves "
                   "them at the prior")
    if untested.any():
        out.append(f"not applied: {det.grouped(untested)} — no half of the recording determines them, so the held-out "
                   "check could not test them; this file leaves them at the prior")
    undet = ~det.determined & np.r_[np.zeros(3), np.ones(15)].astype(bool)
    sigma_only = undet & np.array([r.startswith("σ ") for r in det.reasons])
    if sigma_only.any():
        out.append(f"not determined by this recording: {det.grouped(sigma_only)} (σ above half the prior's): they "
                   "stay at the prior; a session turning longer or faster about the axes concerned would determine "
                   "them")
    reasons = sorted({r for i, r in enumerate(det.reasons) if undet[i] and r and not r.startswith("σ ")})
    for r in reasons:   # the motion's line and the accelerometer's warning say theirs
        if "motion" not in r and "taken as calibrated" not in r:
            out.append(f"left at the prior: {r}")
    return out


def _check_line(check: CrossCheck) -> str:
    """One line: the folds, the verdicts, and the most telling source's RMS per variant."""
    notes = [n for f in check.folds for n in f.notes]
    if not check.sources:
        return "held-out check: could not run — " + "; ".join(notes)
    spans = ", ".join(f"{f.trained_s[0]:.0f}–{f.trained_s[1]:.0f} s → {f.predicted_s[0]:.0f}–{f.predicted_s[1]:.0f} s"
                      for f in check.folds)
    best = next((s for s in check.sources if s.name.startswith("reference") and s.informative(check.params)), None)
    best = best or next((s for s in check.sources if s.informative(check.params)), check.sources[0])
    shown = next((v for v in ("full", "gyro", "accelerometer") if v in best.rms), "bias")
    shown_verdicts = {"gyro": _sg_verdict(check), "accelerometer": check.verdict("accelerometer")}
    verdicts = ", ".join(f"{name} {shown_verdicts[v]}" for name, v in (("S, G", "gyro"), ("accelerometer",
                                                                                         "accelerometer"))
                         if shown_verdicts[v] != "inconclusive" or v in best.rms)
    return (f"held-out check ({spans}): {verdicts or 'nothing to test'}; {best.name.replace('_', ' ')} RMS raw "
            f"{best.rms['raw']:.2f}, bias only {best.rms['bias']:.2f}"
            + (f", calibrated {best.rms[shown]:.2f}" if shown != "bias" else "") + f" {best.unit}"
            + (f" ({'; '.join(notes)})" if notes else ""))
