"""The tremor pre-filter: a zero-phase Butterworth low-pass below a hand's tremor (8–12 Hz) and above the
calibration's rotations (< 1 Hz).

``kf_hand`` rotates the specific force to nav with the gyro's own attitude, low-passes it there (so that the slow
gravity direction, not the fast wobble the gyro also sees, is what is smoothed) and rotates it back — a whitening
pre-filter — and then updates every D-th sample with R = σ_f²/D, D = ⌊1/ρ⌋, ρ = Σh² the low-pass's white-noise
variance ratio (:func:`variance_ratio`): the information per second of the raw samples, not more.  The lever arm's
regressor and the hand-aware bound use the same low-pass (:mod:`calib.session.hand.lever`,
:func:`calib.session.bounds.hand_crlb`); ``calib run``'s coaching splits the hand's acceleration at it.
"""

from __future__ import annotations

import numpy as np
from scipy import signal as sp_signal

__all__ = ["CUTOFF_HZ", "ORDER", "lowpass_design", "lowpass", "lowpass_gain2", "variance_ratio"]

CUTOFF_HZ = 4.0            # below the tremor band (8–12 Hz), above the schedule's rotations (< 1 Hz)
ORDER = 4                  # Butterworth poles (applied forwards and backwards: zero phase, |H_b|² in power)


def lowpass_design(rate_hz: float, cutoff_hz: float = CUTOFF_HZ, order: int = ORDER) -> tuple[np.ndarray, np.ndarray]:
    """The tremor low-pass's Butterworth (b, a): ``order`` poles at ``cutoff_hz`` (capped at 0.9 of Nyquist)."""
    return sp_signal.butter(order, min(cutoff_hz / (rate_hz / 2), 0.9))


def lowpass(x: np.ndarray, rate_hz: float, cutoff_hz: float = CUTOFF_HZ, order: int = ORDER) -> np.ndarray:
    """``x`` (N, …) low-passed along axis 0, zero-phase (forward and backward)."""
    b, a = lowpass_design(rate_hz, cutoff_hz, order)
    return sp_signal.filtfilt(b, a, x, axis=0)


def lowpass_gain2(f_hz: np.ndarray, rate_hz: float, cutoff_hz: float = CUTOFF_HZ, order: int = ORDER) -> np.ndarray:
    """|H(f)|² of :func:`lowpass` (zero-phase: the Butterworth's |H_b|², squared), at any f (periodic in
    ``rate_hz``)."""
    b, a = lowpass_design(rate_hz, cutoff_hz, order)
    return np.abs(sp_signal.freqz(b, a, worN=np.asarray(f_hz, float), fs=rate_hz)[1]) ** 4


def variance_ratio(rate_hz: float, cutoff_hz: float = CUTOFF_HZ, order: int = ORDER) -> float:
    """ρ = Σh² of the zero-phase low-pass's impulse response: its white-noise variance ratio."""
    n = int(40 * rate_hz / cutoff_hz) + 64
    imp = np.zeros(n)
    imp[n // 2] = 1.0
    return float(np.sum(lowpass(imp, rate_hz, cutoff_hz, order) ** 2))
