"""calib — gyroscope and accelerometer calibration from hand rotation (Zhou et al. 2020, extended) on
gyrosim Recordings.

The public API (``from calib import …``; the modules keep everything else)::

    from calib import calibrate, load_recording
    rec = load_recording("session.csv")          # HDF5, CSV or dataset:NAME, checked at the boundary
    cal = calibrate(rec)                         # Calibration: effects, covariance, status, warnings
    corrected = cal.compensate(rec)              # the same Recording with the errors removed
    cal.save("cal.json")                         # Calibration.load("cal.json") reads it back

``Calibration`` is defined in gyrosim's floor (:mod:`gyrosim.calibration`), so the testbed uses it
without importing calib.  Further entry points: :func:`run_closeloop` (find the effects a model
lacks), :func:`calibrate_magnetometer`, :func:`find_north`, :func:`tilt_test`,
:func:`allan_deviation` / :func:`fit_noise_terms`; they are imported when first used.

Note: ``calib.calibrate`` is the function; the module of the same name stays importable as
``from calib.calibrate import …`` (``import calib.calibrate as m`` would give the function, and
string targets such as ``mock.patch("calib.calibrate.x")`` do not reach the module).

Frames: body Right-Forward-Up, navigation East-North-Up; quaternions (w, x, y, z) body→navigation.
"""

from __future__ import annotations

import importlib

from gyrosim.calibration import Calibration

__version__ = "0.1.0"

from .calibrate import METHODS, calibrate  # noqa: E402 - after __version__, which calib.cli reads
from .inputs import InputError, check_recording, load_recording, open_recording  # noqa: E402

# imported when first asked for (PEP 562): these pull in their own machinery (closeloop, magnetometer fits)
_LAZY = {
    "run_closeloop": "calib.closeloop", "CloseloopResult": "calib.closeloop",
    "calibrate_magnetometer": "calib.mag", "MagCalibration": "calib.mag",
    "find_north": "calib.northfind",
    "tilt_test": "calib.tilt",
    "allan_deviation": "calib.allan", "fit_noise_terms": "calib.allan",
}

__all__ = ["__version__", "calibrate", "METHODS", "Calibration", "load_recording", "open_recording",
           "check_recording", "InputError", *_LAZY]


def __getattr__(name: str):
    if name in _LAZY:
        value = getattr(importlib.import_module(_LAZY[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'calib' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))
