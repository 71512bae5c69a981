"""A hand-held session prepared for a filter: what both methods (the paper family's ``calibrate()`` and ``kf_hand``)
take from a recording before any filter runs.

1. input checks (gaps, units, saturation: :mod:`calib.inputs`);
2. rest detection and the static gyro bias (Zhou §3.2, :mod:`calib.session.rest`);
3. noise levels from the first rest segment with floors (:mod:`calib.session.noiselevels`) — never from a
   simulator's stored sensor model;  gravity: ``gravity_m_s2`` (default standard gravity
   9.80665 m/s² when the accelerometer is estimated: the scale factors are relative to it, so a
   local g off by 0.1 % shifts S_a by 0.1 %; with a calibrated accelerometer the mean |f| at rest);
4. the |f| = g fit (estimate mode) and the initial attitude from gravity at rest (roll, pitch;
   heading unobservable, set to 0), P₀ with the tilt's dependence on the accelerometer errors;
5. external-acceleration allowance a_ext, unless given: the larger of the accelerometer's rest
   variance beyond its white noise and √(3 (⟨(|f̂| − g)²⟩ − σ_f²)) over the session (|f| − g sees only
   the component of the external acceleration along gravity, a third of an isotropic one's variance).

A Tedaldi-style |f| = g fit over the session's quasi-static windows (:mod:`calib.session.gravityfit`) is not the answer
but the filter's starting point (linearisation), the source of the external-acceleration allowance (the residual
|f̂| − g after it) and of the pose advice.  :func:`refuse_if_nothing_observed` refuses a session whose motion after the
filter's start determines no gyro parameter.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from gyrosim.errors import RecordingError
from gyrosim.recording import Recording
from gyrosim.rotations import quat_from_two_vectors
from gyrosim.units import G0

from calib.inputs import KF, check_recording
from calib.session.gravityfit import GravityFit, compensate_acc, fit_gravity, quasi_static_windows, sample_variance
from calib.session.kernel import regressor_half_window
from calib.session.model import (
    JOINT,
    PAPER,
    FilterConfig,
    StateLayout,
    acc_theta,
    initial_covariance,
    leave_out_means,
    m_matrix,
    theta_slice,
)
from calib.session.noiselevels import NoiseLevels, estimate_noise
from calib.session.observability import parameter_gram, unobservable_parameters
from calib.session.rest import BiasEstimate, RestSegments, detect_rest, static_bias
from calib.session.rest_bias import RestBias, rest_bias

__all__ = ["ACCELEROMETER_MODES", "Prepared", "prepare", "rest_mask", "session_allowance", "tilt_sigma",
           "initial_attitude", "refuse_if_nothing_observed", "motion_unobservable"]

ACCELEROMETER_MODES = ("estimate", "calibrated")


@dataclass(frozen=True)
class Prepared:
    """Everything the filter needs from a recording, before it runs (steps 1–5)."""

    bias: BiasEstimate
    rest: RestSegments
    noise: NoiseLevels
    config: FilterConfig
    layout: StateLayout
    quat0_nb: np.ndarray
    theta0: np.ndarray
    p0: np.ndarray
    start: int
    saturated: np.ndarray | None
    warnings: tuple[str, ...]
    gravity_fit: GravityFit | None
    windows_f_hat: np.ndarray | None
    bias_std_rad_s: np.ndarray
    rest_range: tuple[int, int] = (0, 0)
    # the first rest's mean at its stated reference with σ = white noise ⊕ the hand's rotation
    # (calib.session.rest_bias); bias_std_rad_s is its σ
    rest_bias: RestBias | None = None
    bias_batch_std_rad_s: np.ndarray | None = None

    @property
    def accelerometer(self) -> str:
        """"estimate" when the layout carries the accelerometer's states, else "calibrated"."""
        return "estimate" if self.layout.estimates_accelerometer else "calibrated"


def session_allowance(rec: Recording, theta_a: np.ndarray | None, a: int, b: int, g: float, sigma_f2: float) -> float:
    """a_ext (m/s² RMS, step 5): √max(rest excess, 3 (⟨(|f̂| − g)²⟩ − σ_f²), 0) over the session from ``a``."""
    f_hat = rec.acc_m_s2 if theta_a is None else compensate_acc(rec.acc_m_s2, theta_a)
    rest_excess = float(np.mean(np.var(rec.acc_m_s2[a:b], axis=0))) - sigma_f2
    along_g = float(np.mean((np.linalg.norm(f_hat[a:], axis=1) - g - sigma_f2 / g) ** 2)) - sigma_f2
    return math.sqrt(max(rest_excess, 3.0 * along_g, 0.0))


def tilt_sigma(rec: Recording, a: int, b: int, g: float) -> float:
    """σ (rad) of roll and pitch from the accelerometer's mean over the rest [a, b): its standard
    error from 10 batch means (honest when tremor correlates the samples) over g."""
    means = np.array([m.mean(axis=0) for m in np.array_split(rec.acc_m_s2[a:b], 10)])
    return float(np.mean(means.std(axis=0, ddof=1)) / math.sqrt(10) / g) + 1e-9


def initial_attitude(rec: Recording, theta: np.ndarray, a: int, b: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """q₀ (body→ENU, heading 0) from the compensated accelerometer mean over the rest [a, b), that
    mean f̂₀ and M̂_a⁻¹."""
    th_a = acc_theta(theta)
    f0 = compensate_acc(rec.acc_m_s2[a:b], th_a).mean(axis=0)
    q0 = quat_from_two_vectors(f0, np.array([0.0, 0.0, 1.0]))
    return q0, f0, np.linalg.inv(m_matrix(th_a[3:6], th_a[6:9]))


def prepare(
    rec: Recording,
    *,
    accelerometer: str = "estimate",
    external_acc_allowance_m_s2: float | None = None,
    arw_rad_s_sqrt_hz: float | None = None,
    vrw_m_s2_sqrt_hz: float | None = None,
    gravity_m_s2: float | None = None,
    min_rest_s: float = 2.0,
) -> Prepared:
    """Steps 1–5 of the module docstring: checks, rest, bias, noise levels, |f| = g fit, allowance, P₀."""
    if accelerometer not in ACCELEROMETER_MODES:
        raise ValueError(f"accelerometer must be one of {ACCELEROMETER_MODES}, got {accelerometer!r}")
    estimate = accelerometer == "estimate"
    check = check_recording(rec, requirements=KF)
    rest = detect_rest(rec)
    bias = static_bias(rec, rest, min_rest_s=min_rest_s)
    a, b = bias.index_range
    fs = rec.rate_hz
    g = gravity_m_s2 or (G0 if estimate else float(np.mean(np.linalg.norm(rec.acc_m_s2[a:b], axis=1))))
    noise = estimate_noise(rec.gyro_rad_s, rec.acc_m_s2, (a, b), fs, g)
    arw = arw_rad_s_sqrt_hz or noise.arw_rad_s_sqrt_hz
    vrw = vrw_m_s2_sqrt_hz or noise.vrw_m_s2_sqrt_hz
    sigma_f2 = vrw**2 * fs
    warnings = list(check.warnings) + noise.notes()
    # the bias's σ: white noise over the rest ⊕ the hand's rotation during it, which the 10 batch means of
    # static_bias count as noise although it cancels in the whole mean (calib.session.rest_bias; measured: the batch
    # means' σ was 4–14× too large with a hand). Its reference (time, temperature, specific force) is finished
    # below, once the accelerometer's calibration is known.
    # N_g from the rest's spectrum above the tremor band (a hand's tremor is not sensor noise), else the spread
    # (at 2–6 Hz when that band is higher: an output low-pass, or a hand's motion that averages out of the mean)
    wd = noise.gyro_white
    n_g = (wd.rest_mean_density if wd is not None else 0.0) or arw    # 0 (noise-free): the floored σ
    rbias = rest_bias(rec.gyro_rad_s, rec.t_s, (a, b), n_g, rec.acc_m_s2, rec.temp_c)
    bias_std = rbias.std_rad_s
    # the 10 batch means' standard error (floored at the white noise): the prior kf_hand's random-walk bias state
    # still starts from (measured on the x-IMU3 hand-held recording: the honest σ above moves its lever arm
    # 5.3 → 2.8 ± 1.5 cm; not yet understood, so kf_hand keeps this prior)
    batch_std = np.maximum(bias.std_rad_s, arw * math.sqrt(fs) / math.sqrt(b - a))
    layout = JOINT if estimate else PAPER
    base = FilterConfig(arw, vrw, 0.0, gravity_m_s2=g, prior_gyro_bias_rad_s=tuple(bias_std))
    theta0 = np.zeros(18)
    theta0[theta_slice("gyro_bias")] = bias.value_rad_s
    gfit, f_windows = None, None
    if estimate:
        f = rec.acc_m_s2[a:]
        f_reg = leave_out_means(f, regressor_half_window(fs), midpoint=False)
        prior = np.concatenate([base.prior_sigma("acc_bias"), base.prior_sigma("acc_scale"),
                                base.prior_sigma("acc_nonorth")])
        gfit = fit_gravity(f, f_reg, sigma_f2, sigma_f2, g, prior)
        if external_acc_allowance_m_s2 is None:
            external_acc_allowance_m_s2 = session_allowance(rec, gfit.theta, a, b, g, sigma_f2)
        if external_acc_allowance_m_s2 > 0:  # refit with the hand's allowance in the weights (honest P_a), the
            # rests weighed by their own scatter (calib.session.gravityfit.sample_variance)
            r_var = sample_variance(f, [(ra - a, rb - a) for ra, rb in rest.index_ranges], sigma_f2,
                                    sigma_f2 + external_acc_allowance_m_s2**2)
            gfit = fit_gravity(f, f_reg, r_var, sigma_f2, g, prior, gfit.theta)
        theta0[theta_slice("acc_bias")] = gfit.bias_m_s2
        theta0[theta_slice("acc_scale")] = gfit.scale_factor
        theta0[theta_slice("acc_nonorth")] = gfit.nonorthogonality
        wins, _ = quasi_static_windows(f, fs, 0.1)
        f_windows = compensate_acc(wins, gfit.theta)
        rbias = replace(rbias, specific_force_m_s2=compensate_acc(rec.acc_m_s2[a:b], gfit.theta).mean(axis=0))
    elif external_acc_allowance_m_s2 is None:
        external_acc_allowance_m_s2 = session_allowance(rec, None, a, b, g, sigma_f2)
    config = FilterConfig(arw, vrw, external_acc_allowance_m_s2, gravity_m_s2=g, prior_gyro_bias_rad_s=tuple(bias_std))
    q0, f0, mi_a = initial_attitude(rec, theta0, a, b)
    tilt = tilt_sigma(rec, a, b, g) if estimate else None
    p0 = initial_covariance(layout, config, q0, f0, mi_a, None if gfit is None else gfit.covariance, tilt)
    saturated = check.excluded if check.excluded_samples else None  # at a rail, bridged or spike-repaired
    # with the gyro bias a state the filter starts after the rest that gave its prior: the same gyro
    # samples would otherwise inform the bias twice (the static average, and the tilt drift at rest)
    start = b - 1 if estimate else a
    return Prepared(bias, rest, noise, config, layout, q0, theta0, p0, start, saturated, tuple(warnings), gfit,
                    f_windows, bias_std, (a, b), rbias, batch_std)


def rest_mask(prep: Prepared, n: int) -> np.ndarray:
    """(n,) True at the steps k−1 → k that lie inside a detected rest segment (samples from ``start``)."""
    mask = np.zeros(n, dtype=bool)
    for a, b in prep.rest.index_ranges:
        lo, hi = max(a - prep.start + 1, 0), min(b - prep.start, n)
        if hi > lo:
            mask[lo:hi] = True
    return mask


def refuse_if_nothing_observed(rec: Recording, bias_rad_s: np.ndarray, ra: int, rb: int, start: int) -> None:
    """Every gyro S, G unobservable from the motion after ``start`` (:func:`motion_unobservable`, the parameter Gram of
    Zhou §4): the filter, which starts at the rest that gave the bias (the first one ≥ 2 s), would see no rotation that
    determines them — a session whose early rests came out shorter (a hand that never held still 2 s before turning;
    rests cut by correlated noise, as an output low-pass did before :func:`calib.session.rest.detect_rest` scaled its
    test) or that does not turn.  Its S, G would be the prior, 0 ± 5 %, with status "ok" (kf_hand, the last rest ending
    the file: a crash in its low-pass): refused instead, saying where the filter starts and how much rotation comes
    before it."""
    names = {f"{b}_{ax}" for b in "SG" for ax in "xyz"}
    enough = rec.n - start >= int(2.0 * rec.rate_hz) + 32
    if enough and not names <= set(motion_unobservable(rec, bias_rad_s, start)):
        return
    w2 = np.sum((rec.gyro_rad_s - np.mean(rec.gyro_rad_s[ra:rb], axis=0)) ** 2, axis=1)
    before = float(np.sum(w2[:start]) / max(float(np.sum(w2)), 1e-300))
    raise RecordingError(
        f"no gyro scale factor or non-orthogonality is determined by this session: the filter starts at the first rest "
        f"of ≥ 2 s (t = {rec.t_s[ra]:.2f}–{rec.t_s[rb - 1]:.2f} s, which gives the bias) and {100 * before:.0f} % of "
        "the "
        "session's rotation comes before it. Hold the sensor still for ≥ 2 s before the turns, then turn about each "
        "axis (Zhou 2020 Table 5); if the rests are there, check the rest segments calib reports"
    )


def motion_unobservable(rec: Recording, bias_rad_s: np.ndarray, start: int) -> list[str]:
    """Gyro filter parameters the recording's motion cannot observe, from the stripped observability
    matrix's parameter Gram (:func:`calib.session.observability.parameter_gram`, attitude-free, Zhou §4).

    Rates and accelerometer averaged over 2 s (calibration rotations live below 1 Hz), sampled at
    ~10 Hz; null space = less excitation than a 0.01 rad/s rotation gives.
    """
    step = max(1, int(round(rec.rate_hz / 10.0)))
    win = max(1, int(round(2.0 * rec.rate_hz)))
    kernel = np.ones(win) / win

    def smooth(x: np.ndarray) -> np.ndarray:
        return np.stack([np.convolve(x[:, i], kernel, mode="same") for i in range(3)], axis=1)[::step]

    w = smooth(rec.gyro_rad_s[start:] - bias_rad_s)
    f = smooth(rec.acc_m_s2[start:])
    return unobservable_parameters(parameter_gram(w, f), float(np.median(np.linalg.norm(f, axis=1))))

