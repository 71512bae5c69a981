"""Gyrocompassing scenario: a board on the virtual indexing table at a latitude, held still in
P positions (two-position 0°/180°, four-position 0/90/180/270°, …), turned between them.

The IMU sits on site ``face_zup`` of ``models/ratetable.xml`` (body z along the table axis).  The
table turns clockwise seen from above by 360°/P between holds, so the heading of the body's
forward axis (y) increases by 360°/P each time; MuJoCo steps one index move (velocity servo:
command −Ω for (360°/P)/Ω, then 0 while it settles) and its encoder (``table_angle``) gives the
angle actually reached, which every later position inherits (the table indexes the same way
each time).  The holds are written down (:mod:`gyrosim.rig`: nothing moves).  A table whose axis
is tilted by δ from the vertical (a tripod not quite level) turns the whole picture by δ.

The Earth's rotation enters through the gyro's ``earth_rate`` effect: :func:`with_latitude`
sets the site's latitude on it, or appends one to a preset without it (a MEMS preset ignores
15 °/h only because it cannot see it — the Earth turns anyway).

Frames: ENU navigation; body RFU; heading ψ = azimuth of the body's forward axis (y) projected
on the horizontal plane, clockwise from true North.  ``meta['northfind']``: latitude, the
sequence, and one entry per hold with its sample range, the encoder angle (what the operator
reads off the table) and, under ``truth_heading_deg``, the true heading (for scoring only).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import mujoco
import numpy as np

from .effects import EarthRate, MagneticSensitivity
from .errors import GyrosimError
from .ratetable import ratetable_model_path
from .recording import Recording
from .rig import Knock, apply_knocks, static_truth
from .rotations import quat_from_rotvec, quat_from_two_vectors, quat_multiply, quat_rotate
from .sensor_model import SensorModel, load_sensor

__all__ = [
    "NorthFindSequence",
    "with_latitude",
    "shielded",
    "simulate_northfind_truth",
    "simulate_northfind",
    "true_heading_deg",
]


@dataclass(frozen=True)
class NorthFindSequence:
    """P equally spaced positions held ``hold_s`` each; index moves at ``index_rate_deg_s``,
    then ``settle_s`` for the servo to stop before the next hold."""

    positions: int = 4
    hold_s: float = 300.0
    index_rate_deg_s: float = 20.0
    settle_s: float = 3.0

    def __post_init__(self) -> None:
        if self.positions < 1:
            raise GyrosimError("north-finding: at least one position")
        if not self.hold_s > 0:
            raise GyrosimError("north-finding: hold_s must be > 0 s")
        if not 0 < self.index_rate_deg_s <= 500:
            raise GyrosimError("north-finding: index_rate_deg_s must be in (0, 500] °/s")

    @property
    def index_deg(self) -> float:
        return 360.0 / self.positions


def with_latitude(model: SensorModel, latitude_deg: float) -> SensorModel:
    """The sensor model with its gyro's Earth-rate effect at ``latitude_deg`` (replaced, or appended
    when the preset has none)."""
    if not abs(latitude_deg) <= 90.0:
        raise GyrosimError(f"latitude {latitude_deg}° is outside ±90°")
    er = EarthRate(latitude_rad=math.radians(latitude_deg))
    gyro = tuple(er if isinstance(e, EarthRate) else e for e in model.gyro)
    if not any(isinstance(e, EarthRate) for e in model.gyro):
        gyro = (er,) + gyro
    return replace(model, gyro=gyro)


def shielded(model: SensorModel, factor: float) -> SensorModel:
    """The sensor model with its gyro's magnetic sensitivity divided by ``factor`` (a µ-metal shield: "Magnetic
    Sensitivity of FOG IMU" gives 1e4 °/(h·T) for an unshielded FOG coil, 1–10 for a shielded POS-grade one, i.e.
    factors 1e3–1e4)."""
    if not factor >= 1:
        raise GyrosimError(f"magnetic shielding factor must be ≥ 1, got {factor}")
    return replace(model, gyro=tuple(replace(e, value=e.value / factor) if isinstance(e, MagneticSensitivity) else e
                                     for e in model.gyro))


def _index_move(seq: NorthFindSequence, rate_hz: float, physics_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """One index move of the MuJoCo table from rest: (angle rad, rate rad/s) at the output rate,
    from the encoder, starting one sample after the move is commanded."""
    model = mujoco.MjModel.from_xml_path(str(ratetable_model_path()))
    model.opt.timestep = 1.0 / physics_hz
    data = mujoco.MjData(model)
    sub = int(round(physics_hz / rate_hz))
    if sub < 1 or abs(sub * rate_hz - physics_hz) > 1e-9 * physics_hz:
        raise GyrosimError(f"north-finding: the physics rate {physics_hz} Hz must be a multiple of the output rate "
                           f"{rate_hz} Hz")
    omega = math.radians(seq.index_rate_deg_s)
    n_turn = int(round(math.radians(seq.index_deg) / omega * physics_hz))
    n_settle = int(round(seq.settle_s * physics_hz))
    n = n_turn + n_settle
    n += (-n) % sub
    ctrl = np.zeros((n, 1))
    ctrl[:n_turn] = -omega                       # clockwise seen from above: the heading increases
    state = np.zeros(mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS))
    mujoco.mj_getState(model, data, state, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    _, sens = mujoco.rollout.rollout(model, data, state[None], ctrl[None])
    sens = sens[0, sub - 1 :: sub]
    adr = {model.sensor(i).name: model.sensor_adr[i] for i in range(model.nsensor)}
    angle, rate = sens[:, adr["table_angle"]], sens[:, adr["table_rate"]]
    if abs(rate[-1]) > 1e-6:
        raise GyrosimError(f"north-finding: the table still turns at {rate[-1]:.2e} rad/s after settle_s = "
                           f"{seq.settle_s} s; lengthen settle_s")
    return angle, rate


def true_heading_deg(quat_nb: np.ndarray) -> np.ndarray:
    """Azimuth (°, [0, 360)) of the body's forward axis projected on the horizontal, clockwise from North."""
    f = quat_rotate(quat_nb, np.array([0.0, 1.0, 0.0]))
    return np.degrees(np.arctan2(f[..., 0], f[..., 1])) % 360.0


def simulate_northfind_truth(latitude_deg: float, heading_deg: float = 30.0, rate_hz: float = 100.0, *,
                             seq: NorthFindSequence | None = None, tilt_deg: float = 0.0,
                             tilt_azimuth_deg: float = 0.0, knocks: tuple[Knock, ...] = (),
                             physics_hz: float = 500.0) -> Recording:
    """The truth of a north-finding sequence (gyro/acc = truth; :func:`simulate_northfind`
    corrupts it).  One truth serves any number of sensor seeds."""
    seq = seq or NorthFindSequence()
    if not abs(latitude_deg) <= 90.0:
        raise GyrosimError(f"latitude {latitude_deg}° is outside ±90°")
    if not 0.0 <= tilt_deg < 10.0:
        raise GyrosimError("north-finding: the table tilt must be in [0, 10)°: level the tripod first")
    n_hold = int(round(seq.hold_s * rate_hz))
    if n_hold < 2:
        raise GyrosimError(f"north-finding: a {seq.hold_s} s hold at {rate_hz} Hz has fewer than 2 samples")
    move_angle, move_rate = _index_move(seq, rate_hz, physics_hz) if seq.positions > 1 else (np.zeros(0), np.zeros(0))
    step = float(move_angle[-1]) if move_angle.size else 0.0
    angle, rate, holds = [], [], []
    n0 = 0
    for k in range(seq.positions):
        angle.append(np.full(n_hold, k * step))
        rate.append(np.zeros(n_hold))
        holds.append((n0, n0 + n_hold))
        n0 += n_hold
        if k < seq.positions - 1:
            angle.append(k * step + move_angle)
            rate.append(move_rate)
            n0 += move_angle.size
    theta = np.concatenate(angle)
    n = theta.size
    t = np.arange(n) / rate_hz
    tilt = math.radians(tilt_deg)
    az = math.radians(tilt_azimuth_deg)
    axis_n = np.array([math.sin(tilt) * math.sin(az), math.sin(tilt) * math.cos(az), math.cos(tilt)])
    q_tilt = quat_from_two_vectors(np.array([0.0, 0.0, 1.0]), axis_n)
    q_head = quat_from_rotvec(np.array([0.0, 0.0, -math.radians(heading_deg)]))   # forward at azimuth ψ₀
    q_table = quat_from_rotvec(theta[:, None] * np.array([0.0, 0.0, 1.0]))
    quat = quat_multiply(quat_multiply(q_tilt, q_head)[None], q_table)
    omega = np.zeros((n, 3))
    omega[:, 2] = np.concatenate(rate)
    apply_knocks(quat, omega, t, holds, tuple(knocks))
    heads = [float(true_heading_deg(quat[a])) for a, _ in holds]
    meta = {
        "rate_hz": float(rate_hz), "source": "gyrosim north-finding scenario (rate-table model)",
        "schedule": f"north-finding, {seq.positions} position(s) × {seq.hold_s:g} s", "model": "ratetable.xml",
        "northfind": {
            "latitude_deg": float(latitude_deg), "positions": seq.positions, "hold_s": seq.hold_s,
            "index_rate_deg_s": seq.index_rate_deg_s, "settle_s": seq.settle_s, "tilt_deg": tilt_deg,
            "tilt_azimuth_deg": tilt_azimuth_deg, "knocks": [k.__dict__ for k in knocks],
            "holds": [{"start": a, "stop": b, "table_angle_deg": float(math.degrees(theta[a])),
                       "truth_heading_deg": h} for (a, b), h in zip(holds, heads)],
        },
    }
    truth = static_truth(quat, omega, extra={"table_angle": theta})
    return Recording(t_s=t, gyro_rad_s=truth.omega_body_rad_s, acc_m_s2=truth.specific_force_body_m_s2,
                     truth=truth, meta=meta)


def simulate_northfind(sensor: "SensorModel | str | Path", latitude_deg: float, heading_deg: float = 30.0,
                       rate_hz: float = 100.0, *, seq: NorthFindSequence | None = None, seed: int | None = None,
                       truth: Recording | None = None, **truth_kw) -> Recording:
    """A north-finding recording of one device of ``sensor`` (its Earth rate set to the latitude).
    ``truth``: a :func:`simulate_northfind_truth` result to reuse (then the geometry arguments are
    ignored)."""
    from .simulate import apply_sensor

    model = load_sensor(sensor) if isinstance(sensor, (str, Path)) else sensor
    if truth is None:
        truth = simulate_northfind_truth(latitude_deg, heading_deg, rate_hz, seq=seq, **truth_kw)
    lat = float(truth.meta["northfind"]["latitude_deg"])
    rec = apply_sensor(truth, with_latitude(model, lat), np.random.default_rng(seed))
    return rec.with_signals(meta={**rec.meta, "seed": -1 if seed is None else int(seed)})
