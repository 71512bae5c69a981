"""Fit a magnetometer model (reference field + candidate terms) on chosen samples of a :class:`MagReference`.

Model and parameters: :mod:`calib.closeloop.mag.terms`.  θ = [base, terms in order], base = B_n
(3, µT, ENU) on an attitude reference, F (1, µT) on a magnitude one.  Residual rows (µT):

    attitude:   r_k = m_k − (A R(θ)ᵀ C_k B_n + h)          3 rows per sample
    magnitude:  r_k = |A⁻¹ (m_k − h)| − F                  1 row per sample

Jacobians analytic except ∂R(θ)ᵀ/∂θ (central differences, step 1e-6 rad: error ~1e-12).
Minimised by :func:`calib.mag.lsq.levenberg_marquardt`; covariance by the block sandwich
:func:`calib.mag.lsq.sandwich_covariance` over 1 s blocks (hand motion and reference errors make
neighbouring residuals correlate; the sandwich grows with that instead of claiming white noise).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gyrosim.effects import rotation_matrix

from calib.closeloop.mag.reference import MagReference
from calib.closeloop.mag.terms import SOFT_BASIS, mag_term, soft_iron_matrix
from calib.mag.ellipsoid import fit_sphere
from calib.mag.lsq import block_index, levenberg_marquardt, sandwich_covariance

__all__ = [
    "MagFit",
    "fit_mag",
    "model_function",
    "initial_base",
    "base_size",
    "split_theta",
    "corrected_field",
    "residual_all",
]

_EPS = 1e-6
RANK_TOL = 1e-7


@dataclass(frozen=True)
class MagFit:
    """A magnetometer model fitted on chosen samples: its term kinds, θ = [base, terms in order] (module
    docstring), the residual (µT) at every sample, θ's block-sandwich covariance, its rank and whether
    the minimiser converged."""

    kinds: tuple[str, ...]
    theta: np.ndarray
    residual: np.ndarray        # (N, k) every sample (NaN where not valid), k = 3 (attitude) or 1 (magnitude)
    cov: np.ndarray             # block-sandwich covariance of θ (on the rows fitted)
    rank: int
    converged: bool

    def rss(self, rows: np.ndarray) -> float:
        r = self.residual[rows]
        return float(np.sum(r * r))


def base_size(ref: MagReference) -> int:
    """Number of base-field parameters at the head of θ: 3 (B_n, µT, ENU) on an attitude reference, 1
    (F, µT) on a magnitude one."""
    return 3 if ref.has_attitude else 1


def split_theta(ref: MagReference, kinds: tuple[str, ...], theta: np.ndarray) -> dict[str, np.ndarray]:
    """θ by name: ``base`` (the reference field) and one slice per kind, in the order of ``kinds``."""
    out = {"base": theta[: base_size(ref)]}
    i = base_size(ref)
    for k in kinds:
        n = mag_term(k).n_params
        out[k] = theta[i : i + n]
        i += n
    return out


def _parts(ref, kinds, theta):
    p = split_theta(ref, kinds, theta)
    h = p.get("hard_iron", np.zeros(3))
    a = soft_iron_matrix(p["soft_iron"]) if "soft_iron" in p else np.eye(3)
    ang = p.get("frame_rotation")
    return p, h, a, ang


def _attitude_fun(ref: MagReference, kinds: tuple[str, ...], idx: np.ndarray):
    m, c = ref.mag_ut[idx], ref.c_bn[idx]

    def fun(theta: np.ndarray):
        p, h, a, ang = _parts(ref, kinds, theta)
        rt = rotation_matrix(ang).T if ang is not None else np.eye(3)
        b = np.einsum("kij,j->ki", c, p["base"])
        q = b @ rt.T
        mhat = q @ a.T + h
        cols = [-np.einsum("ij,kjl->kil", a @ rt, c)]                      # B_n
        for k in kinds:
            if k == "hard_iron":
                cols.append(np.broadcast_to(-np.eye(3), (idx.size, 3, 3)))
            elif k == "soft_iron":
                cols.append(-np.stack([q @ e.T for e in SOFT_BASIS], axis=2))
            elif k == "frame_rotation":
                d = []
                for j in range(3):
                    dth = np.zeros(3)
                    dth[j] = _EPS
                    drt = (rotation_matrix(ang + dth).T - rotation_matrix(ang - dth).T) / (2 * _EPS)
                    d.append(b @ (a @ drt).T)
                cols.append(-np.stack(d, axis=2))
        jac = np.concatenate(cols, axis=2).reshape(idx.size * 3, -1)
        return (m - mhat).ravel(), jac

    return fun


def _magnitude_fun(ref: MagReference, kinds: tuple[str, ...], idx: np.ndarray):
    m = ref.mag_ut[idx]

    def fun(theta: np.ndarray):
        p, h, a, _ = _parts(ref, kinds, theta)
        ainv = np.linalg.inv(a)
        v = (m - h) @ ainv.T
        nv = np.linalg.norm(v, axis=1)
        n = v / nv[:, None]
        na = n @ ainv                                   # (A⁻ᵀ n)ᵀ
        cols = [-np.ones((idx.size, 1))]
        for k in kinds:
            if k == "hard_iron":
                cols.append(-na)
            elif k == "soft_iron":
                cols.append(-np.stack([np.sum(na * (v @ e.T), axis=1) for e in SOFT_BASIS], axis=1))
        return nv - p["base"][0], np.concatenate(cols, axis=1)

    return fun


def model_function(ref: MagReference, kinds: tuple[str, ...], idx: np.ndarray):
    """fun(θ) → (residual rows, Jacobian) on the samples ``idx`` (module docstring)."""
    return _attitude_fun(ref, kinds, idx) if ref.has_attitude else _magnitude_fun(ref, kinds, idx)


def initial_base(ref: MagReference, rows: np.ndarray) -> np.ndarray:
    """Start of the base field from the samples ``rows``: on an attitude reference the measured field
    turned to ENU (C_kᵀ m_k, µT) and averaged, on a magnitude one the median |m_k| (µT)."""
    idx = np.flatnonzero(rows)
    if ref.has_attitude:
        return np.mean(np.einsum("kji,kj->ki", ref.c_bn[idx], ref.mag_ut[idx]), axis=0)   # Cᵀ m averaged
    return np.array([float(np.median(np.linalg.norm(ref.mag_ut[idx], axis=1)))])


def residual_all(ref: MagReference, kinds: tuple[str, ...], theta: np.ndarray) -> np.ndarray:
    """(N, k) residual at every valid sample (NaN elsewhere)."""
    idx = np.flatnonzero(ref.valid)
    k = 3 if ref.has_attitude else 1
    out = np.full((ref.t_s.size, k), np.nan)
    r, _ = model_function(ref, kinds, idx)(theta)
    out[idx] = r.reshape(-1, k)
    return out


def fit_mag(ref: MagReference, kinds: tuple[str, ...], rows: np.ndarray, theta0: np.ndarray | None = None) -> MagFit:
    """Least-squares fit of the base field and ``kinds`` on the samples ``rows`` (module docstring)."""
    kinds = tuple(kinds)
    idx = np.flatnonzero(rows & ref.valid)
    p = base_size(ref) + sum(mag_term(k).n_params for k in kinds)
    if theta0 is None:
        theta0 = np.concatenate([initial_base(ref, rows & ref.valid), np.zeros(p - base_size(ref))])
    theta0 = np.asarray(theta0, float)
    if not ref.has_attitude and "hard_iron" in kinds:
        i = 1 + sum(mag_term(k).n_params for k in kinds[: kinds.index("hard_iron")])
        if not np.any(theta0[i : i + 3]):   # |m − h| is far from linear in h: start from calib.mag's sphere fit
            h, f, _, _ = fit_sphere(ref.mag_ut[idx], block_index(idx.size, 100))
            theta0 = theta0.copy()
            theta0[i : i + 3], theta0[0] = h, f
    res = levenberg_marquardt(model_function(ref, kinds, idx), np.asarray(theta0, float), max_iter=30, tol=1e-12)
    jac, r = res.jacobian, res.residual
    k = r.size // idx.size
    rate = (ref.t_s.size - 1) / max(float(ref.t_s[-1] - ref.t_s[0]), 1e-12)
    blocks = np.repeat(block_index(idx.size, max(1, int(round(rate)))), k)
    # blocks follow the sample order of idx: a gap between stretches starts a new block anyway
    cov, _ = sandwich_covariance(jac, r, blocks)
    scale = np.linalg.norm(jac, axis=0)
    scale[scale == 0] = 1.0
    sv = np.linalg.svd(jac / scale, compute_uv=False)
    rank = int(np.sum(sv > RANK_TOL * sv[0])) if sv.size else 0
    return MagFit(kinds, res.theta, residual_all(ref, kinds, res.theta), cov, rank, res.converged)


def corrected_field(ref: MagReference, kinds: tuple[str, ...], theta: np.ndarray) -> np.ndarray:
    """(N, 3) the magnetometer with the model's sensor terms undone, in the IMU's axes:
    R(θ) A⁻¹ (m − h) (µT, body frame)."""
    _, h, a, ang = _parts(ref, kinds, theta)
    out = (ref.mag_ut - h) @ np.linalg.inv(a).T
    if ang is not None:
        out = out @ rotation_matrix(ang).T
    return out
