"""The simulator's speed-ups change no bit of its output.

Each optimisation (compiled prefix product, in-place quaternion product, control rows written in
place, MuJoCo's island discovery off, segment slices in the schedule's kinematics) claims the same
floating-point operations in the same order as the code it replaced, so the check is exact
equality (``np.array_equal``), not a tolerance: any reordering of a sum would show up at the last
bit on these long, rotating records.
"""

from __future__ import annotations

import mujoco
import numpy as np

from gyrosim.rotations import quat_cumulative_product, quat_from_rotvec, quat_multiply, quat_normalize
from gyrosim.scene import HandScene
from gyrosim.schedule import schedule_from_dict
from gyrosim.simulate import simulate_truth


def _stack_multiply(p, q):
    """The former quat_multiply (np.stack of the four components)."""
    pw, px, py, pz = np.moveaxis(p, -1, 0)
    qw, qx, qy, qz = np.moveaxis(q, -1, 0)
    return np.stack([pw * qw - px * qx - py * qy - pz * qz, pw * qx + px * qw + py * qz - pz * qy,
                     pw * qy - px * qz + py * qw + pz * qx, pw * qz + px * qy - py * qx + pz * qw], axis=-1)


def _numpy_prefix(steps):
    """The former quat_cumulative_product: whole-array Hillis–Steele passes."""
    out = np.array(steps, dtype=float, copy=True)
    shift = 1
    while shift < out.shape[0]:
        out[shift:] = _stack_multiply(out[:-shift], out[shift:])
        shift *= 2
    return out / np.linalg.norm(out, axis=-1, keepdims=True)


def test_quaternion_kernels_are_bit_identical_to_numpy():
    rng = np.random.default_rng(11)
    for shape in [(1, 4), (2, 4), (7, 4), (1000, 4), (513, 2, 4)]:
        steps = quat_from_rotvec(rng.normal(scale=0.05, size=shape[:-1] + (3,)))
        assert np.array_equal(quat_cumulative_product(steps), _numpy_prefix(steps)), shape
    p = quat_normalize(rng.normal(size=(50, 4)))
    q = quat_normalize(rng.normal(size=(50, 4)))
    assert np.array_equal(quat_multiply(p, q), _stack_multiply(p, q))
    assert np.array_equal(quat_multiply(p[:1], q), _stack_multiply(p[:1], q))      # broadcasting
    assert np.array_equal(quat_multiply(p[3], q[4]), _stack_multiply(p[3], q[4]))  # single quaternions


SHORT = schedule_from_dict({"name": "short", "segments": [
    {"kind": "rest", "duration_s": 0.5},
    {"kind": "rotate", "axis": "x", "angle_deg": 90.0, "duration_s": 1.0},
    {"kind": "rotate", "axis": "y", "angle_deg": -120.0, "duration_s": 1.0},
    {"kind": "rest", "duration_s": 0.5}]})


def test_island_discovery_off_leaves_the_simulation_bit_identical():
    """One free body and one weld form one island: MuJoCo's island path and the global path solve
    the same system; the shaky hand (tremor, wobble, pivot) exercises the weld's constraint force."""
    fast = simulate_truth(SHORT, "shaky", 100.0, seed=3, chunk_steps=700, pipeline=False)
    scene = HandScene()
    scene.model.opt.disableflags &= ~int(mujoco.mjtDisableBit.mjDSBL_ISLAND)
    ref = simulate_truth(SHORT, "shaky", 100.0, seed=3, chunk_steps=700, pipeline=False, scene=scene)
    for a, b in [(fast.gyro_rad_s, ref.gyro_rad_s), (fast.acc_m_s2, ref.acc_m_s2), (fast.mag_ut, ref.mag_ut),
                 (fast.truth.quat_nb, ref.truth.quat_nb), (fast.truth.position_nav_m, ref.truth.position_nav_m)]:
        assert np.array_equal(a, b)


def test_schedule_kinematics_same_for_ordered_and_shuffled_times():
    """Ordered times take the per-segment slices, shuffled ones the masks: same values."""
    t = np.linspace(0.0, 3.0, 3001)
    perm = np.random.default_rng(2).permutation(t.size)
    a, b = SHORT.kinematics(t), SHORT.kinematics(t[perm])
    for f in ("omega_body_rad_s", "omega_dot_body_rad_s2", "quat_nb", "translation_m", "segment_index"):
        assert np.array_equal(getattr(a, f)[perm], getattr(b, f)), f
