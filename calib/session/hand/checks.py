"""Checks of ``kf_hand``'s own assumptions on a recording, for measured data (docs/real_imu.md,
"kf_hand on the measured recordings").

``kf_hand`` (:mod:`calib.session.hand.filter`) is exact on data that follow its model; on someone else's data three
assumptions can fail without its innovations saying so (measured on the project's measured recordings):

1. **the accelerometer is calibrated** (Zhou 2020 §3.3.2; ``--accelerometer calibrated``).  An
   uncalibrated triad (bias b_a, scale S_a, non-orthogonality G_a) reads gravity with a magnitude error
   and a direction error of the same order ε (for f = (I + S_a + N(G_a)) g + b_a both are O(|S_a| + |G_a|
   + |b_a|/g)); the filter takes that direction as the truth, so the tilt reference is wrong by ~ε rad
   between poses and S, G absorb ~ε per radian turned.  The rests show it: at rest |f| = g whatever the
   pose for a calibrated accelerometer, so the spread of the rests' |f̄_i| across poses measures ε
   (Ferraris et al. 1995; Tedaldi et al. 2014, the |f| = g cost).  When ε exceeds the median σ of S, G
   (and its own noise) the S, G are not trustworthy at their σ: ``inconsistent`` with a warning.
   Measured: imucal's Ferraris session 113 mg (kf_hand's G 6–10 σ from imucal's), imu_tk's Xsens
   counts 234 mg; BROAD (maker-calibrated) ≤ 0.4 mg, x-io Fusion 0.5 mg.  When every rest has about the
   same attitude (all gravity directions within ``SAME_POSE_DEG``) the rests cannot test it: a note says so;
2. **what the 4-Hz pre-filter removes is a hand's tremor**: impacts (BROAD's tapping trial, 4.8 m/s²
   RMS above 4 Hz) or vibration are bursts whose part below 4 Hz the stationary Gauss–Markov model
   averages over the session; a hand's physiological tremor is ≤ 0.035 g peak (0.34 m/s²; Wade, Gresty &
   Findley 1982, the simulator's ``shaky`` preset), the hand-held recordings here show 0.38–0.79 m/s²
   above 4 Hz (voluntary motion included).  Above ``TREMOR_MAX_M_S2`` (≈ 6× the largest tremor)
   ``inconsistent``: measured on BROAD 25 (tapping), ``ok`` before this check, its S_y, G_y 4.6 σ and
   7.8 σ from a maker-calibrated IMU's ≈ 0 and its optical attitude error 5.8× worse after the calibration;
3. **the lever arm is a hand's**: a rotation centre farther than ``LEVER_ARM_MAX_M`` (30 cm: a
   forearm; Winter, *Biomechanics and Motor Control of Human Movement*, Table 4.1, forearm 0.146 H) means
   the session's translation was read as a lever arm (BROAD 16, fast translation: 32 cm):
   ``inconsistent``;
4. **the slow external acceleration is a hand's** (:func:`slow_displacement`): ``kf_hand`` fits whatever
   the specific force does not explain (|f_lp − K r̂| − g, its component along gravity) as the hand's
   acceleration a_e.  A hand turning a device moves it by centimetres, and at most by a forearm
   (``DISPLACEMENT_MAX_M`` = 30 cm, the lever-arm check's length: the whole forearm swung about the
   elbow, vertical excursion ±30 cm, RMS ≤ 30 cm): its acceleration has almost no power at periods of
   5–20 s, where a displacement x needs only a = (2πf)² x (0.3 m at 0.05 Hz: 0.03 m/s²).  The
   displacement the residual implies in that band,

       x_rms² = ∫_{0.05 Hz}^{0.2 Hz} S_e(f) / (2πf)⁴ df     (S_e: Welch, 40-s Hann segments, mean removed),

   above that bound is not a hand: the device travelled (carried, walked, swung at arm's length) or the
   residual is a sensor effect the model lacks (accelerometer calibration, a time offset between the
   triads, a changing pivot), which ``kf_hand`` counted as the hand's and weighted S, G by:
   ``inconsistent``.  Measured: x-io Fusion (hand-held, a 5-s burst of 2.3 m/s² mean |f| − g at
   t ≈ 55 s, rotations to 368 °/s) 3.7 m — ``ok`` before, its fitted a_e 2.85 m/s² RMS, τ 6.3 s; BROAD's
   slow hand-held rotations 0.06–0.09 m; gyrosim's hands (ideal … shaky, both sensors, 20 seeds each)
   ≤ 0.011 m and the independent generator's ≤ 0.02 m.  White sensor noise of one-sided PSD W = 2N² alone
   gives x_rms² = W Σ_band Δf / (2πf)⁴ (x_rms ≈ 1.8 √W m on these bins, W in m²/s⁴/Hz): ~0.007 m for the
   MPU-9250, but ~0.38 m for the paper's simulated accelerometer (15 mg/√Hz), more than the bound with the
   hand still.  So that share is taken off (N measured on the first rest), and the bound must be passed by
   more than the noise's own scatter: rms² − noise² > bound² + 3 σ, σ from Welch's few segments (each bin's
   relative σ 1/√K for K segments).

And one check of the result itself (:func:`refuse_confounded`): a session whose motion cannot tell the lever arm from S
or G (posterior correlation above ``CONFOUND_CORRELATION``) is refused with the parameters named and the motion that
separates them: the lever arm's acceleration grows with ω² (and ω̇), a scale factor's attitude error with ∫ω, so the
same rotation at two different speeds separates them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy import signal as sp_signal

from gyrosim.errors import RecordingError

from calib.session.model import StateLayout

__all__ = ["HandAssumptions", "check_hand_assumptions", "slow_displacement", "SlowDisplacement", "TREMOR_MAX_M_S2",
           "CONFOUND_CORRELATION", "refuse_confounded",
           "LEVER_ARM_MAX_M", "SAME_POSE_DEG", "MIN_REST_S", "DISPLACEMENT_MAX_M", "SLOW_BAND_HZ"]

TREMOR_MAX_M_S2 = 2.0
LEVER_ARM_MAX_M = 0.30
SAME_POSE_DEG = 20.0
MIN_REST_S = 2.0
NOISE_Z = 5.0           # the rests' |f| spread must also exceed this many of its own noise σ
DISPLACEMENT_MAX_M = LEVER_ARM_MAX_M   # a hand's displacement RMS, at most a forearm (check 4)
SLOW_BAND_HZ = (0.05, 0.2)             # periods 5–20 s: below the simulator's and a hand's sway (0.2–1 Hz)
SLOW_SEGMENT_S = 40.0                  # Welch segment: 0.025-Hz bins, the band's lowest bin two above 0 Hz
SLOW_NOISE_Z = 3.0                     # the noise's scatter allowed above the bound (one-sided, ~1 % on ~7 segments)
SLOW_WINDOW_S = 10.0                   # where it happened: the largest RMS of the band-limited residual


@dataclass(frozen=True)
class SlowDisplacement:
    """:func:`slow_displacement`'s result: the displacement RMS (m) the residual implies in ``SLOW_BAND_HZ``,
    the centre time (s, the recording's clock) of the window where the residual's slow part was largest, and
    ``noise_m``: the part of ``rms_m`` the accelerometer's white noise alone gives (0 when its density is unknown),
    and ``noise_sd_m2``: the standard deviation of the noise's share of ``rms_m²`` (Welch's estimate of a PSD
    averages only a few segments: each bin's relative σ is 1/√K for K segments)."""

    rms_m: float
    worst_t_s: float
    noise_m: float = 0.0
    noise_sd_m2: float = 0.0

    def exceeds(self, limit_m: float, z: float = SLOW_NOISE_Z) -> bool:
        """Whether the displacement beyond the noise is above ``limit_m`` by more than the noise's own scatter:
        rms² − noise² > limit² + z σ(noise's share)."""
        return self.rms_m**2 - self.noise_m**2 > limit_m**2 + z * self.noise_sd_m2

    @property
    def beyond_noise_m(self) -> float:
        """The displacement RMS beyond the noise's: √(max(0, rms² − noise²)) (the two add in power)."""
        return math.sqrt(max(0.0, self.rms_m**2 - self.noise_m**2))


def slow_displacement(residual_m_s2: np.ndarray, t_s: np.ndarray, rate_hz: float,
                      acc_noise_density_m_s2_sqrt_hz: float | None = None) -> SlowDisplacement | None:
    """Check 4 of the module docstring: x_rms = √(Σ_band Ŝ_e(f) / (2πf)⁴ Δf), Ŝ_e the one-sided Welch PSD of the
    residual with ``SLOW_SEGMENT_S`` Hann segments, each segment's mean removed.  Not a linear detrend: the line fitted
    to a sway tone is ~A/(πk) of it (k its bin), and that ramp × Hann lands in the lowest bins, where 1/f⁴ magnifies it
    (a 1-cm sway at 0.3–1 Hz read 3 mm; with the mean removed 0.04 mm).  A slow drift's ramp falls mostly in bins 0–1,
    which the band leaves out (it starts at bin 2).  None for a recording shorter than two segments' band (<
    2/``SLOW_BAND_HZ[0]`` s), where the band has no bin to read.  Source: x(f) = a(f) / (2πf)² (Fourier transform of ẍ =
    a); Welch 1967.  ``acc_noise_density_m_s2_sqrt_hz``: the accelerometer's white density N (per-sample variance
    N² f_s); its one-sided PSD 2N² through the same bins is ``noise_m`` — what a noisy sensor reads with the hand
    still (0.27–0.38 m for the paper's simulated 15 mg/√Hz accelerometer, as much as the bound)."""
    e = np.asarray(residual_m_s2, float)
    t = np.asarray(t_s, float)
    if e.size < 16 or e.size / rate_hz < 2.0 / SLOW_BAND_HZ[0] or not np.all(np.isfinite(e)):
        return None
    e = e - e.mean()
    nper = int(min(e.size, SLOW_SEGMENT_S * rate_hz))
    f, pxx = sp_signal.welch(e, fs=rate_hz, nperseg=nper, detrend="constant")
    band = (f >= SLOW_BAND_HZ[0]) & (f <= SLOW_BAND_HZ[1])
    weight = (f[1] - f[0]) / (2 * math.pi * f[band]) ** 4          # Δf / (2πf)⁴ per bin of the band
    x_rms = math.sqrt(float(np.sum(pxx[band] * weight)))
    n = acc_noise_density_m_s2_sqrt_hz
    noise = math.sqrt(2.0 * n * n * float(np.sum(weight))) if n is not None and math.isfinite(n) else 0.0
    segments = 1 + (e.size - nper) // (nper // 2)                  # scipy's default overlap: half a segment
    noise_sd = noise**2 * math.sqrt(float(np.sum(weight**2))) / float(np.sum(weight)) / math.sqrt(segments)
    b, a = sp_signal.butter(2, SLOW_BAND_HZ[1] / (rate_hz / 2))
    slow = sp_signal.filtfilt(b, a, e)
    w = max(1, int(SLOW_WINDOW_S * rate_hz))
    ms = np.convolve(slow**2, np.ones(w) / w, mode="same")
    return SlowDisplacement(x_rms, float(t[int(np.argmax(ms))]), noise, noise_sd)


@dataclass(frozen=True)
class HandAssumptions:
    """Result of :func:`check_hand_assumptions`: ``trustworthy`` False when an assumption failed (the
    caller makes the status ``inconsistent``), the warnings, and the numbers behind them."""

    trustworthy: bool
    warnings: tuple[str, ...]
    rest_acc_norm_spread_g: float | None          # ε: max |  |f̄_i| − |f̄_0|  | / |f̄_0| over the rests
    rest_pose_spread_deg: float | None            # largest angle between two rests' gravity directions
    tremor_band_rms_m_s2: float
    lever_arm_norm_m: float
    details: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {"trustworthy": self.trustworthy, "rest_acc_norm_spread_g": self.rest_acc_norm_spread_g,
                "rest_pose_spread_deg": self.rest_pose_spread_deg, "tremor_band_rms_m_s2": self.tremor_band_rms_m_s2,
                "lever_arm_norm_m": self.lever_arm_norm_m, "tremor_max_m_s2": TREMOR_MAX_M_S2,
                "lever_arm_max_m": LEVER_ARM_MAX_M, **self.details}


def _rest_means(acc_m_s2: np.ndarray, t_s: np.ndarray, rests) -> tuple[np.ndarray, np.ndarray]:
    means, se = [], []
    for a, b in rests:
        if b - a < 10 or t_s[b - 1] - t_s[a] < MIN_REST_S:
            continue
        f = acc_m_s2[a:b]
        means.append(f.mean(axis=0))
        mag = np.linalg.norm(f, axis=1)
        # the mean's standard error from 10 sub-block means (robust to the rest's slow drift)
        blocks = np.array([m.mean() for m in np.array_split(mag, 10)])
        se.append(float(blocks.std(ddof=1) / math.sqrt(10)))
    return np.array(means).reshape(-1, 3), np.array(se)


def check_hand_assumptions(acc_m_s2: np.ndarray, t_s: np.ndarray, rests, sigma_sg: np.ndarray,
                           tremor_band_rms_m_s2: float, lever_arm_m: np.ndarray,
                           lever_arm_std_m: np.ndarray, check_accelerometer: bool = True,
                           slow_residual_m_s2: np.ndarray | None = None, slow_residual_t_s: np.ndarray | None = None,
                           rate_hz: float | None = None, accelerometer_source: str | None = None,
                           acc_noise_density_m_s2_sqrt_hz: float | None = None) -> HandAssumptions:
    """The checks of the module docstring.  ``rests``: (start, stop) sample ranges; ``sigma_sg``:
    σ of the six S, G the estimator reports; the rest from ``kf_hand``'s hand diagnostics.
    ``check_accelerometer`` False: the accelerometer is estimated with the gyro (``kf_hand_joint``), whose
    own |f̂| = g test at the rests replaces check 1.  ``slow_residual_m_s2`` (with its times and rate):
    |f_lp − K r̂| − g over the filtered span, for check 4 (skipped when None).  ``accelerometer_source``: what
    calibrated the accelerometer (None: assumed calibrated), named by check 1 instead of its advice to calibrate it.
    ``acc_noise_density_m_s2_sqrt_hz``: the accelerometer's white density, whose share check 4 takes off
    (:func:`slow_displacement`; None: nothing taken off)."""
    notes: list[str] = []
    ok = True
    details: dict = {}
    means, se = _rest_means(np.asarray(acc_m_s2, float), np.asarray(t_s, float), rests)
    eps = spread = None
    if check_accelerometer and means.shape[0] >= 2:
        norms = np.linalg.norm(means, axis=1)
        dirs = means / norms[:, None]
        spread = float(np.degrees(np.arccos(np.clip((dirs @ dirs.T).min(), -1.0, 1.0))))
        dev = norms - norms[0]
        k = int(np.argmax(np.abs(dev)))
        eps = float(abs(dev[k]) / norms[0])
        noise = math.hypot(se[k], se[0]) / norms[0]
        sig = float(np.median(np.asarray(sigma_sg, float)))
        details.update({"rest_acc_norm_minus_first_mg": (dev / 9.80665 * 1e3).round(2).tolist(),
                        "rest_acc_norm_noise_g": float(noise), "median_sigma_sg": sig})
        if spread < SAME_POSE_DEG:
            notes.append(f"the calibrated-accelerometer assumption is untested: the {means.shape[0]} rests' gravity "
                         f"directions lie within {spread:.0f}° of each other, so |f| = g cannot be compared across "
                         "poses; rests in several attitudes (or a multi-pose accelerometer calibration) would test it")
        elif eps > sig and eps > NOISE_Z * noise:
            ok = False
            found = (f"|f| at rest differs between the {means.shape[0]} rest poses by up to {eps * 1e3:.1f} mg (noise "
                     f"{noise * 1e3:.2f} mg), which tilts kf_hand's gravity reference by ~{math.degrees(eps):.2f}° "
                     f"between poses and can bias S, G by ~{eps:.1e} — more than their σ (median {sig:.1e})")
            if accelerometer_source is None:
                notes.append(f"inconsistent: the accelerometer is not calibrated: {found}. kf_hand assumes a "
                             "calibrated accelerometer: calibrate it first or use calib run's default "
                             "(--accelerometer estimate)")
            else:
                notes.append(f"inconsistent: with the accelerometer from {accelerometer_source}, {found}: that "
                             "calibration does not hold at every pose of this session. Take S, G as good to "
                             f"~{eps:.1e}, not their σ; rests in more attitudes would calibrate the accelerometer "
                             "for all of them")
    if tremor_band_rms_m_s2 > TREMOR_MAX_M_S2:
        ok = False
        notes.append(
            f"inconsistent: {tremor_band_rms_m_s2:.2f} m/s² RMS of acceleration above the 4-Hz pre-filter is "
            f"not a hand's tremor (at most 0.35 m/s² peak; this check's limit {TREMOR_MAX_M_S2:.1f} m/s²): impacts, "
            "vibration or fast motion, whose bursts the hand model averages over the session — S, G and σ are not "
            "trustworthy. Record the rotations by hand without tapping or shaking the device"
        )
    r = np.asarray(lever_arm_m, float)
    rn = float(np.linalg.norm(r))
    if rn > LEVER_ARM_MAX_M:
        ok = False
        rsd = float(np.linalg.norm(np.asarray(lever_arm_std_m, float)))
        notes.append(f"inconsistent: the lever arm found, {rn * 100:.1f} ± {rsd * 100:.1f} cm, is beyond a hand's "
                     f"({LEVER_ARM_MAX_M * 100:.0f} cm, a forearm): the session's translation was read as a rotation "
                     "about a far point. Turn the device in the hand (wrist), without moving the arm")
    slow = None if slow_residual_m_s2 is None else slow_displacement(slow_residual_m_s2, slow_residual_t_s, rate_hz,
                                                                      acc_noise_density_m_s2_sqrt_hz)
    if slow is not None:
        details.update({"slow_displacement_rms_m": slow.rms_m, "slow_displacement_noise_m": slow.noise_m,
                        "slow_displacement_beyond_noise_m": slow.beyond_noise_m,
                        "slow_displacement_noise_sd_m2": slow.noise_sd_m2, "slow_displacement_noise_z": SLOW_NOISE_Z,
                        "slow_displacement_max_m": DISPLACEMENT_MAX_M, "slow_band_hz": list(SLOW_BAND_HZ)})
        if slow.exceeds(DISPLACEMENT_MAX_M):
            ok = False
            notes.append(
                f"inconsistent: the acceleration kf_hand attributes to the hand has slow content (periods "
                f"{1 / SLOW_BAND_HZ[1]:.0f}–{1 / SLOW_BAND_HZ[0]:.0f} s) that would move a hand by "
                f"{slow.beyond_noise_m:.2f} m RMS"
                + (f" (beyond the {slow.noise_m:.2f} m the accelerometer's noise accounts for)" if slow.noise_m else "")
                + f", more than the {DISPLACEMENT_MAX_M:.2f} m a hand turning a device moves at most "
                f"(largest around t = {slow.worst_t_s:.0f} s). Either the device travelled (carried, walked, "
                "swung at arm's length about a moving pivot) or it is a sensor effect the model lacks — an "
                "accelerometer calibration error, a time offset between gyro and accelerometer, a drifting "
                "accelerometer bias; kf_hand fitted it as the hand's acceleration and weighted S, G by it, so "
                "S, G and σ are not trustworthy. "
                + ("Check the accelerometer calibration (calib run --method kf_hand_joint estimates it) and the "
                   if check_accelerometer else "Check the ")
                + "gyro–accelerometer time alignment, trace the residual with calib closeloop, and record again "
                "turning the device at the wrist without moving the arm"
            )
    return HandAssumptions(ok, tuple(notes), eps, spread, float(tremor_band_rms_m_s2), rn, details)


CONFOUND_CORRELATION = 0.98


def refuse_confounded(P: np.ndarray, layout: StateLayout, threshold: float = CONFOUND_CORRELATION) -> None:
    """Refuse (RecordingError) a session whose motion cannot tell the lever arm from S, G: a posterior correlation
    (``P`` (n, n) of ``layout``) above ``threshold`` between a lever arm state and one of S, G (module docstring)."""
    ol = layout.offset("lever_arm")
    sd = np.sqrt(np.clip(np.diag(P), 1e-300, None))
    corr = P / np.outer(sd, sd)
    names = layout.names
    bad = []
    for i in range(ol, ol + 3):
        for j in range(3, 9):
            if abs(corr[i, j]) > threshold:
                bad.append(f"lever arm {names[i]} with {names[j]} (correlation {corr[i, j]:+.3f})")
    if bad:
        raise RecordingError(
            "this session's motion cannot separate the hand's lever arm from the gyro errors: "
            + "; ".join(bad)
            + ". The lever arm's acceleration grows with ω² and ω̇, a scale or axis error's attitude error with the "
            "angle turned: repeat the rotations about each axis at two clearly different speeds (one at least "
            "twice the other), including rotations about horizontal axes — or use the hand-blind filter (--method "
            "kf_joint; kf_session_r with the accelerometer calibrated) if the device turned about its own sensor (no "
            "lever arm)"
        )
