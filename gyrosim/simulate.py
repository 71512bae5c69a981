"""Simulate a hand-held calibration session: schedule + hand → MuJoCo → truth ``Recording``.

``simulate_truth`` returns a Recording whose ``gyro``/``acc`` equal the truth (the sensor error
model corrupts them afterwards).  Physics runs at ``physics_rate_hz`` (default 1 kHz); the output
is point-sampled every ``substeps`` physics steps at ``rate_hz``.  If ``physics_rate_hz`` is not a
multiple of ``rate_hz``, the physics step is shortened to 1 / (rate_hz · ⌈physics/rate⌉) so that
samples fall exactly on physics steps (noted in ``meta['physics_rate_hz']``).
"""

from __future__ import annotations

import json
import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Callable

import numpy as np

from . import __version__
from .errors import GyrosimError
from .hand import Hand, HandMotion, load_hand
from .magnetic import DEFAULT_EARTH_FIELD_ENU_UT, MagneticEnvironment
from .recording import FRAMES, Recording, Truth
from .rotations import quat_conjugate, quat_rotate
from .scene import ArmPose, HandScene
from .schedule import Schedule, load_schedule

if TYPE_CHECKING:
    from .effects import Effect, SignalContext
    from .sensor_model import SensorModel

__all__ = ["SimulationGrid", "simulation_grid", "simulate_truth", "simulate", "apply_sensor", "with_attached_magnet",
           "EARTH_FIELD_ENU_UT"]

# Default geomagnetic field at the simulated site (µT, ENU): 48° N, central Europe (WMM-class
# values: 20 µT north, 44 µT down); a session may set its own (gyrosim.magnetic).
EARTH_FIELD_ENU_UT = np.array(DEFAULT_EARTH_FIELD_ENU_UT)


@dataclass(frozen=True)
class SimulationGrid:
    """Time grids of a session: physics steps and output samples (s)."""

    rate_hz: float
    physics_rate_hz: float
    substeps: int
    n_samples: int

    @property
    def dt_physics_s(self) -> float:
        return 1.0 / self.physics_rate_hz

    @property
    def t_physics_s(self) -> np.ndarray:
        """Physics step times (s) up to the last sample (inclusive)."""
        return np.arange((self.n_samples - 1) * self.substeps + 1) * self.dt_physics_s

    @property
    def t_samples_s(self) -> np.ndarray:
        return np.arange(self.n_samples) * (self.substeps * self.dt_physics_s)


def simulation_grid(duration_s: float, rate_hz: float, physics_rate_hz: float = 1000.0) -> SimulationGrid:
    """Choose physics step and sample count; rejects a rate above the physics rate."""
    if not (math.isfinite(rate_hz) and rate_hz > 0):
        raise GyrosimError(f"rate must be a positive number of Hz, got {rate_hz}")
    if not (math.isfinite(physics_rate_hz) and physics_rate_hz > 0):
        raise GyrosimError(f"physics rate must be a positive number of Hz, got {physics_rate_hz}")
    if rate_hz > physics_rate_hz:
        raise GyrosimError(
            f"output rate {rate_hz:g} Hz is above the physics rate {physics_rate_hz:g} Hz: "
            "lower --rate or raise --physics-rate"
        )
    ratio = physics_rate_hz / rate_hz
    substeps = round(ratio)
    if abs(ratio - substeps) > 1e-9 * ratio:
        substeps = math.ceil(ratio)
        physics_rate_hz = rate_hz * substeps
    n = int(math.floor(duration_s * rate_hz + 1e-9)) + 1
    return SimulationGrid(rate_hz, physics_rate_hz, substeps, n)


def simulate_truth(
    schedule: Schedule | str,
    hand: Hand | str = "ideal",
    rate_hz: float = 100.0,
    *,
    seed: int | None = None,
    rng: np.random.Generator | None = None,
    physics_rate_hz: float = 1000.0,
    scene: HandScene | None = None,
    progress: Callable[[int], None] | None = None,
    chunk_steps: int = 20000,
    pipeline: bool = True,
    magnetic: MagneticEnvironment | None = None,
) -> Recording:
    """Simulate one session and return its truth Recording (``gyro``/``acc``/``mag`` = truth).

    Args:
        schedule: a :class:`Schedule` or a built-in name / TOML path.
        hand: a :class:`Hand` or a preset name / TOML path.
        rate_hz: output sample rate (Hz), ≤ physics rate.
        seed: seed for ``numpy.random.default_rng`` (ignored if ``rng`` is given).
        rng: the Generator every random draw comes from.
        physics_rate_hz: MuJoCo step rate (Hz).
        scene: a loaded :class:`HandScene` to reuse (its timestep is set here).
        progress: called with the number of physics steps done after each chunk.
        chunk_steps: physics steps per pipeline chunk (results do not depend on the progress
            callback, but do depend, at rounding level, on this value).
        pipeline: step MuJoCo in a second thread while the next chunk is prepared (one session on
            two cores); False runs everything in the calling thread with identical results, for
            callers that already keep every core busy with their own processes (campaigns).
        magnetic: the magnetic field (Earth field and anomalies, :mod:`gyrosim.magnetic`);
            default: :data:`EARTH_FIELD_ENU_UT`, no anomalies.  MuJoCo's ``imu_mag``
            magnetometer reads the Earth field in the board frame; the anomalies' fields are added
            at the magnetometer site's position.  ``/mag`` and ``/truth/mag_field`` hold the total
            (µT, body frame).
    """
    if isinstance(schedule, (str, Path)):
        schedule = load_schedule(schedule)
    if isinstance(hand, (str, Path)):
        hand = load_hand(hand)
    if rng is None:
        rng = np.random.default_rng(seed)
    grid = simulation_grid(schedule.duration_s, rate_hz, physics_rate_hz)
    magnetic = magnetic or MagneticEnvironment()
    scene = scene or HandScene()
    scene.model.opt.timestep = grid.dt_physics_s
    scene.set_earth_field(magnetic.earth_enu_ut)

    # one physics step beyond the last sample: the rate at t_k is ½(ω_k + ω_{k+1}) (scene docstring)
    t_phys = np.append(grid.t_physics_s, grid.t_physics_s[-1] + grid.dt_physics_s)
    n_steps = t_phys.size
    noise = hand.draw_noise(n_steps, grid.dt_physics_s, rng)
    pivot_start = scene.pivot_start_m(schedule.initial_quat_nb, hand.pivot_offset_m)
    rows = np.arange(grid.n_samples) * grid.substeps
    sens = np.empty((n_steps, scene.model.nsensordata))
    sampled: list[tuple[HandMotion, ArmPose]] = []

    # Pipeline: the main thread prepares chunk c+1 (motion, arm IK, controls: numpy) while one
    # worker thread steps chunk c in MuJoCo (C, GIL released).  Chunks run strictly in order on
    # that single worker, so the result is the same as a sequential run.
    state: list[np.ndarray] = []

    def run(a: int, ctrl: np.ndarray) -> None:
        final, sd = scene.step_chunk(state[-1], ctrl)
        sens[a : a + ctrl.shape[0]] = sd
        state.append(final)
        if progress is not None:
            progress(ctrl.shape[0])

    previous = None
    # a small first chunk lets MuJoCo start at once; the rest overlap with the main thread
    bounds = [0, min(n_steps, max(1, chunk_steps // 5))]
    while bounds[-1] < n_steps:
        bounds.append(min(n_steps, bounds[-1] + chunk_steps))
    with ThreadPoolExecutor(max_workers=1) if pipeline else _InlineExecutor() as pool:
        pending = []
        for a, b in zip(bounds[:-1], bounds[1:]):
            motion = hand.motion_chunk(schedule, t_phys[a:b], noise.rows(a, b), previous)
            previous = (motion.quat_nb[-1], motion.omega_body_rad_s[-1])
            arm = scene.arm_pose(motion, pivot_start)
            ctrl = scene.controls(motion, arm, pivot_start)
            if a == 0:
                state.append(scene.initial_state(motion, ctrl[0], pivot_start))
            pending.append(pool.submit(run, a, ctrl))
            keep = rows[(rows >= a) & (rows < b)] - a
            sampled.append((motion.select(keep), _pick_arm(arm, keep)))
        for fut in pending:
            fut.result()  # re-raise any MuJoCo error

    s = scene.sensor_slices
    omega = 0.5 * (sens[rows, s["imu_gyro"]] + sens[rows + 1, s["imu_gyro"]])
    f_b = sens[rows, s["imu_acc"]]
    quat = sens[rows, s["imu_quat"]]
    quat = quat * np.where(quat[:, :1] < 0, -1.0, 1.0)
    pos = sens[rows, s["imu_acc_pos"]]
    mag = sens[rows, s["imu_mag"]] * 1e6  # T → µT, board frame
    if magnetic.anomalies:
        mag_site = pos + quat_rotate(quat, scene.mag_site_body_m - scene.acc_site_body_m)
        mag = mag + quat_rotate(quat_conjugate(quat), magnetic.anomaly_nav_ut(mag_site))
    omega_schedule = np.concatenate([m.omega_schedule_body_rad_s for m, _ in sampled])
    segment_index = np.concatenate([m.segment_index for m, _ in sampled])
    wrist = np.concatenate([arm.wrist_m for _, arm in sampled])
    elbow = np.concatenate([arm.elbow_m for _, arm in sampled])
    g_up_body = quat_rotate(quat_conjugate(quat), np.array([0.0, 0.0, scene.gravity_m_s2]))
    truth = Truth(
        omega_body_rad_s=omega,
        specific_force_body_m_s2=f_b,
        quat_nb=quat,
        position_nav_m=pos,
        extra={
            "external_acc": f_b - g_up_body,
            "omega_schedule": omega_schedule,
            "segment_index": segment_index.astype(float),
            "wrist_position": wrist,
            "elbow_position": elbow,
            "mag_field": mag,
        },
    )
    meta = {
        "rate_hz": float(grid.rate_hz),
        "physics_rate_hz": float(grid.physics_rate_hz),
        "frames": FRAMES,
        "schedule": json.dumps(schedule.to_dict(), sort_keys=True),
        "hand": json.dumps(hand.to_dict(), sort_keys=True),
        "sensor_model": json.dumps({"gyro": [], "accelerometer": [], "note": "truth, no sensor errors"}),
        "seed": -1 if seed is None else int(seed),
        "version": __version__,
        "gravity_m_s2": scene.gravity_m_s2,
        "source": "gyrosim simulation (MuJoCo hand-held scene)",
        "model": scene.model_path.name,
        "magnetic_field": json.dumps(magnetic.to_dict(), sort_keys=True),
    }
    return Recording(
        t_s=grid.t_samples_s,
        gyro_rad_s=omega,
        acc_m_s2=f_b,
        mag_ut=mag,
        truth=truth,
        meta=meta,
    )


class _InlineExecutor:
    """The executor interface, running each job at submit time in the calling thread."""

    def __enter__(self) -> "_InlineExecutor":
        return self

    def __exit__(self, *exc) -> None:
        return None

    def submit(self, fn, *args):
        from concurrent.futures import Future

        fut: Future = Future()
        try:
            fut.set_result(fn(*args))
        except BaseException as err:  # noqa: BLE001 - re-raised by result(), as a thread pool would
            fut.set_exception(err)
        return fut


def _pick_arm(arm: ArmPose, idx: np.ndarray) -> ArmPose:
    return ArmPose(*(getattr(arm, f)[idx] for f in arm.__dataclass_fields__))


def signal_context(rec: Recording) -> "SignalContext":
    """The :class:`~gyrosim.effects.SignalContext` of a truth recording (magnetic field: the
    truth ``mag_field`` channel, else :data:`EARTH_FIELD_ENU_UT` rotated into the body frame)."""
    from .effects import SignalContext

    t = rec.truth
    if t is None or t.omega_body_rad_s is None or t.specific_force_body_m_s2 is None:
        raise GyrosimError("applying a sensor model needs a recording with truth omega and specific force")
    if "mag_field" in t.extra:
        mag = t.extra["mag_field"]
    else:
        mag = quat_rotate(quat_conjugate(t.quat_nb), EARTH_FIELD_ENU_UT) if t.quat_nb is not None else None
    return SignalContext(
        t_s=rec.t_s,
        omega_true_rad_s=t.omega_body_rad_s,
        specific_force_true_m_s2=t.specific_force_body_m_s2,
        temperature_c=rec.temp_c,
        quat_nb=t.quat_nb,
        mag_body_ut=mag,
    )


def apply_sensor(
    truth: Recording, sensor: "SensorModel | str", rng: np.random.Generator, *, realize: bool = True,
    temperature_c: np.ndarray | None = None,
) -> Recording:
    """Corrupt a truth recording with a sensor model; returns a new Recording (input untouched).

    Draws one device (``sensor.realize``) unless ``realize`` is False, computes the sensor
    temperature from the model's thermal model (power-on at the first sample; ``temperature_c``
    overrides it), and stores the
    device's exact model (drawn values, SI) as JSON in ``meta['sensor_model']``.
    Random streams: ``rng.spawn(2)`` → (device draw, measurement noise), then one more child for
    the magnetometer's noise, so a 9-axis model gives the same gyro and accelerometer as its
    6-axis part.  A model without magnetometer effects (a 6-axis IMU) leaves no ``/mag``; the
    true field stays in ``/truth/mag_field``.
    """
    from .sensor_model import load_sensor

    model: SensorModel = load_sensor(sensor) if isinstance(sensor, (str, Path)) else sensor
    device_rng, noise_rng = rng.spawn(2)
    device = model.realize(device_rng) if realize else model
    if temperature_c is not None:  # a scenario that computed the sensor temperature itself (chamber, rate table)
        temp = np.asarray(temperature_c, dtype=float)
    else:
        temp = device.thermal.temperature(truth.t_s) if device.thermal is not None else truth.temp_c
    with_temp = truth.with_signals(temp_c=temp)
    ctx = signal_context(with_temp)
    gyro, acc = device.apply(ctx, noise_rng)
    mag_rng = rng.spawn(1)[0]
    mag = device.apply_magnetometer(ctx, mag_rng) if device.has_magnetometer and ctx.mag_body_ut is not None else None
    meta = dict(truth.meta)
    meta["sensor_model"] = device.to_json()
    meta["sensor"] = device.name
    return with_temp.with_signals(gyro_rad_s=gyro, acc_m_s2=acc, mag_ut=mag, meta=meta)


def with_attached_magnet(sensor: "SensorModel", magnet: "Effect") -> "SensorModel":
    """``sensor`` with a magnet attached to the board part of the session: its magnetometer's effects
    and ``magnet`` (an :class:`gyrosim.effects.AttachedMagnet`) appended last, so the device's other
    draws and noise stay those of the sensor alone.  A sensor without a magnetometer is refused."""
    from dataclasses import replace

    if not sensor.has_magnetometer:
        raise GyrosimError(f"sensor {sensor.name!r} has no magnetometer: an attached magnet needs a 9-axis sensor "
                           "(e.g. --sensor mpu9250_9axis)")
    return replace(sensor, magnetometer=sensor.magnetometer + (magnet,))


def simulate(
    schedule: Schedule | str = "zhou2020",
    hand: Hand | str = "typical",
    sensor: "SensorModel | str | None" = None,
    rate_hz: float = 100.0,
    *,
    seed: int | None = None,
    physics_rate_hz: float = 1000.0,
    scene: HandScene | None = None,
    progress: Callable[[int], None] | None = None,
    pipeline: bool = True,
    magnetic: MagneticEnvironment | None = None,
) -> Recording:
    """Simulate a session and (if ``sensor`` is given) corrupt it with one drawn device.

    Seeding: ``default_rng(seed).spawn(2)`` → (hand motion, sensor), so the truth of a seed is
    the same with or without a sensor model.
    """
    hand_rng, sensor_rng = np.random.default_rng(seed).spawn(2)
    rec = simulate_truth(schedule, hand, rate_hz, rng=hand_rng, physics_rate_hz=physics_rate_hz,
                         scene=scene, progress=progress, pipeline=pipeline, magnetic=magnetic)
    rec = rec.with_signals(meta={**rec.meta, "seed": -1 if seed is None else int(seed)})
    if sensor is None:
        return rec
    return apply_sensor(rec, sensor, sensor_rng)
