"""Confounded candidates: effects that explain the same part of the held-out residual.

For the best candidate b (largest held-out gain among those tied to a measured channel) and every
other candidate c with a positive gain, all fitted on the fit rows and scored on the held-out rows
(RSS₀ of the current model, n_eff and the BIC penalty as in :mod:`calib.closeloop.fit`):

    E_x      = RSS₀ − RSS(x)                                   what x explains alone
    G(c | b) = n_eff · ln(RSS(b) / RSS(b, c)) − Δp_c · ln n_eff   what c adds once b is in
    overlap  = (E_b − (RSS(c) − RSS(b, c))) / min(E_b, E_c)      the share of the smaller explanation
                                                                that the other one explains too

c and b are **confounded** when overlap ≥ ½ or one adds nothing once the other is in
(G(c | b) ≤ 0 or G(b | c) ≤ 0): on this recording their regressors are collinear where the
residual lives.  The correlation of their fitted contributions on the held-out rows is reported too.

**Rule** (stated in the report):

1. *Nested*: if b adds nothing beyond c but c adds something beyond b, c explains all b does and
   more — c is taken (and vice versa).
2. *Mutual*: otherwise the member whose regressor measures its cause most directly is taken —
   :class:`~calib.closeloop.candidates.Channel` order: the gyro's own input rate, then a dedicated
   measurement (thermometer, reference attitude), then a quantity sensed through another sensor whose
   own errors enter (accelerometer, magnetometer), then time — and among equally direct members
   the larger gain.
3. *The catch-all* (bias drift, a spline in time, which can mimic anything slow) is taken over a
   measured-channel candidate only when that candidate adds nothing beyond the drift *and*
   explains less than half of what the drift explains: then it is a partial mimic of the drift,
   not its cause.  A measured candidate that explains most of the slow structure (a temperature
   term in a chamber) keeps priority.

The others are re-tested in the next round on what remains, and the trace says which recording or
motion would separate them.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Sequence

import numpy as np

from calib.closeloop.candidates import Candidate
from calib.closeloop.fit import HeldOutScore, UnionDesign, held_out_score
from calib.closeloop.jsonview import JsonView
from calib.closeloop.state import LoopSetup, ModelState

__all__ = ["MemberEvidence", "ConfoundedGroup", "find_confounded", "RULE", "MIN_OVERLAP", "overlap_summary", "overlap",
           "contribution_correlation"]

MIN_OVERLAP = 0.5
# held-out gains closer than this are a tie (G is a log-likelihood-ratio scale: a difference below 1 is no evidence
# either way); a tie goes to the member with fewer parameters — e.g. the gyro's rotation against the accelerometer (3)
# over the general misalignment (6) when the declared non-orthogonality holds the misalignment's symmetric half
TIE_GAIN = 1.0
RULE = ("a member that explains all another does and more first; else the physically direct channel first (the gyro's "
        "own input rate, then a dedicated measurement such as the thermometer or the reference attitude, then a "
        "quantity sensed through another sensor, then time), ties by held-out gain (gains within 1 of each other: "
        "the fewer parameters); bias drift only over a partial mimic of it")


@dataclass(frozen=True)
class MemberEvidence:
    """One member of a confounded group and the evidence for it, fitted alone on the fit rows."""

    effect: str
    channel: str
    gain: float
    explained_fraction: float      # of the held-out residual's mean square, alone
    overlap_with_best: float       # (see the module docstring) against the best-scoring member (1 for itself)
    gain_beyond_best: float        # G(member | best) (the best itself: its own G)
    best_gain_beyond: float        # G(best | member)
    contribution_correlation: float
    separated_by: str


@dataclass(frozen=True)
class ConfoundedGroup(JsonView):
    """Candidates that explain the same part of the held-out residual in one round: the member chosen, the
    evidence for each, the rule that chose, what would separate them, and why, in words."""

    round: int
    chosen: str
    members: tuple[MemberEvidence, ...]
    rule: str
    separate_by: str
    why: str

    @property
    def rivals(self) -> list[str]:
        return [m.effect for m in self.members if m.effect != self.chosen]

    def to_json(self) -> dict:
        """The ``not_distinguished`` entry: round, chosen, rivals, why (plus members, rule, separate_by)."""
        return {"round": self.round, "chosen": self.chosen, "rivals": self.rivals, "why": self.why,
                "members": [asdict(m) for m in self.members], "rule": self.rule, "separate_by": self.separate_by}


@dataclass(frozen=True)
class _Pair:
    kind: str
    overlap: float
    g_c_given_b: float
    g_b_given_c: float
    rho: float


def _conditional(n_eff: float, rss_without: float, rss_with: float, dp: int) -> float:
    if dp <= 0 or rss_with <= 0:
        return -math.inf
    return n_eff * math.log(rss_without / rss_with) - dp * math.log(n_eff)


def overlap(rss0: float, rss_b: float, rss_c: float, rss_bc: float) -> float:
    """The share of the smaller explanation the other explains too (module docstring):
    (E_b − (RSS(c) − RSS(b, c))) / min(E_b, E_c), E_x = RSS₀ − RSS(x); 0 when either explains nothing."""
    e_b, e_c = rss0 - rss_b, rss0 - rss_c
    shared = e_b - (rss_c - rss_bc)
    return shared / min(e_b, e_c) if min(e_b, e_c) > 0 else 0.0


def contribution_correlation(residual0: np.ndarray, residual_b: np.ndarray, residual_c: np.ndarray) -> float:
    """Correlation of what b and c each take out of the held-out residual r₀ (r₀ − r_b against r₀ − r_c)."""
    d_b, d_c = (residual0 - residual_b).ravel(), (residual0 - residual_c).ravel()
    den = float(np.linalg.norm(d_b) * np.linalg.norm(d_c))
    return float(d_b @ d_c) / den if den > 0 else math.nan


def _pair(setup: LoopSetup, state: ModelState, pool: dict[str, Candidate], scores: dict[str, HeldOutScore],
          best: str, k: str, tau: float | None, union: UnionDesign | None) -> _Pair:
    sb, sc = scores[best], scores[k]
    both = held_out_score(setup.ref, state.terms, state.fit, [pool[best], pool[k]], state.gyro_rad_s, tau, union)
    n_eff = both.n_eff
    g_cb = _conditional(n_eff, sb.rss_after, both.rss_after, both.fit.rank - sb.fit.rank)
    g_bc = _conditional(n_eff, sc.rss_after, both.rss_after, both.fit.rank - sc.fit.rank)
    h = setup.held_rows
    return _Pair(k, overlap(sb.rss_before, sb.rss_after, sc.rss_after, both.rss_after), g_cb, g_bc,
                 contribution_correlation(state.fit.residual[h], sb.fit.residual[h], sc.fit.residual[h]))


def find_confounded(setup: LoopSetup, state: ModelState, pool: dict[str, Candidate],
                    scores: dict[str, HeldOutScore], best: str, rnd: int,
                    tau: float | None = None, union: UnionDesign | None = None) -> tuple[str, ConfoundedGroup | None]:
    """The member to add (by :data:`RULE`) and the confounded group around ``best`` (None: none).

    ``scores``: the candidates with a positive gain (catch-alls included); ``best``: the largest
    gain among those tied to a measured channel (a catch-all only when there is none)."""
    pairs = [
        _pair(setup, state, pool, scores, best, k, tau, union) for k, s in scores.items() if k != best and s.gain > 0
    ]
    group = [p for p in pairs if p.overlap >= MIN_OVERLAP or p.g_c_given_b <= 0 or p.g_b_given_c <= 0]
    if not group:
        return best, None
    fam = {k: pool[k].family for k in scores}
    chosen = best
    drift = [p for p in group if fam[p.kind].catch_all and not fam[best].catch_all]
    for p in drift:   # rule 3: the drift over a partial mimic of it
        e_b = scores[best].rss_before - scores[best].rss_after
        e_w = scores[p.kind].rss_before - scores[p.kind].rss_after
        if p.g_b_given_c <= 0 and p.g_c_given_b > 0 and e_b < 0.5 * e_w:
            chosen = p.kind
    measured = [p for p in group if not fam[p.kind].catch_all or fam[best].catch_all]
    if chosen == best:
        wider = [p for p in measured if p.g_b_given_c <= 0 < p.g_c_given_b]   # rule 1: c explains all b does and more
        if wider:
            chosen = max(wider, key=lambda p: scores[p.kind].gain).kind
        else:                                                                  # rule 2: mutual
            mutual = [best] + [p.kind for p in measured if (p.g_b_given_c <= 0) == (p.g_c_given_b <= 0)]
            channel = min(int(fam[k].channel) for k in mutual)
            direct = [k for k in mutual if int(fam[k].channel) == channel]
            top = max(scores[k].gain for k in direct)
            tied = [k for k in direct if scores[k].gain >= top - TIE_GAIN]   # no evidence either way: the fewer
            chosen = min(tied, key=lambda k: (pool[k].n_params, -scores[k].gain))   # parameters
    rss0 = scores[best].rss_before
    own = MemberEvidence(best, fam[best].channel.name.lower(), float(scores[best].gain),
                         1.0 - scores[best].rss_after / rss0, 1.0, float(scores[best].gain), float(scores[best].gain),
                         1.0, fam[best].separated_by)
    ev = (own,) + tuple(MemberEvidence(p.kind, fam[p.kind].channel.name.lower(), float(scores[p.kind].gain),
                                       1.0 - scores[p.kind].rss_after / rss0, float(p.overlap), float(p.g_c_given_b),
                                       float(p.g_b_given_c), float(p.rho), fam[p.kind].separated_by) for p in group)
    seps: list[str] = []
    for m in ev:
        if m.separated_by not in seps and m.separated_by != "—":
            seps.append(m.separated_by)
    names = [m.effect for m in ev]
    why = (f"{', '.join(names)} explain the same part of the held-out residual on this recording (most of what the "
           f"smaller explains, the other explains too, or one adds nothing once the other is in); chosen {chosen} by "
           f"the rule: {RULE}")
    return chosen, ConfoundedGroup(rnd, chosen, ev, RULE, "; or ".join(seps), why)


def overlap_summary(group: ConfoundedGroup, exclude: Sequence[str] = ()) -> str:
    """One line for a trace: the rivals with their evidence."""
    parts = [f"{m.effect} (G = {m.gain:.0f}, explains {m.explained_fraction:.0%} alone, overlap "
             f"{m.overlap_with_best:.0%}, "
             f"ρ = {m.contribution_correlation:.2f})" for m in group.members if m.effect not in exclude]
    return ", ".join(parts)
