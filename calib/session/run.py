"""One calibration session as one library call: :func:`run_session` does what ``calib run`` does and returns
one :class:`~gyrosim.calibration.Calibration` that carries all of it, so ``calib run --json X`` writes exactly
what ``Calibration.save(X)`` writes.

What a run holds, beyond the method's estimate:

* the method, by its registered estimator name (:data:`SESSION_METHODS`; the same name in campaigns and
  Monte Carlo): ``kf_hand_joint`` by default (the hand-aware filter with the accelerometer estimated;
  ``kf_hand`` with it calibrated), ``kf_joint`` / ``kf_session_r`` when an external-acceleration allowance
  is given (the hand-blind filter of :func:`calib.session.paper.calibrate`), ``iterated_joint`` /
  ``iterated_session_r`` its three-pass form;
* ``warnings``: the input boundary's first (:class:`calib.inputs.InputReport`), then the method's
  (:func:`method_warnings` gives the method's alone);
* ``report``: ``input`` (what the boundary read and did), ``coaching`` (what the hand cost,
  :func:`calib.session.coach.coach`, on the preparation the method itself used — the recording is prepared
  once) and, for a simulated file, ``truth`` (the device's own bias, scale factor and non-orthogonality);
  ``motion``, ``prior`` and ``held_out_check``: what decided the applied parameters;
* ``applied`` (:class:`~gyrosim.calibration.Applied`): what ``calib apply`` applies — the parameters this
  recording determined, the prior's values for the rest (:mod:`calib.session.decision`: the motion is
  classified before the estimate, each parameter is determined against a real prior — a maker-calibrated sensor,
  or a previous calibration whose values the recording is read through first — and S, G and the accelerometer
  are applied only when the method, run again on the first half, predicts the second half no worse than the
  bias alone).  The status is ``ok`` only when that held-out check agrees too.

When the motion cannot separate the accelerometer from the gyro errors and neither the method nor the
accelerometer mode was asked for, the run continues with the accelerometer taken as calibrated (its prior,
``kf_hand``) and one warning says so.

Former method spellings still run and warn (DeprecationWarning here; a one-line note from ``calib run``):
``hand`` → ``kf_hand_joint`` / ``kf_hand``; ``kf_session`` → ``kf_joint`` / ``kf_session_r``;
``iterated_session`` → ``iterated_joint`` / ``iterated_session_r``; and ``kf`` / ``iterated``, which ``calib run``
took for ``kf_session`` / ``iterated_session``: they still run those (not the paper's filter, which the
registered names ``kf`` / ``iterated`` mean in campaigns and Monte Carlo), and the note says so.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from warnings import warn

from gyrosim.calibration import Calibration, truth_calibration
from gyrosim.errors import GyrosimError, RecordingError
from gyrosim.recording import Recording
from gyrosim.units import G0

from calib.inputs import KF, Loaded, prepare_recording
from calib.inputs.turns import Turns
from calib.session.decision.decide import DecisionParams, compensate_prior, decide
from calib.session.decision.prior import Prior
from calib.session.defaults import default_method

__all__ = ["RunOptions", "run_session", "resolve_run_method", "method_warnings", "SESSION_METHODS",
           "FORMER_METHODS"]

# the methods a session run takes, by registered estimator name → (algorithm, accelerometer mode)
SESSION_METHODS = {
    "kf_hand_joint": ("hand", "estimate"),
    "kf_hand": ("hand", "calibrated"),
    "kf_joint": ("kf_session", "estimate"),
    "kf_session_r": ("kf_session", "calibrated"),
    "iterated_joint": ("iterated_session", "estimate"),
    "iterated_session_r": ("iterated_session", "calibrated"),
}
_NAME = {key: name for name, key in SESSION_METHODS.items()}
# former spellings (calib run --method before the registered names) → the algorithm they ran
FORMER_METHODS = {"hand": "hand", "kf_session": "kf_session", "iterated_session": "iterated_session",
                  "kf": "kf_session", "iterated": "iterated_session"}
ACCELEROMETER_MODES = ("estimate", "calibrated")


@dataclass(frozen=True)
class RunOptions:
    """The options of one session run (``calib run``'s).

    ``method``: a name of :data:`SESSION_METHODS` (None: ``kf_hand_joint``, ``kf_hand`` with the accelerometer
    calibrated, ``kf_joint`` / ``kf_session_r`` when ``external_acc_allowance_m_s2`` is given); ``accelerometer``:
    "estimate" or "calibrated" (None: what the method's name says, else "estimate"); ``gravity_m_s2``: local
    gravity (None: the method's default); ``external_acc_allowance_m_s2``: the hand-blind filters' allowance for
    the hand's acceleration, m/s² RMS (None: from the data); ``keep_history``: keep the per-step history for a
    viewer (never saved in the JSON); ``prior``: what the sensor is known to be before this session (None: a
    maker-calibrated sensor, :meth:`calib.session.decision.prior.Prior.maker`); ``decision``: the settings of
    what is applied (:class:`calib.session.decision.decide.DecisionParams`).;
    ``turns``: turns of a known angle (:mod:`calib.inputs.turns`; the hand-aware methods take them as
    measurements, :mod:`calib.session.known_turns`); when they come with a protocol's six box-face poses
    (``turns.poses``, Ferraris's), the accelerometer is taken from those (:func:`protocol_accelerometer`) and the
    hand-aware filter runs with it calibrated and the gyro's rotation against it estimated."""

    method: str | None = None
    accelerometer: str | None = None
    gravity_m_s2: float | None = None
    external_acc_allowance_m_s2: float | None = None
    keep_history: bool = False
    turns: Turns | None = None
    prior: Prior | None = None
    decision: DecisionParams = field(default_factory=DecisionParams)


def _spell(name: str, flag: str | None) -> str:
    return f"{flag} {name}" if flag else repr(name)


def resolve_run_method(options: RunOptions, *, flag: str | None = None) -> tuple[str, str, str | None]:
    """(registered name, accelerometer mode, deprecation note or None) of ``options``'s method (module
    docstring); ``flag`` (``"--method"``) spells the names in the note and errors as a command line's option.
    Raises :class:`~gyrosim.errors.GyrosimError` for an unknown name, a mode the name contradicts, or an
    allowance given to a hand-aware method."""
    method, acc, external = options.method, options.accelerometer, options.external_acc_allowance_m_s2
    if acc is not None and acc not in ACCELEROMETER_MODES:
        raise GyrosimError(f"accelerometer {acc!r}: use one of {', '.join(ACCELEROMETER_MODES)}")
    note = None
    if method is None:
        name = default_method(acc, external)   # the one default (calib.session.defaults)
    elif method in SESSION_METHODS:
        algorithm, mode = SESSION_METHODS[method]
        if acc not in (None, mode):
            raise GyrosimError(f"{_spell(method, flag)} is the filter with the accelerometer {mode}: leave out the "
                               f"accelerometer mode, or use {_spell(_NAME[algorithm, acc], flag)}")
        name = method
    elif method in FORMER_METHODS:
        name = _NAME[FORMER_METHODS[method], acc or "estimate"]
        if method in ("kf", "iterated"):
            note = (f"{_spell(method, flag)} is deprecated: it still runs {name} (calib run's hand-blind filter, as "
                    f"before), not the paper's filter that the registered name {method!r} means in campaigns and "
                    f"Monte Carlo; use {_spell(name, flag)}")
        else:
            note = (f"{_spell(method, flag)} is deprecated: use {_spell(name, flag)} (the same filter, by its "
                    "registered name)")
    else:
        raise GyrosimError(f"unknown method {method!r}: use one of {', '.join(SESSION_METHODS)} (the other registered "
                           "estimators are research baselines for Monte Carlo and campaigns)")
    algorithm, mode = SESSION_METHODS[name]
    if algorithm == "hand" and external is not None:
        blind = ", ".join(n for n, (alg, _) in SESSION_METHODS.items() if alg != "hand")
        raise GyrosimError(f"an external-acceleration allowance is for the hand-blind filters ({blind}); {name} "
                           "models the hand's acceleration and estimates its spectrum from the data")
    return name, mode, note


ACC_REFUSAL = "cannot separate the accelerometer"   # the method's refusal that the run answers by continuing
FALLBACK_NOTE = ("the motion cannot separate the accelerometer from the gyro errors: it is taken as calibrated (its "
                 "prior) and only the gyro is estimated; rest poses of ≥ 2 s in several attitudes would determine it")


def _estimate(rec: Recording, name: str, mode: str, options: RunOptions, keep_history: bool = False,
              turns: Turns | None = None):
    """The method ``name`` on ``rec``: (result, preparation); ``turns``: known turns as measurements (hand-aware
    methods only; the held-out halves run without them).  An accelerometer from a protocol's poses (its prior)
    turns on the gyro's rotation against it in the hand-aware filter: what the rotation was confused with, the
    accelerometer's own shear, is fixed by the poses."""
    from calib.session.hand.filter import kf_hand
    from calib.session.hand.params import HandParams
    from calib.session.paper import calibrate, prepare

    prep = prepare(rec, accelerometer=mode, gravity_m_s2=options.gravity_m_s2,
                   external_acc_allowance_m_s2=options.external_acc_allowance_m_s2)
    if SESSION_METHODS[name][0] == "hand":
        params = HandParams(misalignment=True, accelerometer_source=_poses_source(options)) if _poses(options) else None
        result = kf_hand(rec, accelerometer=mode, gravity_m_s2=options.gravity_m_s2, keep_history=keep_history,
                         prepared=prep, turns=turns, params=params)
    else:
        result = calibrate(rec, name, external_acc_allowance_m_s2=options.external_acc_allowance_m_s2,
                           gravity_m_s2=options.gravity_m_s2, keep_history=keep_history, prepared=prep)
    return result, prep


def _estimate_or_fall_back(rec: Recording, name: str, mode: str, options: RunOptions, keep_history: bool = False):
    """:func:`_estimate`, continuing with the accelerometer calibrated when the motion cannot separate it and the
    caller asked for neither a method nor a mode: (result, preparation, name, mode, fell back)."""
    try:
        return (*_estimate(rec, name, mode, options, keep_history, options.turns), name, mode, False)
    except RecordingError as exc:
        if ACC_REFUSAL not in str(exc) or options.method is not None or options.accelerometer is not None:
            raise
    name = _NAME[SESSION_METHODS[name][0], "calibrated"]
    return (*_estimate(rec, name, "calibrated", options, keep_history, options.turns), name, "calibrated", True)


def _poses(options: RunOptions) -> bool:
    return options.turns is not None and bool(options.turns.poses)


def _poses_source(options: RunOptions) -> str:
    """The protocol's poses as the messages name them."""
    return f"the {options.turns.source}'s six box-face poses"


def protocol_prior(rec: Recording, options: RunOptions, prior: Prior) -> tuple[Prior, RunOptions, dict | None]:
    """With a protocol's six box-face poses (``options.turns.poses``): the prior with the accelerometer they measure
    (:func:`calib.session.six_poses.protocol_accelerometer`, at the run's gravity or g₀), the options with the
    accelerometer calibrated (unless a method or mode was asked for), and the poses' result for the JSON; else
    everything unchanged and None."""
    if not _poses(options):
        return prior, options, None
    from calib.session.six_poses import protocol_accelerometer

    g = options.gravity_m_s2 or G0
    poses, sigma = protocol_accelerometer(rec.acc_m_s2, rec.t_s, options.turns.poses, g)
    prior = prior.with_accelerometer(poses.theta(), sigma, f"the accelerometer from {_poses_source(options)}")
    if options.method is None and options.accelerometer is None:
        options = replace(options, accelerometer="calibrated")
    return prior, options, {**poses.to_dict(), "std": sigma.tolist()}


def run_session(source: Recording | Loaded, options: RunOptions = RunOptions()) -> Calibration:
    """Calibrate one hand-held session as ``calib run`` does (module docstring) and return the one Calibration.

    ``source``: a recording that passed the input boundary (:func:`calib.inputs.open_recording`), or a
    :class:`~gyrosim.recording.Recording`, which is passed through it here (:func:`calib.inputs.prepare_recording`
    for the filter).  Raises the input boundary's and the method's errors for input the method cannot use; a
    result that fails its own check comes back with its status ("inconsistent", "diverged"), and one whose
    held-out check does not agree as "inconsistent" applying the bias alone."""
    from calib.session.coach import coach
    from calib.session.decision.motion import classify_motion

    loaded = source if isinstance(source, Loaded) else prepare_recording(source, KF)
    prior, options, poses = protocol_prior(loaded.recording, options, options.prior or Prior.maker())
    rec = compensate_prior(loaded.recording, prior)
    name, mode, note = resolve_run_method(options)
    if note:
        warn(note, DeprecationWarning, stacklevel=2)
    if options.turns is not None and SESSION_METHODS[name][0] != "hand":
        raise GyrosimError(f"turns of a known angle enter the hand-aware filter only, not {name}: leave out "
                           "--method (or give kf_hand_joint / kf_hand)")
    result, prep, name, mode, fell_back = _estimate_or_fall_back(rec, name, mode, options, options.keep_history)
    motion = classify_motion(rec, prep.bias.value_rad_s, options.decision.motion, prep.noise.acc_density_m_s2_sqrt_hz)
    gravity = float((result.diagnostics.get("noise") or {}).get("gravity_m_s2") or prep.config.gravity_m_s2)
    def part(half: Recording) -> Calibration:   # the held-out check's: through the boundary, the same method
        half = prepare_recording(half, KF).recording
        try:
            return _estimate(half, name, mode, options)[0]
        except RecordingError as exc:
            if ACC_REFUSAL not in str(exc) or mode == "calibrated":
                raise
            return _estimate(half, _NAME[SESSION_METHODS[name][0], "calibrated"], "calibrated", options)[0]

    decision = decide(rec, result, part, prior, motion, gravity, options.decision)
    report = {"coaching": coach(rec, result, prep).to_dict(), "input": loaded.report.to_dict()}
    truth = truth_calibration(loaded.recording)
    if truth is not None:
        report["truth"] = _truth_section(truth)
    report.update(decision.report)
    if poses is not None:
        report["prior"] = {**report.get("prior", {}), "six_poses": poses}
    warnings = tuple(loaded.report.warnings) + ((FALLBACK_NOTE,) if fell_back else ()) + tuple(result.warnings)
    return replace(result, status=decision.status, warnings=warnings + decision.warnings, report=report,
                   applied=decision.applied)


def _truth_section(truth: Calibration) -> dict:
    """The simulated device's linear effects, as ``calib run --json``'s ``truth`` (SI)."""
    return {"bias_rad_s": truth.value("gyro", "bias").tolist(),
            "scale_factor": truth.value("gyro", "scale_factor").tolist(),
            "nonorthogonality": truth.value("gyro", "nonorthogonality").tolist(),
            "accelerometer": {"bias_m_s2": truth.value("accelerometer", "bias").tolist(),
                              "scale_factor": truth.value("accelerometer", "scale_factor").tolist(),
                              "nonorthogonality": truth.value("accelerometer", "nonorthogonality").tolist()}}


def method_warnings(cal: Calibration) -> tuple[str, ...]:
    """The method's own warnings of a :func:`run_session` result (those after the input boundary's)."""
    n = len((cal.report.get("input") or {}).get("warnings") or ())
    return tuple(cal.warnings[n:])
