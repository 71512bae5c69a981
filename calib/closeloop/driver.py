"""The loop's skeleton, shared by the gyro loop (:mod:`calib.closeloop.loop`) and the magnetometer
loop (:mod:`calib.closeloop.mag.loop`): rounds of *score → select → add* over typed values.

Each sensor supplies its own steps (:class:`SensorSteps`): how a candidate is gated and scored,
how a confounded group is formed, how a model grows by one term, and what its held-out metrics are.
This module holds what is the same for both:

1. **score** (sensor step): every candidate in the pool is gated for identifiability against the
   current model and scored by its held-out gain (docs/closeloop.md §3–4)

       G = n_eff · ln(RSS₀ / RSS₁) − Δp · ln(n_eff),   n_eff = n_held / τ_int;

   the result is a :class:`Scoring`: the round's table, the gate's verdicts, the candidates still
   alive (G > 0, plausible size) and why the others are not taken (:class:`NotTaken`).
2. **select** (:func:`select`): the best live candidate and those confounded with it form a group
   whose rule picks one (docs/closeloop.md §5, :mod:`calib.closeloop.confounding`); the model with
   the pick must leave no held-out metric worse beyond its noise, against the current model and
   against the declared one (:func:`accept_on_every_metric`, docs/closeloop.md §6).  A refused
   pick leaves the pool with its :class:`Rejection` and the next best is tried.
3. **add** (:func:`run_rounds`): the accepted term joins the model and the next round starts from
   it; the loop ends when a round adds nothing, the pool is empty or ``max_rounds`` is reached.

The sensor's report step reads the :class:`LoopTrace` this returns.  No step steers on a message's
text: why a candidate is not taken is a :class:`NotTaken` (its cause and detail), a refusal a
:class:`Rejection`.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Generic, Literal, Mapping, Protocol, TypeVar

from calib.closeloop.confounding import ConfoundedGroup
from calib.closeloop.identify import Excitation
from calib.closeloop.metrics import MetricChange, MetricSums, compare_metrics, explain_disagreement

__all__ = ["NotTaken", "Scoring", "Pick", "Selection", "Round", "LoopTrace", "SensorSteps", "select", "run_rounds",
           "accept_on_every_metric", "CandidateScore", "Rejection"]

S = TypeVar("S")     # a sensor's model state (the gyro's ModelState, the magnetometer's MagFit)
C = TypeVar("C")     # a sensor's candidate (the gyro's Candidate, the magnetometer's kind name)
W = TypeVar("W")     # what a sensor's score step keeps for its own select steps (fits, scores)

Cause = Literal["not_buildable", "not_identifiable", "implausible", "refused", "no_reference", "not_analysed"]

_PREFIX: dict[str, str] = {
    "not_buildable": "",
    "not_identifiable": "not identifiable on this recording: ",
    "implausible": "refused: ",
    "refused": "refused by the acceptance on every metric: ",
    "no_reference": "not distinguishable on this recording: ",
    "not_analysed": "not analysed: ",
}


@dataclass(frozen=True)
class CandidateScore:
    """One row of a round's table (``report.json`` ``rounds``; held-out RMS in the rows' unit)."""

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
class NotTaken:
    """Why a candidate is not in the model: its cause and the step's own words (``report.json``
    ``not_tested`` holds :attr:`text`)."""

    cause: Cause
    detail: str

    @property
    def text(self) -> str:
        return _PREFIX[self.cause] + self.detail


@dataclass(frozen=True)
class Scoring(Generic[C, W]):
    """A round's score step: the table (best first), the gate's verdicts, the live candidates' held-out
    gains (pool order), why the others are not taken, the pool the round continues with (a sensor may
    rebuild candidates on the current model) and the sensor's own work for its select steps."""

    table: tuple[CandidateScore, ...]
    excitations: tuple[Excitation, ...]
    live: Mapping[str, float]
    not_taken: Mapping[str, NotTaken]
    pool: Mapping[str, C]
    work: W


@dataclass(frozen=True)
class Pick(Generic[S]):
    """The selection's decision: the kind added, its confounded group, the metrics against the current
    model, and the model with it."""

    kind: str
    confounded: ConfoundedGroup | None
    metrics: tuple[MetricChange, ...]
    state: S


@dataclass(frozen=True)
class Selection(Generic[S]):
    """A round's select step: the pick the acceptance kept (None: none) and the picks it refused before."""

    pick: Pick[S] | None
    rejections: tuple[Rejection, ...]


@dataclass(frozen=True)
class Round(Generic[S]):
    """One round as both loops record it (``report.json`` ``rounds`` is each round's :meth:`table`)."""

    round: int
    scores: tuple[CandidateScore, ...]
    excitations: tuple[Excitation, ...]
    pick: Pick[S] | None
    rejections: tuple[Rejection, ...]
    not_taken: Mapping[str, NotTaken]

    @property
    def added(self) -> str | None:
        return self.pick.kind if self.pick is not None else None

    @property
    def confounded(self) -> ConfoundedGroup | None:
        return self.pick.confounded if self.pick is not None else None

    @property
    def score(self) -> CandidateScore:
        """The added term's row of the table."""
        return next(s for s in self.scores if s.effect == self.added)

    @property
    def excitation(self) -> Excitation | None:
        """The gate's verdict on the added term (the last one of the current round)."""
        return next((e for e in reversed(self.excitations) if e.effect == self.added), None)

    def table(self) -> list[dict]:
        return [s.to_json() for s in self.scores]

    def to_json(self) -> list[dict]:
        return self.table()


@dataclass(frozen=True)
class LoopTrace(Generic[S]):
    """What the rounds leave for the report: the declared and final models, every round, and why each
    candidate not in the model is not (kind → reason, in the order the reasons were last given)."""

    declared: S
    final: S
    rounds: tuple[Round[S], ...]
    not_tested: Mapping[str, NotTaken]

    @property
    def added(self) -> tuple[Round[S], ...]:
        return tuple(r for r in self.rounds if r.pick is not None)

    @property
    def rejected(self) -> list[Rejection]:
        return [j for r in self.rounds for j in r.rejections]

    @property
    def tested(self) -> list[str]:
        """Candidates that passed the gate in some round."""
        return sorted({e.effect for r in self.rounds for e in r.excitations if e.identifiable})

    @property
    def not_distinguished(self) -> list[ConfoundedGroup]:
        return [r.confounded for r in self.rounds if r.confounded is not None]

    def not_tested_text(self) -> dict[str, str]:
        return {k: v.text for k, v in self.not_tested.items()}


class SensorSteps(Protocol[S, C, W]):
    """A sensor's implementation of the round's steps."""

    #: run a round on an empty pool (the gyro records it; the magnetometer stops)
    rounds_on_empty_pool: bool

    def score(self, state: S, pool: Mapping[str, C], rnd: int) -> Scoring[C, W]:
        """Gate and score every candidate of ``pool`` against ``state``."""

    def best(self, live: Mapping[str, float], scoring: Scoring[C, W]) -> str:
        """The candidate the confounding step starts from."""

    def confounded(self, state: S, scoring: Scoring[C, W], live: Mapping[str, float], best: str,
                   rnd: int) -> tuple[str, ConfoundedGroup | None]:
        """The group confounded with ``best`` and the member its rule picks."""

    def with_term(self, state: S, scoring: Scoring[C, W], kind: str) -> S:
        """The model ``state`` plus candidate ``kind``, fitted on the fit rows."""

    def accept(self, state: S, declared: S, new: S, kind: str, rnd: int
               ) -> tuple[tuple[MetricChange, ...], Rejection | None]:
        """Acceptance on every held-out metric (:func:`accept_on_every_metric`)."""


def accept_on_every_metric(current: dict[str, MetricSums], declared: dict[str, MetricSums] | None,
                           new: dict[str, MetricSums], kind: str, rnd: int, fitted_on: str,
                           caveat: str | None) -> tuple[tuple[MetricChange, ...], Rejection | None]:
    """Step 2's acceptance: the model with ``kind`` (metrics ``new``) is compared with the current
    model and, when they differ, with the declared one (:func:`calib.closeloop.metrics.compare_metrics`:
    Wilcoxon signed-rank z of each held-out stretch's change, worse when z > Φ⁻¹(1 − 0.01/m) for m
    metrics).  Any metric worse beyond its noise refuses the addition; the refusal says against which
    model, and — when another metric improved — which reference is likely at fault
    (:func:`calib.closeloop.metrics.explain_disagreement`).  Returns the changes against the current
    model and the refusal (None: accepted)."""
    against_current = tuple(compare_metrics(current, new))
    checks = [("the current model", against_current)]
    if declared is not None:
        checks.append(("the declared model", tuple(compare_metrics(declared, new))))
    for against, changes in checks:
        worse = [c for c in changes if c.verdict == "worse"]
        if worse:
            why = (
                f"adding {kind} makes {', '.join(c.describe() for c in worse)} worse than {against} beyond its noise "
                f"(z > {worse[0].threshold:.2f})"
            )
            return against_current, Rejection(rnd, kind, against, changes,
                                              explain_disagreement(list(changes), fitted_on, caveat), why)
    return against_current, None


def select(steps: SensorSteps[S, C, W], state: S, declared: S, scoring: Scoring[C, W], rnd: int) -> Selection[S]:
    """Step 2 of the module docstring: the first live pick the acceptance keeps, with the refusals
    before it (each refused pick leaves the live set, and the best of the rest is tried)."""
    live = dict(scoring.live)
    rejections: list[Rejection] = []
    while live:
        best = steps.best(live, scoring)
        chosen, group = steps.confounded(state, scoring, live, best, rnd)
        new = steps.with_term(state, scoring, chosen)
        changes, rejection = steps.accept(state, declared, new, chosen, rnd)
        if rejection is None:
            return Selection(Pick(chosen, group, changes, new), tuple(rejections))
        rejections.append(rejection)
        live.pop(chosen)
    return Selection(None, tuple(rejections))


def run_round(steps: SensorSteps[S, C, W], state: S, declared: S, pool: Mapping[str, C], rnd: int
              ) -> tuple[Round[S], dict[str, C]]:
    """One round (score → select); returns it and the pool the next round starts with: without the
    added kind and without refused picks.  A candidate that is not identifiable stays in the pool:
    once another term explains its part of the residual, its own excitation may show."""
    scoring = steps.score(state, pool, rnd)
    chosen = select(steps, state, declared, scoring, rnd)
    refused = {r.effect: NotTaken("refused", r.why) for r in chosen.rejections}
    gone = set(refused) | ({chosen.pick.kind} if chosen.pick is not None else set())
    rest = {k: c for k, c in scoring.pool.items() if k not in gone}
    return Round(rnd, scoring.table, scoring.excitations, chosen.pick, chosen.rejections,
                 {**scoring.not_taken, **refused}), rest


def run_rounds(steps: SensorSteps[S, C, W], declared: S, pool: Mapping[str, C], not_tested: Mapping[str, NotTaken],
               max_rounds: int) -> LoopTrace[S]:
    """Step 3 of the module docstring: rounds from the declared model until one adds nothing.

    ``not_tested`` starts with the reasons known before any round (candidates that cannot be built);
    after each round it holds every candidate's latest reason: a candidate that passed the gate loses
    an earlier "not identifiable", and the added one leaves it."""
    state, pool, why = declared, dict(pool), dict(not_tested)
    rounds: list[Round[S]] = []
    for rnd in range(1, max_rounds + 1):
        if not pool and not steps.rounds_on_empty_pool:
            break
        r, pool = run_round(steps, state, declared, pool, rnd)
        rounds.append(r)
        for e in r.excitations:
            if e.identifiable:
                why.pop(e.effect, None)
        why.update(r.not_taken)
        if r.pick is None:
            break
        why.pop(r.pick.kind, None)
        state = r.pick.state
    return LoopTrace(declared, state, tuple(rounds), why)
