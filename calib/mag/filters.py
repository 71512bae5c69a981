"""The in-motion compensation of the compass heading of *Soft Magnetic Error Compensation Method of Electronic
Compass*: Kalman filter, Sage–Husa adaptive Kalman filter and
particle filter ("Soft Magnetic Error Compensation Method of Electronic Compass", §2.1–2.3), each one class, discovered
through :data:`HEADING_FILTERS`.

The application note treats the soft-iron error as random noise on the compass output and smooths it.  Two
process models, the same for all three filters:

* ``seed`` — the application note's form: the heading is a random walk, ψ_{k+1} = ψ_k + w_k, Var w = q Δt;
  the filter only smooths the measured heading;
* ``gyro`` — the gyro carries the heading between compass samples:
  ψ_{k+1} = ψ_k + Δψ_k − b Δt + w_k,  b_{k+1} = b_k + v_k, with Δψ_k the heading increment of the
  gyro's rotation (:func:`calib.mag.compare.gyro_heading_increments`), b the gyro's bias about
  the vertical (random walk), Var w = N² Δt (N the gyro's angle random walk).

Measurement: z_k = ψ_k + ε_k, the compass heading (wrapped: the innovation is taken modulo 2π),
Var ε = R.

* **KF** (Kalman 1960; filterpy's ``KalmanFilter`` equations, written out for 1–2 states):
  x⁻ = F x + u, P⁻ = F P Fᵀ + Q; ν = wrap(z − H x⁻), S = H P⁻ Hᵀ + R, K = P⁻Hᵀ/S,
  x = x⁻ + K ν, P = (I − K H) P⁻ (Joseph form).
* **AKF** — Sage & Husa (1969) with a forgetting factor b (the "improved Sage–Husa" filter of the
  seed's §2.2): d_k = (1 − b)/(1 − b^{k+1}), R_k = (1 − d_k) R_{k−1} + d_k (ν_k² − H P⁻ Hᵀ); when
  that would go below R_min the subtraction is dropped (R_k = (1 − d_k) R_{k−1} + d_k ν_k²), the
  usual fix that keeps R positive (the loss of positivity the note warns about).
* **PF** — bootstrap particle filter (Gordon, Salmond & Smith 1993): particles drawn from the
  process model, weights ∝ a Student-t likelihood (ν = 4, scale √R) of the wrapped innovation —
  heavy-tailed, so that a compass reading many σ off every particle (a soft-iron error ≫ the
  noise) still ranks them by distance instead of zeroing every weight —, systematic resampling when the
  effective sample size drops below half, followed by roughening (Gordon et al. §3.3: jitter
  K·E·m^(−1/d), K = 0.2, E the cloud's extent); estimate = circular weighted mean.  Random draws from
  the ``numpy.random.Generator`` the caller passes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np

from calib.mag.heading import wrap_pi

__all__ = ["HeadingFilter", "KalmanHeading", "SageHusaHeading", "ParticleHeading", "HEADING_FILTERS",
           "FilterSettings"]


@dataclass(frozen=True)
class FilterSettings:
    """Noise levels of the heading filters (SI: rad, rad/s)."""

    meas_var_rad2: float  # R: the compass heading's noise variance
    process: str = "gyro"  # "gyro" or "seed"
    arw_rad_s_sqrt_hz: float = math.radians(0.01)  # N of the gyro about the vertical
    bias_walk_rad_s2_sqrt_hz: float = 1e-5  # bias random walk (rad/s/√s)
    seed_walk_rad2_s: float = math.radians(5.0) ** 2  # q of the random-walk heading (seed form), rad²/s
    forgetting: float = 0.98  # Sage–Husa b
    particles: int = 500


STUDENT_NU = 4.0  # degrees of freedom of the PF's Student-t likelihood
INIT_SPREAD_RAD = math.radians(5.0)  # the PF's initial heading spread: a compass's first reading is no better


class HeadingFilter:
    """A heading filter: :meth:`run` → the filtered heading (rad) per sample."""

    name: ClassVar[str] = ""
    description: ClassVar[str] = ""

    def run(self, z: np.ndarray, dpsi: np.ndarray | None, dt: np.ndarray, s: FilterSettings,
            rng: np.random.Generator | None = None) -> np.ndarray:
        raise NotImplementedError


def _model(s: FilterSettings, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """(F, Q) of the process model for one step."""
    if s.process == "seed":
        return np.array([[1.0]]), np.array([[s.seed_walk_rad2_s * dt]])
    f = np.array([[1.0, -dt], [0.0, 1.0]])
    q = np.diag([s.arw_rad_s_sqrt_hz**2 * dt, s.bias_walk_rad_s2_sqrt_hz**2 * dt])
    return f, q


class KalmanHeading(HeadingFilter):
    """The Kalman filter of the heading (module docstring, **KF**): the state is ψ (rad), plus the gyro's
    bias about the vertical (rad/s) under the ``gyro`` process model."""

    name = "kf"
    description = "Kalman filter (§2.1 of the electronic-compass note)"
    adaptive: ClassVar[bool] = False

    def run(self, z, dpsi, dt, s, rng=None):
        gyro = s.process == "gyro" and dpsi is not None
        n = z.size
        dim = 2 if gyro else 1
        x = np.zeros(dim)
        x[0] = z[0]
        p = np.diag([s.meas_var_rad2] + ([1e-4] if gyro else []))
        r = s.meas_var_rad2
        r_min = 1e-6 * s.meas_var_rad2
        b = s.forgetting
        out = np.empty(n)
        out[0] = x[0]
        mode = s if gyro else replace(s, process="seed")
        for k in range(1, n):
            f, q = _model(mode, float(dt[k - 1]))
            x = f @ x                                    # x⁻ = F x (+ u)
            if gyro:
                x[0] += dpsi[k - 1]                      #   u = Δψ (gyro heading increment)
            p = f @ p @ f.T + q                          # P⁻ = F P Fᵀ + Q
            nu = float(wrap_pi(z[k] - x[0]))             # ν = wrap(z − H x⁻), H = [1, 0]
            if self.adaptive:                            # Sage–Husa: R from the innovations
                d = (1 - b) / (1 - b ** (k + 1))
                r_new = (1 - d) * r + d * (nu * nu - p[0, 0])
                r = r_new if r_new > r_min else (1 - d) * r + d * nu * nu
            s_k = p[0, 0] + r                            # S = H P⁻ Hᵀ + R
            kg = p[:, 0] / s_k                           # K = P⁻ Hᵀ S⁻¹
            x = x + kg * nu                              # x = x⁻ + K ν
            ikh = np.eye(dim) - np.outer(kg, [1.0] + [0.0] * (dim - 1))
            p = ikh @ p @ ikh.T + np.outer(kg, kg) * r   # Joseph form
            x[0] = wrap_pi(x[0])
            out[k] = x[0]
        return out


class SageHusaHeading(KalmanHeading):
    """The Kalman filter with the measurement variance R estimated from the innovations, Sage–Husa with a
    forgetting factor (module docstring, **AKF**)."""

    name = "akf"
    description = "adaptive Kalman filter, Sage–Husa with forgetting factor (§2.2 of the electronic-compass note)"
    adaptive = True


class ParticleHeading(HeadingFilter):
    """The bootstrap particle filter of the heading (module docstring, **PF**): a Student-t likelihood,
    systematic resampling and roughening; its random draws need the ``rng`` argument."""

    name = "pf"
    description = "bootstrap particle filter with systematic resampling (§2.3 of the electronic-compass note)"

    def run(self, z, dpsi, dt, s, rng=None):
        if rng is None:
            raise ValueError("the particle filter draws random numbers: pass rng=numpy.random.default_rng(seed)")
        gyro = s.process == "gyro" and dpsi is not None
        m = s.particles
        n = z.size
        sd_r = math.sqrt(s.meas_var_rad2)
        psi = z[0] + max(sd_r, INIT_SPREAD_RAD) * rng.standard_normal(m)
        bias = 1e-3 * rng.standard_normal(m) if gyro else np.zeros(m)
        w = np.full(m, 1.0 / m)
        out = np.empty(n)
        out[0] = z[0]
        for k in range(1, n):
            h = float(dt[k - 1])
            if gyro:
                psi = psi + dpsi[k - 1] - bias * h + s.arw_rad_s_sqrt_hz * math.sqrt(h) * rng.standard_normal(m)
                bias = bias + s.bias_walk_rad_s2_sqrt_hz * math.sqrt(h) * rng.standard_normal(m)
            else:
                psi = psi + math.sqrt(s.seed_walk_rad2_s * h) * rng.standard_normal(m)
            e = wrap_pi(z[k] - psi)
            w = w * (1.0 + (e / sd_r) ** 2 / STUDENT_NU) ** (-(STUDENT_NU + 1) / 2)
            tot = w.sum()
            if not tot > 0 or not np.isfinite(tot):  # every particle far off: restart around the measurement
                psi = z[k] + sd_r * rng.standard_normal(m)
                w = np.full(m, 1.0 / m)
            else:
                w /= tot
            out[k] = math.atan2(float(np.sum(w * np.sin(psi))), float(np.sum(w * np.cos(psi))))
            if 1.0 / np.sum(w * w) < m / 2:  # systematic resampling
                pos = (rng.random() + np.arange(m)) / m
                idx = np.minimum(np.searchsorted(np.cumsum(w), pos), m - 1)
                psi, bias = psi[idx], bias[idx]
                w = np.full(m, 1.0 / m)
                # roughening (Gordon et al. 1993 §3.3): jitter ∝ the cloud's extent · m^(−1/d), K = 0.2,
                # so that a cloud that collapsed on a wrong heading can still move
                psi = psi + 0.2 * float(np.ptp(wrap_pi(psi - psi.mean()))) * m ** (-1 / 2) * rng.standard_normal(m)
        return out


HEADING_FILTERS: dict[str, type[HeadingFilter]] = {
    cls.name: cls for cls in (KalmanHeading, SageHusaHeading, ParticleHeading)
}
