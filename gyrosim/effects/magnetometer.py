"""Magnetometer error terms (µT, like the ``Recording``): hard iron, soft iron and the triad's
rotation against the IMU frame, m = A R(θ)ᵀ B + h (Ozyagcilar, Freescale AN4246 eq. 8), and a
magnet attached to the board part of the time (a hard iron, and the soft iron of the parts it
magnetises, that switch on and off).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import ClassVar

import numpy as np

from ..errors import GyrosimError
from ..units import RAD2DEG
from .base import Effect, _check_invertible, _matrix, _vec
from .error_terms import Bias

__all__ = ["HardIron", "SoftIron", "FrameRotation", "AttachedMagnet", "rotation_matrix"]


@dataclass(frozen=True)
class HardIron(Bias):
    """Hard iron: a field fixed in the body frame, δ = h (µT) — the magnetised parts of the board
    and the sensor's own zero-field offset, which the magnetometer cannot tell apart (both turn
    with the board).  ``value_sigma`` draws it per device.  Magnetometer only.

    Model m = A B + h (Ozyagcilar, "Calibrating an eCompass in the Presence of Hard- and Soft-Iron
    Interference", Freescale AN4246, eq. 8): h is this effect, A the :class:`SoftIron` matrix.
    """

    kind: ClassVar[str] = "hard_iron"
    display_units: ClassVar[dict[str, tuple[float, str]]] = {"magnetometer": (1.0, "µT")}
    quantities: ClassVar[dict[str, str]] = {"magnetometer": "magnetic_field"}


@dataclass(frozen=True)
class SoftIron(Effect):
    """Soft iron (and the sensor's scale and cross-axis errors): m = A B + h, so δ = (A − I) B
    with A 3×3 dimensionless (AN4246 eq. 8; soft iron = field induced in the board's
    ferromagnetic parts, proportional to the applied field, so it turns with the board but its
    effect depends on the attitude).  Induced magnetisation is a symmetric tensor: with
    ``symmetric`` True a device draw (``matrix_sigma``) mirrors the upper triangle, and the
    sensor's rotation against the IMU frame is the separate :class:`FrameRotation`.
    Magnetometer only.
    """

    kind: ClassVar[str] = "soft_iron"
    quantities: ClassVar[dict[str, str]] = {"magnetometer": "fraction"}
    pointwise: ClassVar[bool] = True
    param_fields: ClassVar[tuple[str, ...]] = ("matrix",)
    matrix: np.ndarray = field(default_factory=lambda: np.eye(3))
    matrix_sigma: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    symmetric: bool = True

    def __post_init__(self) -> None:
        object.__setattr__(self, "matrix", _matrix(self.matrix, "soft_iron matrix"))
        object.__setattr__(self, "matrix_sigma", _matrix(self.matrix_sigma, "soft_iron matrix_sigma"))
        _check_invertible(self.matrix, self.kind, self.matrix)

    def realize(self, rng):
        if not np.any(self.matrix_sigma):
            return self
        draw = self.matrix_sigma * rng.standard_normal((3, 3))
        if self.symmetric:
            draw = np.triu(draw) + np.triu(draw, 1).T
        return replace(self, matrix=self.matrix + draw, matrix_sigma=np.zeros((3, 3)))

    def delta(self, x, ctx, rng=None):
        return x @ (self.matrix - np.eye(3)).T

    def affine(self):
        return self.matrix - np.eye(3), np.zeros(3)

    def delta_dx(self, x, ctx):
        return np.broadcast_to(self.matrix - np.eye(3), x.shape + (3,))

    def sensitivity(self, x, ctx):
        out = np.zeros(x.shape + (9,))
        for i in range(3):
            out[:, i, 3 * i : 3 * i + 3] = x  # ∂(A x)_i/∂A_ij = x_j
        return out


def rotation_matrix(rotvec: np.ndarray) -> np.ndarray:
    """R = exp([θ]×) of a rotation vector θ (rad), Rodrigues' formula."""
    th = np.asarray(rotvec, dtype=float)
    a = float(np.linalg.norm(th))
    k = np.array([[0.0, -th[2], th[1]], [th[2], 0.0, -th[0]], [-th[1], th[0], 0.0]])
    if a < 1e-12:
        return np.eye(3) + k
    return np.eye(3) + math.sin(a) / a * k + (1 - math.cos(a)) / a**2 * (k @ k)


@dataclass(frozen=True)
class FrameRotation(Effect):
    """The triad's axes rotated against the IMU (body) frame by the rotation vector θ (rad): a
    body-frame vector x has the sensor coordinates R(θ)ᵀ x, so δ = (R(θ)ᵀ − I) x with R from
    Rodrigues' formula.  The magnetometer-to-IMU misalignment (a separate die, or a separate chip
    on the board): an ellipsoid fit cannot see it (it keeps |B|), a fit that knows the attitude
    can.  Magnetometer only.
    """

    kind: ClassVar[str] = "frame_rotation"
    axis_rotation: ClassVar[bool] = True
    display_units: ClassVar[dict[str, tuple[float, str]]] = {"magnetometer": (RAD2DEG, "°")}
    quantities: ClassVar[dict[str, str]] = {"magnetometer": "angle"}
    pointwise: ClassVar[bool] = True
    param_fields: ClassVar[tuple[str, ...]] = ("angles",)
    angles: np.ndarray = field(default_factory=lambda: np.zeros(3))
    angles_sigma: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self) -> None:
        object.__setattr__(self, "angles", _vec(self.angles, name="frame_rotation angles"))
        object.__setattr__(self, "angles_sigma", _vec(self.angles_sigma, name="frame_rotation angles sigma"))

    def matrix(self) -> np.ndarray:
        """The sensor-from-body matrix R(θ)ᵀ."""
        return rotation_matrix(self.angles).T

    def delta(self, x, ctx, rng=None):
        return x @ (self.matrix() - np.eye(3)).T

    def affine(self):
        return self.matrix() - np.eye(3), np.zeros(3)

    def delta_dx(self, x, ctx):
        return np.broadcast_to(self.matrix() - np.eye(3), x.shape + (3,))


@dataclass(frozen=True)
class AttachedMagnet(Effect):
    """A magnet attached to the board from ``t_on_s`` until ``t_off_s`` (s; None: to the end): while it
    is there, δ = h_m + S_m x — a field fixed in the body frame, ``value`` h_m (µT), which is what
    a hard iron is, and the soft iron ``soft_iron`` S_m (dimensionless, added to A − I) of the board's
    parts it magnetises.  It turns with the board, unlike a magnet in the room
    (:class:`gyrosim.magnetic.Dipole`), whose field depends on where the board is.  ``value_sigma``
    draws h_m per device.  Magnetometer only.

    A dipole of moment μ at distance r from the sensor adds |h_m| ≈ μ₀/4π · 2μ/r³ (on its axis,
    Jackson eq. 5.56): a small neodymium disc (μ ≈ 0.02 A·m²) reads ~14 µT at 3 cm, ~380 µT at 1 cm.
    """

    kind: ClassVar[str] = "attached_magnet"
    display_units: ClassVar[dict[str, tuple[float, str]]] = {"magnetometer": (1.0, "µT")}
    quantities: ClassVar[dict[str, str]] = {"magnetometer": "magnetic_field"}
    pointwise: ClassVar[bool] = True
    param_fields: ClassVar[tuple[str, ...]] = ("value", "soft_iron")
    value: np.ndarray = field(default_factory=lambda: np.zeros(3))
    value_sigma: np.ndarray = field(default_factory=lambda: np.zeros(3))
    soft_iron: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    t_on_s: float = 0.0
    t_off_s: float | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "value", _vec(self.value, name="attached_magnet value"))
        object.__setattr__(self, "value_sigma", _vec(self.value_sigma, name="attached_magnet value sigma"))
        object.__setattr__(self, "soft_iron", _matrix(self.soft_iron, "attached_magnet soft_iron"))
        _check_invertible(np.eye(3) + self.soft_iron, self.kind, self.soft_iron)
        if not math.isfinite(float(self.t_on_s)):
            raise GyrosimError(f"attached_magnet t_on_s {self.t_on_s!r}: a finite time in s")
        object.__setattr__(self, "t_on_s", float(self.t_on_s))
        if self.t_off_s is not None:
            if not (math.isfinite(float(self.t_off_s)) and float(self.t_off_s) > self.t_on_s):
                raise GyrosimError(f"attached_magnet t_off_s {self.t_off_s!r}: a time in s after t_on_s "
                                   f"{self.t_on_s:g} (or none: the magnet stays)")
            object.__setattr__(self, "t_off_s", float(self.t_off_s))

    def attached(self, t_s: np.ndarray) -> np.ndarray:
        """Where the magnet is on the board: t_on_s ≤ t < t_off_s (bool per sample)."""
        t = np.asarray(t_s, dtype=float)
        return (t >= self.t_on_s) & (t < (math.inf if self.t_off_s is None else self.t_off_s))

    def delta(self, x, ctx, rng=None):
        on = self.attached(ctx.t_s)[:, None]
        return on * (self.value + x @ self.soft_iron.T)

    def delta_dx(self, x, ctx):
        return self.attached(ctx.t_s)[:, None, None] * np.broadcast_to(self.soft_iron, x.shape + (3,))

    def affine_at(self, t_s: float) -> tuple[np.ndarray, np.ndarray]:
        """(A part, constant part) of δ = A x + c at the time ``t_s`` (s): the magnet's while it is on
        the board, zeros otherwise (its :meth:`affine` is None: δ changes with time)."""
        on = bool(self.attached(np.array([t_s]))[0])
        return (self.soft_iron.copy(), self.value.copy()) if on else (np.zeros((3, 3)), np.zeros(3))
