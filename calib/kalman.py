"""Zhou et al. 2020 §3.3: a 9-state error-state Kalman filter (filterpy) for gyro scale factor and
non-orthogonality from hand rotation, with the accelerometer's gravity residual as measurement.

Model (frames: body RFU, navigation ENU; all derived here, conventions stated):

* gyro, after the static bias b̂ is removed:  ω̃ = (I + S + N(G)) ω + ε,  S = diag(Sx, Sy, Sz),
  N(G) = [[0, Gz, Gy], [Gz, 0, Gx], [Gy, Gx, 0]]  (Zhou eq. 1–2);
* compensated rate ω̂ = M̂⁻¹ ω̃, M̂ = I + Ŝ + N(Ĝ); strapdown attitude Ĉ = Ĉ_bⁿ integrated from ω̂;
* attitude error φ defined by Ĉ = (I − [φ×]) C (Zhou eq. 10); with δS = S − Ŝ, δG = G − Ĝ,

      φ̇ = −Ĉ δω,   δω = ω̂ − ω = M̂⁻¹ (diag(ω̂) δS + J_G(ω̂) δG) − M̂⁻¹ε,

  J_G(ω) = ∂(N(G) ω)/∂G = [[0, ω_z, ω_y], [ω_z, 0, ω_x], [ω_y, ω_x, 0]].  **Correction to Zhou eq. 9**:
  the paper writes the skew matrix [ω×] for the non-orthogonality block; for its own symmetric
  N_g of eq. 2 the block is this symmetric J_G (a skew block would describe a rotation, which
  is unobservable from gravity and is not what eq. 2 models);
* state x = [φ, δS, δG] (9); F = [[0, −Ĉ M̂⁻¹ diag(ω̂), −Ĉ M̂⁻¹ J_G(ω̂)], 0, 0]; since F² = 0 the
  transition over Δt is exactly Φ = I + F Δt (F at the step's midpoint);
* process noise from the ARW N_g (rad/s/√Hz): Q_φφ = N_g² Δt I (ε white, isotropic, so
  Ĉ M̂⁻¹ N_g² M̂⁻ᵀ Ĉᵀ ≈ N_g² I); S and G are random constants (Q = 0);
* measurement (Zhou eq. 11–12): z = Ĉ f − g_up = (I − [φ×])(g_up + a) − g_up ≈ [g_up×] φ + a + v,
  H = [[g_up×], 0, 0], g_up = (0, 0, g); the third row is zero (the vertical component holds no
  attitude information) but is kept as in the paper: its innovation checks |f| against g;
* R = (σ_f² + a_ext²) I: σ_f² = N_a² f_s the accelerometer's white noise (VRW) per sample and
  a_ext the allowance for the hand's external acceleration (m/s² RMS);
* error-state reset after every update: Ŝ += δŜ, Ĝ += δĜ, Ĉ ← (I + [φ̂×]) Ĉ (renormalised),
  x ← 0.  filterpy's update uses the Joseph form; P is re-symmetrised after each update.

filterpy pitfall: ``update`` must get z as a (3, 1) column vector (a 1-D z silently gives x the
wrong shape).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from filterpy.kalman import KalmanFilter

from gyrosim.effects import _nonortho_matrix
from gyrosim.rotations import quat_normalize, skew

__all__ = ["FilterConfig", "FilterHistory", "ZhouFilter", "STATE_NAMES", "jacobian_nonorthogonality"]

STATE_NAMES = ("phi_x", "phi_y", "phi_z", "S_x", "S_y", "S_z", "G_x", "G_y", "G_z")


# ---- single-quaternion helpers for the per-sample loop (the vectorised gyrosim.rotations versions
#      cost ~10 µs of array bookkeeping per call on one vector)
def _qmul(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    pw, px, py, pz = p
    qw, qx, qy, qz = q
    return np.array([pw * qw - px * qx - py * qy - pz * qz, pw * qx + px * qw + py * qz - pz * qy,
                     pw * qy - px * qz + py * qw + pz * qx, pw * qz + px * qy - py * qx + pz * qw])


def _qexp(v: np.ndarray) -> np.ndarray:
    th = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    k = 0.5 - th * th / 48.0 if th < 1e-6 else math.sin(0.5 * th) / th
    return np.array([math.cos(0.5 * th), k * v[0], k * v[1], k * v[2]])


def _qunit(q: np.ndarray) -> np.ndarray:
    return q / math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])


def _qmat(q: np.ndarray) -> np.ndarray:
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def jacobian_nonorthogonality(omega: np.ndarray) -> np.ndarray:
    """J_G(ω) = ∂(N(G) ω)/∂G: the same symmetric pattern as N with G → ω (see module docstring)."""
    return _nonortho_matrix(np.asarray(omega, dtype=float))


@dataclass(frozen=True)
class FilterConfig:
    """Noise and prior of the filter (SI). Paper §5.1: P₀ = diag(3°, 3°, 3°, 0.05 × 6)²."""

    arw_rad_s_sqrt_hz: float
    vrw_m_s2_sqrt_hz: float
    external_acc_allowance_m_s2: float = 0.0
    gravity_m_s2: float = 9.80665
    prior_attitude_rad: float = math.radians(3.0)
    prior_scale: float = 0.05
    prior_nonorthogonality: float = 0.05
    scale0: tuple[float, float, float] = (0.0, 0.0, 0.0)
    nonorthogonality0: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass
class FilterHistory:
    """Per-sample record of the run (for rerun and diagnostics); P is after the update."""

    t_s: list[float] = field(default_factory=list)
    p_diag: list[np.ndarray] = field(default_factory=list)
    scale: list[np.ndarray] = field(default_factory=list)
    nonorthogonality: list[np.ndarray] = field(default_factory=list)
    innovation: list[np.ndarray] = field(default_factory=list)
    nis: list[float] = field(default_factory=list)

    def arrays(self) -> dict[str, np.ndarray]:
        return {
            "t_s": np.asarray(self.t_s),
            "p_diag": np.asarray(self.p_diag),
            "scale": np.asarray(self.scale),
            "nonorthogonality": np.asarray(self.nonorthogonality),
            "innovation": np.asarray(self.innovation),
            "nis": np.asarray(self.nis),
        }


class ZhouFilter:
    """The error-state filter of the module docstring, one sample at a time (filterpy inside)."""

    def __init__(self, config: FilterConfig, quat0_nb: np.ndarray, rate_hz: float) -> None:
        self.config = config
        self.kf = KalmanFilter(dim_x=9, dim_z=3)
        c = config
        self.kf.P = np.diag(
            [c.prior_attitude_rad**2] * 3 + [c.prior_scale**2] * 3 + [c.prior_nonorthogonality**2] * 3
        )
        self.kf.x = np.zeros((9, 1))
        self.kf.Q = np.zeros((9, 9))
        g_up = np.array([0.0, 0.0, c.gravity_m_s2])
        self.g_up = g_up
        self.kf.H = np.hstack([skew(g_up), np.zeros((3, 6))])
        sigma_f2 = c.vrw_m_s2_sqrt_hz**2 * rate_hz + c.external_acc_allowance_m_s2**2
        self.kf.R = np.eye(3) * sigma_f2
        self.scale = np.array(c.scale0, dtype=float)
        self.nonortho = np.array(c.nonorthogonality0, dtype=float)
        self.quat = quat_normalize(np.asarray(quat0_nb, dtype=float))
        self.history = FilterHistory()

    # ------------------------------------------------------------------ model pieces
    def m_hat(self) -> np.ndarray:
        """M̂ = I + Ŝ + N(Ĝ)."""
        sx, sy, sz = self.scale
        gx, gy, gz = self.nonortho
        return np.array([[1 + sx, gz, gy], [gz, 1 + sy, gx], [gy, gx, 1 + sz]])

    def compensate(self, gyro_minus_bias: np.ndarray) -> np.ndarray:
        """ω̂ = M̂⁻¹ ω̃ with the current Ŝ, Ĝ."""
        return np.linalg.solve(self.m_hat(), gyro_minus_bias)

    def transition(self, c_nb: np.ndarray, m_inv: np.ndarray, omega_hat: np.ndarray, dt: float) -> np.ndarray:
        """Φ = I + F Δt (exact: F² = 0), F from the module docstring."""
        cm = c_nb @ m_inv
        wx, wy, wz = omega_hat
        phi = np.eye(9)
        phi[0:3, 3:6] = -dt * cm * omega_hat  # C M⁻¹ diag(ω): scale column j by ω_j
        phi[0:3, 6:9] = -dt * cm @ np.array([[0.0, wz, wy], [wz, 0.0, wx], [wy, wx, 0.0]])
        return phi

    # ------------------------------------------------------------------ one step
    def step(self, t_s: float, dt: float, w_prev: np.ndarray, w_now: np.ndarray, f_body: np.ndarray,
             update: bool = True) -> None:
        """Propagate from the previous sample (compensated rate ``w_prev``) to this one and update.

        ``w_prev`` / ``w_now``: bias-removed gyro (rad/s, body); ``f_body``: accelerometer (m/s², body).
        """
        m_inv = np.linalg.inv(self.m_hat())
        wp = m_inv @ w_prev
        wn = m_inv @ w_now
        phi = 0.5 * (wp + wn) * dt + _cross(wp, wn) * (dt * dt / 12.0)
        q_mid = _qmul(self.quat, _qexp(0.5 * phi))
        self.quat = _qunit(_qmul(self.quat, _qexp(phi)))
        kf = self.kf
        kf.F = self.transition(_qmat(q_mid), m_inv, 0.5 * (wp + wn), dt)
        q_phi = self.config.arw_rad_s_sqrt_hz**2 * dt
        kf.Q[0, 0] = kf.Q[1, 1] = kf.Q[2, 2] = q_phi
        kf.predict()
        if update:
            z = (_qmat(self.quat) @ f_body - self.g_up).reshape(3, 1)  # column vector (filterpy)
            kf.update(z)
            kf.P = 0.5 * (kf.P + kf.P.T)
            self._inject()
            innov = kf.y.ravel()
            nis = float(innov[:2] @ np.linalg.inv(kf.S[:2, :2]) @ innov[:2])  # rows with attitude info
        else:
            innov, nis = np.full(3, np.nan), float("nan")
        h = self.history
        h.t_s.append(t_s)
        h.p_diag.append(np.diag(kf.P).copy())
        h.scale.append(self.scale.copy())
        h.nonorthogonality.append(self.nonortho.copy())
        h.innovation.append(innov)
        h.nis.append(nis)

    def _inject(self) -> None:
        x = self.kf.x.ravel()
        self.scale = self.scale + x[3:6]
        self.nonortho = self.nonortho + x[6:9]
        self.quat = _qunit(_qmul(_qexp(x[0:3]), self.quat))  # Ĉ ← (I + [φ×]) Ĉ
        self.kf.x = np.zeros((9, 1))
