"""What ``kf_hand`` reports beside the parameters: the operating point its scale factors hold at, the gyro's
g-sensitivity and the accelerometer's delay behind the gyro (``diagnostics``).

* a gyro's scale is not exactly linear (k ω|ω|, ±0.1 % of full scale on the MPU-9250), and a linear S learnt from the
  session's turns is the chord slope over ±m_i, m_i = Σ|ω_i|³/Σω_i² (:func:`scale_reference_rate`, reported in
  ``diagnostics["scale_reference_rate"]``); the accelerometer's S_a likewise at the specific force its updates saw
  (:func:`acc_scale_reference_force`);
* ``diagnostics["gyro_g_sensitivity"]`` (:func:`g_sensitivity_report`) and ``diagnostics["acc_delay"]``
  (:func:`delay_report`) when those blocks are states.
"""

from __future__ import annotations

import math

import numpy as np

from calib.session.model import StateLayout

__all__ = ["scale_reference_rate", "acc_scale_reference_force", "chord_point", "g_sensitivity_report",
           "delay_report"]


def scale_reference_rate(omega_rad_s: np.ndarray) -> dict:
    """The rate (rad/s, per body axis) at which the session's linear scale factor holds: m_i = Σ|ω_i|³ / Σω_i²
    over the calibrated rates ω (N, 3) the filter saw.

    A gyro's scale is not exactly linear (the MPU-9250's datasheet: ±0.1 % of its 500 °/s full scale).  With an
    odd-symmetric nonlinearity δ_i = k_i ω_i|ω_i| (gyrosim's ``scale_nonlinearity``), the least-squares linear
    slope over the session's rates is S_i + k_i Σ ω_i²|ω_i| / Σ ω_i² = S_i + k_i m_i (each sample's information
    on S_i ∝ ω_i²) — the chord slope (δ_i(m_i) − δ_i(−m_i)) / 2m_i, the scale at ±m_i, as an accelerometer
    calibrated on the |f| = g sphere holds at ±g.  So S is stated at m_i, as it is stated at a temperature
    (:func:`calib.session.hand.thermal.scale_at_temperature`): applied at other rates it carries the nonlinearity's
    difference.  Measured (warmed-up MPU-9250, ideal hand, 200 seeds): the S error's regression on k_i gives m_eff
    0.79, 0.94, 0.96 rad/s against m_i 0.92, 1.03, 1.10; scoring S at m_i takes NEES(6) 6.77 → 6.21 (band [5.52,
    6.48]).  Also reported: the largest |ω_i| and the RMS of ω_i (rad/s), the span over which the statement was
    learnt."""
    return {
        "rate_rad_s": chord_point(omega_rad_s).tolist(),
        "max_abs_rate_rad_s": np.max(np.abs(omega_rad_s), axis=0).tolist(),
        "rms_rate_rad_s": np.sqrt(np.mean(omega_rad_s**2, axis=0)).tolist(),
        "rule": "m_i = Σ|ω_i|³/Σω_i²: S_i is the chord slope of the gyro's response over ±m_i",
    }


def acc_scale_reference_force(f_m_s2: np.ndarray) -> dict:
    """The specific force (m/s², per body axis) at which ``kf_hand_joint``'s accelerometer scale factor holds:
    m_i = Σ|f_i|³ / Σf_i² over the compensated specific force f (N, 3) at the filter's updates — the rule of
    :func:`scale_reference_rate`, whose argument holds here too: an odd-symmetric nonlinearity k_i f_i|f_i| (the
    MPU-9250's ±0.5 % of 4 g) reads as S_a,i + k_i m_i, the chord slope over ±m_i, and the session's attitudes decide
    m_i (≤ g; g only when every update saw axis i vertical).  Scoring S_a at ±g instead (the |f| = g sphere's chord)
    counted k_i (g − m_i) as error: measured, the MPU-9250 joint's z RMS of S_a,x, S_a,y 1.32, 1.26, and 1.10, 1.11
    with the nonlinearity neutralised (ideal hand, 50 paired seeds)."""
    f = np.asarray(f_m_s2, float)
    return {
        "specific_force_m_s2": chord_point(f).tolist(),
        "max_abs_specific_force_m_s2": np.max(np.abs(f), axis=0).tolist(),
        "rule": "m_i = Σ|f_i|³/Σf_i²: S_a,i is the chord slope of the accelerometer's response over ±m_i",
    }


def chord_point(x: np.ndarray) -> np.ndarray:
    """m_i = Σ|x_i|³ / Σx_i² per column of x (N, 3): where a linear fit's slope equals the chord of x|x| (0 without
    signal)."""
    x2 = np.sum(x**2, axis=0)
    return np.sum(np.abs(x) ** 3, axis=0) / np.where(x2 > 0, x2, np.inf)


def g_sensitivity_report(sens: np.ndarray, P: np.ndarray, layout: StateLayout, inflation: float) -> dict:
    """``diagnostics["gyro_g_sensitivity"]``: the gyro's sensitivity to specific force along its own axis k_i
    (b_g,i = b_i + k_i f_i) with its σ, in rad/s per m/s² and °/s/g (a datasheet's "linear acceleration
    sensitivity").  The common part k_x = k_y = k_z is a bias along gravity — a rate about the vertical, which a
    levelling measurement cannot see — so it stays near its prior σ; the differences are what the session
    measured."""
    o = layout.offset("gyro_g_sens")
    k = sens[6:9]
    sd = np.sqrt(np.clip(np.diag(P)[o:o + 3], 0.0, None) * inflation)
    to_deg_g = math.degrees(1.0) * 9.80665
    cov = P[o:o + 3, o:o + 3] * inflation
    return {
        "model": "b_g,i = b_i + k_i f_i (f the specific force, body; diagonal g-sensitivity)",
        "k_rad_s_per_m_s2": k.tolist(),
        "std_rad_s_per_m_s2": sd.tolist(),
        "covariance_rad2_s2_per_m2_s4": cov.tolist(),
        "k_deg_s_per_g": (k * to_deg_g).tolist(),
        "std_deg_s_per_g": (sd * to_deg_g).tolist(),
    }


def delay_report(sens: np.ndarray, P: np.ndarray, layout: StateLayout, inflation: float) -> dict:
    """``diagnostics["acc_delay"]``: the accelerometer's delay behind the gyro δ (s; f̃(t) = f(t − δ), positive: the
    accelerometer lags; one number for the triad, :func:`calib.session.hand.priors.common_delay_prior`) with its σ — a
    finding for the user: a timing skew between the two triads, or their anti-alias filters' different group delays
    (the MPU-9250's DLPF setting 3: gyro 5.9 ms, accelerometer 4.88 ms — InvenSense RM-MPU-9250A-00 register map,
    CONFIG and ACCEL_CONFIG 2 — so δ ≈ −1 ms)."""
    o = layout.offset("acc_delay")
    d = float(np.mean(sens[12:15]))
    sd = math.sqrt(max(float(P[o, o]), 0.0) * inflation)
    return {"model": "f̃(t) = f(t − δ): the accelerometer samples δ after the gyro (first order in δ; one δ for the "
                     "triad)",
            "delay_s": d, "std_s": sd}

