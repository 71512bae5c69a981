"""Does a hand-blind calibration agree with the hand-aware one on the same recording?  The check that sits above both
methods: the paper family's ``calibrate()`` and its registered variants call it on an "ok" result (their callers, not
their verdicts, run it), and it runs ``kf_hand`` (:mod:`calib.session.hand.filter`).

The lever arm's acceleration is correlated with the rotation, so what a model without it aliases into S and G does not
show in its residuals — no test of its own innovations can see it.  :func:`hand_cross_check` compares the two
estimates of S, G; :func:`hand_checked` applies it to a result (status, warnings, ``diagnostics["consistency"]``).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy import stats

from gyrosim.calibration import Calibration
from gyrosim.errors import RecordingError
from gyrosim.recording import Recording

from calib.session.hand.filter import kf_hand

__all__ = ["CROSS_CHECK_TAIL", "hand_cross_check", "hand_checked"]


CROSS_CHECK_TAIL = 0.001


def hand_cross_check(rec: Recording, gyro_params: np.ndarray, cov_sg: np.ndarray,
                     acc_m_s2: np.ndarray | None = None, accelerometer: str = "calibrated") -> tuple[list[str], dict]:
    """Does a hand-blind estimate of S, G (``gyro_params`` (6,), covariance ``cov_sg`` (6, 6)) agree with
    ``kf_hand``'s on the same recording?  The lever arm's acceleration is correlated with the rotation,
    so what a model without it aliases into S and G does not show in its residuals — no test of its own
    innovations can see it.  The difference δ to the hand-aware estimate can: under both models'
    claims δ ~ N(0, C_δ), C_δ ≤ C + C_hand (conservative: the estimates' positive correlation ignored),
    and δᵀC_δ⁻¹δ above χ²₆'s 99.9 % quantile means the hand-blind σ is understated — by at least
    max_i |δ_i|/σ_i / 3 (the factor a 3σ error would need).  ``acc_m_s2``: the accelerometer already
    compensated, else the recording's.  ``accelerometer="estimate"`` (the hand-blind estimate came from a
    joint calibration, the accelerometer estimated too): the peer is ``kf_hand_joint`` on the raw
    recording (``acc_m_s2`` ignored) — kf_hand on the joint calibration's own compensated accelerometer
    inherits its hand-biased |f| = g fit and agreed with wrong S, G (docs/hand.md, "Honest σ") — and the
    test is the one that defines a wrong answer, with kf_hand_joint as the reference: δᵀC⁻¹δ above χ²₆'s
    99.9 % quantile *or* any |δ_i| + 2σ_peer,i > 3σ_i (C = the hand-blind covariance alone; the hand-blind
    error is δ plus the peer's own, |e_peer,i| ≤ 2σ_peer,i at 95 %, and must stay within 3σ_i — without
    the peer's margin two borderline wrong answers of 50 shaky-hand mpu9250 seeds passed).  The two filters read the
    same samples, so their errors share the noise's part: without a hand δ's spread is ~1 % of C + C_hand
    (measured, mean δᵀ(C + C_hand)⁻¹δ / 6 = 0.006–0.01 on the independent generator; docs/hand.md), and
    C + C_hand let wrong "ok" answers pass (17 and 15 of 45 shaky-hand "ok" seeds).  δ is then the hand-caused
    error of the hand-blind answer up to a small fraction of its σ.

    Returns (warnings — empty when consistent or when ``kf_hand`` cannot run on this recording —,
    diagnostics)."""
    joint = accelerometer == "estimate"
    r = rec if acc_m_s2 is None or joint else rec.with_signals(acc_m_s2=acc_m_s2)
    try:
        h = kf_hand(r, accelerometer="estimate") if joint else kf_hand(r)
    except RecordingError as exc:
        return [], {"skipped": str(exc)}
    items = [("gyro", "scale_factor"), ("gyro", "nonorthogonality")]
    th = np.concatenate([h.value(t, k) for t, k in items])
    ch = h.block_covariance(items)
    d = np.asarray(gyro_params, float) - th
    c = np.asarray(cov_sg, float) + (0.0 if joint else ch)
    stat = float(d @ np.linalg.solve(c, d))
    thr = float(stats.chi2.ppf(1 - CROSS_CHECK_TAIL, 6))
    sd = np.sqrt(np.diag(cov_sg))
    under = float(np.max(np.abs(d) / sd) / 3.0)
    # joint: the hand-blind error is e = δ + e_peer with |e_peer,i| ≤ 2σ_peer,i (95 %); the answer stands
    # only if that bound on |e_i| stays within its own 3σ_i
    bound = float(np.max((np.abs(d) + 2.0 * np.sqrt(np.diag(ch))) / sd))
    bad = stat > thr or (joint and bound > 3.0)
    diag = {"chi2": stat, "threshold_99_9": thr, "kf_hand_minus_this": (-d).tolist(),
            "covariance": "this" if joint else "this + kf_hand", "max_abs_delta_over_sigma": 3 * under,
            "max_error_bound_over_sigma": bound if joint else None,
            "sigma_understated_at_least": max(under, 1.0) if bad else 1.0, "peer": h.method,
            "lever_arm_m": h.diagnostics["hand"]["lever_arm_m"]}
    if not bad:
        return [], diag
    r_cm = np.array(h.diagnostics["hand"]["lever_arm_m"]) * 100
    return [
        f"inconsistent: the hand-aware estimate ({h.method}) differs from this one by χ² {stat:.0f} on 6 S, G "
        f"(99.9 % bound {thr:.1f}), up to {3 * under:.1f} σ"
        + (
            f" (with {h.method}'s own 2σ the error may reach {bound:.1f} σ, beyond 3 σ)"
            if joint and bound > 3.0
            else ""
        )
        + (f": σ is understated at least ×{under:.1f}" if under > 1.0 else "")
        + ". The hand "
        f"turned the device about a point {np.array2string(r_cm, precision=1)} cm away (lever arm, body frame), "
        f"whose acceleration this model reads as gravity; use {h.method} (calib run --method hand)"
    ], diag


def hand_checked(cal: Calibration, rec: Recording, *, noise_free: bool, accelerometer: str = "calibrated",
                 acc_m_s2: np.ndarray | None = None) -> Calibration:
    """``cal`` (a hand-blind calibration of ``rec``) after :func:`hand_cross_check` when it says "ok": "inconsistent"
    with the check's warnings appended when the hand-aware estimate disagrees, the check's numbers in
    ``diagnostics["consistency"]["hand_cross_check"]`` either way.  Not on noise-free input (``noise_free``: the
    methods then differ by their discretisation, not by the hand) and not on a result that is not "ok"."""
    if cal.status != "ok" or noise_free:
        return cal
    items = [("gyro", "scale_factor"), ("gyro", "nonorthogonality")]
    warn, diag = hand_cross_check(rec, np.concatenate([cal.value(t, k) for t, k in items]),
                                  cal.block_covariance(items), acc_m_s2, accelerometer=accelerometer)
    consistency = {**cal.diagnostics.get("consistency", {}), "hand_cross_check": diag}
    return replace(cal, status="inconsistent" if warn else cal.status, warnings=cal.warnings + tuple(warn),
                   diagnostics={**cal.diagnostics, "consistency": consistency})
