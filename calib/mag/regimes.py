"""Hard-iron regimes: where the field that turns with the board changes during a session.

A magnet attached to the board (or taken off it) moves every sample by the same body-frame vector
from then on: a new hard iron.  A magnet in the room changes the field with where the board is, in
the room's frame, and leaves the body-frame offset alone.  The gyro tells the two apart
(:mod:`calib.mag.offsets`): per window of a few seconds, the offset c that is constant in the body
frame while the board turns.

1. **Change points of c.**  Optimal partitioning (Jackson et al. 2005, "An algorithm for optimal
   partitioning of data on an interval", IEEE SPL 12(2)) of the windows into stretches of constant c:
   a stretch costs Σ_w (c_S − c_w)ᵀ N_w (c_S − c_w) / s² plus ``penalty`` per stretch, s² the
   windows' own scatter (their model error — soft iron, gyro drift, the room's gradient — is larger
   than the sensor noise; estimated robustly from neighbouring windows, then from the stretches
   found, :func:`_window_scale`).
2. **Is a change real?**  Neighbouring stretches are merged back, weakest first, until every change
   is both significant — T = Δcᵀ (Σ₁ + Σ₂)⁺ Δc beyond the χ²(ρ) quantile 1 − ``alpha`` — and at
   least ``floor_ut`` (µT) in size; stretches whose offsets agree (non-neighbours too: a magnet
   taken off returns the first hard iron) become one hypothesis.
3. **Which samples belong where.**  Every hypothesis j (offset c_j, field F_j) explains a sample by
   |m_k − c_j| = F_j and, while the board is quasi-static, by the inclination against gravity.  A
   Viterbi pass over ``fine_s`` windows labels each with a hypothesis or "unexplained" (a fixed cost
   of ``unexplained_z``²), switching at a cost of ``switch_z``²: this places a change that happened
   while the board rested (where the gyro sees nothing) at the step in the field, and marks the
   transition while a hand brings a magnet as neither.  A change's time is the middle of its
   transition, its σ the transition's width /√12 or, without one, the stretch where the labelling's
   cost rises by less than 1 (one σ).

The result, :class:`RegimeSplit`, lists the hypotheses (hard iron), per-sample labels and the
changes with their evidence; :func:`calib.mag.calibrate.calibrate_magnetometer` then calibrates each
regime on its own samples.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from gyrosim.lazy import lazy_module

from calib.mag.offsets import MIN_TURN, WindowOffsets, window_offsets

# imported on first use (gyrosim.lazy), so that start-up and a refused file do not pay for it
stats = lazy_module("scipy.stats")

__all__ = ["RegimeSettings", "Hypothesis", "Change", "RegimeSplit", "detect_regimes", "offset_change_test",
           "stretch_offset_test", "merge_hypotheses"]

UNEXPLAINED = -1


@dataclass(frozen=True)
class RegimeSettings:
    """The regime detector's settings (module docstring).

    ``window_s`` (s) window of the gyro-aided offsets; ``min_turn`` information per sample below
    which a direction is not seen; ``penalty`` cost of one more stretch (in units of the windows'
    scatter, χ²); ``min_scatter_ut`` (µT) the least scatter of a fully turning window's offset that
    is assumed, however few windows there are to measure it; ``systematic_ut`` (µT per axis) the
    error a stretch's offset shares with all its windows — the soft iron and the gyro's scale
    errors bias each stretch by how it turned (BROAD's undisturbed trials: stretches 0.5–0.9 µT
    apart; a simulated MPU-9250 with 1.5 % soft iron and 1 % gyro scale: up to 2.4 µT);
    ``max_offset_std_ut`` (µT) the largest σ a hypothesis may have in its worst direction;
    ``floor_ut`` (µT) the smallest hard-iron change reported (a 1.5 µT offset moves a 20 µT
    horizontal field's heading by ≤ 4°); ``alpha`` the false-alarm probability of one change;
    ``fine_s`` (s) the resolution of the change times; ``max_transition_s`` (s) the longest stretch
    around a change that is left to neither hard iron (a hand fixing a magnet: BROAD 34's took
    1.5 s); ``switch_z`` and ``unexplained_z`` (σ) the labelling's costs; ``min_hypothesis_s`` (s)
    the least time a hypothesis must explain."""

    window_s: float = 2.0
    min_turn: float = MIN_TURN
    penalty: float = 25.0
    min_scatter_ut: float = 0.2
    systematic_ut: float = 0.5
    max_offset_std_ut: float = 1.0
    floor_ut: float = 1.5
    alpha: float = 1e-4
    fine_s: float = 0.25
    max_transition_s: float = 3.0
    switch_z: float = 5.0
    unexplained_z: float = 4.0
    min_hypothesis_s: float = 2.0


@dataclass(frozen=True)
class Hypothesis:
    """One body-frame offset: c (µT, body) and its covariance from the windows that see it, the
    field magnitude |m − c| it leaves (µT), and the windows it was estimated from."""

    offset_ut: np.ndarray
    cov: np.ndarray
    field_ut: float
    windows: tuple[int, ...]


@dataclass(frozen=True)
class Change:
    """A change of the hard iron between hypotheses ``before`` → ``after`` at ``time_s`` ± ``std_s``,
    with the transition (s) in which no hypothesis explained the field (empty when the change was
    abrupt), and the test: the offset change (µT, body) with its σ, the statistic T, its degrees of
    freedom and the false-alarm probability."""

    time_s: float
    std_s: float
    transition_s: tuple[float, float]
    before: int
    after: int
    offset_change_ut: np.ndarray
    offset_change_std_ut: np.ndarray
    chi2: float
    dof: int
    p_value: float

    def to_dict(self) -> dict:
        return {"time_s": self.time_s, "std_s": self.std_s, "transition_s": list(self.transition_s),
                "offset_change_uT": self.offset_change_ut.tolist(),
                "offset_change_std_uT": self.offset_change_std_ut.tolist(), "chi2": self.chi2, "dof": self.dof,
                "p_value": self.p_value, "test": "body-frame offset change (gyro-aided windows)"}


@dataclass(frozen=True)
class RegimeSplit:
    """Hypotheses, the per-sample label (hypothesis index, or −1 in a transition), the changes in
    time order, the windows' scatter scale (µT² per unit information) and notes for diagnostics."""

    hypotheses: tuple[Hypothesis, ...]
    labels: np.ndarray
    changes: tuple[Change, ...]
    scale: float
    offsets: WindowOffsets
    notes: dict = field(default_factory=dict)

    @property
    def single(self) -> bool:
        return len(self.hypotheses) <= 1


# ---------------------------------------------------------------------------------------- stretches of c
def _pinv(a: np.ndarray) -> np.ndarray:
    return np.linalg.pinv(a, rcond=1e-9, hermitian=True)


def _rank(a: np.ndarray) -> int:
    scale = float(np.abs(a).max()) if a.size else 0.0
    return int(np.linalg.matrix_rank(a, tol=1e-9 * scale)) if scale > 0 else 0


def _stretch(wo: WindowOffsets, idx) -> tuple[float, np.ndarray, np.ndarray, int]:
    """(excess cost, c, N, degrees of freedom) of one common offset over the windows ``idx``."""
    ns, rs = wo.info[idx].sum(axis=0), wo.rhs[idx].sum(axis=0)
    c = _pinv(ns) @ rs
    q = float(np.einsum("wi,wi->", wo.rhs[idx], wo.offset_ut[idx]))
    return max(q - float(rs @ c), 0.0), c, ns, int(wo.rank[idx].sum()) - _rank(ns)


def _window_scale(wo: WindowOffsets, cuts: list[int]) -> float | None:
    """Robust scatter s² of the windows about their stretch's offset: the median over windows of
    their cost share / the median of χ²(rank) (between neighbours when ``cuts`` is empty)."""
    vals = []
    if not cuts:
        for i in range(wo.size - 1):
            cost, _, _, dof = _stretch(wo, [i, i + 1])
            if dof > 0:
                vals.append(cost / stats.chi2.ppf(0.5, dof))
    else:
        for a, b in zip(cuts[:-1], cuts[1:]):
            idx = [w for w in range(a, b) if wo.rank[w] > 0]
            if len(idx) < 3:
                continue
            _, c, _, _ = _stretch(wo, idx)
            for w in idx:
                d = wo.offset_ut[w] - c
                vals.append(float(d @ wo.info[w] @ d) / stats.chi2.ppf(0.5, wo.rank[w]) * len(idx) / (len(idx) - 1))
    return float(np.median(vals)) if len(vals) >= 5 else None


FULL_TURN_INFO = 2.0 / 3.0  # mean information per sample and direction of a window that turned all round


def _scale_floor(wo: WindowOffsets, st: RegimeSettings) -> float:
    """The least s²: a fully turning window's offset scattering by ``min_scatter_ut``."""
    n_med = float(np.median(wo.n[wo.rank > 0])) if (wo.rank > 0).any() else 1.0
    return st.min_scatter_ut**2 * FULL_TURN_INFO * n_med


def _stretch_cov(ns: np.ndarray, s2: float, st: RegimeSettings) -> np.ndarray:
    """Covariance of a stretch's offset: its windows' scatter s² N⁺ plus the error the stretch shares
    (``systematic_ut`` per axis), both in the directions the stretch sees."""
    ev, vec = np.linalg.eigh(ns)
    keep = ev > 1e-9 * max(float(ev.max()), 1e-300)
    v = vec[:, keep]
    return (v / ev[keep]) @ v.T * s2 + st.systematic_ut**2 * (v @ v.T)


def _partition(wo: WindowOffsets, s2: float, penalty: float) -> list[int]:
    """Optimal partitioning: the cut indices [0, …, W] minimising Σ cost/s² + penalty per stretch."""
    nw = wo.size
    pn = np.concatenate([np.zeros((1, 3, 3)), np.cumsum(wo.info, axis=0)])
    pr = np.concatenate([np.zeros((1, 3)), np.cumsum(wo.rhs, axis=0)])
    pq = np.concatenate([[0.0], np.cumsum(np.einsum("wi,wi->w", wo.rhs, wo.offset_ut))])
    best = np.full(nw + 1, np.inf)
    best[0] = 0.0
    arg = np.zeros(nw + 1, dtype=int)
    for b in range(1, nw + 1):
        a = np.arange(b)
        ns, rs = pn[b] - pn[a], pr[b] - pr[a]
        c = np.einsum("aij,aj->ai", np.linalg.pinv(ns, rcond=1e-9, hermitian=True), rs)
        cost = np.maximum(pq[b] - pq[a] - np.einsum("ai,ai->a", rs, c), 0.0)
        tot = best[a] + cost / s2 + penalty
        k = int(np.argmin(tot))
        best[b], arg[b] = tot[k], k
    cuts, b = [nw], nw
    while b > 0:
        b = arg[b]
        cuts.append(b)
    return cuts[::-1]


def offset_change_test(c1: np.ndarray, cov1: np.ndarray, c2: np.ndarray, cov2: np.ndarray
                       ) -> tuple[np.ndarray, np.ndarray, float, int, float]:
    """(Δc, σ(Δc), T, ρ, p): the change of a body-frame offset and its χ² test in the ρ directions
    both estimates see (Δc = c₂ − c₁; p the probability of a T this large without a change)."""
    cov = cov1 + cov2
    dof = _rank(cov)
    d = c2 - c1
    t = float(d @ _pinv(cov) @ d) if dof else 0.0
    p = float(stats.chi2.sf(t, dof)) if dof else 1.0
    return d, np.sqrt(np.clip(np.diag(cov), 0, None)), t, dof, p


def _merge_weak(wo: WindowOffsets, cuts: list[int], s2: float, st: RegimeSettings) -> list[int]:
    """Remove cuts, weakest first, until every change passes the size floor and the χ² test."""
    cuts = list(cuts)
    while len(cuts) > 2:
        worst, worst_p = None, -1.0
        for i in range(1, len(cuts) - 1):
            a, b, c = cuts[i - 1], cuts[i], cuts[i + 1]
            _, c1, n1, _ = _stretch(wo, range(a, b))
            _, c2, n2, _ = _stretch(wo, range(b, c))
            d, _, _, dof, p = offset_change_test(c1, _stretch_cov(n1, s2, st), c2, _stretch_cov(n2, s2, st))
            small = dof == 0 or float(np.linalg.norm(d)) < st.floor_ut
            score = 2.0 if small else p
            if score > worst_p:
                worst, worst_p = i, score
        if worst_p <= st.alpha:
            break
        del cuts[worst]
    return cuts


def _hypotheses(wo: WindowOffsets, cuts: list[int], s2: float, st: RegimeSettings) -> list[Hypothesis]:
    """One hypothesis per stretch that sees its offset in all three directions to ``max_offset_std_ut``
    (with at least one window that turned about two axes); stretches that agree merged (module
    docstring, step 2)."""
    groups: list[list[int]] = []
    for a, b in zip(cuts[:-1], cuts[1:]):
        idx = [w for w in range(a, b) if wo.rank[w] > 0]
        if not idx or not wo.turning[idx].any():
            continue
        ev = np.linalg.eigvalsh(wo.info[idx].sum(axis=0))
        if ev[0] > 0 and math.sqrt(s2 / ev[0]) <= st.max_offset_std_ut:
            groups.append(idx)
    merged = True
    while merged and len(groups) > 1:
        merged = False
        for i in range(len(groups)):
            for j in range(i + 1, len(groups)):
                _, c1, n1, _ = _stretch(wo, groups[i])
                _, c2, n2, _ = _stretch(wo, groups[j])
                d, _, _, dof, p = offset_change_test(c1, _stretch_cov(n1, s2, st), c2, _stretch_cov(n2, s2, st))
                if dof == 0 or np.linalg.norm(d) < st.floor_ut or p > st.alpha:
                    groups[i] = sorted(groups[i] + groups.pop(j))
                    merged = True
                    break
            if merged:
                break
    out = []
    for g in groups:
        _, c, ns, _ = _stretch(wo, g)
        out.append(Hypothesis(c, _stretch_cov(ns, s2, st), float("nan"), tuple(g)))
    return out


# ---------------------------------------------------------------------------------------- sample labels
def _fine_mean(x: np.ndarray, ok: np.ndarray, starts: np.ndarray, fine: int) -> np.ndarray:
    """Mean of x over the ``ok`` samples of each fine window (NaN with fewer than a quarter of them)."""
    s = np.add.reduceat(np.where(ok, x, 0.0), starts)
    c = np.add.reduceat(ok.astype(float), starts)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(c >= max(1, fine // 4), s / c, np.nan)


def _field_costs(m: np.ndarray, valid: np.ndarray, hyps: list[Hypothesis], own: list[np.ndarray],
                 up_body: np.ndarray | None, quasi_static: np.ndarray | None, starts: np.ndarray, fine: int
                 ) -> tuple[np.ndarray, list[Hypothesis]]:
    """Costs (T, K) of the field each hypothesis leaves: the squared mean of |m − c_j| − F_j per fine
    window over its robust σ, plus the same for the inclination against gravity where the board was
    quasi-static; F_j, the inclination and both σ from the samples ``own[j]`` that hypothesis
    explains (first its windows, then the samples it was given: every attitude the regime saw, so
    that the soft iron's attitude-dependent error is in σ).  Returns the hypotheses with their F_j."""
    cost = np.zeros((starts.size, len(hyps)))
    out = []
    for j, h in enumerate(hyps):
        mine = valid & own[j]
        d = m - h.offset_ut
        norm = np.linalg.norm(d, axis=1)
        f = float(np.median(norm[mine]))
        out.append(Hypothesis(h.offset_ut, h.cov, f, h.windows))
        r = norm - f
        cost[:, j] = np.nan_to_num((_fine_mean(r, valid, starts, fine)
                                    / _robust_sigma(_fine_mean(r, mine, starts, fine))) ** 2)
        if up_body is None or quasi_static is None or (mine & quasi_static).sum() < 3 * fine:
            continue
        incl = np.degrees(np.arcsin(np.clip(-np.sum(d * up_body, axis=1) / np.maximum(norm, 1e-9), -1, 1)))
        dev = incl - float(np.median(incl[mine & quasi_static]))
        cost[:, j] += np.nan_to_num((_fine_mean(dev, valid & quasi_static, starts, fine)
                                     / _robust_sigma(_fine_mean(dev, mine & quasi_static, starts, fine))) ** 2)
    return cost, out


def _offset_costs(hyps: list[Hypothesis], wo: WindowOffsets, s2: float, st: RegimeSettings, starts: np.ndarray
                  ) -> np.ndarray:
    """Costs (T, K) of each turning window's own offset against each hypothesis' (its χ², spread over
    the window's fine windows): while the board turns, the gyro says which hard iron it is.  A
    window no hypothesis explains (it holds a change, or a magnet in the room) adds nothing: where
    in it the field changed is for the field costs to say."""
    cost = np.zeros((starts.size, len(hyps)))
    for w in np.flatnonzero(wo.turning):
        inside = (starts >= wo.lo[w]) & (starts < wo.hi[w])
        if not inside.any():
            continue
        cov_w = _stretch_cov(wo.info[w], s2, st)
        icov = _pinv(cov_w)
        # only the directions the window sees: the differences projected onto them
        chi2 = [float(d @ icov @ d) for d in (cov_w @ icov @ (wo.offset_ut[w] - h.offset_ut) for h in hyps)]
        if min(chi2) > stats.chi2.isf(st.alpha, int(wo.rank[w])):
            continue
        cost[inside] += np.array(chi2) / inside.sum()
    return cost


def _mask_of(h: Hypothesis, wo: WindowOffsets, n: int) -> np.ndarray:
    sel = np.zeros(n, dtype=bool)
    for w in h.windows:
        sel[wo.lo[w]:wo.hi[w]] = True
    return sel


def _robust_sigma(x: np.ndarray) -> float:
    x = x[np.isfinite(x)]
    if x.size < 5:
        return float("inf")
    s = float(1.4826 * np.median(np.abs(x - np.median(x))))
    return max(s, 1e-6)


def _viterbi(cost: np.ndarray, switch: float, unexplained: float) -> np.ndarray:
    """Labels (T,) in 0..K−1 or −1 (unexplained) minimising Σ cost + ``switch`` per change of label
    (half of it to enter or leave "unexplained")."""
    t, k = cost.shape
    full = np.concatenate([cost, np.full((t, 1), unexplained)], axis=1)
    trans = np.full((k + 1, k + 1), switch)
    trans[:, k] = trans[k, :] = switch / 2
    np.fill_diagonal(trans, 0.0)
    acc = full[0].copy()
    back = np.zeros((t, k + 1), dtype=int)
    for i in range(1, t):
        tot = acc[:, None] + trans
        back[i] = np.argmin(tot, axis=0)
        acc = tot[back[i], np.arange(k + 1)] + full[i]
    lab = np.empty(t, dtype=int)
    lab[-1] = int(np.argmin(acc))
    for i in range(t - 1, 0, -1):
        lab[i - 1] = back[i, lab[i]]
    return np.where(lab == k, UNEXPLAINED, lab)


def _runs(lab: np.ndarray) -> list[tuple[int, int, int]]:
    """(label, start, end) of the runs of equal labels (end exclusive)."""
    edges = np.flatnonzero(np.diff(lab)) + 1
    starts = np.r_[0, edges]
    ends = np.r_[edges, lab.size]
    return [(int(lab[a]), int(a), int(b)) for a, b in zip(starts, ends)]


def _settle_unexplained(lab: np.ndarray) -> np.ndarray:
    """Unexplained runs inside one hypothesis (or at an end) go back to it: only those between two
    different hypotheses are transitions (a stretch that is off inside a regime is that regime's
    business: its own fit finds and excludes it)."""
    lab = lab.copy()
    runs = _runs(lab)
    for i, (v, a, b) in enumerate(runs):
        if v != UNEXPLAINED:
            continue
        left = runs[i - 1][0] if i > 0 else None
        right = runs[i + 1][0] if i + 1 < len(runs) else None
        if left is None or right is None or left == right:
            lab[a:b] = right if left is None else left
    return lab


def _absorb_short_end_runs(lab: np.ndarray, min_len: int) -> np.ndarray:
    """A run of one hypothesis shorter than ``min_len`` fine windows at the start or the end of the
    session (the last window, partly filled, fits another hard iron by chance) goes to the hypothesis
    next to it, with the unexplained windows between."""
    lab = lab.copy()
    runs = [r for r in _runs(lab) if r[0] != UNEXPLAINED]
    if len(runs) < 2:
        return lab
    if runs[0][2] - runs[0][1] < min_len:
        lab[: runs[1][1]] = runs[1][0]
    if runs[-1][2] - runs[-1][1] < min_len:
        lab[runs[-2][2]:] = runs[-2][0]
    return lab


def _switch_profile(cost: np.ndarray, lo: int, hi: int, i: int, j: int) -> tuple[int, float]:
    """Where between fine windows ``lo`` and ``hi`` (inclusive) the field switched from hypothesis i to
    j: the position p (first window of j) minimising Σ_{<p} cost_i + Σ_{≥p} cost_j, and its σ (in
    fine windows): half the width of the positions whose cost is at most 1 more (one σ), at least
    the resolution's 1/√12."""
    seg_i, seg_j = cost[lo:hi + 1, i], cost[lo:hi + 1, j]
    tot = np.r_[0.0, np.cumsum(seg_i)] + np.r_[np.cumsum(seg_j[::-1])[::-1], 0.0]
    within = np.flatnonzero(tot - tot.min() <= 1.0)
    return lo + int(np.argmin(tot)), max((within.max() - within.min()) / 2.0, 1.0 / math.sqrt(12.0))


def _changes(lab: np.ndarray, cost: np.ndarray, starts: np.ndarray, t_s: np.ndarray, fine_s: float,
             hyps: list[Hypothesis], max_transition: int) -> tuple[list[Change], np.ndarray]:
    """The changes between hypotheses in the settled labels (module docstring, step 3), and the
    labels with every transition cut to at most ``max_transition`` fine windows around its change:
    a direct switch is placed by the cost profile over the two runs it joins; a change inside a
    transition by the profile over the transition (and a window either side), its σ at least the
    (cut) transition's width /√12 (the field changed somewhere in it).  A hypothesis the sphere model
    fits poorly (a strong soft iron) can leave long unexplained stretches next to a change; beyond
    the cut they go to the hypotheses on either side."""
    lab = lab.copy()
    runs = _runs(lab)
    out = []
    for k in range(1, len(runs)):
        v, a, b = runs[k]
        prev = runs[k - 1]
        if v == UNEXPLAINED or prev[0] == v:
            continue
        if prev[0] == UNEXPLAINED:  # the change happened inside a transition
            before = runs[k - 2][0]
            p, sig = _switch_profile(cost, max(prev[1] - 1, 0), a, before, v)
            lo, hi = max(prev[1], p - max_transition // 2), min(a, p + (max_transition + 1) // 2)
            lab[prev[1]:lo], lab[hi:a] = before, v
            t0, t1 = float(t_s[starts[lo]]), float(t_s[starts[min(hi, starts.size - 1)]])
            std = max(sig * fine_s, (t1 - t0) / math.sqrt(12.0))
        else:
            before = prev[0]
            p, sig = _switch_profile(cost, prev[1], b - 1, before, v)
            std = sig * fine_s
            t0 = t1 = float(t_s[starts[a]])
        when = float(t_s[starts[min(p, starts.size - 1)]])
        h1, h2 = hyps[before], hyps[v]
        d, sd, chi2, dof, pv = offset_change_test(h1.offset_ut, h1.cov, h2.offset_ut, h2.cov)
        out.append(Change(when, std, (t0, t1), before, v, d, sd, chi2, dof, pv))
    return out, lab


def _refine(changes: list[Change], per_sample: np.ndarray, m: np.ndarray, valid: np.ndarray, t_s: np.ndarray,
            hyps: list[Hypothesis], fine: int) -> tuple[list[Change], np.ndarray]:
    """A change placed to the sample: the split minimising Σ r_i² + Σ r_j² of the two hypotheses'
    |m − c| − F (each over its robust per-sample σ) within a fine window either side of a direct
    switch, or within a transition and a fine window either side (its samples stay unexplained) —
    for a strong magnet the 0.25 s windows' resolution would leave a few hundred µT on the samples
    between."""
    per_sample = per_sample.copy()
    out = []
    n = t_s.size
    for ch in changes:
        direct = ch.transition_s[0] == ch.transition_s[1]
        k0, k1 = (int(np.searchsorted(t_s, x)) for x in ch.transition_s)
        lo, hi = max(k0 - fine, 0), min(k1 + fine, n)
        seg = slice(lo, hi)
        r = []
        for j in (ch.before, ch.after):
            h = hyps[j]
            res = np.linalg.norm(m - h.offset_ut, axis=1) - h.field_ut
            own = valid & (per_sample == j)
            r.append(np.where(valid[seg], res[seg], 0.0) / _robust_sigma(res[own]))
        tot = np.r_[0.0, np.cumsum(r[0] ** 2)] + np.r_[np.cumsum((r[1] ** 2)[::-1])[::-1], 0.0]
        k = lo + int(np.argmin(tot))
        when = float(t_s[min(k, n - 1)])
        if direct:
            per_sample[lo:k], per_sample[k:hi] = ch.before, ch.after
            out.append(replace(ch, time_s=when, transition_s=(when, when)))
        else:
            out.append(replace(ch, time_s=when))
    return out, per_sample


def _label(t_s: np.ndarray, m: np.ndarray, valid: np.ndarray, hyps: list[Hypothesis], wo: WindowOffsets,
           up_body: np.ndarray | None, quasi_static: np.ndarray | None, s2: float, st: RegimeSettings
           ) -> tuple[list[Hypothesis], np.ndarray, list[Change]]:
    """Label every sample (step 3): twice — the second time with each hypothesis' field and σ taken
    from the samples the first gave it —, dropping hypotheses that explain less than
    ``min_hypothesis_s`` or no window in which the board turned."""
    n = t_s.size
    rate = (n - 1) / max(float(t_s[-1] - t_s[0]), 1e-12)
    fine = max(2, int(round(st.fine_s * rate)))
    starts = np.arange(0, n, fine)
    while True:
        own = [_mask_of(h, wo, n) for h in hyps]
        for _ in range(2):
            cost, hyps = _field_costs(m, valid, hyps, own, up_body, quasi_static, starts, fine)
            cost += _offset_costs(hyps, wo, s2, st, starts)
            lab = _viterbi(cost, st.switch_z**2, st.unexplained_z**2)
            lab = _settle_unexplained(_absorb_short_end_runs(lab, int(math.ceil(st.min_hypothesis_s / st.fine_s))))
            changes, lab = _changes(lab, cost, starts, t_s, fine / rate, hyps,
                                    max(1, int(round(st.max_transition_s / st.fine_s))))
            per_sample = np.repeat(lab, np.diff(np.r_[starts, n]))
            own = [(per_sample == j) if (per_sample == j).sum() >= 3 * fine else own[j] for j in range(len(hyps))]
        held = np.array([(lab == j).sum() * fine / rate for j in range(len(hyps))])
        # a hard iron is seen while the board turns: one that only explains rests is a near miss
        turned = np.array([sum(np.mean(per_sample[wo.lo[w]:wo.hi[w]] == j) >= 0.5 for w in np.flatnonzero(wo.turning))
                           for j in range(len(hyps))])
        weak = np.flatnonzero((held < st.min_hypothesis_s) | (turned == 0))
        if len(hyps) <= 1 or weak.size == 0:
            break
        drop = int(weak[np.argmin(held[weak])])
        hyps = [h for j, h in enumerate(hyps) if j != drop]
    changes, per_sample = _refine(changes, per_sample, m, valid, t_s, hyps, fine)
    return hyps, per_sample, changes


def detect_regimes(t_s: np.ndarray, mag_ut: np.ndarray, valid: np.ndarray, gyro_rad_s: np.ndarray,
                   gyro_bias_rad_s: np.ndarray, *, up_body: np.ndarray | None = None,
                   quasi_static: np.ndarray | None = None, settings: RegimeSettings | None = None) -> RegimeSplit:
    """Hard-iron regimes of a session (module docstring).

    ``mag_ut`` (N, 3) µT body frame, ``valid`` (N,) usable samples, ``gyro_rad_s`` (N, 3) body rate
    and its bias (3,); ``up_body`` (N, 3) and ``quasi_static`` (N,) from the gravity reference, if
    there is one.  One hypothesis (or none, when the board never turned about two axes) means one
    regime."""
    st = settings or RegimeSettings()
    n = t_s.size
    wo = window_offsets(t_s, mag_ut, valid, gyro_rad_s, gyro_bias_rad_s, window_s=st.window_s, min_turn=st.min_turn)
    notes: dict = {"windows": wo.size, "window_s": st.window_s, "turning_windows": int(wo.turning.sum())}
    if wo.turning.sum() < 2:
        notes["skipped"] = "the board turned about two axes in fewer than 2 windows: hard-iron changes not sought"
        return RegimeSplit((), np.zeros(n, dtype=int), (), float("nan"), wo, notes)
    floor = _scale_floor(wo, st)
    s2 = max(_window_scale(wo, []) or floor, floor)
    cuts = _partition(wo, s2, st.penalty)
    s2 = max(_window_scale(wo, cuts) or s2, floor)
    cuts = _partition(wo, s2, st.penalty)
    notes["stretches_before_merging"] = len(cuts) - 1
    cuts = _merge_weak(wo, cuts, s2, st)
    hyps = _hypotheses(wo, cuts, s2, st)
    notes["window_scatter_uT"] = math.sqrt(s2 / (FULL_TURN_INFO * float(np.median(wo.n[wo.rank > 0]))))
    if len(hyps) <= 1:
        return RegimeSplit(tuple(hyps), np.zeros(n, dtype=int), (), s2, wo, notes)
    hyps, labels, changes = _label(t_s, mag_ut, valid, hyps, wo, up_body, quasi_static, s2, st)
    if len(hyps) <= 1:
        return RegimeSplit(tuple(hyps), np.zeros(n, dtype=int), (), s2, wo, notes)
    return RegimeSplit(tuple(hyps), labels, tuple(changes), s2, wo, notes)


def _field_rms(m: np.ndarray, c: np.ndarray, f: float) -> float:
    return float(np.sqrt(np.mean((np.linalg.norm(m - c, axis=1) - f) ** 2))) if m.shape[0] else float("nan")


def stretch_offset_test(split: RegimeSplit, t_s: np.ndarray, mag_ut: np.ndarray, t0_s: float, t1_s: float,
                        hypothesis: int, settings: RegimeSettings | None = None) -> dict:
    """Is a stretch (a local disturbance) attached to the board?  The evidence and its ``verdict``:

    * its windows' common body-frame offset against the regime's (:func:`offset_change_test`): a
      field fixed in the room leaves the offset where it was, one that turns with the board moves it
      (by ≥ ``floor_ut``, beyond the 1 − ``alpha`` quantile);
    * it moves it to one place, well determined: the windows agree with each other (homogeneity χ²
      of their common offset: a magnet in the room, passed while turning, biases each window
      differently) and see it in all three directions to ``max_offset_std_ut``;
    * the moved offset explains the field: |m − c| keeps the regime's field magnitude F with at
      most half the RMS deviation the regime's offset leaves there.

    ``attached`` when all hold, ``world-fixed`` otherwise; ``undetermined`` when the board did not
    turn enough there to see the offset in all three directions (no test, or one that cannot tell)."""
    st = settings or RegimeSettings()
    wo = split.offsets
    # the windows at least half inside the stretch
    half = 0.5 * (wo.t_end_s - wo.t_start_s)
    overlap = np.minimum(wo.t_end_s, t1_s) - np.maximum(wo.t_start_s, t0_s)
    idx = [w for w in range(wo.size) if overlap[w] >= half[w] and wo.rank[w] > 0]
    if not idx or not wo.turning[idx].any() or not split.hypotheses or not math.isfinite(split.scale):
        return {"verdict": "undetermined"}
    cost, c, ns, dof_h = _stretch(wo, idx)
    h = split.hypotheses[hypothesis]
    d, sd, chi2, dof, p = offset_change_test(h.offset_ut, h.cov, c, _stretch_cov(ns, split.scale, st))
    chi2_h = cost / split.scale
    p_h = float(stats.chi2.sf(chi2_h, dof_h)) if dof_h > 0 else 1.0
    ev_min = float(np.linalg.eigvalsh(ns)[0])
    well = ev_min > 0 and math.sqrt(split.scale / ev_min) <= st.max_offset_std_ut
    inside = (t_s >= t0_s) & (t_s <= t1_s)
    own = _mask_of(h, wo, t_s.size) & ~inside
    f = float(np.median(np.linalg.norm(mag_ut[own] - h.offset_ut, axis=1))) if own.any() else float("nan")
    rms_regime, rms_own = _field_rms(mag_ut[inside], h.offset_ut, f), _field_rms(mag_ut[inside], c, f)
    attached = (p <= st.alpha and float(np.linalg.norm(d)) >= st.floor_ut and p_h > st.alpha
                and rms_own <= 0.5 * rms_regime)
    verdict = "undetermined" if not well else "attached" if attached else "world-fixed"
    return {"verdict": verdict, "offset_change_uT": d.tolist(),
            "offset_change_std_uT": sd.tolist(), "chi2": chi2, "dof": dof, "p_value": p, "windows": len(idx),
            "homogeneity_chi2": chi2_h, "homogeneity_dof": dof_h, "homogeneity_p_value": p_h,
            "field_rms_regime_offset_uT": rms_regime, "field_rms_own_offset_uT": rms_own}


def merge_hypotheses(split: RegimeSplit, t_s: np.ndarray, keep: int, drop: int,
                     settings: RegimeSettings | None = None) -> RegimeSplit:
    """``split`` with hypothesis ``drop`` folded into ``keep`` (one hard iron, where the caller found
    that one calibration explains both: a strong soft iron makes a regime's windows disagree by how
    they turned, which the offsets alone read as changes).  The changes between the two go, with
    their transitions; the others are tested again against the pooled hypothesis."""
    st = settings or RegimeSettings()
    hk, hd = split.hypotheses[keep], split.hypotheses[drop]
    windows = sorted(set(hk.windows) | set(hd.windows))
    _, c, ns, _ = _stretch(split.offsets, windows)
    pooled = Hypothesis(c, _stretch_cov(ns, split.scale, st), float("nan"), tuple(windows))
    new_index = {j: (keep if j == drop else j) for j in range(len(split.hypotheses))}
    new_index = {j: i - (i > drop) for j, i in new_index.items()}
    hyps = [pooled if j == keep else h for j, h in enumerate(split.hypotheses) if j != drop]
    labels = split.labels.copy()
    changes = []
    for ch in split.changes:
        if {ch.before, ch.after} == {keep, drop}:
            labels[(t_s >= ch.transition_s[0]) & (t_s <= ch.transition_s[1]) & (labels < 0)] = keep
            continue
        changes.append(ch)
    labels = np.where(labels < 0, labels, np.vectorize(new_index.get, otypes=[int])(np.maximum(labels, 0)))
    out = []
    for ch in changes:
        b, a = new_index[ch.before], new_index[ch.after]
        if b == a:  # the stretch between two changes was the dropped hypothesis: no change left here
            continue
        d, sd, chi2, dof, p = offset_change_test(hyps[b].offset_ut, hyps[b].cov, hyps[a].offset_ut, hyps[a].cov)
        out.append(replace(ch, before=b, after=a, offset_change_ut=d, offset_change_std_ut=sd, chi2=chi2, dof=dof,
                           p_value=p))
    return RegimeSplit(tuple(hyps), labels, tuple(out), split.scale, split.offsets, dict(split.notes))
