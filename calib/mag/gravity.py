"""The gravity direction in the body frame, from the accelerometer with the gyro's help: the
reference the attitude-aided fit (and the tilt-compensated heading) measures the field against.

1. **Gyro-stabilised averaging.**  The gyro (bias from the first rest, Zhou 2020 eq. 3) is
   integrated to a relative attitude q_k (:func:`gyrosim.strapdown.integrate_gyro`); the specific
   force is rotated into that frame, f_k^r = q_k f_k, averaged over a short centred window
   (``window_s``) and rotated back: f̄_k = q_k* (mean f^r) q_k.  At rest or in a slow rotation
   gravity is constant in the stabilised frame, so the average removes sensor noise and hand
   tremor without the lag a plain low-pass has while the board turns (the gyro's errors act only
   over the window: 1 °/s of bias misplaces gravity by 0.1° over 0.2 s).
2. **Quasi-static samples.**  In the stabilised frame a window's variance is sensor noise unless
   something else accelerates the board; a sample is quasi-static when its window variance is at
   most the session's quiet level (10th percentile) times χ²₀.₉₉₉(ν)/ν with ν = 4 (the hand's
   narrow-band tremor: :mod:`calib.session.rest`), and its |f̄| is within ``static_tol_m_s2`` of gravity.
3. **Accelerometer calibration and the hand's lever arm** (when the quasi-static directions
   cover the sphere): the hand turns the board about a pivot ρ metres away (wrist, elbow), so the
   accelerometer also reads a = α × ρ + ω × (ω × ρ) = K(ω, α) ρ with ω from the gyro and
   α = dω/dt — during a 9 s turn this is a constant body-frame acceleration of ω²|ρ| ≈ 0.05 m/s²
   that a plain sphere fit would take for an accelerometer bias (0.3° of tilt).  Fitted together:

       |L_a (f̄_k − b_a) − K̄_k ρ| = g     (L_a symmetric: scale and the symmetric cross-axis terms)

   on the quasi-static window means (K̄ averaged in the stabilised frame like f̄), so that
   neither an accelerometer bias (±60 mg on an MPU-9250, ±3.4° of tilt) nor the pivot poses as
   magnetometer misalignment.  Its symmetric convention defines the IMU frame the misalignment is
   measured against.  What remains is the hand's sway (0.2–1 Hz), ~0.2° of tilt over seconds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gyrosim.errors import RecordingError
from gyrosim.lazy import lazy_module
from gyrosim.recording import Recording
from gyrosim.rotations import quat_conjugate, quat_rotate, quat_to_matrix
from gyrosim.strapdown import integrate_gyro
from gyrosim.units import G0

from calib.mag.lsq import block_index

# imported on first use (gyrosim.lazy), so that start-up and a refused file do not pay for it
stats = lazy_module("scipy.stats")

__all__ = ["GravityReference", "gravity_reference", "direction_coverage"]


@dataclass(frozen=True)
class GravityReference:
    """Unit 'up' vector in the body frame per sample (the direction of the specific force at rest),
    the quasi-static mask, the accelerometer calibration used (L_a, b_a) or None, and notes."""

    up_body: np.ndarray
    quasi_static: np.ndarray
    acc_l: np.ndarray | None
    acc_bias_m_s2: np.ndarray | None
    gyro_bias_rad_s: np.ndarray
    notes: tuple[str, ...]
    lever_arm_m: np.ndarray | None = None


def _centred_mean(x: np.ndarray, w: int) -> np.ndarray:
    c = np.concatenate([np.zeros((1, x.shape[1])), np.cumsum(x, axis=0)])
    n = x.shape[0]
    lo = np.clip(np.arange(n) - w // 2, 0, n)
    hi = np.clip(lo + w, 0, n)
    lo = np.maximum(hi - w, 0)
    return (c[hi] - c[lo]) / (hi - lo)[:, None]


def direction_coverage(x: np.ndarray) -> tuple[float, np.ndarray]:
    """How much of the sphere a set of vectors spans: the smallest eigenvalue of the covariance
    of the points over (r²/3), r² their mean squared distance from the centroid — 1 for points
    spread evenly over a sphere, 0 for points in a plane (one rotation axis only) — and the
    direction (unit, same frame) along which they vary least."""
    d = x - x.mean(axis=0)
    c = d.T @ d / max(x.shape[0], 1)
    w, v = np.linalg.eigh(c)
    r2 = float(np.trace(c))
    return (float(w[0]) / (r2 / 3.0) if r2 > 0 else 0.0), v[:, 0]


def _skew(v: np.ndarray) -> np.ndarray:
    o = np.zeros(v.shape[0])
    x, y, z = v[:, 0], v[:, 1], v[:, 2]
    return np.stack([np.stack([o, -z, y], -1), np.stack([z, o, -x], -1), np.stack([-y, x, o], -1)], axis=-2)


def _acc_lever_fit(
    f: np.ndarray, k: np.ndarray, blocks: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """|L (f − b) − K ρ| = g over (L symmetric, b m/s², ρ m): returns (L, b, ρ, covariance (12×12))."""
    from calib.mag.ellipsoid import SYM_IDX, sym
    from calib.mag.lsq import levenberg_marquardt, sandwich_covariance

    def fun(theta):
        lm, b, rho = sym(theta[:6]), theta[6:9], theta[9:12]
        d = f - b
        v = d @ lm.T - np.einsum("nij,j->ni", k, rho)
        nv = np.linalg.norm(v, axis=1)
        n = v / nv[:, None]
        jac = np.empty((f.shape[0], 12))
        for c, (i, j) in enumerate(SYM_IDX):
            jac[:, c] = n[:, i] * d[:, j] if i == j else n[:, i] * d[:, j] + n[:, j] * d[:, i]
        jac[:, 6:9] = -(n @ lm)
        jac[:, 9:12] = -np.einsum("ni,nij->nj", n, k)
        return nv / G0 - 1.0, jac / G0

    res = levenberg_marquardt(fun, np.array([1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0, 0, 0, 0, 0, 0]))
    cov, _ = sandwich_covariance(res.jacobian, res.residual, blocks)
    th = res.theta
    return sym(th[:6]), th[6:9], th[9:12], cov


def _gyro_bias(rec: Recording) -> tuple[np.ndarray, str | None]:
    from calib.session.rest import detect_rest, static_bias

    try:
        b = static_bias(rec, detect_rest(rec), min_rest_s=1.0)
        return b.value_rad_s, None
    except RecordingError as exc:
        return np.zeros(3), f"gyro bias not removed before the gravity averaging ({exc})"


def gravity_reference(rec: Recording, *, window_s: float = 0.2, static_tol_m_s2: float = 0.2,
                      calibrate_accelerometer: bool = True) -> GravityReference:
    """Gravity direction per sample (module docstring)."""
    notes: list[str] = []
    bias, note = _gyro_bias(rec)
    if note:
        notes.append(note)
    omega = rec.gyro_rad_s - bias
    q = integrate_gyro(rec.t_s, omega, np.array([1.0, 0.0, 0.0, 0.0]))
    w = max(3, int(round(window_s * rec.rate_hz)))
    f_ref = quat_rotate(q, rec.acc_m_s2)
    mean_ref = _centred_mean(f_ref, w)
    var = np.sum(_centred_mean(f_ref**2, w) - mean_ref**2, axis=1) * w / max(w - 1, 1)
    f_bar = quat_rotate(quat_conjugate(q), mean_ref)
    floor = float(np.percentile(var, 10))
    quiet = var <= floor * stats.chi2.ppf(0.999, 4) / 4

    acc_l = acc_b = None
    lever = np.zeros(3)
    f_cal = f_bar
    if calibrate_accelerometer and quiet.sum() > 20 * w:
        pick = np.flatnonzero(quiet)[:: max(1, w // 2)]
        cover, _ = direction_coverage(f_bar[pick] / np.linalg.norm(f_bar[pick], axis=1, keepdims=True))
        if cover >= 0.05:
            # K(ω, α) of the lever arm, averaged in the stabilised frame like f̄: R_j K_j, mean, R_kᵀ (·)
            alpha = np.gradient(omega, rec.t_s, axis=0)
            sw = _skew(omega)
            kmat = _skew(alpha) + sw @ sw
            rmat = quat_to_matrix(q)
            k_ref = _centred_mean((rmat @ kmat).reshape(-1, 9), w).reshape(-1, 3, 3)
            k_bar = np.swapaxes(rmat, 1, 2) @ k_ref
            # start at the nominal calibration (unit scale, no bias, no lever arm): the algebraic
            # start needs the full sphere, an accelerometer rarely gets more than a few faces
            lm, b, rho, cov = _acc_lever_fit(f_bar[pick], k_bar[pick], block_index(pick.size, max(1, pick.size // 60)))
            sig_b = float(np.sqrt(np.max(np.diag(cov)[6:9])))
            if sig_b <= 0.03 and np.linalg.norm(rho) < 1.0:  # ±3 mg; a pivot within an arm's length
                acc_l, acc_b, lever = lm, b, rho
                f_cal = (f_bar - acc_b) @ acc_l.T - np.einsum("nij,j->ni", k_bar, rho)
                notes.append(f"accelerometer calibrated on {pick.size} quasi-static window means: bias "
                             f"{np.round(acc_b, 3).tolist()} ± {sig_b:.3f} m/s², lever arm of the hand's pivot "
                             f"{np.round(rho, 3).tolist()} m")
            else:
                notes.append(f"accelerometer not calibrated: its bias would be uncertain to ±{sig_b:.3f} m/s² "
                             "from these poses; its bias tilts the gravity reference")
        else:
            notes.append(f"accelerometer not calibrated: its quasi-static directions cover {cover:.2f} of the sphere "
                         "(needs ≥ 0.05); its bias tilts the gravity reference")
    norm = np.linalg.norm(f_cal, axis=1)
    up = f_cal / np.maximum(norm, 1e-9)[:, None]
    g_level = float(np.median(norm[quiet])) if quiet.any() else G0
    static = quiet & (np.abs(norm - g_level) <= static_tol_m_s2)
    if not static.any():
        notes.append("no quasi-static sample: the board never held still long enough to see gravity")
    if not math.isfinite(g_level):
        raise RecordingError("the accelerometer gives no usable gravity reference")
    return GravityReference(up, static, acc_l, acc_b, bias, tuple(notes), lever)
