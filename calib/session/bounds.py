"""Cramér–Rao bounds of the calibration: what any unbiased estimator could reach on a trajectory.

For the linear-Gaussian error model linearised at the *true* trajectory (true attitude, true rate, true S and
G), the Kalman covariance with a vague prior on the constants is the Cramér–Rao bound of any unbiased estimator
of them from the whole record (for constant parameters the final filtered covariance equals the smoothed one):

* :func:`crlb` — the paper's 9 states (Zhou 2020), a plain Riccati recursion here;
* :func:`crlb_joint` — any layout's states, the compiled filter (:func:`calib.session.kernel.run_filter`) fed the
  noise-free readings of the true device, with all three measurement rows;
* :func:`hand_crlb` — the hand-aware bound: ``kf_hand``'s model (the lever arm as a nuisance, the slow external
  acceleration as its fitted shaping filter, the tremor-free decimated measurement), at the truth.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from gyrosim.rotations import quat_to_matrix

from calib.session.hand.lever import lever_jacobian, lever_regressor
from calib.session.hand.lowpass import variance_ratio
from calib.session.hand.params import joint_layout
from calib.session.hand.priors import common_delay_prior, g_sensitivity_prior
from calib.session.kernel import run_filter
from calib.session.model import (
    ACC_DELAY_BLOCKS,
    EXT_ACC_EXTRA_BLOCKS,
    G_SENS_BLOCKS,
    HAND,
    HAND_BIAS,
    FilterConfig,
    StateLayout,
    initial_covariance,
    nonorthogonality_jacobians,
)

__all__ = ["crlb", "crlb_joint", "hand_crlb", "hand_crlb_layout"]


def crlb(
    omega_true_rad_s: np.ndarray,
    quat_true_nb: np.ndarray,
    t_s: np.ndarray,
    config: FilterConfig,
    rate_hz: float,
    scale_true: np.ndarray,
    nonortho_true: np.ndarray,
    vague: float = 10.0,
) -> np.ndarray:
    """Cramér–Rao bound (9, 9) of [φ₀-tracked attitude, S, G] for one trajectory (module docstring).

    The Riccati recursion of the error model at the true attitude and true rate (the
    compensated rate equals the true one), with the true M⁻¹, a vague prior σ = ``vague`` on S
    and G and the config's attitude prior; the measurement noise and ARW are the config's.
    """
    m_inv = np.linalg.inv(_m_hat(np.asarray(scale_true, float), np.asarray(nonortho_true, float)))
    c = config
    p = np.diag([c.prior_attitude_rad**2] * 3 + [vague**2] * 6)
    gz = c.gravity_m_s2
    h = np.zeros((3, 9))
    h[0, 1], h[1, 0] = -gz, gz
    r = np.eye(3) * c.r_var(rate_hz)
    cmats = quat_to_matrix(quat_true_nb)
    w = np.asarray(omega_true_rad_s, float)
    for k in range(1, t_s.size):
        dt = float(t_s[k] - t_s[k - 1])
        w_bar = 0.5 * (w[k - 1] + w[k])
        c_mid = 0.5 * (cmats[k - 1] + cmats[k])
        cm = -dt * c_mid @ m_inv
        f = np.eye(9)
        f[0:3, 3:6] = cm * w_bar[None, :]
        f[0:3, 6:9] = cm @ nonorthogonality_jacobians(w_bar[None])[0]
        p = f @ p @ f.T
        p[0:3, 0:3] += np.eye(3) * c.arw_rad_s_sqrt_hz**2 * dt
        ph = p @ h.T
        s = h @ ph + r
        kg = ph @ np.linalg.inv(s)
        p = p - kg @ ph.T
        p = 0.5 * (p + p.T)
    return p


def crlb_joint(omega_true_rad_s: np.ndarray, specific_force_true_m_s2: np.ndarray, quat_true_nb: np.ndarray,
               t_s: np.ndarray, theta_true: np.ndarray, layout: StateLayout, config: FilterConfig, rate_hz: float,
               vague: float = 10.0) -> np.ndarray:
    """Cramér–Rao bound (n, n) of a layout's states for one trajectory: the filter's Riccati recursion
    fed the noise-free readings of the true device (so its nominal stays on the truth and the
    covariance is the information of the linearised model there), with all three measurement rows
    and a vague prior (σ = ``vague`` in the parameters' units) on every parameter block."""
    th = np.asarray(theta_true, float)
    def m(s, g):
        return np.eye(3) + np.diag(s) + np.array([[0, g[2], g[1]], [g[2], 0, g[0]], [g[1], g[0], 0]])
    gyro = np.asarray(omega_true_rad_s) @ m(th[0:3], th[3:6]).T + th[6:9]
    acc = np.asarray(specific_force_true_m_s2) @ m(th[12:15], th[15:18]).T + th[9:12]
    p0 = np.eye(layout.n) * vague**2
    p0[0:3, 0:3] = np.eye(3) * config.prior_attitude_rad**2
    run = run_filter(gyro[None], acc[None], t_s, np.asarray(quat_true_nb[0], float)[None], th[None], p0, layout,
                     config, rate_hz, rows=3)
    return run.p[0]


def _m_hat(scale: np.ndarray, nonortho: np.ndarray) -> np.ndarray:
    """M = I + diag(S) + N(G), built as the compiled kernel's cofactor inverse expects (N(G) has J_G's pattern)."""
    m = nonorthogonality_jacobians(np.asarray(nonortho, float)[None])[0]
    m[0, 0] += 1 + scale[0]
    m[1, 1] += 1 + scale[1]
    m[2, 2] += 1 + scale[2]
    return m


def hand_crlb(omega_true_rad_s: np.ndarray, f_gravity_body_m_s2: np.ndarray, quat_true_nb: np.ndarray,
              t_s: np.ndarray, theta_true: np.ndarray, config: FilterConfig, rate_hz: float, sigma_s_m_s2: float,
              tau_s: float, vague: float = 10.0, highpass_tau_s: float = math.inf,
              bias_rw_rad_s_sqrt_s: float = 0.0, highpass_order: int = 1,
              temperature_rel_c: np.ndarray | None = None, g_sensitivity: bool = False,
              estimate_accelerometer: bool = False, band_hz: tuple[float, float] | None = None,
              band_rms_m_s2: float = 0.0, band_order: int = 2, delay: bool = True) -> np.ndarray:
    """The hand-aware Cramér–Rao bound (n, n) over the :data:`calib.session.model.HAND` states (module docstring): the
    Riccati recursion at the truth with the lever arm's regressor K(ω, ω̇) of the true rate, a vague prior on S, G and
    r, the Gauss–Markov a_e (σ_s, τ, high-pass τ_h) and the decimated, tremor-free measurement of
    :mod:`calib.session.hand.filter` (every D-th sample, R = σ_f²/D); with ``bias_rw_rad_s_sqrt_s`` > 0 the gyro bias is
    a random-walk state as in ``kf_hand`` (prior: the rest average's σ in ``config``); with ``temperature_rel_c`` (N,),
    T − T₀ (°C), the scale factor's temperature coefficient s_T is three more nuisance states with a vague prior, S_i(T)
    = S_i(T₀) + s_T,i (T − T₀), as in ``kf_hand`` on a session whose temperature moved
    (:func:`calib.session.hand.thermal.scale_at_temperature` maps the result to S at the temperatures the session
    determined it); ``g_sensitivity``: the gyro's g-sensitivity (diagonal, b_g,i = b_i + k_i f_i with f the true
    specific force) is three more nuisance states with a vague prior, as in ``kf_hand``.  ``estimate_accelerometer``:
    ``kf_hand_joint``'s model — the :data:`calib.session.model.HAND_JOINT` states, the accelerometer's nine with a vague
    prior, the true device's accelerometer reading M_a f + b_a and all three measurement rows (no g-sensitivity block,
    which ``kf_hand_joint`` does not carry; with ``temperature_rel_c`` its temperature blocks,
    :func:`calib.session.hand.params.joint_layout`: the accelerometer bias's c_a and the gyro scale's s_T as nuisance
    states with vague priors).  ``band_hz`` (f₁, f₂): kf_hand's band-limited sway — a_e is then the Gauss–Markov floor
    (``sigma_s_m_s2``, ``tau_s``) plus a Butterworth band-pass of ``band_order`` poles per edge with RMS
    ``band_rms_m_s2`` (:meth:`calib.session.model.FilterConfig.ext_acc_model`), the same model the filter fitted.  S, G
    are rows 3:9 of the result either way (S at T₀).  ``delay``: the accelerometer's delay behind the gyro is one more
    nuisance state (as in ``kf_hand``: one δ for the triad, prior σ 10 ms; regressor ḟ of the true specific force).  The
    layout is :func:`hand_crlb_layout`'s."""
    th = np.asarray(theta_true, float)
    m = np.eye(3) + np.diag(th[0:3]) + np.array([[0, th[5], th[4]], [th[5], 0, th[3]], [th[4], th[3], 0]])
    gyro = np.asarray(omega_true_rad_s) @ m.T + th[6:9]
    dec = max(1, int(math.floor(1.0 / variance_ratio(rate_hz))))
    n = t_s.size
    upd = np.zeros(n, bool)
    upd[::dec] = True
    cfg = replace(
        config,
        external_acc_allowance_m_s2=0.0,
        ext_acc_rms_m_s2=max(sigma_s_m_s2, 1e-9),
        ext_acc_tau_s=tau_s,
        ext_acc_highpass_tau_s=highpass_tau_s,
        ext_acc_highpass_order=int(highpass_order),
        gyro_bias_rw_rad_s_sqrt_s=bias_rw_rad_s_sqrt_s,
        ext_acc_band_hz=None if band_hz is None else (float(band_hz[0]), float(band_hz[1])),
        ext_acc_band_rms_m_s2=float(band_rms_m_s2),
        ext_acc_band_order=int(band_order),
    )
    layout = hand_crlb_layout(
        bias_rw_rad_s_sqrt_s > 0,
        temperature_rel_c is not None,
        g_sensitivity,
        estimate_accelerometer,
        2 * int(band_order) - 2 if band_hz is not None else 0,
        delay,
    )
    p0 = initial_covariance(layout, cfg)
    common_delay_prior(p0, layout)
    p0[3:9, 3:9] = np.eye(6) * vague**2
    vague_blocks = ("lever_arm", "acc_bias", "acc_scale", "acc_nonorth") if estimate_accelerometer else ("lever_arm",)
    for blk in vague_blocks:
        o = layout.offset(blk)
        p0[o:o + 3, o:o + 3] = np.eye(3) * vague**2
    # vague priors of the nuisance blocks in their own units: 0.1/°C (10 %/°C) for s_T, 0.01 rad/s per m/s²
    # (5.6 °/s/g) for the g-sensitivity — fifty times any MEMS datasheet; ``vague`` itself (10 rad/s per m/s²)
    # would put ~100 rad/s in the bias's direction and lose the recursion's precision
    # (and 1 m/s²/°C for the accelerometer bias's c_a, 700 times the MPU-9250's datasheet limit)
    for blk, sd in (("gyro_temp_scale", 0.1), ("gyro_g_sens", 0.01), ("acc_temp_bias", 1.0)):
        if layout.has(blk):
            ot = layout.offset(blk)
            p0[ot:ot + 3, ot:ot + 3] = np.eye(3) * sd**2
    if layout.has("gyro_g_sens") and layout.has("gyro_bias"):   # the bias's prior is a rest's reading b + diag(k) f̄
        g_sensitivity_prior(p0, layout, np.asarray(f_gravity_body_m_s2)[0])
    acc = np.asarray(f_gravity_body_m_s2, float)
    if estimate_accelerometer:
        ma = np.eye(3) + np.diag(th[12:15]) + np.array([[0, th[17], th[16]], [th[17], 0, th[15]], [th[16], th[15], 0]])
        acc = acc @ ma.T + th[9:12]
    r_var = config.vrw_m_s2_sqrt_hz**2 * rate_hz / dec
    run = run_filter(gyro[None], acc[None], t_s, np.asarray(quat_true_nb[0], float)[None],
                     th[None], p0, layout, cfg, rate_hz, r_var_per_sample=np.full(n, r_var), update_mask=upd,
                     lever_regressor=lever_regressor(np.asarray(omega_true_rad_s), t_s, rate_hz),
                     lever_jacobian=lever_jacobian(np.asarray(omega_true_rad_s), t_s, rate_hz, m),
                     rows=3 if estimate_accelerometer else 2,
                     temperature_rel_c=temperature_rel_c if layout.models_temperature else None,
                     specific_force_m_s2=np.asarray(f_gravity_body_m_s2) if layout.has("gyro_g_sens") else None,
                     acc_rate_m_s3=np.gradient(acc, t_s, axis=0) if layout.models_acc_delay else None)
    return run.p[0]


def hand_crlb_layout(bias_rw: bool, temperature: bool, g_sensitivity: bool, estimate_accelerometer: bool,
                     band_states: int = 0, delay: bool = True) -> StateLayout:
    """The states of :func:`hand_crlb`: kf_hand's (:func:`calib.session.hand.params.hand_layout`; ``band_states`` extra
    shaping-filter blocks of the band-limited sway) or kf_hand_joint's (:func:`calib.session.hand.params.joint_layout`)
    on a session whose temperature moved (``temperature``) or not; ``delay``: with the accelerometer's delay δ.  The
    gyro bias's temperature coefficient c_b (kf_hand's, ``HandParams.gyro_temp_bias``) is in neither: the bound's bias
    is the random walk of the truth's own end-to-end drift, as before."""
    if estimate_accelerometer:
        return joint_layout(temperature, delay=delay, gyro_temp_bias=False)
    base = HAND_BIAS if bias_rw else HAND
    return StateLayout(
        base.blocks
        + (("gyro_temp_scale",) if temperature else ())
        + (G_SENS_BLOCKS if g_sensitivity else ())
        + EXT_ACC_EXTRA_BLOCKS[:band_states]
        + (ACC_DELAY_BLOCKS if delay else ())
    )

