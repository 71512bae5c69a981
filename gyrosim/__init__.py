"""gyrosim — a virtual hand-held IMU in MuJoCo and a sensor error model.

Frames everywhere: body Right-Forward-Up (RFU), navigation East-North-Up (ENU); quaternions
(w, x, y, z) rotate body → navigation.  Units are SI unless a name says otherwise.

The public API (what ``from gyrosim import …`` offers; the modules keep everything else)::

    from gyrosim import simulate, save_hdf5, load_hdf5
    rec = simulate("zhou2020", "typical", "mpu9250", 100.0, seed=1)   # Recording, truth included

Note: ``gyrosim.simulate`` is the function; the module of the same name stays importable as
``from gyrosim.simulate import …`` (``import gyrosim.simulate as m`` would give the function).
"""

__version__ = "0.1.0"

# imported after __version__: the modules below read it
from .calibration import Calibration, truth_calibration
from .errors import GyrosimError, PresetError, RecordingError, ScheduleError
from .estimator import Estimate, load_estimator, registered_estimators
from .hand import Hand, hand_preset_names, load_hand
from .recording import Recording, Truth, load_hdf5, save_csv, save_hdf5
from .schedule import Schedule, builtin_schedule_names, load_schedule
from .sensor_model import SensorModel, load_sensor, sensor_preset_names
from .simulate import apply_sensor, simulate, simulate_truth

__all__ = [
    "__version__",
    # simulate a session
    "simulate", "simulate_truth", "apply_sensor",
    # what a session is made of
    "Schedule", "load_schedule", "builtin_schedule_names",
    "Hand", "load_hand", "hand_preset_names",
    "SensorModel", "load_sensor", "sensor_preset_names",
    # recordings
    "Recording", "Truth", "load_hdf5", "save_hdf5", "save_csv",
    # calibration results and the estimator interface
    "Calibration", "truth_calibration", "Estimate", "load_estimator", "registered_estimators",
    # errors
    "GyrosimError", "RecordingError", "PresetError", "ScheduleError",
]
