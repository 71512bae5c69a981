"""The accelerometer from |f| = g alone: the multi-position calibration of Ferraris et al. (1995) and
Tedaldi et al. (2014), generalised to every quasi-static window of a session.

Model (body RFU, SI): f̃ = M_a f + b_a + v, M_a = I + diag(S_a) + N(G_a) (symmetric, see
:mod:`calib.session.model`), so f̂ = M_a⁻¹(f̃ − b_a) and wherever the board is (nearly) still |f̂| = g.
Tedaldi's cost Σ_k (g − |f̂_k|)² over static windows, minimised here by Gauss–Newton with the
filter's prior as a ridge (a maximum a posteriori estimate, so a schedule that does not excite a
parameter leaves it at its prior instead of making the normal equations singular):

    r_k = |f̂_k| − g,   ∂r_k/∂θ = −u_kᵀ M̂⁻¹ [I, diag(f̂_k), J_G(f̂_k)],   u_k = f̂_k/|f̂_k|

(f̃ − b = M f̂ ⇒ df̂ = −M⁻¹(db + dM f̂)).  Every sample from the first rest on is a row; its weight is
the inverse of the variance |f̂| − g has there (:func:`sample_variance`): at a detected rest the rest's
own scatter of |f̃| (the white noise, or a hand-held rest's sway — measured, never assumed), elsewhere the
white noise plus the hand's allowance.  A still pose is where |f| = g holds to the noise, so it is the
multi-position calibration's information (Ferraris 1995, Tedaldi 2014); one allowance for every sample
drowned it under the moves' hand acceleration — on imu_tk's Xsens session (38 still poses between hand
rotations, allowance 0.52 m/s²) the fit's |f| − g at the poses was 2.1× imu_tk's own, 1.0× with the rests
weighed by their scatter.  Huber weights (k = 3σ) on the residuals against transient motion.

Why only as the *start* of the filter (:func:`calib.session.paper.calibrate`): |f| = g says nothing
about the horizontal components of an accelerometer error, and a session such as Zhou's Table 6
holds still in two poses only; the filter sees the same windows plus the gyro-propagated attitude
between them, so it observes all nine parameters from the rotations.  This fit gives the filter a
linearisation point near the answer, the external-acceleration allowance from the residual
|f̂| − g, and — through :func:`gravity_regressor` — the pose analysis of the observability check.

Sources: Ferraris, Grimaldi, Parvis, Sensors and Materials 7(5):311–330 (1995); Tedaldi, Pretto,
Menegatti, ICRA 2014 (imu_tk), eq. 10; Skog & Händel (2006) for the MAP/ridge form.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from calib.session.model import jacobian_nonorthogonality, m_matrix

__all__ = ["GravityFit", "quasi_static_windows", "fit_gravity", "gravity_regressor", "compensate_acc",
           "sample_variance"]

REST_BLOCKS = 8   # a rest's block means that measure its slow part (a hand's sway)


def compensate_acc(f: np.ndarray, theta_a: np.ndarray) -> np.ndarray:
    """f̂ = M_a⁻¹(f̃ − b_a) for θ_a = [b_a, S_a, G_a] (9,), rows of ``f`` (N, 3)."""
    m = m_matrix(theta_a[3:6], theta_a[6:9])
    return np.linalg.solve(m, (np.asarray(f, float) - theta_a[0:3]).T).T


def gravity_regressor(f_hat: np.ndarray) -> np.ndarray:
    """∂|f̂|/∂θ_a at M̂ = I (N, 9): [u, g u², 2g (u_y u_z, u_x u_z, u_x u_y)] for f̂ = g u — what one
    gravity direction u (body) tells about the nine parameters (up to sign)."""
    f = np.asarray(f_hat, float)
    norm = np.linalg.norm(f, axis=1, keepdims=True)
    u = f / np.where(norm > 0, norm, 1.0)
    jg = np.einsum("ni,nij->nj", u, np.stack([jacobian_nonorthogonality(v) for v in f]))
    return np.hstack([u, u * f, jg])


def quasi_static_windows(acc_m_s2: np.ndarray, rate_hz: float, window_s: float = 0.1,
                         noise_sigma_m_s2: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Means of consecutive ``window_s`` windows (K, 3) and their σ (K,): √(spread²/n + σ_f²/n)
    (for the pose analysis: which gravity directions a session holds)."""
    w = max(1, int(round(window_s * rate_hz)))
    k = acc_m_s2.shape[0] // w
    blocks = np.asarray(acc_m_s2[: k * w], float).reshape(k, w, 3)
    mean = blocks.mean(axis=1)
    spread = np.sqrt(np.sum(blocks.var(axis=1), axis=1))
    return mean, np.sqrt(spread**2 + noise_sigma_m_s2**2 / w + 1e-18)


def sample_variance(f: np.ndarray, rests: tuple[tuple[int, int], ...] | list[tuple[int, int]], noise_var: float,
                    moving_var: float) -> np.ndarray:
    """(N,) variance of |f̂| − g per sample of ``f`` (raw, m/s²; sample 0 of ``f`` is sample 0 of the rest ranges'
    indexing): inside each rest [a, b) what that rest's own |f̃| shows — the white noise's radial part, or more
    where a hand held the pose — never below ``noise_var``; ``moving_var`` (white noise + the hand's allowance)
    everywhere else.  A rest's |f̃| is attitude-free, so its scatter is the sensor's and the hand's, not the pose's;
    its slow part does not average out (:func:`_rest_sample_variance`)."""
    n = np.asarray(f).shape[0]
    var = np.full(n, float(moving_var))
    norm = np.linalg.norm(np.asarray(f, float), axis=1)
    for a, b in rests:
        a, b = max(int(a), 0), min(int(b), n)
        if b - a >= 2 * REST_BLOCKS:
            var[a:b] = _rest_sample_variance(norm[a:b], float(noise_var))
    return var


def _rest_sample_variance(norm: np.ndarray, noise_var: float) -> float:
    """Per-sample variance that gives a rest of n samples the information it has about |f| = g: its fast part
    (white noise, tremor — the differences' variance, ≥ ``noise_var``) averages over the rest, its slow part (a
    hand's sway: the excess variance of ``REST_BLOCKS`` block means over what the fast part gives them) does not,
    so the rest's mean has variance fast/n + slow and each sample weighs 1/(fast + n·slow)."""
    n = norm.size
    fast = max(float(np.var(np.diff(norm))) / 2.0, noise_var)
    size = n // REST_BLOCKS
    means = norm[: size * REST_BLOCKS].reshape(REST_BLOCKS, size).mean(axis=1)
    slow = max(float(np.var(means, ddof=1)) - fast / size, 0.0)
    return fast + n * slow


@dataclass(frozen=True)
class GravityFit:
    """θ_a = [b_a (m/s²), S_a, G_a] (9,) and its covariance (9, 9); the RMS of |f̂| − g over the
    samples that kept full weight (m/s²) and how many they were."""

    theta: np.ndarray
    covariance: np.ndarray
    residual_rms_m_s2: float
    samples: int
    prior_sigma: np.ndarray

    @property
    def bias_m_s2(self) -> np.ndarray:
        return self.theta[0:3]

    @property
    def scale_factor(self) -> np.ndarray:
        return self.theta[3:6]

    @property
    def nonorthogonality(self) -> np.ndarray:
        return self.theta[6:9]


def fit_gravity(f: np.ndarray, f_reg: np.ndarray, r_var: np.ndarray | float, noise_var_m2_s4: float,
                gravity_m_s2: float, prior_sigma: np.ndarray, theta0: np.ndarray | None = None,
                iterations: int = 15, robust: bool = True, block_samples: int | None = None) -> GravityFit:
    """MAP fit of θ_a to |f̂_k| = g over samples (module docstring).

    ``f`` (N, 3) raw samples (m/s²); ``f_reg`` the regressors (leave-out means, so the Jacobian
    does not carry the sample's own noise); ``r_var`` the variance of |f̂| − g per sample (white
    noise plus the hand's allowance); ``noise_var_m2_s4`` the white noise's per-axis variance σ_f²,
    whose tangential part lengthens a noisy vector on average: E|g + v| ≈ g + σ_f²/g, subtracted
    from the residual.  Huber weights (k = 3 robust σ) against samples with transient motion.
    The covariance is (Jᵀ W J + P₀⁻¹)⁻¹: honest when the residuals are white with variance r_var.
    ``block_samples``: residuals correlated in time (a hand's sway and tremor) — the sandwich
    I⁻¹ (Σ_b s_b s_bᵀ + P₀⁻¹) I⁻¹ instead, s_b = Σ_{k∈b} J_kᵀ w_k r_k summed over consecutive blocks of
    that many samples (I = Jᵀ W J + P₀⁻¹; the batch-means / Newey–West estimate of the score's long-run
    variance, Newey & West 1987), which for white residuals is I⁻¹ again.
    """
    f = np.asarray(f, float)
    f_reg = np.asarray(f_reg, float)
    theta = np.zeros(9) if theta0 is None else np.array(theta0, float)
    prior_info = 1.0 / np.asarray(prior_sigma, float) ** 2
    w = np.broadcast_to(1.0 / np.asarray(r_var, float), (f.shape[0],))
    offset = noise_var_m2_s4 / gravity_m_s2
    huber = np.ones(f.shape[0])
    cov = np.diag(1.0 / prior_info)
    for it in range(iterations):
        m = m_matrix(theta[3:6], theta[6:9])
        mi = np.linalg.inv(m)
        fh = (f - theta[0:3]) @ mi.T
        r = np.linalg.norm(fh, axis=1) - gravity_m_s2 - offset
        fr = (f_reg - theta[0:3]) @ mi.T
        u = fr / np.linalg.norm(fr, axis=1, keepdims=True)
        v = u @ mi                                    # rows uᵀ M̂⁻¹, so J = −vᵀ [I, diag(f̂), J_G(f̂)]
        jac = -np.hstack([v, v * fr, np.stack([v[:, 1] * fr[:, 2] + v[:, 2] * fr[:, 1],
                                               v[:, 0] * fr[:, 2] + v[:, 2] * fr[:, 0],
                                               v[:, 0] * fr[:, 1] + v[:, 1] * fr[:, 0]], axis=1)])
        if robust and it >= 2:  # Huber weights on the normalised residuals (robust to transient motion)
            z = np.abs(r) * np.sqrt(w)
            scale = max(1.4826 * float(np.median(z)), 1.0)
            huber = np.where(z <= 3 * scale, 1.0, 3 * scale / np.maximum(z, 1e-300))
        ww = w * huber
        info = jac.T @ (jac * ww[:, None]) + np.diag(prior_info)
        grad = jac.T @ (ww * r) + prior_info * theta
        step = np.linalg.solve(info, grad)
        theta = theta - step
        cov = np.linalg.inv(info)
        if it >= 3 and np.all(np.abs(step) <= 1e-6 * np.sqrt(np.abs(np.diag(cov)))):  # converged to 1e-6 σ
            break
    if block_samples:
        nb = f.shape[0] // int(block_samples)
        score = (jac * (ww * r)[:, None])[: nb * int(block_samples)].reshape(nb, int(block_samples), 9).sum(axis=1)
        cov = cov @ (score.T @ score + np.diag(prior_info)) @ cov
    fh = compensate_acc(f, theta)
    r = np.linalg.norm(fh, axis=1) - gravity_m_s2 - offset
    used = huber > 0.999
    return GravityFit(
        theta,
        0.5 * (cov + cov.T),
        float(math.sqrt(np.mean(r[used] ** 2))) if used.any() else float("nan"),
        int(used.sum()),
        np.asarray(prior_sigma, float),
    )
