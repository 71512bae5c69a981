"""The named classes of bad input.  Every one is a :class:`~gyrosim.errors.RecordingError` (so a
``ValueError``); the command lines print the message and exit with code 2.

Each class has a short ``kind`` (the table of docs/bad-input.md and the test table use it).
"""

from __future__ import annotations

from gyrosim.errors import RecordingError

__all__ = ["InputError", "FormatError", "FieldError", "TimeBaseError", "GapError", "RateError", "UnitError",
           "SpikeError", "DegenerateError", "MotionError", "TooShortError", "TemperatureTrendError", "TurnsError"]


class InputError(RecordingError):
    """Base of the input boundary's errors."""

    kind = "input"


def _input_error(name: str, kind: str, doc: str) -> type[InputError]:
    """A named :class:`InputError` subclass with its ``kind`` and docstring (one row per class below:
    the classes differ only in these three things)."""
    return type(name, (InputError,), {"kind": kind, "__doc__": doc, "__module__": __name__, "__qualname__": name})


FormatError = _input_error("FormatError", "format", "Not a readable CSV or HDF5 recording: empty, binary, truncated, "
                           "wrong layout, missing columns.")
FieldError = _input_error("FieldError", "field", "A CSV row with the wrong number of fields, a non-numeric or "
                          "non-finite value (with its line).")
TimeBaseError = _input_error("TimeBaseError", "time", "Timestamps in an unknown or ambiguous unit, not increasing, or "
                             "inconsistent with the stated rate.")
GapError = _input_error("GapError", "gap", "A gap in time longer than the few samples that are bridged.")
RateError = _input_error("RateError", "rate", "A sample rate outside what the method supports (the message names the "
                         "decimation option).")
UnitError = _input_error("UnitError", "unit", "Values in another unit than declared (deg/s as rad/s, g as m/s², ...).")
SpikeError = _input_error("SpikeError", "spike", "More isolated corrupt samples than can be excluded, or spikes in a "
                          "recording given unrepaired.")
DegenerateError = _input_error("DegenerateError", "degenerate", "A dead axis, a constant channel, integer counts "
                               "without a scale.")
MotionError = _input_error("MotionError", "motion", "The wrong kind of motion for the method: a moving record for "
                           "Allan, a motionless one for calibration.")
TooShortError = _input_error("TooShortError", "short", "Too few samples or too short a record for the method.")
TemperatureTrendError = _input_error(
    "TemperatureTrendError", "temperature", "A temperature trend over a static record that a random-walk (or "
    "rate-ramp) estimate would absorb: the bias follows the temperature, and the drift looks like a random walk.")
TurnsError = _input_error("TurnsError", "turns", "A turns file or a protocol's section list that cannot be used: a "
                          "missing column or key, an unknown axis, a stretch outside the recording.")
