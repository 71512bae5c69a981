"""The input boundary used by every command: read a recording whatever its format, and make sure a
method gets data it can use — or a named error saying what is wrong and what to do.

Entry points:

* :func:`open_recording` (path → :class:`Loaded`: recording + :class:`InputReport`) and
  :func:`load_recording` (path → Recording, the historical signature); both take ``columns=`` (a CSV
  column mapping, :func:`parse_columns` reads the command lines' ``--columns t=…,gyro_x=…``) and
  ``topic=`` (a ROS bag's ``sensor_msgs/Imu`` topic);
* :func:`prepare_recording` (Recording → :class:`Loaded`), for recordings made in code or by a loader;
* :func:`check_recording` (Recording → :class:`InputCheck`), the cheap re-check every method runs;
* :class:`Requirements` and the per-method presets (``KF``, ``CLOSELOOP``, ``ALLAN``, ``INSPECT``, …).

The classes of bad input and what each gets (docs/bad-input.md):

=================  ===================================================================  =====================
class              examples                                                             result
=================  ===================================================================  =====================
format             empty, binary, truncated HDF5, no header, missing column             FormatError
format             ambiguous header, a mapping naming a missing column, no IMU topic    FormatError
unit               a column name's unit contradicted by --gyro-unit/--acc-unit          UnitError
field              wrong field count, text in a number column, NaN/inf, empty cell     FieldError (line, column)
time               ms/µs/ns or Unix epoch time column                                   converted, warning
time               ambiguous or implausible unit, not increasing                        TimeBaseError
gap                ≤ 5 missing samples                                                  bridged, warning
gap                longer gaps                                                          GapError (closeloop: warning)
rate               outside the method's range (e.g. > 1 kHz for the filter)             RateError, ``--decimate``
unit               g as m/s², deg/s as rad/s (peak, rest level, gravity consistency)    UnitError (which option)
spike              isolated corrupt samples ≤ 1 %                                       excluded, counted
spike              more, or a corrupt stretch                                           SpikeError
degenerate         dead axis, constant sensor, integer counts                           DegenerateError
motion             a moving record for Allan, a motionless one for calibration          MotionError
short              fewer samples or seconds than the method needs                      TooShortError
=================  ===================================================================  =====================
"""

from calib.inputs.boundary import (
                       MAX_INSERTED_FRACTION,
                       ReadInfo,
                       check_recording,
                       load_recording,
                       open_recording,
                       prepare_recording,
                       read_recording,
                       repaired_mask,
)
from calib.inputs.columns import parse_columns
from calib.inputs.csvfile import CSV_COLUMNS, KNOWN_COLUMNS, resample_temperature
from calib.inputs.errors import (
                       DegenerateError,
                       FieldError,
                       FormatError,
                       GapError,
                       InputError,
                       MotionError,
                       RateError,
                       SpikeError,
                       TemperatureTrendError,
                       TimeBaseError,
                       TooShortError,
                       TurnsError,
                       UnitError,
)
from calib.inputs.plausibility import MAX_PLAUSIBLE_RATE_RAD_S
from calib.inputs.report import InputCheck, InputReport, Loaded
from calib.inputs.requirements import (
                       ALLAN,
                       CLOSELOOP,
                       GENERIC,
                       INSPECT,
                       KF,
                       MAG,
                       NOISE,
                       NORTHFIND,
                       RATETABLE,
                       TEMPERATURE,
                       TILT,
                       Requirements,
)
from calib.inputs.saturation import saturated_samples

__all__ = [
    "open_recording",
    "load_recording",
    "prepare_recording",
    "read_recording",
    "parse_columns",
    "check_recording",
    "repaired_mask",
    "Loaded",
    "InputReport",
    "InputCheck",
    "ReadInfo",
    "Requirements",
    "KF",
    "CLOSELOOP",
    "ALLAN",
    "NOISE",
    "INSPECT",
    "MAG",
    "NORTHFIND",
    "TILT",
    "TEMPERATURE",
    "RATETABLE",
    "GENERIC",
    "CSV_COLUMNS",
    "KNOWN_COLUMNS",
    "MAX_PLAUSIBLE_RATE_RAD_S",
    "MAX_INSERTED_FRACTION",
    "resample_temperature",
    "saturated_samples",
    "InputError",
    "FormatError",
    "FieldError",
    "TimeBaseError",
    "GapError",
    "RateError",
    "UnitError",
    "SpikeError",
    "DegenerateError",
    "MotionError",
    "TooShortError",
    "TemperatureTrendError",
    "TurnsError",
]
