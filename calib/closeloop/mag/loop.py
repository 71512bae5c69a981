"""The loop on the magnetometer channel: name what the declared magnetometer model lacks, under the
same rules as the gyro's, and report a local anomaly as unexplained structure.

Steps (each reusing the gyro loop's rule where it applies):

0. **reference** (:mod:`calib.closeloop.mag.reference`): attitude (vector residual) or magnitude;
   fit / held-out stretches of 4 s.
1. **disturbances first**: the model with every buildable candidate is fitted on the fit stretches
   and :func:`calib.mag.disturbance.find_disturbances` run on its residual, refitting without the
   flagged samples until the set stops changing (≤ 3 passes).  The richest model is used so that
   a missing sensor term (which turns with the board, everywhere) is not taken for a local field;
   what remains local is a field that changes with where the board is.  The flagged samples are
   left out of every fit and metric: the anomaly is never absorbed, and it is reported.
2. **rounds** (:mod:`calib.closeloop.mag.select`, run by :mod:`calib.closeloop.driver`): gate →
   held-out gain → confounding → acceptance on every metric → add, until a round adds nothing.
3. **report**: parameters (fitted on every stretch, block-sandwich σ), the trace of each finding,
   what could not be tested and why, and the unexplained structure: disturbances (time, size,
   position when known) and the residual's level against the magnetometer's own noise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gyrosim.effects import EFFECTS
from gyrosim.errors import RecordingError
from gyrosim.recording import Recording

from calib.closeloop.driver import LoopTrace, NotTaken, Round, run_rounds
from calib.closeloop.fit import integrated_time
from calib.closeloop.identify import Excitation
from calib.closeloop.jsonview import JsonView
from calib.closeloop.mag.fit import MagFit, fit_mag
from calib.closeloop.mag.identify import mag_excitation
from calib.closeloop.mag.metrics import detect_disturbances
from calib.closeloop.mag.reference import MagReference, build_mag_reference
from calib.closeloop.mag.select import MAG_RULE, MagSetup, MagSteps, noise_of
from calib.closeloop.mag.terms import MAG_TERMS, mag_term
from calib.closeloop.metrics import MetricChange, compare_metrics, explain_disagreement
from calib.closeloop.result import Finding, LoopReport, trace_of

__all__ = ["MagFinding", "MagEvidence", "MagUnexplained", "MagLoopResult", "run_mag_loop", "MAG_RULE",
           "reference_frame_note", "not_analysed"]

#: a magnetometer finding is a :class:`~calib.closeloop.result.Finding` (µT, rad)
MagFinding = Finding

#: the magnetometer part of report.json, in the order it is written
JSON_KEYS = ("reference", "reference_description", "notes", "declared", "declared_params", "found", "unexplained",
             "not_tested", "not_distinguished", "error_before", "error_after", "metrics", "rejected", "rounds",
             "identifiability", "tested")


@dataclass(frozen=True)
class MagEvidence(JsonView):
    """Why a magnetometer effect was added: its round, held-out gain G, the held-out field residual RMS
    before → after (µT), the gate's verdict, the metrics' changes, the rivals it was confounded with."""

    round: int
    criterion_gain: float
    held_out_rms_before_uT: float
    held_out_rms_after_uT: float
    identifiability: Excitation
    metrics: tuple[MetricChange, ...]
    rivals: list[str]
    summary: str

    def to_json(self) -> dict:
        return {"round": self.round, "criterion_gain": self.criterion_gain,
                "held_out_rms_before_uT": self.held_out_rms_before_uT,
                "held_out_rms_after_uT": self.held_out_rms_after_uT, "identifiability": self.identifiability.to_json(),
                "metrics": [m.to_json() for m in self.metrics], "rivals": self.rivals, "summary": self.summary}


@dataclass(frozen=True)
class MagUnexplained(JsonView):
    """What the final field residual still holds: local disturbances (excluded from every fit) and the
    residual's level against the magnetometer's white noise (µT).  ``analysed=False``: the channel
    was not analysed, and ``report.json`` shows ``{}``."""

    disturbances: tuple[dict, ...] = ()
    disturbed_samples: int = 0
    residual_rms_uT: float = math.nan
    white_noise_uT: float = math.nan
    ratio_to_noise: float = math.nan
    tau_int_samples: float = math.nan
    summary: str = ""
    analysed: bool = True

    def to_json(self) -> dict:
        if not self.analysed:
            return {}
        return {"disturbances": list(self.disturbances), "disturbed_samples": self.disturbed_samples,
                "residual_rms_uT": self.residual_rms_uT, "white_noise_uT": self.white_noise_uT,
                "ratio_to_noise": self.ratio_to_noise, "tau_int_samples": self.tau_int_samples,
                "summary": self.summary}


@dataclass(frozen=True, kw_only=True)
class MagLoopResult(LoopReport, JsonView):
    """The magnetometer loop's report (rounds' held-out RMS in µT)."""

    unexplained: MagUnexplained

    @property
    def identifiability(self) -> list[Excitation]:
        return [e for r in self.rounds for e in r.excitations]

    @property
    def disturbances(self) -> list[dict]:
        return list(self.unexplained.disturbances)

    def to_json(self) -> dict:
        return {k: self._json(k) for k in JSON_KEYS}


def not_analysed(why: str) -> MagLoopResult:
    """The magnetometer part of a report when the channel cannot be used (said, nothing guessed)."""
    return MagLoopResult(reference="none", reference_description="not analysed",
                         notes=[f"magnetometer not analysed: {why}"], declared=[], declared_params={}, found=[],
                         unexplained=MagUnexplained(analysed=False),
                         not_tested={k: NotTaken("not_analysed", why).text for k in MAG_TERMS}, not_distinguished=[],
                         error_before={}, error_after={})


# ================================================================ steps
def _disturbance_mask(ref: MagReference, kinds: tuple[str, ...]) -> tuple[np.ndarray, MagFit]:
    """Step 1 of the module docstring: the disturbance mask of the richest model."""
    exclude = np.zeros(ref.t_s.size, bool)
    f = fit_mag(ref, kinds, ref.rows(held=False))
    for _ in range(3):
        new, _ = detect_disturbances(ref, f)
        if np.array_equal(new, exclude):
            break
        exclude = new
        f = fit_mag(ref, kinds, ref.rows(held=False, exclude=exclude), f.theta)
    return exclude, f


def _params(ref: MagReference, f: MagFit, kind: str) -> tuple[np.ndarray, np.ndarray]:
    i = (3 if ref.has_attitude else 1) + sum(mag_term(k).n_params for k in f.kinds[: f.kinds.index(kind)])
    n = mag_term(kind).n_params
    sig = np.sqrt(np.maximum(np.diag(f.cov), 0.0))
    return f.theta[i : i + n], sig[i : i + n]


def _jsonable_effect(e) -> dict:
    out = {}
    for k, v in e.to_dict().items():
        out[k] = v.tolist() if isinstance(v, np.ndarray) else list(v) if isinstance(v, tuple) else v
    return out


def reference_frame_note(mag: MagLoopResult, gyro_axes: np.ndarray | None) -> str | None:
    """When the magnetometer's ``frame_rotation`` was found against a reference that also fitted the
    gyro's axes: compare the magnetometer's rotation θ with the rotation part of the gyro's fitted
    axis matrix M (declared non-orthogonality plus any misalignment found, y = (I + S + M) ω; its
    antisymmetric part [a]×).  A rotation of the reference's body frame against the IMU frame acts on
    both sensors alike: m ≈ (I − [θ]×) b and y ≈ (I + [a]×) ω with a = −θ.  Agreement points to the
    reference frame, not to the magnetometer."""
    f = next((x for x in mag.found if EFFECTS[x.effect].axis_rotation), None)
    if f is None or gyro_axes is None:
        return None
    theta = np.array([v["value"] for v in f.params.values()])
    m = np.asarray(gyro_axes, float)
    a = 0.5 * np.array([m[2, 1] - m[1, 2], m[0, 2] - m[2, 0], m[1, 0] - m[0, 1]])
    d = np.degrees(np.linalg.norm(theta + a))
    deg = lambda x: ", ".join(f"{y:.2f}" for y in np.degrees(x))  # noqa: E731
    same = d < 0.5 * max(np.degrees(np.linalg.norm(theta)), 1e-9)
    return (f"the magnetometer's frame_rotation ({deg(theta)})° and the rotation part of the gyro's fitted axes "
            f"against the same reference (−a = {deg(-a)})° differ by {d:.2f}°: "
            + ("the same rotation seen by both sensors — most likely the reference's body frame against the IMU "
               "frame, not the magnetometer's own misalignment" if same else
               "not the same rotation — the magnetometer's axes are rotated against the IMU's beyond what the "
               "reference frame explains"))


# ================================================================ the loop
def run_mag_loop(rec: Recording, declared: tuple[str, ...] | list[str] = (), *, holdout_s: float = 4.0,
                 candidates: list[str] | None = None, max_rounds: int = 4, reference: str | None = None
                 ) -> MagLoopResult:
    """The module docstring's loop on ``rec``'s magnetometer channel (``declared``: magnetometer
    kinds the user's model already holds; ``candidates``: restrict the pool)."""
    if rec.mag_ut is None:
        return not_analysed("the recording has no magnetometer channel")
    try:
        ref = build_mag_reference(rec, holdout_s, reference)
    except RecordingError as err:
        return not_analysed(str(err))
    declared = tuple(declared)
    for k in declared:
        if mag_term(k).needs_attitude and not ref.has_attitude:
            raise RecordingError(f"declared magnetometer effect {k!r} needs an attitude reference, which this "
                                 "recording lacks")
    pool, not_tested = _candidates(ref, declared, candidates)
    exclude, rich = _disturbance_mask(ref, declared + tuple(pool))
    setup = MagSetup(ref, exclude, *noise_of(ref, rich, exclude))
    trace = run_rounds(MagSteps(setup), setup.fit(declared), pool, not_tested, max_rounds)
    return _report(setup, declared, trace)


def _candidates(ref: MagReference, declared: tuple[str, ...], kinds: list[str] | None
                ) -> tuple[dict[str, str], dict[str, NotTaken]]:
    """The magnetometer kinds not declared (or ``kinds``); one that needs an attitude the recording
    lacks is left out with the gate's reason."""
    pool: dict[str, str] = {}
    not_tested: dict[str, NotTaken] = {}
    for k in kinds if kinds is not None else MAG_TERMS:
        if k in declared:
            continue
        if mag_term(k).needs_attitude and not ref.has_attitude:
            exc = mag_excitation(ref, fit_mag(ref, declared, ref.rows(held=False)), k, ref.valid, ref.noise_ut)
            not_tested[k] = NotTaken("not_buildable", exc.reason)
        else:
            pool[k] = k
    return pool, not_tested


def _finding(ref: MagReference, final: MagFit, rnd: Round[MagFit]) -> Finding:
    """The term added in round ``rnd``: parameters from the fit on every stretch, evidence and trace."""
    k = rnd.added
    term = mag_term(k)
    v, s = _params(ref, final, k)
    summ = term.summary(v, s)
    score, changes, g = rnd.score, rnd.pick.metrics, rnd.confounded
    trace = trace_of(term.driver, summ, "field residual", score.held_out_rms_before, score.held_out_rms_after, "µT",
                     score.gain, term.n_params, changes, "held_out_field_residual_rms")
    if EFFECTS[k].axis_rotation and ref.source == "optical":
        trace += (" — against an optical reference, a rotation between the optical body frame and the IMU frame "
                  "looks exactly like this; a misalignment the gyro loop finds against the same reference points "
                  "to the reference frame, not the magnetometer")
    if g is not None:
        trace += f". Confounded with {', '.join(g.rivals)} (under not_distinguished); separated by: {g.separate_by}"
    params = {n: {"value": float(x), "sigma": float(y)} for n, x, y in zip(term.param_names, v, s)}
    evidence = MagEvidence(rnd.round, score.gain, score.held_out_rms_before, score.held_out_rms_after, rnd.excitation,
                           changes, g.rivals if g is not None else [], summ)
    return Finding(k, params, _jsonable_effect(term.to_effect(v)), evidence, trace)


def _report(c: MagSetup, declared: tuple[str, ...], trace: LoopTrace[MagFit]) -> MagLoopResult:
    """Step 3 of the module docstring: parameters fitted on every stretch (block-sandwich σ), held-out
    metrics declared → after the loop, and the structure the final residual still holds."""
    ref = c.ref
    declared_fit, cur = trace.declared, trace.final
    final = c.fit(cur.kinds, cur, rows=ref.valid & ~c.exclude)        # parameters on every stretch
    declared_params = {}
    for k in declared:
        v, s = _params(ref, final, k)
        for n, a, b in zip(mag_term(k).param_names, v, s):
            declared_params[f"{k}.{n}"] = {"value": float(a), "sigma": float(b)}
    base = final.theta[: 3 if ref.has_attitude else 1]
    found = [_finding(ref, final, r) for r in trace.added]
    m_before, m_after = c.metrics(declared_fit), c.metrics(cur)
    metrics = compare_metrics(m_before, m_after) if found else []
    err_b = {k: v.value for k, v in m_before.items()}
    err_a = {k: v.value for k, v in m_after.items()}
    notes = list(ref.warnings)
    if ref.saturated:
        notes.append(f"{ref.saturated} saturated magnetometer samples excluded")
    dis = explain_disagreement(metrics, "the magnetometer's residual rows", None)
    tested = trace.tested
    not_tested = trace.not_tested_text()
    if not tested and not found:
        notes.insert(0, f"nothing could be tested on the magnetometer: no candidate is identifiable here "
                        f"({len(not_tested)} reasons under not_tested)")
    unexplained = _unexplained(c, final, base, list(not_tested))
    if dis:
        notes.append(f"after the loop: {dis}")
    return MagLoopResult(reference=f"magnetometer/{ref.kind} ({ref.source})", reference_description=ref.description,
                         notes=notes, declared=list(declared), declared_params=declared_params, found=found,
                         unexplained=unexplained, not_tested=not_tested, not_distinguished=trace.not_distinguished,
                         error_before=err_b, error_after=err_a, metrics=metrics, rejected=trace.rejected,
                         rounds=list(trace.rounds), tested=tested)


def _unexplained(c: MagSetup, final: MagFit, base: np.ndarray, untested: list[str]) -> MagUnexplained:
    """Local disturbances of the final model's residual (:func:`calib.mag.disturbance.find_disturbances`)
    and the held-out residual outside them against the magnetometer's white noise σ_w: its RMS, the
    ratio RMS / σ_w and the autocorrelation time τ_int (1 sample = white)."""
    ref = c.ref
    mask, dist = detect_disturbances(ref, final)
    parts = []
    for d in dist:
        where = (f" near ({', '.join(f'{x:.2f}' for x in d.position_nav_m)}) m ENU"
                 if d.position_nav_m is not None else "")
        parts.append(f"local disturbance {d.t_start_s:.1f}–{d.t_end_s:.1f} s: the field magnitude leaves the fitted "
                     f"{np.linalg.norm(base):.1f} µT by up to {d.max_field_deviation_ut:.2f} µT"
                     + (f", the inclination by up to {d.max_inclination_deviation_deg:.2f}°"
                        if math.isfinite(d.max_inclination_deviation_deg) else "") + where
                     + " — a field that changes with where the board is (or when: a magnet brought near, attached, "
                       "taken off): excluded from the fit, not absorbed")
    held = ref.rows(held=True, exclude=mask | c.exclude)
    r = final.residual[held]
    rms = float(np.sqrt(np.mean(r**2))) if r.size else math.nan
    ratio = rms / ref.noise_ut
    tau = float(np.mean([integrated_time(r[:, a]) for a in range(r.shape[1])])) if r.size else math.nan
    if ref.noise_ut < 0.01:
        parts.append(f"residual {rms:.3g} µT with autocorrelation time {tau:.0f} samples; the field samples have no "
                     "white noise to compare with (read slower than the log and interpolated, or filtered)")
    elif ratio > 2.0:
        causes = ["the reference attitude's own error", "a time offset between reference and magnetometer"] \
            if ref.has_attitude else []
        if untested:
            causes.append(f"the candidates that could not be tested here ({', '.join(untested)})")
        causes.append("a field that varies over the room")
        parts.append(f"the residual outside disturbances is {ratio:.1f}× the magnetometer's white noise "
                     f"({ref.noise_ut:.2f} µT) with autocorrelation time {tau:.0f} samples: structure no candidate "
                     f"explains ({', '.join(causes)})")
    else:
        parts.append(f"residual {rms:.3g} µT = {ratio:.2f}× the magnetometer's white noise ({ref.noise_ut:.2f} µT), "
                     f"autocorrelation time {tau:.1f} samples")
    return MagUnexplained(tuple(d.to_dict() for d in dist), int(mask.sum()), rms, ref.noise_ut, ratio, tau,
                          "; ".join(parts))
