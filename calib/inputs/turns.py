"""Turns of a known angle: stretches of a recording where the user says how far the device turned, and about
which body axis — the protocol's knowledge that gravity cannot give.

A turn about an axis held vertical keeps gravity fixed in the body frame, so the accelerometer cannot tell how far
the gyro says it turned: a session of such turns leaves that axis's scale factor to its prior.  Ferraris et al.
(1995) and imucal take the angle from the protocol instead (360° per turn).  Here a turn is a row

    start_s, end_s, axis, angle_deg, sigma_deg

(times in the recording's clock, s; ``axis`` the body axis RFU — ``x``, ``y``, ``z``, ``-x``, … or a vector; the
angle right-handed about it, ° — imucal's clockwise turns are −360; ``sigma_deg`` how well the protocol returns to
its start, ° 1σ), read from

* a turns file (:func:`read_turns`): CSV with that header (a vector axis as three numbers separated by spaces or
  semicolons, or columns ``axis_x, axis_y, axis_z``), or JSON — a list of objects with those keys (``axis`` a name
  or a list of three numbers), or ``{"turns": [...]}``;
* imucal's Ferraris section list (:func:`ferraris_turns`): ``x_rot``, ``y_rot``, ``z_rot`` as sample ``start``,
  ``end`` (imucal's own file, the JSON beside the session named ``<session>_list.json``, or a loader's
  ``meta["segments"]``), each imucal's ``expected_angle`` −360° about its axis.

The filter takes each turn as a measurement (:mod:`calib.session`): the compensated rate integrated over the
stretch, about the axis, against the stated angle with the stated σ.  Bad rows are refused with the row named
(:class:`TurnsError`, exit code 2).
"""

from __future__ import annotations

import csv
import io
import json
import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from calib.inputs.errors import TurnsError

__all__ = ["Turn", "Turns", "TurnsError", "read_turns", "ferraris_turns", "FERRARIS_ANGLE_DEG",
           "FERRARIS_SIGMA_DEG", "PROTOCOLS", "turns_for_protocol"]

# imucal's FerrarisCalibration(expected_angle=-360): a clockwise turn about the vertical sensor axis
FERRARIS_ANGLE_DEG = -360.0
# how well a hand-made Ferraris turn returns to its start heading: the device is turned on a table against a fixed
# edge and set down where it started, ±0.5° (1σ, engineering value; imucal takes the 360° as exact)
FERRARIS_SIGMA_DEG = 0.5
FERRARIS_TURNS = {"x_rot": "x", "y_rot": "y", "z_rot": "z"}
FERRARIS_POSES = ("x_p", "x_a", "y_p", "y_a", "z_p", "z_a")   # the box's faces: body axis up (p), down (a)
PROTOCOLS = ("ferraris",)
_AXES = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}
_KEYS = ("start_s", "end_s", "axis", "angle_deg", "sigma_deg")
# the largest σ a turn may claim: beyond it the row says nothing a filter could use (a quarter turn)
MAX_SIGMA_DEG = 90.0


@dataclass(frozen=True)
class Turn:
    """One stretch [start_s, end_s] (s) in which the device turned ``angle_rad`` (right-handed) about the unit body
    axis ``axis`` (RFU), known to ``sigma_rad`` (1σ); ``label`` names it in messages."""

    start_s: float
    end_s: float
    axis: tuple[float, float, float]
    angle_rad: float
    sigma_rad: float
    label: str = ""

    def to_dict(self) -> dict[str, Any]:
        return {"label": self.label, "start_s": self.start_s, "end_s": self.end_s, "axis": list(self.axis),
                "angle_deg": math.degrees(self.angle_rad), "sigma_deg": math.degrees(self.sigma_rad)}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "Turn":
        return cls(float(d["start_s"]), float(d["end_s"]), tuple(float(v) for v in d["axis"]),  # type: ignore[arg-type]
                   math.radians(float(d["angle_deg"])), math.radians(float(d["sigma_deg"])), str(d.get("label", "")))


@dataclass(frozen=True)
class Turns:
    """The turns of a recording and where they came from (a file's name, ``protocol ferraris``); ``poses``: the
    protocol's static poses on a box's faces, label → (start_s, end_s) on the recording's clock (Ferraris: ``x_p``,
    ``x_a``, … the body axis up, down; empty when the protocol has none)."""

    turns: tuple[Turn, ...]
    source: str
    poses: tuple[tuple[str, float, float], ...] = ()

    def __len__(self) -> int:
        return len(self.turns)

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"source": self.source, "turns": [t.to_dict() for t in self.turns]}
        if self.poses:
            out["poses"] = [{"label": a, "start_s": b, "end_s": c} for a, b, c in self.poses]
        return out

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "Turns":
        poses = tuple((str(p["label"]), float(p["start_s"]), float(p["end_s"])) for p in d.get("poses", []))
        return cls(tuple(Turn.from_dict(t) for t in d.get("turns", [])), str(d.get("source", "")), poses)

    def sample_ranges(self, t_s: np.ndarray) -> list[tuple[int, int]]:
        """(i0, i1) per turn: the first sample at or after ``start_s`` and the last at or before ``end_s`` of the
        clock ``t_s``; a stretch that holds fewer than two samples or lies outside the clock is refused."""
        t = np.asarray(t_s, float)
        out = []
        for turn in self.turns:
            i0 = int(np.searchsorted(t, turn.start_s - 1e-9, side="left"))
            i1 = int(np.searchsorted(t, turn.end_s + 1e-9, side="right")) - 1
            if turn.start_s < t[0] - 1e-9 or turn.end_s > t[-1] + 1e-9 or i1 - i0 < 1:
                raise TurnsError(f"turn {turn.label}: {turn.start_s:g}–{turn.end_s:g} s is not inside the recording "
                                 f"({t[0]:g}–{t[-1]:g} s) or holds fewer than two samples: give times in the "
                                 "recording's clock")
            out.append((i0, i1))
        return out


def _axis(value: Any, where: str) -> tuple[float, float, float]:
    """A unit body axis from ``x``/``-y``/… or three numbers (a list, or a string split by spaces, ``;`` or ``,``)."""
    if isinstance(value, str):
        name = value.strip().strip("[]()").lower()
        sign = -1.0 if name.startswith("-") else 1.0
        if name.lstrip("+-") in _AXES:
            return tuple(sign * c for c in _AXES[name.lstrip("+-")])  # type: ignore[return-value]
        parts = [p for p in name.replace(";", " ").replace(",", " ").split() if p]
    else:
        parts = list(value) if isinstance(value, (list, tuple)) else [value]
    try:
        v = np.array([float(p) for p in parts], float)
    except (TypeError, ValueError):
        v = np.zeros(0)
    if v.size != 3 or not np.all(np.isfinite(v)) or np.linalg.norm(v) < 1e-9:
        raise TurnsError(f"{where}: axis {value!r} is neither x, y, z (with an optional sign) nor three numbers "
                         "of a non-zero vector (body frame, right-forward-up)")
    v = v / np.linalg.norm(v)
    return (float(v[0]), float(v[1]), float(v[2]))


def _number(row: dict[str, Any], key: str, where: str) -> float:
    try:
        x = float(row[key])
    except KeyError:
        raise TurnsError(f"{where}: no {key!r}; every turn needs {', '.join(_KEYS)}") from None
    except (TypeError, ValueError):
        raise TurnsError(f"{where}: {key} {row[key]!r} is not a number") from None
    if not math.isfinite(x):
        raise TurnsError(f"{where}: {key} is {x}: give a finite number")
    return x


def _turn(row: dict[str, Any], where: str) -> Turn:
    row = {str(k).strip().lower(): v for k, v in row.items() if k is not None}
    if "axis" not in row and all(f"axis_{c}" in row for c in "xyz"):
        row["axis"] = [row[f"axis_{c}"] for c in "xyz"]
    start, end = _number(row, "start_s", where), _number(row, "end_s", where)
    angle, sigma = _number(row, "angle_deg", where), _number(row, "sigma_deg", where)
    if "axis" not in row:
        raise TurnsError(f"{where}: no 'axis' (x, y, z, -x, … or three numbers)")
    if end <= start:
        raise TurnsError(f"{where}: end_s {end:g} s is not after start_s {start:g} s")
    if not 0.0 < sigma <= MAX_SIGMA_DEG:
        raise TurnsError(f"{where}: sigma_deg {sigma:g} must be above 0 and at most {MAX_SIGMA_DEG:g}° (how well "
                         "the turn's angle is known, 1σ)")
    return Turn(start, end, _axis(row["axis"], where), math.radians(angle), math.radians(sigma),
                str(row.get("label") or where))


def _check_order(turns: list[Turn], source: str) -> Turns:
    if not turns:
        raise TurnsError(f"{source}: no turns in it")
    ordered = sorted(turns, key=lambda t: t.start_s)
    for a, b in zip(ordered[:-1], ordered[1:]):
        if b.start_s < a.end_s:
            raise TurnsError(f"{source}: turns {a.label} and {b.label} overlap ({a.start_s:g}–{a.end_s:g} s and "
                             f"{b.start_s:g}–{b.end_s:g} s): one stretch, one turn")
    return Turns(tuple(ordered), source)


def read_turns(path: str | Path) -> Turns:
    """The turns of a CSV or JSON turns file (module docstring); :class:`TurnsError` names the row when one is bad."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise TurnsError(f"no turns file at {path}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise TurnsError(f"cannot read the turns file {path.name}: {exc}") from None
    if path.suffix.lower() == ".json" or text.lstrip().startswith(("[", "{")):
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise TurnsError(f"{path.name} is not valid JSON: {exc}") from None
        rows = data.get("turns") if isinstance(data, dict) else data
        if not isinstance(rows, list) or not all(isinstance(r, dict) for r in rows):
            raise TurnsError(f"{path.name}: expected a list of turns (objects with {', '.join(_KEYS)}) or "
                             "{\"turns\": [...]}")
        turns = [_turn(r, f"{path.name} turn {i + 1}") for i, r in enumerate(rows)]
    else:
        lines = [ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
        reader = csv.DictReader(io.StringIO("\n".join(lines)), skipinitialspace=True)
        if reader.fieldnames is None:
            raise TurnsError(f"{path.name} is empty: a header row {','.join(_KEYS)} and one row per turn")
        turns = [_turn(r, f"{path.name} row {i + 2}") for i, r in enumerate(reader)]
    return _check_order(turns, path.name)


def ferraris_turns(segments: dict[str, Any], t_s: np.ndarray, source: str = "protocol ferraris",
                   sigma_deg: float = FERRARIS_SIGMA_DEG) -> Turns:
    """The three turns of imucal's Ferraris section list ``segments`` (``x_rot``, ``y_rot``, ``z_rot`` with sample
    ``start``, ``end``, the others — the six poses — not turns) on the recording's clock ``t_s``: each −360° about
    its axis (imucal's ``expected_angle``), ``sigma_deg`` 1σ."""
    t = np.asarray(t_s, float)
    turns = []
    for key, axis in FERRARIS_TURNS.items():
        seg = segments.get(key)
        if not isinstance(seg, dict) or "start" not in seg or "end" not in seg:
            raise TurnsError(f"{source}: the section list has no {key!r} with 'start' and 'end' (imucal's Ferraris "
                             f"sections: {', '.join(FERRARIS_TURNS)} and the six poses)")
        i0, i1 = int(seg["start"]), int(seg["end"])
        if not 0 <= i0 < i1 < t.size:
            raise TurnsError(f"{source}: {key} spans samples {i0}–{i1}, outside the recording's {t.size} samples")
        turns.append(Turn(float(t[i0]), float(t[i1]), _AXES[axis], math.radians(FERRARIS_ANGLE_DEG),
                          math.radians(sigma_deg), key))
    checked = _check_order(turns, source)
    poses = []
    for key in FERRARIS_POSES:   # the six box faces, when the list has every one inside the recording
        seg = segments.get(key)
        if not isinstance(seg, dict) or not 0 <= int(seg.get("start", -1)) < int(seg.get("end", -1)) < t.size:
            return checked
        poses.append((key, float(t[int(seg["start"])]), float(t[int(seg["end"])])))
    return replace(checked, poses=tuple(poses))


def turns_for_protocol(protocol: str, meta: dict[str, Any], t_s: np.ndarray,
                       recording_path: str | Path | None = None) -> Turns:
    """The turns a named protocol implies for a recording: ``ferraris`` reads imucal's section list from the
    recording's ``meta["segments"]`` (a loader's) or the JSON beside the recording file, ``<stem>_list.json``."""
    if protocol not in PROTOCOLS:
        raise TurnsError(f"unknown protocol {protocol!r}; known: {', '.join(PROTOCOLS)}")
    segments = meta.get("segments") if isinstance(meta, dict) else None
    source = "protocol ferraris"
    if not segments and recording_path is not None and not str(recording_path).startswith("dataset:"):
        beside = Path(recording_path).with_name(f"{Path(recording_path).stem}_list.json")
        if not beside.is_file():
            raise TurnsError(f"--protocol ferraris needs imucal's section list beside the recording: no "
                             f"{beside.name} next to {Path(recording_path).name} (or give the turns with --turns FILE)")
        try:
            segments = json.loads(beside.read_text())
        except (OSError, json.JSONDecodeError) as exc:
            raise TurnsError(f"cannot read the section list {beside.name}: {exc}") from None
        source = f"protocol ferraris ({beside.name})"
    if not isinstance(segments, dict) or not segments:
        raise TurnsError("--protocol ferraris needs imucal's section list (x_rot, y_rot, z_rot as sample start, end): "
                         "this recording has none; give the turns with --turns FILE")
    return ferraris_turns(segments, t_s, source)
