"""A package's public names, imported when first used (PEP 562), including names equal to a submodule's.

``from gyrosim import simulate`` should not cost ``import gyrosim.errors`` the import of MuJoCo, and
``gyrosim --help`` should start as fast as before the package exported anything: the package's
``__init__`` lists its exports as name → module and :func:`lazy_exports` imports a module when one
of its names is first asked for.

One trap is handled here: an exported function named like the submodule it lives in
(``gyrosim.simulate`` the function, in ``gyrosim/simulate.py``; ``calib.calibrate``).  The import
system sets ``package.<submodule>`` to the module when the submodule is first imported, which would
make ``gyrosim.simulate`` the function or the module depending on import order.  The package's
module type therefore keeps the export: the submodule stays reachable by its path
(``from gyrosim.simulate import simulate_truth``, ``sys.modules["gyrosim.simulate"]``).
PEP 562: https://peps.python.org/pep-0562/.
"""

from __future__ import annotations

import importlib
import sys
import types

__all__ = ["lazy_exports"]


class _ExportingPackage(types.ModuleType):
    """A package module whose exported names win over same-named submodules."""

    def __setattr__(self, name: str, value: object) -> None:
        exports = self.__dict__.get("_EXPORTS", {})
        if name in exports and isinstance(value, types.ModuleType):
            return  # the import system announcing a submodule (or an old path to one): the export keeps the name
        super().__setattr__(name, value)


def lazy_exports(package: str, exports: dict[str, str]) -> None:
    """Make ``package``'s names ``exports`` (name → module that defines it) resolve on first use."""
    mod = sys.modules[package]

    def __getattr__(name: str) -> object:
        if name in exports:
            value = getattr(importlib.import_module(exports[name]), name)
            mod.__dict__[name] = value  # resolved once
            return value
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def __dir__() -> list[str]:
        return sorted(set(mod.__dict__) | set(exports))

    mod.__dict__.update(_EXPORTS=dict(exports), __getattr__=__getattr__, __dir__=__dir__)
    mod.__class__ = _ExportingPackage
