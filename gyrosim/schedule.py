"""Calibration rotation schedules: what the hand is asked to do, as data.

A :class:`Schedule` is an initial attitude plus an ordered list of :class:`Segment` s:

* ``rest``      — hold still for ``duration_s``;
* ``rotate``    — turn about a *body* axis (Right-Forward-Up) by ``angle_rad`` in ``duration_s``;
* ``switch``    — the same motion, marking a re-orientation between calibration rotations
                  (Zhou et al. 2020, Table 6, "Switch");
* ``translate`` — move the hand by ``displacement_m`` (navigation frame, East-North-Up).

Every motion follows the minimum-jerk (quintic) profile

    s(τ) = 10τ³ − 15τ⁴ + 6τ⁵,   τ = (t − t₀)/T ∈ [0, 1],

so angle, rate and angular acceleration are continuous across segment boundaries and the jerk is
bounded (|s'''| ≤ 60): rate(t) = A/T · s'(τ), peak 1.875 A/T; acceleration A/T² · s''(τ), peak
5.77 A/T².  A rotation about a body axis keeps that axis fixed in space, so the attitude within a
segment is q₀ ⊗ Exp(axis · A s(τ)) exactly.

Built-in schedules live as TOML files in ``gyrosim/schedules/``; users write their own in the same
format (see :func:`load_schedule` and docs/simulation.md, "Schedules").
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ._presets import builtin_names, load_named_toml
from .errors import ScheduleError
from .rotations import quat_from_rotvec, quat_multiply, quat_normalize

__all__ = [
    "Segment",
    "Schedule",
    "ScheduleKinematics",
    "builtin_schedule_names",
    "load_schedule",
    "schedule_from_dict",
    "minimum_jerk",
]

SEGMENT_KINDS = ("rest", "rotate", "switch", "translate")
_AXES = {
    "x": (1.0, 0.0, 0.0),
    "y": (0.0, 1.0, 0.0),
    "z": (0.0, 0.0, 1.0),
    "-x": (-1.0, 0.0, 0.0),
    "-y": (0.0, -1.0, 0.0),
    "-z": (0.0, 0.0, -1.0),
}


def minimum_jerk(tau: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Quintic minimum-jerk profile s(τ) and its first two derivatives with respect to τ.

    s = 10τ³ − 15τ⁴ + 6τ⁵, s' = 30τ²(1 − τ)², s'' = 60τ(1 − τ)(1 − 2τ); τ is clipped to [0, 1].
    """
    tau = np.clip(tau, 0.0, 1.0)
    s = tau**3 * (10.0 - 15.0 * tau + 6.0 * tau**2)
    ds = 30.0 * tau**2 * (1.0 - tau) ** 2
    dds = 60.0 * tau * (1.0 - tau) * (1.0 - 2.0 * tau)
    return s, ds, dds


@dataclass(frozen=True)
class Segment:
    """One step of a schedule.

    Attributes
    ----------
        kind: ``rest``, ``rotate``, ``switch`` or ``translate``.
        duration_s: length of the segment (s), > 0.
        axis_body: unit rotation axis in the body frame (RFU) for rotate/switch, else None.
        angle_rad: signed rotation angle (rad) about ``axis_body`` (right-hand rule).
        displacement_m: translation (m) in the navigation frame (ENU) for translate, else None.
        label: free text shown in reports.
    """

    kind: str
    duration_s: float
    axis_body: tuple[float, float, float] | None = None
    angle_rad: float = 0.0
    displacement_m: tuple[float, float, float] | None = None
    label: str = ""

    def __post_init__(self) -> None:
        if self.kind not in SEGMENT_KINDS:
            raise ScheduleError(
                f"unknown segment kind {self.kind!r}; use one of {', '.join(SEGMENT_KINDS)}"
            )
        if not (math.isfinite(self.duration_s) and self.duration_s > 0):
            raise ScheduleError(
                f"segment {self.label or self.kind!r} has duration_s={self.duration_s}; "
                "it must be a finite number of seconds > 0"
            )
        if self.kind in ("rotate", "switch"):
            if self.axis_body is None:
                raise ScheduleError(f"{self.kind} segment {self.label!r} needs an axis")
            n = math.sqrt(sum(c * c for c in self.axis_body))
            if not math.isclose(n, 1.0, rel_tol=1e-9):
                raise ScheduleError(f"axis {self.axis_body} of segment {self.label!r} is not unit")
            if not math.isfinite(self.angle_rad):
                raise ScheduleError(f"segment {self.label!r}: angle must be finite")
        if self.kind == "translate":
            if self.displacement_m is None or not all(map(math.isfinite, self.displacement_m)):
                raise ScheduleError(f"translate segment {self.label!r} needs displacement_m [E,N,U]")

    @property
    def peak_rate_rad_s(self) -> float:
        """Peak angular rate (rad/s) of the minimum-jerk profile: 1.875 |angle| / T."""
        return 1.875 * abs(self.angle_rad) / self.duration_s

    def to_dict(self) -> dict[str, Any]:
        d: dict[str, Any] = {"kind": self.kind, "duration_s": self.duration_s}
        if self.axis_body is not None:
            d["axis"] = list(self.axis_body)
            d["angle_deg"] = math.degrees(self.angle_rad)
        if self.displacement_m is not None:
            d["displacement_m"] = list(self.displacement_m)
        if self.label:
            d["label"] = self.label
        return d


@dataclass(frozen=True)
class ScheduleKinematics:
    """Commanded kinematics of a schedule sampled at times ``t_s``.

    Frames: ``omega_body_rad_s`` and ``omega_dot_body_rad_s2`` in the body frame (RFU);
    ``quat_nb`` body→navigation (w, x, y, z); ``translation_m`` and its derivatives are the hand's
    commanded displacement from its start point in the navigation frame (ENU).
    """

    t_s: np.ndarray
    omega_body_rad_s: np.ndarray
    omega_dot_body_rad_s2: np.ndarray
    quat_nb: np.ndarray
    translation_m: np.ndarray
    velocity_m_s: np.ndarray
    acceleration_m_s2: np.ndarray
    segment_index: np.ndarray


@dataclass(frozen=True)
class Schedule:
    """An initial attitude and a list of segments. See module docstring."""

    name: str
    segments: tuple[Segment, ...]
    initial_quat_nb: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)
    description: str = ""
    notes: str = ""
    source: str = ""
    boundaries_s: tuple[float, ...] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if not self.segments:
            raise ScheduleError(f"schedule {self.name!r} has no segments")
        q = np.asarray(self.initial_quat_nb, dtype=float)
        if q.shape != (4,) or not np.all(np.isfinite(q)) or abs(np.linalg.norm(q) - 1) > 1e-6:
            raise ScheduleError(
                f"initial_quat of schedule {self.name!r} must be a unit quaternion [w,x,y,z]"
            )
        b = np.concatenate([[0.0], np.cumsum([s.duration_s for s in self.segments])])
        object.__setattr__(self, "boundaries_s", tuple(float(x) for x in b))

    @property
    def duration_s(self) -> float:
        return self.boundaries_s[-1]

    def segment_at(self, t_s: np.ndarray) -> np.ndarray:
        """Index of the segment active at each time (s); times past the end map to the last."""
        idx = np.searchsorted(np.asarray(self.boundaries_s), np.asarray(t_s), side="right") - 1
        return np.clip(idx, 0, len(self.segments) - 1)

    def kinematics(self, t_s: np.ndarray) -> ScheduleKinematics:
        """Commanded (ideal-hand) kinematics at the given times, closed form (no integration)."""
        t = np.asarray(t_s, dtype=float)
        n = t.shape[0]
        idx = self.segment_at(t)
        omega = np.zeros((n, 3))
        omega_dot = np.zeros((n, 3))
        rotvec = np.zeros((n, 3))
        trans = np.zeros((n, 3))
        vel = np.zeros((n, 3))
        acc = np.zeros((n, 3))
        # attitude and position at the start of every segment
        q_start = [np.asarray(self.initial_quat_nb, dtype=float)]
        p_start = [np.zeros(3)]
        for seg in self.segments:
            if seg.kind in ("rotate", "switch"):
                dq = quat_from_rotvec(np.asarray(seg.axis_body) * seg.angle_rad)
                q_start.append(quat_multiply(q_start[-1], dq))
            else:
                q_start.append(q_start[-1])
            step = np.asarray(seg.displacement_m) if seg.kind == "translate" else 0.0
            p_start.append(p_start[-1] + step)
        q0 = np.empty((n, 4))
        # times in order (the simulator's chunks): each segment is one slice of rows, and only the
        # segments the times reach are visited; otherwise a mask per segment
        ordered = n > 0 and bool(np.all(idx[1:] >= idx[:-1]))
        for i, seg in enumerate(self.segments):
            if ordered:
                if i < idx[0] or i > idx[-1]:
                    continue
                sel = slice(int(np.searchsorted(idx, i, "left")), int(np.searchsorted(idx, i, "right")))
            else:
                sel = idx == i
            if not np.any(idx[sel] == i):
                continue
            q0[sel] = q_start[i]
            trans[sel] = p_start[i]
            T = seg.duration_s
            tau = (t[sel] - self.boundaries_s[i]) / T
            s, ds, dds = minimum_jerk(tau)
            if seg.kind in ("rotate", "switch"):
                a = np.asarray(seg.axis_body)
                rotvec[sel] = np.outer(seg.angle_rad * s, a)
                omega[sel] = np.outer(seg.angle_rad / T * ds, a)
                omega_dot[sel] = np.outer(seg.angle_rad / T**2 * dds, a)
            elif seg.kind == "translate":
                d = np.asarray(seg.displacement_m)
                trans[sel] += np.outer(s, d)
                vel[sel] = np.outer(ds / T, d)
                acc[sel] = np.outer(dds / T**2, d)
        quat = quat_normalize(quat_multiply(q0, quat_from_rotvec(rotvec)))
        return ScheduleKinematics(t, omega, omega_dot, quat, trans, vel, acc, idx)

    def to_dict(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "description": self.description,
            "notes": self.notes,
            "source": self.source,
            "initial_quat": list(self.initial_quat_nb),
            "segments": [s.to_dict() for s in self.segments],
        }


def _parse_axis(value: Any, where: str) -> tuple[float, float, float]:
    if isinstance(value, str):
        key = value.strip().lower()
        if key not in _AXES:
            raise ScheduleError(f"{where}: axis {value!r} is not one of {sorted(_AXES)} or [x,y,z]")
        return _AXES[key]
    try:
        v = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ScheduleError(f"{where}: axis must be 'x'/'y'/'z' or a 3-vector, got {value!r}") from exc
    if v.shape != (3,) or not np.all(np.isfinite(v)) or np.linalg.norm(v) == 0:
        raise ScheduleError(f"{where}: axis must be a finite non-zero 3-vector, got {value!r}")
    v = v / np.linalg.norm(v)
    return (float(v[0]), float(v[1]), float(v[2]))


_SEGMENT_KEYS = {"kind", "duration_s", "axis", "angle_deg", "angle_rad", "displacement_m", "label"}
_SCHEDULE_KEYS = {"name", "description", "notes", "source", "initial_quat", "segments"}


def schedule_from_dict(data: dict[str, Any], default_name: str = "custom") -> Schedule:
    """Build a :class:`Schedule` from the TOML/JSON layout documented in docs/simulation.md."""
    unknown = set(data) - _SCHEDULE_KEYS
    if unknown:
        raise ScheduleError(
            f"unknown schedule key(s) {sorted(unknown)}; allowed: {sorted(_SCHEDULE_KEYS)}"
        )
    raw_segments = data.get("segments")
    if not isinstance(raw_segments, list) or not raw_segments:
        raise ScheduleError("a schedule needs a non-empty [[segments]] list")
    segments = []
    for i, raw in enumerate(raw_segments):
        where = f"segment {i + 1}"
        if not isinstance(raw, dict):
            raise ScheduleError(f"{where} must be a table")
        bad = set(raw) - _SEGMENT_KEYS
        if bad:
            raise ScheduleError(f"{where}: unknown key(s) {sorted(bad)}; allowed: {sorted(_SEGMENT_KEYS)}")
        kind = raw.get("kind")
        if "duration_s" not in raw:
            raise ScheduleError(f"{where}: duration_s is required (seconds)")
        duration = float(raw["duration_s"])
        label = str(raw.get("label", ""))
        if kind in ("rotate", "switch"):
            if ("angle_deg" in raw) == ("angle_rad" in raw):
                raise ScheduleError(f"{where}: give exactly one of angle_deg or angle_rad")
            angle = math.radians(float(raw["angle_deg"])) if "angle_deg" in raw else float(raw["angle_rad"])
            if "axis" not in raw:
                raise ScheduleError(f"{where}: axis is required for a {kind} segment")
            segments.append(Segment(kind, duration, _parse_axis(raw["axis"], where), angle, label=label))
        elif kind == "translate":
            disp = raw.get("displacement_m")
            if disp is None or len(disp) != 3:
                raise ScheduleError(f"{where}: translate needs displacement_m = [E, N, U] in metres")
            segments.append(
                Segment(kind, duration, displacement_m=tuple(float(x) for x in disp), label=label)
            )
        else:
            segments.append(Segment(str(kind), duration, label=label))
    q0 = tuple(float(x) for x in data.get("initial_quat", (1.0, 0.0, 0.0, 0.0)))
    return Schedule(
        name=str(data.get("name", default_name)),
        segments=tuple(segments),
        initial_quat_nb=q0,  # type: ignore[arg-type]
        description=str(data.get("description", "")),
        notes=str(data.get("notes", "")),
        source=str(data.get("source", "")),
    )


def builtin_schedule_names() -> list[str]:
    """Names of the schedules shipped in ``gyrosim/schedules/*.toml``."""
    return builtin_names("schedules")


def load_schedule(name_or_path: str | Path) -> Schedule:
    """Load a built-in schedule by name (e.g. ``zhou2020``) or a user TOML file by path."""
    name, data = load_named_toml(("schedules",), name_or_path, "schedule", ScheduleError)
    return schedule_from_dict(data, default_name=name)
