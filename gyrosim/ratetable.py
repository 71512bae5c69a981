"""Virtual rate table in a thermal chamber: the tri-axis ±rate / one-position scheme of "Measurement Error and
Calibration of FOG IMU".

``models/ratetable.xml`` is a single-axis table (velocity servo on a hinge about world z) carrying
a cube with six IMU sites, one per face (each IMU axis up and down).  At every calibration
temperature (each hold of a :class:`~gyrosim.chamber.ChamberProfile` at least ``settle_s +
sequence`` long), after ``settle_s`` of soak, the sequence per face is

    one position (table at rest, ``static_s``) → +Ω for ``turns`` full turns → −Ω for ``turns`` turns

(each turn segment also holds the spin-up and the stop).  MuJoCo steps the table once per
calibration temperature and the six faces are read from their own sites; the faces are laid out
one after another in time, as the operator flips the cube.  The logger records only the sequences,
so the time axis has gaps between temperature points (the sensor temperature still follows the
whole profile, :func:`gyrosim.chamber.sensor_temperature`).

``meta['segments']``: one entry per (temperature point, face, phase) with sample indices
[start, stop) of the *steady* part (after spin-up, before the stop), the face, the table rate
(rad/s, about world z, the table encoder's reading as a calibration uses it) and the hold's
ambient temperature.  Frames: IMU body frame of the face's site; navigation ENU.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from .chamber import ChamberProfile, load_chamber, sensor_temperature
from .errors import GyrosimError
from .recording import Recording, Truth
from .scene import model_file

__all__ = ["FACES", "ratetable_model_path", "simulate_rate_table", "RateTableSequence"]

FACES = ("xup", "xdown", "yup", "ydown", "zup", "zdown")


def ratetable_model_path() -> Path:
    """Path of ``ratetable.xml`` (installed package copy, else the checkout's ``models/``)."""
    return model_file("ratetable.xml")


@dataclass(frozen=True)
class RateTableSequence:
    """The per-face sequence: rate Ω (°/s), full turns per direction, dwell times (s)."""

    rate_deg_s: float = 30.0
    turns: float = 2.0
    static_s: float = 20.0
    spin_up_s: float = 2.0      # excluded from the steady window (servo settles in ~0.5 s)
    stop_s: float = 2.0
    settle_s: float = 3600.0    # soak before the sequence starts

    def __post_init__(self) -> None:
        if not (0 < self.rate_deg_s <= 500):
            raise GyrosimError("rate table: rate_deg_s must be in (0, 500] °/s")
        if self.turns < 1:
            raise GyrosimError("rate table: at least one full turn per direction (≥ 360°)")

    @property
    def turn_s(self) -> float:
        return self.turns * 360.0 / self.rate_deg_s

    @property
    def face_s(self) -> float:
        return self.static_s + 2 * (self.spin_up_s + self.turn_s + self.stop_s)


def _run_table(seq: RateTableSequence, rate_hz: float, physics_hz: float) -> tuple[np.ndarray, np.ndarray, list]:
    """One face-sequence of table motion: sensordata (n, nsensor) at the output rate, times, phases."""
    model = mujoco.MjModel.from_xml_path(str(ratetable_model_path()))
    model.opt.timestep = 1.0 / physics_hz
    data = mujoco.MjData(model)
    sub = int(round(physics_hz / rate_hz))
    if abs(sub * rate_hz - physics_hz) > 1e-9 * physics_hz:
        raise GyrosimError(f"rate table: the physics rate {physics_hz} Hz must be a multiple of the output rate "
                           f"{rate_hz} Hz")
    omega = math.radians(seq.rate_deg_s)
    phases = [("static", 0.0, seq.static_s),
              ("+rate", omega, seq.spin_up_s + seq.turn_s + seq.stop_s),
              ("-rate", -omega, seq.spin_up_s + seq.turn_s + seq.stop_s)]
    ctrl, marks, t0 = [], [], 0.0
    for name, w, dur in phases:
        n = int(round(dur * physics_hz))
        c = np.full(n, w)
        if w != 0.0:
            c[-int(round(seq.stop_s * physics_hz)):] = 0.0
            marks.append((name, w, t0 + seq.spin_up_s, t0 + seq.spin_up_s + seq.turn_s))
        else:
            marks.append((name, 0.0, t0 + 1.0, t0 + dur))   # 1 s for the previous stop to settle
        ctrl.append(c)
        t0 += dur
    ctrl = np.concatenate(ctrl)[:, None]
    state = np.zeros(mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS))
    mujoco.mj_getState(model, data, state, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    _, sens = mujoco.rollout.rollout(model, data, state[None], ctrl[None])
    sens = sens[0, sub - 1 :: sub]
    t = (np.arange(sens.shape[0]) + 1) * sub / physics_hz
    return sens, t, marks


def simulate_rate_table(profile: "ChamberProfile | str" = "points_001", sensor="consumer_thermal",
                        rate_hz: float = 100.0, *, seq: RateTableSequence | None = None, seed: int | None = None,
                        physics_hz: float = 500.0) -> Recording:
    """The ±rate / one-position sequence on all six faces at every long-enough hold of ``profile``,
    corrupted by one device of ``sensor`` (see the module docstring)."""
    from .sensor_model import SensorModel, load_sensor
    from .simulate import apply_sensor

    profile = load_chamber(profile) if isinstance(profile, (str, Path)) else profile
    model: SensorModel = load_sensor(sensor) if isinstance(sensor, (str, Path)) else sensor
    seq = seq or RateTableSequence()
    holds = profile.holds(min_s=seq.settle_s + 6 * seq.face_s)
    if not holds:
        raise GyrosimError(
            f"chamber profile {profile.name!r} has no hold of ≥ {seq.settle_s + 6 * seq.face_s:.0f} s "
            "(settle + six faces): lengthen the holds or shorten settle_s")
    sens, t_face, marks = _run_table(seq, rate_hz, physics_hz)
    m = mujoco.MjModel.from_xml_path(str(ratetable_model_path()))
    adr = {m.sensor(i).name: (m.sensor_adr[i], m.sensor_dim[i]) for i in range(m.nsensor)}
    table_rate = sens[:, adr["table_rate"][0]]
    ts, gyro, acc, rate_ref, segments = [], [], [], [], []
    n0 = 0
    for h, (a, _, amb) in enumerate(holds):
        for k, face in enumerate(FACES):
            start = a + seq.settle_s + k * seq.face_s
            g0, _ = adr[f"gyro_{face}"]
            a0, _ = adr[f"acc_{face}"]
            ts.append(start + t_face)
            gyro.append(sens[:, g0 : g0 + 3])
            acc.append(sens[:, a0 : a0 + 3])
            rate_ref.append(table_rate)
            for name, w, s0, s1 in marks:
                i0, i1 = np.searchsorted(t_face, [s0, s1])
                segments.append({"hold": h, "ambient_c": amb, "face": face, "phase": name, "start": n0 + int(i0),
                                 "stop": n0 + int(i1), "table_rate_rad_s": w})
            n0 += t_face.size
    t = np.concatenate(ts)
    w = np.concatenate(gyro)
    f = np.concatenate(acc)
    truth = Recording(
        t_s=t, gyro_rad_s=w, acc_m_s2=f,
        truth=Truth(omega_body_rad_s=w, specific_force_body_m_s2=f, extra={"table_rate": np.concatenate(rate_ref)}),
        meta={"rate_hz": rate_hz, "segments": segments, "schedule": f"rate table in chamber profile {profile.name}",
              "rate_table": {"rate_deg_s": seq.rate_deg_s, "turns": seq.turns, "static_s": seq.static_s,
                             "faces": list(FACES)},
              "seed": -1 if seed is None else seed})
    temp = sensor_temperature(profile, model.thermal, t)
    return apply_sensor(truth, model, np.random.default_rng(seed), temperature_c=temp)
