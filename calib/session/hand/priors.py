"""The priors of ``kf_hand``'s extra blocks: how the first rest that gave the gyro bias's prior ties it to the blocks
that change what the gyro read there, the accelerometer's delay as one number, and the accelerometer's prior in the
joint filter.

* the gyro's g-sensitivity (a MEMS gyro's "linear acceleration sensitivity", 0.1 °/s/g for the MPU-9250 family): b_g,i =
  b_i + k_i f_i with f the (calibrated, low-passed) specific force — a bias step after every change of attitude, which a
  random walk can only cover by inflating σ; three states, prior σ 1e-3 rad/s per m/s² (0.56 °/s/g), reported in
  ``diagnostics["gyro_g_sensitivity"]``; the rest read b + diag(f̄) k (:func:`g_sensitivity_prior`), as it read
  b + c_b (T_rest − T₀) on a warming sensor (:func:`temp_bias_prior`);
* the accelerometer's delay behind the gyro, δ (s): f̃(t) = f(t − δ), to first order f = f̃ + δ ḟ̃ (ḟ̃ the derivative of
  the low-passed f̃, body) — one state for the triad (``acc_delay``, :func:`common_delay_prior`, prior σ 10 ms).  The
  filter's attitude comes from the gyro and its levelling measurement from the accelerometer, so a skew between them
  reads as an attitude error δ ω × g_b during every turn: at 1 rad/s a 1-ms skew is 10 mm/s², the signature of a 1e-3
  scale factor error over the same turn.  Two triads' anti-alias filters of different bandwidth make such a skew
  (MPU-9250 DLPF setting 3: gyro 5.9 ms, accelerometer 4.88 ms); unmodelled it stayed in the innovations, and σ of S, G
  was inflated for it (MPU-9250 preset, ideal hand, 20 seeds: NEES(6) 4.24 → 4.85 with δ estimated: δ̂ −0.81 ms mean,
  0.16 ms spread over the seeds, reported σ 0.16–0.21 ms, against the simulated gyro's 0.82-ms low-pass delay); reported
  in ``diagnostics["acc_delay"]``;
* with the accelerometer estimated (``kf_hand_joint``): the |f| = g fit's mean and (inflated) covariance as its prior,
  from pass 2 the fit without the lever arm's acceleration (:func:`gravity_fit_lever_free`), and the initial tilt's
  dependence on c_a (:func:`acc_temp_tilt_prior`).
"""

from __future__ import annotations

import numpy as np

from gyrosim.recording import Recording
from gyrosim.rotations import skew

from calib.session.consistency import INFLATION_BLOCK_S
from calib.session.gravityfit import GravityFit, fit_gravity, sample_variance
from calib.session.kernel import regressor_half_window
from calib.session.model import SENSOR_EXTRA_BLOCKS, StateLayout, leave_out_means, q_matrix
from calib.session.prepare import Prepared

__all__ = ["FIT_PRIOR_INFLATION", "acc_temp_tilt_prior", "g_sensitivity_prior", "rest_reading_prior",
           "temp_bias_prior", "common_delay_prior", "sensor_extra_prior", "gravity_fit_lever_free"]


def acc_temp_tilt_prior(p0: np.ndarray, layout: StateLayout, q0_nb: np.ndarray, acc_m_inv: np.ndarray, dt_rest_c: float,
                         gravity_m_s2: float) -> None:
    """The initial tilt levels the rest's accelerometer mean, whose bias is b_a + c_a (T_rest − T₀): the c_a part
    of φ₀ = [g_up×] Ĉ₀ M̂_a⁻¹ δb_a / g² (:func:`calib.session.model.initial_covariance`) with δb_a → δc_a (T_rest − T₀):
    P_φφ += A P_cc Aᵀ, P_φc = A P_cc."""
    oc = layout.offset("acc_temp_bias")
    if oc < 0 or dt_rest_c == 0.0:
        return
    c0 = q_matrix(np.asarray(q0_nb, float) / np.linalg.norm(q0_nb))
    A = skew(np.array([0.0, 0.0, gravity_m_s2])) @ c0 @ acc_m_inv
    A = A * (dt_rest_c / gravity_m_s2**2)
    pcc = p0[oc:oc + 3, oc:oc + 3]
    p0[0:3, 0:3] += A @ pcc @ A.T
    p0[0:3, oc:oc + 3] = A @ pcc
    p0[oc:oc + 3, 0:3] = (A @ pcc).T


# kf_hand_joint: the |f| = g fit's covariance × this is the accelerometer's prior (σ × 10): the fit is the
# linearisation point, the filter's vertical row the information (the same data would otherwise count twice,
# and the fit's white-residual covariance is optimistic with a hand's sway: its err/σ RMS 2–5 on the
# independent generator).  A vague prior (the consumer ±1 m/s², ±5 %) diverged on the MPU-9250 (4 of 8 seeds).
# From pass 2 the covariance is the fit's block sandwich (gravity_fit_lever_free), which does not shrink with the
# sample rate: the white-residual one did (σ²/N), and with a shaky hand at 100 Hz that left σ of S, G 1.4–2.4×
# optimistic while the same hands at 200 Hz were honest (docs/hand.md, "Hands we did not tune for")
FIT_PRIOR_INFLATION = 100.0


def g_sensitivity_prior(p0: np.ndarray, layout: StateLayout, f_rest_m_s2: np.ndarray) -> None:
    """The bias's prior comes from a rest, where the gyro read b + diag(k) f̄ (f̄ that rest's specific force): so
    b = b̄ − diag(f̄) k, and with k ~ N(0, P_k) the prior of (b, k) is correlated,

        P_bb = s² + F P_k F,   P_bk = −F P_k,   F = diag(f̄).

    Independent priors would pin b at the rest's reading and misread every change of attitude afterwards
    (measured on the independent generator with 0.3 °/s/g: innovations ×15 their model, "diverged")."""
    rest_reading_prior(p0, layout, "gyro_g_sens", np.asarray(f_rest_m_s2, float))


def rest_reading_prior(p0: np.ndarray, layout: StateLayout, block: str, f: np.ndarray) -> None:
    """The gyro bias's prior when the rest that gave it read b + diag(f) x, x the 3-state ``block`` with prior P_x: b =
    b̄ − F x, so P_bb += F P_x F, P_bx = −F P_x, F = diag(f) (:func:`g_sensitivity_prior`, :func:`temp_bias_prior`;
    several such blocks add).  A no-op without ``block`` or the bias."""
    ox, ob = layout.offset(block), layout.offset("gyro_bias")
    if ox < 0 or ob < 0:
        return
    F = np.diag(f)
    px = p0[ox:ox + 3, ox:ox + 3].copy()
    p0[ob:ob + 3, ob:ob + 3] += F @ px @ F
    p0[ob:ob + 3, ox:ox + 3] = -F @ px
    p0[ox:ox + 3, ob:ob + 3] = -px @ F


def temp_bias_prior(p0: np.ndarray, layout: StateLayout, dt_rest_c: float) -> None:
    """The bias's prior comes from a rest at T_rest, where the gyro read b + c_b ΔT (ΔT = T_rest − T₀, the filter's
    reference T₀): so b = b̄ − c_b ΔT, and with c_b ~ N(0, P_c) the prior of (b, c_b) is correlated,

        P_bb = s² + ΔT² P_c,   P_bc = −ΔT P_c

    (as :func:`g_sensitivity_prior` for the specific force; the two add when both blocks are on).  A no-op without
    the block."""
    rest_reading_prior(p0, layout, "gyro_temp_bias", np.full(3, dt_rest_c))


def common_delay_prior(p0: np.ndarray, layout: StateLayout) -> None:
    """One delay for the whole accelerometer triad: the three ``acc_delay`` states' prior is σ² 𝟙𝟙ᵀ (rank one), so
    with no process noise every update moves them together and they stay one number δ.  Two chips' (or two dies')
    anti-alias filters and sampling set one offset between the triads; a per-axis δ_i took other misfits instead
    (measured on the x-IMU3 hand-held session: δ = +5.4, −3.6, −15.3 ms per axis, and G_y moved 36 σ from the factory
    calibration)."""
    o = layout.offset("acc_delay")
    if o < 0:
        return
    v = float(np.mean(np.diag(p0)[o:o + 3]))
    p0[o:o + 3, :] = 0.0
    p0[:, o:o + 3] = 0.0
    p0[o:o + 3, o:o + 3] = v


def sensor_extra_prior(x0: np.ndarray, layout: StateLayout, sens: np.ndarray) -> None:
    """Prior mean 0 of the gyro's extra blocks (c_b, s_T, k) seen from the linearisation point ``sens`` (9,)."""
    for i, blk in enumerate(SENSOR_EXTRA_BLOCKS):
        o = layout.offset(blk)
        if o >= 0:
            x0[o:o + 3] = -sens[3 * i:3 * i + 3]


def gravity_fit_lever_free(rec: Recording, prep: Prepared, start: int, kreg: np.ndarray, r_m: np.ndarray,
                            theta_a: np.ndarray) -> GravityFit:
    """The |f| = g fit of :func:`calib.session.prepare.prepare` (same samples from the first rest on, weights, prior) on
    f̃ − K(ω, ω̇) r̂ (the rest itself uncorrected: ω = 0 there): a hand's steady turn about a pivot adds a constant
    centripetal ω × (ω × r) that a quasi-static |f| = g fit reads as accelerometer bias (measured: b_y off by 0.05 m/s²,
    27 of its σ, with the typical hand's 6 cm).  The lever arm's acceleration in raw units is M_a K r̂ ≈ K r̂ (the
    difference is second order: S_a · K r̂).  The hand's sway and tremor stay in the residuals, correlated over seconds:
    the covariance is the fit's block-sum sandwich over ``INFLATION_BLOCK_S`` blocks (Newey & West 1987's batch means;
    :func:`calib.session.gravityfit.fit_gravity`, ``block_samples``), not the white-residual (Jᵀ W J)⁻¹, which was ~2×
    optimistic in σ for the accelerometer on the independent generator's hand and, scaling as 1/N, made the joint's
    prior depend on the sample rate."""
    ra, _ = prep.rest_range
    cfg = prep.config
    fs = rec.rate_hz
    f = rec.acc_m_s2[ra:].copy()
    f[start - ra:] -= np.einsum("nij,j->ni", kreg, r_m)
    f_reg = leave_out_means(f, regressor_half_window(fs), midpoint=False)
    prior = np.concatenate([cfg.prior_sigma("acc_bias"), cfg.prior_sigma("acc_scale"), cfg.prior_sigma("acc_nonorth")])
    sigma_f2 = cfg.vrw_m_s2_sqrt_hz**2 * fs
    r_var = sample_variance(f, [(a - ra, b - ra) for a, b in prep.rest.index_ranges], sigma_f2,
                            sigma_f2 + cfg.external_acc_allowance_m_s2**2)     # the rests by their own scatter
    return fit_gravity(f, f_reg, r_var, sigma_f2, cfg.gravity_m_s2, prior, theta_a,
                       block_samples=max(1, int(round(INFLATION_BLOCK_S * fs))))

