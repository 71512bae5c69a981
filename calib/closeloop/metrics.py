"""Held-out error metrics, and whether a model change makes any of them worse beyond its own noise.

Every metric is a mean square over the held-out groups (the odd 4 s stretches of the split; the
rest poses of the gravity reference), kept per group: Σ squares SS_g and count n_g.

The metrics (reference; rows; what they weigh):

``held_out_residual_rms`` (°/s)
    Reference: truth / optical / static rate.  Rows: the rate residual rows.  Weighs fast
    structure: timing, the rate's high frequencies.
``held_out_strapdown_orientation_rms_deg`` (°)
    Reference: the reference attitude.  Rows: the corrected gyro integrated over each held-out
    stretch from the reference attitude at its start, angle to the reference.  Weighs slow errors
    integrated over a stretch: bias, scale, frame alignment.
``held_out_rest_rate_rms_deg_s`` (°/s)
    Reference: zero rate at rest.  Rows: the gravity reference's rest rows.  Weighs the bias (and a
    hand not quite still).
``held_out_tilt_rms_deg`` (°)
    Reference: gravity carried pose to pose.  Rows: the gravity reference's tilt rows (the gravity
    residual).  Weighs the rate integrated over the moves: scale, axes.

**Noise of a change.**  Two models A (before) and B (after) are scored on the same held-out
groups, so the change is judged group by group: d_g = (SS_B,g − SS_A,g) / n_g, the change of the
group's mean square.  The groups differ in how much an effect shows (a misalignment shows where the
board turns, not at rest), so the *size* of d_g varies from group to group for reasons that are
not noise; what noise cannot do is make most groups change the same way.  The test is therefore
Wilcoxon's signed-rank statistic on the d_g (zeros dropped), in its normal approximation,

    W = Σ_g sign(d_g) · rank(|d_g|),   z = W / √(n(n + 1)(2n + 1)/6).

The stretches are taken as independent: neighbouring held-out stretches are 8 s apart, and d_g is
the difference of two models on the same data, in which a drift common to both cancels to first
order.  With m metrics tested per addition,
a change is *worse beyond its noise* when z > Φ⁻¹(1 − 0.01/m) (one-sided, family-wise 1 % false
alarm for an addition that changes no metric: 2.33 for one metric, 2.58 for two), and *better*
when z < −that.  The largest |z| of n groups (all changing the same way) is √(3n(n + 1)/(2(2n + 1))):
with fewer than 7 held-out groups no change can reach 2.33 and with fewer than 9 none can reach
2.58 — on so short a recording the report calls every metric "same".
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Callable

import numpy as np
from scipy import stats

from gyrosim.recording import Recording
from gyrosim.rotations import quat_angle_between, quat_conjugate, quat_multiply
from gyrosim.strapdown import integrate_gyro
from gyrosim.units import RAD2DEG

from calib.closeloop.fit import held_out_split
from calib.closeloop.reference import GravityReference, RateReference, Reference

__all__ = ["MetricSums", "MetricChange", "MetricContext", "held_out_metrics", "compare_metrics", "z_worse",
           "explain_disagreement"]



@dataclass(frozen=True)
class MetricSums:
    """One metric of one model: per held-out group Σ squares (display units²) and counts."""

    name: str
    unit: str
    reference: str          # what the metric compares against
    weighs: str             # what it is most sensitive to
    ss: np.ndarray
    n: np.ndarray

    @property
    def value(self) -> float:
        tot = float(self.n.sum())
        return math.sqrt(float(self.ss.sum()) / tot) if tot else math.nan


@dataclass(frozen=True)
class MetricChange:
    """How one metric moved from model A to model B on the held-out groups."""

    name: str
    unit: str
    before: float
    after: float
    relative_change: float   # after / before − 1 (RMS)
    z: float                 # Δ(mean square) / its standard error; > 0: worse
    groups: int
    threshold: float
    verdict: str             # "worse", "better" or "same"
    reference: str
    weighs: str

    def to_json(self) -> dict:
        return asdict(self)

    def describe(self) -> str:
        return (f"{self.name} {self.before:.4g} → {self.after:.4g} {self.unit} ({self.relative_change:+.1%}, "
                f"z = {self.z:+.1f})")


@dataclass(frozen=True)
class MetricContext:
    """What the metrics need besides a model: the reference, its held-out groups, the reference attitude."""

    ref: Reference
    held_rows: np.ndarray
    t_s: np.ndarray
    quat_ref: np.ndarray | None      # (N, 4) body→ENU reference attitude (NaN where missing), or None
    sample_group: np.ndarray | None  # (N,) held-out group of each sample (rate references)

    @classmethod
    def of(cls, ref: Reference, rec: Recording) -> "MetricContext":
        _, held = held_out_split(ref)
        tr = rec.truth
        quat = None
        if isinstance(ref, RateReference) and ref.kind != "static" and tr is not None and tr.quat_nb is not None:
            quat = np.asarray(tr.quat_nb, float)
        groups = ref.sample_groups() if isinstance(ref, RateReference) else None
        return cls(ref, held, np.asarray(rec.t_s, float), quat, groups)


def _per_group(values_sq: np.ndarray, groups: np.ndarray, keep: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    g = groups[keep]
    if g.size == 0:
        return np.zeros(0), np.zeros(0)
    uniq, inv = np.unique(g, return_inverse=True)
    return np.bincount(inv, values_sq[keep]), np.bincount(inv).astype(float)


def _rate_rows(mc: MetricContext, residual: np.ndarray, corrected: np.ndarray) -> list[MetricSums]:
    ref = mc.ref
    if not isinstance(ref, RateReference):
        return []
    ss, n = _per_group((residual * RAD2DEG) ** 2, ref.groups, mc.held_rows)
    return [MetricSums("held_out_residual_rms", "°/s", f"the {ref.kind} rate rows",
                       "fast structure: timing and the rate's high frequencies", ss, n)]


def _strapdown(mc: MetricContext, residual: np.ndarray, corrected: np.ndarray) -> list[MetricSums]:
    """Corrected gyro integrated over each held-out stretch from the reference attitude at its first
    valid sample; the angle to the reference attitude at every sample of the stretch."""
    q_ref, grp = mc.quat_ref, mc.sample_group
    if q_ref is None or grp is None:
        return []
    good = np.all(np.isfinite(q_ref), axis=1)
    held = (grp % 2 == 1) & good
    if held.sum() < 10:
        return []
    q_cum = integrate_gyro(mc.t_s, corrected, np.array([1.0, 0.0, 0.0, 0.0]))
    idx = np.arange(grp.size)
    first = np.full(int(grp.max()) + 1, -1)
    hi = idx[held]
    # first valid held-out sample of each group
    order = np.unique(grp[hi], return_index=True)
    first[order[0]] = hi[order[1]]
    s = first[grp[hi]]
    start = quat_multiply(q_ref[s], quat_conjugate(q_cum[s]))
    err = quat_angle_between(quat_multiply(start, q_cum[hi]), q_ref[hi]) * RAD2DEG
    ok = np.isfinite(err)
    keep = np.zeros(grp.size, bool)
    keep[hi[ok]] = True
    sq = np.zeros(grp.size)
    sq[hi[ok]] = err[ok] ** 2
    ss, n = _per_group(sq, grp, keep)
    return [MetricSums("held_out_strapdown_orientation_rms_deg", "°", "the reference attitude (integrated gyro)",
                       "slow errors integrated over each stretch: bias, scale, frame alignment", ss, n)]


def _gravity(mc: MetricContext, residual: np.ndarray, corrected: np.ndarray) -> list[MetricSums]:
    ref = mc.ref
    if not isinstance(ref, GravityReference):
        return []
    k = ref.rate_rows_share
    idx = np.arange(residual.size)
    rate = residual * ref.rest_sigma_rad_s * RAD2DEG
    tilt = residual * ref.tilt_sigma_rad * RAD2DEG
    rs, rn = _per_group(np.where(idx < k, rate, 0.0) ** 2, ref.groups, mc.held_rows & (idx < k))
    ts, tn = _per_group(np.where(idx >= k, tilt, 0.0) ** 2, ref.groups, mc.held_rows & (idx >= k))
    # align both on the union of groups so that paired differences line up
    return [MetricSums("held_out_rest_rate_rms_deg_s", "°/s", "zero rate at the rest poses",
                       "the bias, and a hand not quite still", rs, rn),
            MetricSums("held_out_tilt_rms_deg", "°", "gravity carried from pose to pose (the gravity residual)",
                       "the rate integrated over each move: scale and axes", ts, tn)]


METRICS: tuple[Callable[[MetricContext, np.ndarray, np.ndarray], list[MetricSums]], ...] = (_rate_rows, _strapdown,
                                                                                              _gravity)


def held_out_metrics(mc: MetricContext, residual: np.ndarray, corrected_gyro: np.ndarray) -> dict[str, MetricSums]:
    """Every metric the reference offers, for a model's residual rows and corrected gyro (N, 3) rad/s."""
    out: dict[str, MetricSums] = {}
    for metric in METRICS:
        for m in metric(mc, residual, corrected_gyro):
            if m.n.sum() > 0:
                out[m.name] = m
    return out


def z_worse(m: int) -> float:
    """One-sided threshold for m metrics at a family-wise 1 % false alarm."""
    return float(stats.norm.ppf(1.0 - 0.01 / max(1, m)))


def _signed_rank_z(d: np.ndarray) -> tuple[float, int]:
    """Wilcoxon signed-rank z of the per-group changes d (see the module docstring), and n."""
    d = d[d != 0]
    n = d.size
    if n == 0:
        return 0.0, 0
    ranks = stats.rankdata(np.abs(d))
    signed = np.sign(d) * ranks
    var = n * (n + 1) * (2 * n + 1) / 6.0
    return float(signed.sum() / math.sqrt(var)), n


def compare_metrics(before: dict[str, MetricSums], after: dict[str, MetricSums]) -> list[MetricChange]:
    """Paired comparison of every metric both models have (see the module docstring)."""
    names = [k for k in before if k in after]
    thr = z_worse(len(names))
    out = []
    for k in names:
        a, b = before[k], after[k]
        z, g = _signed_rank_z((b.ss - a.ss) / np.maximum(a.n, 1))
        verdict = "worse" if z > thr else "better" if z < -thr else "same"
        rel = b.value / a.value - 1.0 if a.value > 0 else math.nan
        out.append(MetricChange(k, a.unit, a.value, b.value, rel, z, g, thr, verdict, a.reference, a.weighs))
    return out


def explain_disagreement(changes: list[MetricChange], fitted_on: str, caveat: str | None) -> str | None:
    """When one metric improves beyond its noise and another worsens beyond its noise: say so, and
    which reference is likely at fault (the one that gains: the term takes up something in it that
    the other view does not see)."""
    better = [c for c in changes if c.verdict == "better"]
    worse = [c for c in changes if c.verdict == "worse"]
    if not (better and worse):
        return None
    text = (f"the metrics disagree: {', '.join(c.describe() for c in better)} improved, but "
            f"{', '.join(c.describe() for c in worse)} got worse beyond its noise. "
            f"{' and '.join(c.name for c in worse)} compares against {' and '.join(c.reference for c in worse)} and "
            f"weighs {'; '.join(c.weighs for c in worse)}; the term was fitted to {fitted_on}. Likely at fault: "
            f"{better[0].reference}, whose flaw the term takes up where the other view does not see it")
    return text + (f" ({caveat})" if caveat else "")
