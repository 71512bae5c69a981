"""Our estimators behind the :mod:`gyrosim.estimator` interface, for campaigns.

Each returns a :class:`gyrosim.calibration.Calibration` (effects, covariance, status, warnings). ``kf_joint`` is ``calib
run``'s default: the gyro and the accelerometer from one session (:func:`calib.session.paper.calibrate`, 21 states,
session allowance); ``iterated_joint`` its re-linearised form.  ``kf_session_r`` and ``iterated_session_r`` are what
``calib run --accelerometer calibrated`` runs (the same filter and verdict as :func:`calib.session.paper.calibrate`; a
test holds them equal), so a name means one algorithm wherever it is used.  The others run Zhou 2020's 9-state filter
(the compiled kernel :func:`calib.session.kernel.run_batch`, equal to the filterpy filter to rounding) after the static
bias (§3.2), assuming a calibrated accelerometer; they differ only in how the accelerometer's gravity measurement is
trusted when the hand adds external acceleration a_e:

| name | measurement variance R per axis (m/s²)² | gating |
|---|---|---|
| ``kf`` | σ_f² = VRW²·f_s (the paper: only gravity is sensed) | — |
| ``iterated`` | as ``kf``; three passes, each re-linearised at the previous pass's estimate | — |
| ``kf_session_r`` | σ_f² + max(rest excess, 3⟨(|f| − g)²⟩): one constant for the session | — |
| ``iterated_session_r`` | as ``kf_session_r``; three passes as ``iterated`` | — |
| ``kf_adaptive`` | σ_f² + 3·LP₀.₂ₛ[(|f| − g)²] per sample | — |
| ``kf_gated`` | σ_f² | skip an update with NIS > χ²₂(0.999) = 13.8 |
| ``kf_adaptive_gated`` | as ``kf_adaptive`` | as ``kf_gated`` |

Why 3·(|f| − g)²: to first order |f| − g is the component of a_e along gravity; for a direction
of a_e uniform on the sphere E[(a_e·ĝ)²] = |a_e|²/3, so 3(|f| − g)² estimates |a_e|², a bound on
each horizontal component's variance.  Low-passed over 0.2 s because (|f| − g) crosses zero
whenever a_e is horizontal, while a_e itself does not.

``kf_hand`` (:mod:`calib.session.hand.filter`) puts the hand in the model instead: the lever arm and a coloured
external acceleration as filter states after a tremor low-pass (docs/hand.md).  Every method
here reports an honest σ or says it cannot: P is inflated from the innovations' long-run variance, a
result whose σ had to grow more than ×1.5 is ``inconsistent``, and an ``ok`` result that disagrees with
``kf_hand`` beyond both σ becomes ``inconsistent`` with the factor its σ is understated by
(:func:`calib.session.consistency.innovation_inflation`, :func:`calib.session.hand.filter.hand_cross_check`).

``iterated`` (formerly ``smoother``, still accepted with a DeprecationWarning: it is the same three-pass algorithm as
``calib run --method iterated_session``, not a smoother): the parameters are constants, so a Rauch–Tung–Striebel pass
leaves their final filtered estimate unchanged (the smoothed estimate of a constant state equals the filtered one at the
last sample); what a smoother can still improve is the linearisation, which these passes do (an iterated-linearisation
smoother in the parameters).
"""

from __future__ import annotations

import math

import numpy as np
from scipy import signal as sp_signal
from scipy import stats

from gyrosim.calibration import Calibration
from gyrosim.recording import Recording

from calib.session.consistency import (
    apply_inflation,
    check_estimate,
    check_innovations,
    fixed_parameter_effect,
    innovation_inflation,
    verdict,
)
from calib.session.hand.filter import kf_hand  # noqa: F401  (registered: the hand-aware method)
from calib.session.kernel import run_filter
from calib.session.model import PAPER, initial_covariance, theta_slice
from calib.session.paper import Prepared, bias_drift_note, calibrate, prepare, rest_mask

__all__ = [
    "kf",
    "iterated",
    "smoother",
    "kf_session_r",
    "iterated_session_r",
    "kf_adaptive",
    "kf_gated",
    "kf_adaptive_gated",
    "kf_lever_arm",
    "kf_joint",
    "iterated_joint",
    "kf_hand",
    "kf_hand_joint",
]

GATE_NIS = float(stats.chi2.ppf(0.999, 2))


def _run(rec: Recording, *, session_r: bool = False, adaptive: bool = False, gate: float = 0.0,
         passes: int = 1, prep: Prepared | None = None, name: str = "kf", check_hand: bool = True) -> Calibration:
    """The paper's filter on ``rec``; ``prep`` (from :func:`prepare` with the matching allowance) when
    the caller already has it."""
    prep = prep or prepare(rec, accelerometer="calibrated", external_acc_allowance_m_s2=None if session_r else 0.0)
    a, fs = prep.start, rec.rate_hz
    acc = rec.acc_m_s2[None, a:]
    r_var = None
    if adaptive:
        c = prep.config
        excess = (np.linalg.norm(rec.acc_m_s2[a:], axis=1) - c.gravity_m_s2) ** 2
        alpha = math.exp(-1.0 / (0.2 * fs))
        lp = sp_signal.lfilter([1 - alpha], [1, -alpha], excess, zi=[alpha * excess[0]])[0]
        r_var = c.vrw_m_s2_sqrt_hz**2 * fs + c.external_acc_allowance_m_s2**2 + 3.0 * lp
    theta = prep.theta0.copy()
    p0 = initial_covariance(PAPER, prep.config)
    mask = None if prep.saturated is None else ~prep.saturated[a:]
    rmask = rest_mask(prep, rec.n - a)

    def one_pass(th: np.ndarray, x0: np.ndarray):
        return run_filter(rec.gyro_rad_s[None, a:], acc, rec.t_s[a:], prep.quat0_nb[None], th[None], p0, PAPER,
                          prep.config, fs, r_var_per_sample=r_var, gate_nis=gate, update_mask=mask,
                          rest_mask=rmask, x0=x0[None])

    for _ in range(passes):
        x0 = np.zeros(PAPER.n)
        x0[3:9] = -theta[0:6]  # the prior (S = G = 0) seen from the linearisation point
        theta_in = theta
        out = one_pass(theta_in, x0)
        theta = out.theta[0].copy()

    def rerun(th: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        o = one_pass(th, x0)
        return o.whitened[0], o.theta[0][0:6]

    # the static bias b̂ is held fixed by the paper's filter: its error is part of the model, in the
    # innovation test and in σ of S, G (calib.session.consistency, "Parameters the filter holds fixed")
    fx = fixed_parameter_effect(rerun, theta_in, theta_slice("gyro_bias"), prep.bias_std_rad_s, out.whitened[0],
                                theta[0:6])
    infl = innovation_inflation(out.whitened[0], rec.t_s[a + 1:], sensitivity=fx.sensitivity,
                                sensitivity_cov=fx.cov)
    cov = np.zeros((9, 9))
    cov[:3, :3] = fx.cov
    cov[3:, 3:] = out.p[0, 3:9, 3:9] * infl.factor + fx.added_covariance
    cov[3:, :3] = fx.jacobian @ fx.cov
    cov[:3, 3:] = cov[3:, :3].T
    values = {"gyro scale factor": theta[theta_slice("gyro_scale")],
              "gyro non-orthogonality": theta[theta_slice("gyro_nonorth")]}
    status, notes = verdict(check_innovations(out.nis[0], 2, fs), check_estimate(values, cov, prep.config.gravity_m_s2))
    status = apply_inflation(status, notes, infl, can_fail=not prep.noise.noise_free)
    if infl.factor > 1 and (note := bias_drift_note(rec, prep)) is not None:
        notes.append(note)
    diag: dict = {"consistency": {"sigma_inflation": infl.to_dict()}}
    # the reported bias is the first rest's mean, at its reference (calib.session.rest_bias)
    if prep.rest_bias is not None:
        diag["gyro_bias"] = prep.rest_bias.to_dict()
    if check_hand and status == "ok" and not prep.noise.noise_free:   # noise-free: methods differ by discretisation
        status, diag["consistency"]["hand_cross_check"] = _hand_check(rec, theta[0:6], cov[3:, 3:], notes, status)
    gyro = {"bias": prep.bias.value_rad_s, "scale_factor": theta[theta_slice("gyro_scale")],
            "nonorthogonality": np.clip(np.nan_to_num(theta[theta_slice("gyro_nonorth")]), -0.45, 0.45)}
    return Calibration.from_linear(gyro=gyro, covariance=cov, status=status, warnings=prep.warnings + tuple(notes),
                                   method=name, diagnostics=diag)


def _hand_check(rec: Recording, sg: np.ndarray, cov_sg: np.ndarray, notes: list[str], status: str,
                acc_m_s2: np.ndarray | None = None) -> tuple[str, dict]:
    """:func:`calib.session.hand.filter.hand_cross_check`: a hand-blind "ok" whose S, G disagree with the hand-aware
    estimate beyond both σ becomes "inconsistent", with the factor σ is understated by."""
    from calib.session.hand.filter import hand_cross_check

    warn, diag = hand_cross_check(rec, sg, cov_sg, acc_m_s2)
    notes.extend(warn)
    return ("inconsistent" if warn else status), diag


def kf(rec: Recording) -> Calibration:
    """Zhou 2020's filter as published: R from the accelerometer noise only."""
    return _run(rec, name="kf")


def iterated(rec: Recording) -> Calibration:
    """The paper's filter in three passes, each linearised at the previous estimate (module docstring)."""
    return _run(rec, passes=3, name="iterated")


def smoother(rec: Recording) -> Calibration:
    """Deprecated name of :func:`iterated` (the same three passes; no smoothing pass is involved)."""
    import warnings

    warnings.warn("estimator 'smoother' is deprecated: it is the three-pass iterated filter, registered as "
                  "'iterated'", DeprecationWarning, stacklevel=2)
    return iterated(rec)


smoother.deprecated_alias_of = "iterated"  # type: ignore[attr-defined]  (gyrosim.estimator warns on load)


def kf_session_r(rec: Recording) -> Calibration:
    """One R for the session from its (|f| − g)² (``calib run --accelerometer calibrated``)."""
    return _run(rec, session_r=True, name="kf_session_r")


def iterated_session_r(rec: Recording) -> Calibration:
    """``calib run --method iterated_session --accelerometer calibrated``: three passes with the session R."""
    return calibrate(rec, "iterated_session_r", keep_history=False)


def kf_adaptive(rec: Recording) -> Calibration:
    """R per sample from the low-passed (|f| − g)²."""
    return _run(rec, adaptive=True, name="kf_adaptive")


def kf_gated(rec: Recording) -> Calibration:
    """The paper's R with innovation gating at χ²₂(0.999)."""
    return _run(rec, gate=GATE_NIS, name="kf_gated")


def kf_adaptive_gated(rec: Recording) -> Calibration:
    """R per sample from the low-passed (|f| − g)², and innovation gating at χ²₂(0.999)."""
    return _run(rec, adaptive=True, gate=GATE_NIS, name="kf_adaptive_gated")


def kf_joint(rec: Recording) -> Calibration:
    """``calib run``'s default: gyro and accelerometer from one session (21 states, session allowance)."""
    return calibrate(rec, "kf_joint", keep_history=False)


def iterated_joint(rec: Recording) -> Calibration:
    """``calib run --method iterated_session``: the joint filter re-linearised three times."""
    return calibrate(rec, "iterated_joint", keep_history=False)


def kf_hand_joint(rec: Recording) -> Calibration:
    """``kf_hand`` with the accelerometer estimated jointly (36 states, 42 on a warming session: + its bias, scale
    factor and non-orthogonality; :func:`calib.session.hand.filter.kf_hand` with ``accelerometer="estimate"``) — for a
    raw accelerometer, as ``calib run`` has by default."""
    return kf_hand(rec, accelerometer="estimate")


LEVER_ARM_RETIRED = (
    "kf_lever_arm is retired and now runs kf_hand: its σ could not be made honest — with the typical hand "
    "(zhou2020_sim_consumer, 10 seeds) NEES 9.36 above its 95 % band [4.05, 8.33] while 8 of 10 seeds said "
    "\"ok\", with the ideal hand 3.52 below [4.58, 7.61] (20 seeds) — because the hand's coloured acceleration "
    "it does not model is aliased into S, G (error 18× kf_hand's); kf_hand models the lever arm and that "
    "acceleration (docs/hand.md)")


def kf_lever_arm(rec: Recording) -> Calibration:
    """Retired name: runs :func:`kf_hand` (which estimates the lever arm inside the filter, with the hand's
    coloured acceleration) and says so in a warning and in the result's ``warnings``.  The former two-pass
    method is :func:`lever_arm_two_pass` (not registered; its σ is not honest, see ``LEVER_ARM_RETIRED``)."""
    import warnings

    warnings.warn(LEVER_ARM_RETIRED, DeprecationWarning, stacklevel=2)
    c = kf_hand(rec)
    return Calibration(gyro=c.gyro, accelerometer=c.accelerometer, covariance=c.covariance, status=c.status,
                       method=c.method, warnings=c.warnings + (LEVER_ARM_RETIRED,), diagnostics=c.diagnostics)


kf_lever_arm.deprecated_alias_of = "kf_hand"  # type: ignore[attr-defined]  (gyrosim.estimator warns on load)
kf_lever_arm.deprecation_note = ("a retired method: this name runs kf_hand; the two-pass lever-arm fit's σ was "  # type: ignore[attr-defined]
                                 "optimistic with a hand while it said 'ok'")


def lever_arm_two_pass(rec: Recording) -> Calibration:
    """The former ``kf_lever_arm`` (kept importable, ``calib.session.registry:lever_arm_two_pass``, to reproduce
    docs/campaigns.md's rows; not registered: its σ is not honest with a hand — ``LEVER_ARM_RETIRED``).

    The hand turns about a pivot (wrist, elbow) away from the accelerometer, so the sensor
    sees f = g_b + ω̇ × r + ω × (ω × r) with r the lever arm (body frame, constant): a
    deterministic acceleration correlated with the rotation, which no choice of R removes
    (the campaign measured a 0.23–0.28 % non-orthogonality bias from it).  It is linear in r:

        f − g_b = K(ω, ω̇) r,   K = [ω̇×] + [ω×][ω×]

    Pass 1 (``kf_session_r``) calibrates the gyro; its compensated rate, integrated from the
    rest attitude, gives g_b(t); least squares over the motion gives r̂; pass 2 runs on
    f − K r̂.  ω̇ from the compensated rate, zero-phase low-passed at 5 Hz (above the schedule,
    below the tremor).  σ includes r̂'s own error carried into S, G (J C_r Jᵀ; without it NEES was 7.6
    against [5.1, 7.0] with the ideal hand, G_y's error 1.9 σ RMS).  ``kf_hand`` estimates r inside the
    filter instead and supersedes this method (docs/hand.md)."""
    from gyrosim.effects import nonortho_matrix
    from gyrosim.rotations import quat_conjugate, quat_rotate, skew
    from gyrosim.strapdown import integrate_gyro

    # the session-R preparation of pass 1, used again for the rest attitude
    prep = prepare(rec, accelerometer="calibrated")
    first = _run(rec, session_r=True, prep=prep, name="lever_arm_two_pass", check_hand=False)
    a, fs = prep.start, rec.rate_hz
    m = np.eye(3) + np.diag(first.scale_factor) + nonortho_matrix(first.nonorthogonality)
    w = (rec.gyro_rad_s - first.bias_rad_s) @ np.linalg.inv(m).T
    b, c = sp_signal.butter(2, min(5.0 / (fs / 2), 0.9))
    w_s = sp_signal.filtfilt(b, c, w, axis=0)
    dw = np.gradient(w_s, rec.t_s, axis=0)
    q = integrate_gyro(rec.t_s[a:], w[a:], prep.quat0_nb)
    g_b = quat_rotate(quat_conjugate(q), np.array([0.0, 0.0, prep.config.gravity_m_s2]))
    k = skew(dw[a:]) + skew(w_s[a:]) @ skew(w_s[a:])          # (N, 3, 3)
    f_s = sp_signal.filtfilt(b, c, rec.acc_m_s2[a:], axis=0)  # the tremor is not the lever arm
    moving = np.linalg.norm(w_s[a:], axis=1) > 0.2
    if moving.sum() < 10:
        return first
    y = f_s - g_b
    r, *_ = np.linalg.lstsq(k[moving].reshape(-1, 3), y[moving].reshape(-1), rcond=None)
    kk = skew(dw) + skew(w_s) @ skew(w_s)

    def pass2(r_m: np.ndarray) -> Calibration:
        corrected = rec.acc_m_s2 - np.einsum("nij,j->ni", kk, r_m)
        return _run(rec.with_signals(acc_m_s2=corrected), session_r=True, name="lever_arm_two_pass", check_hand=False)

    second = pass2(r)
    # r̂'s own error goes into S, G through pass 2: Cov += J C_r Jᵀ, J = ∂(S, G)/∂r by finite differences
    # (1 mm), C_r the least squares' sandwich with block sums over 4 s (the residual — sway, the pass-1
    # attitude error — is correlated in time; Newey & West 1987)
    e = (y - np.einsum("nij,j->ni", k, r)) * moving[:, None]
    g_k = np.einsum("nji,nj->ni", k, e)                                      # Kᵀ e per sample
    blk = np.floor((rec.t_s[a:] - rec.t_s[a]) / 4.0).astype(int)
    sums = np.stack([np.bincount(blk, g_k[:, i]) for i in range(3)], axis=1)
    a_inv = np.linalg.inv(np.einsum("nji,njk->ik", k[moving], k[moving]))
    c_r = a_inv @ (sums.T @ sums) @ a_inv
    items = [("gyro", "scale_factor"), ("gyro", "nonorthogonality")]
    base = np.concatenate([second.value(t, kd) for t, kd in items])
    jac = np.stack([(np.concatenate([pass2(r + 1e-3 * np.eye(3)[i]).value(t, kd) for t, kd in items]) - base) / 1e-3
                    for i in range(3)], axis=1)
    cov2 = np.array(second.covariance, float)
    cov2[3:9, 3:9] += jac @ c_r @ jac.T
    second = Calibration(gyro=second.gyro, accelerometer=second.accelerometer, covariance=cov2, status=second.status,
                         method="lever_arm_two_pass", warnings=second.warnings, diagnostics=second.diagnostics)
    if second.status == "ok" and not prep.noise.noise_free:   # the check on the recording as given
        notes: list[str] = []
        items = [("gyro", "scale_factor"), ("gyro", "nonorthogonality")]
        status, chk = _hand_check(rec, np.concatenate([second.value(t, k) for t, k in items]),
                                  second.block_covariance(items), notes, second.status)
        second = Calibration(gyro=second.gyro, accelerometer=second.accelerometer, covariance=second.covariance,
                             status=status, method="lever_arm_two_pass", warnings=second.warnings + tuple(notes),
                             diagnostics={**second.diagnostics, "consistency": {
                                 **second.diagnostics.get("consistency", {}), "hand_cross_check": chk}})
    return Calibration(
        gyro=second.gyro,
        accelerometer=second.accelerometer,
        covariance=second.covariance,
        status=second.status,
        method="lever_arm_two_pass",
        warnings=second.warnings + (f"lever arm r̂ = {np.array2string(r * 100, precision=1)} cm (body frame)",),
        diagnostics={**second.diagnostics, "hand": {"lever_arm_m": r.tolist()}},
    )


# What each estimator estimates (gyrosim.estimator.estimated_triads): calib montecarlo --accelerometer
# estimate refuses a gyro-only method before simulating a seed.
for _f in (kf, iterated, smoother, kf_session_r, iterated_session_r, kf_adaptive, kf_gated, kf_adaptive_gated,
           kf_lever_arm, lever_arm_two_pass, kf_hand):
    _f.estimates = ("gyro",)  # type: ignore[attr-defined]
for _f in (kf_joint, iterated_joint, kf_hand_joint):
    _f.estimates = ("gyro", "accelerometer")  # type: ignore[attr-defined]
del _f
