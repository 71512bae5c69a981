"""Kinematic fixtures for static instrument tests: a board held still at a sequence of attitudes,
turned between them smoothly, and optionally knocked during a hold.

A board clamped to a fixture and held still has zero rate relative to the navigation frame
(ENU) and measures gravity only, f_b = C_nbᵀ (0, 0, g) — so the truth of a hold is written down,
as :mod:`gyrosim.chamber` does; the Earth's rotation is added by the sensor model's
``earth_rate`` effect from the attitude.  The board sits on the turning axis, so a turn adds no
lever-arm acceleration.

Profiles (t from the start of the motion, duration T):

* turn by A (raised-cosine rate, starts and ends at rest):
      ω(t) = (A/T)(1 − cos 2πt/T),       θ(t) = (A/T)(t − (T/2π) sin 2πt/T);
* knock of amplitude a (out and back, e.g. a bump on the tripod or the dividing head):
      β(t) = (a/2)(1 − cos 2πt/T),        β̇(t) = (π a/T) sin 2πt/T.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import GyrosimError
from .recording import Truth
from .rotations import quat_conjugate, quat_from_rotvec, quat_multiply, quat_rotate
from .units import G0

__all__ = ["Knock", "turn_profile", "knock_profile", "axis_vector", "static_truth", "apply_knocks"]

_AXES = {"x": 0, "y": 1, "z": 2}


@dataclass(frozen=True)
class Knock:
    """A knock during hold ``hold`` (0-based): the board tilts by ``amplitude_deg`` about body
    ``axis`` and comes back over ``duration_s``, starting ``at`` (fraction of the hold)."""

    hold: int
    amplitude_deg: float = 0.5
    axis: str = "x"
    duration_s: float = 2.0
    at: float = 0.5

    def __post_init__(self) -> None:
        if self.axis not in _AXES:
            raise GyrosimError(f"knock axis must be x, y or z, got {self.axis!r}")
        if not (self.duration_s > 0 and 0.0 <= self.at < 1.0 and math.isfinite(self.amplitude_deg)):
            raise GyrosimError("knock: duration_s > 0, 0 ≤ at < 1 and a finite amplitude_deg")


def axis_vector(axis: str) -> np.ndarray:
    """The unit vector (3,) of the body axis ``x``, ``y`` or ``z`` (Right, Forward, Up)."""
    v = np.zeros(3)
    v[_AXES[axis]] = 1.0
    return v


def turn_profile(angle_rad: float, duration_s: float, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(θ(t) rad, ω(t) rad/s) of a raised-cosine turn by ``angle_rad`` over ``duration_s``."""
    t = np.clip(np.asarray(t_s, float), 0.0, duration_s)
    w = 2 * math.pi / duration_s
    theta = angle_rad / duration_s * (t - np.sin(w * t) / w)
    rate = angle_rad / duration_s * (1 - np.cos(w * t))
    return theta, rate


def knock_profile(amplitude_rad: float, duration_s: float, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(β(t) rad, β̇(t) rad/s) of an out-and-back knock; zero outside [0, duration_s]."""
    t = np.asarray(t_s, float)
    inside = (t >= 0) & (t <= duration_s)
    w = 2 * math.pi / duration_s
    beta = np.where(inside, 0.5 * amplitude_rad * (1 - np.cos(w * t)), 0.0)
    rate = np.where(inside, 0.5 * amplitude_rad * w * np.sin(w * t), 0.0)
    return beta, rate


def apply_knocks(quat_nb: np.ndarray, omega_b: np.ndarray, t_s: np.ndarray, holds: list[tuple[int, int]],
                 knocks: tuple[Knock, ...]) -> None:
    """Add ``knocks`` to the attitude (body → ENU) and body rate in place; ``holds`` are the
    sample ranges [start, stop) of the holds.  The board is at rest in a hold, so the knock's
    rotation composes on the body side: q ← q ⊗ Exp(β a), ω_b ← ω_b + β̇ a."""
    for k in knocks:
        if not 0 <= k.hold < len(holds):
            raise GyrosimError(f"knock in hold {k.hold}: the sequence has holds 0…{len(holds) - 1}")
        a, b = holds[k.hold]
        t0 = t_s[a] + k.at * (t_s[b - 1] - t_s[a])
        if t0 + k.duration_s > t_s[b - 1]:
            raise GyrosimError(f"knock in hold {k.hold} lasts past the end of the hold: start it earlier or shorten it")
        idx = np.arange(a, b)
        beta, rate = knock_profile(math.radians(k.amplitude_deg), k.duration_s, t_s[idx] - t0)
        ax = axis_vector(k.axis)
        quat_nb[idx] = quat_multiply(quat_nb[idx], quat_from_rotvec(beta[:, None] * ax))
        omega_b[idx] += rate[:, None] * ax


def static_truth(quat_nb: np.ndarray, omega_b: np.ndarray, gravity_m_s2: float = G0,
                 extra: dict[str, np.ndarray] | None = None) -> Truth:
    """Truth of a board on a fixture turning about axes through the sensor: rate ω_b (rad/s,
    body RFU, relative to ENU), specific force f_b = C_nbᵀ (0, 0, g) (m/s², body)."""
    f_b = quat_rotate(quat_conjugate(quat_nb), np.array([0.0, 0.0, gravity_m_s2]))
    return Truth(omega_body_rad_s=omega_b, specific_force_body_m_s2=f_b, quat_nb=quat_nb, extra=extra or {})
