"""The estimator interface: what a calibration method receives and returns.

An *estimator* is any callable ``estimator(rec: Recording) -> Calibration``:

* it receives a :class:`~gyrosim.recording.Recording` — gyro (rad/s) and accelerometer (m/s²) in
  the body frame RFU, times (s), optional temperature/field; in a campaign that is
  :func:`as_user_file` of the corrupted simulation: no truth, no sensor model, no hand (the
  campaign scores against them afterwards);
* it returns a :class:`gyrosim.calibration.Calibration`: the estimated effects of the vocabulary
  (the gyro's bias, scale factor and non-orthogonality at least — Zhou 2020 eq. 1:
  ω̃ = (I + diag(S) + N(G)) ω + b), their covariance, a status and warnings.  :func:`Estimate`
  builds one from the gyro's three arrays, for estimators written before the result type.

Estimators are found by name through the entry-point group ``gyrosim.estimators``
(:mod:`gyrosim.plugins`), so gyrosim never imports the package that provides them: calib registers
its own there (``kf``, ``iterated``, ``kf_session_r``, ... in its ``pyproject.toml``), and a user's
installed package can register more the same way.  Any estimator can also be named by import path
``package.module:attribute``.  Either names an estimator, or a class/factory called with no
arguments that returns one.  ``examples/own_estimator.py`` plugs one in.

An estimator may declare which triads it estimates, ``estimator.estimates = ("gyro",)`` or
``("gyro", "accelerometer")`` (:func:`estimated_triads`): a campaign that scores the accelerometer then
refuses a gyro-only method before simulating anything; an undeclared one is checked on its first result.
"""

from __future__ import annotations

import warnings
from typing import Callable, Protocol

import numpy as np

from .calibration import Calibration
from .errors import GyrosimError
from .plugins import load, registered
from .recording import Recording

__all__ = ["Estimate", "Estimator", "load_estimator", "registered_estimators", "as_user_file", "estimated_triads",
           "ENTRY_POINT_GROUP"]

ENTRY_POINT_GROUP = "gyrosim.estimators"


def registered_estimators() -> tuple[str, ...]:
    """The names registered in the ``gyrosim.estimators`` entry-point group (calib's and any user's)."""
    return tuple(registered(ENTRY_POINT_GROUP))


def __getattr__(name: str):  # BUILTIN_ESTIMATORS: the registered names, read when asked (was a fixed tuple)
    if name == "BUILTIN_ESTIMATORS":
        return registered_estimators()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


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


def as_user_file(rec: Recording) -> Recording:
    """What a user's file carries: times, gyro, accelerometer (and temperature, field) with the rate —
    no truth, no sensor model, no hand, no seed.  Campaigns hand estimators this view of a simulated
    session, so an estimator cannot lean on the simulator's knowledge (an oracle that needs the
    truth is asked for by name and reads the full recording itself)."""
    return Recording(rec.t_s, rec.gyro_rad_s, rec.acc_m_s2, rec.temp_c, rec.mag_ut, None, {"rate_hz": rec.rate_hz})


class Estimator(Protocol):
    """What a campaign calls an estimator: any callable that maps a Recording (as a user's file,
    :func:`as_user_file`) to a Calibration."""

    def __call__(self, rec: Recording) -> Calibration: ...


def load_estimator(spec: str) -> Callable[[Recording], Calibration]:
    """A registered name (entry-point group ``gyrosim.estimators``) or ``package.module:attribute``;
    raises :class:`GyrosimError` before any work if it cannot be loaded.  An estimator whose
    ``deprecated_alias_of`` attribute names another (a former name kept working) loads with a
    FutureWarning naming the current one; its ``deprecation_note`` (if any) replaces the default reason
    "the same algorithm under its one name" (a retired method whose name now runs its successor)."""
    obj = load(ENTRY_POINT_GROUP, spec, what="estimator")
    alias = getattr(obj, "deprecated_alias_of", None)
    if alias:  # a former name kept working; FutureWarning: shown to command-line users by default
        why = getattr(obj, "deprecation_note", None) or "the same algorithm under its one name"
        warnings.warn(f"estimator {spec!r} is deprecated: use {alias!r} ({why})", FutureWarning, stacklevel=2)
    if isinstance(obj, type):
        obj = obj()
    if not callable(obj):
        raise GyrosimError(f"estimator {spec!r} is not callable: it must map a Recording to a Calibration")
    return obj


TRIADS = ("gyro", "accelerometer")


def estimated_triads(estimator: Callable) -> tuple[str, ...] | None:
    """The triads an estimator declares it estimates (its ``estimates`` attribute, a subset of
    ``("gyro", "accelerometer")``), or None when it declares nothing (then only its results tell)."""
    d = getattr(estimator, "estimates", None)
    if d is None:
        return None
    d = (d,) if isinstance(d, str) else tuple(d)
    bad = [t for t in d if t not in TRIADS]
    if bad:
        raise GyrosimError(f"estimator declares unknown triad(s) {bad} in 'estimates' (known: {', '.join(TRIADS)})")
    return d
