"""A module imported when one of its names is first used, for the heavy libraries behind a few functions.

``calib --help`` and a refusal of a bad file should not pay for scipy.signal (≈1–4 s under load) or numba
(≈0.7 s) that only a simulation or a filter run uses.  A module that needs them at call time names them once
at the top, as before, through :func:`lazy_module`::

    sp_signal = lazy_module("scipy.signal")      # nothing imported yet
    sp_signal.lfilter(b, a, x)                   # scipy.signal imported here, once

The import itself is the ordinary :func:`importlib.import_module` (errors, ``sys.modules`` and import locks as
usual); the proxy only defers it.
"""

from __future__ import annotations

import importlib
import types

__all__ = ["lazy_module"]


class _LazyModule:
    """Stands for the module ``name`` until an attribute is asked for, then forwards to it."""

    __slots__ = ("_name", "_module")

    def __init__(self, name: str) -> None:
        object.__setattr__(self, "_name", name)
        object.__setattr__(self, "_module", None)

    def _load(self) -> types.ModuleType:
        module = object.__getattribute__(self, "_module")
        if module is None:
            module = importlib.import_module(object.__getattribute__(self, "_name"))
            object.__setattr__(self, "_module", module)
        return module

    def __getattr__(self, attr: str) -> object:
        return getattr(self._load(), attr)

    def __dir__(self) -> list[str]:
        return dir(self._load())

    def __repr__(self) -> str:
        name = object.__getattribute__(self, "_name")
        loaded = object.__getattribute__(self, "_module") is not None
        return f"<lazy module {name!r}{'' if loaded else ' (not imported yet)'}>"


def lazy_module(name: str) -> types.ModuleType:
    """A stand-in for the module ``name`` (absolute, e.g. ``"scipy.signal"``) that imports it when one of its
    attributes is first read; typed as the module so call sites read as usual."""
    return _LazyModule(name)  # type: ignore[return-value]
