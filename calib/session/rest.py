"""Static (rest) detection and bias by averaging over rest (Zhou 2020 §3.2, eq. 3).

Rest detection, thresholds from the recording's own noise, not magic numbers:

1. sliding windows of ``window_s`` (default 0.5 s, w samples); per window the summed variance of
   the three gyro axes v_g and of the three accelerometer axes v_a;
2. noise floors σ²_g, σ²_a = the 10th percentile of v over the session (the quietest windows: at
   rest their variance is sensor noise plus hand tremor, both of which the bias average removes);
3. a window is at rest when v ≤ σ² · q, q = χ²₀.₉₉₉(ν)/ν = 4.6 with ν = 4: at rest the signal
   may be narrowband hand tremor (8–12 Hz), which has only ~2·4 Hz·0.5 s = 4 degrees of freedom
   in a window, so the variance test is loose and only rejects clear motion; both triads must
   pass;
   and when its gyro mean m lies at the rest level: w‖m − b₀(t)‖² / (σ²_g/3) ≤ χ²₀.₉₉₉(3) = 16.3,
   b₀(t) the densest cluster of the low-variance windows' means within ±20 s (the unknown bias,
   local because it drifts: a warming MPU-9250 moves it by 0.09 °/s over the zhou2020 session).  The mean test
   is what separates a slow smooth rotation from rest when the gyro noise is large (Zhou's
   Table 7 noise: 5 °/s per sample hides a 0.2 rad/s change within a window);
4. runs of rest windows, merged across gaps shorter than one window, at least
   ``min_segment_s`` long are rest segments.

Limit: a constant-rate rotation about the vertical for a whole recording looks exactly like a
biased gyro at rest to these tests (gravity stays put); a calibration session starts at rest.

Bias (§3.2): the mean gyro output over the first rest segment; its standard error from batch
means (10 batches), which stays honest when tremor makes the samples correlated.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import stats

from gyrosim.errors import RecordingError
from gyrosim.recording import Recording

__all__ = ["RestSegments", "detect_rest", "BiasEstimate", "static_bias"]


@dataclass(frozen=True)
class RestSegments:
    """Rest segments as sample index ranges [start, stop) and times (s), with the thresholds used."""

    index_ranges: tuple[tuple[int, int], ...]
    times_s: tuple[tuple[float, float], ...]
    window_samples: int
    gyro_floor_rad2_s2: float
    acc_floor_m2_s4: float
    quantile_factor: float

    def to_list(self) -> list[list[float]]:
        return [[round(a, 6), round(b, 6)] for a, b in self.times_s]


def _sliding_var(x: np.ndarray, w: int) -> np.ndarray:
    """Summed per-axis variance over centred windows of w samples (edges use the nearest full window)."""
    c1 = np.concatenate([np.zeros((1, x.shape[1])), np.cumsum(x, axis=0)])
    c2 = np.concatenate([np.zeros((1, x.shape[1])), np.cumsum(x * x, axis=0)])
    s1 = c1[w:] - c1[:-w]
    s2 = c2[w:] - c2[:-w]
    var = np.maximum(s2 / w - (s1 / w) ** 2, 0.0).sum(axis=1) * w / (w - 1)
    half = w // 2
    out = np.empty(x.shape[0])
    out[half : half + var.size] = var
    out[:half] = var[0]
    out[half + var.size :] = var[-1]
    return out


def _sliding_mean(x: np.ndarray, w: int) -> np.ndarray:
    c1 = np.concatenate([np.zeros((1, x.shape[1])), np.cumsum(x, axis=0)])
    m = (c1[w:] - c1[:-w]) / w
    half = w // 2
    out = np.empty_like(x)
    out[half : half + m.shape[0]] = m
    out[:half] = m[0]
    out[half + m.shape[0] :] = m[-1]
    return out


def _densest(points: np.ndarray, radius: float) -> np.ndarray:
    """The point with the most neighbours within ``radius`` (the mode of a 3-D cloud)."""
    if points.shape[0] == 0:
        return np.zeros(3)
    if points.shape[0] > 2000:
        points = points[:: points.shape[0] // 2000 + 1]
    d2 = np.sum((points[:, None, :] - points[None, :, :]) ** 2, axis=2)
    k = int(np.argmax(np.sum(d2 <= radius**2, axis=1)))
    return points[np.sum((points - points[k]) ** 2, axis=1) <= radius**2].mean(axis=0)


def _local_level(t: np.ndarray, means: np.ndarray, quiet: np.ndarray, w: int, radius: float,
                 half_span_s: float = 20.0, every_s: float = 5.0) -> np.ndarray:
    """b₀(t): densest cluster of quiet-window means within ±half_span_s, every ``every_s`` (s),
    carried to every sample from the nearest centre that has quiet windows."""
    centres = np.arange(t[0], t[-1] + every_s, every_s)
    idx = np.flatnonzero(quiet)[:: max(1, w // 2)]
    levels = np.full((centres.size, 3), np.nan)
    for i, c in enumerate(centres):
        near = idx[np.abs(t[idx] - c) <= half_span_s]
        if near.size:
            levels[i] = _densest(means[near], radius)
    ok = ~np.isnan(levels[:, 0])
    if not ok.any():
        return np.zeros_like(means)
    nearest = np.abs(centres[:, None] - centres[ok][None, :]).argmin(axis=1)
    levels = levels[ok][nearest]
    pos = np.clip(np.round((t - centres[0]) / every_s).astype(int), 0, centres.size - 1)
    return levels[pos]


def detect_rest(rec: Recording, window_s: float = 0.5, min_segment_s: float = 1.0) -> RestSegments:
    """Find the rest segments of ``rec`` (see module docstring).

    The mean test takes the window mean's variance as σ²/w, white noise's.  Behind an output low-pass (a DLPF) the
    samples are correlated and the window mean varies ×(1 + 2Σρ_k) more: the test then cut a rest into pieces
    shorter than the bias needs (the independent generator behind a 10-Hz Butterworth: its 8-s first rest in four
    1.0–1.4-s pieces, the first ≥ 2-s rest the session's last, and kf_hand's filter saw 4 s of a 112-s session).
    So the rests are found once, the longest one's spectrum is checked for a roll-off
    (:func:`calib.session.noiselevels.white_density_check`), and when one is found they are found again with the mean's
    variance scaled by the variance inflation N_low² f_s / σ² (the low band's density over the samples' spread:
    a first-order 10-Hz corner at 100 Hz gives ~3).  Without a roll-off nothing changes."""
    fs = rec.rate_hz
    w = max(5, int(round(window_s * fs)))
    if rec.n < 4 * w:
        raise RecordingError(f"recording of {rec.n} samples is too short for rest detection (need ≥ {4 * w})")
    first = _detect(rec, w, min_segment_s, 1.0)
    vif = _mean_variance_inflation(rec, first)
    return first if vif <= 1.0 else _detect(rec, w, min_segment_s, vif)


def _mean_variance_inflation(rec: Recording, rest: RestSegments) -> float:
    """The window mean's variance over white noise's, from the longest rest's gyro spectrum: N_low² f_s / σ² when
    :func:`calib.session.noiselevels.white_density_check` finds an output low-pass there, else 1."""
    from calib.session.noiselevels import white_density_check

    if not rest.index_ranges:
        return 1.0
    a, b = max(rest.index_ranges, key=lambda r: r[1] - r[0])
    x = rec.gyro_rad_s[a:b]
    chk = white_density_check(x, rec.rate_hz)
    var = float(np.mean(np.var(x, axis=0)))
    if chk is None or not chk.rolled_off or var <= 0:
        return 1.0
    return max(1.0, chk.density**2 * rec.rate_hz / var)


def _detect(rec: Recording, w: int, min_segment_s: float, mean_variance_factor: float) -> RestSegments:
    """The module docstring's steps 1–4, the window mean's variance taken as ``mean_variance_factor`` × σ²/w."""
    fs = rec.rate_hz
    # remove a running offset so slow drifts do not count as motion: variance is offset-free already
    vg = _sliding_var(rec.gyro_rad_s, w)
    va = _sliding_var(rec.acc_m_s2, w)
    floor_g = float(np.percentile(vg, 10))
    floor_a = float(np.percentile(va, 10))
    dof = 4  # narrowband tremor: ~4 degrees of freedom per window (module docstring)
    q = float(stats.chi2.ppf(0.999, dof) / dof)
    quiet = (vg <= floor_g * q) & (va <= floor_a * q)
    means = _sliding_mean(rec.gyro_rad_s, w)
    mean_var = mean_variance_factor * floor_g / 3 / w          # per axis, (rad/s)²
    radius = math.sqrt(mean_var) * math.sqrt(stats.chi2.ppf(0.999, 3))
    level = _local_level(rec.t_s, means, quiet, w, radius)
    dist2 = np.sum((means - level) ** 2, axis=1) / mean_var
    rest = quiet & (dist2 <= stats.chi2.ppf(0.999, 3))
    edges = np.diff(np.concatenate([[0], rest.astype(np.int8), [0]]))
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    if starts.size > 1:  # merge runs split by a few rejected windows (0.1 % false alarms per window)
        keep = np.concatenate([[True], starts[1:] - stops[:-1] > w])
        starts = starts[keep]
        stops = np.concatenate([stops[:-1][keep[1:]], stops[-1:]])
    min_len = int(math.ceil(min_segment_s * fs))
    ranges = tuple((int(a), int(b)) for a, b in zip(starts, stops) if b - a >= min_len)
    times = tuple((float(rec.t_s[a]), float(rec.t_s[b - 1])) for a, b in ranges)
    return RestSegments(ranges, times, w, floor_g, floor_a, q)


@dataclass(frozen=True)
class BiasEstimate:
    """Gyro bias (rad/s, body frame) with its standard error, and the samples it came from."""

    value_rad_s: np.ndarray
    std_rad_s: np.ndarray
    index_range: tuple[int, int]
    time_range_s: tuple[float, float]


def static_bias(rec: Recording, rest: RestSegments, min_rest_s: float = 2.0) -> BiasEstimate:
    """Zhou 2020 eq. 3: b = mean of the gyro over the first rest segment at least ``min_rest_s`` long.

    Raises RecordingError if there is no rest segment, or none is long enough (a short average
    carries the motion edges and too little data; the message gives what the longest would have
    achieved).
    """
    if not rest.index_ranges:
        raise RecordingError(
            "no rest period found: the bias is the average of the gyro at rest (Zhou 2020 §3.2); start the "
            f"session with ≥ {min_rest_s:g} s of holding still, or give the bias yourself"
        )
    durations = [float(rec.t_s[b - 1] - rec.t_s[a]) for a, b in rest.index_ranges]
    long_enough = [i for i, d in enumerate(durations) if d >= min_rest_s]
    pick = long_enough[0] if long_enough else int(np.argmax(durations))
    a, b = rest.index_ranges[pick]
    seg = rec.gyro_rad_s[a:b]
    dur = durations[pick]
    batches = np.array_split(seg, 10)
    means = np.array([m.mean(axis=0) for m in batches])
    std = means.std(axis=0, ddof=1) / math.sqrt(len(batches))
    if not long_enough:
        raise RecordingError(
            f"the longest rest period lasts {dur:.2f} s (t = {rec.t_s[a]:.2f}–{rec.t_s[b - 1]:.2f} s), shorter than "
            f"the {min_rest_s:g} s needed; its bias would be uncertain to ±{np.degrees(std.max()):.3f} °/s: "
            "hold still longer at the start"
        )
    return BiasEstimate(seg.mean(axis=0), std, (a, b), (float(rec.t_s[a]), float(rec.t_s[b - 1])))
