"""Exceptions raised by gyrosim. Every message says what was wrong and what to do about it."""

from __future__ import annotations


class GyrosimError(ValueError):
    """Base class: bad input or a request that cannot be carried out as asked."""


class ScheduleError(GyrosimError):
    """A schedule file or segment is malformed."""


class PresetError(GyrosimError):
    """An unknown preset name, or a preset file with missing/unknown keys."""


class ReachError(GyrosimError):
    """The schedule (with the hand's imperfections) drives an arm joint past its limit."""


class RecordingError(GyrosimError):
    """A recording is malformed: shapes, NaNs, timestamps, units or metadata."""


class OutputPathError(GyrosimError):
    """An output path that cannot or must not be written: a missing or read-only folder, a
    directory where a file is expected, or a path equal to one of the command's inputs."""
