"""The design of a north-finding: the holds, the least-squares design of a turning board, and what its σ
depends on besides the noise.  Shared by :mod:`.northfind` (the estimate) and :mod:`.northfind_plan`
(the accuracy limit before recording), so neither needs the other.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from calib.noise.allan import NoiseTerms
from calib.noise.window_means import window_mean_covariance

__all__ = ["Design", "turning_design"]


def _rot2(alpha: np.ndarray) -> np.ndarray:
    """(P, 2, 2): a world-fixed vector in the plane basis after the body turned by α about the axis."""
    c, s = np.cos(alpha), np.sin(alpha)
    return np.stack([np.stack([c, s], -1), np.stack([-s, c], -1)], -2)


def turning_design(alpha: np.ndarray) -> np.ndarray:
    """The GLS design (2P, 4) of P holds turned by α about the axis: rows (hold k, plane component p), columns
    c₁, c₂ (the fixed bias in the plane) and w₁, w₂ (the Earth's rate, world-fixed, seen turned by α)."""
    r = _rot2(alpha)
    P = alpha.size
    a = np.zeros((2 * P, 4))
    for k in range(P):
        a[2 * k : 2 * k + 2, 0:2] = np.eye(2)
        a[2 * k : 2 * k + 2, 2:4] = r[k]
    return a


@dataclass(frozen=True)
class Design:
    """What the σ of a north-finding depends on besides the noise: the hold windows (samples),
    the GLS design, the plane basis and ∂ψ/∂w.  :meth:`heading_sigma_rad` gives σ_ψ for any
    per-axis noise model (the physical limit with the true noise, the reported σ with the fitted)."""

    windows: np.ndarray       # (P, 2) sample ranges
    design: np.ndarray        # (2P, 4) rows (hold k, plane component p); columns c₁, c₂, w₁, w₂
    basis: np.ndarray         # (2, 3) e₁, e₂ in body coordinates
    jac: np.ndarray           # (2,) ∂ψ/∂(w₁, w₂)  (rad per rad/s)
    north_unit: np.ndarray    # (2,) North in the plane basis
    rate_hz: float
    n_record: int

    def sigma_matrix(self, noise: tuple[NoiseTerms, ...]) -> np.ndarray:
        """Σ (2P, 2P) of the projected hold means: Σ_{(k,p),(j,q)} = Σ_i e_p[i] e_q[i] C_i[k, j]."""
        P = self.windows.shape[0]
        sig = np.zeros((2 * P, 2 * P))
        cache: dict[NoiseTerms, np.ndarray] = {}
        for i in range(3):
            if noise[i] not in cache:
                cache[noise[i]] = window_mean_covariance(noise[i], self.windows, self.rate_hz, self.n_record)
            c = cache[noise[i]]
            proj = np.outer(self.basis[:, i], self.basis[:, i])           # (2, 2)
            sig += np.kron(c, proj)
        return sig

    def w_covariance(self, noise: tuple[NoiseTerms, ...]) -> np.ndarray:
        sig = self.sigma_matrix(noise)
        a = self.design
        return np.linalg.inv(a.T @ np.linalg.solve(sig, a))[2:, 2:]

    def bias_residual_sigma(self, noise: tuple[NoiseTerms, ...]) -> float:
        """σ_res (rad/s): the w error perpendicular to North."""
        t = np.array([-self.north_unit[1], self.north_unit[0]])
        return float(math.sqrt(t @ self.w_covariance(noise) @ t))

    def heading_sigma_rad(self, noise: tuple[NoiseTerms, ...]) -> float:
        return float(math.sqrt(self.jac @ self.w_covariance(noise) @ self.jac))
