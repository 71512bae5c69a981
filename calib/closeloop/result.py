"""The report both loops fill in (gyro: :class:`calib.closeloop.loop.CloseloopResult`, magnetometer:
:class:`calib.closeloop.mag.loop.MagLoopResult`): what was declared, found, not tested, not
distinguished and refused, and the held-out errors before and after.  ``report.json``'s keys are
promises: each result's ``to_json`` writes them in the order they always had."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping

from calib.closeloop.confounding import ConfoundedGroup
from calib.closeloop.driver import Rejection, Round
from calib.closeloop.jsonview import JsonView
from calib.closeloop.metrics import MetricChange

__all__ = ["Finding", "LoopReport", "trace_of"]


@dataclass(frozen=True)
class Finding:
    """One effect the loop added: its fitted parameters (SI or the sensor's unit, with 1σ), the effect
    as gyrosim serialises it (inject it with ``effect_from_dict``), the evidence for it and its trace."""

    effect: str
    params: dict[str, dict[str, float]]
    model: dict
    evidence: JsonView
    trace: str

    def to_json(self) -> dict:
        return {"effect": self.effect, "params": self.params, "model": self.model, "evidence": self.evidence.to_json(),
                "trace": self.trace}


def trace_of(follows: str, summary: str, residual: str, before: float, after: float, unit: str, gain: float,
             n_params: int, metrics: tuple[MetricChange, ...], residual_metric: str) -> str:
    """A finding's trace, first part: what the residual follows, what was found, how much of the
    held-out ``residual`` it took (RMS before → after in ``unit``, G for ``n_params`` parameters), and
    every other held-out metric's change."""
    trace = (f"the residual follows {follows} → {summary}; adding it cut the held-out {residual} from "
             f"{before:.4g} to {after:.4g} {unit} (G = {gain:.0f} for {n_params} parameter(s))")
    others = [m for m in metrics if m.name != residual_metric]
    if others:
        trace += "; " + ", ".join(m.describe() for m in others)
    return trace


@dataclass(frozen=True, kw_only=True)
class LoopReport:
    """What a loop reports, whatever the sensor."""

    reference: str
    reference_description: str
    notes: list[str]
    declared: list[str]
    declared_params: dict[str, dict[str, float]]
    found: list[Finding]
    unexplained: JsonView                         # structure in the final residual no candidate explains
    not_tested: dict[str, str]                    # kind → why (not buildable, not identifiable, refused)
    not_distinguished: list[ConfoundedGroup]
    error_before: Mapping[str, float]             # held-out errors of the declared model
    error_after: Mapping[str, float]              # ... and of the loop's model
    rounds: list[Round] = field(default_factory=list)
    metrics: list[MetricChange] = field(default_factory=list)     # declared → after the loop, held out
    rejected: list[Rejection] = field(default_factory=list)
    tested: list[str] = field(default_factory=list)                # candidates that passed the gate

    @property
    def found_kinds(self) -> list[str]:
        return [f.effect for f in self.found]

    def _json(self, key: str):
        """One ``report.json`` entry: a field as JSON (typed values write themselves), or the gate's
        verdicts of every round (``identifiability``)."""
        if key == "identifiability":
            return [e.to_json() for r in self.rounds for e in r.excitations]
        value = getattr(self, key)
        if isinstance(value, list):
            return [_as_json(x) for x in value]
        return _as_json(value)


def _as_json(value):
    to_json = getattr(value, "to_json", None)
    return to_json() if to_json is not None else value
