"""What the board did, from the data alone: still or moving, where it rests, and whether the gyro's
rotation agrees with the gravity direction the accelerometer sees (which tests the gyro and time
units together).

Windows of ~1 s, at least 5 samples (non-overlapping block means):

* gravity swing: angle of each window's mean specific force from the record's median direction;
* a window moves when its gravity direction turns by > 1° from the previous or to the next window
  (a still hand sways by < 0.2°), or its mean rate differs from the rate level by more than
  0.1 rad/s (5.7 °/s) — a hand turn is ≥ 20 °/s, a bias never changes that fast; the level is the
  running median (±30) of the quiet windows (steady rate within the window, no tilting),
  interpolated in time, so slow bias drift is not motion;
* rest level: the median gyro mean over windows where the accelerometer is calm (variance within
  4.6× its 10th percentile, |f| within 3 % of the median) and, among those, the rate is in its lowest
  fifth (a turn about the vertical, e.g. on a rate table, keeps the accelerometer calm too; a bias
  is in every calm window): a bias, whatever the motion elsewhere.

Gravity consistency (:func:`rotation_consistency`): at calm moments (|f| within 3 % of g, 0.1 s
smoothing) the accelerometer measures the gravity direction u in the body frame.  Between a calm moment a
and the last calm moment b at most 3 s later, integrating the gyro (bias = rest level, scaled by a candidate
factor k) predicts u_b = R_abᵀ u_a.  The median prediction error over the pairs where gravity turned
by ≥ 15° is computed for k ∈ {1, π/180, 180/π, 10⁻³, 10³}: the factor that fits names a unit mistake
(deg/s read as rad/s, ms read as s, …).  Measured medians at k = 1: gyrosim sessions 1°, BROAD
1.7–9°, imu_tk 18°, x-io 0.8–8°; BROAD's tapping trial 22° vs 20° at k = π/180, so a factor is only
blamed when it fits at least twice as well, the declared units miss by > 10°, and ≥ 5 pairs inform.
The rates are block-averaged to ≤ 20 Hz first (a hand turn's rate is smooth on that scale; the
mean rate keeps the angle) and the other factors are only integrated when the declared units miss.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gyrosim.recording import Recording
from gyrosim.rotations import quat_conjugate, quat_multiply, quat_rotate
from gyrosim.strapdown import integrate_gyro

__all__ = ["MotionSummary", "summarise_motion", "rotation_consistency", "FACTORS"]

FACTORS = {1.0: "as declared", math.pi / 180: "deg/s read as rad/s", 180 / math.pi: "rad/s read as deg/s",
           1e-3: "time 1000× too long (ms read as s?)", 1e3: "time 1000× too short (s read as ms?)"}
MOVE_TILT_DEG = 1.0
MOVE_RATE_RAD_S = 0.1


@dataclass(frozen=True)
class MotionSummary:
    """Window-level description of the motion (module docstring)."""

    window_s: float
    gravity_swing_deg: float            # largest window tilt from the median gravity direction
    moving: np.ndarray                  # (W,) bool per window
    window_t_s: np.ndarray              # (W,) window start times
    peak_rate_rad_s: float              # largest |window-mean rate − running level|
    rest_level_rad_s: np.ndarray | None  # gyro at calm windows (bias), None when never calm
    calm_fraction: float

    @property
    def moving_fraction(self) -> float:
        return float(self.moving.mean()) if self.moving.size else 0.0

    def first_motion_s(self) -> float | None:
        k = np.flatnonzero(self.moving)
        return float(self.window_t_s[k[0]]) if k.size else None

    def longest_still(self) -> tuple[float, float] | None:
        still = ~self.moving
        if not still.any():
            return None
        edges = np.diff(np.concatenate([[0], still.astype(np.int8), [0]]))
        s, e = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
        i = int(np.argmax(e - s))
        return float(self.window_t_s[s[i]]), float(self.window_t_s[e[i] - 1] + self.window_s)


def _running_median(x: np.ndarray, half: int) -> np.ndarray:
    from numpy.lib.stride_tricks import sliding_window_view

    xp = np.pad(x, ((half, half), (0, 0)), mode="edge")
    return np.median(sliding_window_view(xp, 2 * half + 1, axis=0), axis=-1)


def summarise_motion(rec: Recording, window_s: float = 1.0) -> MotionSummary:
    """Window statistics of ``rec`` (see the module docstring)."""
    with np.errstate(all="ignore"):  # absurd values (inspect lists them) must not spill warnings
        return _summarise_motion(rec, window_s)


def _summarise_motion(rec: Recording, window_s: float) -> MotionSummary:
    dt = float(np.median(np.diff(rec.t_s)))
    w = max(5, int(round(window_s / dt)))  # ≥ 5 samples: a slow log still gets a variance per window
    if rec.n < 2 * w:
        w = max(1, rec.n // 2)
    m = (rec.n // w) * w
    starts = np.arange(0, m, w)
    tw = np.asarray(rec.t_s)[starts]

    def block_stats(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per-window mean (W, 3) and summed variance (W,) from contiguous segment sums (one pass,
        channel-major: numpy's passes over (N, 3) columns are ~20× slower)."""
        xt = np.ascontiguousarray(np.asarray(x[:m], dtype=float).T)
        s1 = np.add.reduceat(xt, starts, axis=1) / w
        s2 = np.add.reduceat(xt * xt, starts, axis=1) / w
        return s1.T, np.maximum(s2 - s1 * s1, 0.0).sum(axis=0)

    gm, var_g = block_stats(rec.gyro_rad_s)
    fm, var_f = block_stats(rec.acc_m_s2)
    fn = np.linalg.norm(fm, axis=1)
    ok = fn > 0
    u = np.where(ok[:, None], fm / np.where(ok, fn, 1.0)[:, None], 0.0)
    ref = np.median(u, axis=0)
    ref = ref / (np.linalg.norm(ref) or 1.0)
    swing = np.degrees(np.arccos(np.clip(u @ ref, -1.0, 1.0)))
    turn = np.degrees(np.arccos(np.clip(np.sum(u[1:] * u[:-1], axis=1), -1.0, 1.0)))
    tilting = np.zeros(u.shape[0], bool)
    tilting[1:] |= turn > MOVE_TILT_DEG
    tilting[:-1] |= turn > MOVE_TILT_DEG
    # the rate level from quiet windows (steady rate within the window, no tilting), tracked in time
    quiet = ~tilting & (var_g <= 4.6 * float(np.percentile(var_g, 10)) + 1e-30)
    if quiet.any():
        qi = np.flatnonzero(quiet)
        run = _running_median(gm[qi], min(30, max(1, qi.size // 2)))
        level = np.stack([np.interp(tw, tw[qi], run[:, j]) for j in range(3)], axis=1)
    else:
        level = np.repeat(np.median(gm, axis=0)[None], gm.shape[0], axis=0)
    dev = np.linalg.norm(gm - level, axis=1)
    moving = tilting | (dev > MOVE_RATE_RAD_S)
    if w > 1:
        floor = float(np.percentile(var_f, 10))
        f_med = float(np.median(fn))
        calm = (var_f <= 4.6 * floor + 1e-30) & (np.abs(fn / (f_med or 1.0) - 1) < 0.03)
    else:
        calm = np.zeros(gm.shape[0], bool)
    rest = None
    if calm.any():  # the calm windows turning least: a turn about the vertical leaves the accelerometer calm too
        mag = np.linalg.norm(gm[calm], axis=1)
        rest = np.median(gm[calm][mag <= np.percentile(mag, 20)], axis=0)
    return MotionSummary(w * dt, float(swing.max(initial=0.0)), moving, tw, float(dev.max(initial=0.0)), rest,
                         float(calm.mean()) if calm.size else 0.0)


def _smooth(x: np.ndarray, w: int) -> np.ndarray:
    c = np.cumsum(np.concatenate([np.zeros((1,) + x.shape[1:]), x]), axis=0)
    out = (c[w:] - c[:-w]) / w
    pad = w // 2
    return np.concatenate([np.repeat(out[:1], pad, 0), out, np.repeat(out[-1:], x.shape[0] - out.shape[0] - pad, 0)])


@dataclass(frozen=True)
class Consistency:
    """Median prediction error (°) of the gravity direction per factor, over ``pairs`` informative pairs."""

    errors_deg: dict[float, float]
    pairs: int

    def verdict(self) -> float | None:
        """The factor that explains the data when the declared units clearly do not, else None."""
        if self.pairs < 5 or 1.0 not in self.errors_deg:
            return None
        e1 = self.errors_deg[1.0]
        best = min(self.errors_deg, key=self.errors_deg.get)
        if best != 1.0 and e1 > 10.0 and self.errors_deg[best] < 0.5 * e1:
            return best
        return None


def rotation_consistency(rec: Recording, bias_rad_s: np.ndarray | None = None, max_rate_hz: float = 20.0,
                         factors: tuple[float, ...] = tuple(FACTORS)) -> Consistency:
    """Gravity-direction prediction errors per unit factor (module docstring)."""
    with np.errstate(all="ignore"):
        return _rotation_consistency(rec, bias_rad_s, max_rate_hz, factors)


def _rotation_consistency(rec: Recording, bias_rad_s: np.ndarray | None, max_rate_hz: float,
                          factors: tuple[float, ...]) -> Consistency:
    t = np.asarray(rec.t_s, dtype=float)
    g = np.asarray(rec.gyro_rad_s, dtype=float)
    f = np.asarray(rec.acc_m_s2, dtype=float)
    dt = float(np.median(np.diff(t)))
    n = max(1, int(math.ceil(1.0 / (dt * max_rate_hz) - 1e-9)))
    if n > 1:
        m = (t.size // n) * n
        starts = np.arange(0, m, n)
        t = np.add.reduceat(t[:m], starts) / n
        g, f = (np.ascontiguousarray((np.add.reduceat(np.ascontiguousarray(x[:m].T), starts, axis=1) / n).T)
                for x in (g, f))
        dt *= n
    if t.size < 10:
        return Consistency({}, 0)
    w = max(3, int(round(0.1 / dt)))
    fs = _smooth(f, w)
    fn = np.linalg.norm(f, axis=1)
    gmed = float(np.median(fn))
    if not gmed > 0:
        return Consistency({}, 0)
    sd = np.sqrt(np.maximum(_smooth(fn[:, None] ** 2, w)[:, 0] - _smooth(fn[:, None], w)[:, 0] ** 2, 0.0))
    fsn = np.linalg.norm(fs, axis=1)
    calm = (np.abs(fsn / gmed - 1) < 0.03) & (sd < 0.03 * gmed)
    idx = np.flatnonzero(calm)
    if idx.size < 2:
        return Consistency({}, 0)
    slot = np.floor((t[idx] - t[0]) / 0.5).astype(np.int64)
    _, first = np.unique(slot, return_index=True)
    anchors = idx[first]
    # pair each calm moment with the last calm moment at most 3 s later (slow turns need the span)
    j = np.searchsorted(t[anchors], t[anchors] + 3.0, side="right") - 1
    a, b = anchors, anchors[j]
    a, b = a[b > a], b[b > a]
    u = fs / np.where(fsn > 0, fsn, 1.0)[:, None]
    turned = np.degrees(np.arccos(np.clip(np.sum(u[a] * u[b], axis=1), -1.0, 1.0)))
    inf = turned >= 15.0
    if inf.sum() < 1:
        return Consistency({}, 0)
    a, b = a[inf], b[inf]
    bias = np.zeros(3) if bias_rad_s is None else np.asarray(bias_rad_s, dtype=float)
    errors = {}
    q_start = np.array([1.0, 0.0, 0.0, 0.0])
    for k in sorted(factors, key=lambda f: f != 1.0):  # the declared units first
        q = integrate_gyro(t, (g - bias) * k, q_start)
        q_ab = quat_multiply(quat_conjugate(q[a]), q[b])
        pred = quat_rotate(quat_conjugate(q_ab), u[a])
        err = np.degrees(np.arccos(np.clip(np.sum(pred * u[b], axis=1), -1.0, 1.0)))
        errors[k] = float(np.median(err))
        if k == 1.0 and (errors[k] <= 10.0 or a.size < 5):
            break  # the declared units fit (or too few moves to blame them): no other factor can be blamed
    return Consistency(errors, int(a.size))
