"""White-noise levels of a recording, estimated from its own rest data, with floors.

An estimator under test sees only what a real recording carries: the noise levels come from the
data (never from a simulator's stored sensor model).  Per triad, the per-sample σ is the standard
deviation over the first rest segment (mean of the three axes; hand tremor at rest inflates it,
which only makes the filter more cautious), and the density N = σ/√f_s (IEEE 952, the convention
of :class:`gyrosim.effects.WhiteNoise` and Kalibr's continuous-time noise density).

A noise-free or coarsely quantised input must not give σ = 0 (R = 0 makes the filter's innovation
covariance singular: the last round's noise-free input diverged to S_x = 2.9e6).  Each σ is
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
        noise-free input is exempted from use :attr:`noise_free` (tests/test_quantised_not_noise_free.py)."""
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

    def to_dict(self) -> dict[str, float]:
        return {"gyro_sigma_rad_s": self.gyro_sigma_rad_s, "acc_sigma_m_s2": self.acc_sigma_m_s2,
                "gyro_measured_rad_s": self.gyro_measured_rad_s, "acc_measured_m_s2": self.acc_measured_m_s2,
                "gyro_floor_rad_s": self.gyro_floor_rad_s, "acc_floor_m_s2": self.acc_floor_m_s2,
                "gyro_lsb_rad_s": self.gyro_lsb_rad_s, "acc_lsb_m_s2": self.acc_lsb_m_s2}


def estimate_noise(gyro_rad_s: np.ndarray, acc_m_s2: np.ndarray, rest: tuple[int, int], rate_hz: float,
                   gravity_m_s2: float = 9.80665) -> NoiseLevels:
    """σ per sample of both triads over ``rest`` = [a, b) sample indices, with the floors of the
    module docstring (ω̇ from the rate smoothed over 0.05 s)."""
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
    g_floor = max(lsb_g / math.sqrt(12.0), NUMERICAL_FLOOR_GYRO_RAD_S)
    f_floor = max(lsb_f / math.sqrt(12.0), gravity_m_s2 * dt * dt * wdot_max / 12.0, NUMERICAL_FLOOR_ACC_M_S2)
    return NoiseLevels(max(g_meas, g_floor), max(f_meas, f_floor), g_meas, f_meas, g_floor, f_floor, lsb_g, lsb_f,
                       rate_hz)


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
    did: +6 % on N, synthetic rest of tests/test_hand.py; the same rest gives the same number of
    independent PSD averages either way, more bins of fewer segments).  Both because a shaky hand's tremor is
    ~60 dB above the sensor's white floor: (i) a Hann window's sidelobes (−31 dB, falling 18 dB/octave)
    leak it 3–7 bins away, into 15–20 Hz; (ii) what is quadratic in the tremor — the centripetal
    ω_tr × (ω_tr × r) of the rotational tremor at the lever arm — sits at the sum frequencies, 16–24 Hz
    for an 8–12 Hz tremor.  Measured (zhou2020_sim_consumer, true N = 1.47e-4 m/s²/√Hz, shaky hand, 3
    seeds): Hann 15–45 Hz 1.65–1.85e-4 (R = σ_f²/D overstated ×1.25–1.6, σ pessimistic), Blackman–Harris
    15–45 Hz 1.47–1.64e-4, Blackman–Harris 25–45 Hz 1.43–1.50e-4.  None when the rate leaves no such band
    or the rest is shorter than 2 s."""
    p = _white_band_psd(x, rate_hz)
    return None if p is None else float(np.sqrt(np.mean(p) / 2.0))


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
    hi = 0.45 * rate_hz
    if hi <= WHITE_BAND_HZ + 5.0 or x.shape[0] < 2 * rate_hz:
        return None
    lo = WHITE_BAND2_HZ if hi >= WHITE_BAND2_HZ + 10.0 else WHITE_BAND_HZ
    f, pxx = sp_signal.welch(x - x.mean(axis=0), fs=rate_hz, window="blackmanharris",
                             nperseg=int(min(x.shape[0], WHITE_SEGMENT_S * rate_hz)), axis=0)
    band = (f >= lo) & (f <= hi)
    return pxx[band]
