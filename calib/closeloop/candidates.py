"""Candidate effects: what the loop may add to the declared model, built and described by their family.

A *candidate* is an effect of the gyro triad whose output change is linear in its parameters at
the null point, R(t) = ∂y/∂θ (N, 3, P), taken from the effect's own :meth:`Effect.sensitivity` on
the reference rate (body frame RFU, rad/s) and the recording's context (specific force,
temperature, attitude body→ENU, magnetic field).  The fitted θ is turned back into the same effect
class, so what the loop finds can be injected by the simulator unchanged.

What an effect kind is lives on its class (:mod:`gyrosim.effects`): its triads, units and display
unit, whether it is a candidate at all (``Effect.candidate``; a non-candidate says why in
``Effect.closeloop_reason``) and its regressor from the context alone
(``Effect.candidate_regressor``).  What the loop knows beyond that lives in the kind's
:class:`CandidateFamily` (:mod:`calib.closeloop.families`): how its regressor is built on a
reference, what it claims to depend on (its *driver*) and through which channel that driver
reaches the regressor, its largest plausible size (for the identifiability gate), how to finalise
what was fitted, and what recording would separate it from an effect of another driver.  Families
register themselves with :func:`register_family`; the loop asks
:func:`calib.closeloop.catalogue.family_for` and never tests
an effect's name.  A candidate effect class without a registered family is still proposed, through
:class:`GenericFamily` (its own ``candidate_regressor`` and display unit): adding an effect is one
class in one file.

Adding a candidate family (e.g. a magnetometer-driven term)::

    @register_family
    class MyFamily(CandidateFamily):
        effects = (MyEffect,)
        driver = "the thing it depends on"
        channel = Channel.OTHER_SENSOR
        separated_by = "what recording separates it"
        def build(self, kind, ctx, ref, options): ...     # → Candidate | Untestable
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Callable, ClassVar

import numpy as np

from gyrosim.effects import EFFECTS, Effect, SignalContext

if TYPE_CHECKING:  # annotations only
    from calib.closeloop.reference import Reference

__all__ = [
    "Channel",
    "Candidate",
    "Untestable",
    "FittedTerm",
    "ReportedTerm",
    "BuildOptions",
    "CandidateFamily",
    "GenericFamily",
    "register_family",
    "unregister_family",
    "registered_families",
]


class Channel(enum.IntEnum):
    """How directly a candidate's regressor measures what the effect depends on (lower = more direct).

    The confounding rule (:mod:`calib.closeloop.confounding`) prefers the lowest channel."""

    RATE = 0          # the gyro's own input: the reference rate, its derivative, a constant
    DEDICATED = 1     # a dedicated sensor of the quantity at the gyro (thermometer) or the reference attitude
    OTHER_SENSOR = 2  # a quantity measured through another sensor whose own errors enter (accelerometer, magnetometer)
    TIME = 3          # nothing measured: a function of time (the catch-all)

    def describe(self) -> str:
        return {
            Channel.RATE: "the gyro's own input rate (from the reference)",
            Channel.DEDICATED: "a dedicated measurement of the quantity (thermometer at the gyro, reference attitude)",
            Channel.OTHER_SENSOR: "another sensor whose own errors enter the regressor",
            Channel.TIME: "time only (nothing measured)",
        }[self]


class Untestable(Exception):
    """A candidate that cannot be built on this recording, and why (said in the report's "Not tested").

    :func:`build_candidate` raises it; a family's ``build`` and :func:`family_for` may return it as a
    value, which :func:`build_candidate` then raises."""

    def __init__(self, kind: str, reason: str) -> None:
        super().__init__(f"{kind}: {reason}")
        self.kind = kind
        self.reason = reason


@dataclass(frozen=True)
class BuildOptions:
    """Options of candidate construction that the loop passes through."""

    drift_knot_s: float = 20.0                 # bias drift: knot spacing (s)
    modelled_rate: np.ndarray | None = None    # output-stage terms: the error-stage output (I + S + N) ω + b (N, 3)


@dataclass(frozen=True)
class FittedTerm:
    """A term of the final model as fitted on all rows (input of :meth:`CandidateFamily.report`)."""

    kind: str
    names: tuple[str, ...]
    values: np.ndarray
    sigmas: np.ndarray
    effect: Effect                                   # the candidate's own effect at ``values``
    total: np.ndarray | None                         # output stage: the value undone on the gyro before the fit
    residual_without: Callable[[], tuple[np.ndarray, np.ndarray] | None]   # (row times (B,), residual (B, 3)) of
    # the final model without this term (rate references), else None
    candidate: "Candidate | None" = None

    def params(self) -> dict[str, dict[str, float]]:
        return {n: {"value": float(v), "sigma": float(s)} for n, v, s in zip(self.names, self.values, self.sigmas)}


@dataclass(frozen=True)
class ReportedTerm:
    """What the report says of a term the loop added (:meth:`CandidateFamily.report`): its parameters
    (value and 1σ, SI), the effect the simulator can inject, and a one-line summary."""

    params: dict[str, dict[str, float]]
    effect: Effect
    summary: str


@dataclass(frozen=True, eq=False)
class Candidate:
    """One effect as columns of the design: its family, regressors, parameters and how to make the effect.

    ``regressors`` (N, 3, P) are ∂y/∂θ per sample (rad/s per parameter unit).  A family whose
    per-sample regressors would be large (bias drift: a column per knot) gives ``lazy`` instead and
    ``apply`` (θ ↦ Σ R θ without building R); ``rows`` are the design rows (M, P) of a linear
    reference, computed once."""

    family: "CandidateFamily"
    kind: str
    param_names: tuple[str, ...]
    to_effect: Callable[[np.ndarray], Effect]
    follows: str                                  # what the residual follows, in words
    follows_series: np.ndarray | None             # (N, 3) the driver signal, for plots
    regressors: np.ndarray | None = None
    rows: np.ndarray | None = None
    lazy: Callable[[], np.ndarray] | None = None
    apply: Callable[[np.ndarray], np.ndarray] | None = None
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    @property
    def n_params(self) -> int:
        return len(self.param_names)

    def sample_regressors(self) -> np.ndarray:
        """(N, 3, P) ∂y/∂θ per sample (built on first use for lazy families, then kept)."""
        if self.regressors is not None:
            return self.regressors
        if "reg" not in self._cache:
            self._cache["reg"] = self.lazy()
        return self._cache["reg"]

    def correction(self, theta: np.ndarray) -> np.ndarray:
        """Σ_j R_j θ_j per sample (N, 3), rad/s."""
        if self.apply is not None and self.regressors is None and "reg" not in self._cache:
            return self.apply(np.asarray(theta, float))
        return self.sample_regressors() @ np.asarray(theta, float)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        b = self.family.bound
        return np.full(self.n_params, -b), np.full(self.n_params, b)


class CandidateFamily:
    """What the loop knows about one or more effect kinds (see the module docstring).

    Subclasses set the class attributes and implement :meth:`build`; the defaults of the other
    methods suit a linear, error-stage effect whose regressor is its driver measured directly."""

    effects: ClassVar[tuple[type[Effect], ...]] = ()   # the effect classes it describes
    kinds: ClassVar[tuple[str, ...]] = ()              # their kinds (set from ``effects`` on registration)
    triad: ClassVar[str] = "gyro"
    driver: ClassVar[str] = ""                   # what the effect claims to depend on, in words
    quantity: ClassVar[str] = ""                 # short token of the driver ("rate", "temperature", ...)
    channel: ClassVar[Channel] = Channel.RATE
    separated_by: ClassVar[str] = ""             # what recording or motion separates it from other drivers
    catch_all: ClassVar[bool] = False            # chosen only when no measured-channel candidate helps
    output_stage: ClassVar[bool] = False         # linearised about the value found so far (see loop)
    bound: ClassVar[float] = math.inf            # |θ| box of a nonlinear fit

    @property
    def display(self) -> tuple[float, str]:
        """Report factor and unit of the parameters: the effect class's own (``Effect.display_unit``);
        a family whose parameters are not the effect's (a reparametrisation) sets its own."""
        return self.effects[0].display_unit(self.triad) if self.effects else (1.0, "SI")

    def build(self, kind: str, ctx: SignalContext, ref: "Reference", options: BuildOptions) -> Candidate | Untestable:
        raise NotImplementedError

    # ------------------------------------------------------------ identifiability (calib.closeloop.identify)
    def plausible_max(self, kind: str, ctx: SignalContext) -> float | np.ndarray:
        """Each parameter's largest plausible |θ| (its units): an effect this size must be detectable for
        the candidate to count as identifiable, and a fit beyond it is refused.  NaN: no stated size."""
        return math.nan

    def driver_signal(self, cand: "Candidate", ref: "Reference") -> np.ndarray | None:
        """The candidate's regressor signal (``cand.follows_series``) as predicted from the driver alone
        (N, k), when the regressor may also move through something else (another sensor's own errors,
        the model's own terms); None when the regressor is the driver itself.  The identifiability
        gate requires the driver to explain most of the signal's variation."""
        return None

    def proxy_reason(self, share: float, ref: "Reference") -> str:
        """Why the regressor follows something other than the driver (share < ½), in words."""
        return (f"{self.driver} explains only {share:.0%} of its regressor's variation (needs ≥ 50 %): the rest "
                f"comes through {self.channel.describe()}")

    def measurement_check(self, ctx: SignalContext) -> str | None:
        """Why the driver's own measurement is too coarse for a regressor (None: fine)."""
        return None

    def unexcited(self, kind: str, ref: "Reference") -> str:
        """Why the regressor has no excitation here (rank 0 against the model), in words."""
        return (f"no excitation on this recording: {self.driver} does not vary independently of what the model "
                "already holds (its regressor is zero or spanned by the model)")

    # ------------------------------------------------------------ reporting
    def implausible(self, kind: str, theta: np.ndarray, sigma: np.ndarray, ctx: SignalContext) -> str | None:
        """Why fitted parameters (with their σ) cannot be this effect (None: plausible): a parameter
        beyond the fit box, or beyond the largest plausible size by more than 3σ."""
        if math.isfinite(self.bound) and np.any(np.abs(theta) >= 0.99 * self.bound):
            return (f"fitted {kind} reaches ±{self.bound:g}: not a sensor defect but a different solution of the "
                    "reference's equations")
        big = np.broadcast_to(np.asarray(self.plausible_max(kind, ctx), float), theta.shape)
        over = (np.abs(theta) - 3 * sigma > big) & np.isfinite(big)
        if np.any(over):
            j = int(np.argmax(np.where(over, np.abs(theta) / big, 0)))
            f, unit = self.display
            return (f"fitted {kind} reaches {theta[j] * f:.3g} {unit}, beyond the largest plausible size "
                    f"({big[j] * f:.3g} {unit}) by more than 3σ: a proxy for something else, not this effect")
        return None

    def summary(self, kind: str, values: np.ndarray, sigmas: np.ndarray) -> str:
        f, unit = self.display
        vals = ", ".join(f"{v * f:.3g}±{s * f:.2g}" for v, s in zip(values, sigmas))
        return f"{kind} [{vals}] {unit}"

    def caveat(self, kind: str, reference_kind: str) -> str | None:
        """What else, in this reference, looks exactly like the effect (appended to the trace)."""
        return None

    def absorb(self, total: np.ndarray | None, increment: np.ndarray) -> np.ndarray:
        """Output-stage families: the value found so far plus the fitted remainder."""
        return increment if total is None else total + increment

    def undo(self, kind: str, total: np.ndarray, gyro_rad_s: np.ndarray, ctx: SignalContext) -> np.ndarray:
        """Output-stage families: the measured gyro with the effect of parameters ``total`` undone."""
        raise NotImplementedError

    def report(self, kind: str, fitted: "FittedTerm") -> "ReportedTerm":
        """What the report says of a term the loop added: its parameters (SI, 1σ), the effect the
        simulator can inject, and a one-line summary."""
        return ReportedTerm(fitted.params(), fitted.effect, self.summary(kind, fitted.values, fitted.sigmas))

    def extra_covariance(self, cand: "Candidate", influence: np.ndarray, ref: "Reference",
                         residual_without: Callable[[], tuple[np.ndarray, np.ndarray] | None]) -> np.ndarray | None:
        """Covariance (P, P) the term's own stochastic part adds to every parameter of the final model,
        given the influence U = (JᵀJ)⁺Jᵀ (P, M) of the rows on θ̂ (None: nothing)."""
        return None

    def compare_with_truth(self, kind: str, finding_params: dict, declared_params: dict, true_effect: Effect,
                           device: dict[str, Effect]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(estimate, truth, σ) of what the loop can identify of ``true_effect`` (for the suites)."""
        vals = np.array([v["value"] for v in finding_params.values()])
        sig = np.array([v["sigma"] for v in finding_params.values()])
        return vals, np.asarray(true_effect.params()), sig


_FAMILIES: dict[str, CandidateFamily] = {}


def register_family(cls: type[CandidateFamily]) -> type[CandidateFamily]:
    """Class decorator: make the family's kinds candidates of the loop (a later registration wins)."""
    if cls.effects:
        cls.kinds = tuple(e.kind for e in cls.effects)
    inst = cls()
    for kind in cls.kinds:
        _FAMILIES[kind] = inst
    return cls


class GenericFamily(CandidateFamily):
    """A candidate effect class that no family describes: its own ``candidate_regressor`` (the
    prototype's sensitivity) is the regressor, its parameters the columns, its ``display_unit`` the
    report's unit (only the rank gates it)."""

    driver = "its own inputs"
    quantity = "unknown"
    channel = Channel.OTHER_SENSOR
    separated_by = "a recording that varies its inputs independently"

    def __init__(self, effect: type[Effect] | None = None) -> None:
        self.effects = (effect,) if effect is not None else ()

    def build(self, kind, ctx, ref, options):
        try:
            proto, reg = EFFECTS[kind].candidate_regressor(ctx)
        except Exception as err:  # noqa: BLE001 - an effect needing context the recording lacks says so
            return Untestable(kind, f"cannot be evaluated on this recording: {err}")
        return Candidate(self, kind, tuple(proto.param_names()), proto.with_params, f"the inputs of {kind}", None, reg)


def unregister_family(kind: str) -> None:
    """Remove ``kind``'s registered family (a test's toy family, or to fall back to the generic one)."""
    _FAMILIES.pop(kind, None)


def registered_families() -> dict[str, CandidateFamily]:
    """The registered families by kind (a copy; :mod:`calib.closeloop.catalogue` adds the vocabulary's own)."""
    return dict(_FAMILIES)
