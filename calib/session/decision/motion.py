"""What the motion of a session is, before S and G are estimated from it: a hand turning a device, a
board carried along a path, tapping or vibration, at rest — and, for the magnetometer, a magnet nearby.

The session estimators (``kf_hand``, ``kf_session``) read the gyro's scale factor S and
non-orthogonality G from how the gyro-propagated attitude disagrees with the gravity direction the
accelerometer sees.  Their model of what else moves the specific force is a hand: a lever arm from the
wrist (f = g + ω̇×r + ω×(ω×r)) and a small, stationary external acceleration.  A board carried along a
path adds large, slow accelerations without the rotation that would explain them; the estimator reads
them as tilt and fits S and G to it (BROAD's translation trials: S up to 0.5 with σ 0.03 on a
maker-calibrated IMU).  Taps add impulses the hand model averages over the session.  This module
names the motion window by window from the data alone, so the caller can refuse to read S and G from
a motion that breaks the model (:class:`MotionClassification`).

Per window of ``window_s`` (4 s by default; a hand-held board needs a few seconds to travel):

* **at rest**: mean |ω − b| below ``rest_rate_deg_s`` (b: the gyro's rest level);
* **carried along a path**: the displacement the specific force implies beyond the wrist's lever arm
  exceeds ``carried_displacement_m``.  The gyro-propagated attitude rotates f into the navigation
  frame, gravity is its slow (< 0.05 Hz) part, the rest is acceleration; the lever-arm term
  K(ω, ω̇) r (r fitted to the session by least squares, the regressor of
  :func:`calib.session.hand.filter.lever_regressor`) is removed, and the residual integrated twice in the
  0.2–2 Hz band (x(f) = −a(f)/(2πf)², Fourier domain).  Measured (4-s windows, RMS): a hand turning the
  BROAD board 1.4–6.7 cm (10th–90th percentile over the rotation trials, slow and fast), the same board
  carried along paths 6.6–25 cm (10th–90th over the five translation trials; medians 11–17 cm),
  combined rotation and translation 10–19 cm; gyrosim's hands stay below a few millimetres.  The band
  starts at 0.2 Hz because the gyro-propagated attitude's slow errors (a residual bias) leak gravity
  into the lowest frequencies, where 1/f² magnifies them; hand-held paths have most of their power
  above it.  The accelerometer's white noise (density N, one-sided PSD 2N² per axis) reads as a displacement
  too, x_n² = 3 Σ_band 2N² |G(f)|² Δf / (2πf)⁴ (G the filters'): with the density given, a window is carried when
  d² − x_n² exceeds the threshold² — negligible for MEMS accelerometers (~0.1 mm at 200 µg/√Hz), but ~6 cm for the
  paper's simulated 15 mg/√Hz one, which called a fifth of its windows carried with the hand turning it;
* **tapping or vibration**: the specific force above the 4-Hz tremor band, less the lever arm's part,
  has impulses: a peak above ``tap_peak_m_s2`` (2 g) with a kurtosis above ``tap_kurtosis`` within the
  window (BROAD's tapping trial: peaks 78 m/s² median, kurtosis 172; every other trial and gyrosim's
  hands: peaks ≤ 13 m/s², kurtosis ≤ 15), or sustained content above 30 Hz beyond
  ``vibration_rms_m_s2`` (a vibrating phone or motor; a hand's motion has none there);
* **hand turning**: every other moving window;
* **magnet nearby** (a flag beside the label, for the magnetometer only): |m| departs from the session's
  median by more than ``magnet_fraction`` of it.

The session: S and G can be read from it (``model_holds``) when the windows carried along a path are at
most ``max_carried_fraction`` of the moving windows and the tapped ones at most ``max_tapping_fraction``
(BROAD: 0–3 % of the rotation trials' moving windows read as carried, 79–100 % of the translation and
combined trials').  The lever arm fitted here is reported, not judged: an uncalibrated accelerometer's bias,
rotating with the body, lends it decimetres (gyrosim's MPU-9250 with a 7-cm wrist: 33 cm raw, 6 cm compensated).
Otherwise :attr:`MotionClassification.reason` says what broke the model
and :attr:`MotionClassification.advice` what motion would determine S and G.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from gyrosim.lazy import lazy_module
from gyrosim.recording import Recording
from gyrosim.rotations import quat_conjugate, quat_from_two_vectors, quat_rotate, skew
from gyrosim.strapdown import integrate_gyro

sp_signal = lazy_module("scipy.signal")   # imported on first use: not before a bad file is refused

__all__ = ["MotionParams", "MotionClassification", "classify_motion", "LABELS"]

# window labels, in the order of precedence (a tapped window that also travelled is "tapping")
LABELS = ("rest", "tapping", "carried", "turning")
_TEXT = {"rest": "at rest", "tapping": "tapping or vibration", "carried": "carried along a path",
         "turning": "a hand turning the device"}
LEVER_ARM_MAX_M = 0.30      # a forearm (calib.session.hand.checks.LEVER_ARM_MAX_M)


@dataclass(frozen=True)
class MotionParams:
    """Thresholds of :func:`classify_motion` (module docstring gives where each comes from)."""

    window_s: float = 4.0
    rest_rate_deg_s: float = 3.0
    carried_displacement_m: float = 0.08
    band_hz: tuple[float, float] = (0.2, 2.0)
    gravity_cutoff_hz: float = 0.05
    tap_peak_m_s2: float = 19.6
    tap_kurtosis: float = 20.0
    vibration_band_hz: float = 30.0
    vibration_rms_m_s2: float = 2.0
    magnet_fraction: float = 0.10
    max_carried_fraction: float = 0.20
    max_tapping_fraction: float = 0.10


@dataclass(frozen=True)
class MotionClassification:
    """What the session's motion is (module docstring): per window a label of :data:`LABELS` and the numbers
    behind it; for the session the fractions, whether S and G can be read from it, and why not."""

    window_s: float
    window_t_s: np.ndarray = field(repr=False)
    labels: tuple[str, ...] = field(repr=False)
    displacement_m: np.ndarray = field(repr=False)
    rate_deg_s: np.ndarray = field(repr=False)
    tap_peak_m_s2: np.ndarray = field(repr=False)
    magnet: np.ndarray | None = field(repr=False)
    lever_arm_m: np.ndarray = field(default_factory=lambda: np.zeros(3))
    params: MotionParams = MotionParams()
    acc_noise_density_m_s2_sqrt_hz: float | None = None   # the density whose share was taken off (None: none)
    noise_displacement_m: float = 0.0                       # that share, per window (RMS, 3-D)

    def fraction(self, label: str) -> float:
        """Share of all windows with ``label``."""
        return float(np.mean([lb == label for lb in self.labels])) if self.labels else 0.0

    def moving_fraction(self, label: str) -> float:
        """Share of the moving (not rest) windows with ``label`` (0 when nothing moved)."""
        moving = [lb for lb in self.labels if lb != "rest"]
        return float(np.mean([lb == label for lb in moving])) if moving else 0.0

    @property
    def magnet_nearby(self) -> bool:
        """A magnet or magnetic disturbance near the device in more than one window (magnetometer only)."""
        return self.magnet is not None and int(np.sum(self.magnet)) > 1

    @property
    def kind(self) -> str:
        """The session in words: the most common moving label, "at rest" when nothing moved."""
        moving = [lb for lb in self.labels if lb != "rest"]
        if not moving:
            return _TEXT["rest"]
        best = max(("tapping", "carried", "turning"), key=moving.count)
        return _TEXT[best]

    @property
    def lever_arm_is_a_hand(self) -> bool:
        return float(np.linalg.norm(self.lever_arm_m)) <= LEVER_ARM_MAX_M

    @property
    def model_holds(self) -> bool:
        """S and G can be read from this motion: a hand turning the device, no path, no taps (module docstring)."""
        moving = [lb for lb in self.labels if lb != "rest"]
        return (bool(moving) and self.moving_fraction("carried") <= self.params.max_carried_fraction
                and self.moving_fraction("tapping") <= self.params.max_tapping_fraction)

    @property
    def reason(self) -> str:
        """Why S and G cannot be read from this motion ('' when they can)."""
        if self.model_holds:
            return ""
        parts = []
        if not any(lb != "rest" for lb in self.labels):
            return "the device stayed at rest: nothing turned it"
        carried, tapped = self.moving_fraction("carried"), self.moving_fraction("tapping")
        if carried > self.params.max_carried_fraction:
            parts.append(f"carried along a path in {carried:.0%} of the moving time ("
                         f"{np.median(self.displacement_m[self._is('carried')]) * 100:.0f} cm per "
                         f"{self.window_s:.0f} s, a hand turning it: a few cm)")
        if tapped > self.params.max_tapping_fraction:
            parts.append(f"taps or vibration in {tapped:.0%} of the moving time")
        return "; ".join(parts)

    @property
    def advice(self) -> str:
        """What motion would determine S and G ('' when this one does)."""
        if self.model_holds:
            return ""
        return "turning it in the hand about each axis, without carrying or tapping it, determines them"

    def _is(self, label: str) -> np.ndarray:
        return np.array([lb == label for lb in self.labels], bool)

    def to_dict(self) -> dict:
        """The JSON block (``motion`` in ``calib run --json``): fractions, verdict, reason, thresholds."""
        moving = self._is("rest") == 0
        disp = self.displacement_m[moving & self._is("turning")] if moving.any() else np.zeros(0)
        return {"kind": self.kind, "model_holds": self.model_holds, "reason": self.reason, "advice": self.advice,
                "window_s": self.window_s, "windows": len(self.labels),
                "fraction": {lb: round(self.fraction(lb), 4) for lb in LABELS},
                "moving_fraction": {lb: round(self.moving_fraction(lb), 4) for lb in LABELS if lb != "rest"},
                "displacement_m_median": {lb: (float(np.median(self.displacement_m[self._is(lb)]))
                                               if self._is(lb).any() else None) for lb in LABELS},
                "turning_displacement_m_p90": float(np.percentile(disp, 90)) if disp.size else None,
                "lever_arm_m": [float(v) for v in self.lever_arm_m],
                "noise_displacement_m": self.noise_displacement_m,
                "magnet_nearby": self.magnet_nearby,
                "magnet_fraction": None if self.magnet is None else round(float(np.mean(self.magnet)), 4),
                "thresholds": {"rest_rate_deg_s": self.params.rest_rate_deg_s,
                               "carried_displacement_m": self.params.carried_displacement_m,
                               "band_hz": list(self.params.band_hz), "tap_peak_m_s2": self.params.tap_peak_m_s2,
                               "tap_kurtosis": self.params.tap_kurtosis,
                               "max_carried_fraction": self.params.max_carried_fraction,
                               "max_tapping_fraction": self.params.max_tapping_fraction,
                               "lever_arm_max_m": LEVER_ARM_MAX_M}}

    def lines(self) -> list[str]:
        """One line for the terminal: what the motion is and, when S and G cannot be read from it, why, what it
        does to the result and what motion would determine them."""
        share = ", ".join(f"{_TEXT[lb]} {self.fraction(lb):.0%}" for lb in LABELS if self.fraction(lb) > 0)
        if self.model_holds:
            return [f"motion: {self.kind} ({share} of {len(self.labels)} windows of {self.window_s:.0f} s)"]
        return [f"motion: {self.reason} — S, G cannot be read from it: left at the prior; {self.advice}"]


def _lowpass(x: np.ndarray, rate_hz: float, cutoff_hz: float, order: int = 2) -> np.ndarray:
    b, a = sp_signal.butter(order, min(cutoff_hz / (rate_hz / 2), 0.9))
    return sp_signal.filtfilt(b, a, x, axis=0)


def _highpass(x: np.ndarray, rate_hz: float, cutoff_hz: float, order: int = 2) -> np.ndarray:
    b, a = sp_signal.butter(order, min(cutoff_hz / (rate_hz / 2), 0.9), btype="high")
    return sp_signal.filtfilt(b, a, x, axis=0)


def _lever(w_rad_s: np.ndarray, t_s: np.ndarray) -> np.ndarray:
    """K(ω, ω̇) = [ω̇×] + [ω×]² (N, 3, 3): the lever arm's specific force K r (body)."""
    dw = np.gradient(w_rad_s, t_s, axis=0)
    sw = skew(w_rad_s)
    return skew(dw) + sw @ sw


def _fit_lever(k: np.ndarray, a: np.ndarray, use: np.ndarray) -> np.ndarray:
    if use.sum() < 10:
        return np.zeros(3)
    r, *_ = np.linalg.lstsq(k[use].reshape(-1, 3), a[use].reshape(-1), rcond=None)
    return r


def _band_displacement(a_m_s2: np.ndarray, rate_hz: float, band_hz: tuple[float, float]) -> np.ndarray:
    """x(t) (N, 3) with x(f) = −a(f)/(2πf)² inside ``band_hz``, zero outside (Fourier domain)."""
    n = a_m_s2.shape[0]
    f = np.fft.rfftfreq(n, 1.0 / rate_hz)
    spec = np.fft.rfft(a_m_s2 - a_m_s2.mean(axis=0), axis=0)
    inside = (f >= band_hz[0]) & (f <= band_hz[1])
    out = np.zeros_like(spec)
    out[inside] = -spec[inside] / (2 * math.pi * f[inside, None]) ** 2
    return np.fft.irfft(out, n=n, axis=0)


def _windows(n: int, w: int) -> list[slice]:
    return [slice(i * w, (i + 1) * w) for i in range(max(1, n // w))]


def classify_motion(rec: Recording, bias_rad_s: np.ndarray | None = None, params: MotionParams = MotionParams(),
                    acc_noise_density_m_s2_sqrt_hz: float | None = None) -> MotionClassification:
    """Label each window of ``rec`` and judge the session (module docstring).  ``bias_rad_s``: the gyro's rest
    level (default: the median gyro over the windows that turn least, :func:`calib.inputs.motion.summarise_motion`);
    ``acc_noise_density_m_s2_sqrt_hz``: the accelerometer's white density, whose share of the displacement is taken
    off (None: nothing taken off)."""
    with np.errstate(all="ignore"):
        return _classify(rec, bias_rad_s, params, acc_noise_density_m_s2_sqrt_hz)


def _noise_displacement2(density: float | None, rate_hz: float, band_hz: tuple[float, float], cut_hz: float,
                         params: MotionParams) -> float:
    """x_n² (m²): the mean square 3-D displacement white accelerometer noise of ``density`` gives through the
    classifier's filters — the gravity high-pass and the ``cut_hz`` low-pass (second order, forward and backward:
    |H|⁴ of a Butterworth's |H|²) — in ``band_hz`` (module docstring)."""
    if density is None or not math.isfinite(density):
        return 0.0
    f = np.linspace(band_hz[0], band_hz[1], 2001)
    lp2 = 1.0 / (1.0 + (f / cut_hz) ** 4)                      # |H|² of the 2nd-order low-pass at cut_hz
    hp2 = 1.0 - 1.0 / (1.0 + (f / params.gravity_cutoff_hz) ** 4)
    psd = 2.0 * density**2 * lp2**2 * hp2**2 / (2 * math.pi * f) ** 4
    return 3.0 * float(np.sum(0.5 * (psd[1:] + psd[:-1]) * np.diff(f)))


def _rest_level(rec: Recording) -> np.ndarray:
    from calib.inputs.motion import summarise_motion

    level = summarise_motion(rec).rest_level_rad_s
    return np.zeros(3) if level is None else np.asarray(level, float)


def _classify(rec: Recording, bias_rad_s: np.ndarray | None, params: MotionParams,
              acc_noise_density: float | None) -> MotionClassification:
    fs, t = rec.rate_hz, np.asarray(rec.t_s, float)
    b = _rest_level(rec) if bias_rad_s is None else np.asarray(bias_rad_s, float)
    w = np.asarray(rec.gyro_rad_s, float) - b
    f = np.asarray(rec.acc_m_s2, float)
    rate = np.degrees(np.linalg.norm(w, axis=1))
    # the attitude from the gyro, levelled on the first second's specific force
    f0 = f[: max(1, int(fs))].mean(axis=0)
    q = integrate_gyro(t, w, quat_from_two_vectors(f0 / (np.linalg.norm(f0) or 1.0), np.array([0.0, 0.0, 1.0])))
    f_nav = quat_rotate(q, f)
    cut = min(params.band_hz[1], 0.4 * fs)
    a_nav = _lowpass(f_nav - _lowpass(f_nav, fs, params.gravity_cutoff_hz), fs, cut)
    a_body = quat_rotate(quat_conjugate(q), a_nav)
    k_slow = _lever(_lowpass(w, fs, cut), t)
    moving = rate > params.rest_rate_deg_s
    r = _fit_lever(k_slow, a_body, moving)
    x = _band_displacement(a_nav - quat_rotate(q, k_slow @ r), fs, params.band_hz)
    noise2 = _noise_displacement2(acc_noise_density, fs, params.band_hz, cut, params)
    # above the tremor band: the specific force less the lever arm's part there (its own fit)
    k_fast = _lever(_lowpass(w, fs, min(25.0, 0.4 * fs)), t)
    k_hf = k_fast - _lowpass(k_fast.reshape(-1, 9), fs, 4.0).reshape(-1, 3, 3)
    f_hf = f - _lowpass(f, fs, 4.0)
    f_hf = f_hf - k_hf @ _fit_lever(k_hf, f_hf, moving)
    f_vib = _highpass(f, fs, params.vibration_band_hz) if fs > 2.5 * params.vibration_band_hz else None
    mag = None
    if rec.mag_ut is not None:
        m = np.linalg.norm(np.asarray(rec.mag_ut, float), axis=1)
        mag = np.abs(m / (np.median(m) or 1.0) - 1.0) > params.magnet_fraction
    n_w = max(1, int(round(params.window_s * fs)))
    labels, disp, rates, peaks, magnet, t_w = [], [], [], [], [], []
    for s in _windows(rec.n, n_w):
        e = np.linalg.norm(f_hf[s], axis=1)
        peak = float(e.max())
        kurt = float(np.mean(e**4) / max(np.mean(e**2) ** 2, 1e-30))
        vib = f_vib is not None and float(np.sqrt(np.mean(np.sum(f_vib[s] ** 2, axis=1)))) > params.vibration_rms_m_s2
        d = float(np.sqrt(np.mean(np.sum(x[s] ** 2, axis=1))))
        mean_rate = float(np.mean(rate[s]))
        if mean_rate <= params.rest_rate_deg_s:
            label = "rest"
        elif (peak > params.tap_peak_m_s2 and kurt > params.tap_kurtosis) or vib:
            label = "tapping"
        elif d * d - noise2 > params.carried_displacement_m**2:
            label = "carried"
        else:
            label = "turning"
        labels.append(label)
        disp.append(d)
        rates.append(mean_rate)
        peaks.append(peak)
        t_w.append(float(t[s][0]))
        if mag is not None:
            magnet.append(bool(np.mean(mag[s]) > 0.5))
    return MotionClassification(params.window_s, np.array(t_w), tuple(labels), np.array(disp), np.array(rates),
                                np.array(peaks), None if mag is None else np.array(magnet, bool), r, params,
                                acc_noise_density, math.sqrt(noise2))
