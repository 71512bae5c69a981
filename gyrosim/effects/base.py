"""The base of every effect: the signal context, the :class:`Effect` interface and the registry.

An effect class registers itself by being defined: a subclass that declares its own ``kind``
enters :data:`EFFECTS` (``kind`` → class) in definition order, so no other module lists effect
names.  Everything the rest of the code asks of an effect kind is a class attribute here:

* ``quantities``: triad → unit quantity of the main parameter (:data:`gyrosim.units.QUANTITIES`);
  its keys are the triads the effect applies to (``triads``), how a preset in datasheet units is
  read (:meth:`Effect.preset_to_si`);
* ``display_units``: triad → (factor, unit) that turns the SI parameters into the unit a report
  shows (x_display = factor · x_SI);
* ``stage``, ``stochastic``, ``invertible``, ``pointwise``: how a sensor model simulates and
  compensates it;
* ``is_white_noise``: the triad's white measurement noise (its density sets the noise floor that
  slow processes are drawn against, and the sensor-only noise a campaign keeps);
* ``candidate``: whether the closed loop may propose it as a term of the gyro model, with
  :meth:`Effect.candidate_prototype` and :meth:`Effect.candidate_regressor` building its
  regressor R = ∂y/∂θ (N, 3, P) from the recording's context alone (numpy only: calib
  discovers it, gyrosim imports nothing from calib).
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace
from typing import Any, ClassVar

import numpy as np

from ..errors import GyrosimError
from ..units import to_si

__all__ = ["SignalContext", "Effect", "VectorEffect", "EFFECTS", "effect_from_dict", "unregister_effect",
           "zeros_field"]

EFFECTS: dict[str, type["Effect"]] = {}  # kind → class, filled by Effect.__init_subclass__ in definition order


# ``quantities`` of an effect that any triad can carry (noise terms, output stage)
ANY_TRIAD: dict[str, str] = {"gyro": "rate", "accelerometer": "acceleration", "magnetometer": "magnetic_field"}


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
    # triad → (factor, unit) of a report: x_display = factor · x_SI (the parameters' own SI unit if absent)
    display_units: ClassVar[dict[str, tuple[float, str]]] = {}
    is_white_noise: ClassVar[bool] = False  # the triad's white measurement noise (``density``)
    # the closed loop may propose it as a gyro term; None → every deterministic error-stage gyro effect
    candidate: ClassVar[bool | None] = None
    # a non-candidate: why the loop fits no term for it and how it is covered instead ("" → a general reason)
    closeloop_reason: ClassVar[str] = ""
    # the effect turns the sensor's axes (its axis matrix has a rotation part): a rotation of the
    # reference's body frame against the IMU frame looks like it, on every sensor alike
    axis_rotation: ClassVar[bool] = False

    def __init_subclass__(cls, **kwargs: Any) -> None:
        """Derive ``triads`` and ``candidate``, and register a class that declares its own ``kind``."""
        super().__init_subclass__(**kwargs)
        cls.triads = tuple(cls.quantities)
        if "candidate" not in cls.__dict__:
            cls.candidate = "gyro" in cls.triads and not cls.stochastic and cls.stage == "error"
        kind = cls.__dict__.get("kind")
        if not kind:
            return
        old = EFFECTS.get(kind)
        if old is not None and (old.__module__, old.__qualname__) != (cls.__module__, cls.__qualname__):
            raise GyrosimError(f"effect kind {kind!r} is defined twice: {old.__module__}.{old.__qualname__} and "
                               f"{cls.__module__}.{cls.__qualname__}; give the new class another kind")
        EFFECTS[kind] = cls  # (a module reloaded re-registers its own class)

    # ---------------------------------------------------------------- what the rest of the code asks
    @classmethod
    def display_unit(cls, triad: str = "gyro") -> tuple[float, str]:
        """(factor, unit) that shows this effect's SI parameters on ``triad`` in a report."""
        return cls.display_units.get(triad, (1.0, "SI"))

    @classmethod
    def preset_to_si(cls, raw: dict[str, Any], unit: str, quantity: str) -> dict[str, Any]:
        """The keys of a preset table (datasheet ``unit`` of the main parameter, its ``quantity``)
        converted to SI: the main parameter and its ``_sigma`` (:func:`gyrosim.units.to_si`).
        Effects with preset keys of their own override it (and call this)."""
        raw = dict(raw)
        main = cls.param_fields[0]
        for key in (main, f"{main}_sigma"):
            if key in raw:
                v = np.asarray(raw[key], dtype=float)
                raw[key] = np.asarray(to_si(v.ravel().tolist(), unit, quantity)).reshape(v.shape)
        return raw

    @classmethod
    def candidate_prototype(cls, ctx: "SignalContext") -> "Effect":
        """The effect at its null point, shaped for this recording, whose sensitivity is the closed
        loop's regressor (default: the default-constructed effect)."""
        return cls()

    @classmethod
    def candidate_regressor(cls, ctx: "SignalContext") -> tuple["Effect", np.ndarray]:
        """(prototype, R) with R = ∂y/∂θ (N, 3, P) at the prototype, evaluated on the reference rate
        ``ctx.omega_true_rad_s`` (rad/s, body RFU) and the recording's context."""
        proto = cls.candidate_prototype(ctx)
        return proto, np.asarray(proto.sensitivity(ctx.omega_true_rad_s, ctx), dtype=float)

    # ---------------------------------------------------------------- parameters
    def params(self) -> np.ndarray:
        """Flat parameter vector θ (SI), in ``param_fields`` order."""
        if not self.param_fields:
            return np.zeros(0)
        return np.concatenate(
            [np.atleast_1d(np.asarray(getattr(self, f), dtype=float)).ravel() for f in self.param_fields]
        )

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
    noise_short_name: ClassVar[str] = ""  # the term in a model name ("white+flicker+rw")
    noise_bias_drift: ClassVar[bool] = False  # a slow bias drift: a temperature trend over a record reads as it
    noise_rank: ClassVar[int] = 0         # a model lists its terms by rank (the shortest τ they dominate first)
    # triad → unit of the noise parameter in SI, and in the datasheet unit a summary shows (``noise_units`` keys)
    noise_si_units: ClassVar[dict[str, str]] = {}
    noise_datasheet_units: ClassVar[dict[str, str]] = {}

    @classmethod
    def noise_unit(cls, field: str, triad: str, *, datasheet: bool = False) -> str:
        """Unit of the noise parameter ``field`` on ``triad`` (SI, or the datasheet unit); a correlation
        time is in s."""
        if field == "tau_s":
            return "s"
        return (cls.noise_datasheet_units if datasheet else cls.noise_si_units).get(triad, "SI")

    @classmethod
    def noise_units(cls, field: str, value: float, rate_hz: float, triad: str) -> dict[str, float]:
        """{unit label: value} of one identified noise parameter (SI ``value``) in the units users
        need: the continuous and discrete (per sample at ``rate_hz``) forms and the datasheet unit
        (gyro units for ``triad == 'gyro'``, accelerometer units otherwise)."""
        return {"si": value}

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

    def noise_model_term(self) -> "Effect":
        """The term a stochastic-model fit (calib.noise) describes this effect by: itself, unless the
        same process has a kind of its own (a Gauss–Markov ``bias_instability``)."""
        return self

    def sample_noise_variance(self, rate_hz: float) -> np.ndarray | None:
        """Variance per sample (3,) this effect adds to the output as white noise at the sample rate
        ``rate_hz`` (N² f_s for white noise, LSB²/12 for rounding); None if it adds none."""
        return None

    def ieee952_terms(self) -> dict[str, np.ndarray]:
        """The effect's share of the IEEE Std 952 three-term noise model, per axis (SI):
        ``arw`` N (white: σ_A = N/√τ), ``bias_instability`` B (flicker: σ_A = 0.664 B),
        ``rate_random_walk`` K (Wiener: σ_A = K√(τ/3)).  {} for everything else, so a caller
        (e.g. the covariance of window means in calib.noise.window_means) can sum over a triad's effects
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


def diagonal_jacobian(per_axis: np.ndarray) -> np.ndarray:
    """(N, 3) → (N, 3, 3) with ``per_axis`` on each sample's diagonal, zero elsewhere: the Jacobian (∂δ/∂x or
    ∂δ/∂θ) of an effect whose axes act each on their own."""
    d = np.asarray(per_axis, dtype=float)
    out = np.zeros(d.shape + (3,))
    axes = np.arange(3)
    out[:, axes, axes] = d
    return out


def zeros_field(*shape: int) -> Any:
    """A dataclass field defaulting to a fresh zero array of ``shape``."""
    return field(default_factory=lambda: np.zeros(shape))


def _check_invertible(m: np.ndarray, kind: str, value: np.ndarray) -> None:
    """(I + N) must stay a proper, well-conditioned axis set: det > 0.1 and cond < 100."""
    det = float(np.linalg.det(m))
    if not det > 0.1 or np.linalg.cond(m) > 100:
        raise GyrosimError(
            f"{kind} {np.round(value, 6).tolist()} makes the axis matrix singular or flips an axis "
            f"(det(I + N) = {det:.3g}); real non-orthogonality is a few 1e-2 at most: check units (% vs fraction)"
        )



@dataclass(frozen=True)
class VectorEffect(Effect):
    """An effect with one parameter vector ``value`` (``size`` values) and its unit-to-unit spread
    ``value_sigma`` (drawn by :meth:`Effect.realize`), both finite; ``labels`` name them in errors.
    Subclasses declare ``kind`` and their δ; ``check`` adds their own constraint."""

    param_fields: ClassVar[tuple[str, ...]] = ("value",)
    size: ClassVar[int] = 3
    labels: ClassVar[tuple[str, str]] = ("parameter", "parameter sigma")
    value: np.ndarray = zeros_field(3)
    value_sigma: np.ndarray = zeros_field(3)

    def __post_init__(self) -> None:
        object.__setattr__(self, "value", _vec(self.value, self.size, self.labels[0]))
        object.__setattr__(self, "value_sigma", _vec(self.value_sigma, self.size, self.labels[1]))
        self.check()

    def check(self) -> None:
        """Raise :class:`GyrosimError` when ``value`` is not a valid parameter (default: any finite)."""


def _matrix(v: Any, name: str) -> np.ndarray:
    a = np.array(v, dtype=float)
    a = np.diag(a) if a.shape == (3,) else a.reshape(3, 3) if a.size == 9 else a
    if a.shape != (3, 3) or not np.all(np.isfinite(a)):
        raise GyrosimError(f"{name} must be a finite 3×3 matrix (or 3 diagonal values), got shape {np.shape(v)}")
    return a



def _need_rng(rng: np.random.Generator | None, kind: str) -> np.random.Generator:
    if rng is None:
        raise GyrosimError(f"{kind} is random: pass a numpy.random.Generator (rng=...)")
    return rng



def unregister_effect(kind: str) -> None:
    """Remove ``kind`` from the registry (a test's toy effect, when the test is done)."""
    EFFECTS.pop(kind, None)


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
