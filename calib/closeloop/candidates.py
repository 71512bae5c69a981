"""Candidate effects from the shared vocabulary (``gyrosim.effects.EFFECTS``) as regressors.

A candidate is an effect of the gyro triad whose output change is linear in its parameters at
the null point: R(t) = ∂y/∂θ (N, 3, P) from the effect's own :meth:`Effect.sensitivity`,
evaluated on the reference rate (body frame, rad/s) and the recording's context (specific force,
temperature, attitude body→ENU, magnetic field).  The fitted θ is turned back into the same
effect class with :meth:`Effect.with_params`, so what the loop finds can be injected by the
simulator unchanged.

Two vocabulary entries need a parameterisation that is linear at the null point:

* ``earth_rate``: δ = C_nᵇ ω_ieⁿ is fitted as the 3-vector ω_ieⁿ (ENU); latitude
  L = atan2(ω_U, ω_N) and |ω_ie| (7.29e-5 rad/s on Earth) are reported from it.
* ``random_walk`` (bias drift, also standing for ``bias_instability``: on one recording the two
  only differ in the spectrum of the same slow bias): a piecewise-linear bias with knots every
  ``drift_knot_s``; its random-walk coefficient K is estimated afterwards by maximum likelihood
  (:func:`calib.closeloop.drift.random_walk_mle`).

Effects that are not parameters of a deterministic term say why (:data:`NOT_CANDIDATES`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Callable

import numpy as np

from gyrosim.effects import (EARTH_RATE_RAD_S, EFFECTS, Bias, Effect, EarthRate, GSensitivity, MagneticSensitivity,
                             Misalignment, NonOrthogonality, RandomWalk, ScaleFactor, ScaleNonlinearity, SignalContext,
                             TemperatureBias, TemperaturePiecewise, TemperatureRBF, TemperatureScale,
                             ThermalHysteresis, TimeOffset)
from gyrosim.rotations import quat_conjugate, quat_rotate

DIMENSIONLESS = ("scale_factor", "nonorthogonality", "misalignment")
DIMENSIONLESS_BOUND = 0.3

__all__ = ["Candidate", "build_candidate", "candidate_kinds", "NOT_CANDIDATES"]

NOT_CANDIDATES = {
    "white_noise": "the noise floor itself: its level is the held-out residual the loop reports, not a term to fit",
    "jitter": "random sampling-time error: checked as residual variance growing with |dω/dt|² (structure tests)",
    "bias_instability": "tested together with random_walk as 'bias drift' (one slow bias; one recording cannot "
                        "separate the two spectra reliably)",
    "bandwidth": "a first-order low-pass equals a time offset d = 1/(2π f_c) to first order in f/f_c; tested as "
                 "time_offset, whose equivalent cutoff is reported",
    "quantization": "not a residual term (RMS LSB/√12): detected from the output's granularity (checks)",
    "saturation": "not a residual term: detected as samples at the rails (checks)",
}


@dataclass(frozen=True)
class Candidate:
    """One effect as columns of the design: what it is, its regressors, how to make the effect."""

    effect: str                              # vocabulary kind
    regressors: np.ndarray                   # (N, 3, P) ∂y/∂θ, rad/s per parameter unit
    param_names: tuple[str, ...]
    to_effect: Callable[[np.ndarray], Effect]
    follows: str                             # what the residual follows, in words
    follows_series: np.ndarray               # (N, 3) the regressor signal, for plots
    implausible: Callable[[np.ndarray], str | None] | None = None  # physics check of fitted θ

    def check(self, theta: np.ndarray) -> str | None:
        """Why fitted parameters cannot be this effect (None: plausible)."""
        if self.effect in DIMENSIONLESS and np.any(np.abs(theta) >= 0.99 * DIMENSIONLESS_BOUND):
            return (f"fitted {self.effect} reaches ±{DIMENSIONLESS_BOUND:g} (a {DIMENSIONLESS_BOUND * 100:.0f} % axis error): "
                    "not a sensor defect but a different solution of the self-consistency equations")
        return self.implausible(theta) if self.implausible is not None else None

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Box for a nonlinear fit: dimensionless axis errors within ±DIMENSIONLESS_BOUND (a real
        scale or axis error is a few %; the pose-to-pose equations have far-away spurious solutions)."""
        b = DIMENSIONLESS_BOUND if self.effect in DIMENSIONLESS else np.inf
        return np.full(self.n_params, -b), np.full(self.n_params, b)

    @property
    def n_params(self) -> int:
        return self.regressors.shape[2]


def _null_candidate(proto: Effect, ctx: SignalContext, follows: str, series: np.ndarray) -> Candidate:
    x = ctx.omega_true_rad_s
    reg = np.asarray(proto.sensitivity(x, ctx), dtype=float)
    return Candidate(proto.kind, reg, tuple(proto.param_names()), proto.with_params, follows, series)


def _earth_rate(ctx: SignalContext) -> Candidate:
    q = ctx.quat_nb
    reg = np.stack([quat_rotate(quat_conjugate(q), np.broadcast_to(e, (q.shape[0], 3))) for e in np.eye(3)], axis=2)

    def to_effect(theta: np.ndarray) -> Effect:
        return EarthRate(latitude_rad=float(math.atan2(theta[2], theta[1])))

    def implausible(theta: np.ndarray) -> str | None:
        ratio = float(np.linalg.norm(theta)) / EARTH_RATE_RAD_S
        if not 0.5 <= ratio <= 1.5:
            return (f"the rate fixed in ENU is {ratio:.2g} × the Earth rate: not the Earth's rotation (something "
                    "else that follows the attitude, e.g. gravity or the magnetic field)")
        return None

    return Candidate("earth_rate", reg, ("earth_rate.omega_ie_enu[0]", "earth_rate.omega_ie_enu[1]",
                                         "earth_rate.omega_ie_enu[2]"), to_effect,
                     "the attitude (a constant rate fixed in the ENU frame)", reg[:, :, 2], implausible)


def _bias_drift(ctx: SignalContext, knot_s: float) -> Candidate:
    t = ctx.t_s
    span = t[-1] - t[0]
    k = min(max(2, int(math.ceil(span / knot_s)) + 1), 41)  # ≤ 40 intervals: long records get longer ones
    knots = np.linspace(t[0], t[-1], k)
    hats = np.stack([np.interp(t, knots, np.eye(k)[j]) for j in range(k)], axis=1)  # (N, k)
    reg = np.zeros((t.size, 3, 3 * k))
    for i in range(3):
        reg[:, i, i * k : (i + 1) * k] = hats
    names = tuple(f"random_walk.knot[{i}][{j}]" for i in range(3) for j in range(k))

    def to_effect(theta: np.ndarray) -> Effect:  # K is set by the maximum-likelihood step afterwards
        return RandomWalk(value=np.zeros(3))

    return Candidate("random_walk", reg, names, to_effect, f"time (piecewise-linear bias, knots every {knots[1] - knots[0]:.0f} s)",
                     np.broadcast_to(t[:, None], (t.size, 3)))


def _temperature_range(ctx: SignalContext) -> tuple[float, tuple[float, float]]:
    temp = ctx.temperature_c
    return float(np.mean(temp)), (float(np.min(temp)) - 1.0, float(np.max(temp)) + 1.0)


def build_candidate(kind: str, ctx: SignalContext, *, drift_knot_s: float = 20.0,
                    modelled_rate: np.ndarray | None = None) -> Candidate | str:
    """The candidate for vocabulary ``kind`` on this context, or the reason it cannot be tested.

    ``modelled_rate``: for output-stage effects (time offset), the sensor's error-stage output
    (I + S + N) ω + b of the current model, which is what the output stage delays; without it the
    delay would absorb the scale factor (d̂ = d (1 + s)) and leave N ω̇ in the residual."""
    if kind == "time_offset" and modelled_rate is not None:
        ctx = replace(ctx, omega_true_rad_s=modelled_rate)
    if kind in NOT_CANDIDATES:
        return NOT_CANDIDATES[kind]
    if kind not in EFFECTS:
        return f"not in the effect vocabulary (known: {', '.join(EFFECTS)})"
    if "gyro" not in EFFECTS[kind].triads:
        return "not an effect of the gyro triad"
    w = ctx.omega_true_rad_s
    dw = np.gradient(w, ctx.t_s, axis=0)
    simple: dict[str, tuple[Callable[[], Effect], str, np.ndarray]] = {
        "bias": (Bias, "a constant", np.ones_like(w)),
        "scale_factor": (ScaleFactor, "the rate on the same axis", w),
        "nonorthogonality": (NonOrthogonality, "the rate on the other axes (symmetric)", w),
        "misalignment": (Misalignment, "the rate on the other axes", w),
        "scale_nonlinearity": (ScaleNonlinearity, "ω·|ω| on the same axis", w * np.abs(w)),
        "time_offset": (TimeOffset, "dω/dt", dw),
        "g_sensitivity": (GSensitivity, "the specific force", ctx.specific_force_true_m_s2),
    }
    if kind in simple:
        make, follows, series = simple[kind]
        return _null_candidate(make(), ctx, follows, series)
    if kind == "magnetic_sensitivity":
        if ctx.mag_body_ut is None:
            return "the recording has no magnetometer channel"
        return _null_candidate(MagneticSensitivity(), ctx, "the magnetic field", ctx.mag_body_ut)
    if kind in ("temperature_bias", "temperature_scale", "thermal_hysteresis", "temperature_pwl", "temperature_rbf"):
        if ctx.temperature_c is None:
            return "the recording has no temperature channel"
        span = float(np.ptp(ctx.temperature_c))
        if span < 0.5:
            return f"temperature span {span:.2f} °C is too small to fit a temperature term (needs ≥ 0.5 °C)"
        t_ref, rng = _temperature_range(ctx)
        lo, hi = float(np.min(ctx.temperature_c)), float(np.max(ctx.temperature_c))
        temp_series = np.broadcast_to((ctx.temperature_c - t_ref)[:, None], w.shape)
        if kind == "temperature_pwl":  # seed 001: values at 5 temperature points, linear between
            proto = TemperaturePiecewise(points_c=np.linspace(lo, hi, 5), bias=np.zeros((3, 5)), scale=np.zeros((3, 5)))
            return _null_candidate(proto, ctx, "the temperature (piecewise linear)", temp_series)
        if kind == "temperature_rbf":  # seed 003: Gaussian RBF on ΔT and ΔT², 6 centres
            centres = np.linspace(lo, hi, 6)
            proto = TemperatureRBF(centres_c=centres, width_c=float(centres[1] - centres[0]), t_ref_c=t_ref,
                                   weights=np.zeros((3, 6)))
            return _null_candidate(proto, ctx, "the temperature (RBF of ΔT, ΔT²)", temp_series)
        if kind == "thermal_hysteresis":
            proto = ThermalHysteresis(tau_s=300.0)
            return _null_candidate(proto, ctx, "the low-passed temperature rate dT/dt",
                                   np.broadcast_to(proto.regressor(ctx)[:, None], w.shape))
        cls = TemperatureBias if kind == "temperature_bias" else TemperatureScale
        proto = cls(coefficients=np.zeros((3, 1)), t_ref_c=t_ref, range_c=rng)
        temp = np.broadcast_to((ctx.temperature_c - t_ref)[:, None], w.shape)
        return _null_candidate(proto, ctx, "the temperature" if kind == "temperature_bias" else "temperature × rate",
                               temp if kind == "temperature_bias" else temp * w)
    if kind == "earth_rate":
        if ctx.quat_nb is None:
            return "needs an attitude (truth or optical orientation) to project the Earth rate"
        return _earth_rate(ctx)
    if kind == "random_walk":
        return _bias_drift(ctx, drift_knot_s)
    return "no parameterisation for the loop yet"


def candidate_kinds() -> list[str]:
    """Every gyro-triad kind of the vocabulary, in vocabulary order."""
    return [k for k, cls in EFFECTS.items() if "gyro" in cls.triads]


def earth_rate_summary(theta: np.ndarray) -> dict[str, float]:
    """Latitude (°) and |ω_ie| relative to the WGS-84 value from the fitted ENU vector."""
    return {"latitude_deg": math.degrees(math.atan2(theta[2], theta[1])),
            "magnitude_over_wgs84": float(np.linalg.norm(theta) / EARTH_RATE_RAD_S)}
