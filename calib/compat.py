"""Old module paths of calib, kept importable: each resolves to the module's new home, with a warning.

calib was flat until its modules moved into one folder per job (``session/``, ``noise/``,
``temperature/``, ``instruments/``, ``orientation/``, ``scoring/``, ``app/``, ``closeloop/mag/``).
A user's script that imports an old path (``from calib.handkf import kf_hand``,
``gyrosim campaign --method calib.estimators:kf``) keeps working: :data:`MOVED` maps the old
name to the new one (``calib.orientation`` and ``calib.temperature`` became packages of the same
name that re-export the old module's names), and the import returns the very same module object (so monkeypatching
either name patches both) after a :class:`DeprecationWarning` that names the new path.

A name that moved to a module *above* its old one (an alias in the old module would import upwards, a cycle) is
listed in :data:`MOVED_NAMES`; the old module's ``__getattr__`` (:func:`moved_attribute`, PEP 562) finds it at its
new home, with the same warning (``from calib.session.kernel import crlb`` → :mod:`calib.session.bounds`).  A module
switch that became a method's parameter (:data:`NOW_PARAMETERS`: ``calib.session.hand.filter.QB_LADDER`` is
``HandParams.qb_ladder``) is an AttributeError that says how to pass it: assigning the old global would change
nothing, so reading it must not seem to work.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import sys
import warnings

__all__ = ["MOVED", "MOVED_NAMES", "NOW_PARAMETERS", "install", "moved_attribute"]

MOVED: dict[str, str] = {
    "calib.kalman": "calib.session.model",
    "calib.fastkf": "calib.session.kernel",
    "calib.calibrate": "calib.session.paper",
    "calib.estimators": "calib.session.registry",
    "calib.handkf": "calib.session.hand.filter",
    "calib.handchecks": "calib.session.hand.checks",
    "calib.handbias": "calib.session.rest_bias",
    "calib.consistency": "calib.session.consistency",
    "calib.spectral_covariance": "calib.session.spectral",
    "calib.observability": "calib.session.observability",
    "calib.gravityfit": "calib.session.gravityfit",
    "calib.rest": "calib.session.rest",
    "calib.noiselevels": "calib.session.noiselevels",
    "calib.validation": "calib.session.validation",
    "calib.residuals": "calib.session.residuals",
    "calib.coach": "calib.session.coach",
    "calib.allan": "calib.noise.allan",
    "calib.noisecov": "calib.noise.window_means",
    "calib.thermal_comp": "calib.temperature.compensation",
    "calib.ratetable": "calib.temperature.ratetable",
    "calib.timeblocks": "calib.temperature.timeblocks",
    "calib.northfind": "calib.instruments.northfind",
    "calib.northfind_plan": "calib.instruments.northfind_plan",
    "calib.tilt": "calib.instruments.tilt",
    "calib.holds": "calib.instruments.holds",
    "calib.attitude_kernels": "calib.orientation.kernels",
    "calib.montecarlo": "calib.scoring.montecarlo",
    "calib.instruments_mc": "calib.scoring.instruments_mc",
    "calib.bench": "calib.scoring.speed",
    "calib.mag.bench": "calib.scoring.mag_speed",
    "calib.cli": "calib.app.cli",
    "calib.demo": "calib.app.demo",
    "calib.report": "calib.app.report",
    "calib.viz_rerun": "calib.app.rerun",
    "calib.viz_temperature": "calib.app.rerun_temperature",
    "calib.recording_summary": "calib.app.inspect",
    "calib.outputs": "calib.app.outputs",
    "calib.closeloop.mag_fit": "calib.closeloop.mag.fit",
    "calib.closeloop.mag_identify": "calib.closeloop.mag.identify",
    "calib.closeloop.mag_loop": "calib.closeloop.mag.loop",
    "calib.closeloop.mag_metrics": "calib.closeloop.mag.metrics",
    "calib.closeloop.mag_reference": "calib.closeloop.mag.reference",
    "calib.closeloop.mag_select": "calib.closeloop.mag.select",
    "calib.closeloop.mag_terms": "calib.closeloop.mag.terms",
}


# module → {name: the module it moved to}, for names that moved upwards (module docstring)
MOVED_NAMES: dict[str, dict[str, str]] = {
    "calib.session.kernel": {"crlb": "calib.session.bounds", "crlb_joint": "calib.session.bounds"},
    "calib.session.model": {"ZhouFilter": "calib.session.reference"},
    "calib.session.hand.filter": {"hand_cross_check": "calib.session.crosscheck",
                                  "CROSS_CHECK_TAIL": "calib.session.crosscheck"},
}


# module → {former experiment switch: the parameter that replaced it, and how to pass it}
_HAND = "calib.session.hand.params.HandParams"
NOW_PARAMETERS: dict[str, dict[str, str]] = {
    "calib.session.hand.filter": {
        "SPECTRAL_SIGMA": f"{_HAND}.spectral_sigma", "PREFILTER_REFERENCE": f"{_HAND}.prefilter_reference",
        "GYRO_TEMP_BIAS": f"{_HAND}.gyro_temp_bias", "QB_LADDER": f"{_HAND}.qb_ladder",
        "JOINT_GYRO_THERMAL": f"{_HAND}.joint_gyro_thermal", "JOINT_GYRO_TEMP_BIAS": f"{_HAND}.joint_gyro_temp_bias",
        "PASSES": f"{_HAND}.passes",
    },
}


def moved_attribute(module: str):
    """The ``__getattr__`` of ``module`` (PEP 562): a name of :data:`MOVED_NAMES` resolves at its new home after a
    :class:`DeprecationWarning` naming it; a former switch of :data:`NOW_PARAMETERS` is an AttributeError naming its
    parameter; any other name is an AttributeError, as without the hook."""
    table = MOVED_NAMES.get(module, {})
    params = NOW_PARAMETERS.get(module, {})

    def __getattr__(name: str):
        if name in params:
            cls, _, fld = params[name].rpartition(".")
            raise AttributeError(f"{module}.{name} is now the parameter {params[name]}: pass "
                                 f"{cls.rpartition('.')[2]}({fld}=…) to the method (params=…) instead of editing the "
                                 "module")
        if name not in table:
            raise AttributeError(f"module {module!r} has no attribute {name!r}")
        new = table[name]
        warnings.warn(f"{module}.{name} has moved to {new}.{name}: import it from there (the old path still works, "
                      "for now)", DeprecationWarning, stacklevel=2)
        return getattr(importlib.import_module(new), name)

    return __getattr__


class _MovedModuleFinder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Finds an old module name and loads it as the module at its new path."""

    def __init__(self) -> None:
        self._own_spec: dict = {}

    def find_spec(self, fullname, path=None, target=None):  # noqa: D102 - importlib's protocol
        if fullname not in MOVED:
            return None
        return importlib.machinery.ModuleSpec(fullname, self)

    def create_module(self, spec):  # noqa: D102 - importlib's protocol
        new = MOVED[spec.name]
        warnings.warn(f"{spec.name} has moved to {new}: import it from there (the old path still works, "
                      f"for now)", DeprecationWarning, stacklevel=2)
        module = importlib.import_module(new)
        self._own_spec[module.__name__] = module.__spec__
        return module

    def exec_module(self, module):  # noqa: D102 - importlib's protocol
        # the import system gave the module the old name's spec: it keeps its own
        module.__spec__ = self._own_spec[module.__name__]


def install() -> None:
    """Put the finder on ``sys.meta_path`` once (``import calib`` does this)."""
    if not any(isinstance(f, _MovedModuleFinder) for f in sys.meta_path):
        sys.meta_path.append(_MovedModuleFinder())
