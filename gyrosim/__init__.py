"""gyrosim — a virtual hand-held IMU in MuJoCo and a sensor error model.

Frames everywhere: body Right-Forward-Up (RFU), navigation East-North-Up (ENU); quaternions
(w, x, y, z) rotate body → navigation.  Units are SI unless a name says otherwise.

The public API (what ``from gyrosim import …`` offers; the modules keep everything else)::

    from gyrosim import simulate, save_hdf5, load_hdf5
    rec = simulate("zhou2020", "typical", "mpu9250", 100.0, seed=1)   # Recording, truth included

The names are imported when first used (:mod:`gyrosim.exports`), so importing one small module
does not load MuJoCo.  ``gyrosim.simulate`` is the function; the module of the same name stays
importable by its path (``from gyrosim.simulate import simulate_truth``).
"""

__version__ = "0.1.0"

from .exports import lazy_exports  # noqa: E402 - after __version__, which the submodules read

_EXPORTS = {
    # simulate a session
    "simulate": "gyrosim.simulate", "simulate_truth": "gyrosim.simulate", "apply_sensor": "gyrosim.simulate",
    # what a session is made of
    "Schedule": "gyrosim.schedule", "load_schedule": "gyrosim.schedule", "builtin_schedule_names": "gyrosim.schedule",
    "Hand": "gyrosim.hand", "load_hand": "gyrosim.hand", "hand_preset_names": "gyrosim.hand",
    "SensorModel": "gyrosim.sensor_model", "load_sensor": "gyrosim.sensor_model",
    "sensor_preset_names": "gyrosim.sensor_model",
    # recordings
    "Recording": "gyrosim.recording", "Truth": "gyrosim.recording", "load_hdf5": "gyrosim.recording",
    "save_hdf5": "gyrosim.recording", "save_csv": "gyrosim.recording",
    # calibration results and the estimator interface
    "Calibration": "gyrosim.calibration", "truth_calibration": "gyrosim.calibration",
    "Estimate": "gyrosim.estimator", "load_estimator": "gyrosim.estimator",
    "registered_estimators": "gyrosim.estimator",
    # errors
    "GyrosimError": "gyrosim.errors", "RecordingError": "gyrosim.errors", "PresetError": "gyrosim.errors",
    "ScheduleError": "gyrosim.errors",
}
__all__ = ["__version__", *_EXPORTS]
lazy_exports(__name__, _EXPORTS)
