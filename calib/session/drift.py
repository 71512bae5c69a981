"""The gyro bias's drift during a session, from the session's own rests (never from a sensor model).

A consumer gyro's bias moves during a session (warm-up, its g-sensitivity after a change of attitude, bias
instability).  :func:`bias_drift` measures how much from the rests' means; ``kf_hand`` models the bias as a random walk
of that intensity (ḃ_g = w, E w² = q_b; 0 when the rests agree within their white noise), and the paper's filters,
which hold the bias at the first rest's average, say why their innovations carry low-frequency power
(:func:`bias_drift_note`).  Two rests cannot tell a random walk from a flicker floor: :func:`drift_ambiguity` gives σ
as the two models' mixture when the temperature stayed flat.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import stats

from gyrosim.recording import Recording

from calib.session.consistency import Inflation
from calib.session.prepare import Prepared

__all__ = ["DRIFT_QUANTILE", "BiasDrift", "bias_drift", "bias_drift_note", "drift_ambiguity"]


DRIFT_QUANTILE = 0.95      # the rests' bias differences must exceed their white-noise χ² quantile to be drift


@dataclass(frozen=True)
class BiasDrift:
    """The gyro bias's drift seen between the session's rests (:func:`bias_drift`): the random-walk
    intensity q_b (rad²/s³ per axis; √q_b in rad/s/√s is IEEE 952's rate random walk K), the statistic
    X = Σ|Δb̄|²/(s_i² + s_j²) with its degrees of freedom and the threshold it had to pass, and the rest
    means (rad/s, body) at their mid times (s)."""

    q_rad2_s3: float
    chi2: float
    dof: int
    threshold: float
    rest_bias_rad_s: tuple[tuple[float, float, float], ...]
    rest_mid_s: tuple[float, ...]

    @property
    def rrw_rad_s_sqrt_s(self) -> float:
        return math.sqrt(self.q_rad2_s3)

    def to_dict(self) -> dict:
        return {"rate_random_walk_rad_s_sqrt_s": self.rrw_rad_s_sqrt_s, "q_rad2_s3": self.q_rad2_s3,
                "chi2": self.chi2, "dof": self.dof, "threshold_95": self.threshold,
                "rest_bias_rad_s": [list(b) for b in self.rest_bias_rad_s], "rest_mid_s": list(self.rest_mid_s)}


def bias_drift(gyro_rad_s: np.ndarray, t_s: np.ndarray, rests: tuple[tuple[int, int], ...],
               arw_rad_s_sqrt_hz: float, min_rest_s: float = 2.0, quantile: float = DRIFT_QUANTILE) -> BiasDrift:
    """The gyro bias's random-walk intensity q_b from the recording's own rests (never from a sensor model).

    At a rest the gyro reads its bias (plus white noise): the mean b̄_i over rest i (length L_i) has
    white-noise variance s_i² = N_g²/L_i per axis.  For a bias that is a random walk ḃ = w,
    E[w²] = q_b, the mean over a window of length L differs from the walk's value at the window's
    edge by a variance q_b L/3 (∫₀ᴸ (s/L)² ds · q_b), so consecutive rests separated by a gap g_ij
    give  E|b̄_j − b̄_i|² = 3 [q_b (g_ij + (L_i + L_j)/3) + s_i² + s_j²]  (three axes).  The
    method-of-moments estimate over the k consecutive pairs:

        q̂_b = Σ (|Δb̄|² − 3(s_i² + s_j²)) / (3 Σ (g_ij + (L_i + L_j)/3)),

    applied only when X = Σ |Δb̄|² / (s_i² + s_j²) exceeds χ²(3k)'s ``quantile`` (95 %) (no drift is
    modelled that the rests' white noise explains), else 0.  A deterministic drift (a warm-up ramp,
    the bias's g-sensitivity after a change of attitude) enters as its end-to-end change: the random
    walk fitted to it predicts a variance ∝ τ over a sub-interval τ where the ramp gives ∝ τ², so the
    model is conservative inside the session.  Sources: the random walk's structure function
    (IEEE Std 952-1997 Annex C, rate random walk: σ²(τ) = K²τ/3 for the Allan variance, the same
    window-mean argument); Brown & Hwang, *Introduction to Random Signals and Applied Kalman
    Filtering*, 4th ed., §2.10 (Wiener process), §9 (a gyro bias as a random-walk state).
    """
    means, mids, lengths, s2 = [], [], [], []
    for a, b in rests:
        if b - a < 2 or t_s[b - 1] - t_s[a] < min_rest_s:
            continue
        L = float(t_s[b - 1] - t_s[a])
        means.append(np.mean(gyro_rad_s[a:b], axis=0))
        mids.append(0.5 * float(t_s[a] + t_s[b - 1]))
        lengths.append(L)
        s2.append(arw_rad_s_sqrt_hz**2 / L)
    k = len(means) - 1
    if k < 1:
        return BiasDrift(0.0, 0.0, 0, float("inf"), tuple(tuple(m) for m in means), tuple(mids))
    num, den, x = 0.0, 0.0, 0.0
    for i in range(k):
        d2 = float(np.sum((means[i + 1] - means[i]) ** 2))
        gap = (mids[i + 1] - lengths[i + 1] / 2) - (mids[i] + lengths[i] / 2)
        num += d2 - 3.0 * (s2[i] + s2[i + 1])
        den += 3.0 * (max(gap, 0.0) + (lengths[i] + lengths[i + 1]) / 3.0)
        x += d2 / (s2[i] + s2[i + 1])
    thr = float(stats.chi2.ppf(quantile, 3 * k))
    q = max(num, 0.0) / den if x > thr else 0.0
    return BiasDrift(q, x, 3 * k, thr, tuple(tuple(float(v) for v in m) for m in means), tuple(mids))


def drift_ambiguity(cov_rw: np.ndarray, cov_const: np.ndarray, infl_const: Inflation) -> tuple[np.ndarray, dict]:
    """σ of the reported parameters when the rests saw a gyro bias drift that the temperature does not explain.

    Two rests (3 degrees of freedom) measure how far the bias moved, not how it moved: a random walk (the
    model, q_b from :func:`bias_drift`) and a flicker floor (a warmed-up MEMS gyro's bias instability, PSD
    B²/(2πf), IEEE Std 952 Annex C) fitted to the same end-to-end change differ inside the session, where S
    and G are learnt (the flicker has more power at 0.01–0.1 Hz).  The random-walk filter absorbs that power
    into its bias state, so its innovations show no excess and κ̂ stays 1, while S, G take the error
    (measured, warmed-up MPU-9250 — its preset without warm-up and g-sensitivity — ideal hand, 200 seeds:
    NEES(6) 8.04, σ ~1.16× small, every seed ``ok``).  The last pass run with a constant bias (q_b = 0) leaves
    the drift in its innovations, where κ̂₀ (one-sided, :func:`calib.session.consistency.innovation_inflation`) sees
    it.  The session cannot tell the two models apart, so they are given equal weight — a two-model mixture's
    variance (Bar-Shalom, Li & Kirubarajan, *Estimation with Applications to Tracking and Navigation*, 2001,
    §11.6, the multiple-model estimate's covariance), here without its spread-of-means term and never below
    the random-walk model's:

        σ_i² = max(σ_i,rw², (σ_i,rw² + κ̂₀ σ_i,const²) / 2),   C ← D C_rw D,   D_ii = σ_i / σ_i,rw

    (the random-walk model's correlations and estimate kept — its S error is 7 % smaller on the same seeds).
    Applied when the recording's temperature channel stayed flat (< ``THERMAL_MIN_SPAN_C``,
    :mod:`calib.session.hand.thermal`): then the drift is not
    a warm-up.  Without a channel a warm-up's ramp is as likely, and on it the constant-bias pass's κ̂₀ is 5–38
    (flicker: 1.9–3.3): the mixture took the MPU-9250 preset with its channel removed from NEES(6) 5.93 to 2.2
    (kf_hand, 50 seeds) — so there the random walk stays alone, with a warning.
    Measured (200 seeds, ideal hand, NEES(6), band [5.52, 6.48]): the warmed-up MPU-9250 8.04 → 6.75; with its
    g-sensitivity (a bias step at each change of attitude, which the constant-bias pass reads as drift) 7.25 →
    5.21; the larger of the two σ instead of the mixture gave 5.96 and 4.21.  ``cov_rw``: the reported block
    with its own κ̂ applied; ``cov_const``: the same block of the constant-bias pass, before κ̂₀."""
    ratio = np.sqrt(np.diag(cov_const) * infl_const.factor / np.diag(cov_rw))
    d = np.sqrt(np.maximum((1.0 + ratio**2) / 2.0, 1.0))
    return cov_rw * np.outer(d, d), {"kappa_constant_bias": float(infl_const.factor),
                                     "sigma_ratio_constant_over_random_walk": ratio.tolist(),
                                     "sigma_factor": d.tolist()}


def bias_drift_note(rec: Recording, prep: Prepared) -> str | None:
    """Why a constant-bias filter's innovations may carry low-frequency power without any hand: the gyro
    bias moved between the session's rests beyond their white noise (:func:`bias_drift`,
    χ² of the rests' mean differences above its 95 % quantile).  The paper's filter holds the bias at the
    first rest's average (Zhou 2020 §3.2), so a drifting bias tilts its attitude like an unmodelled
    disturbance — the inflation is then right to fire, and this says why."""
    d = bias_drift(rec.gyro_rad_s, rec.t_s, prep.rest.index_ranges, prep.config.arw_rad_s_sqrt_hz)
    if d.q_rad2_s3 <= 0 or len(d.rest_bias_rad_s) < 2:
        return None
    b = np.asarray(d.rest_bias_rad_s)
    change = float(np.max(np.linalg.norm(b[1:] - b[:-1], axis=1)))
    return (f"the gyro bias drifts: the rests' mean gyro readings differ by up to {change:.2e} rad/s (χ² {d.chi2:.0f} "
            f"against its 95 % quantile {d.threshold:.1f}, {d.dof} dof; rate random walk ≈ {d.rrw_rad_s_sqrt_s:.1e} "
            "rad/s/√s): this method holds the bias at the first rest's average, so the drift tilts its attitude like "
            "an unmodelled disturbance and its σ cannot be trusted; the hand-aware method (kf_hand) models the "
            "bias as a random walk fitted to the rests")

