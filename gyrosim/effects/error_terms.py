"""Error terms of the classic linear model and its extensions, δ computed from the true input x
(rate or specific force) and the other triad's truth (Zhou 2020 eq. 1–2):

    ω̃ = (I + S + N) ω + b + ε,   plus a general misalignment M, the gyro triad's rotation against the
    accelerometer's (−[α×]), a quadratic nonlinearity k x|x| and the gyro's g-sensitivity K f.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from ..errors import GyrosimError
from ..lazy import lazy_module
from ..rotations import skew
from ..units import G0, RAD2DEG
from .base import Effect, VectorEffect, _check_invertible, diagonal_jacobian, zeros_field

# heavy libraries the functions below call, imported on first use (gyrosim.lazy): not at start-up
kern = lazy_module("gyrosim._kernels")

__all__ = ["Bias", "ScaleFactor", "NonOrthogonality", "Misalignment", "GyroAccMisalignment", "ScaleNonlinearity",
           "GSensitivity", "nonortho_matrix"]


@dataclass(frozen=True)
class Bias(VectorEffect):
    """Constant bias: δ = b.  ``value_sigma`` draws a turn-on bias per run (b ~ N(value, σ²)).

    Units: rad/s (gyro) or m/s² (accelerometer).  Zhou 2020 eq. 1, §3.2.
    """

    kind: ClassVar[str] = "bias"
    display_units: ClassVar[dict[str, tuple[float, str]]] = {"gyro": (RAD2DEG, "°/s")}
    quantities: ClassVar[dict[str, str]] = {"gyro": "rate", "accelerometer": "acceleration"}
    pointwise: ClassVar[bool] = True
    labels: ClassVar[tuple[str, str]] = ("bias value", "bias sigma")

    def delta(self, x, ctx, rng=None):
        return np.broadcast_to(self.value, x.shape).copy()

    def add_delta(self, y, x, ctx, rng=None):
        y += self.value

    def affine(self):
        return np.zeros((3, 3)), self.value

    def sensitivity(self, x, ctx):
        return np.broadcast_to(np.eye(3), x.shape + (3,)).copy()


def nonortho_matrix(g: np.ndarray) -> np.ndarray:
    """N(G), the symmetric non-orthogonality matrix of ω̃ = (I + diag(S) + N(G)) ω + b (Zhou 2020 eq. 1):
    zero diagonal, N[0,1] = N[1,0] = Gz, N[0,2] = N[2,0] = Gy, N[1,2] = N[2,1] = Gx."""
    gx, gy, gz = g
    return np.array([[0.0, gz, gy], [gz, 0.0, gx], [gy, gx, 0.0]])


@dataclass(frozen=True)
class ScaleFactor(VectorEffect):
    """Scale-factor error: δ = S x, S = diag(Sx, Sy, Sz) (dimensionless).  Zhou 2020 eq. 2."""

    kind: ClassVar[str] = "scale_factor"
    display_units: ClassVar[dict[str, tuple[float, str]]] = {"gyro": (1e6, "ppm")}
    quantities: ClassVar[dict[str, str]] = {"gyro": "fraction", "accelerometer": "fraction"}
    pointwise: ClassVar[bool] = True
    labels: ClassVar[tuple[str, str]] = ("scale factor", "scale factor sigma")

    def delta(self, x, ctx, rng=None):
        return x * self.value

    def add_delta(self, y, x, ctx, rng=None):
        y += x * self.value

    def affine(self):
        return np.diag(self.value), np.zeros(3)

    def delta_dx(self, x, ctx):
        return np.broadcast_to(np.diag(self.value), x.shape + (3,))

    def sensitivity(self, x, ctx):
        return diagonal_jacobian(x)


@dataclass(frozen=True)
class NonOrthogonality(VectorEffect):
    """Non-orthogonality in the paper's symmetric form (Zhou 2020 eq. 2): δ = N x,

        N = [[0, Gz, Gy], [Gz, 0, Gx], [Gy, Gx, 0]]   (dimensionless, small-angle rad).

    ∂(N x)/∂Gx = (0, x_z, x_y), ∂/∂Gy = (x_z, 0, x_x), ∂/∂Gz = (x_y, x_x, 0).
    """

    kind: ClassVar[str] = "nonorthogonality"
    display_units: ClassVar[dict[str, tuple[float, str]]] = {"gyro": (1e3, "mrad")}
    quantities: ClassVar[dict[str, str]] = {"gyro": "fraction", "accelerometer": "fraction"}
    pointwise: ClassVar[bool] = True
    labels: ClassVar[tuple[str, str]] = ("non-orthogonality", "non-orthogonality sigma")

    def check(self) -> None:
        _check_invertible(np.eye(3) + nonortho_matrix(self.value), self.kind, self.value)

    def delta(self, x, ctx, rng=None):
        return x @ nonortho_matrix(self.value).T

    def affine(self):
        return nonortho_matrix(self.value), np.zeros(3)

    def delta_dx(self, x, ctx):
        return np.broadcast_to(nonortho_matrix(self.value), x.shape + (3,))

    def sensitivity(self, x, ctx):
        out = np.zeros(x.shape + (3,))
        out[:, 1, 0], out[:, 2, 0] = x[:, 2], x[:, 1]
        out[:, 0, 1], out[:, 2, 1] = x[:, 2], x[:, 0]
        out[:, 0, 2], out[:, 1, 2] = x[:, 1], x[:, 0]
        return out


_MISALIGN_IDX = ((0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1))


@dataclass(frozen=True)
class Misalignment(VectorEffect):
    """General 6-parameter misalignment/cross-coupling: δ = M x, M off-diagonal with
    value = [m_xy, m_xz, m_yx, m_yz, m_zx, m_zy] (row = sensing axis, column = input axis)."""

    kind: ClassVar[str] = "misalignment"
    display_units: ClassVar[dict[str, tuple[float, str]]] = {"gyro": (1e3, "mrad")}
    quantities: ClassVar[dict[str, str]] = {"gyro": "fraction", "accelerometer": "fraction"}
    pointwise: ClassVar[bool] = True
    labels: ClassVar[tuple[str, str]] = ("misalignment", "misalignment sigma")
    axis_rotation: ClassVar[bool] = True   # M general: its antisymmetric part is a rotation
    size: ClassVar[int] = 6
    value: np.ndarray = zeros_field(6)
    value_sigma: np.ndarray = zeros_field(6)

    def check(self) -> None:
        _check_invertible(np.eye(3) + self.matrix(), self.kind, self.value)

    def matrix(self) -> np.ndarray:
        m = np.zeros((3, 3))
        for k, (i, j) in enumerate(_MISALIGN_IDX):
            m[i, j] = self.value[k]
        return m

    def delta(self, x, ctx, rng=None):
        return x @ self.matrix().T

    def affine(self):
        return self.matrix(), np.zeros(3)

    def delta_dx(self, x, ctx):
        return np.broadcast_to(self.matrix(), x.shape + (3,))

    def sensitivity(self, x, ctx):
        out = np.zeros(x.shape + (6,))
        for k, (i, j) in enumerate(_MISALIGN_IDX):
            out[:, i, k] = x[:, j]
        return out


@dataclass(frozen=True)
class GyroAccMisalignment(VectorEffect):
    """The gyro triad rotated against the accelerometer triad by the small angles α = (α_x, α_y, α_z) (rad, about
    the body axes): δ = −[α×] ω = ω × α, so ω̃ = (I + diag(S) + N(G) − [α×]) ω + b.  Gyrosim's body frame is the
    accelerometer's (gravity fixes it, :mod:`calib.session.model`), so a gyro whose axes are turned by α reads a
    body rate ω in its own axes as R(α)ᵀ ω = ω − α × ω + O(α²): the antisymmetric part of the gyro's axis matrix,
    which the symmetric S, N(G) cannot hold (Kalibr's ``C_gyro_i``, imu_tk's gyro misalignment against its
    accelerometer, Tedaldi et al. 2014 eq. 3).  The term is linear in α on purpose: the rotation's second-order part,
    (R(α)ᵀ − I + [α×]) ≈ ½[α×]² (1.5e-4 at 1°), is symmetric and belongs to S and G, so S, G, α are together the
    nine parameters of a general matrix and nothing trades between them.  Gyro only; datasheets do not state it
    (a die's or a board's assembly: imu_tk's Xsens session 0.95°, imucal's NilsPod 0.3–0.7°)."""

    kind: ClassVar[str] = "gyro_acc_misalignment"
    display_units: ClassVar[dict[str, tuple[float, str]]] = {"gyro": (RAD2DEG, "°")}
    quantities: ClassVar[dict[str, str]] = {"gyro": "angle"}
    pointwise: ClassVar[bool] = True
    labels: ClassVar[tuple[str, str]] = ("gyro-to-accelerometer misalignment", "misalignment sigma")
    axis_rotation: ClassVar[bool] = True   # a rotation of the reference's body frame looks exactly like it

    max_rad: ClassVar[float] = 0.2   # ~11°: a linear small-angle term, and far beyond any assembly's error

    def check(self) -> None:
        if np.any(np.abs(self.value) > self.max_rad):
            raise GyrosimError(f"{self.kind} {np.round(self.value, 6).tolist()} rad exceeds {self.max_rad} rad per "
                               "axis: it is a small-angle term (a real one is below 2°); check units (° vs rad)")

    def matrix(self) -> np.ndarray:
        """−[α×], the term's share of the gyro's axis matrix."""
        return -skew(self.value)

    def delta(self, x, ctx, rng=None):
        return np.cross(x, self.value)

    def affine(self):
        return self.matrix(), np.zeros(3)

    def delta_dx(self, x, ctx):
        return np.broadcast_to(self.matrix(), x.shape + (3,))

    def sensitivity(self, x, ctx):
        """∂(ω × α)/∂α = [ω×] (N, 3, 3)."""
        out = np.zeros(x.shape + (3,))
        out[:, 0, 1], out[:, 0, 2] = -x[:, 2], x[:, 1]
        out[:, 1, 0], out[:, 1, 2] = x[:, 2], -x[:, 0]
        out[:, 2, 0], out[:, 2, 1] = -x[:, 1], x[:, 0]
        return out


@dataclass(frozen=True)
class ScaleNonlinearity(VectorEffect):
    """Quadratic scale nonlinearity per axis: δ_i = k_i x_i |x_i| (odd-symmetric, so it is a
    true nonlinearity and not a bias).  k in 1/(rad/s) or 1/(m/s²); a datasheet "nonlinearity
    ±p % of full scale R" gives k = p/100 / R (the error at full scale is p % of R)."""

    kind: ClassVar[str] = "scale_nonlinearity"
    display_units: ClassVar[dict[str, tuple[float, str]]] = {"gyro": (1.0, "1/(rad/s)")}
    quantities: ClassVar[dict[str, str]] = {"gyro": "per_rate", "accelerometer": "per_acceleration"}
    pointwise: ClassVar[bool] = True
    labels: ClassVar[tuple[str, str]] = ("nonlinearity", "nonlinearity sigma")

    def delta(self, x, ctx, rng=None):
        return self.value * x * np.abs(x)

    def add_delta(self, y, x, ctx, rng=None):
        kern.add_nonlinearity(y, x, self.value)

    def delta_dx(self, x, ctx):
        return diagonal_jacobian(2 * self.value * np.abs(x))

    def sensitivity(self, x, ctx):
        return diagonal_jacobian(x * np.abs(x))


@dataclass(frozen=True)
class ScaleAsymmetry(VectorEffect):
    """Scale factor that differs with the sign of the input: δ_i = a_i |x_i|, so axis i reads (1 + S_i + a_i) x_i
    for x_i > 0 and (1 + S_i − a_i) x_i for x_i < 0 (dimensionless, even in x: a turn and its return do not
    cancel).  Measured on imucal's Ferraris session: the NilsPod gyro's z axis carries gravity best at S_z ≈ −0.008
    turning +z and ≈ −0.001 turning −z (docs/real_imu.md), a ≈ −0.004.  The model loop's candidate
    (``calib closeloop``) regresses on |ω|; a Monte Carlo sensor may draw it like any vector effect."""

    kind: ClassVar[str] = "scale_asymmetry"
    display_units: ClassVar[dict[str, tuple[float, str]]] = {"gyro": (1e6, "ppm")}
    quantities: ClassVar[dict[str, str]] = {"gyro": "fraction", "accelerometer": "fraction"}
    pointwise: ClassVar[bool] = True
    labels: ClassVar[tuple[str, str]] = ("scale asymmetry", "scale asymmetry sigma")

    def delta(self, x, ctx, rng=None):
        return self.value * np.abs(x)

    def delta_dx(self, x, ctx):
        return diagonal_jacobian(self.value * np.sign(x))

    def sensitivity(self, x, ctx):
        return diagonal_jacobian(np.abs(x))


@dataclass(frozen=True)
class GSensitivity(Effect):
    """Gyro sensitivity to specific force: δ = K f, K 3×3 in (rad/s)/(m/s²) (gyro only)."""

    kind: ClassVar[str] = "g_sensitivity"
    display_units: ClassVar[dict[str, tuple[float, str]]] = {"gyro": (RAD2DEG * G0, "°/s/g")}
    quantities: ClassVar[dict[str, str]] = {"gyro": "rate_per_acceleration"}
    pointwise: ClassVar[bool] = True
    param_fields: ClassVar[tuple[str, ...]] = ("value",)
    value: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    value_sigma: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))

    def __post_init__(self) -> None:
        for name in ("value", "value_sigma"):
            v = np.array(getattr(self, name), dtype=float)
            v = np.diag(v) if v.shape == (3,) else v.reshape(3, 3)
            if not np.all(np.isfinite(v)):
                raise GyrosimError("g-sensitivity has NaN/inf values")
            object.__setattr__(self, name, v)

    def delta(self, x, ctx, rng=None):
        return ctx.specific_force_true_m_s2 @ self.value.T

    def add_delta(self, y, x, ctx, rng=None):
        kern.add_matvec(y, np.ascontiguousarray(ctx.specific_force_true_m_s2), self.value)

    def sensitivity(self, x, ctx):
        f = ctx.specific_force_true_m_s2
        out = np.zeros(x.shape + (9,))
        for i in range(3):
            out[:, i, 3 * i : 3 * i + 3] = f
        return out
