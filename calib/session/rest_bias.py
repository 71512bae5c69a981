"""The gyro bias a hand-held session's first rest gives, at a stated reference, with an honest σ.

A hand never holds the sensor still: over a "rest" [t₀, t₀ + T] it turns by a small, real attitude change
Δθ (tremor 8–12 Hz, sway 0.2–1 Hz), which the gyro measures truthfully.  The rest's mean is therefore

    ω̄ = b(t_r, T_r, f_r) + Δθ/T + n̄,      n̄ ~ N(0, N_g²/T)  (white noise, N_g the ARW in rad/s/√Hz),

exactly (the integral of the body rate is the attitude change, to first order in the small rotation).  The
mean is the estimate; its error is Δθ/T + n̄.  The 10-batch-means standard error that the paper's static
average uses (Zhou 2020 eq. 3, :func:`calib.session.rest.static_bias`) counts the rotation *inside* each batch as
noise, which cancels in the whole mean: with a shaky hand it overstated σ up to ×10 (Monte Carlo, consumer
sensor, err/σ RMS 0.07–0.2).

σ from the model (per body axis):

    σ_b² = N_g²/T + Var(Δθ)/T²,     Var(Δθ) = 2 σ_θ²   (Δθ = θ(t₀+T) − θ(t₀), stationary wander, correlation ≪ T),

σ_θ² the attitude wander's variance, measured on the rest itself: the de-meaned integral of the de-meaned
rate, c(t) = ∫_{t₀}^{t} (ω − ω̄) dt − ⟨·⟩, is the attitude minus its mean and minus the bridge (t/T − ½)Δθ, so
E⟨c²⟩ = σ_θ² + Var(Δθ)/12 + N_g² T/12 (the last term: a Brownian bridge's de-meaned variance, white gyro noise
integrated).  Hence σ_θ² = (6/7)(⟨c²⟩ − N_g² T/12) and Var(Δθ) = (12/7)(⟨c²⟩ − N_g² T/12), floored at 0.  N_g
is the white density measured above the tremor band (:func:`calib.session.noiselevels.white_density`), never the rest's
spread.  Sources: the mean of a derivative is the end-point difference over T; Brownian-bridge moments
(e.g. Karatzas & Shreve, *Brownian Motion and Stochastic Calculus*, §5.6.B); the white-noise term is IEEE Std
952-1997 Annex C's ARW.  A slow turn during the rest (a ramp in attitude over ≳ T) looks like bias to this
estimate and to any gyro-only one.

**Reference.** The bias moves during a session: with temperature (the MPU-9250's ±0.24 °/s/°C ZRO) and with the specific
force (a gyro's g-sensitivity, 0.1 °/s/g: at a level rest the z axis reads b_z + k_z g) and by its own instability.  The
rest's mean is the bias *during that rest*: at time t_r (its middle), temperature T_r (its mean temperature, when the
recording has a temperature channel) and body specific force f_r (the accelerometer's mean over it, m/s², compensated
when the accelerometer is estimated).  That is what :class:`RestBias` reports and what a Monte Carlo must score it
against (:func:`calib.scoring.montecarlo.truth_bias_at_reference`): measured on the MPU-9250 (steady hand, 20 seeds) the
oracle's bias at 25 °C and zero specific force differs from it by k_z g on z (err/σ RMS 9.3 on z; 1.06 against the
device's bias at (T_r, f_r)).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class RestBias:
    """The gyro bias (rad/s, body RFU) as the mean over one rest, its σ (rad/s: white noise ⊕ the hand's
    rotation during the rest, module docstring) and the reference it holds at."""

    value_rad_s: np.ndarray
    std_rad_s: np.ndarray
    white_std_rad_s: np.ndarray
    rotation_std_rad_s: np.ndarray
    time_s: float
    duration_s: float
    temperature_c: float | None
    specific_force_m_s2: np.ndarray
    index_range: tuple[int, int]

    def to_dict(self) -> dict:
        return {"value_rad_s": self.value_rad_s.tolist(), "std_rad_s": self.std_rad_s.tolist(),
                "white_std_rad_s": self.white_std_rad_s.tolist(),
                "rotation_std_rad_s": self.rotation_std_rad_s.tolist(),
                "reference": "the mean over the first rest: the bias at reference_time_s, reference_temperature_c "
                             "and reference_specific_force_m_s2 (body); it moves with temperature, specific force "
                             "(g-sensitivity) and time (gyro_bias_drift)",
                "reference_time_s": self.time_s, "rest_duration_s": self.duration_s,
                "reference_temperature_c": self.temperature_c,
                "reference_specific_force_m_s2": self.specific_force_m_s2.tolist(),
                "rest_index_range": list(self.index_range)}


def rest_bias(gyro_rad_s: np.ndarray, t_s: np.ndarray, index_range: tuple[int, int], arw_rad_s_sqrt_hz: float,
              specific_force_m_s2: np.ndarray, temp_c: np.ndarray | None = None) -> RestBias:
    """The bias over the rest ``index_range`` = [a, b) (module docstring): ``gyro_rad_s`` (N, 3), ``t_s`` (N,),
    ``arw_rad_s_sqrt_hz`` the gyro's white density, ``specific_force_m_s2`` (N, 3) the (compensated)
    accelerometer, ``temp_c`` (N,) the sensor temperature or None."""
    a, b = index_range
    if b - a < 4:
        raise ValueError(f"rest_bias: the rest [{a}, {b}) has fewer than 4 samples")
    w = np.asarray(gyro_rad_s[a:b], float)
    t = np.asarray(t_s[a:b], float)
    dt = float(np.median(np.diff(t)))
    T = float(t[-1] - t[0]) + dt                        # b − a samples of dt each
    mean = w.mean(axis=0)
    c = np.cumsum(w - mean, axis=0) * dt
    c -= c.mean(axis=0)
    excess = np.maximum(np.mean(c**2, axis=0) - arw_rad_s_sqrt_hz**2 * T / 12.0, 0.0)
    var_dtheta = (12.0 / 7.0) * excess
    white = np.full(3, arw_rad_s_sqrt_hz / math.sqrt(T))
    rot = np.sqrt(var_dtheta) / T
    t_ref = None
    if temp_c is not None:
        tc = np.asarray(temp_c[a:b], float)
        if np.all(np.isfinite(tc)):
            t_ref = float(tc.mean())
    return RestBias(mean, np.sqrt(white**2 + rot**2), white, rot, 0.5 * float(t[0] + t[-1]), T, t_ref,
                    np.asarray(specific_force_m_s2[a:b], float).mean(axis=0), (int(a), int(b)))
