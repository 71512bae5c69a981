"""Static test of a tilt sensor on a dividing head ("Static Capacitance Test of MEMS
Tilt Sensor", after JJF 1427-2013): the board tilted in steps and held still, one sweep per
sensitive axis, the 0°/180° two-point positions, and a long level hold for the zero stability.

The dividing head's axis is horizontal.  In sweep ``y`` the board turns about its x axis by +θ,
so its y axis reads g sin θ; in sweep ``x`` it turns about its y axis by −θ, so its x axis reads
g sin θ (the sign makes the input of the swept axis +g sin θ in both).  Each sweep runs through
the angles (default the test's ±15° range: −15, −12.5, …, +15°), then to 180° (the board upside
down about the head's axis: the test's two-point method for the mechanical zero) and back to
level; after both sweeps the board stays level for ``zero_hold_s`` (zero stability, the test's: 1 h).

Nothing needs dynamics (:mod:`gyrosim.rig`): the holds are written down and the moves between
them are raised-cosine turns of ``move_s`` (``flip_move_s`` for the 180° turns) about the head's
axis, which passes through the sensor.  ``meta['tilttable']['holds']``: per hold its sweep (x, y
or zero), kind (step, flip, zero), commanded angle (°, the dividing head's reading), and sample
range [start, stop).  Frames: body RFU, navigation ENU; the board faces North when level.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import GyrosimError
from .recording import Recording
from .rig import Knock, apply_knocks, static_truth, turn_profile
from .rotations import quat_from_rotvec
from .sensor_model import SensorModel, load_sensor

__all__ = ["TiltSequence", "SWEEP_AXIS", "simulate_tilt_truth", "simulate_tilttable"]

SEED_001_ANGLES_DEG = tuple(np.round(np.arange(-15.0, 15.0 + 1e-9, 2.5), 6).tolist())
# sweep (the sensitive axis) → (body axis turned about, sign of the turn so that input = +g sin θ)
SWEEP_AXIS = {"y": (np.array([1.0, 0.0, 0.0]), 1.0), "x": (np.array([0.0, 1.0, 0.0]), -1.0)}


@dataclass(frozen=True)
class TiltSequence:
    """The dividing-head programme (module docstring)."""

    angles_deg: tuple[float, ...] = SEED_001_ANGLES_DEG
    sweeps: tuple[str, ...] = ("x", "y")
    hold_s: float = 30.0
    move_s: float = 4.0
    flip: bool = True
    flip_move_s: float = 10.0
    zero_hold_s: float = 3600.0     # the tilt-sensor test: the zero stability over 1 h

    def __post_init__(self) -> None:
        if len(self.angles_deg) < 3 or any(not -90 <= a <= 90 for a in self.angles_deg):
            raise GyrosimError("tilt table: at least three angles, each within ±90°")
        if sorted(self.angles_deg) != list(self.angles_deg) or len(set(self.angles_deg)) != len(self.angles_deg):
            raise GyrosimError("tilt table: the angles must be strictly increasing (the head steps one way)")
        if self.flip and 0.0 not in self.angles_deg:
            raise GyrosimError("tilt table: the 0°/180° two-point method needs 0° among the angles (or flip = false)")
        if set(self.sweeps) - set(SWEEP_AXIS) or not self.sweeps:
            raise GyrosimError(f"tilt table: sweeps must be among {sorted(SWEEP_AXIS)}")
        if not (self.hold_s > 0 and self.move_s > 0 and self.flip_move_s > 0 and self.zero_hold_s >= 0):
            raise GyrosimError("tilt table: hold_s, move_s, flip_move_s > 0 and zero_hold_s ≥ 0")


def _programme(seq: TiltSequence) -> list[tuple]:
    """[("hold", sweep, kind, angle, seconds) | ("move", sweep, from, to, seconds)]."""
    prog: list[tuple] = []
    for sweep in seq.sweeps:
        angle = 0.0
        points = [("step", a) for a in seq.angles_deg] + ([("flip", 180.0)] if seq.flip else [])
        for kind, target in points:
            if target != angle:
                prog.append(("move", sweep, angle, target, seq.flip_move_s if kind == "flip" else seq.move_s))
            prog.append(("hold", sweep, kind, target, seq.hold_s))
            angle = target
        if angle != 0.0:
            prog.append(("move", sweep, angle, 0.0, seq.flip_move_s if angle == 180.0 else seq.move_s))
    if seq.zero_hold_s > 0:
        prog.append(("hold", seq.sweeps[-1], "zero", 0.0, seq.zero_hold_s))
    return prog


def simulate_tilt_truth(rate_hz: float = 10.0, *, seq: TiltSequence | None = None,
                        knocks: tuple[Knock, ...] = ()) -> Recording:
    """The truth of the tilt-table programme (acc = gravity in the body frame, gyro = the turns)."""
    seq = seq or TiltSequence()
    if not rate_hz > 0:
        raise GyrosimError("tilt table: rate must be > 0 Hz")
    angle, rate, axis_of, holds, info = [], [], [], [], []
    n0 = 0
    for step in _programme(seq):
        if step[0] == "hold":
            _, sweep, kind, a, dur = step
            n = int(round(dur * rate_hz))
            if n < 2:
                raise GyrosimError(f"tilt table: a {dur} s hold at {rate_hz} Hz has fewer than 2 samples")
            angle.append(np.full(n, math.radians(a)))
            rate.append(np.zeros(n))
            holds.append((n0, n0 + n))
            info.append({"sweep": "zero" if kind == "zero" else sweep, "kind": kind, "angle_deg": float(a),
                         "start": n0, "stop": n0 + n})
        else:
            _, sweep, a0, a1, dur = step
            n = int(round(dur * rate_hz))
            th, w = turn_profile(math.radians(a1 - a0), dur, (np.arange(n) + 1) / rate_hz)
            angle.append(math.radians(a0) + th)
            rate.append(w)
        axis_of += [sweep] * n
        n0 += n
    theta = np.concatenate(angle)
    omega_s = np.concatenate(rate)
    ax = np.array([SWEEP_AXIS[s][0] * SWEEP_AXIS[s][1] for s in axis_of])
    quat = quat_from_rotvec(theta[:, None] * ax)
    omega = omega_s[:, None] * ax
    t = np.arange(theta.size) / rate_hz
    apply_knocks(quat, omega, t, holds, tuple(knocks))
    meta = {"rate_hz": float(rate_hz), "source": "gyrosim tilt-table scenario (dividing head, kinematic)",
            "schedule": f"tilt table, sweeps {','.join(seq.sweeps)} over {seq.angles_deg[0]:g}…{seq.angles_deg[-1]:g}°",
            "tilttable": {"angles_deg": list(seq.angles_deg), "sweeps": list(seq.sweeps), "hold_s": seq.hold_s,
                          "zero_hold_s": seq.zero_hold_s, "flip": seq.flip, "knocks": [k.__dict__ for k in knocks],
                          "holds": info}}
    truth = static_truth(quat, omega)
    return Recording(t_s=t, gyro_rad_s=truth.omega_body_rad_s, acc_m_s2=truth.specific_force_body_m_s2,
                     truth=truth, meta=meta)


def simulate_tilttable(sensor: "SensorModel | str | Path" = "tilt_001", rate_hz: float = 10.0, *,
                       seq: TiltSequence | None = None, knocks: tuple[Knock, ...] = (), seed: int | None = None,
                       truth: Recording | None = None) -> Recording:
    """A tilt-table record of one device of ``sensor``; ``truth`` (a :func:`simulate_tilt_truth`
    result) is reused when given, for many devices on one programme."""
    from .simulate import apply_sensor

    model = load_sensor(sensor) if isinstance(sensor, (str, Path)) else sensor
    truth = truth if truth is not None else simulate_tilt_truth(rate_hz, seq=seq, knocks=knocks)
    rec = apply_sensor(truth, model, np.random.default_rng(seed))
    return rec.with_signals(meta={**rec.meta, "seed": -1 if seed is None else int(seed)})
