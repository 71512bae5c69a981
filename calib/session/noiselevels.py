"""White-noise levels of a recording, estimated from its own rest data, with floors.

An estimator under test sees only what a real recording carries: the noise levels come from the
data (never from a simulator's stored sensor model).  Per triad, the per-sample σ is the standard
deviation over the first rest segment (mean of the three axes; hand tremor at rest inflates it,
which only makes the filter more cautious), and the density N = σ/√f_s (IEEE 952, the convention
of :class:`gyrosim.effects.WhiteNoise` and Kalibr's continuous-time noise density).

A noise-free or coarsely quantised input must not give σ = 0 (R = 0 makes the filter's innovation
covariance singular: a noise-free input once diverged to S_x = 2.9e6).  Each σ is
therefore at least its floor:

* quantisation: LSB/√12, the LSB being the smallest step between the channel's distinct values
  (a 16-bit MEMS channel; a CSV written with 9 digits has an LSB of 1e-9 of the value);
* accelerometer, the filter's own discretisation: the trapezoid + coning attitude integration of
  a smooth rate errs by at most Δt²·|ω̇|/12 rad between samples (local error of the trapezoid rule
  over a step, which does not accumulate for a smooth profile), seen by the accelerometer as
  g·Δt²·max|ω̇|/12; at 100 Hz and the zhou2020 profile 0.4 µrad·g ≈ 5e-5 m/s²;
* numerical: 1e-6 m/s² and 1e-8 rad/s, far below any real sensor, keeping P well conditioned.

The floors are the "discretisation limit" of a calibration: parameters of a noise-free record are
recovered to the error these floors allow, ~1e-6 (see docs/real_imu.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import signal as sp_signal

__all__ = ["NoiseLevels", "estimate_noise", "quantization_step"]

NUMERICAL_FLOOR_ACC_M_S2 = 1e-6
NUMERICAL_FLOOR_GYRO_RAD_S = 1e-8


def _rolled_off_sigma(chk: WhiteDensity | None, rate_hz: float) -> float:
    """N_low √f_s when :func:`white_density_check` found an output low-pass in the rest, else 0."""
    return chk.density * math.sqrt(rate_hz) if chk is not None and chk.rolled_off else 0.0


def quantization_step(x: np.ndarray) -> float:
    """The smallest positive step between distinct values of any channel of ``x`` (N, 3) — the LSB
    of a quantised channel (0 if a channel is constant everywhere)."""
    steps = []
    for c in np.asarray(x, float).T:
        u = np.unique(c)
        if u.size > 1:
            d = np.diff(u)
            steps.append(float(d[d > 0].min()))
    return min(steps) if steps else 0.0


@dataclass(frozen=True)
class NoiseLevels:
    """Per-sample white-noise σ of both triads (SI) after their floors, and what set them."""

    gyro_sigma_rad_s: float
    acc_sigma_m_s2: float
    gyro_measured_rad_s: float
    acc_measured_m_s2: float
    gyro_floor_rad_s: float
    acc_floor_m_s2: float
    gyro_lsb_rad_s: float
    acc_lsb_m_s2: float
    rate_hz: float
    # the rest's spectrum per triad (white_density_check; None when the rest or the rate leaves no band): the densities
    # every estimator reads from this rest, computed here once
    gyro_white: WhiteDensity | None = None
    acc_white: WhiteDensity | None = None

    @property
    def arw_rad_s_sqrt_hz(self) -> float:
        return self.gyro_sigma_rad_s / math.sqrt(self.rate_hz)

    @property
    def vrw_m_s2_sqrt_hz(self) -> float:
        return self.acc_sigma_m_s2 / math.sqrt(self.rate_hz)

    @property
    def at_floor(self) -> bool:
        """Either triad's measured noise below its floor (a noise-free or coarsely quantised input).  Not a test
        for noise-free input: a real sensor with ~1 LSB of noise is at its floor too — the checks that
        noise-free input is exempted from use :attr:`noise_free` (tests/session/test_quantised_not_noise_free.py)."""
        return self.gyro_measured_rad_s < self.gyro_floor_rad_s or self.acc_measured_m_s2 < self.acc_floor_m_s2

    @property
    def noise_free(self) -> bool:
        """Either triad's measured rest noise below half its floor: a noise-free (simulated) input.  A real,
        coarsely quantised sensor whose noise is about one LSB (imucal's NilsPod accelerometer: 1.50e-2
        measured, floor LSB/√12 = 1.51e-2 m/s²) is :attr:`at_floor` but not noise-free."""
        return (self.gyro_measured_rad_s < 0.5 * self.gyro_floor_rad_s
                or self.acc_measured_m_s2 < 0.5 * self.acc_floor_m_s2)

    def notes(self) -> list[str]:
        out = []
        if self.gyro_measured_rad_s < self.gyro_floor_rad_s:
            out.append(f"gyro noise at rest {self.gyro_measured_rad_s:.2e} rad/s is below its floor "
                       f"{self.gyro_floor_rad_s:.2e} rad/s (quantisation/numerical): the floor is used")
        if self.acc_measured_m_s2 < self.acc_floor_m_s2:
            out.append(f"accelerometer noise at rest {self.acc_measured_m_s2:.2e} m/s² is below its floor "
                       f"{self.acc_floor_m_s2:.2e} m/s² (quantisation/discretisation): the floor is used")
        return out

    @property
    def gyro_density_rad_s_sqrt_hz(self) -> float | None:
        """The gyro's white density from the rest's spectrum (:func:`white_density`), None without a band."""
        return None if self.gyro_white is None else self.gyro_white.density

    @property
    def acc_density_m_s2_sqrt_hz(self) -> float | None:
        """The accelerometer's white density from the rest's spectrum (:func:`white_density`), None without a band."""
        return None if self.acc_white is None else self.acc_white.density

    def to_dict(self) -> dict[str, float]:
        return {"gyro_sigma_rad_s": self.gyro_sigma_rad_s, "acc_sigma_m_s2": self.acc_sigma_m_s2,
                "gyro_measured_rad_s": self.gyro_measured_rad_s, "acc_measured_m_s2": self.acc_measured_m_s2,
                "gyro_floor_rad_s": self.gyro_floor_rad_s, "acc_floor_m_s2": self.acc_floor_m_s2,
                "gyro_lsb_rad_s": self.gyro_lsb_rad_s, "acc_lsb_m_s2": self.acc_lsb_m_s2}


def estimate_noise(gyro_rad_s: np.ndarray, acc_m_s2: np.ndarray, rest: tuple[int, int], rate_hz: float,
                   gravity_m_s2: float = 9.80665) -> NoiseLevels:
    """σ per sample of both triads over ``rest`` = [a, b) sample indices, with the floors of the
    module docstring (ω̇ from the rate smoothed over 0.05 s); raised to N_low √f_s when the rest's spectrum shows an
    output low-pass (:func:`white_density_check`)."""
    a, b = rest
    g_rest, f_rest = gyro_rad_s[a:b], acc_m_s2[a:b]
    g_meas = float(np.mean(np.std(g_rest, axis=0)))
    f_meas = float(np.mean(np.std(f_rest, axis=0)))
    lsb_g = quantization_step(g_rest)
    lsb_f = quantization_step(f_rest)
    dt = 1.0 / rate_hz
    w = max(1, int(round(0.05 * rate_hz)))
    kernel = np.ones(w) / w
    smooth = np.stack([np.convolve(gyro_rad_s[:, i], kernel, mode="same") for i in range(3)], axis=1)
    wdot = np.linalg.norm(np.gradient(smooth, dt, axis=0), axis=1)
    wdot_max = float(np.percentile(wdot[w:-w], 99.9)) if wdot.size > 2 * w + 10 else float(wdot.max())
    # an output low-pass below Nyquist (white_density_check: found in the rest's spectrum) leaves the spread the
    # filtered noise's, N² × its equivalent bandwidth (a first-order 10-Hz corner at 100 Hz: σ 0.56 of N√f_s) — the
    # density that integrates is the low band's, so the per-sample σ is raised to N_low √f_s
    g_white, f_white = white_density_check(g_rest, rate_hz), white_density_check(f_rest, rate_hz)
    g_meas = max(g_meas, _rolled_off_sigma(g_white, rate_hz))
    f_meas = max(f_meas, _rolled_off_sigma(f_white, rate_hz))
    g_floor = max(lsb_g / math.sqrt(12.0), NUMERICAL_FLOOR_GYRO_RAD_S)
    f_floor = max(lsb_f / math.sqrt(12.0), gravity_m_s2 * dt * dt * wdot_max / 12.0, NUMERICAL_FLOOR_ACC_M_S2)
    return NoiseLevels(max(g_meas, g_floor), max(f_meas, f_floor), g_meas, f_meas, g_floor, f_floor, lsb_g, lsb_f,
                       rate_hz, g_white, f_white)


WHITE_BAND_HZ = 15.0       # sensor white noise measured above the tremor band (8–12 Hz)
WHITE_BAND2_HZ = 25.0      # … and above its second harmonic (16–24 Hz) when the rate allows (white_density)
WHITE_SEGMENT_S = 4.0      # Welch segments of white_density (Blackman–Harris main lobe ±1 Hz)


def white_density(x: np.ndarray, rate_hz: float) -> float | None:
    """White-noise density N (per √Hz, mean of the axes) of rest samples ``x`` (N, 3) from their spectrum
    above the tremor band (Welch, one-sided PSD 2N²): the rest segment's standard deviation would count the
    hand's tremor as sensor noise.  The band starts at ``WHITE_BAND2_HZ`` (25 Hz, above the tremor's
    second harmonic) when the rate leaves ≥ 10 Hz above it, else at ``WHITE_BAND_HZ`` (15 Hz), and ends at
    0.45 f_s; the window is Blackman–Harris (sidelobes −92 dB) over ``WHITE_SEGMENT_S`` = 4-s segments, so
    that its main lobe (±4 bins) spans ±1 Hz and a 24-Hz line does not reach 25 Hz (with 1-s segments it
    did: +6 % on N, synthetic rest of tests/session/test_hand.py; the same rest gives the same number of
    independent PSD averages either way, more bins of fewer segments).  Both because a shaky hand's tremor is
    ~60 dB above the sensor's white floor: (i) a Hann window's sidelobes (−31 dB, falling 18 dB/octave)
    leak it 3–7 bins away, into 15–20 Hz; (ii) what is quadratic in the tremor — the centripetal
    ω_tr × (ω_tr × r) of the rotational tremor at the lever arm — sits at the sum frequencies, 16–24 Hz
    for an 8–12 Hz tremor.  Measured (zhou2020_sim_consumer, true N = 1.47e-4 m/s²/√Hz, shaky hand, 3
    seeds): Hann 15–45 Hz 1.65–1.85e-4 (R = σ_f²/D overstated ×1.25–1.6, σ pessimistic), Blackman–Harris
    15–45 Hz 1.47–1.64e-4, Blackman–Harris 25–45 Hz 1.43–1.50e-4.  None when the rate leaves no such band
    or the rest is shorter than 2 s.

    **An output low-pass below the band** (a MEMS gyro's DLPF, an AHRS's decimation filter) leaves the band
    N²|H(f)|², not N²: the density that integrates into a bias and an attitude is the one at low frequency.
    :func:`white_density_check` compares the band with ``ROLLOFF_BAND_HZ`` (2–6 Hz: below the tremor, above
    the sway) and, when the low band is significantly higher, returns the low band's density instead — the
    number returned here."""
    chk = white_density_check(x, rate_hz)
    return None if chk is None else chk.density


ROLLOFF_BAND_HZ = (2.0, 6.0)   # the low band an output low-pass is checked in: below the tremor, above the sway
ROLLOFF_Z = 3.0                # the low band above the high one at z > 3 (one-sided: 0.13 % of flat-noise rests) …
SLOPE_Z = 2.0                  # … and the high band falling with frequency at z > 2 (one-sided 2.3 %; 4 % measured)


@dataclass(frozen=True)
class WhiteDensity:
    """The white-noise density of a rest (per √Hz: rad/s/√Hz or m/s²/√Hz, mean of the axes) and the roll-off
    check behind it (:func:`white_density_check`)."""

    density: float                     # the density used: the high band's, or the low band's when it rolled off
    high_band_density: float           # what the band above the tremor reads (white_density before the check)
    high_band_hz: tuple[float, float]
    low_band_density: float | None     # what 2–6 Hz reads (None: the rest is too short for it)
    low_band_hz: tuple[float, float]
    low_over_high_psd: float | None    # PSD ratio low band ÷ high band (1 for white noise)
    z: float | None                    # ln(that ratio) over its standard deviation from the bands' spread
    high_band_log_slope: float | None  # d ln PSD / d ln f over the high band (0 for white noise)
    slope_z: float | None              # −that slope over its standard error (> 0: falling)
    rolled_off: bool                   # z > ROLLOFF_Z and slope_z > SLOPE_Z: the low band's density is used

    def to_dict(self) -> dict:
        return {"density": self.density, "high_band_density": self.high_band_density,
                "high_band_hz": list(self.high_band_hz), "low_band_density": self.low_band_density,
                "low_band_hz": list(self.low_band_hz), "low_over_high_psd": self.low_over_high_psd,
                "z": self.z, "high_band_log_slope": self.high_band_log_slope, "slope_z": self.slope_z,
                "rolled_off": self.rolled_off}

    @property
    def rest_mean_density(self) -> float:
        """The density for the σ of a rest's *mean* (:mod:`calib.session.rest_bias`): the low band's whenever it is
        significantly higher (z > ``ROLLOFF_Z``), found roll-off or not.  A hand's motion at 2–6 Hz (the other
        reading of a higher low band) averages out of the mean and leaves this σ cautious; a roll-off the slope test
        missed (gyrosim's one-pole recursion at 10 Hz: 15 % of 9-s rests) would leave it ~3× small."""
        if self.low_band_density is not None and self.z is not None and self.z > ROLLOFF_Z:
            return max(self.density, self.low_band_density)
        return self.density

    def note(self, what: str, unit: str) -> str | None:
        """A report line when the roll-off was found, else None."""
        if not self.rolled_off:
            return None
        return (f"{what} noise rolls off below {self.high_band_hz[0]:.0f} Hz (an output low-pass): its PSD at "
                f"{self.low_band_hz[0]:.0f}–{self.low_band_hz[1]:.0f} Hz is {self.low_over_high_psd:.2f}× that at "
                f"{self.high_band_hz[0]:.0f}–{self.high_band_hz[1]:.0f} Hz (z = {self.z:.1f}); its white density "
                f"{self.density:.3g} {unit}/√Hz is read at {self.low_band_hz[0]:.0f}–{self.low_band_hz[1]:.0f} Hz "
                f"({self.high_band_density:.3g} above the tremor). A corner below ~10 Hz attenuates even that "
                "band: record with the output filter at its widest setting.")


def _band_mean_and_rel_sd(p: np.ndarray) -> tuple[float, float]:
    """Mean of PSD values (bins × axes) and its relative σ: their spread over √(their number / 2) — adjacent
    Blackman–Harris bins are correlated, about two per independent value (:func:`white_variance_relative_sd`)."""
    m = float(np.mean(p))
    return m, (float(np.std(p) / m * np.sqrt(2.0 / p.size)) if m > 0 else math.inf)


def white_density_check(x: np.ndarray, rate_hz: float) -> WhiteDensity | None:
    """:func:`white_density` with its roll-off check.  A first-order output low-pass at f_c leaves white noise
    the PSD 2N²/(1 + (f/f_c)²): at f_c = 10 Hz the 25–45 Hz band reads N² ×0.1 (the MPU-9250's DLPF_CFG 5:
    a rest's bias σ came out ×2.4 optimistic with every seed ``ok``, measured), the 2–6 Hz band ×0.87.

    Two tests, both needed.  (1) The low band is higher: z = ln(P̄_low/P̄_high)/√(s_low² + s_high²), P̄ each
    band's mean PSD over bins and axes, s its relative σ from the values' spread (:func:`_band_mean_and_rel_sd`),
    z > ``ROLLOFF_Z``.  (2) The high band itself falls with frequency: the least-squares slope of ln PSD (mean of
    the axes) on ln f over the high band, its standard error from the residual scatter ×√2 (about two correlated
    Blackman–Harris bins per independent value), −slope/SE > ``SLOPE_Z``.  A hand's rotation below the tremor
    raises the low band too but leaves the band above it flat: the x-IMU3 hand-held rest (tests/
    test_hand_measured.py) has 2–6 Hz at 4.2× the 25–45 Hz PSD (z 5.2) with a flat high band (slope z −0.4) —
    test (1) alone took its density ×2 and the hand's motion as sensor noise.  Power of (2) on 9-s rests at 100 Hz
    (100 draws each): a Butterworth at 10 Hz, 1 or 2 poles, z 15–23; gyrosim's one-pole recursion
    (:class:`gyrosim.effects.output.Bandwidth`, its response flattened near Nyquist) at 10 Hz 3.2 ± 1.3 (86 % found),
    20 Hz 53 %, 41 Hz 14 %; white noise 4 % above 2, and (1) and (2) together ≪ 1 %.  Found: N² = P̄_low/2
    (the low band's density; no extrapolation to 0 Hz — the filter's order and shape are unknown, and a first-order
    10-Hz corner still leaves 2–6 Hz 13 % low in N², 7 % in N).  Source: the white-noise PSD through a linear
    filter, S_y = |H|² S_x (Papoulis & Pillai, *Probability, Random Variables and Stochastic Processes*, 4th ed.,
    §9-3).  None as for :func:`white_density`."""
    psd = _rest_psd(x, rate_hz)
    band = _high_band_hz(rate_hz)
    if psd is None or band is None:
        return None
    lo, hi = band
    ph, sh = _band_mean_and_rel_sd(_select(psd, lo, hi))
    n_high = float(np.sqrt(ph / 2.0))
    pl = _select(psd, *ROLLOFF_BAND_HZ)
    if pl is None or ph <= 0:
        return WhiteDensity(n_high, n_high, band, None, ROLLOFF_BAND_HZ, None, None, None, None, False)
    ml, sl = _band_mean_and_rel_sd(pl)
    ratio = ml / ph
    z = float(math.log(ratio) / math.hypot(sl, sh)) if ratio > 0 and math.isfinite(sl) else -math.inf
    slope, slope_z = _log_slope(psd, lo, hi)
    n_low = float(np.sqrt(ml / 2.0))
    rolled = z > ROLLOFF_Z and slope_z > SLOPE_Z
    return WhiteDensity(n_low if rolled else n_high, n_high, band, n_low, ROLLOFF_BAND_HZ, float(ratio), z,
                        slope, slope_z, rolled)


def _log_slope(psd: tuple[np.ndarray, np.ndarray], lo_hz: float, hi_hz: float) -> tuple[float, float]:
    """The slope of ln PSD (mean of the axes) on ln f over [lo_hz, hi_hz] and −slope over its standard error (the
    residual scatter's, ×√2 for the correlated bins)."""
    f_all, pxx = psd
    keep = (f_all >= lo_hz) & (f_all <= hi_hz)
    lp, lf = np.log(np.maximum(pxx[keep].mean(axis=1), 1e-300)), np.log(f_all[keep])
    dx = lf - lf.mean()
    slope = float(np.sum(dx * (lp - lp.mean())) / np.sum(dx**2))
    resid = lp - lp.mean() - slope * dx
    se = math.sqrt(2.0 * float(np.sum(resid**2)) / max(lf.size - 2, 1) / float(np.sum(dx**2)))
    return slope, (-slope / se if se > 0 else (math.inf if slope < 0 else 0.0))


def white_variance_relative_sd(x: np.ndarray, rate_hz: float) -> float | None:
    """Relative standard deviation of :func:`white_density`'s N² (its band's mean PSD): the spread of the band's
    PSD values (each a Welch average) over √(their number / 2) — adjacent Blackman–Harris bins are correlated,
    about two per independent value.  What subtracting the white noise's variance from a band's power can resolve
    (kf_hand's tremor-band RMS) follows from it.  None as for :func:`white_density`."""
    p = _white_band_psd(x, rate_hz)
    if p is None or np.mean(p) <= 0:
        return None
    return float(np.std(p) / np.mean(p) * np.sqrt(2.0 / p.size))


def _white_band_psd(x: np.ndarray, rate_hz: float) -> np.ndarray | None:
    """The one-sided PSD values (bins × axes) of :func:`white_density`'s band, None when there is none."""
    psd, band = _rest_psd(x, rate_hz), _high_band_hz(rate_hz)
    return None if psd is None or band is None else _select(psd, *band)


def _high_band_hz(rate_hz: float) -> tuple[float, float] | None:
    """:func:`white_density`'s band (Hz): from 25 Hz (15 Hz when the rate leaves < 10 Hz above 25) to 0.45 f_s;
    None when the rate leaves no such band."""
    hi = 0.45 * rate_hz
    if hi <= WHITE_BAND_HZ + 5.0:
        return None
    return (WHITE_BAND2_HZ if hi >= WHITE_BAND2_HZ + 10.0 else WHITE_BAND_HZ), hi


def _rest_psd(x: np.ndarray, rate_hz: float) -> tuple[np.ndarray, np.ndarray] | None:
    """Welch's one-sided PSD (Blackman–Harris, ``WHITE_SEGMENT_S`` segments) of the de-meaned ``x`` (N, 3): the bin
    frequencies (Hz) and the values (bins × axes); None when the rest is shorter than 2 s."""
    if x.shape[0] < 2 * rate_hz:
        return None
    return sp_signal.welch(x - x.mean(axis=0), fs=rate_hz, window="blackmanharris",
                           nperseg=int(min(x.shape[0], WHITE_SEGMENT_S * rate_hz)), axis=0)


def _select(psd: tuple[np.ndarray, np.ndarray], lo_hz: float, hi_hz: float) -> np.ndarray | None:
    """The PSD values (bins × axes) at the bins in [lo_hz, hi_hz]; None when fewer than two fall there."""
    f, pxx = psd
    band = (f >= lo_hz) & (f <= hi_hz)
    return pxx[band] if band.sum() >= 2 else None
