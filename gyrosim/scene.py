"""The MuJoCo scene: the hand-held IMU model, how it is driven, and how truth is read from it.

Driving the hand (a free rigid body, ``models/handheld.xml``) — measured choices:

* three wrist hinges gimbal-lock at the "x vertical" pose of zhou2020, and an orientation servo on a
  ball joint is badly damped on two axes; a free body has neither problem;
* the hand receives, every physics step, the Newton–Euler wrench of its commanded motion
  (``xfrc_applied`` at the centre of mass, world frame):

      F = m a_c,    τ = R (I_b ω̇_b + ω_b × I_b ω_b),
      a_c = a_P + α × r + ω × (ω × r),   r = R (c_b − p_b)

  (P: rotation centre, p_b its body coordinates, c_b the centre of mass; gravity is carried by
  ``gravcomp``), plus a soft weld to a mocap target that pulls back any deviation (rounding, the
  intermediate-axis instability of a free rigid body).  A mocap body has zero velocity, so a plain
  weld's damping drags the hand (the ~20 ms lag of a pure weld); the target is therefore offset
  along the commanded velocity and acceleration (:meth:`HandScene.weld_offsets`), which makes the
  weld force-free on track.  Measured on zhou2020 (1 kHz): attitude within 5e-5° of the command,
  rate within 3e-6 rad/s RMS, for every imperfection.  All inputs are known
  in advance, so the whole session is one open-loop :func:`mujoco.rollout.rollout` call.

Sensor samples: after ``mj_step`` the sensor data describe the state *before* the step, so the
sensordata of step k is stamped t_k = k Δt (the time it describes).  Semi-implicit Euler keeps the
velocity half a step behind the pose (qvel_k ≈ v(t_k − Δt/2)); the true rate at t_k is therefore
½(ω_k + ω_{k+1}) (second order), which :func:`gyrosim.simulate.simulate_truth` records.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import mujoco
import numpy as np
from mujoco import rollout as mj_rollout

from .errors import ReachError
from .hand import HandMotion
from .rotations import (
    cross3,
    quat_from_rotvec,
    quat_from_two_vectors,
    quat_multiply,
    quat_rotate,
    quat_to_matrix,
)

__all__ = ["ArmPose", "HandScene", "default_model_path", "CONTROL_SPEC"]

CONTROL_SPEC = int(
    mujoco.mjtState.mjSTATE_XFRC_APPLIED
    | mujoco.mjtState.mjSTATE_MOCAP_POS
    | mujoco.mjtState.mjSTATE_MOCAP_QUAT
)
STATE_SPEC = int(mujoco.mjtState.mjSTATE_FULLPHYSICS)


def model_file(filename: str) -> Path:
    """Path of an MJCF model of ``models/``: the installed package copy, else the checkout's."""
    try:
        packaged = resources.files("gyrosim.models") / filename
        if packaged.is_file():
            return Path(str(packaged))
    except ModuleNotFoundError:
        pass
    checkout = Path(__file__).resolve().parents[1] / "models" / filename
    if checkout.is_file():
        return checkout
    raise FileNotFoundError(
        f"models/{filename} not found in the installed package nor next to the source tree; "
        "reinstall gyrosim (pip install .) or pass model_path"
    )


def default_model_path() -> Path:
    """Path of ``handheld.xml`` (:func:`model_file`)."""
    return model_file("handheld.xml")


@dataclass(frozen=True)
class ArmPose:
    """Arm posture from inverse kinematics, navigation frame (ENU), m and rad."""

    shoulder_m: np.ndarray
    elbow_m: np.ndarray
    wrist_m: np.ndarray
    elbow_flexion_rad: np.ndarray
    shoulder_elevation_rad: np.ndarray


def _block_view(rows: np.ndarray, columns: slice, shape: tuple[int, ...]) -> np.ndarray:
    """``rows[:, columns]`` seen as (n, *shape), writable into ``rows`` (never a copy)."""
    view = rows[:, columns].reshape(rows.shape[0], *shape)
    if not np.shares_memory(view, rows):
        raise RuntimeError("control block is not a view of the control rows")
    return view


class HandScene:
    """A loaded ``handheld.xml`` with the ids, inertia and arm geometry gyrosim needs."""

    def __init__(self, model_path: str | Path | None = None, timestep_s: float = 0.001) -> None:
        self.model_path = Path(model_path) if model_path else default_model_path()
        self.model = mujoco.MjModel.from_xml_path(str(self.model_path))
        self.model.opt.timestep = timestep_s
        # One free body and one weld: a single constraint island, so MuJoCo's per-step island
        # discovery only costs time (~15 % of a step); the solver then sees the same system and
        # the sensor data are bit-identical (tests/gyrosim/test_simulation_speed.py).
        self.model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_ISLAND)
        self.data = mujoco.MjData(self.model)
        m = self.model

        def numeric(name: str) -> np.ndarray:
            return np.array(m.numeric(name).data, dtype=float)

        self.hand_id = m.body("hand").id
        self.target_mocap = m.body("hand_target").mocapid[0]
        self.upper_mocap = m.body("upper_arm").mocapid[0]
        self.forearm_mocap = m.body("forearm").mocapid[0]
        self.hand_start_pos_m = m.body("hand").pos.copy()
        self.acc_site_body_m = m.site("imu_acc").pos.copy()
        self.gyro_site_body_m = m.site("imu_gyro").pos.copy()
        self.mag_site_body_m = m.site("imu_mag").pos.copy()
        self.mass_kg = float(m.body_mass[self.hand_id])
        self.com_body_m = m.body_ipos[self.hand_id].copy()
        r_i = quat_to_matrix(m.body_iquat[self.hand_id])
        self.inertia_body_kg_m2 = r_i @ np.diag(m.body_inertia[self.hand_id]) @ r_i.T
        self.shoulder_m = m.body("upper_arm").pos.copy()
        self.upper_length_m = float(numeric("arm_upper_length_m")[0])
        self.forearm_length_m = float(numeric("arm_forearm_length_m")[0])
        self.elbow_range_rad = np.radians(numeric("arm_elbow_flexion_range_deg"))
        self.shoulder_elevation_max_rad = math.radians(float(numeric("arm_shoulder_elevation_max_deg")[0]))
        self.wrist_body_m = numeric("hand_wrist_body_m")
        self.gravity_m_s2 = float(-m.opt.gravity[2])
        sensor = {m.sensor(i).name: (m.sensor_adr[i], m.sensor_dim[i]) for i in range(m.nsensor)}
        self.sensor_slices = {k: slice(a, a + d) for k, (a, d) in sensor.items()}
        self._control_layout()

    def set_earth_field(self, earth_enu_ut: np.ndarray) -> None:
        """MuJoCo's uniform field (``option/magnetic``, tesla, world = ENU) from µT."""
        self.model.opt.magnetic[:] = np.asarray(earth_enu_ut, dtype=float) * 1e-6

    @property
    def timestep_s(self) -> float:
        return float(self.model.opt.timestep)

    def _control_layout(self) -> None:
        """Find where xfrc_applied / mocap_pos / mocap_quat sit in a CONTROL_SPEC vector."""
        m = self.model
        self.ncontrol = mujoco.mj_stateSize(m, CONTROL_SPEC)
        probe = mujoco.MjData(m)
        probe.xfrc_applied[:] = 1.0
        probe.mocap_pos[:] = 2.0
        probe.mocap_quat[:] = 3.0
        vec = np.empty(self.ncontrol)
        mujoco.mj_getState(m, probe, vec, CONTROL_SPEC)
        n_x, n_p, n_q = m.nbody * 6, m.nmocap * 3, m.nmocap * 4
        expected = np.concatenate([np.full(n_x, 1.0), np.full(n_p, 2.0), np.full(n_q, 3.0)])
        if vec.shape != expected.shape or not np.array_equal(vec, expected):
            raise RuntimeError("unexpected MuJoCo control-state layout; gyrosim needs an update")
        self._xfrc = slice(0, n_x)
        self._mpos = slice(n_x, n_x + n_p)
        self._mquat = slice(n_x + n_p, n_x + n_p + n_q)

    # ------------------------------------------------------------------ kinematics
    def pivot_body_coords(self, motion: HandMotion) -> np.ndarray:
        """Rotation centre in hand-body coordinates (m): accelerometer site + pivot offset."""
        return self.acc_site_body_m + motion.pivot_body_m

    def pivot_start_m(self, initial_quat_nb: np.ndarray, pivot_offset_m: np.ndarray) -> np.ndarray:
        """Navigation-frame start point (m) of the rotation centre: the hand starts at the model's
        pose (board centre at ``hand`` body pos) with the schedule's initial attitude."""
        p_b = self.acc_site_body_m + np.asarray(pivot_offset_m, dtype=float)
        return self.hand_start_pos_m + quat_rotate(np.asarray(initial_quat_nb, dtype=float), p_b)

    def body_origin_m(self, motion: HandMotion, pivot_start_m: np.ndarray) -> np.ndarray:
        """Commanded navigation-frame position of the hand body origin (board centre), m."""
        p_b = self.pivot_body_coords(motion)
        return pivot_start_m + motion.pivot_m - quat_rotate(motion.quat_nb, p_b)

    def arm_pose(self, motion: HandMotion, pivot_start_m: np.ndarray) -> ArmPose:
        """Analytic two-link inverse kinematics of the arm for the commanded wrist path.

        Wrist w = o + R w_b; with d = |w − S|: elbow flexion = π − acos((L₁² + L₂² − d²)/(2 L₁ L₂));
        the elbow lies in the plane of (w − S) and a down-outward hint, at angle
        acos((L₁² + d² − L₂²)/(2 L₁ d)) from the shoulder–wrist line.  Raises :class:`ReachError`
        naming the joint, the time and the limit when the path leaves the arm's range.
        """
        origin = self.body_origin_m(motion, pivot_start_m)
        wrist = origin + quat_rotate(motion.quat_nb, self.wrist_body_m)
        s = self.shoulder_m
        l1, l2 = self.upper_length_m, self.forearm_length_m
        sw = wrist - s
        dist = np.linalg.norm(sw, axis=1)
        cos_int = (l1**2 + l2**2 - dist**2) / (2 * l1 * l2)
        t = motion.t_s
        if np.any(cos_int < -1.0):
            k = int(np.argmax(-cos_int))
            raise ReachError(
                f"the schedule moves the wrist {dist[k]:.3f} m from the shoulder at t = {t[k]:.3f} s, "
                f"beyond the arm's reach of {l1 + l2:.3f} m (elbow fully extended): shorten the "
                "translations or the hand's pivot offset"
            )
        flexion = math.pi - np.arccos(np.clip(cos_int, -1.0, 1.0))
        lo, hi = self.elbow_range_rad
        bad = (flexion < lo - 1e-9) | (flexion > hi + 1e-9)
        if np.any(bad):
            k = int(np.flatnonzero(bad)[0])
            raise ReachError(
                f"the schedule drives the elbow to {math.degrees(flexion[k]):.1f}° flexion at "
                f"t = {t[k]:.3f} s, outside its range {math.degrees(lo):.0f}–{math.degrees(hi):.0f}°: "
                "keep the hand farther from the shoulder"
            )
        u = sw / dist[:, None]
        hint = np.array([0.35, -0.15, -1.0])
        n = hint - (u @ hint)[:, None] * u
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        cos_b = np.clip((l1**2 + dist**2 - l2**2) / (2 * l1 * dist), -1.0, 1.0)
        upper_dir = cos_b[:, None] * u + np.sqrt(1 - cos_b**2)[:, None] * n
        elbow = s + l1 * upper_dir
        elevation = np.arccos(np.clip(-upper_dir[:, 2], -1.0, 1.0))
        if np.any(elevation > self.shoulder_elevation_max_rad):
            k = int(np.argmax(elevation))
            raise ReachError(
                f"the schedule raises the upper arm {math.degrees(elevation[k]):.1f}° from hanging at "
                f"t = {t[k]:.3f} s, beyond the shoulder's {math.degrees(self.shoulder_elevation_max_rad):.0f}°"
            )
        return ArmPose(np.broadcast_to(s, wrist.shape), elbow, wrist, flexion, elevation)

    # ------------------------------------------------------------------ controls
    def weld_offsets(self) -> tuple[float, float]:
        """Gains (c_v, c_a) of the weld-target offset that makes the weld force-free on track.

        MuJoCo's soft weld produces zero force exactly when the hand's unconstrained relative
        acceleration equals the reference a_ref = −B v − K·imp·r, where v, r are the hand's
        velocity and pose error relative to the mocap target (whose own velocity MuJoCo takes as
        zero).  On the commanded motion (velocity v, acceleration a) that requires
        r = −(a + B v)/(K·imp): the target is placed at the commanded pose shifted by
        c_v·v + c_a·a with c_v = B/(K·imp), c_a = 1/(K·imp).  Only deviations from the commanded
        motion are then pulled back; a plain weld would drag the hand by ~2 time constants.
        K, B, imp are read from ``efc_KBIP`` of the weld rows (constant impedance in the model).
        """
        m, d = self.model, mujoco.MjData(self.model)
        mujoco.mj_forward(m, d)
        kbip = np.asarray(d.efc_KBIP[: d.nefc])
        eq = np.asarray(d.efc_type[: d.nefc]) == mujoco.mjtConstraint.mjCNSTR_EQUALITY
        if not eq.any():
            return 0.0, 0.0
        k, b, imp = kbip[eq][0, 0], kbip[eq][0, 1], kbip[eq][0, 2]
        return float(b / (k * imp)), float(1.0 / (k * imp))

    def controls(self, motion: HandMotion, arm: ArmPose, pivot_start_m: np.ndarray) -> np.ndarray:
        """The (nstep, ncontrol) open-loop control rows for the steps of ``motion``.

        Row k is applied during step k (t_k → t_k + Δt).  MuJoCo's semi-implicit Euler keeps
        velocities half a step behind positions (v_k ≈ v(t_k − Δt/2)), and evaluates Coriolis and
        centripetal terms with v_k; the feedforward uses the same staggered rate
        ω_s = ω(t_k) − ½Δt ω̇(t_k) in its velocity-product terms, so the commanded motion is
        reproduced to second order and nothing drifts.
        """
        m = self.model
        n = motion.t_s.size
        quat = motion.quat_nb
        wd_b = motion.omega_dot_body_rad_s2
        w_b, v_origin = self._staggered_velocities(motion)
        w_n = quat_rotate(quat, w_b)
        a_n = quat_rotate(quat, wd_b)  # α_n = R ω̇_b  (d/dt(R ω_b) = R(ω_b×ω_b + ω̇_b))
        p_b = self.pivot_body_coords(motion)
        r_c = quat_rotate(quat, self.com_body_m - p_b)
        acc_com = motion.pivot_acceleration_m_s2 + cross3(a_n, r_c) + cross3(w_n, cross3(w_n, r_c))
        ib = self.inertia_body_kg_m2
        torque_b = wd_b @ ib.T + cross3(w_b, w_b @ ib.T)
        # the rows are written in place through views of ``ctrl`` (no per-block temporaries)
        ctrl = np.zeros((n, self.ncontrol))
        xfrc = _block_view(ctrl, self._xfrc, (m.nbody, 6))
        xfrc[:, self.hand_id, :3] = self.mass_kg * acc_com
        xfrc[:, self.hand_id, 3:] = quat_rotate(quat, torque_b)

        origin = self.body_origin_m(motion, pivot_start_m)
        r_o = -quat_rotate(quat, p_b)  # body origin relative to the pivot, world
        a_origin = motion.pivot_acceleration_m_s2 + cross3(a_n, r_o) + cross3(w_n, cross3(w_n, r_o))
        c_v, c_a = self.weld_offsets()
        mpos = _block_view(ctrl, self._mpos, (m.nmocap, 3))
        mquat = _block_view(ctrl, self._mquat, (m.nmocap, 4))
        mpos[:, self.target_mocap] = origin + c_v * v_origin + c_a * a_origin
        mquat[:, self.target_mocap] = quat_multiply(quat, quat_from_rotvec(c_v * w_b + c_a * wd_b))
        z = np.array([0.0, 0.0, 1.0])
        mpos[:, self.upper_mocap] = arm.shoulder_m
        mquat[:, self.upper_mocap] = quat_from_two_vectors(z, arm.elbow_m - arm.shoulder_m)
        mpos[:, self.forearm_mocap] = arm.elbow_m
        mquat[:, self.forearm_mocap] = quat_from_two_vectors(z, arm.wrist_m - arm.elbow_m)
        return ctrl

    def _staggered_velocities(self, motion: HandMotion) -> tuple[np.ndarray, np.ndarray]:
        """Body rate (body frame) and body-origin velocity (world) at t_k − Δt/2, as Euler holds them."""
        h = self.timestep_s
        w_b = motion.omega_body_rad_s - 0.5 * h * motion.omega_dot_body_rad_s2
        r_o = -quat_rotate(motion.quat_nb, self.pivot_body_coords(motion))
        v_pivot = motion.pivot_velocity_m_s - 0.5 * h * motion.pivot_acceleration_m_s2
        return w_b, v_pivot + cross3(quat_rotate(motion.quat_nb, w_b), r_o)

    def initial_state(self, motion: HandMotion, ctrl0: np.ndarray, pivot_start_m: np.ndarray) -> np.ndarray:
        """FULLPHYSICS state at the first step of ``motion`` (pose at t₀, velocities at t₀ − Δt/2)."""
        m, d = self.model, self.data
        first = motion.select(slice(0, 1))
        w_b, v_origin = self._staggered_velocities(first)
        mujoco.mj_resetData(m, d)
        d.qpos[:3] = self.body_origin_m(first, pivot_start_m)[0]
        d.qpos[3:7] = first.quat_nb[0]
        d.qvel[:3] = v_origin[0]  # free joint: linear velocity of the body origin, world frame
        d.qvel[3:6] = w_b[0]  # free joint: angular velocity, body frame
        mujoco.mj_setState(m, d, ctrl0, CONTROL_SPEC)
        mujoco.mj_forward(m, d)
        state0 = np.empty(mujoco.mj_stateSize(m, STATE_SPEC))
        mujoco.mj_getState(m, d, state0, STATE_SPEC)
        return state0

    def step_chunk(self, state: np.ndarray, ctrl: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Roll ``ctrl`` (nstep, ncontrol) out from ``state``; returns (final state, sensordata).

        Sensordata row k describes the state at the start of step k.  Runs in C without the GIL,
        so the next chunk's controls can be prepared meanwhile.
        """
        st, sd = mj_rollout.rollout(self.model, self.data, state[None], ctrl[None], control_spec=CONTROL_SPEC)
        return st[0, -1].copy(), sd[0]
