"""Does the calibration hold on data it did not see?  Cut the recording in two, calibrate on one half, and
predict the other — then the other way round when both halves start at a rest.

**Why halves.**  Each half is a recording of its own for the method: it starts at a rest (where the method takes
its bias and levels its attitude) and the method runs unchanged on it — the check sits above every method and
needs nothing inside a filter.  Alternating blocks (holding the references of every other 10-s block out of the
measurement updates) would let each fold see every part of a designed protocol, but it has to reach into the
filter's updates, and the held-out blocks' gravity references share the hand's slow acceleration with their
trained neighbours (τ up to ~7 s in the fits), so they are less independent than they look.  The cut
(:func:`split_point`) is the middle of the rest nearest the middle of the recording when one lies in its middle
half — both halves then start at a rest and there are two folds — else the middle, and only the first half
predicts the second.  The price: a protocol that puts each axis in its own stretch (Ferraris: the poses, then
one turn per axis) determines in a half only part of what the whole does; what neither half determines cannot be
tested, and the caller leaves it at the prior — the accelerometer of a session with enough rest poses has its own
check, each pose left out of the |f| = g fit in turn (:func:`calib.session.decision.decide.rest_pose_check`).

**What is predicted** (each a *source*; an item is one prediction, its error an angle in degrees unless
said otherwise), within the predicted half, for every variant of the fold's result — ``raw`` (nothing
applied), ``bias`` (its gyro bias), ``gyro`` (the bias and the S, G it determined), ``accelerometer`` (the bias
and the accelerometer parameters it determined), ``full`` (all of it); a variant the fold determined nothing
for is not scored:

* ``gravity_pairs``: at calm moments (the 2-Hz low-passed specific force within ``calm_tolerance`` of its median
  magnitude) the accelerometer gives the gravity direction u in the body frame; the gyro carries u from one
  calm moment to the last one at most ``pair_max_gap_s`` later, u_b ≈ R_abᵀ u_a, over pairs where gravity turned
  by at least ``pair_min_turn_deg`` (S and G act in proportion to the angle turned);
* ``rests``: gravity carried by the gyro from one held-out rest to the next, however far (the turns between
  them included), against the accelerometer's mean there (few items, each precise);
* ``rest_gravity`` (accelerometer): |f̂| − g at each held-out rest (m/s²);
* ``reference_rotation``, ``reference_inclination`` — only for a recording with a *measured* reference
  attitude (a motion-capture quaternion, e.g. BROAD's optical ``opt_quat``; a simulated file's truth is an
  oracle and is never used): the angle between the rotation the gyro integrates over ``reference_window_s``
  windows and the reference's (as :func:`calib.session.validation.windowed_rotation_error_deg`, per window),
  and the angle between the accelerometer's gravity direction at the calm moments and the reference's.

**The verdict** of a variant in a fold: every source with at least ``min_items`` items (``rests`` and
``rest_gravity``: 2) must find it *no worse than bias-only and no worse than raw* — its mean paired error
difference at most ``z`` = 2 standard errors above zero (one-sided, ≈ 2.3 % false alarms per source; the
standard error from the means of ``block_s`` blocks, since neighbouring predictions share their errors), and
*better than raw* in the mean on at least one of them.  No source with enough items: ``inconclusive``.

Sources of a variant: ``gyro`` — gravity_pairs, rests, reference_rotation; ``accelerometer`` — gravity_pairs,
rests, rest_gravity, reference_inclination; ``full`` and ``bias`` — all.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from gyrosim.lazy import lazy_module
from gyrosim.recording import Recording
from gyrosim.rotations import quat_conjugate, quat_multiply, quat_rotate
from gyrosim.strapdown import integrate_gyro

from calib.session.model import gyro_axis_matrix

sp_signal = lazy_module("scipy.signal")   # imported on first use: not before a bad file is refused

__all__ = ["HeldOutParams", "HeldOutCheck", "CrossCheck", "SourceScore", "held_out_check", "split_recording",
           "split_point", "VARIANTS", "GYRO_GIVEN_ACC", "has_measured_reference", "linear_compensate"]

VARIANTS = ("raw", "bias", "gyro", "accelerometer", "full")
# the verdict on S, G with the accelerometer calibrated ("full" against "accelerometer"): :func:`_given_accelerometer`
GYRO_GIVEN_ACC = "gyro_given_accelerometer"
SOURCES = {"gyro": ("gravity_pairs", "rests", "reference_rotation"),
           "accelerometer": ("gravity_pairs", "rests", "rest_gravity", "reference_inclination"),
           "full": ("gravity_pairs", "rests", "rest_gravity", "reference_rotation", "reference_inclination"),
           "bias": ("gravity_pairs", "rests", "reference_rotation")}
FEW_ITEM_SOURCES = ("rests", "rest_gravity")


@dataclass(frozen=True)
class HeldOutParams:
    """Settings of :func:`held_out_check` (module docstring)."""

    split: float = 0.5
    pair_max_gap_s: float = 3.0
    pair_min_turn_deg: float = 15.0
    calm_tolerance: float = 0.03
    lowpass_hz: float = 2.0
    anchor_s: float = 0.25
    block_s: float = 10.0
    z: float = 2.0
    min_items: int = 10
    reference_window_s: float = 5.0
    reference_step_s: float = 0.5
    use_reference: bool = True
    max_rate_hz: float = 100.0


@dataclass(frozen=True)
class SourceScore:
    """One source's predictions: ``items``; per variant the RMS error (``unit``) and the mean paired difference to
    bias-only and to raw with its standard error (positive: worse)."""

    name: str
    unit: str
    items: int
    rms: dict
    vs_bias: dict
    vs_raw: dict
    vs_accelerometer: dict = field(default_factory=dict)   # "full" against the accelerometer alone

    def informative(self, p: HeldOutParams) -> bool:
        return self.items >= (2 if self.name in FEW_ITEM_SOURCES else p.min_items)

    def worse(self, variant: str, p: HeldOutParams) -> bool:
        """Significantly worse than bias-only or than raw (one-sided, z standard errors)."""
        return any(m > p.z * se for m, se in (self.vs_bias[variant], self.vs_raw[variant]))

    def better_than_raw(self, variant: str) -> bool:
        return self.vs_raw[variant][0] < 0.0

    def to_dict(self) -> dict:
        r = lambda x: round(float(x), 5)  # noqa: E731
        return {"items": self.items, "unit": self.unit, "rms": {k: r(v) for k, v in self.rms.items()},
                "vs_bias_only": {k: [r(m), r(s)] for k, (m, s) in self.vs_bias.items()},
                "vs_raw": {k: [r(m), r(s)] for k, (m, s) in self.vs_raw.items()},
                **({"vs_accelerometer_only": {k: [r(m), r(s)] for k, (m, s) in self.vs_accelerometer.items()}}
                   if self.vs_accelerometer else {})}


@dataclass(frozen=True)
class HeldOutCheck:
    """The check (module docstring): the two halves' spans (s), the sources, and per variant ``agrees``,
    ``disagrees`` or ``inconclusive``; ``notes`` say why a part could not be checked."""

    trained_s: tuple[float, float]
    predicted_s: tuple[float, float]
    sources: tuple[SourceScore, ...]
    verdicts: dict
    params: HeldOutParams = HeldOutParams()
    notes: tuple[str, ...] = field(default=())

    def verdict(self, variant: str) -> str:
        return self.verdicts.get(variant, "inconclusive")

    def source(self, name: str) -> SourceScore | None:
        return next((s for s in self.sources if s.name == name), None)

    def to_dict(self) -> dict:
        return {"trained_s": list(self.trained_s), "predicted_s": list(self.predicted_s),
                "verdicts": dict(self.verdicts), "sources": {s.name: s.to_dict() for s in self.sources},
                "rule": f"no worse than bias-only and raw (paired, {self.params.z:g} standard errors) on every source "
                        "with enough items, better than raw on one", "notes": list(self.notes)}


def split_point(rec: Recording, rests: list, fraction: float = 0.5, min_rest_s: float = 2.0) -> tuple[int, bool]:
    """Where to cut ``rec`` (a sample index) and whether both halves start at a rest: the middle of the rest of
    ``rests`` ((t0, t1) in s) nearest to ``fraction`` of the recording, when one lies between a quarter and three
    quarters of it and lasts at least twice ``min_rest_s`` (each side keeps a rest the method can take its bias
    from); else ``fraction`` of the samples, and only the first half starts at a rest."""
    t0, dur = float(rec.t_s[0]), rec.duration_s
    best = None
    for a, b in rests:
        mid = 0.5 * (a + b) - t0
        if b - a >= 2 * min_rest_s and 0.25 * dur <= mid <= 0.75 * dur and a - t0 > 0.05 * dur:
            if best is None or abs(mid - fraction * dur) < abs(best - fraction * dur):
                best = mid
    if best is None:
        return int(round(rec.n * fraction)), False
    return int(np.searchsorted(rec.t_s, t0 + best)), True


def split_recording(rec: Recording, fraction: float | int = 0.5) -> tuple[Recording, Recording]:
    """``rec`` cut in two, each its own recording (times from 0; the truth's channels cut alike): at ``fraction``
    of the samples (a float), or at sample index ``fraction`` (an int, e.g. :func:`split_point`'s)."""
    from gyrosim.recording import Truth

    k = fraction if isinstance(fraction, (int, np.integer)) else int(round(rec.n * fraction))

    def cut(a: int, b: int) -> Recording:
        tr = rec.truth
        truth = None if tr is None else Truth(**{name: (None if getattr(tr, name) is None else getattr(tr, name)[a:b])
                                                 for name in ("omega_body_rad_s", "specific_force_body_m_s2",
                                                              "quat_nb", "position_nav_m")},
                                              extra={n: v[a:b] for n, v in tr.extra.items()})
        opt = {n: (None if getattr(rec, n) is None else getattr(rec, n)[a:b]) for n in ("temp_c", "mag_ut")}
        return Recording(rec.t_s[a:b] - rec.t_s[a], rec.gyro_rad_s[a:b], rec.acc_m_s2[a:b], truth=truth,
                         meta=dict(rec.meta), **opt)

    return cut(0, k), cut(k, rec.n)


def has_measured_reference(rec: Recording) -> bool:
    """A reference attitude that is a measurement (motion capture), not a simulator's truth."""
    from gyrosim.sensor_model import stored_sensor_model

    return (rec.truth is not None and rec.truth.quat_nb is not None and stored_sensor_model(rec.meta or {}) is None
            and "sensor_model_before_compensation" not in (rec.meta or {}))


def linear_compensate(x: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """x̂ = M⁻¹ (x̃ − b) for θ = [b, S, G] (9,), rows of ``x`` (N, 3); θ (12,) = [b, S, G, α] adds the gyro's
    rotation against the accelerometer, M = I + diag(S) + N(G) − [α×] (:class:`gyrosim.effects.GyroAccMisalignment`)."""
    m = gyro_axis_matrix(theta[3:6], theta[6:9], theta[9:12] if len(theta) == 12 else None)
    return np.linalg.solve(m, (np.asarray(x, float) - theta[0:3]).T).T


def _blocks(x: np.ndarray, n: int) -> np.ndarray:
    m = (x.shape[0] // n) * n
    return x[:m].reshape(-1, n, *x.shape[1:]).mean(axis=1)


def _angle(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return np.degrees(np.arccos(np.clip(np.sum(u * v, axis=1), -1.0, 1.0)))


def _paired(diff: np.ndarray, t: np.ndarray, block_s: float) -> tuple[float, float]:
    """Mean of ``diff`` and its standard error from ``block_s`` batch means (item-level when < 3 blocks)."""
    if diff.size == 0:
        return 0.0, 0.0
    mean = float(np.mean(diff))
    ids = np.floor((t - t[0]) / block_s).astype(int)
    uniq = np.unique(ids)
    if uniq.size >= 3:
        bm = np.array([diff[ids == k].mean() for k in uniq])
        return mean, float(bm.std(ddof=1) / math.sqrt(uniq.size))
    if diff.size >= 2:
        return mean, float(diff.std(ddof=1) / math.sqrt(diff.size))
    return mean, abs(mean)


@dataclass(frozen=True)
class _Half:
    """The predicted half, block-averaged to ≤ max_rate_hz, and what every variant shares."""

    t: np.ndarray
    gyro: np.ndarray
    acc: np.ndarray
    rests: tuple[tuple[int, int], ...]
    quat_ref: np.ndarray | None
    pairs: tuple[np.ndarray, np.ndarray]
    gravity_m_s2: float


def _prepare_half(rec: Recording, rests: tuple[tuple[int, int], ...], gravity_m_s2: float,
                  p: HeldOutParams) -> _Half:
    n = max(1, int(math.ceil(rec.rate_hz / p.max_rate_hz - 1e-9)))
    t = _blocks(np.asarray(rec.t_s, float), n)
    gyro, acc = _blocks(np.asarray(rec.gyro_rad_s, float), n), _blocks(np.asarray(rec.acc_m_s2, float), n)
    q_ref = None
    if p.use_reference and has_measured_reference(rec):
        q_ref = np.asarray(rec.truth.quat_nb, float)[: (rec.n // n) * n: n][: t.size]
    rests_d = tuple((a // n, max(a // n + 1, b // n)) for a, b in rests if b // n - a // n >= 2)
    fs = 1.0 / float(np.median(np.diff(t)))
    pairs = _calm_pairs(t, acc, fs, p)
    return _Half(t, gyro, acc, rests_d, q_ref, pairs, gravity_m_s2)


def _lowpass(x: np.ndarray, fs: float, fc: float) -> np.ndarray:
    b, a = sp_signal.butter(2, min(fc / (fs / 2), 0.9))
    return sp_signal.filtfilt(b, a, x, axis=0) if x.shape[0] > 15 else x


def _calm(acc: np.ndarray, fs: float, p: HeldOutParams) -> tuple[np.ndarray, np.ndarray]:
    """Unit gravity directions of the low-passed specific force and where it is calm."""
    f = _lowpass(acc, fs, p.lowpass_hz)
    n = np.linalg.norm(f, axis=1)
    g = float(np.median(np.linalg.norm(acc, axis=1)))
    return f / np.where(n > 0, n, 1.0)[:, None], np.abs(n / (g or 1.0) - 1.0) < p.calm_tolerance


def _calm_pairs(t: np.ndarray, acc: np.ndarray, fs: float, p: HeldOutParams) -> tuple[np.ndarray, np.ndarray]:
    u, calm = _calm(acc, fs, p)
    idx = np.flatnonzero(calm)
    if idx.size < 2:
        return np.zeros(0, int), np.zeros(0, int)
    _, first = np.unique(np.floor((t[idx] - t[0]) / p.anchor_s).astype(int), return_index=True)
    anchors = idx[first]
    j = np.searchsorted(t[anchors], t[anchors] + p.pair_max_gap_s, side="right") - 1
    a, b = anchors, anchors[j]
    keep = b > a
    a, b = a[keep], b[keep]
    turned = _angle(u[a], u[b]) >= p.pair_min_turn_deg
    return a[turned], b[turned]


def _errors(half: _Half, gyro: np.ndarray, acc: np.ndarray, p: HeldOutParams) -> dict:
    """Per source: (item times, errors) of one variant's compensated signals."""
    fs = 1.0 / float(np.median(np.diff(half.t)))
    q = integrate_gyro(half.t, gyro, np.array([1.0, 0.0, 0.0, 0.0]))
    u, _ = _calm(acc, fs, p)
    out = {}
    a, b = half.pairs
    if a.size:
        q_ab = quat_multiply(quat_conjugate(q[a]), q[b])
        out["gravity_pairs"] = (half.t[a], _angle(quat_rotate(quat_conjugate(q_ab), u[a]), u[b]))
    if len(half.rests) >= 2:
        means = np.array([acc[r0:r1].mean(axis=0) for r0, r1 in half.rests])
        dirs = means / np.linalg.norm(means, axis=1, keepdims=True)
        ends = np.array([r1 - 1 for _, r1 in half.rests[:-1]])
        starts = np.array([r0 for r0, _ in half.rests[1:]])
        q_ab = quat_multiply(quat_conjugate(q[ends]), q[starts])
        out["rests"] = (half.t[starts], _angle(quat_rotate(quat_conjugate(q_ab), dirs[:-1]), dirs[1:]))
    if half.rests:
        means = np.array([acc[r0:r1].mean(axis=0) for r0, r1 in half.rests])
        out["rest_gravity"] = (half.t[[r0 for r0, _ in half.rests]],
                               np.abs(np.linalg.norm(means, axis=1) - half.gravity_m_s2))
    if half.quat_ref is not None:
        k, s = int(round(p.reference_window_s * fs)), max(1, int(round(p.reference_step_s * fs)))
        i = np.arange(0, half.t.size - k, s)
        j = i + k
        ref = half.quat_ref
        ok = np.isfinite(ref[i]).all(axis=1) & np.isfinite(ref[j]).all(axis=1)
        i, j = i[ok], j[ok]
        if i.size:
            d = quat_multiply(quat_conjugate(quat_multiply(quat_conjugate(ref[i]), ref[j])),
                              quat_multiply(quat_conjugate(q[i]), q[j]))
            out["reference_rotation"] = (half.t[i], 2.0 * np.degrees(np.arccos(np.clip(np.abs(d[:, 0]), 0.0, 1.0))))
        ca = half.pairs[0]
        ca = ca[np.isfinite(ref[ca]).all(axis=1)]
        if ca.size:
            up = quat_rotate(quat_conjugate(ref[ca]), np.tile([0.0, 0.0, 1.0], (ca.size, 1)))
            out["reference_inclination"] = (half.t[ca], _angle(u[ca], up))
    return out


UNITS = {"rest_gravity": "m/s²"}


def held_out_check(predicted: Recording, variants: dict, rests: tuple[tuple[int, int], ...] = (),
                   gravity_m_s2: float = 9.80665, trained_s: tuple[float, float] = (0.0, 0.0),
                   predicted_s: tuple[float, float] = (0.0, 0.0), params: HeldOutParams = HeldOutParams(),
                   notes: tuple[str, ...] = ()) -> HeldOutCheck:
    """Score ``variants`` (name → (gyro θ (9,), accelerometer θ (9,) or None), the first half's results) on the
    ``predicted`` half (module docstring); ``rests``: its rest segments (sample ranges within it)."""
    half = _prepare_half(predicted, rests, gravity_m_s2, params)
    errs = {}
    for name in VARIANTS:
        if name not in variants:
            continue
        g, a = variants[name]
        gyro = half.gyro if g is None else linear_compensate(half.gyro, g)
        acc = half.acc if a is None else linear_compensate(half.acc, a)
        errs[name] = _errors(half, gyro, acc, params)
    sources = []
    names = sorted({s for e in errs.values() for s in e}, key=lambda s: list(SOURCES["full"]).index(s))
    for src in names:
        t, base = errs["bias"][src]
        _, raw = errs["raw"][src]
        rms, vs_b, vs_r = {}, {}, {}
        for name, e in errs.items():
            _, v = e[src]
            rms[name] = float(np.sqrt(np.mean(v**2))) if v.size else float("nan")
            vs_b[name] = _paired(v - base, t, params.block_s)
            vs_r[name] = _paired(v - raw, t, params.block_s)
        vs_a = {}
        if "full" in errs and "accelerometer" in errs:   # S, G on top of the calibrated accelerometer
            _, acc_only = errs["accelerometer"][src]
            vs_a = {"full": _paired(errs["full"][src][1] - acc_only, t, params.block_s)}
        sources.append(SourceScore(src, UNITS.get(src, "°"), int(t.size), rms, vs_b, vs_r, vs_a))
    verdicts = {}
    for name in errs:
        if name == "raw":
            continue
        used = [s for s in sources if s.name in SOURCES[name] and s.informative(params)]
        verdicts[name] = _verdict([(s.worse(name, params), s.better_than_raw(name)) for s in used])
    if "full" in errs and "accelerometer" in errs:
        verdicts[GYRO_GIVEN_ACC] = _given_accelerometer(sources, params)
    return HeldOutCheck(trained_s, predicted_s, tuple(sources), verdicts, params, notes)


def _given_accelerometer(sources: list[SourceScore], params: HeldOutParams) -> str:
    """S, G judged on top of the calibrated accelerometer: ``full`` against ``accelerometer`` alone on the sources
    S, G reach — no worse on any with enough items (``z`` standard errors) and better on one.  With the accelerometer
    left raw (the ``gyro`` variant) its own errors set the gravity the pairs are scored against and can hide what S, G
    do."""
    used = [s for s in sources if s.name in SOURCES["gyro"] and s.informative(params) and "full" in s.vs_accelerometer]
    return _verdict([(m > params.z * se, m < 0.0) for m, se in (s.vs_accelerometer["full"] for s in used)])


def _verdict(judged: list[tuple[bool, bool]]) -> str:
    """The verdict over the sources with enough items, each judged (significantly worse, better): ``disagrees`` when
    one is worse or none is better, ``agrees`` otherwise, ``inconclusive`` without a source."""
    if not judged:
        return "inconclusive"
    return "disagrees" if any(w for w, _ in judged) or not any(b for _, b in judged) else "agrees"


@dataclass(frozen=True)
class CrossCheck:
    """One or two folds of :func:`held_out_check` (first half → second, and second → first when both start at a
    rest) and the combined verdict per variant: ``disagrees`` when a fold disagrees, ``agrees`` when one agrees
    and none disagrees, else ``inconclusive``."""

    folds: tuple[HeldOutCheck, ...]
    params: HeldOutParams = HeldOutParams()
    notes: tuple[str, ...] = field(default=())

    @property
    def sources(self) -> tuple[SourceScore, ...]:
        return tuple(s for f in self.folds for s in f.sources)

    def verdict(self, variant: str) -> str:
        v = [f.verdict(variant) for f in self.folds]
        if "disagrees" in v:
            return "disagrees"
        return "agrees" if "agrees" in v else "inconclusive"

    def to_dict(self) -> dict:
        return {"verdicts": {v: self.verdict(v) for v in VARIANTS + (GYRO_GIVEN_ACC,) if v != "raw"},
                "folds": [f.to_dict() for f in self.folds], "notes": list(self.notes),
                "split": "at the rest nearest the middle when one lies in the middle half (both halves start at a "
                         "rest: two folds), else at the middle (the first half predicts the second)"}
