"""The lever arm term: what a hand's turn about a pivot adds to the specific force the accelerometer senses.

The hand turns the board about a pivot (wrist, elbow) r away from the accelerometer (body frame, m; the
accelerometer–gyro site offset is part of it), so besides gravity the sensor reads

    f − g_b = K(ω, ω̇) r,     K(ω, ω̇) = [ω̇×] + [ω×][ω×]

— deterministic and correlated with the rotation, which the paper's filter turns into S and G errors (0.3 % with a
6 cm wrist): ``kf_hand`` estimates r as three states.  K is built from the rate compensated with the pass's S, G, b
(:func:`lever_regressor`), so K r̂ depends on them too: the update carries that dependence, ∂(K r̂)/∂(S, G, b)
(:func:`lever_jacobian`) — without it a session that pins S, G weakly left σ ~1.4× optimistic.

Source: the lever-arm kinematics of any rigid body (e.g. Titterton & Weston, *Strapdown Inertial Navigation
Technology*, 2nd ed., §10.4, lever-arm compensation).
"""

from __future__ import annotations

import numpy as np

from gyrosim.rotations import skew

from calib.session.hand.lowpass import CUTOFF_HZ, ORDER, lowpass
from calib.session.kernel import LeverJacobian
from calib.session.model import nonorthogonality_jacobians

__all__ = ["lever_regressor", "lever_jacobian"]


def lever_regressor(w_rad_s: np.ndarray, t_s: np.ndarray, rate_hz: float, cutoff_hz: float = CUTOFF_HZ,
                    order: int = ORDER) -> np.ndarray:
    """K(ω, ω̇) = [ω̇×] + [ω×]² (N, 3, 3) from a compensated rate (N, 3), both low-passed at ``cutoff_hz``
    (the same band as the specific force they explain); ω̇ by central differences."""
    ws = lowpass(w_rad_s, rate_hz, cutoff_hz, order)
    dw = np.gradient(ws, t_s, axis=0)
    sw = skew(ws)
    return skew(dw) + sw @ sw


def lever_jacobian(w_rad_s: np.ndarray, t_s: np.ndarray, rate_hz: float, m: np.ndarray,
                   cutoff_hz: float = CUTOFF_HZ, order: int = ORDER, misalignment: bool = False) -> LeverJacobian:
    """How :func:`lever_regressor`'s K r moves with the gyro's errors, for the rate ``w_rad_s`` (N, 3, body)
    compensated with M = ``m`` (3, 3): ω = M⁻¹ (ω̃ − b) gives ∂ω/∂S = −M⁻¹ diag(ω), ∂ω/∂G = −M⁻¹ J_G(ω),
    ∂ω/∂b = −M⁻¹ (the first-order error model of Zhou 2020 eq. 9, as the attitude's propagation uses it); the
    regressor low-passes ω and differentiates it, and so are these sensitivities (the low-pass and the central
    difference are linear).  Returns :class:`calib.session.kernel.LeverJacobian`; the kernel forms ∂(K r̂)/∂θ for the
    current r̂ from it at each update.  ``misalignment``: also ∂ω/∂α = −M⁻¹ [ω×] (the gyro's rotation against the
    accelerometer, M = I + diag(S) + N(G) − [α×]: 12 columns)."""
    n = w_rad_s.shape[0]
    mi = np.linalg.inv(m)
    nc = 12 if misalignment else 9
    d = np.empty((n, 3, nc))
    d[:, :, 0:3] = -mi[None, :, :] * w_rad_s[:, None, :]                         # −M⁻¹ diag(ω)
    d[:, :, 3:6] = -np.einsum("ij,njk->nik", mi, nonorthogonality_jacobians(w_rad_s))   # −M⁻¹ J_G(ω): N(G)ω = J_G(ω)G
    d[:, :, 6:9] = -mi[None]                                                      # −M⁻¹
    if misalignment:
        d[:, :, 9:12] = -np.einsum("ij,njk->nik", mi, skew(w_rad_s))               # −M⁻¹ [ω×]: −[α×]ω = [ω×]α
    ld = lowpass(d.reshape(n, 3 * nc), rate_hz, cutoff_hz, order).reshape(n, 3, nc)
    return LeverJacobian(lowpass(w_rad_s, rate_hz, cutoff_hz, order), ld, np.gradient(ld, t_s, axis=0))
