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
:func:`allan_deviation` / :func:`fit_noise_terms`.  Names are imported when first used
(:mod:`gyrosim.exports`).

Where things live: one folder per job — ``inputs/`` (the boundary every command reads through),
``session/`` (the hand-held calibration: model, filters, checks), ``noise/``, ``temperature/``,
``instruments/``, ``orientation/``, ``mag/``, ``closeloop/``, ``scoring/`` and ``app/`` (the command
line).  Old module paths (``calib.handkf``, ``calib.estimators``…) still import, with a warning
(:mod:`calib.compat`).

Frames: body Right-Forward-Up, navigation East-North-Up; quaternions (w, x, y, z) body→navigation.
"""

from gyrosim.exports import lazy_exports

from calib.compat import install as install_moved_modules

__version__ = "0.1.0"

_EXPORTS = {
    "Calibration": "gyrosim.calibration",
    "calibrate": "calib.session.paper", "METHODS": "calib.session.paper",
    "load_recording": "calib.inputs", "open_recording": "calib.inputs", "check_recording": "calib.inputs",
    "InputError": "calib.inputs",
    "run_closeloop": "calib.closeloop", "CloseloopResult": "calib.closeloop",
    "calibrate_magnetometer": "calib.mag", "MagCalibration": "calib.mag",
    "find_north": "calib.instruments.northfind",
    "tilt_test": "calib.instruments.tilt",
    "allan_deviation": "calib.noise.allan", "fit_noise_terms": "calib.noise.allan",
}
__all__ = ["__version__", *_EXPORTS]
lazy_exports(__name__, _EXPORTS)
install_moved_modules()
