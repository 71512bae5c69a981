"""The gyro loop's round steps (:class:`GyroSteps`, run by :mod:`calib.closeloop.driver`): gate →
score → confounding → acceptance on every metric → add (or not).

1. **Gate** (:mod:`calib.closeloop.identify`): every candidate left in the pool is checked for
   identifiability against the current model; one that fails says why and is gated again next
   round (once another term explains its part of the residual, its own excitation may show).
2. **Score** (:func:`calib.closeloop.fit.held_out_score`): held-out gain G of each identifiable
   candidate; a positive G whose fitted parameters are physically implausible is refused.
3. **Confounding** (:mod:`calib.closeloop.confounding`): the best candidate tied to a measured
   channel (bias drift, a spline in time, can mimic any slow term, so it is the best only when
   nothing else has G > 0) and those that explain the same residual form a group; the rule picks
   the one that explains all the others do, else the physically direct channel first, and the drift
   only over a partial mimic of it.
4. **Acceptance** (:func:`calib.closeloop.driver.accept_on_every_metric`): the model with the
   pick, fitted on the fit rows, must leave no held-out metric worse beyond its noise, against the
   current model and against the declared one.  A refused pick is reported (with the metrics' disagreement, if any)
   and the next best is tried.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from calib.closeloop.candidates import Candidate
from calib.closeloop.confounding import ConfoundedGroup, find_confounded
from calib.closeloop.driver import CandidateScore, NotTaken, Rejection, Scoring, accept_on_every_metric
from calib.closeloop.fit import HeldOutScore, UnionDesign, held_out_score, noise_tau
from calib.closeloop.identify import Excitation, excitation, precheck
from calib.closeloop.metrics import MetricChange
from calib.closeloop.state import LoopSetup, ModelState, error_stage_rate, rebuild, refit

__all__ = ["CandidateScore", "Rejection", "GyroSteps", "GyroWork"]


@dataclass(frozen=True)
class GyroWork:
    """What the score step keeps for the select steps: each scored candidate's held-out score (with its
    fit), the union design of the round's candidates and the noise's autocorrelation time τ_int."""

    scores: Mapping[str, HeldOutScore]
    union: UnionDesign | None
    tau: float | None


@dataclass(frozen=True)
class GyroSteps:
    """:class:`calib.closeloop.driver.SensorSteps` on the gyro's residual rows."""

    setup: LoopSetup
    rounds_on_empty_pool: bool = True

    def score(self, state: ModelState, pool: Mapping[str, Candidate], rnd: int) -> Scoring[Candidate, GyroWork]:
        """Step 1 and 2 of the module docstring.  Output-stage candidates are first rebuilt on the
        current model's error-stage rate (:func:`calib.closeloop.state.rebuild`); the union of every
        candidate's columns is reduced once and each candidate scored from it."""
        setup = self.setup
        rate = error_stage_rate(setup.ref, state.terms, [np.zeros(t.n_params) if t.family.output_stage else th
                                                         for t, th in zip(state.terms, state.thetas())])
        pool = {k: (rebuild(setup, c, rate) if c.family.output_stage else c) for k, c in pool.items()}
        not_taken: dict[str, NotTaken] = {}
        pre = {k: precheck(setup.ref, c) for k, c in pool.items()}
        union = tau = None
        if setup.ref.linear and any(p is None for p in pre.values()):
            union = UnionDesign(setup.ref, state.terms, {k: c for k, c in pool.items() if pre[k] is None},
                                state.gyro_rad_s)
            tau = noise_tau(union)
        exc: dict[str, Excitation] = {}
        scores: dict[str, HeldOutScore] = {}
        table: list[CandidateScore] = []
        implausible: set[str] = set()
        for kind, c in pool.items():
            setup.say(f"round {rnd}: testing {kind}")
            if pre[kind] is not None:
                exc[kind] = pre[kind]
                not_taken[kind] = NotTaken("not_identifiable", pre[kind].reason)
                continue
            s = held_out_score(setup.ref, state.terms, state.fit, [c], state.gyro_rad_s, tau, union)
            exc[kind] = excitation(setup.ref, state.terms, state.fit, c, state.gyro_rad_s, setup.fit_rows, s.fit)
            if not exc[kind].identifiable:
                not_taken[kind] = NotTaken("not_identifiable", exc[kind].reason)
                continue
            scores[kind] = s
            p0 = state.fit.theta.size
            sig_new = np.sqrt(np.maximum(np.diag(s.fit.cov), 0.0))[p0:]
            why = c.family.implausible(kind, s.theta_new, sig_new, setup.ref.ctx) if s.gain > 0 else None
            if why:
                implausible.add(kind)
            table.append(CandidateScore(kind, s.gain if math.isfinite(s.gain) else None, s.added_rank, s.rms_before,
                                        s.rms_after, s.n_eff, why))
        table.sort(key=lambda r: -(r.gain if r.gain is not None else -math.inf))
        live = {k: s.gain for k, s in scores.items() if s.gain > 0 and s.added_rank > 0 and k not in implausible}
        return Scoring(tuple(table), tuple(exc.values()), live, not_taken, pool, GyroWork(scores, union, tau))

    def best(self, live: Mapping[str, float], scoring: Scoring[Candidate, GyroWork]) -> str:
        """The largest gain among candidates tied to a measured channel (the catch-all bias drift, a
        spline in time that can mimic any slow term, only when nothing else is live)."""
        measured = [k for k in live if not scoring.pool[k].family.catch_all] or list(live)
        return max(measured, key=lambda k: live[k])

    def confounded(self, state: ModelState, scoring: Scoring[Candidate, GyroWork], live: Mapping[str, float],
                   best: str, rnd: int) -> tuple[str, ConfoundedGroup | None]:
        w = scoring.work
        return find_confounded(self.setup, state, dict(scoring.pool), {k: w.scores[k] for k in live}, best, rnd,
                               w.tau, w.union)

    def with_term(self, state: ModelState, scoring: Scoring[Candidate, GyroWork], kind: str) -> ModelState:
        """The fit the score step made from the union design when no output-stage term is involved;
        else a refit that undoes the output stage about the current values (:func:`calib.closeloop.state.refit`)."""
        cand = scoring.pool[kind]
        if scoring.work.union is not None and not any(t.family.output_stage for t in state.terms + (cand,)):
            return ModelState(state.terms + (cand,), scoring.work.scores[kind].fit, state.gyro_rad_s,
                              dict(state.totals))
        return refit(self.setup, state.terms + (cand,), base=state,
                     theta0=np.concatenate([state.fit.theta, np.zeros(cand.n_params)]))

    def accept(self, state: ModelState, declared: ModelState, new: ModelState, kind: str, rnd: int
               ) -> tuple[tuple[MetricChange, ...], Rejection | None]:
        setup = self.setup
        caveat = new.terms[-1].family.caveat(kind, setup.ref.kind)
        return accept_on_every_metric(state.metrics(setup), declared.metrics(setup) if state is not declared else None,
                                      new.metrics(setup), kind, rnd, f"the {setup.ref.kind} reference's residual rows",
                                      caveat)
