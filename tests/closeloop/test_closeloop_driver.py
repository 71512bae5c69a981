"""The loop's shared skeleton (calib.closeloop.driver): what the rounds do with the steps' verdicts,
independent of any sensor.  The steps here are a table: each candidate's held-out gain, which
candidates pass the gate in which round, which additions the acceptance refuses.  These are
decisions, not estimates: no tolerance is involved; the physics of each step is tested in
test_closeloop*.py on simulated, independent and measured recordings."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping

import numpy as np
import pytest

from calib.closeloop.driver import CandidateScore, NotTaken, Rejection, Scoring, accept_on_every_metric, run_rounds
from calib.closeloop.identify import Excitation
from calib.closeloop.metrics import MetricSums


@dataclass(frozen=True)
class TableSteps:
    """State: the kinds in the model (a tuple).  ``gains``: held-out gain of each kind;
    ``gated``: round → kinds not identifiable that round; ``refuse``: kinds the acceptance refuses."""

    gains: Mapping[str, float]
    gated: Mapping[int, set[str]] = field(default_factory=dict)
    refuse: frozenset[str] = frozenset()
    rounds_on_empty_pool: bool = True

    def score(self, state, pool, rnd):
        exc, table, live, why = [], [], {}, {}
        for k in pool:
            ok = k not in self.gated.get(rnd, set())
            exc.append(Excitation(k, "driver", ok, 1, 5.0, 1.0, "" if ok else "not excited"))
            if not ok:
                why[k] = NotTaken("not_identifiable", "not excited")
                continue
            table.append(CandidateScore(k, self.gains[k], 1, 1.0, 0.5, 100.0))
            if self.gains[k] > 0:
                live[k] = self.gains[k]
        return Scoring(tuple(table), tuple(exc), live, why, dict(pool), None)

    def best(self, live, scoring):
        return max(live, key=live.get)

    def confounded(self, state, scoring, live, best, rnd):
        return best, None

    def with_term(self, state, scoring, kind):
        return state + (kind,)

    def accept(self, state, declared, new, kind, rnd):
        if kind in self.refuse:
            return (), Rejection(rnd, kind, "the current model", (), None, "a metric got worse")
        return (), None


def _run(steps: TableSteps, pool=("a", "b", "c"), max_rounds: int = 6, before=None):
    return run_rounds(steps, (), {k: k for k in pool}, before or {}, max_rounds)


def test_best_first_then_the_rest_until_nothing_gains():
    trace = _run(TableSteps({"a": 5.0, "b": 9.0, "c": -1.0}))
    assert trace.final == ("b", "a")
    assert [r.added for r in trace.rounds] == ["b", "a", None]       # the third round adds nothing and ends
    assert trace.not_tested == {} and trace.tested == ["a", "b", "c"]


def test_a_refused_pick_leaves_the_pool_with_its_reason_and_the_next_best_is_tried():
    trace = _run(TableSteps({"a": 5.0, "b": 9.0, "c": -1.0}, refuse=frozenset({"b"})))
    first = trace.rounds[0]
    assert first.added == "a" and [j.effect for j in first.rejections] == ["b"]
    assert all(r.effect != "b" for r in trace.rounds[1].scores)    # not scored again
    assert trace.not_tested_text() == {"b": "refused by the acceptance on every metric: a metric got worse"}
    assert [j.effect for j in trace.rejected] == ["b"]


def test_a_candidate_gated_out_is_gated_again_and_loses_its_reason_once_identifiable():
    trace = _run(TableSteps({"a": 5.0, "b": 9.0}, gated={1: {"b"}}), pool=("a", "b"))
    assert trace.rounds[0].added == "a"
    assert trace.rounds[0].not_taken["b"].cause == "not_identifiable"
    assert trace.rounds[1].added == "b" and "b" not in trace.not_tested


def test_reasons_known_before_the_rounds_are_kept_and_max_rounds_bounds_the_loop():
    before = {"z": NotTaken("not_buildable", "needs a thermometer")}
    trace = _run(TableSteps({"a": 5.0, "b": 9.0, "c": 2.0}), max_rounds=1, before=before)
    assert len(trace.rounds) == 1 and trace.final == ("b",)
    assert trace.not_tested_text() == {"z": "needs a thermometer"}


@pytest.mark.parametrize("on_empty, rounds", [(True, 1), (False, 0)])
def test_an_empty_pool_runs_one_empty_round_or_none(on_empty, rounds):
    trace = _run(TableSteps({}, rounds_on_empty_pool=on_empty), pool=())
    assert len(trace.rounds) == rounds and trace.final == ()


def _sums(ss_by_group: list[float]) -> dict[str, MetricSums]:
    v = np.asarray(ss_by_group, float)
    return {"m": MetricSums("m", "u", "ref", "what", v, np.ones(v.size))}


def test_acceptance_refuses_a_metric_worse_against_the_declared_model_though_not_the_current():
    """Ten held-out stretches, each 20 % worse (RMS) than the declared model: every change has the
    same sign, so the signed-rank z is 55/√385 = 2.80 > 2.33 (one metric: Φ⁻¹(0.99)); against the
    current model nothing changes (z = 0)."""
    declared = _sums([1.0] * 10)
    current = _sums([1.44] * 10)
    new = _sums([1.44] * 10)
    changes, rejection = accept_on_every_metric(current, declared, new, "x", 2, "rows", None)
    assert [c.verdict for c in changes] == ["same"]
    assert rejection is not None and rejection.against == "the declared model"
    _, rejection = accept_on_every_metric(current, None, new, "x", 2, "rows", None)
    assert rejection is None
