"""The magnetometer calibration result: a frozen dataclass that applies, saves and loads itself.

Model: m = A·B + h (µT), B the field in the IMU body frame (RFU).  ``soft_iron`` is A (3×3,
dimensionless), ``hard_iron_ut`` is h.  Unless the true field magnitude was given, A is
normalised to det A = 1 and ``field_ut`` is the field magnitude in the sensor's own average
scale.  The ellipsoid fit's A is symmetric (it cannot see a rotation); the attitude-aided fit's
is general, its rotation part is ``misalignment_deg`` (A = P·R(θ)ᵀ, P symmetric: the sensor's
axes are the IMU's rotated by θ).

The JSON layout (``calib mag --json``) is a promise to users' scripts:

    {"format": "calib.magnetometer/1", "method": ..., "status": "ok" | ..., "warnings": [...],
     "magnetometer": {"hard_iron_uT": [3], "soft_iron": [[3×3]], "field_uT": F,
                      "inclination_deg": I, "misalignment_deg": [3] | null,
                      "std": {same keys: 1σ}, "refused": [...], "disturbances": [...],
                      "regimes": [...], ...},
     "samples": {...}, "coverage": {...}, "consistency": {...}, "model": "..."}

NaN (not estimated) is written as null.

**Regimes.**  A magnet attached to the board (or taken off) changes the hard iron mid-session
(:mod:`calib.mag.regimes`).  ``regimes`` lists the stretches of one hard iron in time order, each
``{"index", "start_s", "end_s", "group", "kind", "status", "reason", "hard_iron_uT", "soft_iron",
"field_uT", "std": {...}, "samples": {...}, "change": {...} | null, "warnings": [...]}``: regimes
with the same hard iron share a ``group`` and one calibration; ``kind`` is ``reference`` (the
group of the top-level keys, the one with most samples) or ``attached`` (a different field that
turns with the board); ``status`` is one of :data:`STATUSES` or ``not_calibratable`` (too short or
too little turning: ``reason`` says which; nothing is fitted then); ``change`` is the change that
starts the regime: its time and σ (s), the transition in which no hard iron explained the field,
and the test (the body-frame offset change with σ, χ², degrees of freedom, p).  The top-level keys
are the reference group's calibration; a session of one regime lists it alone.  Each
``disturbances`` entry says its ``kind``: ``world-fixed`` (tied to a place in the room: excluded,
not calibrated), ``attached`` (a regime of its own, calibrated; ``regime`` is its index) or
``undetermined`` (the board did not turn there: the two cannot be told apart; excluded), with the
``evidence`` of the body-frame offset test where the board turned.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gyrosim.effects import HardIron, SoftIron
from gyrosim.recording import Recording

__all__ = ["Disturbance", "Regime", "MagCalibration", "STATUSES", "REGIME_STATUSES", "DISTURBANCE_KINDS", "FORMAT",
           "write_json_atomic"]

FORMAT = "calib.magnetometer/1"
# status → exit code of ``calib mag``: 0 done and ok, 1 done but not ok (the status and the
# warnings say why); bad input (2) and internal errors (3) never produce a result
STATUSES = {
    "ok": 0,
    "hard_iron_only": 1,  # the soft iron refused by name (coverage, prior, no magnetometer's ellipsoid)
    "inconsistent": 1,  # σ not honest: the residual has structure the model lacks
    "disturbed": 1,  # more than half of the samples magnetically disturbed
    "partial": 1,  # the hard iron changed and a regime could not be calibrated (or not to ok)
}
REGIME_STATUSES = (*STATUSES, "not_calibratable")
DISTURBANCE_KINDS = ("world-fixed", "attached", "undetermined")
MODEL = "m = A·B + h; m measured, B the field in the IMU body frame (RFU), µT; A = soft_iron, h = hard_iron_uT"


def _jsonable(v: Any) -> Any:
    if isinstance(v, np.ndarray):
        return _jsonable(v.tolist())
    if isinstance(v, (list, tuple)):
        return [_jsonable(x) for x in v]
    if isinstance(v, dict):
        return {k: _jsonable(x) for k, x in v.items()}
    if isinstance(v, (float, np.floating)):
        return None if not math.isfinite(float(v)) else float(v)
    if isinstance(v, np.integer):
        return int(v)
    if isinstance(v, np.bool_):
        return bool(v)
    return v


def _arr(v: Any, shape: tuple[int, ...]) -> np.ndarray:
    if v is None:
        return np.full(shape, np.nan)
    return np.array([[np.nan if x is None else x for x in row] for row in v], dtype=float) if len(shape) == 2 \
        else np.array([np.nan if x is None else x for x in v], dtype=float)


def write_json_atomic(path: str | os.PathLike[str], obj: Any) -> Path:
    """JSON (NaN → null, the reason in ``warnings``) written atomically: a failed write leaves nothing
    half-written and an existing file untouched (:func:`calib.app.outputs.write_json_atomic`)."""
    from calib.app.outputs import write_json_atomic as write

    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise ValueError(f"cannot write {path}: folder {folder} does not exist; create it first")
    write(path, _jsonable(obj))
    return path


@dataclass(frozen=True)
class Disturbance:
    """A stretch where the field magnitude or inclination left the calibrated values.  ``kind``:
    ``world-fixed`` — a local anomaly (a magnet, a steel object the board passed), excluded from the
    fit and reported; ``attached`` — a field that turned with the board (a magnet on it), calibrated
    as its own regime (index ``regime``); ``undetermined`` — the board did not turn there, so the
    two cannot be told apart (excluded; also what a disturbance is until the test has been made).
    ``evidence``: the body-frame offset test (:func:`calib.mag.regimes.stretch_offset_test`) where the
    board turned, else None."""

    t_start_s: float
    t_end_s: float
    samples: int
    max_field_deviation_ut: float
    max_inclination_deviation_deg: float
    position_nav_m: tuple[float, float, float] | None = None
    kind: str = "undetermined"
    regime: int | None = None
    evidence: dict[str, Any] | None = None

    def __post_init__(self) -> None:
        if self.kind not in DISTURBANCE_KINDS:
            raise ValueError(f"disturbance kind {self.kind!r}: one of {', '.join(DISTURBANCE_KINDS)}")

    def to_dict(self) -> dict[str, Any]:
        return _jsonable({"t_start_s": self.t_start_s, "t_end_s": self.t_end_s, "samples": self.samples,
                          "max_field_deviation_uT": self.max_field_deviation_ut,
                          "max_inclination_deviation_deg": self.max_inclination_deviation_deg,
                          "position_nav_m": list(self.position_nav_m) if self.position_nav_m else None,
                          "kind": self.kind, "regime": self.regime, "evidence": self.evidence})

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "Disturbance":
        nan = float("nan")
        pos = d.get("position_nav_m")
        return cls(float(d["t_start_s"]), float(d["t_end_s"]), int(d["samples"]),
                   nan if d.get("max_field_deviation_uT") is None else float(d["max_field_deviation_uT"]),
                   nan if d.get("max_inclination_deviation_deg") is None else float(d["max_inclination_deviation_deg"]),
                   tuple(pos) if pos else None, d.get("kind", "undetermined"), d.get("regime"), d.get("evidence"))


def _num(v: Any) -> float:
    return float("nan") if v is None else float(v)


@dataclass(frozen=True)
class Regime:
    """A stretch of one hard iron [``start_s``, ``end_s``] (s) and its calibration (module docstring,
    *Regimes*): hard iron (µT), soft iron, field (µT) with 1σ, its status and, when not ok, why."""

    index: int
    start_s: float
    end_s: float
    group: int
    kind: str
    status: str
    reason: str
    hard_iron_ut: np.ndarray
    soft_iron: np.ndarray
    field_ut: float
    hard_iron_std_ut: np.ndarray
    soft_iron_std: np.ndarray
    field_std_ut: float
    samples: dict[str, int] = field(default_factory=dict)
    change: dict[str, Any] | None = None
    warnings: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if self.status not in REGIME_STATUSES:
            raise ValueError(f"regime status {self.status!r}: one of {', '.join(REGIME_STATUSES)}")

    @property
    def calibrated(self) -> bool:
        """A hard iron was estimated (the soft iron may still be refused)."""
        return self.status != "not_calibratable" and bool(np.all(np.isfinite(self.hard_iron_ut)))

    def compensate(self, mag_ut: np.ndarray) -> np.ndarray:
        """B = A⁻¹ (m − h) with this regime's calibration (a refused soft iron taken as I)."""
        a = np.where(np.isfinite(self.soft_iron), self.soft_iron, np.eye(3))
        return (np.asarray(mag_ut, dtype=float) - np.nan_to_num(self.hard_iron_ut)) @ np.linalg.inv(a).T

    def to_dict(self) -> dict[str, Any]:
        return _jsonable({
            "index": self.index, "start_s": self.start_s, "end_s": self.end_s, "group": self.group,
            "kind": self.kind, "status": self.status, "reason": self.reason, "hard_iron_uT": self.hard_iron_ut,
            "soft_iron": self.soft_iron, "field_uT": self.field_ut,
            "std": {"hard_iron_uT": self.hard_iron_std_ut, "soft_iron": self.soft_iron_std,
                    "field_uT": self.field_std_ut},
            "samples": dict(self.samples), "change": self.change, "warnings": list(self.warnings)})

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "Regime":
        s = d.get("std", {})
        return cls(int(d["index"]), float(d["start_s"]), float(d["end_s"]), int(d["group"]), d["kind"], d["status"],
                   d.get("reason", ""), _arr(d["hard_iron_uT"], (3,)), _arr(d["soft_iron"], (3, 3)),
                   _num(d.get("field_uT")), _arr(s.get("hard_iron_uT"), (3,)), _arr(s.get("soft_iron"), (3, 3)),
                   _num(s.get("field_uT")), dict(d.get("samples", {})), d.get("change"),
                   tuple(d.get("warnings", [])))


@dataclass(frozen=True)
class MagCalibration:
    """Hard iron, soft iron, field, inclination (and misalignment) with 1σ, status and warnings."""

    method: str
    status: str
    hard_iron_ut: np.ndarray
    soft_iron: np.ndarray
    field_ut: float
    inclination_deg: float
    misalignment_deg: np.ndarray | None
    hard_iron_std_ut: np.ndarray
    soft_iron_std: np.ndarray
    field_std_ut: float
    inclination_std_deg: float
    misalignment_std_deg: np.ndarray | None
    field_reference: str
    warnings: tuple[str, ...] = ()
    refused: tuple[str, ...] = ()
    disturbances: tuple[Disturbance, ...] = ()
    samples: dict[str, int] = field(default_factory=dict)
    coverage: dict[str, Any] = field(default_factory=dict)
    consistency: dict[str, Any] = field(default_factory=dict)
    diagnostics: dict[str, Any] = field(default_factory=dict)
    regimes: tuple[Regime, ...] = ()

    def __post_init__(self) -> None:
        if self.status not in STATUSES:
            raise ValueError(f"status {self.status!r}: one of {', '.join(STATUSES)}")

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    @property
    def exit_code(self) -> int:
        """0 when ``ok``, else 1 (done, but not ok: the status and warnings say why)."""
        return STATUSES[self.status]

    # ------------------------------------------------------------------ apply
    def compensate(self, mag_ut: np.ndarray, t_s: np.ndarray | None = None) -> np.ndarray:
        """B = A⁻¹ (m − h): the field in the IMU body frame (µT) from measured samples (N, 3).
        Components the fit refused (NaN hard iron) are left uncorrected (treated as 0).  With the
        samples' times ``t_s`` (s) each regime's calibration applies on its stretch (a regime that
        could not be calibrated takes its calibrated neighbour's, the one before it first: a magnet
        is more often put on and left than the other way round); without them, the top-level one
        applies everywhere."""
        h = np.nan_to_num(self.hard_iron_ut)
        a = np.where(np.isfinite(self.soft_iron), self.soft_iron, np.eye(3))
        m = np.asarray(mag_ut, dtype=float)
        out = (m - h) @ np.linalg.inv(a).T
        if t_s is None or len(self.regimes) < 2:
            return out
        t = np.asarray(t_s, dtype=float)
        if t.shape != (m.shape[0],):
            raise ValueError(f"t_s has shape {t.shape}; expected ({m.shape[0]},), one time per sample")
        last = len(self.regimes) - 1
        for i, r in enumerate(self.regimes):
            order = [r, *self.regimes[:i][::-1], *self.regimes[i + 1:]]  # itself, then before it, then after
            use = next((x for x in order if x.calibrated), None)
            if use is None:
                continue
            inside = (t >= r.start_s) & ((t < r.end_s) if i < last else (t <= r.end_s))
            out[inside] = use.compensate(m[inside])
        return out

    def compensate_recording(self, rec: Recording) -> Recording:
        """A copy of ``rec`` whose ``mag_ut`` is compensated, each regime on its stretch (the input is
        untouched)."""
        if rec.mag_ut is None:
            raise ValueError("the recording has no magnetometer channel to compensate")
        meta = {**rec.meta, "magnetometer_calibration": json.dumps(self.to_dict(), sort_keys=True)}
        return rec.with_signals(mag_ut=self.compensate(rec.mag_ut, rec.t_s), meta=meta)

    def to_effects(self) -> tuple[HardIron, SoftIron]:
        """The result in the effect vocabulary (gyrosim.effects): simulate or compensate with it."""
        return (HardIron(value=np.nan_to_num(self.hard_iron_ut)),
                SoftIron(matrix=np.where(np.isfinite(self.soft_iron), self.soft_iron, np.eye(3)), symmetric=False))

    # ------------------------------------------------------------------ serialise
    def to_dict(self) -> dict[str, Any]:
        mis = None if self.misalignment_deg is None else self.misalignment_deg
        mis_s = None if self.misalignment_std_deg is None else self.misalignment_std_deg
        return _jsonable({
            "format": FORMAT,
            "method": self.method,
            "status": self.status,
            "warnings": list(self.warnings),
            "magnetometer": {
                "hard_iron_uT": self.hard_iron_ut,
                "soft_iron": self.soft_iron,
                "field_uT": self.field_ut,
                "inclination_deg": self.inclination_deg,
                "misalignment_deg": mis,
                "std": {"hard_iron_uT": self.hard_iron_std_ut, "soft_iron": self.soft_iron_std,
                        "field_uT": self.field_std_ut, "inclination_deg": self.inclination_std_deg,
                        "misalignment_deg": mis_s},
                "field_reference": self.field_reference,
                "refused": list(self.refused),
                "disturbances": [d.to_dict() for d in self.disturbances],
                "regimes": [r.to_dict() for r in self.regimes],
            },
            "samples": dict(self.samples),
            "coverage": dict(self.coverage),
            "consistency": dict(self.consistency),
            "diagnostics": dict(self.diagnostics),
            "model": MODEL,
        })

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "MagCalibration":
        if d.get("format") != FORMAT:
            raise ValueError(f"not a magnetometer calibration of format {FORMAT!r} (got {d.get('format')!r})")
        m = d["magnetometer"]
        s = m["std"]
        nan = float("nan")

        def num(v):
            return nan if v is None else float(v)

        return cls(
            method=d["method"], status=d["status"],
            hard_iron_ut=_arr(m["hard_iron_uT"], (3,)), soft_iron=_arr(m["soft_iron"], (3, 3)),
            field_ut=num(m["field_uT"]), inclination_deg=num(m["inclination_deg"]),
            misalignment_deg=None if m.get("misalignment_deg") is None else _arr(m["misalignment_deg"], (3,)),
            hard_iron_std_ut=_arr(s["hard_iron_uT"], (3,)), soft_iron_std=_arr(s["soft_iron"], (3, 3)),
            field_std_ut=num(s["field_uT"]), inclination_std_deg=num(s["inclination_deg"]),
            misalignment_std_deg=None if s.get("misalignment_deg") is None else _arr(s["misalignment_deg"], (3,)),
            field_reference=m.get("field_reference", ""), warnings=tuple(d.get("warnings", [])),
            refused=tuple(m.get("refused", [])),
            disturbances=tuple(Disturbance.from_dict(x) for x in m.get("disturbances", [])),
            samples=dict(d.get("samples", {})), coverage=dict(d.get("coverage", {})),
            consistency=dict(d.get("consistency", {})), diagnostics=dict(d.get("diagnostics", {})),
            regimes=tuple(Regime.from_dict(x) for x in m.get("regimes", [])),
        )

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the JSON atomically (temporary file in the same folder, then rename)."""
        return write_json_atomic(path, self.to_dict())

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> "MagCalibration":
        return cls.from_dict(json.loads(Path(path).read_text()))
