"""The estimator interface: what a calibration method receives and returns (issue 6).

An *estimator* is any callable ``estimator(rec: Recording) -> Estimate``:

* it receives a :class:`~gyrosim.recording.Recording` — gyro (rad/s) and accelerometer (m/s²) in
  the body frame RFU, times (s), optional temperature/field; in a campaign the recording is the
  corrupted simulation, and its truth is *not* for the estimator to use (the campaign scores
  against it afterwards);
* it returns an :class:`Estimate`: the gyro's bias (rad/s), scale-factor error and
  non-orthogonality (Zhou 2020 eq. 1: ω̃ = (I + diag(S) + N(G)) ω + b), each (3,), and their
  9×9 covariance in the order (b, S, G) when the method has one (NaN where it has none).

Built-ins live in :mod:`calib.estimators` (``kf``, ``smoother``, ``kf_session_r``,
``kf_adaptive``, ``kf_gated``, ``kf_adaptive_gated``); a user's estimator is named by import
path ``package.module:attribute`` (an estimator, or a class/factory called with no arguments that
returns one).  ``examples/own_estimator.py`` plugs one in and compares it with ours.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass, field
from typing import Callable, Protocol

import numpy as np

from .errors import GyrosimError
from .recording import Recording

__all__ = ["Estimate", "Estimator", "load_estimator", "BUILTIN_ESTIMATORS"]

BUILTIN_ESTIMATORS = ("kf", "smoother", "kf_session_r", "kf_adaptive", "kf_gated", "kf_adaptive_gated",
                      "kf_lever_arm")


@dataclass(frozen=True)
class Estimate:
    """A gyro calibration: b (rad/s), S and G (fractions), each (3,); covariance (9, 9) over (b, S, G)."""

    bias_rad_s: np.ndarray
    scale_factor: np.ndarray
    nonorthogonality: np.ndarray
    covariance: np.ndarray = field(default_factory=lambda: np.full((9, 9), np.nan))
    warnings: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        for name in ("bias_rad_s", "scale_factor", "nonorthogonality"):
            v = np.asarray(getattr(self, name), dtype=float).reshape(-1)
            if v.shape != (3,):
                raise GyrosimError(f"Estimate.{name} must have 3 values, got {v.size}")
            object.__setattr__(self, name, v)
        c = np.asarray(self.covariance, dtype=float)
        if c.shape != (9, 9):
            raise GyrosimError(f"Estimate.covariance must be 9×9 over (b, S, G), got {c.shape}")
        object.__setattr__(self, "covariance", c)

    def vector(self) -> np.ndarray:
        return np.concatenate([self.bias_rad_s, self.scale_factor, self.nonorthogonality])


class Estimator(Protocol):
    def __call__(self, rec: Recording) -> Estimate: ...


def load_estimator(spec: str) -> Callable[[Recording], Estimate]:
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
        raise GyrosimError(f"estimator {spec!r} is not callable: it must map a Recording to an Estimate")
    return obj
