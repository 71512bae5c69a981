"""Named plug-ins found through Python entry points, so gyrosim uses other packages' code without importing them.

A package offers an object under a name by declaring it in its ``pyproject.toml``::

    [project.entry-points."gyrosim.estimators"]
    kf = "calib.session.registry:kf"
    my_filter = "my_package.filters:MyFilter"

and gyrosim finds it by that name (:func:`load`): calib registers its calibration estimators this
way, and a user's installed package registers its own the same way, neither edits gyrosim.  Without
registering, an object is still reachable by its import path ``package.module:attribute``.

Where the names come from (:func:`registered`):

1. the installed packages' metadata (:func:`importlib.metadata.entry_points`), read once per process;
2. when gyrosim itself runs from a source tree (``pyproject.toml`` beside the ``gyrosim`` folder:
   a checkout on ``PYTHONPATH``, or an editable install whose metadata predates a change to the
   entry points), that tree's ``pyproject.toml``, which then wins for the names it declares: it
   describes the code actually running, the installed metadata may be stale until
   ``pip install -e .`` is run again.

A name two packages register with different targets is refused when asked for (which one was
meant cannot be guessed); a name nobody registers is refused with the registered names and the
import-path form.  Entry points: PyPA, "Entry points specification",
https://packaging.python.org/en/latest/specifications/entry-points/.
"""

from __future__ import annotations

import functools
import importlib
import importlib.metadata
import tomllib
from dataclasses import dataclass
from pathlib import Path

from .errors import GyrosimError

__all__ = ["Registration", "registered", "load", "load_object", "clear_cache"]

SOURCE_TREE_PYPROJECT = Path(__file__).resolve().parent.parent / "pyproject.toml"


@dataclass(frozen=True)
class Registration:
    """One name in an entry-point group: its target ``module:attribute`` and who declared it."""

    name: str
    target: str
    origin: str  # "distribution NAME" or the path of the source tree's pyproject.toml


def _from_metadata(group: str) -> list[Registration]:
    out = []
    for ep in importlib.metadata.entry_points(group=group):
        dist = getattr(ep, "dist", None)
        origin = f"distribution {dist.metadata['Name']}" if dist is not None else "installed metadata"
        out.append(Registration(ep.name, ep.value.strip(), origin))
    return out


def _from_source_tree(group: str, pyproject: Path) -> list[Registration]:
    if not pyproject.is_file():
        return []
    try:
        with pyproject.open("rb") as f:
            table = tomllib.load(f).get("project", {}).get("entry-points", {}).get(group, {})
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise GyrosimError(f"cannot read the entry points of the source tree {pyproject}: {exc}") from exc
    return [Registration(str(k), str(v).strip(), str(pyproject)) for k, v in table.items()]


@functools.cache
def _registered(group: str, pyproject: Path) -> dict[str, tuple[Registration, ...]]:
    by_name: dict[str, list[Registration]] = {}
    for reg in _from_metadata(group):
        by_name.setdefault(reg.name, []).append(reg)
    for reg in _from_source_tree(group, pyproject):
        by_name[reg.name] = [reg]  # the running source tree's own declaration wins over (stale) metadata
    # the same target declared twice (e.g. metadata of two installs of one tree) is one registration
    return {name: tuple({r.target: r for r in regs}.values()) for name, regs in sorted(by_name.items())}


def registered(group: str, pyproject: Path | None = None) -> dict[str, tuple[Registration, ...]]:
    """Every name registered in ``group``: name → its registrations (one, unless packages disagree).

    ``pyproject``: the source tree's file to read besides the metadata (default: beside the
    ``gyrosim`` folder, if there is one).  Cached per process; :func:`clear_cache` after installing."""
    return _registered(group, SOURCE_TREE_PYPROJECT if pyproject is None else Path(pyproject))


def clear_cache() -> None:
    """Forget what :func:`registered` read (after installing or removing a package in-process)."""
    _registered.cache_clear()


def load_object(spec: str, what: str = "object") -> object:
    """The object at import path ``package.module:attribute`` (dotted attributes allowed)."""
    mod_name, sep, attr = spec.partition(":")
    if not sep or not mod_name or not attr:
        raise GyrosimError(f"{what} {spec!r}: an import path must be package.module:attribute")
    try:
        mod = importlib.import_module(mod_name)
    except ImportError as exc:
        raise GyrosimError(f"{what} {spec!r}: cannot import module {mod_name!r} ({exc}); is it installed or on "
                           "PYTHONPATH?") from exc
    obj = mod
    for part in attr.split("."):
        if not hasattr(obj, part):
            raise GyrosimError(f"{what} {spec!r}: module {mod_name!r} has no attribute {attr!r}")
        obj = getattr(obj, part)
    return obj


def load(group: str, spec: str, what: str = "object", pyproject: Path | None = None) -> object:
    """A registered name of ``group``, or an import path ``package.module:attribute``.

    Raises :class:`GyrosimError` before any work when the name is unknown or ambiguous or its target
    cannot be imported."""
    if ":" in spec:
        return load_object(spec, what)
    regs = registered(group, pyproject)
    if spec not in regs:
        names = ", ".join(regs) or "none"
        hint = ("" if regs else " (no installed package registers any: install the package that provides them, "
                "e.g. `pip install -e .` in this source tree — entry points are read from installed metadata)")
        raise GyrosimError(f"unknown {what} {spec!r}: registered in entry-point group {group!r}: {names}{hint}; "
                           "or give an import path package.module:attribute")
    found = regs[spec]
    if len(found) > 1:
        listing = "; ".join(f"{r.target} ({r.origin})" for r in found)
        raise GyrosimError(f"{what} {spec!r} is registered by more than one package in {group!r}: {listing}; "
                           "give the one you mean as an import path package.module:attribute")
    return load_object(found[0].target, f"{what} {spec!r} (registered as {found[0].target} by {found[0].origin})")
