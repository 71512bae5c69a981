"""The orientation-estimator interface: a Recording in, the attitude body → ENU out.

Beside the calibration interface (:mod:`gyrosim.estimator`).  An *orientation estimator* is any
callable ``estimator(rec: Recording) -> Attitude`` (or an (N, 4) array of quaternions):

* it receives a :class:`~gyrosim.recording.Recording`: gyro (rad/s) and accelerometer (m/s²) in
  the body frame Right-Forward-Up, times (s), and for 9-axis estimators the magnetometer (µT,
  body frame); the truth is not for the estimator (the campaign scores against it afterwards);
* it returns one quaternion per sample, (w, x, y, z), Hamilton product, rotating body vectors into
  the navigation frame East-North-Up: v_n = q ⊗ v_b ⊗ q* (the convention of
  :mod:`gyrosim.rotations` and of ``/truth/quat``).  A 6-axis estimate's heading is relative (it
  starts where the filter starts it); scoring removes that offset (:mod:`gyrosim.attitude_errors`).

Registered names (entry-point group ``gyrosim.orientation_estimators``, :mod:`gyrosim.plugins`; calib registers these
from :mod:`calib.orientation.estimators`, the optional extra ``orientation``): ``vqf`` (Laidig & Seel 2023, package
``vqf``), ``madgwick`` and ``mahony`` (compiled, equal to the ``ahrs`` package's to rounding;
``madgwick_ahrs``/``mahony_ahrs`` run ``ahrs`` itself), ``fusion`` (x-io's Fusion, package ``imufusion``).  Each exists
6-axis (``vqf``) and 9-axis (``vqf_9d``).  A user's own is registered the same way by an installed package (the entry
point names a zero-argument factory that returns the estimator), or named by import path ``package.module:attribute`` (a
callable, or a class/factory called with no arguments that returns one).  :func:`run_orientation` checks what comes
back: an estimator that raises, returns the wrong shape, NaN or non-unit quaternions raises :class:`OrientationFailure`
with the reason, which a campaign records for that task and goes on.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, Protocol

import numpy as np

from .errors import GyrosimError
from .plugins import load, load_object, registered
from .recording import Recording

__all__ = [
    "Attitude",
    "OrientationEstimator",
    "OrientationFailure",
    "MissingExtraError",
    "ENTRY_POINT_GROUP",
    "registered_orientation_estimators",
    "load_orientation_estimator",
    "run_orientation",
    "UNIT_NORM_TOL",
    "EXTRA_HINT",
]

ENTRY_POINT_GROUP = "gyrosim.orientation_estimators"

EXTRA_HINT = "pip install 'gyrosim-calib[orientation]'"

# |‖q‖ − 1| above this is not a rotation: every filter here renormalises each step, so a float64
# quaternion is unit to ~1e-15 and a float32 one (Fusion) to ~1e-7.
UNIT_NORM_TOL = 1e-4


class OrientationFailure(GyrosimError):
    """An orientation estimator raised or returned something that is not an attitude series."""


class MissingExtraError(GyrosimError):
    """A built-in orientation estimator's package is not installed."""


@dataclass(frozen=True)
class Attitude:
    """An attitude series: ``quat_nb`` (N, 4) (w, x, y, z) body RFU → nav ENU, one per sample of
    the recording; ``magnetometer`` whether the heading is absolute (9-axis) or relative (6-axis);
    ``diagnostics`` what the estimator wants to report (e.g. its final gyro bias, rad/s)."""

    quat_nb: np.ndarray
    method: str = ""
    magnetometer: bool = False
    diagnostics: dict[str, Any] = field(default_factory=dict)


class OrientationEstimator(Protocol):
    """An orientation estimator: any callable that maps a Recording to an :class:`Attitude`, or to its
    (N, 4) quaternions (w, x, y, z) body RFU → nav ENU."""

    def __call__(self, rec: Recording) -> Attitude | np.ndarray: ...


def registered_orientation_estimators() -> tuple[str, ...]:
    """The names registered in the ``gyrosim.orientation_estimators`` entry-point group."""
    return tuple(registered(ENTRY_POINT_GROUP))


def __getattr__(name: str):  # BUILTIN_ORIENTATION: the registered names, read when asked
    if name == "BUILTIN_ORIENTATION":
        return registered_orientation_estimators()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def load_orientation_estimator(spec: str) -> Callable[[Recording], Attitude | np.ndarray]:
    """A registered name or ``package.module:attribute``; raises before any work if it cannot be loaded
    (an unknown name, a module that does not import, a missing optional package)."""
    try:
        if ":" in spec:
            obj = load_object(spec, "orientation estimator")
            if isinstance(obj, type):
                obj = obj()
        else:  # a registered name: its entry point is a zero-argument factory (it checks its package)
            obj = load(ENTRY_POINT_GROUP, spec, what="orientation estimator")()
    except ImportError as exc:
        raise MissingExtraError(str(exc)) from exc
    if not callable(obj):
        raise GyrosimError(f"orientation estimator {spec!r} is not callable: it must map a Recording to quaternions")
    return obj


def run_orientation(
    estimator: Callable[[Recording], Attitude | np.ndarray], rec: Recording, name: str = ""
) -> Attitude:
    """Run ``estimator`` on ``rec`` and check the result; any failure is an :class:`OrientationFailure`
    whose message says what went wrong (the estimator's own exception, a shape, NaN, a norm)."""
    try:
        out = estimator(rec)
    except MissingExtraError:
        raise
    except ImportError as exc:
        raise MissingExtraError(str(exc)) from exc
    except Exception as exc:  # noqa: BLE001 - the estimator's failure becomes a recorded one
        raise OrientationFailure(f"{name or 'estimator'} raised {type(exc).__name__}: {exc}") from exc
    if isinstance(out, dict) and "quat_nb" in out:  # the built-in adapters' plain form
        out = Attitude(quat_nb=np.asarray(out["quat_nb"], dtype=float), method=out.get("method", name),
                       magnetometer=bool(out.get("magnetometer", False)), diagnostics=dict(out.get("diagnostics", {})))
    att = out if isinstance(out, Attitude) else Attitude(quat_nb=np.asarray(out, dtype=float), method=name)
    q = np.asarray(att.quat_nb, dtype=float)
    if q.shape != (rec.n, 4):
        raise OrientationFailure(
            f"{name or 'estimator'} returned quaternions of shape {q.shape}, expected ({rec.n}, 4) "
            "(one (w, x, y, z) per sample)"
        )
    bad = ~np.isfinite(q).all(axis=1)
    if bad.any():
        raise OrientationFailure(f"{name or 'estimator'} returned {int(bad.sum())} non-finite quaternion(s), first at "
                                 f"sample {int(np.argmax(bad))} (t = {float(rec.t_s[np.argmax(bad)]):.3f} s)")
    dev = np.abs(np.linalg.norm(q, axis=1) - 1.0)
    if dev.max() > UNIT_NORM_TOL:
        k = int(np.argmax(dev))
        raise OrientationFailure(f"{name or 'estimator'} returned non-unit quaternions: |‖q‖ − 1| = {dev[k]:.3g} at "
                                 f"sample {k} (tolerance {UNIT_NORM_TOL:g}); an attitude must be a unit quaternion")
    return Attitude(quat_nb=q / np.linalg.norm(q, axis=1, keepdims=True), method=att.method or name,
                    magnetometer=att.magnetometer, diagnostics=dict(att.diagnostics))
