"""The gyro/accelerometer model loop: fit the declared model, find what its residual lacks, add it,
repeat — naming causes, not proxies (docs/closeloop.md).

Small named steps over typed, frozen values; the rounds are the driver's
(:mod:`calib.closeloop.driver`, shared with the magnetometer loop :mod:`calib.closeloop.mag.loop`),
the round's gyro steps are :class:`calib.closeloop.select.GyroSteps`:

1. **reference** (:func:`~calib.closeloop.reference.build_reference`): truth rate > optical
   orientation > at rest (zero rate) | gravity self-consistency; its rows r (rad/s, or weighted
   pose-to-pose rows) are split into alternating fit / held-out stretches (4 s by default).  A
   recording with none gives a report that says why (:class:`~calib.closeloop.reference.NoReferenceError`).
2. **residual of the declared model** (:func:`_declared_residual`): the vocabulary effects the user
   names (default bias, scale factor, non-orthogonality: y = (I + S + N) ω + b, Zhou et al. 2020
   eq. 1), fitted by least squares on the fit rows, θ̂ = argmin ‖r − J θ‖² (:func:`~calib.closeloop.state.refit`).
3. **candidates** (:func:`_candidates`): every other gyro effect of the vocabulary, its regressor
   the effect's own sensitivity built by its family (:mod:`calib.closeloop.families`); one that
   cannot be built says why (a :class:`~calib.closeloop.driver.NotTaken`).
4. **select** (:class:`~calib.closeloop.select.GyroSteps`, :func:`~calib.closeloop.driver.select`):
   identifiability gate → held-out gain G = n_eff ln(RSS₀/RSS₁) − Δp ln n_eff → confounding rule
   → acceptance on every held-out metric (Wilcoxon signed-rank z per stretch).
5. **add** (:func:`~calib.closeloop.driver.run_rounds`): the accepted term joins the model; repeat
   until no candidate is accepted (at most ``max_rounds``).
6. **report** (:func:`_report` → :class:`CloseloopResult`): parameters on all rows with σ the larger
   of the τ_int-inflated and the cluster-robust covariance plus each term's own stochastic part
   (:func:`_final_covariance`), errors on held-out rows, the trace of each finding, what could not
   be tested and why, confounded groups, refused additions and metric disagreements, and the
   structure no candidate explains (:mod:`calib.closeloop.structure`).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, replace
from typing import Callable

import numpy as np
from threadpoolctl import threadpool_limits

from gyrosim.effects import EFFECTS, effect_from_dict
from gyrosim.errors import RecordingError
from gyrosim.recording import Recording
from gyrosim.rotations import quat_angle_between
from gyrosim.strapdown import integrate_gyro
from gyrosim.units import G0, RAD2DEG

from calib.closeloop.candidates import BuildOptions, Candidate, FittedTerm, Untestable
from calib.closeloop.catalogue import build_candidate, candidate_kinds, family_for
from calib.closeloop.confounding import overlap_summary
from calib.closeloop.driver import LoopTrace, NotTaken, Round, run_rounds
from calib.closeloop.fit import FitResult, cluster_robust, design_rows, fit_model, held_out_score
from calib.closeloop.identify import Excitation
from calib.closeloop.jsonview import JsonView
from calib.closeloop.mag.loop import MagLoopResult, reference_frame_note, run_mag_loop
from calib.closeloop.mag.terms import is_mag_kind
from calib.closeloop.metrics import MetricChange, compare_metrics, explain_disagreement
from calib.closeloop.reference import GravityReference, NoReferenceError, RateReference, Reference, build_reference
from calib.closeloop.result import Finding, LoopReport, trace_of
from calib.closeloop.select import GyroSteps
from calib.closeloop.state import LoopSetup, ModelState, refit
from calib.closeloop.structure import (
    ChannelCorrelation,
    JitterGrowth,
    SpectralLine,
    channel_correlations,
    spectral_lines,
    variance_growth,
    whiteness,
)
from calib.inputs import CLOSELOOP, check_recording

__all__ = ["Finding", "RateEvidence", "CloseloopResult", "Unexplained", "Checks", "run_closeloop", "DEFAULT_DECLARED",
           "JSON_KEYS"]

DEFAULT_DECLARED = ("bias", "scale_factor", "nonorthogonality")


@dataclass(frozen=True)
class RateEvidence(JsonView):
    """Why a gyro effect was added (``report.json`` ``found[i].evidence``): its round, held-out gain G
    for Δp added parameters, n_eff, the held-out residual RMS before → after (row units), the share
    of the residual's power it explains (1 − (RMS₁/RMS₀)²), what its regressor follows, the rivals it
    was confounded with, the gate's verdict and the held-out metrics' changes.

    ``gain_given_the_others``: the same held-out G for this term added last, to the final model without
    it — what it explains with every other finding in.  The rounds' order depends on the path (a term
    whose symptom another effect hides shows only once that effect is in); this does not, and ranks the
    findings by size (None: an output-stage term, whose value is undone on the gyro, not refitted)."""

    round: int
    criterion_gain: float
    added_parameters: int
    n_eff: float
    held_out_rms_before: float
    held_out_rms_after: float
    follows: str
    rivals: list[str]
    identifiability: Excitation | None
    metrics: tuple[MetricChange, ...]
    summary: str
    gain_given_the_others: float | None = None

    @property
    def explained_fraction(self) -> float:
        return 1 - (self.held_out_rms_after / self.held_out_rms_before) ** 2

    def to_json(self) -> dict:
        return {"round": self.round, "criterion_gain": self.criterion_gain, "added_parameters": self.added_parameters,
                "n_eff": self.n_eff, "held_out_rms_before": self.held_out_rms_before,
                "held_out_rms_after": self.held_out_rms_after, "explained_fraction": self.explained_fraction,
                "follows": self.follows, "rivals": self.rivals,
                "identifiability": self.identifiability.to_json() if self.identifiability is not None else None,
                "metrics": [m.to_json() for m in self.metrics], "summary": self.summary,
                "gain_given_the_others": self.gain_given_the_others}


@dataclass(frozen=True)
class Unexplained(JsonView):
    """Structure in the final residual that no candidate explains (docs/closeloop.md §7): spectral
    lines, correlations with every channel, the residual's whiteness per axis (τ_int, Ljung–Box Q)
    and variance growing with (dω/dt)² as timing jitter would."""

    spectral_lines: tuple[SpectralLine, ...] = ()
    channel_correlations: tuple[ChannelCorrelation, ...] = ()
    whiteness: dict[str, float] = field(default_factory=dict)
    variance_growth: JitterGrowth | None = None
    summary: str = ""

    def to_json(self) -> dict:
        return {"spectral_lines": [asdict(x) for x in self.spectral_lines],
                "channel_correlations": [asdict(x) for x in self.channel_correlations],
                "whiteness": dict(self.whiteness),
                "variance_growth": None if self.variance_growth is None else self.variance_growth.to_json(),
                "summary": self.summary}


@dataclass(frozen=True)
class Checks(JsonView):
    """What the output itself says: quantization step per axis (rad/s), saturated samples, input warnings."""

    quantization_lsb: dict[str, float | None]
    saturated_samples: int
    warnings: tuple[str, ...]

    def to_json(self) -> dict:
        return {"quantization_lsb": self.quantization_lsb, "saturated_samples": self.saturated_samples,
                "warnings": list(self.warnings)}


#: report.json's keys, in the order ``calib closeloop`` writes them (promises: add, don't rename)
JSON_KEYS = (
    "reference",
    "reference_description",
    "notes",
    "declared",
    "declared_params",
    "found",
    "unexplained",
    "not_tested",
    "not_distinguished",
    "error_before",
    "error_after",
    "checks",
    "rounds",
    "metrics",
    "rejected",
    "disagreements",
    "tested",
    "identifiability",
)


@dataclass(frozen=True, kw_only=True)
class CloseloopResult(LoopReport):
    """The gyro loop's report (and the magnetometer's, when the recording has one), plus the rows the
    plots and the viewer draw."""

    checks: Checks
    disagreements: list[str] = field(default_factory=list)
    row_time_s: np.ndarray | None = field(repr=False, default=None)
    row_axis: np.ndarray | None = field(repr=False, default=None)
    held_out_rows: np.ndarray | None = field(repr=False, default=None)
    residual_before: np.ndarray | None = field(repr=False, default=None)
    residual_after: np.ndarray | None = field(repr=False, default=None)
    follows_series: dict = field(repr=False, default_factory=dict)
    rows_of: Callable | None = field(repr=False, default=None)   # per-sample (N, 3) → residual rows
    magnetometer: MagLoopResult | None = None    # the loop on the magnetometer channel (None: no channel)

    def ranked_by_size(self) -> list[tuple[str, float]]:
        """The findings, largest first, as (effect, held-out G of the effect added last with the others in)
        — :attr:`RateEvidence.gain_given_the_others`; findings without one are left out."""
        sized = [(f.effect, f.evidence.gain_given_the_others) for f in self.found]
        return sorted(((k, g) for k, g in sized if g is not None), key=lambda kg: -kg[1])

    def to_json_dict(self) -> dict:
        out = {k: self._json(k) for k in JSON_KEYS}
        if self.magnetometer is not None:
            out["magnetometer"] = self.magnetometer.to_json()
        return out


def _gyro_axes(res: "CloseloopResult") -> np.ndarray | None:
    """The gyro's fitted off-diagonal axis matrix: declared non-orthogonality plus any term found that turns
    the axes (the effect class's ``axis_rotation``: the misalignment)."""
    total = np.zeros((3, 3))
    vals = [res.declared_params.get(f"nonorthogonality.value[{i}]", {}).get("value") for i in range(3)]
    if all(v is not None for v in vals):
        total += EFFECTS["nonorthogonality"](value=vals).affine()[0]
    for f in res.found:
        if getattr(EFFECTS.get(f.effect), "axis_rotation", False):   # a family's own kind has no class
            total += effect_from_dict(f.model).affine()[0]
    return total if np.any(total) else None


# ================================================================ steps
def _check_declared(declared: list[str]) -> list[str]:
    declared = list(declared)
    unknown = [k for k in declared if k not in EFFECTS]
    if unknown:
        raise RecordingError(f"--declared: unknown effect(s) {unknown}; the vocabulary has {', '.join(EFFECTS)}")
    return declared


def _declared_terms(setup: LoopSetup, declared: list[str]) -> tuple[Candidate, ...]:
    """The declared effects' regressors (each built by its family); one that cannot be built here is bad input."""
    terms = []
    for kind in declared:
        try:
            terms.append(build_candidate(kind, setup.ref.ctx, setup.ref, setup.options))
        except Untestable as why:
            raise RecordingError(f"declared effect {kind!r} cannot be fitted here: {why.reason}") from None
    return tuple(terms)


def _declared_residual(setup: LoopSetup, terms: tuple[Candidate, ...]) -> ModelState:
    """Step 2 of the module docstring: the declared model fitted on the fit rows by least squares,
    θ̂ = argmin ‖W (r − J θ)‖² (:func:`calib.closeloop.fit.fit_model`).  A gravity reference then
    re-weights its pose-to-pose rows by the declared model's residual (each row's own scatter) and the
    model is fitted again on those weights."""
    ref = setup.ref
    if setup.held_rows.sum() < 3 or setup.fit_rows.sum() < 3:
        raise RecordingError(
            f"the recording is too short for a held-out split: {setup.fit_rows.sum()} fit and {setup.held_rows.sum()} "
            f"held-out rows with {ref.holdout_s:g} s held-out groups; record longer or pass a shorter --holdout")
    state = refit(setup, terms)
    if isinstance(ref, GravityReference):
        ref.reweight(state.fit.residual)
        state = refit(setup, terms, theta0=state.fit.theta)
    return state


def _candidates(setup: LoopSetup, declared: list[str], kinds: list[str] | None
                ) -> tuple[dict[str, Candidate], dict[str, NotTaken]]:
    """Step 3 of the module docstring: every gyro effect of the vocabulary not declared (or the
    ``kinds`` asked for), built by its family on the reference; one that cannot be built says why."""
    pool: dict[str, Candidate] = {}
    not_tested: dict[str, NotTaken] = {}
    for kind in kinds if kinds is not None else candidate_kinds():
        if kind in declared:
            continue
        try:
            pool[kind] = build_candidate(kind, setup.ref.ctx, setup.ref, setup.options)
        except Untestable as why:
            not_tested[kind] = NotTaken("not_buildable", why.reason)
    return pool, not_tested


def run_closeloop(
    rec: Recording,
    declared: tuple[str, ...] | list[str] = DEFAULT_DECLARED,
    *,
    reference: str | None = None,
    holdout_s: float = 4.0,
    candidates: list[str] | None = None,
    max_rounds: int = 6,
    drift_knot_s: float = 20.0,
    progress: Callable[[str], None] | None = None,
) -> CloseloopResult:
    """Run the loop on a recording (the input is not modified); see the module docstring.  Declared
    and candidate kinds of the magnetometer go to its own loop (:func:`calib.closeloop.mag.loop.run_mag_loop`),
    run when the recording has a magnetometer channel.

    BLAS runs single-threaded inside (the project's rule for many small factorizations, as in
    ``calib.mag``): a QR of 20 000 × 130 rows took 0.15 s on one thread and 7.5 s with OpenBLAS's
    threads contending on the loaded 2-core machine (measured, same run)."""
    declared = list(declared)
    mag_declared = [k for k in declared if is_mag_kind(k)]
    gyro_declared = [k for k in declared if not is_mag_kind(k)]
    gyro_cands = None if candidates is None else [k for k in candidates if not is_mag_kind(k)]
    mag_cands = None if candidates is None else [k for k in candidates if is_mag_kind(k)]
    if mag_declared and rec.mag_ut is None:
        raise RecordingError(f"--declared names magnetometer effects {mag_declared}, but the recording has no "
                             "magnetometer channel (/mag, or mag_x,mag_y,mag_z columns)")
    with threadpool_limits(limits=1, user_api="blas"):
        res = _run(rec, gyro_declared, reference=reference, holdout_s=holdout_s, candidates=gyro_cands,
                   max_rounds=max_rounds, drift_knot_s=drift_knot_s, progress=progress)
        if rec.mag_ut is None:
            return res
        if progress:
            progress("magnetometer")
        mag = run_mag_loop(rec, mag_declared, holdout_s=holdout_s, candidates=mag_cands, max_rounds=max_rounds)
    note = reference_frame_note(mag, _gyro_axes(res)) if res.reference in ("optical", "truth") else None
    if note:
        mag = replace(mag, notes=mag.notes + [note])
    return replace(res, magnetometer=mag)


def _run(rec: Recording, declared: list[str], *, reference: str | None, holdout_s: float,
         candidates: list[str] | None, max_rounds: int, drift_knot_s: float,
         progress: Callable[[str], None] | None) -> CloseloopResult:
    """The gyro loop's steps in order: reference → residual → candidates → rounds (select, add) → report."""
    declared = _check_declared(declared)
    check = check_recording(rec, allow_gaps=True, requirements=CLOSELOOP)
    try:  # saturated samples carry no information about the rate: their rows are left out
        ref = build_reference(rec, holdout_s=holdout_s, prefer=reference, exclude=check.excluded)
    except NoReferenceError as err:
        return _no_reference(rec, declared, err, check)
    setup = LoopSetup.of(rec, ref, BuildOptions(drift_knot_s=drift_knot_s), progress or (lambda s: None))
    declared_state = _declared_residual(setup, _declared_terms(setup, declared))
    pool, not_tested = _candidates(setup, declared, candidates)
    trace = run_rounds(GyroSteps(setup), declared_state, pool, not_tested, max_rounds)
    return _report(setup, check, declared, trace)


# ================================================================ report
def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x**2))) if x.size else float("nan")


def _quantization(y: np.ndarray) -> dict:
    out = {}
    for a, name in enumerate("xyz"):
        u = np.unique(y[:, a])
        if u.size < 3 or u.size > y.shape[0] // 2:
            out[name] = None
            continue
        lsb = float(np.min(np.diff(u)))
        k = y[:, a] / lsb
        out[name] = lsb if float(np.sqrt(np.mean((k - np.round(k)) ** 2))) < 0.01 else None
    return out


def _checks(rec: Recording, check) -> Checks:
    return Checks(_quantization(np.asarray(rec.gyro_rad_s)), int(check.saturated.sum()), tuple(check.warnings))


def _attitude_rms(rec: Recording, corrected: np.ndarray) -> float | None:
    """Strapdown orientation error RMS (°) over the movement phase (BROAD's definition: the
    ``movement`` mask; else the whole record), integrated from its first sample with the reference
    orientation there.  Not held out: one integration over fit and held-out stretches alike."""
    tr = rec.truth
    if tr is None or tr.quat_nb is None:
        return None
    q_ref = np.asarray(tr.quat_nb)
    move = tr.extra.get("movement")
    mask = np.asarray(move, bool) if move is not None else np.ones(rec.t_s.size, bool)
    idx = np.flatnonzero(mask)
    a, b = int(idx[0]), int(idx[-1]) + 1
    start = a + int(np.argmax(np.all(np.isfinite(q_ref[a:b]), axis=1)))
    q = integrate_gyro(rec.t_s[start:b], corrected[start:b], q_ref[start])
    err = quat_angle_between(q, q_ref[start:b])
    ok = mask[start:b] & np.isfinite(err)
    return float(np.sqrt(np.mean(err[ok] ** 2)) * RAD2DEG)


def _row_display(ref: Reference) -> tuple[str, float]:
    """How the residual rows are shown: (unit, factor from the rows' unit): rate rows in °/s,
    self-consistency rows (weighted, dimensionless) as they are."""
    return ("°/s", RAD2DEG) if ref.row_unit == "rad/s" else ("weighted", 1.0)


def _errors(setup: LoopSetup, state: ModelState) -> dict[str, float]:
    """Held-out errors of a model: residual RMS, the reference's own split (gravity: rest rate and tilt),
    every held-out metric, and the strapdown orientation over the movement (not held out)."""
    ref = setup.ref
    held = setup.held_rows
    unit, scale = _row_display(ref)
    out: dict = {"held_out_residual_rms": _rms(state.fit.residual[held]) * scale, "unit": unit}
    if isinstance(ref, GravityReference):
        out.update(ref.split_rms(state.fit.residual, held))
    for name, m in state.metrics(setup).items():
        out.setdefault(name, m.value)
    att = _attitude_rms(setup.rec, state.corrected_gyro())
    if att is not None:
        out["strapdown_orientation_rms_deg"] = att
    return out


def _residual_without(setup: LoopSetup, final: ModelState, index: int):
    def compute():
        ref = setup.ref
        if not isinstance(ref, RateReference):
            return None
        terms = tuple(t for i, t in enumerate(final.terms) if i != index)
        fit = fit_model(ref, terms, final.gyro_rad_s)
        return ref.row_time_s.reshape(-1, 3)[:, 0], fit.residual.reshape(-1, 3)
    return compute


def _gain_given_the_others(setup: LoopSetup, final: ModelState, index: int) -> float | None:
    """Held-out G of ``final.terms[index]`` added last: the final model refitted without it (fit rows), scored
    with it on the held-out rows (:func:`calib.closeloop.fit.held_out_score`); None for an output-stage term."""
    term = final.terms[index]
    if term.family.output_stage:
        return None
    without = refit(setup, tuple(t for i, t in enumerate(final.terms) if i != index))
    score = held_out_score(setup.ref, without.terms, without.fit, [term], without.gyro_rad_s)
    return float(score.gain) if math.isfinite(score.gain) else None


def _finding(setup: LoopSetup, final: ModelState, full: FitResult, index: int, rnd: Round[ModelState],
             given_others: float | None) -> Finding:
    """A term the loop added (``final.terms[index]``, added in round ``rnd``): its parameters and σ from
    the fit on every row (``full``), its family's summary, the evidence and the trace that says why."""
    term = final.terms[index]
    fam = term.family
    sig = np.sqrt(np.maximum(np.diag(full.cov), 0.0))
    i0 = sum(t.n_params for t in final.terms[:index])
    vals, sigs = full.theta[i0 : i0 + term.n_params], sig[i0 : i0 + term.n_params]
    fitted = FittedTerm(term.kind, term.param_names, vals, sigs, term.to_effect(vals), final.totals.get(term.kind),
                        _residual_without(setup, final, index), term)
    rep = fam.report(term.kind, fitted)
    s = rnd.score
    group = rnd.confounded
    metrics = rnd.pick.metrics
    evidence = RateEvidence(rnd.round, s.gain, s.added_parameters, s.n_eff, s.held_out_rms_before,
                            s.held_out_rms_after, term.follows, group.rivals if group is not None else [],
                            rnd.excitation, metrics, rep.summary, given_others)
    unit, scale = _row_display(setup.ref)
    trace = trace_of(term.follows, rep.summary, "residual", s.held_out_rms_before * scale, s.held_out_rms_after * scale,
                     unit, s.gain, s.added_parameters, metrics, "held_out_residual_rms")
    caveat = fam.caveat(term.kind, setup.ref.kind)
    if caveat:
        trace += f" — {caveat}"
    if group is not None:
        trace += (f". Confounded with {overlap_summary(group, exclude=(term.kind,))}: they explain the same residual "
                  f"here; chosen by the stated rule (under not_distinguished). What would separate them: "
                  f"{group.separate_by}")
    return Finding(term.kind, rep.params, _jsonable(rep.effect.to_dict()), evidence, trace)


def _declared_params(terms: tuple[Candidate, ...], full: FitResult) -> dict[str, dict[str, float]]:
    """The declared terms' parameters (value, σ) from the fit on every row."""
    sig = np.sqrt(np.maximum(np.diag(full.cov), 0.0))
    out: dict[str, dict[str, float]] = {}
    i = 0
    for t in terms:
        for j, name in enumerate(t.param_names):
            out[name] = {"value": float(full.theta[i + j]), "sigma": float(sig[i + j])}
        i += t.n_params
    return out


def _weakly_determined(declared_params: dict[str, dict[str, float]]) -> list[str]:
    """Dimensionless axis errors (the families with a finite fit box) whose σ exceeds 0.1 %."""
    return [f"{k} ± {v['sigma'] * 100:.2g} %" for k, v in declared_params.items()
            if math.isfinite(family_bound(k.split(".")[0])) and v["sigma"] > 1e-3]


def _report(setup: LoopSetup, check, declared: list[str], trace: LoopTrace[ModelState]) -> CloseloopResult:
    """Step 6 of the module docstring: parameters on all rows (σ: :func:`_final_covariance`), errors
    and metrics on the held-out rows, declared → after the loop, and what the residual still holds."""
    ref = setup.ref
    declared_state, state = trace.declared, trace.final
    notes = list(ref.notes) + list(check.warnings)
    p_decl = sum(t.n_params for t in declared_state.terms)
    if declared_state.fit.rank < p_decl:
        notes.append(f"the declared model has {p_decl} parameters but the recording identifies only "
                     f"{declared_state.fit.rank}: the motion does not excite all of them")
    full_state = refit(setup, state.terms, base=state, theta0=state.fit.theta, rows=np.ones(ref.groups.size, bool))
    full = _final_covariance(setup, full_state)
    n_decl = len(declared)
    declared_params = _declared_params(full_state.terms[:n_decl], full)
    weak = _weakly_determined(declared_params)
    if weak:
        notes.append("weakly determined (σ > 0.1 %: little motion excites them): " + ", ".join(weak))
    added = trace.added
    # with one finding, "added last" is its own round; with more, each is refitted without it
    given = ([_gain_given_the_others(setup, state, n_decl + k) for k in range(len(added))] if len(added) > 1
             else [r.score.gain for r in added])
    found = [_finding(setup, full_state, full, n_decl + k, r, given[k]) for k, r in enumerate(added)]

    err_b, err_a = _errors(setup, declared_state), _errors(setup, state)
    raw = _attitude_rms(setup.rec, setup.measured_gyro)
    if raw is not None:
        err_b["strapdown_orientation_rms_deg_raw_gyro"] = raw
    metrics = compare_metrics(declared_state.metrics(setup), state.metrics(setup)) if added else []
    rejected = trace.rejected
    disagreements = [f"{r.effect} (round {r.round}): {r.disagreement}" for r in rejected if r.disagreement]
    final_dis = explain_disagreement(metrics, f"the {ref.kind} reference's residual rows", None)
    if final_dis:
        disagreements.append(f"after the loop: {final_dis}")
    tested = trace.tested
    not_tested = trace.not_tested_text()
    if not tested and not found:
        notes.insert(0, "nothing could be tested on this recording: no candidate is identifiable here "
                        f"({len(not_tested)} reasons under not_tested)")
    follows = {t.kind: t.follows_series for t in full_state.terms[n_decl:] if t.follows_series is not None}
    return CloseloopResult(
        reference=ref.kind, reference_description=ref.description, notes=notes, declared=declared,
        declared_params=declared_params, found=found,
        unexplained=_unexplained(ref, setup.rec, state.fit.residual, setup.held_rows), not_tested=not_tested,
        not_distinguished=trace.not_distinguished, error_before=err_b, error_after=err_a,
        checks=_checks(setup.rec, check), rounds=list(trace.rounds), metrics=metrics, rejected=rejected,
        disagreements=disagreements, tested=tested, row_time_s=ref.row_time_s, row_axis=ref.row_axis,
        held_out_rows=setup.held_rows, residual_before=declared_state.fit.residual, residual_after=state.fit.residual,
        follows_series=follows, rows_of=ref.rows_of if isinstance(ref, RateReference) else None)


def _final_covariance(setup: LoopSetup, final: ModelState) -> FitResult:
    """The final fit's covariance: cluster-robust over the held-out stretches, plus what each term's
    own stochastic part adds (the drift the spline leaves between its knots)."""
    ref = setup.ref
    if not ref.linear or final.fit.theta.size == 0:
        return final.fit
    j = design_rows(ref, final.terms, final.gyro_rad_s)
    fit = cluster_robust(ref, final.fit, j)
    f0 = final.fit
    influence = (f0.cov / (f0.sigma**2 * f0.tau_int)) @ j.T if f0.sigma > 0 else None
    cov = fit.cov
    for i, t in enumerate(final.terms):
        extra = (
            t.family.extra_covariance(t, influence, ref, _residual_without(setup, final, i))
            if influence is not None
            else None
        )
        if extra is not None:
            cov = cov + extra
    return replace(fit, cov=cov)


def family_bound(kind: str) -> float:
    fam = family_for(kind)
    return math.inf if isinstance(fam, Untestable) else fam.bound


def _no_reference(rec: Recording, declared: list[str], err: NoReferenceError, check) -> CloseloopResult:
    """The report of a recording that cannot separate candidates: say why, guess nothing."""
    kinds = [k for k in candidate_kinds() if k not in declared]
    return CloseloopResult(
        reference="none", reference_description="no usable reference",
        notes=[f"nothing could be tested on this recording: {err}"] + list(check.warnings), declared=declared,
        declared_params={}, found=[], unexplained=Unexplained(summary="not analysed: no reference"),
        not_tested={k: NotTaken("no_reference", str(err)).text for k in kinds}, not_distinguished=[],
        error_before={}, error_after={}, checks=_checks(rec, check), rounds=[])


def _jsonable(d: dict) -> dict:
    out = {}
    for k, v in d.items():
        if isinstance(v, float) and not math.isfinite(v):
            out[k] = str(v)
        elif isinstance(v, tuple):
            out[k] = list(v)
        else:
            out[k] = v
    return out


def _channels(ref: RateReference, rec: Recording) -> dict[str, np.ndarray]:
    ctx = ref.ctx
    per = {f"gyro_{a}": rec.gyro_rad_s[:, i] for i, a in enumerate("xyz")}
    per.update({f"acc_{a}": rec.acc_m_s2[:, i] for i, a in enumerate("xyz")})
    per["|f| - g"] = np.linalg.norm(rec.acc_m_s2, axis=1) - G0
    per["|omega|"] = np.linalg.norm(ctx.omega_true_rad_s, axis=1)
    dw = np.gradient(ctx.omega_true_rad_s, ctx.t_s, axis=0)
    per.update({f"domega_{a}/dt": dw[:, i] for i, a in enumerate("xyz")})
    if rec.temp_c is not None:
        per["temperature"] = rec.temp_c
        per["dT/dt"] = np.gradient(rec.temp_c, rec.t_s)
    if ctx.mag_body_ut is not None:
        per.update({f"mag_{a}": ctx.mag_body_ut[:, i] for i, a in enumerate("xyz")})
    per["time"] = rec.t_s
    out = {}
    for k, v in per.items():
        b = ref.rows_of(np.repeat(np.asarray(v, float)[:, None], 3, axis=1)).reshape(-1, 3)[:, 0]
        if np.ptp(b) > 0:
            out[k] = b
    return out


def _unexplained(ref: Reference, rec: Recording, r: np.ndarray, held: np.ndarray) -> Unexplained:
    if not isinstance(ref, RateReference):
        groups = ref.groups
        worst = int(groups[np.argmax(np.abs(r))])
        return Unexplained(summary=f"self-consistency rows are per pose, not a time series: no spectral or channel "
                                   f"tests; largest weighted residual {np.max(np.abs(r)):.2f} at pose {worst}")
    blocks = r.reshape(-1, 3)
    fs = 1.0 / (float(np.median(np.diff(rec.t_s))) * ref.block)
    lines = spectral_lines(blocks, fs)
    corr = channel_correlations(blocks, _channels(ref, rec))
    white = whiteness(blocks)
    parts = []
    if lines:
        l0 = lines[0]
        parts.append(
            f"spectral line at {l0.frequency_hz:.2f} Hz on {l0.axis} (amplitude {l0.amplitude_rad_s * RAD2DEG:.3g} "
            f"°/s, {l0.ratio:.0f}× the background)" + (f" and {len(lines) - 1} more" if len(lines) > 1 else "")
        )
    if corr:
        c0 = corr[0]
        parts.append(f"residual {c0.axis} correlates with {c0.channel} (ρ = {c0.rho:.3f}, {c0.z:.1f}σ)"
                     + (f" and {len(corr) - 1} more channel pairs" if len(corr) > 1 else ""))
    dw = ref.rows_of(np.gradient(ref.ctx.omega_true_rad_s, ref.ctx.t_s, axis=0)).reshape(-1, 3)
    jitter = variance_growth(blocks, dw)
    if jitter:
        parts.append(f"residual variance grows with (dω/dt)² as sampling-time jitter of {jitter.jitter_s * 1e3:.2f} ms "
                     f"would ({jitter.z:.1f}σ)")
    taus = [white[f"tau_int_{a}"] for a in "xyz"]
    parts.append(f"residual autocorrelation time {min(taus):.1f}–{max(taus):.1f} samples (1 = white)")
    return Unexplained(tuple(lines), tuple(corr), white, jitter, "; ".join(parts))
