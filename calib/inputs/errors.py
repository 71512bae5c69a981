"""The named classes of bad input.  Every one is a :class:`~gyrosim.errors.RecordingError` (so a
``ValueError``); the command lines print the message and exit with code 2.

Each class has a short ``kind`` (the README's "Bad input" table and the test table use it).
"""

from __future__ import annotations

from gyrosim.errors import RecordingError

__all__ = ["InputError", "FormatError", "FieldError", "TimeBaseError", "GapError", "RateError", "UnitError",
           "SpikeError", "DegenerateError", "MotionError", "TooShortError"]


class InputError(RecordingError):
    """Base of the input boundary's errors."""

    kind = "input"


class FormatError(InputError):
    """Not a readable CSV or HDF5 recording: empty, binary, truncated, wrong layout, missing columns."""

    kind = "format"


class FieldError(InputError):
    """A CSV row with the wrong number of fields, a non-numeric or non-finite value (with its line)."""

    kind = "field"


class TimeBaseError(InputError):
    """Timestamps in an unknown or ambiguous unit, not increasing, or inconsistent with the stated rate."""

    kind = "time"


class GapError(InputError):
    """A gap in time longer than the few samples that are bridged."""

    kind = "gap"


class RateError(InputError):
    """A sample rate outside what the method supports (the message names the decimation option)."""

    kind = "rate"


class UnitError(InputError):
    """Values in another unit than declared (deg/s as rad/s, g as m/s², ...)."""

    kind = "unit"


class SpikeError(InputError):
    """More isolated corrupt samples than can be excluded, or spikes in a recording given unrepaired."""

    kind = "spike"


class DegenerateError(InputError):
    """A dead axis, a constant channel, integer counts without a scale."""

    kind = "degenerate"


class MotionError(InputError):
    """The wrong kind of motion for the method: a moving record for Allan, a motionless one for calibration."""

    kind = "motion"


class TooShortError(InputError):
    """Too few samples or too short a record for the method."""

    kind = "short"


class TemperatureTrendError(InputError):
    """A temperature trend over a static record that a random-walk (or rate-ramp) estimate would
    absorb: the bias follows the temperature, and the drift looks like a random walk."""

    kind = "temperature"
