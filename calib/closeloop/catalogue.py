"""The loop's candidates by kind: the family that proposes each effect kind, and the candidate built on a reference.

Above both :mod:`.candidates` (the base types and the registry) and :mod:`.families` (the vocabulary's
families, registered when imported): importing this module registers them, so the loop asks here and
never imports a family by name.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from gyrosim.effects import EFFECTS, SignalContext

from calib.closeloop import families  # noqa: F401 - registers the vocabulary's families
from calib.closeloop.candidates import (
    BuildOptions,
    Candidate,
    CandidateFamily,
    GenericFamily,
    Untestable,
    registered_families,
)

if TYPE_CHECKING:
    from calib.closeloop.reference import Reference

__all__ = ["family_for", "candidate_kinds", "build_candidate"]


def family_for(kind: str) -> CandidateFamily | Untestable:
    """The family proposing ``kind``, or why the vocabulary entry is no candidate."""
    registered = registered_families()
    if kind in registered:
        return registered[kind]
    if kind not in EFFECTS:
        return Untestable(kind, f"not in the effect vocabulary (known: {', '.join(EFFECTS)})")
    cls = EFFECTS[kind]
    if "gyro" not in cls.triads:
        return Untestable(kind, "not an effect of the gyro triad")
    if not cls.candidate:
        return Untestable(kind, cls.closeloop_reason or "a random process or output transform with no family to "
                                                          "linearise it")
    return GenericFamily(cls)


def candidate_kinds() -> list[str]:
    """Every gyro-triad kind of the vocabulary, in vocabulary order (then families' own kinds)."""
    kinds = [k for k, cls in EFFECTS.items() if "gyro" in cls.triads]
    return kinds + [k for k, f in registered_families().items() if k not in kinds and f.triad == "gyro"]


def build_candidate(kind: str, ctx: SignalContext, ref: "Reference", options: BuildOptions | None = None
                    ) -> Candidate:
    """The candidate for ``kind`` on this reference (design rows computed for a linear one).

    Raises :class:`Untestable` (its ``reason``) when ``kind`` is no candidate or cannot be built here."""
    fam = family_for(kind)
    if isinstance(fam, Untestable):
        raise fam
    cand = fam.build(kind, ctx, ref, options or BuildOptions())
    if isinstance(cand, Untestable):
        raise cand
    if cand.rows is not None or not ref.linear:
        return cand
    return Candidate(cand.family, cand.kind, cand.param_names, cand.to_effect, cand.follows, cand.follows_series,
                     cand.regressors, ref.jacobian(cand.sample_regressors()), cand.lazy, cand.apply, cand._cache)
