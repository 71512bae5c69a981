"""One round of the loop: gate → score → confounding → acceptance on every metric → add (or not).

1. **Gate** (:mod:`calib.closeloop.identify`): every candidate left in the pool is checked for
   identifiability against the current model; one that fails leaves the pool with its reason.
2. **Score** (:func:`calib.closeloop.fit.held_out_score`): held-out gain G of each identifiable
   candidate; a positive G whose fitted parameters are physically implausible is refused.
3. **Confounding** (:mod:`calib.closeloop.confounding`): the best candidate tied to a measured
   channel (bias drift, a spline in time, can mimic any slow term, so it is the best only when
   nothing else has G > 0) and those that explain the same residual form a group; the rule picks
   the one that explains all the others do, else the physically direct channel first, and the drift
   only over a partial mimic of it.
4. **Acceptance** (:mod:`calib.closeloop.metrics`): the model with the pick, fitted on the fit
   rows, must leave no held-out metric worse beyond its noise, against the current model and
   against the declared one.  A refused pick is reported (with the metrics' disagreement, if any)
   and the next best is tried.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from .candidates import Candidate
from .confounding import ConfoundedGroup, find_confounded
from .fit import HeldOutScore, UnionDesign, held_out_score, noise_tau
from .identify import Excitation, excitation, precheck
from .metrics import MetricChange, compare_metrics, explain_disagreement
from .state import LoopSetup, ModelState, error_stage_rate, rebuild, refit

__all__ = ["CandidateScore", "Rejection", "RoundOutcome", "run_round"]


@dataclass(frozen=True)
class CandidateScore:
    """One row of a round's table (``report.json`` ``rounds``)."""

    effect: str
    gain: float | None
    added_parameters: int
    held_out_rms_before: float
    held_out_rms_after: float
    n_eff: float
    rejected: str | None = None

    def to_json(self) -> dict:
        d = asdict(self)
        if d["rejected"] is None:
            d.pop("rejected")
        return d


@dataclass(frozen=True)
class Rejection:
    """A pick the acceptance step refused: the metric changes and, when they disagree, why."""

    round: int
    effect: str
    against: str                          # "the current model" or "the declared model"
    metrics: tuple[MetricChange, ...]
    disagreement: str | None
    why: str

    def to_json(self) -> dict:
        return {"round": self.round, "effect": self.effect, "against": self.against, "why": self.why,
                "disagreement": self.disagreement, "metrics": [m.to_json() for m in self.metrics]}


@dataclass(frozen=True)
class RoundOutcome:
    round: int
    scores: tuple[CandidateScore, ...]
    excitations: tuple[Excitation, ...]
    added: str | None
    state: ModelState
    score: HeldOutScore | None             # the added term's held-out score
    metrics: tuple[MetricChange, ...]      # the added term's metric changes against the current model
    confounded: ConfoundedGroup | None
    rejections: tuple[Rejection, ...]


def _accept(setup: LoopSetup, state: ModelState, declared: ModelState, new: ModelState, kind: str, rnd: int,
            cand: Candidate) -> tuple[tuple[MetricChange, ...], Rejection | None]:
    fitted_on = f"the {setup.ref.kind} reference's residual rows"
    caveat = cand.family.caveat(kind, setup.ref.kind)
    current = tuple(compare_metrics(state.metrics(setup), new.metrics(setup)))
    checks = [("the current model", current)]
    if state is not declared:
        checks.append(("the declared model", tuple(compare_metrics(declared.metrics(setup), new.metrics(setup)))))
    for against, changes in checks:
        worse = [c for c in changes if c.verdict == "worse"]
        if worse:
            why = (f"adding {kind} makes {', '.join(c.describe() for c in worse)} worse than {against} beyond its noise "
                   f"(z > {worse[0].threshold:.2f})")
            return current, Rejection(rnd, kind, against, changes, explain_disagreement(list(changes), fitted_on, caveat),
                                      why)
    return current, None


def run_round(setup: LoopSetup, state: ModelState, declared: ModelState, pool: dict[str, Candidate],
              rnd: int) -> tuple[RoundOutcome, dict[str, Candidate], dict[str, str]]:
    """Run round ``rnd`` (1-based); returns its outcome, the pool left, and why candidates were not
    taken this round (kind → reason: not identifiable now, or refused).  A candidate that is not
    identifiable stays in the pool: once another term explains its part of the residual, its own
    excitation may show (it is gated again next round); a refused one leaves the pool."""
    rate = error_stage_rate(setup.ref, state.terms, [np.zeros(t.n_params) if t.family.output_stage else th
                                                     for t, th in zip(state.terms, state.thetas())])
    pool = {k: (rebuild(setup, c, rate) if c.family.output_stage else c) for k, c in pool.items()}
    gone: dict[str, str] = {}
    pre = {k: precheck(setup.ref, c) for k, c in pool.items()}
    union = tau = None
    if setup.ref.linear and any(p is None for p in pre.values()):
        union = UnionDesign(setup.ref, state.terms, {k: c for k, c in pool.items() if pre[k] is None}, state.gyro_rad_s)
        tau = noise_tau(union)
    exc: dict[str, Excitation] = {}
    scores: dict[str, HeldOutScore] = {}
    table: list[CandidateScore] = []
    implausible: dict[str, str] = {}
    for kind, c in pool.items():
        setup.say(f"round {rnd}: testing {kind}")
        if pre[kind] is not None:
            exc[kind] = pre[kind]
            gone[kind] = f"not identifiable on this recording: {pre[kind].reason}"
            continue
        s = held_out_score(setup.ref, state.terms, state.fit, [c], state.gyro_rad_s, tau, union)
        exc[kind] = excitation(setup.ref, state.terms, state.fit, c, state.gyro_rad_s, setup.fit_rows, s.fit)
        if not exc[kind].identifiable:
            gone[kind] = f"not identifiable on this recording: {exc[kind].reason}"
            continue
        scores[kind] = s
        p0 = state.fit.theta.size
        sig_new = np.sqrt(np.maximum(np.diag(s.fit.cov), 0.0))[p0:]
        why = c.family.implausible(kind, s.theta_new, sig_new, setup.ref.ctx) if s.gain > 0 else None
        if why:
            implausible[kind] = why
        table.append(CandidateScore(kind, s.gain if math.isfinite(s.gain) else None, s.added_rank, s.rms_before,
                                    s.rms_after, s.n_eff, why))
    table.sort(key=lambda r: -(r.gain if r.gain is not None else -math.inf))

    live = {k: s for k, s in scores.items() if s.gain > 0 and s.added_rank > 0 and k not in implausible}
    rejections: list[Rejection] = []
    while live:
        measured = [k for k in live if not pool[k].family.catch_all] or list(live)
        best = max(measured, key=lambda k: live[k].gain)
        chosen, group = find_confounded(setup, state, pool, live, best, rnd, tau, union)
        cand = pool[chosen]
        if union is not None and not any(t.family.output_stage for t in state.terms + (cand,)):
            new = ModelState(state.terms + (cand,), scores[chosen].fit, state.gyro_rad_s, dict(state.totals))
        else:
            new = refit(setup, state.terms + (cand,), base=state,
                        theta0=np.concatenate([state.fit.theta, np.zeros(cand.n_params)]))
        changes, rejection = _accept(setup, state, declared, new, chosen, rnd, cand)
        if rejection is None:
            rest = {k: c for k, c in pool.items() if k != chosen}
            outcome = RoundOutcome(rnd, tuple(table), tuple(exc.values()), chosen, new, scores[chosen], changes,
                                   group, tuple(rejections))
            return outcome, rest, gone
        rejections.append(rejection)
        gone[chosen] = f"refused by the acceptance on every metric: {rejection.why}"
        live.pop(chosen)
        pool = {k: c for k, c in pool.items() if k != chosen}
    return RoundOutcome(rnd, tuple(table), tuple(exc.values()), None, state, None, (), None, tuple(rejections)), pool, gone
