"""The gyro–accelerometer timing skew of a noise-free recording, measured before a filter runs.

A filter whose gyro propagates the attitude and whose accelerometer levels it reads a skew τ between the two
triads as an attitude error g·|ω|·τ during every turn: at 1.5 rad/s a 5-ms skew (half a sample at 100 Hz, a gyro
sample that stands for its whole interval) is 0.07 m/s².  On real data that is ~10 × the white noise and the
filter's σ holds it; on a noise-free (simulated) recording the noise levels sit at their numerical floors
(:mod:`calib.session.noiselevels`, ~5e-5 m/s²), so a filter without a timing state — the hand-blind
``kf_session`` / ``iterated_session`` — trusts every sample a thousand times too much and diverges (measured on the
independent generator's held gyro: S off by 1.1, and 3e4 re-linearised).  ``kf_hand`` carries the skew as a state
and is exact there (5e-6).

Noise-free data allow the skew to be measured without a filter, from the kinematics alone: gravity turns in the
body as ġ = g × ω, and the accelerometer reads f̃ = M_a g + b_a, the gyro ω̃ = M_g ω + b_g, so

    ḟ̃(t) = M_a [ (M_a⁻¹ (f̃(t) − b_a)) × (M_g⁻¹ (ω̃(t) − τ ω̃̇(t) − b_g)) ]

(τ > 0: the accelerometer samples τ after the gyro, the sign of ``kf_hand``'s ``acc_delay``).  Gauss–Newton over
(M_a symmetric, b_a, M_g general, b_g, τ) on the moving samples, started at identity; the derivatives are central
differences, exact to O(Δt²) on a smooth noise-free record.  The overall scale of M_a does not enter (f̃ and g
trade it), so its trace is held.  A hand's lever arm or translation breaks the relation: the check is for
recordings the hand-blind filters are meant for, and says so.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize

from gyrosim.effects import nonortho_matrix
from gyrosim.errors import RecordingError
from gyrosim.recording import Recording

__all__ = ["Skew", "measure_skew", "refuse_skew_at_floor"]

MOVING_RAD_S = 0.05        # samples turning faster than this carry the skew's signature
MAX_ROWS = 6000            # the moving samples used (evenly thinned beyond)


@dataclass(frozen=True)
class Skew:
    """τ (s; the accelerometer after the gyro), the RMS of the kinematic residual (m/s³) and of ḟ̃ (m/s³), and the
    skew the accelerometer's noise floor absorbs, σ_f / (g · ω_max) (s)."""

    tau_s: float
    residual_rms_m_s3: float
    signal_rms_m_s3: float
    floor_tau_s: float


def _model(p: np.ndarray, f: np.ndarray, w: np.ndarray, dw: np.ndarray) -> np.ndarray:
    """ḟ̃ predicted for parameters p = [S_a (2: the third from the held trace), G_a (3), b_a (3), M_g − I (9),
    b_g (3), τ]."""
    sa = np.array([p[0], p[1], -p[0] - p[1]])
    ma = np.eye(3) + np.diag(sa) + nonortho_matrix(p[2:5])
    mg = np.eye(3) + p[8:17].reshape(3, 3)
    g = np.linalg.solve(ma, (f - p[5:8]).T).T
    om = np.linalg.solve(mg, (w - p[20] * dw - p[17:20]).T).T
    return np.cross(g, om) @ ma.T


def measure_skew(gyro_rad_s: np.ndarray, acc_m_s2: np.ndarray, t_s: np.ndarray, acc_floor_m_s2: float,
                 gravity_m_s2: float = 9.80665) -> Skew | None:
    """The skew of a noise-free recording (module docstring); None when it barely turns (nothing to measure)."""
    t = np.asarray(t_s, float)
    w, f = np.asarray(gyro_rad_s, float), np.asarray(acc_m_s2, float)
    df = np.gradient(f, t, axis=0)
    dw = np.gradient(w, t, axis=0)
    moving = np.linalg.norm(w - np.median(w, axis=0), axis=1) > MOVING_RAD_S
    idx = np.flatnonzero(moving)[2:-2]
    if idx.size < 50:
        return None
    idx = idx[:: max(1, idx.size // MAX_ROWS)]
    fi, wi, dwi, dfi = f[idx], w[idx], dw[idx], df[idx]
    sol = optimize.least_squares(lambda p: (_model(p, fi, wi, dwi) - dfi).ravel(), np.zeros(21), method="lm",
                                 x_scale=np.r_[np.full(17, 0.01), np.full(3, 0.01), 1e-3], xtol=1e-12, ftol=1e-12)
    res = sol.fun.reshape(-1, 3)
    w_max = float(np.percentile(np.linalg.norm(wi, axis=1), 99))
    return Skew(float(sol.x[20]), float(np.sqrt(np.mean(res**2))), float(np.sqrt(np.mean(dfi**2))),
                float(acc_floor_m_s2 / (gravity_m_s2 * max(w_max, 1e-3))))


def refuse_skew_at_floor(rec: Recording, acc_floor_m_s2: float, gravity_m_s2: float, method: str) -> Skew | None:
    """Before a hand-blind filter runs on noise-free input: refuse (a :class:`RecordingError`, one line) when the
    gyro and the accelerometer are skewed by more than the noise floor absorbs; the skew measured otherwise."""
    sk = measure_skew(rec.gyro_rad_s, rec.acc_m_s2, rec.t_s, acc_floor_m_s2, gravity_m_s2)
    if sk is None or not math.isfinite(sk.tau_s):
        return sk
    # the kinematic fit must explain the record (no hand): its residual a small share of ḟ̃
    if sk.residual_rms_m_s3 < 1e-3 * sk.signal_rms_m_s3 and abs(sk.tau_s) > max(sk.floor_tau_s, 1e-6):
        raise RecordingError(
            f"noise-free input with the accelerometer {sk.tau_s * 1e3:+.2f} ms after the gyro (measured from the "
            f"kinematics; {method} has no timing state and its noise floor absorbs {sk.floor_tau_s * 1e6:.0f} µs): "
            "use --method hand, which estimates the skew, or shift one triad's timestamps")
    return sk
