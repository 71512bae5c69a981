"""The accelerometer from a protocol's six static poses on a box's faces (Ferraris et al. 1995, as imucal uses it).

A Ferraris session rests the device on each face of its box in turn: the x axis up (``x_p``), down (``x_a``), then
y and z.  The faces are at right angles, so the six mean readings say more than |f| = g does: with the columns
U₊, U₋ the poses' mean readings (body x, y, z up; down), the bias is the diagonal of (U₊ + U₋)/2 (each axis from
the pair that turned it up and down) and the matrix

    A = (U₊ − U₋) / (2 g)        (raw reading − bias = A e for gravity along the box's axis e)

holds the accelerometer's scale factor, non-orthogonality *and* how the box sits on the sensor's axes.  Our model
is symmetric, f̃ = (I + diag(S) + N(G)) f + b with f in the accelerometer's own frame, so A is split A = P U (polar
decomposition): P = I + diag(S) + N(G), U the box's rotation against the accelerometer (reported, not applied).

Why it matters (imucal's own Ferraris session): the rests' |f| = g sees N(G) only to second order when every pose
is near a body axis, and a shear in the x–z plane changes the angle the accelerometer sees over a quarter turn
about y by 2 G_y — the same as a scale-factor error of the gyro's y axis of 2 G_y / (π/2).  Left to the hand-held
motion, the joint filter put G_y at 0.013 ± 0.0007 (the six poses: 0.003) and S_y 0.022 from imucal's; the
faces' right angles fix G_y.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np
from scipy.linalg import polar

from calib.inputs.errors import TurnsError

__all__ = ["SixPoses", "six_pose_accelerometer", "POSES", "protocol_accelerometer"]

# the section list's names of the six poses (imucal's): the body axis up (p) and down (a)
POSES = (("x_p", "x_a"), ("y_p", "y_a"), ("z_p", "z_a"))


@dataclass(frozen=True)
class SixPoses:
    """The accelerometer of six box-face poses (module docstring): bias (m/s²), scale factor and non-orthogonality
    (G_x, G_y, G_z: N(G)'s [1,2], [0,2], [0,1]; fractions) in the accelerometer's frame; the box's rotation
    against it (° about x, y, z, small angles of U); the gravity the poses were scaled to (m/s²)."""

    bias_m_s2: np.ndarray
    scale_factor: np.ndarray
    nonorthogonality: np.ndarray
    box_rotation_deg: np.ndarray
    gravity_m_s2: float

    def theta(self) -> np.ndarray:
        """[b_a, S_a, G_a] (9,), the accelerometer's parameters in :func:`calib.session.gravityfit.compensate_acc`'s
        order."""
        return np.concatenate([self.bias_m_s2, self.scale_factor, self.nonorthogonality])

    def to_dict(self) -> dict[str, Any]:
        return {"bias_m_s2": self.bias_m_s2.tolist(), "scale_factor": self.scale_factor.tolist(),
                "nonorthogonality": self.nonorthogonality.tolist(), "box_rotation_deg": self.box_rotation_deg.tolist(),
                "gravity_m_s2": self.gravity_m_s2}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "SixPoses":
        return cls(*(np.asarray(d[k], float) for k in ("bias_m_s2", "scale_factor", "nonorthogonality",
                                                        "box_rotation_deg")), float(d["gravity_m_s2"]))


def six_pose_accelerometer(acc_m_s2: np.ndarray, segments: Mapping[str, Any], gravity_m_s2: float) -> SixPoses:
    """The accelerometer of the six poses in ``segments`` (a Ferraris section list: ``x_p``, ``x_a``, … with sample
    ``start``, ``end``) over the readings ``acc_m_s2`` (N, 3, m/s²), scaled to ``gravity_m_s2`` (module docstring).
    :class:`~calib.inputs.errors.TurnsError` names a missing pose or a stretch outside the recording."""
    acc = np.asarray(acc_m_s2, float)
    means = {}
    for name in (n for pair in POSES for n in pair):
        seg = segments.get(name)
        if not isinstance(seg, Mapping) or "start" not in seg or "end" not in seg:
            raise TurnsError(f"the section list has no pose {name!r} with 'start' and 'end' (a Ferraris session's "
                             "six poses: x_p, x_a, y_p, y_a, z_p, z_a)")
        i0, i1 = int(seg["start"]), int(seg["end"])
        if not 0 <= i0 < i1 <= acc.shape[0]:
            raise TurnsError(f"pose {name} spans samples {i0}–{i1}, outside the recording's {acc.shape[0]} samples")
        means[name] = acc[i0:i1].mean(axis=0)
    return _from_means(means, gravity_m_s2)


def _from_means(means: Mapping[str, np.ndarray], gravity_m_s2: float) -> SixPoses:
    """:class:`SixPoses` of the six poses' mean readings (label → (3,), m/s²)."""
    up = np.column_stack([means[p] for p, _ in POSES])
    down = np.column_stack([means[a] for _, a in POSES])
    # the bias: each axis from the pair that turned it up and down (imucal's, Ferraris's), where gravity's share on
    # that axis cancels whatever the poses' tilt; the other pairs' means carry their tilt (on imucal's session the
    # three-pair mean put |f| − g at rest 0.025 m/s² against this one's 0.018)
    bias = np.diag(0.5 * (up + down)).copy()
    u, p = polar((up - down) / (2.0 * gravity_m_s2), side="left")   # A = P U (scipy returns U first)
    rot = 0.5 * (u - u.T)                            # U ≈ I + [φ×] for small φ
    return SixPoses(bias, np.diag(p) - 1.0, np.array([p[1, 2], p[0, 2], p[0, 1]]),
                    np.degrees([rot[2, 1], rot[0, 2], rot[1, 0]]), float(gravity_m_s2))


def protocol_accelerometer(acc_m_s2: np.ndarray, t_s: np.ndarray, poses, gravity_m_s2: float,
                           block_s: float = 0.1) -> tuple[SixPoses, np.ndarray]:
    """The accelerometer of a protocol's six poses given on the clock ``t_s`` (``poses``: label, start_s, end_s, as
    :attr:`calib.inputs.turns.Turns.poses`) and its 1σ (9,): the noise of each pose's mean reading (the scatter of
    its ``block_s`` means over √their number, so correlation within a block is counted) carried through the six-pose
    equations to first order (a central difference per reading).  It is the noise's σ only: how square the box's
    faces are is what the method assumes."""
    acc, t = np.asarray(acc_m_s2, float), np.asarray(t_s, float)
    means, se = {}, {}
    rate = (t.size - 1) / (t[-1] - t[0])
    for label, t0, t1 in poses:
        i0, i1 = np.searchsorted(t, [t0, t1])
        x = acc[i0:i1]
        n = max(1, int(round(block_s * rate)))
        blocks = x[: (x.shape[0] // n) * n].reshape(-1, n, 3).mean(axis=1)
        if blocks.shape[0] < 2:
            raise TurnsError(f"pose {label} holds too few samples ({x.shape[0]}) to measure the accelerometer")
        means[label] = x.mean(axis=0)
        se[label] = blocks.std(axis=0, ddof=1) / np.sqrt(blocks.shape[0])
    result = _from_means(means, gravity_m_s2)
    var = np.zeros(9)
    for label in means:
        for k in range(3):
            h = max(float(se[label][k]), 1e-9)
            plus, minus = dict(means), dict(means)
            plus[label] = means[label] + h * np.eye(3)[k]
            minus[label] = means[label] - h * np.eye(3)[k]
            var += ((_from_means(plus, gravity_m_s2).theta() - _from_means(minus, gravity_m_s2).theta()) / 2.0) ** 2
    return result, np.sqrt(var)
