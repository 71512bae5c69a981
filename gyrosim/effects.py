"""One vocabulary of sensor error effects: simulated by gyrosim, estimated by calib.

An :class:`Effect` is a named, parameterised term of a triad's measurement model.  Two stages:

* **error** effects add a term computed from the *true* input x (rate or specific force) and
  the context (the other triad's truth, temperature, attitude, magnetic field, time):

      y = x + Σ_i δ_i(x, ctx; θ_i)                          (Zhou 2020 eq. 1 for the first four)

  so their order does not matter and the classic linear model ω̃ = (I + S + N) ω + b + ε is the
  sum of the ``scale_factor``, ``nonorthogonality``, ``bias`` and ``white_noise`` terms;
* **output** effects then transform the sensor's output in order (bandwidth, latency, jitter,
  quantization, saturation): y ← T_j(y).

Every effect knows (a) how to corrupt (:meth:`Effect.delta` / :meth:`Effect.transform`), (b) how
the output depends on x (``delta_dx``, used to invert the model: compensation) and on its
parameters (:meth:`Effect.sensitivity`, used to fit it and to test it as a candidate against a
residual).  Stochastic effects (noise processes) draw from the ``numpy.random.Generator`` the
caller passes.  Random unit-to-unit parameters (turn-on bias, scale tolerance, ...) are given as
``<param>_sigma`` next to the nominal value and are drawn by :meth:`Effect.realize`.

Frames: x and δ in the body frame (RFU); the Earth rate uses the attitude body→ENU.  Parameters
are SI (rad/s, m/s², s, Hz, °C) except the magnetometer triad's, which are in µT like the
``Recording``; presets convert datasheet units with :mod:`gyrosim.units`.  Each effect class
declares the triads it applies to and the unit quantity of its main parameter (``quantities``):
nothing else switches on effect names.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace
from functools import lru_cache
from typing import Any, ClassVar

import numpy as np
from scipy import fft as sp_fft
from scipy import signal as sp_signal
from scipy.interpolate import CubicSpline

from . import _kernels as kern
from .errors import GyrosimError
from .rotations import quat_conjugate, quat_rotate

__all__ = [
    "SignalContext",
    "Effect",
    "EFFECTS",
    "effect_from_dict",
    "rotation_matrix",
    "nonortho_matrix",
]

EARTH_RATE_RAD_S = 7.2921150e-5  # WGS-84 ω_ie


@dataclass(frozen=True)
class SignalContext:
    """What effects may depend on, all sampled at ``t_s`` (s).

    ``omega_true_rad_s`` and ``specific_force_true_m_s2`` in the body frame (RFU);
    ``temperature_c`` the sensor temperature (°C); ``quat_nb`` attitude body→ENU;
    ``mag_body_ut`` the magnetic field at the sensor (µT, body frame).
    """

    t_s: np.ndarray
    omega_true_rad_s: np.ndarray
    specific_force_true_m_s2: np.ndarray
    temperature_c: np.ndarray | None = None
    quat_nb: np.ndarray | None = None
    mag_body_ut: np.ndarray | None = None
    dt_s: float = 0.0  # nominal sample interval (s); 0 → median of Δt, computed once

    def __post_init__(self) -> None:
        if not self.dt_s:
            object.__setattr__(self, "dt_s", float(np.median(np.diff(self.t_s))))

    @property
    def n(self) -> int:
        return int(self.t_s.shape[0])

    @property
    def rate_hz(self) -> float:
        return 1.0 / self.dt_s

    def require(self, name: str, effect: str) -> np.ndarray:
        v = getattr(self, name)
        if v is None:
            raise GyrosimError(f"effect {effect!r} needs {name} in the context; the recording has none")
        return v


def _vec(v: Any, n: int = 3, name: str = "parameter") -> np.ndarray:
    a = np.array(v, dtype=float).reshape(-1)
    if a.size == 1 and n > 1:
        a = np.full(n, float(a[0]))
    if a.size != n:
        raise GyrosimError(f"{name} needs {n} values, got {a.size}")
    if not np.all(np.isfinite(a)):
        raise GyrosimError(f"{name} has NaN/inf values {a.tolist()}: every parameter must be finite")
    return a


@dataclass(frozen=True)
class Effect:
    """Base class. Subclasses declare ``kind``, ``stage``, ``quantity`` and ``param_fields``."""

    kind: ClassVar[str] = ""
    stage: ClassVar[str] = "error"  # "error" (additive on truth) or "output" (transform, in order)
    stochastic: ClassVar[bool] = False
    invertible: ClassVar[bool] = True  # an exact compensation exists (deterministic effects)
    # triad → unit quantity of the main parameter (gyrosim.units.QUANTITIES), how a preset in
    # datasheet units is read; the triads an effect applies to are the keys (``triads``)
    quantities: ClassVar[dict[str, str]] = {}
    triads: ClassVar[tuple[str, ...]] = ()
    param_fields: ClassVar[tuple[str, ...]] = ()
    pointwise: ClassVar[bool] = False  # δ_k depends on sample k only (a single in-place pass)

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        cls.triads = tuple(cls.quantities)

    # ---------------------------------------------------------------- parameters
    def params(self) -> np.ndarray:
        """Flat parameter vector θ (SI), in ``param_fields`` order."""
        if not self.param_fields:
            return np.zeros(0)
        return np.concatenate([np.atleast_1d(np.asarray(getattr(self, f), dtype=float)).ravel() for f in self.param_fields])

    def param_names(self) -> list[str]:
        names = []
        for f in self.param_fields:
            a = np.atleast_1d(np.asarray(getattr(self, f)))
            names += [f"{self.kind}.{f}[{i}]" for i in range(a.size)] if a.size > 1 else [f"{self.kind}.{f}"]
        return names

    def with_params(self, theta: np.ndarray) -> "Effect":
        """A copy with parameters θ (same layout as :meth:`params`)."""
        theta = np.asarray(theta, dtype=float)
        out, i = {}, 0
        for f in self.param_fields:
            cur = np.asarray(getattr(self, f), dtype=float)
            out[f] = theta[i : i + cur.size].reshape(cur.shape) if cur.ndim else float(theta[i])
            i += max(cur.size, 1)
        return replace(self, **out)

    def realize(self, rng: np.random.Generator) -> "Effect":
        """Draw the unit-to-unit random parameters (``<p>_sigma``) of one device; sigmas become 0."""
        changes: dict[str, Any] = {}
        for f in self.param_fields:
            sig_name = f"{f}_sigma"
            if hasattr(self, sig_name):
                sig = np.asarray(getattr(self, sig_name), dtype=float)
                if np.any(sig):
                    nominal = np.asarray(getattr(self, f), dtype=float)
                    changes[f] = nominal + sig * rng.standard_normal(nominal.shape)
                    changes[sig_name] = np.zeros_like(sig)
        return replace(self, **changes) if changes else self

    # ---------------------------------------------------------------- forward
    def delta(self, x: np.ndarray, ctx: SignalContext, rng: np.random.Generator | None = None) -> np.ndarray:
        """Error-stage term δ(x, ctx) (N, 3) added to the true signal x."""
        raise NotImplementedError

    def delta_dx(self, x: np.ndarray, ctx: SignalContext) -> np.ndarray | None:
        """∂δ/∂x (N, 3, 3), or None when δ does not depend on x."""
        return None

    def affine(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(A, c) if δ = A x + c with constant A (3×3) and c (3,), else None.  A sensor model sums
        these over effects and applies them in one pass (exact: the terms simply add)."""
        return None

    def add_delta(self, y: np.ndarray, x: np.ndarray, ctx: SignalContext, rng: np.random.Generator | None) -> None:
        """y += δ(x, ctx) in place (hot effects override it to avoid temporaries)."""
        y += self.delta(x, ctx, rng)

    def coarse_step_s(self, white_density: np.ndarray, dt_s: float) -> float | None:
        """For a slow random process: the longest grid step on which it may be drawn and then
        linearly interpolated, given the white-noise density N of the same triad.

        The step Δc is chosen so that above the coarse Nyquist frequency 1/(2Δc) the process's PSD
        is below 1 % of the white PSD N²: what the coarse grid omits is < 1 % of the noise already
        there.  None: not a slow process (draw it per sample).
        """
        return None

    def delta_on_grid(self, n: int, dt_s: float, rng: np.random.Generator) -> np.ndarray:
        """(n, 3) realisation on a uniform grid of step ``dt_s`` (slow processes only)."""
        raise NotImplementedError

    def psd_two_sided(self, f_hz: np.ndarray) -> np.ndarray | None:
        """Two-sided PSD (3, F) of a stationary Gaussian noise effect that is synthesised in the
        frequency domain (:func:`spectral_noise`), else None."""
        return None

    # ---------------------------------------------------------------- stochastic-model identification
    # the fields a stochastic-model fit (calib.noise, GMWM) estimates, each > 0; () = not a noise term
    noise_parameters: ClassVar[tuple[str, ...]] = ()

    def haar_wavelet_variance(self, m: np.ndarray, dt_s: float) -> np.ndarray:
        """Theoretical Haar (MODWT) wavelet variance ν²_j (3, J) of this term's sampled sequence at
        scales τ_j = 2 m_j Δt (m_j samples per half-filter).  ν² is half the Allan variance at
        cluster time m Δt (Percival & Walden 2000 §8.6).  Only for noise terms (``noise_parameters``)."""
        raise NotImplementedError(f"{self.kind} is not a stochastic-model term")

    def discrete_psd(self, f_cyc: np.ndarray, dt_s: float) -> np.ndarray:
        """Two-sided PSD (3, F) of this term's sampled sequence at f (cycles/sample, |f| ≤ ½), in
        per-sample variance units (∫_{−½}^{½} S df = variance per sample); a random walk's is the
        pseudo-spectrum γ²/(4 sin²πf) of its stationary increments.  Noise terms only."""
        raise NotImplementedError(f"{self.kind} is not a stochastic-model term")

    def ieee952_terms(self) -> dict[str, np.ndarray]:
        """This effect's share of the IEEE Std 952 three-term noise model, per axis (SI):
        ``arw`` N (white: σ_A = N/√τ), ``bias_instability`` B (flicker: σ_A = 0.664 B),
        ``rate_random_walk`` K (Wiener: σ_A = K√(τ/3)).  {} for everything else, so a caller
        (e.g. the covariance of window means in calib.noisecov) can sum over a triad's effects
        without knowing their kinds."""
        return {}

    def transform(self, y: np.ndarray, ctx: SignalContext, rng: np.random.Generator | None = None) -> np.ndarray:
        """Output-stage transform of the sensor output y (N, 3)."""
        raise NotImplementedError

    def inverse(self, y: np.ndarray, ctx: SignalContext) -> np.ndarray:
        """Undo :meth:`transform` (output stage)."""
        raise GyrosimError(f"effect {self.kind!r} cannot be undone")

    # ---------------------------------------------------------------- estimation
    def sensitivity(self, x: np.ndarray, ctx: SignalContext) -> np.ndarray:
        """∂y/∂θ (N, 3, P) at the current parameters.

        Default: central finite differences of the forward model (exact for linear-in-θ
        effects up to rounding); linear effects override it with the closed form.
        """
        if self.stochastic:
            raise GyrosimError(f"{self.kind!r} is a random process: it has no parameter sensitivity")
        theta = self.params()
        out = np.empty(x.shape + (theta.size,))
        for j in range(theta.size):
            h = 1e-6 * max(1.0, abs(theta[j]))
            tp, tm = theta.copy(), theta.copy()
            tp[j] += h
            tm[j] -= h
            out[..., j] = (self.with_params(tp)._forward(x, ctx) - self.with_params(tm)._forward(x, ctx)) / (2 * h)
        return out

    def _forward(self, x: np.ndarray, ctx: SignalContext) -> np.ndarray:
        return x + self.delta(x, ctx) if self.stage == "error" else self.transform(x, ctx)

    # ---------------------------------------------------------------- serialisation
    def to_dict(self) -> dict[str, Any]:
        d: dict[str, Any] = {"effect": self.kind}
        for f in fields(self):
            v = getattr(self, f.name)
            d[f.name] = np.asarray(v).tolist() if isinstance(v, (np.ndarray, list, tuple)) else v
        return d


# ================================================================ error-stage effects
@dataclass(frozen=True)
class Bias(Effect):
    """Constant bias: δ = b.  ``value_sigma`` draws a turn-on bias per run (b ~ N(value, σ²)).

    Units: rad/s (gyro) or m/s² (accelerometer).  Zhou 2020 eq. 1, §3.2.
    """

    kind: ClassVar[str] = "bias"
    quantities: ClassVar[dict[str, str]] = {"gyro": "rate", "accelerometer": "acceleration"}
    pointwise: ClassVar[bool] = True
    param_fields: ClassVar[tuple[str, ...]] = ("value",)
    value: np.ndarray = field(default_factory=lambda: np.zeros(3))
    value_sigma: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self) -> None:
        object.__setattr__(self, "value", _vec(self.value, name="bias value"))
        object.__setattr__(self, "value_sigma", _vec(self.value_sigma, name="bias sigma"))

    def delta(self, x, ctx, rng=None):
        return np.broadcast_to(self.value, x.shape).copy()

    def add_delta(self, y, x, ctx, rng=None):
        y += self.value

    def affine(self):
        return np.zeros((3, 3)), self.value

    def sensitivity(self, x, ctx):
        return np.broadcast_to(np.eye(3), x.shape + (3,)).copy()


def _check_invertible(m: np.ndarray, kind: str, value: np.ndarray) -> None:
    """(I + N) must stay a proper, well-conditioned axis set: det > 0.1 and cond < 100."""
    det = float(np.linalg.det(m))
    if not det > 0.1 or np.linalg.cond(m) > 100:
        raise GyrosimError(
            f"{kind} {np.round(value, 6).tolist()} makes the axis matrix singular or flips an axis "
            f"(det(I + N) = {det:.3g}); real non-orthogonality is a few 1e-2 at most: check units (% vs fraction)"
        )


def nonortho_matrix(g: np.ndarray) -> np.ndarray:
    """N(G), the symmetric non-orthogonality matrix of ω̃ = (I + diag(S) + N(G)) ω + b (Zhou 2020 eq. 1):
    zero diagonal, N[0,1] = N[1,0] = Gz, N[0,2] = N[2,0] = Gy, N[1,2] = N[2,1] = Gx."""
    gx, gy, gz = g
    return np.array([[0.0, gz, gy], [gz, 0.0, gx], [gy, gx, 0.0]])


@dataclass(frozen=True)
class ScaleFactor(Effect):
    """Scale-factor error: δ = S x, S = diag(Sx, Sy, Sz) (dimensionless).  Zhou 2020 eq. 2."""

    kind: ClassVar[str] = "scale_factor"
    quantities: ClassVar[dict[str, str]] = {"gyro": "fraction", "accelerometer": "fraction"}
    pointwise: ClassVar[bool] = True
    param_fields: ClassVar[tuple[str, ...]] = ("value",)
    value: np.ndarray = field(default_factory=lambda: np.zeros(3))
    value_sigma: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self) -> None:
        object.__setattr__(self, "value", _vec(self.value, name="scale factor"))
        object.__setattr__(self, "value_sigma", _vec(self.value_sigma, name="scale factor sigma"))

    def delta(self, x, ctx, rng=None):
        return x * self.value

    def add_delta(self, y, x, ctx, rng=None):
        y += x * self.value

    def affine(self):
        return np.diag(self.value), np.zeros(3)

    def delta_dx(self, x, ctx):
        return np.broadcast_to(np.diag(self.value), x.shape + (3,))

    def sensitivity(self, x, ctx):
        out = np.zeros(x.shape + (3,))
        for i in range(3):
            out[:, i, i] = x[:, i]
        return out


@dataclass(frozen=True)
class NonOrthogonality(Effect):
    """Non-orthogonality in the paper's symmetric form (Zhou 2020 eq. 2): δ = N x,

        N = [[0, Gz, Gy], [Gz, 0, Gx], [Gy, Gx, 0]]   (dimensionless, small-angle rad).

    ∂(N x)/∂Gx = (0, x_z, x_y), ∂/∂Gy = (x_z, 0, x_x), ∂/∂Gz = (x_y, x_x, 0).
    """

    kind: ClassVar[str] = "nonorthogonality"
    quantities: ClassVar[dict[str, str]] = {"gyro": "fraction", "accelerometer": "fraction"}
    pointwise: ClassVar[bool] = True
    param_fields: ClassVar[tuple[str, ...]] = ("value",)
    value: np.ndarray = field(default_factory=lambda: np.zeros(3))
    value_sigma: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self) -> None:
        object.__setattr__(self, "value", _vec(self.value, name="non-orthogonality"))
        object.__setattr__(self, "value_sigma", _vec(self.value_sigma, name="non-orthogonality sigma"))
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
class Misalignment(Effect):
    """General 6-parameter misalignment/cross-coupling: δ = M x, M off-diagonal with
    value = [m_xy, m_xz, m_yx, m_yz, m_zx, m_zy] (row = sensing axis, column = input axis)."""

    kind: ClassVar[str] = "misalignment"
    quantities: ClassVar[dict[str, str]] = {"gyro": "fraction", "accelerometer": "fraction"}
    pointwise: ClassVar[bool] = True
    param_fields: ClassVar[tuple[str, ...]] = ("value",)
    value: np.ndarray = field(default_factory=lambda: np.zeros(6))
    value_sigma: np.ndarray = field(default_factory=lambda: np.zeros(6))

    def __post_init__(self) -> None:
        object.__setattr__(self, "value", _vec(self.value, 6, "misalignment"))
        object.__setattr__(self, "value_sigma", _vec(self.value_sigma, 6, "misalignment sigma"))
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
class ScaleNonlinearity(Effect):
    """Quadratic scale nonlinearity per axis: δ_i = k_i x_i |x_i| (odd-symmetric, so it is a
    true nonlinearity and not a bias).  k in 1/(rad/s) or 1/(m/s²); a datasheet "nonlinearity
    ±p % of full scale R" gives k = p/100 / R (the error at full scale is p % of R)."""

    kind: ClassVar[str] = "scale_nonlinearity"
    quantities: ClassVar[dict[str, str]] = {"gyro": "per_rate", "accelerometer": "per_acceleration"}
    pointwise: ClassVar[bool] = True
    param_fields: ClassVar[tuple[str, ...]] = ("value",)
    value: np.ndarray = field(default_factory=lambda: np.zeros(3))
    value_sigma: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self) -> None:
        object.__setattr__(self, "value", _vec(self.value, name="nonlinearity"))
        object.__setattr__(self, "value_sigma", _vec(self.value_sigma, name="nonlinearity sigma"))

    def delta(self, x, ctx, rng=None):
        return self.value * x * np.abs(x)

    def add_delta(self, y, x, ctx, rng=None):
        kern.add_nonlinearity(y, x, self.value)

    def delta_dx(self, x, ctx):
        out = np.zeros(x.shape + (3,))
        for i in range(3):
            out[:, i, i] = 2 * self.value[i] * np.abs(x[:, i])
        return out

    def sensitivity(self, x, ctx):
        out = np.zeros(x.shape + (3,))
        for i in range(3):
            out[:, i, i] = x[:, i] * np.abs(x[:, i])
        return out


@dataclass(frozen=True)
class GSensitivity(Effect):
    """Gyro sensitivity to specific force: δ = K f, K 3×3 in (rad/s)/(m/s²) (gyro only)."""

    kind: ClassVar[str] = "g_sensitivity"
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


def _poly(t: np.ndarray, coeffs: np.ndarray) -> np.ndarray:
    """Σ_p c[:, p] ΔT^(p+1) for coefficient matrix (3, P) → (N, 3)."""
    powers = np.stack([t ** (p + 1) for p in range(coeffs.shape[1])], axis=1)  # (N, P)
    return powers @ coeffs.T


@dataclass(frozen=True)
class TemperatureBias(Effect):
    """Bias over temperature: δ = Σ_{p=1..P} c_p (T − T_ref)^p, coefficients (3, P) in
    rad/s/°C^p or m/s²/°C^p.  Valid on ``range_c``; a temperature outside it is an error."""

    kind: ClassVar[str] = "temperature_bias"
    quantities: ClassVar[dict[str, str]] = {"gyro": "rate", "accelerometer": "acceleration"}  # per °C^p
    pointwise: ClassVar[bool] = True
    param_fields: ClassVar[tuple[str, ...]] = ("coefficients",)
    coefficients: np.ndarray = field(default_factory=lambda: np.zeros((3, 1)))
    coefficients_sigma: np.ndarray = field(default_factory=lambda: np.zeros((3, 1)))
    t_ref_c: float = 25.0
    range_c: tuple[float, float] = (-40.0, 85.0)

    def __post_init__(self) -> None:
        for name in ("coefficients", "coefficients_sigma"):
            c = np.array(getattr(self, name), dtype=float)
            c = c.reshape(3, -1) if c.size % 3 == 0 and c.ndim != 2 else c
            if c.ndim == 1:
                c = np.tile(c[:, None], (3, 1)) if c.size == 1 else c.reshape(3, -1)
            if not np.all(np.isfinite(c)):
                raise GyrosimError(f"{self.kind}: coefficients must be finite")
            object.__setattr__(self, name, c)

    def _dT(self, ctx: SignalContext) -> np.ndarray:
        temp = ctx.require("temperature_c", self.kind)
        lo, hi = self.range_c
        if np.nanmin(temp) < lo - 1e-9 or np.nanmax(temp) > hi + 1e-9:
            raise GyrosimError(
                f"{self.kind}: temperature {np.nanmin(temp):.1f}–{np.nanmax(temp):.1f} °C leaves the model's "
                f"valid range {lo:g}–{hi:g} °C; the preset cannot extrapolate"
            )
        return temp - self.t_ref_c

    def delta(self, x, ctx, rng=None):
        return _poly(self._dT(ctx), self.coefficients)

    def add_delta(self, y, x, ctx, rng=None):
        kern.add_poly_bias(y, np.ascontiguousarray(self._dT(ctx)), self.coefficients)

    def sensitivity(self, x, ctx):
        dT = self._dT(ctx)
        P = self.coefficients.shape[1]
        out = np.zeros(x.shape + (3 * P,))
        for i in range(3):
            for p in range(P):
                out[:, i, i * P + p] = dT ** (p + 1)
        return out


@dataclass(frozen=True)
class TemperatureScale(TemperatureBias):
    """Scale factor over temperature: δ = diag(Σ_p s_p (T − T_ref)^p) x, s in 1/°C^p."""

    kind: ClassVar[str] = "temperature_scale"
    quantities: ClassVar[dict[str, str]] = {"gyro": "fraction", "accelerometer": "fraction"}  # per °C^p

    def delta(self, x, ctx, rng=None):
        return x * _poly(self._dT(ctx), self.coefficients)

    def add_delta(self, y, x, ctx, rng=None):
        kern.add_poly_scale(y, x, np.ascontiguousarray(self._dT(ctx)), self.coefficients)

    def delta_dx(self, x, ctx):
        s = _poly(self._dT(ctx), self.coefficients)
        out = np.zeros(x.shape + (3,))
        for i in range(3):
            out[:, i, i] = s[:, i]
        return out

    def sensitivity(self, x, ctx):
        # ∂δ_i/∂s_ip = x_i ΔT^p: the bias sensitivity times the input on that axis
        return super().sensitivity(x, ctx) * x[:, :, None]


@dataclass(frozen=True)
class ThermalHysteresis(Effect):
    """Heating/cooling hysteresis: a bias proportional to the low-passed temperature rate,
    δ = h · LP_τ(dT/dt), h in (rad/s)/(°C/s) or (m/s²)/(°C/s); the bias lags differently when
    warming (dT/dt > 0) and cooling (< 0), which opens the loop of a bias-vs-T plot."""

    kind: ClassVar[str] = "thermal_hysteresis"
    quantities: ClassVar[dict[str, str]] = {"gyro": "rate", "accelerometer": "acceleration"}  # per (°C/s)
    param_fields: ClassVar[tuple[str, ...]] = ("value",)
    value: np.ndarray = field(default_factory=lambda: np.zeros(3))
    value_sigma: np.ndarray = field(default_factory=lambda: np.zeros(3))
    tau_s: float = 300.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "value", _vec(self.value, name="hysteresis"))
        object.__setattr__(self, "value_sigma", _vec(self.value_sigma, name="hysteresis sigma"))
        if not (math.isfinite(self.tau_s) and self.tau_s > 0):
            raise GyrosimError("thermal_hysteresis: tau_s must be > 0 s")

    def regressor(self, ctx: SignalContext) -> np.ndarray:
        temp = ctx.require("temperature_c", self.kind)
        rate = np.gradient(temp, ctx.t_s)
        a = math.exp(-ctx.dt_s / self.tau_s)
        return sp_signal.lfilter([1 - a], [1, -a], rate, zi=[a * rate[0]])[0]

    def delta(self, x, ctx, rng=None):
        return np.outer(self.regressor(ctx), self.value)

    def sensitivity(self, x, ctx):
        r = self.regressor(ctx)
        return np.broadcast_to(np.eye(3), x.shape + (3,)) * r[:, None, None]


def _hats(temp: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(N, K) linear-interpolation weights of each temperature on the points (held beyond the ends)."""
    t = np.clip(temp, points[0], points[-1])
    j = np.clip(np.searchsorted(points, t, side="right") - 1, 0, points.size - 2)
    w = (t - points[j]) / (points[j + 1] - points[j])
    out = np.zeros((t.size, points.size))
    rows = np.arange(t.size)
    out[rows, j] = 1.0 - w
    out[rows, j + 1] = w
    return out


@dataclass(frozen=True)
class TemperaturePiecewise(Effect):
    """Bias and scale factor interpolated linearly between calibration temperatures (seed 001 §4,
    piecewise-linear interpolation compensation): δ_i = b_i(T) + s_i(T) x_i, with b_i, s_i the
    values at ``points_c`` (°C, increasing) joined linearly and held beyond the end points.
    ``bias`` (3, K) in rad/s or m/s², ``scale`` (3, K) fraction (SI in presets too)."""

    kind: ClassVar[str] = "temperature_pwl"
    # bias values in the preset unit; scale in SI
    quantities: ClassVar[dict[str, str]] = {"gyro": "rate", "accelerometer": "acceleration"}
    pointwise: ClassVar[bool] = True
    param_fields: ClassVar[tuple[str, ...]] = ("bias", "scale")
    points_c: np.ndarray = field(default_factory=lambda: np.array([-40.0, 85.0]))
    bias: np.ndarray = field(default_factory=lambda: np.zeros((3, 2)))
    scale: np.ndarray = field(default_factory=lambda: np.zeros((3, 2)))

    def __post_init__(self) -> None:
        pts = np.asarray(self.points_c, dtype=float).ravel()
        if pts.size < 2 or np.any(np.diff(pts) <= 0) or not np.all(np.isfinite(pts)):
            raise GyrosimError("temperature_pwl: points_c must be ≥ 2 finite, strictly increasing temperatures (°C)")
        object.__setattr__(self, "points_c", pts)
        for name in ("bias", "scale"):
            v = np.array(getattr(self, name), dtype=float)
            v = np.tile(v.reshape(1, -1), (3, 1)) if v.ndim == 1 else v
            if v.shape != (3, pts.size) or not np.all(np.isfinite(v)):
                raise GyrosimError(f"temperature_pwl: {name} must be finite with shape (3, {pts.size}), got {v.shape}")
            object.__setattr__(self, name, v)

    def _h(self, ctx: SignalContext) -> np.ndarray:
        return _hats(ctx.require("temperature_c", self.kind), self.points_c)

    def delta(self, x, ctx, rng=None):
        h = self._h(ctx)
        return h @ self.bias.T + x * (h @ self.scale.T)

    def delta_dx(self, x, ctx):
        s = self._h(ctx) @ self.scale.T
        out = np.zeros(x.shape + (3,))
        for i in range(3):
            out[:, i, i] = s[:, i]
        return out

    def sensitivity(self, x, ctx):
        h = self._h(ctx)
        k = self.points_c.size
        out = np.zeros(x.shape + (6 * k,))
        for i in range(3):
            out[:, i, i * k : (i + 1) * k] = h
            out[:, i, 3 * k + i * k : 3 * k + (i + 1) * k] = h * x[:, i : i + 1]
        return out


@dataclass(frozen=True)
class TemperatureRBF(Effect):
    """Bias drift over temperature as a Gaussian radial-basis network with the inputs ΔT and ΔT²
    (seed 003, §3.2: TDE modelled from ΔT = T − T_ref and ΔT²):

        δ_i = Σ_k a_ik exp(−½ [((ΔT − ΔT_k)/w)² + ((ΔT² − ΔT_k²)/(w·s))²]),   s = 2 max_k |ΔT_k|

    with centres ΔT_k = ``centres_c`` − ``t_ref_c`` and width w = ``width_c`` (°C); s puts the ΔT²
    axis on the same scale as ΔT.  The centres are fixed, so δ is linear in the weights a (3, K),
    rad/s or m/s² (an RBF network whose output layer is fitted by least squares)."""

    kind: ClassVar[str] = "temperature_rbf"
    quantities: ClassVar[dict[str, str]] = {"gyro": "rate", "accelerometer": "acceleration"}
    pointwise: ClassVar[bool] = True
    param_fields: ClassVar[tuple[str, ...]] = ("weights",)
    centres_c: np.ndarray = field(default_factory=lambda: np.linspace(-40.0, 85.0, 6))
    width_c: float = 25.0
    t_ref_c: float = 25.0
    weights: np.ndarray = field(default_factory=lambda: np.zeros((3, 6)))

    def __post_init__(self) -> None:
        c = np.asarray(self.centres_c, dtype=float).ravel()
        if c.size < 1 or not np.all(np.isfinite(c)):
            raise GyrosimError("temperature_rbf: centres_c must be finite temperatures (°C)")
        if not (math.isfinite(self.width_c) and self.width_c > 0):
            raise GyrosimError("temperature_rbf: width_c must be > 0 °C")
        object.__setattr__(self, "centres_c", c)
        w = np.array(self.weights, dtype=float)
        w = np.tile(w.reshape(1, -1), (3, 1)) if w.ndim == 1 else w
        if w.shape != (3, c.size) or not np.all(np.isfinite(w)):
            raise GyrosimError(f"temperature_rbf: weights must be finite with shape (3, {c.size}), got {w.shape}")
        object.__setattr__(self, "weights", w)

    def basis(self, temp_c: np.ndarray) -> np.ndarray:
        """(N, K) Gaussian activations of the hidden layer."""
        d = np.asarray(temp_c, dtype=float)[:, None] - self.t_ref_c
        dk = self.centres_c[None, :] - self.t_ref_c
        s = 2.0 * max(float(np.max(np.abs(dk))), 1.0)
        z = ((d - dk) / self.width_c) ** 2 + ((d**2 - dk**2) / (self.width_c * s)) ** 2
        return np.exp(-0.5 * z)

    def delta(self, x, ctx, rng=None):
        return self.basis(ctx.require("temperature_c", self.kind)) @ self.weights.T

    def sensitivity(self, x, ctx):
        b = self.basis(ctx.require("temperature_c", self.kind))
        k = self.centres_c.size
        out = np.zeros(x.shape + (3 * k,))
        for i in range(3):
            out[:, i, i * k : (i + 1) * k] = b
        return out


@dataclass(frozen=True)
class EarthRate(Effect):
    """Earth rotation seen by the gyro: δ = C_nᵇ ω_ieⁿ, ω_ieⁿ = Ω (0, cos L, sin L) in ENU,
    Ω = 7.2921150e-5 rad/s (15.04 °/h), L = latitude.  Needs the attitude; gyro only."""

    kind: ClassVar[str] = "earth_rate"
    quantities: ClassVar[dict[str, str]] = {"gyro": "angle"}
    pointwise: ClassVar[bool] = True
    param_fields: ClassVar[tuple[str, ...]] = ("latitude_rad",)
    latitude_rad: float = 0.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.latitude_rad) and abs(self.latitude_rad) <= math.pi / 2):
            raise GyrosimError("earth_rate: latitude must be within ±90°")

    def delta(self, x, ctx, rng=None):
        q = ctx.require("quat_nb", self.kind)
        w_n = EARTH_RATE_RAD_S * np.array([0.0, math.cos(self.latitude_rad), math.sin(self.latitude_rad)])
        return quat_rotate(quat_conjugate(q), np.broadcast_to(w_n, x.shape))


@dataclass(frozen=True)
class MagneticSensitivity(Effect):
    """Gyro bias from the magnetic field (Faraday effect in FOG coils, seed 001): δ = K B_b,
    K 3×3 in (rad/s)/µT; unshielded FOG ~1e4 °/(h·T), POS grade 1–10 °/(h·T).  Gyro only."""

    kind: ClassVar[str] = "magnetic_sensitivity"
    quantities: ClassVar[dict[str, str]] = {"gyro": "rate_per_tesla"}
    pointwise: ClassVar[bool] = True
    param_fields: ClassVar[tuple[str, ...]] = ("value",)
    value: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))

    def __post_init__(self) -> None:
        v = np.array(self.value, dtype=float)
        v = np.diag(v) if v.shape == (3,) else v.reshape(3, 3)
        if not np.all(np.isfinite(v)):
            raise GyrosimError("magnetic_sensitivity has NaN/inf values")
        object.__setattr__(self, "value", v)

    def delta(self, x, ctx, rng=None):
        return ctx.require("mag_body_ut", self.kind) @ self.value.T

    def add_delta(self, y, x, ctx, rng=None):
        kern.add_matvec(y, np.ascontiguousarray(ctx.require("mag_body_ut", self.kind)), self.value)

    def sensitivity(self, x, ctx):
        b = ctx.require("mag_body_ut", self.kind)
        out = np.zeros(x.shape + (9,))
        for i in range(3):
            out[:, i, 3 * i : 3 * i + 3] = b
        return out


# ---------------------------------------------------------------- magnetometer (µT)
@dataclass(frozen=True)
class HardIron(Bias):
    """Hard iron: a field fixed in the body frame, δ = h (µT) — the magnetised parts of the board
    and the sensor's own zero-field offset, which the magnetometer cannot tell apart (both turn
    with the board).  ``value_sigma`` draws it per device.  Magnetometer only.

    Model m = A B + h (Ozyagcilar, "Calibrating an eCompass in the Presence of Hard- and Soft-Iron
    Interference", Freescale AN4246, eq. 8): h is this effect, A the :class:`SoftIron` matrix.
    """

    kind: ClassVar[str] = "hard_iron"
    quantities: ClassVar[dict[str, str]] = {"magnetometer": "magnetic_field"}


def _matrix(v: Any, name: str) -> np.ndarray:
    a = np.array(v, dtype=float)
    a = np.diag(a) if a.shape == (3,) else a.reshape(3, 3) if a.size == 9 else a
    if a.shape != (3, 3) or not np.all(np.isfinite(a)):
        raise GyrosimError(f"{name} must be a finite 3×3 matrix (or 3 diagonal values), got shape {np.shape(v)}")
    return a


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


# ---------------------------------------------------------------- random processes
def _need_rng(rng: np.random.Generator | None, kind: str) -> np.random.Generator:
    if rng is None:
        raise GyrosimError(f"{kind} is random: pass a numpy.random.Generator (rng=...)")
    return rng


def spectral_noise(effects: list["Effect"], n: int, fs: float, rng: np.random.Generator) -> np.ndarray:
    """One (N, 3) realisation of the summed stationary Gaussian processes of ``effects``.

    Spectrum drawn directly in the frequency domain: for the two-sided PSD S(f), the rFFT bin k
    of a length-n real sequence has E|X_k|² = n f_s S(f_k) (n f_s S for k = 0 and Nyquist,
    which are real), so X_k = √(n f_s S(f_k)/2) (g₁ + i g₂) for 0 < k < n/2; irfft then gives
    E[x²] = Σ S Δf over [−f_s/2, f_s/2], the discrete white sequence of σ² = N² f_s for S = N².
    The DC bin is zero (a constant belongs to the bias effect).
    """
    f = np.fft.rfftfreq(n, 1.0 / fs)
    psd = sum(e.psd_two_sided(f) for e in effects)  # (3, F)
    amp = np.sqrt(psd * (n * fs / 2.0))
    g = rng.standard_normal((3, f.size, 2)).view(complex)[..., 0]  # g₁ + i g₂ without temporaries
    spec = g
    spec *= amp
    spec[:, 0] = 0.0
    if n % 2 == 0:  # Nyquist bin of a real signal is real: E|X|² = n f_s S with one real normal
        spec[:, -1] = np.sqrt(2.0) * spec[:, -1].real
    return sp_fft.irfft(spec, n=n, axis=1, workers=-1).T


def haar_gain2(f_cyc: np.ndarray, m: int) -> np.ndarray:
    """|H_m(f)|² of the level-j Haar MODWT filter (half-length m = 2^{j−1}; taps ±1/(2m)):
    sin⁴(π f m) / (m² sin²(π f)), f in cycles/sample (Percival & Walden 2000 eq. 163)."""
    s = np.sin(np.pi * f_cyc)
    return np.sin(np.pi * f_cyc * m) ** 4 / (m * m * s * s)


@lru_cache(maxsize=4096)
def _haar_integral_flicker(m: int) -> float:
    """2 ∫_0^½ |H_m(f)|² / (2π f) df: the Haar wavelet variance of a unit flicker process (S(f) =
    1/(2π|f|) per sample).  Core f < 32/m on a fine grid in u = f m (128 points per period of
    sin⁴), beyond it sin⁴(π f m) is replaced by its mean 3/8 (the rest of the integrand is smooth)."""
    f1 = min(0.5, 32.0 / m)
    u = np.linspace(1e-9, f1 * m, 8193)
    f = u / m
    core = float(np.trapezoid(haar_gain2(f, m) / (2 * np.pi * f), f))
    tail = 0.0
    if f1 < 0.5:
        ft = np.geomspace(f1, 0.5, 2049)
        tail = float(np.trapezoid(0.375 / (m * m * np.sin(np.pi * ft) ** 2) / (2 * np.pi * ft), ft))
    return 2.0 * (core + tail)


def _ar1_draw(n: int, dt_s: float, sigma: np.ndarray, tau_s: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """(n, 3) first-order Gauss–Markov process, exact discretisation: b_{k+1} = φ b_k + σ √(1 − φ²) w_k,
    φ = e^{−Δt/τ}, started from its stationary N(0, σ²) (Maybeck 1979 §4.11)."""
    phi = np.exp(-dt_s / np.asarray(tau_s, float))
    w = rng.standard_normal((n, 3)) * (sigma * np.sqrt(1 - phi**2))
    w[0] = rng.standard_normal(3) * sigma
    out = np.empty_like(w)
    for i in range(3):
        out[:, i] = sp_signal.lfilter([1.0], [1.0, -phi[i]], w[:, i])
    return out


def _ar1_haar(m: np.ndarray, dt_s: float, sigma: np.ndarray, tau_s: np.ndarray) -> np.ndarray:
    """Haar wavelet variance (3, J) of the sampled Gauss–Markov process (σ², φ = e^{−Δt/τ}):
    ν² = [Var S_m − Cov(S_m, S'_m)] / (2 m²) with the sums of m consecutive samples
    Var S_m = σ² [m (1+φ)/(1−φ) − 2φ(1−φ^m)/(1−φ)²], Cov = σ² φ (1−φ^m)²/(1−φ)² (geometric sums of
    the autocovariance σ² φ^|k|; Guerrier et al. 2013 give the same closed form)."""
    m = np.asarray(m, float)[None, :]
    a = (dt_s / np.asarray(tau_s, float))[:, None]
    phi = np.exp(-a)
    one_m = -np.expm1(-a)               # 1 − φ without cancellation
    one_mm = -np.expm1(-a * m)          # 1 − φ^m
    var_s = m * (1 + phi) / one_m - 2 * phi * one_mm / one_m**2
    cov = phi * one_mm**2 / one_m**2
    return (np.asarray(sigma, float) ** 2)[:, None] * (var_s - cov) / (2 * m * m)


@dataclass(frozen=True)
class WhiteNoise(Effect):
    """White measurement noise: ARW (gyro) or VRW (accelerometer).

    ``density`` is the IEEE-952 coefficient N (rad/s/√Hz = rad/√s, or m/s²/√Hz): the Allan
    deviation is N/√τ and each sample gets σ = N √f_s (see :mod:`gyrosim.units`).
    """

    kind: ClassVar[str] = "white_noise"
    quantities: ClassVar[dict[str, str]] = {"gyro": "rate_density", "accelerometer": "acceleration_density",
                                            "magnetometer": "magnetic_field_density"}
    stochastic: ClassVar[bool] = True
    invertible: ClassVar[bool] = False
    param_fields: ClassVar[tuple[str, ...]] = ("density",)
    density: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self) -> None:
        d = _vec(self.density, name="noise density")
        if np.any(d < 0):
            raise GyrosimError(f"noise density must be >= 0, got {d.tolist()}")
        object.__setattr__(self, "density", d)

    def delta(self, x, ctx, rng=None):
        rng = _need_rng(rng, self.kind)
        return rng.standard_normal(x.shape) * (self.density * math.sqrt(ctx.rate_hz))

    def add_delta(self, y, x, ctx, rng=None):
        kern.add_scaled(y, _need_rng(rng, self.kind).standard_normal(x.shape), self.density * math.sqrt(ctx.rate_hz))

    def ieee952_terms(self):
        return {"arw": self.density}

    noise_parameters: ClassVar[tuple[str, ...]] = ("density",)

    def haar_wavelet_variance(self, m, dt_s):
        # σ² = N²/Δt per sample; ν² = σ²/(2m) (P&W 2000 eq. 296)
        return (self.density**2 / dt_s)[:, None] / (2 * np.asarray(m, float))[None, :]

    def discrete_psd(self, f_cyc, dt_s):
        return np.repeat((self.density**2 / dt_s)[:, None], np.size(f_cyc), axis=1)


@dataclass(frozen=True)
class BiasInstability(Effect):
    """Bias instability: a first-order Gauss–Markov process (``model = "gauss_markov"``) or
    flicker (1/f) noise (``model = "flicker"``), sized by the datasheet bias instability B.

    * Gauss–Markov, exact discretisation: b_{k+1} = φ b_k + σ √(1 − φ²) w_k, φ = e^{−Δt/τ},
      stationary σ = B / 0.664 so that the Allan-deviation bump (≈ 0.62 σ at τ ≈ 1.9 τ_c) sits
      near B's floor; starts from its stationary distribution.
    * Flicker: white noise shaped to the two-sided PSD S(f) = B² / (2π f) (IEEE Std 952 Annex C
      convention, as the ARW N²) for 1/T ≤ f ≤ f_s/2; its Allan deviation is flat at
      √(2 ln 2/π) B = 0.664 B for 1/f_s ≪ τ ≪ T.
    """

    kind: ClassVar[str] = "bias_instability"
    quantities: ClassVar[dict[str, str]] = {"gyro": "rate", "accelerometer": "acceleration",
                                            "magnetometer": "magnetic_field"}
    stochastic: ClassVar[bool] = True
    invertible: ClassVar[bool] = False
    param_fields: ClassVar[tuple[str, ...]] = ("value",)
    value: np.ndarray = field(default_factory=lambda: np.zeros(3))
    tau_s: float = 100.0
    model: str = "flicker"

    def __post_init__(self) -> None:
        v = _vec(self.value, name="bias instability")
        if np.any(v < 0):
            raise GyrosimError("bias instability must be >= 0")
        object.__setattr__(self, "value", v)
        if self.model not in ("flicker", "gauss_markov"):
            raise GyrosimError(f"bias_instability model {self.model!r}: use 'flicker' or 'gauss_markov'")
        if not (math.isfinite(self.tau_s) and self.tau_s > 0):
            raise GyrosimError("bias_instability tau_s must be > 0 s")

    def delta(self, x, ctx, rng=None):
        return self.delta_on_grid(x.shape[0], ctx.dt_s, _need_rng(rng, self.kind))

    def delta_on_grid(self, n, dt_s, rng):
        if self.model == "gauss_markov":  # the gauss_markov effect's process, sized by B
            return _ar1_draw(n, dt_s, self.value / 0.664, np.full(3, self.tau_s), rng)
        return spectral_noise([self], n, 1.0 / dt_s, rng)

    def coarse_step_s(self, white_density, dt_s):
        # flicker: B²/(2π f) ≤ 0.01 N²  ⇔  f ≥ 100 B²/(2π N²);  Gauss–Markov (σ², τ): its PSD
        # 2σ²τ/(1 + (2πfτ)²) ≤ 2σ²/(τ(2πf)²) ≤ 0.01 N²  ⇔  f ≥ √(200 σ²/τ)/(2π N)
        if np.any(white_density <= 0):
            return None
        if self.model == "flicker":
            f_min = float(np.max(100 * self.value**2 / (2 * math.pi * white_density**2)))
        else:
            sigma = self.value / 0.664
            f_min = float(np.max(np.sqrt(200 * sigma**2 / self.tau_s) / (2 * math.pi * white_density)))
        return 1.0 / (2.0 * f_min) if f_min > 0 else None

    def psd_two_sided(self, f_hz):
        if self.model != "flicker":
            return None
        out = np.zeros((3, f_hz.size))
        pos = f_hz > 0
        out[:, pos] = (self.value**2)[:, None] / (2 * math.pi * f_hz[pos])
        return out

    def ieee952_terms(self):
        # a Gauss–Markov process is not one of the three terms (its Allan curve has a bump)
        return {"bias_instability": self.value} if self.model == "flicker" else {}

    # a noise fit builds this effect with its default model, flicker (a Gauss–Markov term is the
    # gauss_markov effect, sized by σ and τ rather than by B)
    noise_parameters: ClassVar[tuple[str, ...]] = ("value",)

    def haar_wavelet_variance(self, m, dt_s):
        if self.model == "gauss_markov":
            return _ar1_haar(m, dt_s, self.value / 0.664, np.full(3, self.tau_s))
        coef = np.array([_haar_integral_flicker(int(mi)) for mi in np.asarray(m).ravel()])
        return (self.value**2)[:, None] * coef[None, :]

    def discrete_psd(self, f_cyc, dt_s):
        f = np.abs(np.asarray(f_cyc, float))
        if self.model == "gauss_markov":
            return GaussMarkov(sigma=self.value / 0.664, tau_s=np.full(3, self.tau_s)).discrete_psd(f, dt_s)
        # S_c(F) = B²/(2πF) (Hz) sampled at f_s: S_d(f) = f_s S_c(f f_s) = B²/(2π f)
        return (self.value**2)[:, None] / (2 * np.pi * np.maximum(f, 1e-300))[None, :]


@dataclass(frozen=True)
class RandomWalk(Effect):
    """Rate random walk (gyro) / acceleration random walk: the Wiener process
    b_k = Σ K √Δt w_j starting at 0 at power-on, so σ_A(τ) = K √(τ/3); K in rad/s/√s or m/s²/√s.
    (Not synthesised spectrally: a periodic 1/f² spectrum lacks the power below 1/T and biased
    K low by 3.5 % over 2 h in our Monte Carlo.)"""

    kind: ClassVar[str] = "random_walk"
    quantities: ClassVar[dict[str, str]] = {"gyro": "rate_random_walk", "accelerometer": "acceleration_random_walk",
                                            "magnetometer": "magnetic_field_random_walk"}
    stochastic: ClassVar[bool] = True
    invertible: ClassVar[bool] = False
    param_fields: ClassVar[tuple[str, ...]] = ("value",)
    value: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self) -> None:
        v = _vec(self.value, name="random walk")
        if np.any(v < 0):
            raise GyrosimError("random walk must be >= 0")
        object.__setattr__(self, "value", v)

    def delta(self, x, ctx, rng=None):
        return self.delta_on_grid(x.shape[0], ctx.dt_s, _need_rng(rng, self.kind))

    def delta_on_grid(self, n, dt_s, rng):
        steps = rng.standard_normal((3, n))  # (3, N): cumsum along contiguous rows
        steps[:, 0] = 0.0
        np.cumsum(steps, axis=1, out=steps)
        steps *= (self.value * math.sqrt(dt_s))[:, None]
        return steps.T

    def ieee952_terms(self):
        return {"rate_random_walk": self.value}

    def coarse_step_s(self, white_density, dt_s):
        # K²/(2πf)² ≤ 0.01 N²  ⇔  f ≥ 10 K / (2π N)
        if np.any(white_density <= 0):
            return None
        f_min = float(np.max(10 * self.value / (2 * math.pi * white_density)))
        return 1.0 / (2.0 * f_min) if f_min > 0 else None

    noise_parameters: ClassVar[tuple[str, ...]] = ("value",)

    def haar_wavelet_variance(self, m, dt_s):
        # increments γ² = K²Δt; ν² = γ² (2m² + 1)/(12 m) (sum of squared weights of the increments
        # in a Haar coefficient, m(2m² + 1)/3, over (2m)²)
        m = np.asarray(m, float)[None, :]
        return (self.value**2 * dt_s)[:, None] * (2 * m * m + 1) / (12 * m)

    def discrete_psd(self, f_cyc, dt_s):
        s2 = np.sin(np.pi * np.asarray(f_cyc, float)) ** 2
        return (self.value**2 * dt_s)[:, None] / (4 * np.maximum(s2, 1e-300))[None, :]


@dataclass(frozen=True)
class GaussMarkov(Effect):
    """First-order Gauss–Markov (exponentially correlated) bias: stationary σ (rate or
    acceleration units) and correlation time τ (s) per axis; continuous ḃ = −b/τ + w with
    two-sided driving PSD q = 2σ²/τ; exact discretisation b_{k+1} = φ b_k + σ√(1 − φ²) w_k,
    φ = e^{−Δt/τ} (Maybeck 1979 §4.11).  A sensor model may hold several (GMWM's "2 GM" model).
    ``bias_instability`` with ``model = "gauss_markov"`` is this process sized by B (σ = B/0.664)."""

    kind: ClassVar[str] = "gauss_markov"
    quantities: ClassVar[dict[str, str]] = {"gyro": "rate", "accelerometer": "acceleration",
                                            "magnetometer": "magnetic_field"}
    stochastic: ClassVar[bool] = True
    invertible: ClassVar[bool] = False
    param_fields: ClassVar[tuple[str, ...]] = ("sigma", "tau_s")
    noise_parameters: ClassVar[tuple[str, ...]] = ("sigma", "tau_s")
    sigma: np.ndarray = field(default_factory=lambda: np.zeros(3))
    tau_s: np.ndarray = field(default_factory=lambda: np.full(3, 100.0))

    def __post_init__(self) -> None:
        v = _vec(self.sigma, name="Gauss-Markov sigma")
        t = _vec(self.tau_s, name="Gauss-Markov tau_s")
        if np.any(v < 0) or np.any(t <= 0):
            raise GyrosimError(f"gauss_markov needs sigma >= 0 and tau_s > 0 s, got {v.tolist()}, {t.tolist()}")
        object.__setattr__(self, "sigma", v)
        object.__setattr__(self, "tau_s", t)

    def delta(self, x, ctx, rng=None):
        return self.delta_on_grid(x.shape[0], ctx.dt_s, _need_rng(rng, self.kind))

    def delta_on_grid(self, n, dt_s, rng):
        return _ar1_draw(n, dt_s, self.sigma, self.tau_s, rng)

    def coarse_step_s(self, white_density, dt_s):
        # PSD 2σ²τ/(1 + (2πfτ)²) ≤ 2σ²/(τ(2πf)²) ≤ 0.01 N²  ⇔  f ≥ √(200 σ²/τ)/(2π N)
        if np.any(white_density <= 0):
            return None
        f_min = float(np.max(np.sqrt(200 * self.sigma**2 / self.tau_s) / (2 * math.pi * white_density)))
        return 1.0 / (2.0 * f_min) if f_min > 0 else None

    def haar_wavelet_variance(self, m, dt_s):
        return _ar1_haar(m, dt_s, self.sigma, self.tau_s)

    def discrete_psd(self, f_cyc, dt_s):
        phi = np.exp(-dt_s / self.tau_s)[:, None]
        c = np.cos(2 * np.pi * np.asarray(f_cyc, float))[None, :]
        return (self.sigma**2)[:, None] * (1 - phi**2) / (1 - 2 * phi * c + phi**2)


@dataclass(frozen=True)
class QuantizationNoise(Effect):
    """IEEE Std 952 quantization noise Q: white noise of variance Q² on the *integrated* output
    (angle rad, velocity m/s), so the rate sample is y_k += (e_k − e_{k−1})/Δt, e ~ N(0, Q²);
    σ_A(τ) = √3 Q/τ.  The statistical model of an integrating sensor's output counts (Gaussian
    here: only second moments enter the Allan and wavelet variances).  Not the ``quantization``
    output effect, which rounds each sample to its LSB."""

    kind: ClassVar[str] = "quantization_noise"
    quantities: ClassVar[dict[str, str]] = {"gyro": "angle", "accelerometer": "velocity"}
    stochastic: ClassVar[bool] = True
    invertible: ClassVar[bool] = False
    param_fields: ClassVar[tuple[str, ...]] = ("value",)
    noise_parameters: ClassVar[tuple[str, ...]] = ("value",)
    value: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self) -> None:
        v = _vec(self.value, name="quantization noise Q")
        if np.any(v < 0):
            raise GyrosimError("quantization noise Q must be >= 0")
        object.__setattr__(self, "value", v)

    def delta(self, x, ctx, rng=None):
        e = _need_rng(rng, self.kind).standard_normal((x.shape[0] + 1, 3)) * self.value
        return np.diff(e, axis=0) / ctx.dt_s

    def haar_wavelet_variance(self, m, dt_s):
        # a Haar coefficient of the rate is (2e_m − e_0 − e_2m)/(2mΔt): ν² = 6Q²/(2mΔt)²
        m = np.asarray(m, float)[None, :]
        return (6 * self.value**2)[:, None] / (2 * m * dt_s) ** 2

    def discrete_psd(self, f_cyc, dt_s):
        s2 = np.sin(np.pi * np.asarray(f_cyc, float)) ** 2
        return (self.value**2 / dt_s**2)[:, None] * (4 * s2)[None, :]


@dataclass(frozen=True)
class RateRamp(Effect):
    """IEEE Std 952 rate ramp R: a deterministic drift of the bias, δ = R (t − t₀) (rad/s², m/s³);
    σ_A(τ) = R τ/√2 (GMWM's "drift").  The wavelet variance sees R² only, so a fit gives |R|."""

    kind: ClassVar[str] = "rate_ramp"
    quantities: ClassVar[dict[str, str]] = {"gyro": "rate_ramp", "accelerometer": "acceleration_ramp"}
    param_fields: ClassVar[tuple[str, ...]] = ("value",)
    noise_parameters: ClassVar[tuple[str, ...]] = ("value",)
    value: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self) -> None:
        object.__setattr__(self, "value", _vec(self.value, name="rate ramp"))

    def delta(self, x, ctx, rng=None):
        return (ctx.t_s - ctx.t_s[0])[:, None] * self.value[None, :]

    def sensitivity(self, x, ctx):
        return (ctx.t_s - ctx.t_s[0])[:, None, None] * np.eye(3)[None]

    def haar_wavelet_variance(self, m, dt_s):
        # a line of slope RΔt per sample: (S₂ − S₁)/(2m) = RΔt m/2
        m = np.asarray(m, float)[None, :]
        return (self.value**2 * dt_s**2)[:, None] * m * m / 4

    def discrete_psd(self, f_cyc, dt_s):
        return np.zeros((3, np.size(f_cyc)))  # deterministic: adds nothing to the estimator's variance


# ================================================================ output-stage effects
@dataclass(frozen=True)
class Bandwidth(Effect):
    """First-order low-pass of the sensor output (its digital low-pass filter), exact
    discretisation y_k = a y_{k−1} + (1 − a) u_k, a = exp(−2π f_c Δt), started at steady state
    (y_0 = u_0).  Inverse: u_k = (y_k − a y_{k−1}) / (1 − a), exact."""

    kind: ClassVar[str] = "bandwidth"
    quantities: ClassVar[dict[str, str]] = {"gyro": "frequency", "accelerometer": "frequency",
                                            "magnetometer": "frequency"}
    stage: ClassVar[str] = "output"
    param_fields: ClassVar[tuple[str, ...]] = ("cutoff_hz",)
    cutoff_hz: float = 50.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.cutoff_hz) and self.cutoff_hz > 0):
            raise GyrosimError("bandwidth cutoff_hz must be > 0 Hz")

    def _a(self, ctx: SignalContext) -> float:
        return math.exp(-2 * math.pi * self.cutoff_hz * ctx.dt_s)

    def transform(self, y, ctx, rng=None):
        return kern.lowpass(np.ascontiguousarray(y), self._a(ctx))

    def inverse(self, y, ctx):
        a = self._a(ctx)
        u = np.empty_like(y)
        u[0] = y[0]
        u[1:] = (y[1:] - a * y[:-1]) / (1 - a)
        return u


@dataclass(frozen=True)
class TimeOffset(Effect):
    """Latency: the output at t is the input at t − d (d in s, may be fractional and negative),
    applied as a Fourier phase shift (band-limited interpolation; the record is treated as
    periodic, so start and end should be at rest).  Inverse: the shift by −d, exact.
    Linearised sensitivity ∂y/∂d = −ẋ."""

    kind: ClassVar[str] = "time_offset"
    quantities: ClassVar[dict[str, str]] = {"gyro": "time", "accelerometer": "time", "magnetometer": "time"}
    stage: ClassVar[str] = "output"
    param_fields: ClassVar[tuple[str, ...]] = ("delay_s",)
    delay_s: float = 0.0

    def __post_init__(self) -> None:
        if not math.isfinite(self.delay_s):
            raise GyrosimError("time_offset delay_s must be finite")

    @staticmethod
    def _shift(y: np.ndarray, d: float, dt: float) -> np.ndarray:
        """y(t − d) by multiplying the spectrum with e^{−i2πfd}.  For an even length the Nyquist
        bin cannot carry a phase in a real signal (irfft keeps its real part), so signals with
        energy at f_s/2 are not shifted exactly there; physical IMU signals have none."""
        n = y.shape[0]
        f = np.fft.rfftfreq(n, dt)
        spec = np.fft.rfft(y, axis=0) * np.exp(-2j * np.pi * f * d)[:, None]
        return np.fft.irfft(spec, n=n, axis=0)

    def transform(self, y, ctx, rng=None):
        return self._shift(y, self.delay_s, ctx.dt_s)

    def inverse(self, y, ctx):
        return self._shift(y, -self.delay_s, ctx.dt_s)

    def sensitivity(self, x, ctx):
        """∂y/∂d = −ẋ(t − d): the spectral derivative of the shifted input, (N, 3, 1)."""
        n = x.shape[0]
        f = np.fft.rfftfreq(n, ctx.dt_s)
        spec = np.fft.rfft(x, axis=0) * (-2j * np.pi * f * np.exp(-2j * np.pi * f * self.delay_s))[:, None]
        if n % 2 == 0:
            spec[-1] = 0.0  # the Nyquist bin has no real derivative
        return np.fft.irfft(spec, n=n, axis=0)[:, :, None]


@dataclass(frozen=True)
class Jitter(Effect):
    """Sample-time jitter: the sensor samples at t_k + ε_k, ε_k ~ N(0, σ²) (σ in s); the output
    is the signal interpolated there (cubic spline).  Random, not invertible."""

    kind: ClassVar[str] = "jitter"
    quantities: ClassVar[dict[str, str]] = {"gyro": "time", "accelerometer": "time", "magnetometer": "time"}
    stage: ClassVar[str] = "output"
    stochastic: ClassVar[bool] = True
    invertible: ClassVar[bool] = False
    param_fields: ClassVar[tuple[str, ...]] = ("sigma_s",)
    sigma_s: float = 0.0

    def transform(self, y, ctx, rng=None):
        rng = _need_rng(rng, self.kind)
        t = ctx.t_s
        eps = rng.standard_normal(t.shape) * self.sigma_s
        return CubicSpline(t, y, axis=0)(np.clip(t + eps, t[0], t[-1]))


@dataclass(frozen=True)
class Quantization(Effect):
    """Quantization to a least significant bit: y = LSB · round(y / LSB).  Deterministic but
    information-losing: compensation leaves it (error ≤ LSB/2, RMS LSB/√12)."""

    kind: ClassVar[str] = "quantization"
    quantities: ClassVar[dict[str, str]] = {"gyro": "rate", "accelerometer": "acceleration",
                                            "magnetometer": "magnetic_field"}
    pointwise: ClassVar[bool] = True
    stage: ClassVar[str] = "output"
    invertible: ClassVar[bool] = False
    param_fields: ClassVar[tuple[str, ...]] = ("lsb",)
    lsb: np.ndarray = field(default_factory=lambda: np.full(3, 1e-6))

    def __post_init__(self) -> None:
        v = _vec(self.lsb, name="LSB")
        if np.any(v <= 0):
            raise GyrosimError("quantization lsb must be > 0")
        object.__setattr__(self, "lsb", v)

    def transform(self, y, ctx, rng=None):
        return kern.quantize(np.ascontiguousarray(y), self.lsb)

    def inverse(self, y, ctx):
        return y


@dataclass(frozen=True)
class Saturation(Effect):
    """Output clipped to ±range.  Compensation cannot recover clipped samples: it raises
    (:meth:`check`) naming how many samples sit at the rails."""

    kind: ClassVar[str] = "saturation"
    quantities: ClassVar[dict[str, str]] = {"gyro": "rate", "accelerometer": "acceleration",
                                            "magnetometer": "magnetic_field"}
    pointwise: ClassVar[bool] = True
    stage: ClassVar[str] = "output"
    invertible: ClassVar[bool] = False
    param_fields: ClassVar[tuple[str, ...]] = ("range",)
    range: np.ndarray = field(default_factory=lambda: np.full(3, np.inf))

    def __post_init__(self) -> None:
        v = np.array(self.range, dtype=float).reshape(-1)
        v = np.full(3, v[0]) if v.size == 1 else v
        if v.size != 3 or np.any(np.isnan(v)) or np.any(v <= 0):
            raise GyrosimError("saturation range must be 3 positive values")
        object.__setattr__(self, "range", v)

    def transform(self, y, ctx, rng=None):
        return kern.saturate(np.ascontiguousarray(y), self.range)

    def saturated(self, y: np.ndarray) -> np.ndarray:
        return np.abs(y) >= self.range * (1 - 1e-12)

    def inverse(self, y, ctx):
        bad = self.saturated(y)
        if bad.any():
            raise GyrosimError(
                f"{int(bad.any(axis=1).sum())} sample(s) sit at the ±{self.range.tolist()} rails (saturated): "
                "their true value is unknown; exclude them before calibrating"
            )
        return y


EFFECTS: dict[str, type[Effect]] = {
    cls.kind: cls
    for cls in (
        Bias, ScaleFactor, NonOrthogonality, Misalignment, ScaleNonlinearity, GSensitivity,
        TemperatureBias, TemperatureScale, ThermalHysteresis, TemperaturePiecewise, TemperatureRBF, EarthRate,
        MagneticSensitivity, HardIron, SoftIron, FrameRotation,
        WhiteNoise, BiasInstability, RandomWalk, GaussMarkov, QuantizationNoise, RateRamp, Bandwidth, TimeOffset, Jitter, Quantization, Saturation,
    )
}


def effect_from_dict(d: dict[str, Any]) -> Effect:
    """Rebuild an effect from :meth:`Effect.to_dict` output (SI values)."""
    d = dict(d)
    kind = d.pop("effect", None)
    if kind not in EFFECTS:
        raise GyrosimError(f"unknown effect {kind!r}; known: {', '.join(EFFECTS)}")
    cls = EFFECTS[kind]
    names = {f.name for f in fields(cls)}
    bad = set(d) - names
    if bad:
        raise GyrosimError(f"effect {kind!r}: unknown key(s) {sorted(bad)}; allowed: {sorted(names)}")
    if "range_c" in d:
        d["range_c"] = tuple(d["range_c"])
    return cls(**d)
