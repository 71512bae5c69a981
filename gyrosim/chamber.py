"""Thermal-chamber profiles: the ambient temperature (°C) a sensor sits in, over time (s).

A profile is written in TOML as a start temperature and a list of steps, each a hold or a ramp,
optionally repeated (``repeat``) — the way a chamber programme is written:

    start_c = -40.0
    repeat = 5
    [[step]]
    hold_s = 3600            # soak
    [[step]]
    ramp_to_c = 85.0
    rate_c_per_h = 18.0      # heating at 18 °C/h (the MTEA temperature-drift paper, §3.1)
    [[step]]
    hold_s = 3600
    [[step]]
    ramp_to_c = -40.0
    rate_c_per_h = 18.0      # cooling

The ambient is piecewise linear between the corners.  Built-ins (``gyrosim/presets/chambers``):
``tde_cycles_003`` (the MTEA paper's −40→85 °C cycles at 18 °C/h, five times) and ``points_001``
(the FOG IMU calibration note's points −10, 5, 20, 30, 40 °C, each soaked); a user's profile is a TOML
path in the same format.  The sensor's own temperature follows the ambient through the sensor
model's :class:`~gyrosim.thermal.ThermalModel` (first-order case lag, self-heating).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ._presets import builtin_names, load_named_toml
from .errors import PresetError

if TYPE_CHECKING:  # annotations only
    from .recording import Recording
    from .thermal import ThermalModel

__all__ = ["ChamberProfile", "load_chamber", "chamber_preset_names", "sensor_temperature", "simulate_chamber"]

_KEYS = {"name", "description", "source", "start_c", "repeat", "step", "notes"}
_STEP_KEYS = {"hold_s", "ramp_to_c", "rate_c_per_h", "label"}


@dataclass(frozen=True)
class ChamberProfile:
    """Corners (t_s, ambient_c) of a piecewise-linear ambient, with a label per segment."""

    name: str
    times_s: np.ndarray
    ambient_c: np.ndarray
    labels: tuple[str, ...]          # one per segment: "hold", "heat", "cool" (or the step's label)
    cycle_starts_s: tuple[float, ...]
    description: str = ""
    source: str = ""

    @property
    def duration_s(self) -> float:
        return float(self.times_s[-1])

    def ambient(self, t_s: np.ndarray) -> np.ndarray:
        """Ambient temperature (°C) at times t_s (s); held at the ends."""
        return np.interp(np.asarray(t_s, float), self.times_s, self.ambient_c)

    def segments(self) -> list[tuple[float, float, str]]:
        """(start s, end s, label) of every hold and ramp."""
        return [(float(a), float(b), lab) for a, b, lab in zip(self.times_s[:-1], self.times_s[1:], self.labels)]

    def cycle_of(self, t_s: np.ndarray) -> np.ndarray:
        """Index of the repetition each time belongs to (0-based)."""
        return np.searchsorted(np.asarray(self.cycle_starts_s), np.asarray(t_s, float), side="right") - 1

    def holds(self, min_s: float = 0.0) -> list[tuple[float, float, float]]:
        """(start s, end s, ambient °C) of the holds (soaks) at least ``min_s`` long."""
        return [(a, b, float(self.ambient(a))) for a, b, lab in self.segments()
                if lab.startswith("hold") and b - a >= min_s]


def profile_from_dict(data: dict, name: str) -> ChamberProfile:
    bad = set(data) - _KEYS
    if bad:
        raise PresetError(f"chamber profile {name!r}: unknown key(s) {sorted(bad)}; allowed: {sorted(_KEYS)}")
    if "start_c" not in data or "step" not in data:
        raise PresetError(f"chamber profile {name!r} needs start_c and at least one [[step]]")
    repeat = int(data.get("repeat", 1))
    if repeat < 1:
        raise PresetError(f"chamber profile {name!r}: repeat must be ≥ 1")
    t, temp = [0.0], [float(data["start_c"])]
    labels: list[str] = []
    starts: list[float] = []
    for _ in range(repeat):
        starts.append(t[-1])
        for i, step in enumerate(data["step"]):
            sbad = set(step) - _STEP_KEYS
            if sbad:
                raise PresetError(f"chamber profile {name!r} step {i + 1}: unknown key(s) {sorted(sbad)}; "
                                  f"allowed: {sorted(_STEP_KEYS)}")
            if "hold_s" in step:
                dur, end, lab = float(step["hold_s"]), temp[-1], "hold"
            elif "ramp_to_c" in step:
                rate = float(step.get("rate_c_per_h", 0.0))
                if not rate > 0:
                    raise PresetError(f"chamber profile {name!r} step {i + 1}: a ramp needs rate_c_per_h > 0")
                end = float(step["ramp_to_c"])
                dur = abs(end - temp[-1]) / rate * 3600.0
                lab = "heat" if end > temp[-1] else "cool"
            else:
                raise PresetError(f"chamber profile {name!r} step {i + 1}: give hold_s or ramp_to_c (+ rate_c_per_h)")
            if not (math.isfinite(dur) and dur > 0):
                raise PresetError(f"chamber profile {name!r} step {i + 1}: duration must be > 0 s")
            t.append(t[-1] + dur)
            temp.append(end)
            labels.append(str(step.get("label", lab)))
    return ChamberProfile(name, np.array(t), np.array(temp), tuple(labels), tuple(starts),
                          str(data.get("description", "")), str(data.get("source", "")))


def chamber_preset_names() -> list[str]:
    """Names of the chamber profiles shipped in ``gyrosim/presets/chambers/*.toml``."""
    return builtin_names("presets", "chambers")


def load_chamber(name_or_path: str | Path) -> ChamberProfile:
    """A built-in chamber profile by name, or a TOML file in the format of the module docstring."""
    name, data = load_named_toml(("presets", "chambers"), name_or_path, "chamber profile", PresetError)
    return profile_from_dict(data, name)


def sensor_temperature(profile: ChamberProfile, thermal: "ThermalModel | None", t_s: np.ndarray,
                       grid_s: float = 1.0) -> np.ndarray:
    """Sensor temperature (°C) at times ``t_s`` (s, may have gaps) in the chamber: the thermal
    model's first-order lag run on a uniform ``grid_s`` grid over the whole profile (so the lag
    also acts while nothing is recorded), then interpolated."""
    from .thermal import ThermalModel

    thermal = thermal or ThermalModel()
    grid = np.arange(0.0, max(profile.duration_s, float(np.max(t_s))) + grid_s, grid_s)
    temp = thermal.temperature(grid, ambient=profile.ambient)
    return np.interp(np.asarray(t_s, float), grid, temp)


def simulate_chamber(profile: "ChamberProfile | str", sensor, rate_hz: float = 1.0, *,
                     seed: int | None = None, up_axis: str = "z") -> "Recording":
    """A board fixed in the chamber (static: true rate 0, specific force g₀ along ``up_axis``),
    sampled at ``rate_hz`` over the whole profile and corrupted by one device of ``sensor`` whose
    temperature follows the profile through its thermal model.  Nothing moves, so there is no
    dynamics to simulate: the truth is written down, not integrated.  ``meta['chamber']`` holds
    the profile's corners and cycle starts (s)."""
    from .recording import Recording, Truth
    from .sensor_model import SensorModel, load_sensor
    from .simulate import apply_sensor
    from .units import G0

    profile = load_chamber(profile) if isinstance(profile, (str, Path)) else profile
    model: SensorModel = load_sensor(sensor) if isinstance(sensor, (str, Path)) else sensor
    if up_axis not in ("x", "y", "z"):
        raise PresetError(f"up_axis must be x, y or z, got {up_axis!r}")
    t = np.arange(0.0, profile.duration_s, 1.0 / rate_hz)
    f = np.zeros((t.size, 3))
    f[:, "xyz".index(up_axis)] = G0
    quat = {"z": [1.0, 0, 0, 0], "x": [math.cos(math.pi / 4), 0, -math.sin(math.pi / 4), 0],
            "y": [math.cos(math.pi / 4), math.sin(math.pi / 4), 0, 0]}[up_axis]
    truth = Recording(
        t_s=t,
        gyro_rad_s=np.zeros((t.size, 3)),
        acc_m_s2=f,
        truth=Truth(
            omega_body_rad_s=np.zeros((t.size, 3)), specific_force_body_m_s2=f, quat_nb=np.tile(quat, (t.size, 1))
        ),
        meta={
            "rate_hz": rate_hz,
            "chamber": {
                "name": profile.name,
                "times_s": profile.times_s.tolist(),
                "ambient_c": profile.ambient_c.tolist(),
                "labels": list(profile.labels),
                "cycle_starts_s": list(profile.cycle_starts_s),
            },
            "schedule": f"static in chamber profile {profile.name}",
            "seed": -1 if seed is None else seed,
        },
    )
    temp = sensor_temperature(profile, model.thermal, t)
    return apply_sensor(truth, model, np.random.default_rng(seed), temperature_c=temp)
