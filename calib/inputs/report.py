"""The typed results of the input boundary: :class:`InputReport` (what was read and what was done
to it) and :class:`InputCheck` (what a method's own check of a recording found)."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from gyrosim.recording import Recording

__all__ = ["InputReport", "InputCheck", "Loaded"]


@dataclass(frozen=True)
class InputReport:
    """What the boundary read and did (all times in s after conversion).

    ``warnings``: named, for the JSON and the console (conversions, bridged gaps, excluded
    spikes, ignored columns, ...). ``problems``: in non-strict mode (``calib inspect``), what a
    method would refuse; empty in strict mode (it raises instead)."""

    source: str
    format: str
    encoding: str | None = None
    separator: str | None = None
    columns: tuple[str, ...] = ()
    ignored_columns: tuple[str, ...] = ()
    time_unit: str = "s"
    time_unit_how: str = "seconds"
    time_origin_unix_s: float | None = None
    samples: int = 0
    duration_s: float = 0.0
    rate_hz: float = float("nan")
    bridged_gaps: int = 0
    inserted_samples: int = 0
    spikes: dict[str, int] = field(default_factory=dict)
    saturated_samples: int = 0
    decimated_by: int = 1
    warnings: tuple[str, ...] = ()
    problems: tuple[str, ...] = ()

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class Loaded:
    """A recording that passed the boundary, and the report of how."""

    recording: Recording
    report: InputReport


@dataclass(frozen=True)
class InputCheck:
    """What the input checks found that is not fatal (``warnings``: named, for the JSON).

    ``saturated``: per-sample mask of samples at a rail; ``excluded``: samples that are not
    measurements and get no measurement update — saturated, bridged (inserted) or spike-repaired."""

    warnings: tuple[str, ...]
    saturated: np.ndarray
    excluded: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.excluded is None:
            object.__setattr__(self, "excluded", np.asarray(self.saturated, bool))

    @property
    def saturated_samples(self) -> int:
        return int(self.saturated.sum())

    @property
    def excluded_samples(self) -> int:
        return int(np.asarray(self.excluded).sum())
