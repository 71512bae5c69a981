"""The estimator interface: what a calibration method receives and returns.

An *estimator* is any callable ``estimator(rec: Recording) -> Calibration``:

* it receives a :class:`~gyrosim.recording.Recording` — gyro (rad/s) and accelerometer (m/s²) in
  the body frame RFU, times (s), optional temperature/field; in a campaign the recording is the
  corrupted simulation, and its truth (and the simulator's sensor model in its metadata) is *not*
  for the estimator to use (the campaign scores against it afterwards);
* it returns a :class:`gyrosim.calibration.Calibration`: the estimated effects of the vocabulary
  (the gyro's bias, scale factor and non-orthogonality at least — Zhou 2020 eq. 1:
  ω̃ = (I + diag(S) + N(G)) ω + b), their covariance, a status and warnings.  :func:`Estimate`
  builds one from the gyro's three arrays, for estimators written before the result type.

Built-ins live in :mod:`calib.estimators` (``kf``, ``smoother``, ``kf_session_r``, ``kf_adaptive``,
``kf_gated``, ``kf_adaptive_gated``, ``kf_lever_arm``, ``kf_joint``, ``iterated_joint``, ``kf_hand``); a user's
estimator is named by import path ``package.module:attribute`` (an estimator, or a class/factory
called with no arguments that returns one).  ``examples/own_estimator.py`` plugs one in.
"""

from __future__ import annotations

import importlib
from typing import Callable, Protocol

import numpy as np

from .calibration import Calibration
from .errors import GyrosimError
from .recording import Recording

__all__ = ["Estimate", "Estimator", "load_estimator", "BUILTIN_ESTIMATORS"]

BUILTIN_ESTIMATORS = ("kf", "smoother", "kf_session_r", "kf_adaptive", "kf_gated", "kf_adaptive_gated",
                      "kf_lever_arm", "kf_joint", "iterated_joint", "kf_hand")


def Estimate(bias_rad_s: np.ndarray, scale_factor: np.ndarray, nonorthogonality: np.ndarray,  # noqa: N802
             covariance: np.ndarray | None = None, warnings: tuple[str, ...] = (), method: str = "") -> Calibration:
    """A gyro :class:`Calibration` from b (rad/s), S and G (each (3,)) and their (9, 9) covariance over
    (b, S, G) (default: unknown).  Kept for estimators written against the first interface."""
    arrays = {}
    for name, v in (("bias", bias_rad_s), ("scale_factor", scale_factor), ("nonorthogonality", nonorthogonality)):
        a = np.asarray(v, dtype=float).reshape(-1)
        if a.shape != (3,):
            raise GyrosimError(f"Estimate {name} must have 3 values, got {a.size}")
        arrays[name] = a
    if covariance is not None:
        c = np.asarray(covariance, dtype=float)
        if c.shape != (9, 9):
            raise GyrosimError(f"Estimate covariance must be 9×9 over (b, S, G), got {c.shape}")
    return Calibration.from_linear(gyro=arrays, covariance=covariance, warnings=tuple(warnings), method=method)


class Estimator(Protocol):
    def __call__(self, rec: Recording) -> Calibration: ...


def load_estimator(spec: str) -> Callable[[Recording], Calibration]:
    """A built-in name or ``package.module:attribute``; raises before any work if it cannot be loaded."""
    if spec in BUILTIN_ESTIMATORS:
        from calib import estimators

        return getattr(estimators, spec)
    if ":" not in spec:
        raise GyrosimError(f"unknown estimator {spec!r}: use a built-in ({', '.join(BUILTIN_ESTIMATORS)}) or an "
                           "import path package.module:attribute")
    mod_name, attr = spec.split(":", 1)
    try:
        mod = importlib.import_module(mod_name)
    except ImportError as exc:
        raise GyrosimError(f"estimator {spec!r}: cannot import module {mod_name!r} ({exc}); is it on PYTHONPATH?") from exc
    obj = mod
    for part in attr.split("."):
        if not hasattr(obj, part):
            raise GyrosimError(f"estimator {spec!r}: module {mod_name!r} has no attribute {attr!r}")
        obj = getattr(obj, part)
    if isinstance(obj, type):
        obj = obj()
    if not callable(obj):
        raise GyrosimError(f"estimator {spec!r} is not callable: it must map a Recording to a Calibration")
    return obj
