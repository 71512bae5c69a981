"""The calibration filter written for reading: one sample at a time, one equation a line (filterpy inside).

:class:`ZhouFilter` is the error-state filter of :mod:`calib.session.model` for every state layout the compiled
kernel (:mod:`calib.session.kernel`) runs — the paper's 9 states (``PAPER``), the joint 21 (``JOINT``), the hand's
(``HAND``, ``HAND_BIAS``, ``HAND_JOINT``) with the thermal blocks, the gyro's g-sensitivity, the accelerometer bias's
temperature coefficient, the accelerometer's delay and the external acceleration's shaping filters — with the same
gating, update masks, rest handling and measurement rows.  It is the kernel's readable twin: the same equations in
plain numpy on dense matrices (Φ n × n, H m × n), where the kernel exploits their sparsity; :func:`run_reference`
runs it with :func:`calib.session.kernel.run_filter`'s arguments and returns the same :class:`FilterRun`, and a test
holds the two equal on short recordings of every layout (tests/session/test_reference_filter.py).
``calibrate(..., engine="filterpy")`` runs it over a whole session.

One step k−1 → k (symbols of :mod:`calib.session.model`; body RFU, nav ENU, SI):

1. nominal: M̂ = I + diag(Ŝ + ŝ_T ΔT) + N(Ĝ), b̂ = b̂_g + ĉ_b ΔT + k̂ ⊙ f (ΔT = T − T₀ at the step's middle), ω̂ =
   M̂⁻¹(ω̃ − b̂) at both ends, q̂ ← q̂ ⊗ Exp(½(ω̂ₖ₋₁ + ω̂ₖ)Δt + (ω̂ₖ₋₁ × ω̂ₖ)Δt²/12) (trapezoid + coning);
2. transition: Φ = I + E + (Φ_ae − I), E = −Ĉ M̂⁻¹ Δt [diag(ω), J_G(ω), I, I ΔT, diag(ω) ΔT, diag(f)] in the φ
   rows (ω the leave-out regressor, zero at rest), Φ_ae the external acceleration's transition; Q = diag(N_g²Δt on
   φ, q_b Δt on b_g, a_e's Q_d); x ← Φ x, P ← Φ P Φᵀ + Q, the nominal a_e ← Φ_ae a_e;
3. measurement (when the sample updates): f̂ = M̂_a⁻¹(f̃ − b̂_a − ĉ_a ΔT) + δ̂ ⊙ ḟ̃ − K r̂ − J (θ̂ − θ₀),
   z = Ĉ f̂ − g_up − â_e, H = [[g_up×], …] (:meth:`ZhouFilter.measurement`); y = z − H x, S = H P Hᵀ + R;
   NIS = yᵀS⁻¹y; gated (NIS > gate: no update) or x ← x + K y, P ← (I − K H) P (I − K H)ᵀ + K R Kᵀ (Joseph);
4. reset: θ̂ += δθ̂ (and the hand's, the sensor's extra nominals), q̂ ← Exp(φ̂) ⊗ q̂, x ← 0.

filterpy pitfall: ``update`` must get z as a column vector (a 1-D z silently gives x the wrong shape).
"""

from __future__ import annotations

import math

import numpy as np
from filterpy.kalman import KalmanFilter

from gyrosim.rotations import quat_normalize, skew

from calib.session.kernel import HAND_NOMINALS, SENSOR_NOMINALS, FilterRun, filter_inputs, lever_jacobian_columns
from calib.session.model import (
    EXT_ACC_BLOCKS,
    PAPER,
    SENSOR_EXTRA_BLOCKS,
    FilterConfig,
    FilterHistory,
    StateLayout,
    cross3,
    ext_acc_discrete,
    initial_covariance,
    jacobian_nonorthogonality,
    m_matrix,
    q_exp,
    q_matrix,
    q_mul,
    q_unit,
    theta_slice,
)

__all__ = ["ZhouFilter", "run_reference"]

# where each extra block's nominal sits in ZhouFilter.sensor (SENSOR_EXTRA_BLOCKS order) and ZhouFilter.hand
_SENSOR_AT = {b: slice(3 * i, 3 * i + 3) for i, b in enumerate(SENSOR_EXTRA_BLOCKS)}


class ZhouFilter:
    """The error-state filter of the module docstring, one sample at a time.

    ``theta0``: nominal parameters (18, ``THETA`` order; default: the config's S₀, G₀, zeros); ``p0``: initial
    covariance (default :func:`calib.session.model.initial_covariance` of the layout); ``x0``: the prior mean as an
    error state (θ_prior − θ̂₀; default zero: the prior centred on the nominal), propagated (x ← Φ x) and used in the
    innovation (z − H x) until the first reset.  ``hand0`` (≤ ``HAND_NOMINALS``): the nominal lever arm and a_e's
    shaping-filter states (i of nav axis j at 3 + 3i + j); ``sensor0`` (≤ ``SENSOR_NOMINALS``): c_b, s_T, k, c_a, δ, α;
    ``rows``: measurement rows (2: levelling; 3: + the vertical, |f| = g); ``gate_nis`` > 0 skips an update whose NIS
    exceeds it.
    """

    def __init__(self, config: FilterConfig, quat0_nb: np.ndarray, rate_hz: float, layout: StateLayout = PAPER,
                 theta0: np.ndarray | None = None, p0: np.ndarray | None = None, x0: np.ndarray | None = None, *,
                 hand0: np.ndarray | None = None, sensor0: np.ndarray | None = None, rows: int = 2,
                 gate_nis: float = 0.0) -> None:
        self.config, self.layout, self.rate_hz = config, layout, rate_hz
        n = layout.n
        self.kf = KalmanFilter(dim_x=n, dim_z=3)
        self.kf.P = initial_covariance(layout, config) if p0 is None else np.array(p0, float)
        self.kf.x = np.zeros((n, 1)) if x0 is None else np.asarray(x0, float).reshape(n, 1)  # prior mean − nominal
        self.kf.Q = np.zeros((n, n))
        self.g_up = np.array([0.0, 0.0, config.gravity_m_s2])
        self.kf.R = np.eye(3) * config.r_var(rate_hz)
        if theta0 is None:
            theta0 = np.zeros(18)
            theta0[theta_slice("gyro_scale")] = config.scale0
            theta0[theta_slice("gyro_nonorth")] = config.nonorthogonality0
        self.theta = np.array(theta0, dtype=float)
        self.theta_lin = self.theta.copy()     # θ₀: the lever arm regressor's linearisation point (lever_jacobian)
        self.hand = _padded(hand0, HAND_NOMINALS)
        self.sensor = _padded(sensor0, SENSOR_NOMINALS)
        self.sensor_lin = self.sensor.copy()   # α₀: the lever arm regressor's linearisation point of the misalignment
        self.quat = quat_normalize(np.asarray(quat0_nb, dtype=float))
        self._rows = int(rows)
        self.gate_nis = float(gate_nis)
        self._ae = _ExternalAcceleration(layout, config)
        self._hist: dict[str, list] = {"t_s": [], "sd": [], "theta": [], "innovation": [], "nis": [], "whitened": []}

    # ------------------------------------------------------------------ nominal parameters
    def _block(self, block: str) -> np.ndarray:
        if block in _SENSOR_AT:
            return self.sensor[_SENSOR_AT[block]]
        return self.theta[theta_slice(block)]

    @property
    def scale(self) -> np.ndarray:
        """Ŝ_g (3,)."""
        return self._block("gyro_scale").copy()

    @property
    def nonortho(self) -> np.ndarray:
        """Ĝ_g (3,)."""
        return self._block("gyro_nonorth").copy()

    def m_hat(self, dtemp_c: float = 0.0) -> np.ndarray:
        """M̂_g = I + diag(Ŝ_g + ŝ_T ΔT) + N(Ĝ_g) − [α̂×] (α̂: the rotation against the accelerometer, 0 without it)."""
        m = m_matrix(self._block("gyro_scale") + self._block("gyro_temp_scale") * dtemp_c, self._block("gyro_nonorth"))
        return m - skew(self._block("gyro_misalign")) if self.layout.models_misalignment else m

    def m_hat_acc(self) -> np.ndarray:
        """M̂_a = I + diag(Ŝ_a) + N(Ĝ_a) (I without the accelerometer's blocks: θ̂_a stays 0)."""
        return m_matrix(self._block("acc_scale"), self._block("acc_nonorth"))

    @property
    def whitened(self) -> np.ndarray:
        """(steps, 3) whitened innovations L⁻¹ν of the levelling rows of every step so far (NaN where no update)."""
        return np.asarray(self._hist["whitened"]).reshape(-1, 3)

    @property
    def history(self) -> FilterHistory:
        """The per-step record so far (:class:`calib.session.model.FilterHistory`)."""
        h = self._hist
        return FilterHistory(np.asarray(h["t_s"]), np.asarray(h["sd"]).reshape(-1, self.layout.n),
                             np.asarray(h["theta"]).reshape(-1, 18), np.asarray(h["innovation"]).reshape(-1, 3),
                             np.asarray(h["nis"]), self.layout.names)

    # ------------------------------------------------------------------ one step
    def step(self, t_s: float, dt: float, w_prev: np.ndarray, w_now: np.ndarray, f_body: np.ndarray,
             update: bool = True, w_reg: np.ndarray | None = None, f_reg: np.ndarray | None = None,
             still: bool = False, *, r_var: float | None = None, dtemp_c: tuple[float, float] = (0.0, 0.0),
             force: tuple[np.ndarray, np.ndarray] | None = None, acc_rate: np.ndarray | None = None,
             lever: np.ndarray | None = None, lever_jac: tuple | None = None) -> None:
        """Propagate from the previous sample to this one and update with this accelerometer sample.

        ``w_prev`` / ``w_now``: raw gyro samples (rad/s, body); ``f_body``: raw accelerometer (m/s², body);
        ``w_reg`` / ``f_reg``: the raw regressors for F and H (module docstring of :mod:`calib.session.model`;
        default: the step's midpoint rate and gravity predicted in the body); ``still``: the step lies in a rest
        (zero rate regressor); ``r_var``: this sample's R per axis (default the config's); ``dtemp_c``: T − T₀ at
        the previous and this sample (°C, temperature blocks); ``force``: the specific force f at both (body, m/s²;
        g-sensitivity); ``acc_rate``: ḟ̃ at this sample (body, m/s³; the delay); ``lever``: K(ω, ω̇) (3, 3) at this
        sample (the lever arm); ``lever_jac``: (ω, L ∂ω/∂θ, d/dt of it) at this sample
        (:class:`calib.session.kernel.LeverJacobian`'s rows).
        """
        F, Q = self.propagate(dt, w_prev, w_now, w_reg, still, dtemp_c, force)
        self.kf.predict(F=F, Q=Q)                                        # x = Φ x,  P = Φ P Φᵀ + Q
        innov, nis, white = np.full(3, np.nan), float("nan"), np.full(3, np.nan)
        if update:
            m = self._rows
            z, H = self.measurement(f_body, f_reg, dtemp_c[1], force, acc_rate, lever, lever_jac)
            R = np.eye(m) * (self.config.r_var(self.rate_hz) if r_var is None else r_var)   # R = r I (m × m)
            y = z[:m] - H[:m] @ self.kf.x.ravel()                        # innovation y = z − H x
            S = H[:m] @ self.kf.P @ H[:m].T + R                          # S = H P Hᵀ + R
            nis = float(y @ np.linalg.solve(S, y))                       # NIS = yᵀ S⁻¹ y
            innov[:m] = y
            white[:2] = np.linalg.solve(np.linalg.cholesky(S[:2, :2]), y[:2])   # L⁻¹ν, S = L Lᵀ (levelling rows)
            if not (self.gate_nis > 0.0 and nis > self.gate_nis):        # gating: skip an update whose NIS exceeds it
                self.kf.update(z[:m].reshape(m, 1), R=R, H=H[:m])        # K = P Hᵀ S⁻¹; x += K y; Joseph form P
                self.kf.P = 0.5 * (self.kf.P + self.kf.P.T)              # re-symmetrised
                self._inject()
        h = self._hist
        h["t_s"].append(t_s)
        h["sd"].append(np.sqrt(np.clip(np.diag(self.kf.P), 0.0, None)))
        h["theta"].append(self.theta.copy())
        h["innovation"].append(innov)
        h["nis"].append(nis)
        h["whitened"].append(white)

    def propagate(self, dt: float, w_prev: np.ndarray, w_now: np.ndarray, w_reg: np.ndarray | None, still: bool,
                  dtemp_c: tuple[float, float], force: tuple[np.ndarray, np.ndarray] | None
                  ) -> tuple[np.ndarray, np.ndarray]:
        """Steps 1–2 of the module docstring: move the nominal (attitude, a_e) to this sample; return (Φ, Q)."""
        lay, n = self.layout, self.layout.n
        dtm = 0.5 * (dtemp_c[0] + dtemp_c[1])                            # T − T₀ at the step's middle
        f_mid = np.zeros(3) if force is None else 0.5 * (force[0] + force[1])   # f at the step's middle (body)
        b_g = self._block("gyro_bias") + self._block("gyro_temp_bias") * dtm    # b̂ = b̂_g + ĉ_b ΔT …
        if lay.has("gyro_g_sens"):
            b_g = b_g + self._block("gyro_g_sens") * f_mid                # … + k̂ ⊙ f
        m_inv = np.linalg.inv(self.m_hat(dtm))                            # M̂⁻¹
        wp = m_inv @ (w_prev - b_g)                                      # ω̂ at k−1
        wn = m_inv @ (w_now - b_g)                                       # ω̂ at k
        phi = 0.5 * (wp + wn) * dt + cross3(wp, wn) * (dt * dt / 12.0)   # rotation vector of the step (coning)
        q_mid = q_mul(self.quat, q_exp(0.5 * phi))                       # q̂ at the step's middle
        self.quat = q_unit(q_mul(self.quat, q_exp(phi)))                 # q̂ ⊗ Exp(φ)
        if still:                                                        # at rest the true rate is zero
            w_bar = np.zeros(3)
        else:
            w_bar = 0.5 * (wp + wn) if w_reg is None else m_inv @ (w_reg - b_g)
        cm = -dt * q_matrix(q_mid) @ m_inv                               # −Ĉ M̂⁻¹ Δt
        F = np.eye(n)
        columns = {"gyro_scale": cm * w_bar,                             # scale: column j × ω_j
                   "gyro_nonorth": cm @ jacobian_nonorthogonality(w_bar),   # non-orthogonality: J_G(ω)
                   "gyro_bias": cm,                                      # bias
                   "gyro_temp_bias": cm * dtm,                           # c_b: (T − T₀)
                   "gyro_temp_scale": cm * w_bar * dtm,                  # s_T: ω_j (T − T₀)
                   "gyro_g_sens": cm * f_mid,                            # k: column j × f_j
                   "gyro_misalign": cm @ skew(w_bar)}                    # α: −[δα×] ω = [ω×] δα
        for block, col in columns.items():
            o = lay.offset(block)
            if o >= 0:
                F[0:3, o:o + 3] = col                                    # Φ's φ rows: I + E (F² = 0 there)
        Q = np.zeros((n, n))
        Q[0, 0] = Q[1, 1] = Q[2, 2] = self.config.arw_rad_s_sqrt_hz**2 * dt   # Q_φφ = N_g² Δt
        ob = lay.offset("gyro_bias")
        if ob >= 0 and self.config.gyro_bias_rw_rad_s_sqrt_s > 0:       # the bias's random walk, Q_bb = q_b Δt
            for j in range(3):
                Q[ob + j, ob + j] = self.config.gyro_bias_rw_rad_s_sqrt_s**2 * dt
        self._ae.transition(F, Q, dt)                                   # a_e's Φ_ae and Q_d on its blocks
        self._ae.propagate_nominal(self.hand, dt)                       # â_e ← Φ_ae â_e
        return F, Q

    def measurement(self, f_body: np.ndarray, f_reg: np.ndarray | None, dtemp_c: float,
                    force: tuple[np.ndarray, np.ndarray] | None, acc_rate: np.ndarray | None,
                    lever: np.ndarray | None, lever_jac: tuple | None) -> tuple[np.ndarray, np.ndarray]:
        """Step 3 of the module docstring: the residual z (3,) at the nominal and H (3, n)."""
        lay, n = self.layout, self.layout.n
        c = q_matrix(self.quat)                                          # Ĉ body → nav
        mi_a = np.linalg.inv(self.m_hat_acc()) if lay.estimates_accelerometer else np.eye(3)   # M̂_a⁻¹
        b_a = self._block("acc_bias")                                    # b̂_a (held at θ̂₀ without its block)
        if lay.has("acc_temp_bias"):
            b_a = b_a + self._block("acc_temp_bias") * dtemp_c           # b̂_a(T) = b̂_a + ĉ_a ΔT
        f_hat = mi_a @ (f_body - b_a)                                    # f̂ = M̂_a⁻¹ (f̃ − b̂_a)
        if lay.models_acc_delay:
            f_hat = f_hat + self._block("acc_delay") * acc_rate          # f = f̃ + δ ḟ̃ (first order in δ)
        J = np.zeros((3, 9 if lever_jac is None else np.shape(lever_jac[1])[-1]))   # (S, G, b[, α])
        if lay.has("lever_arm"):
            r = self.hand[0:3]
            f_hat = f_hat - lever @ r                                    # minus the lever arm's K r̂ (body)
            if lever_jac is not None:                                    # K was built at θ₀: K(θ̂) r̂ ≈ K r̂ + J (θ̂ − θ₀)
                lever_jacobian_columns(lever_jac[0], lever_jac[1], lever_jac[2], r, J)   # J = ∂(K r̂)/∂(S, G, b)
                f_hat = f_hat - J @ self._lever_shift(dtemp_c, force)
        z = c @ f_hat - self.g_up - self._ae.nominal(self.hand)         # z = Ĉ f̂ − g_up − â_e
        H = np.zeros((3, n))
        H[:, 0:3] = skew(self.g_up)                                      # [g_up×] φ
        if lay.estimates_accelerometer:
            f_bar = c.T @ self.g_up if f_reg is None else np.asarray(f_reg, float)   # gravity predicted in body
            cma = c @ mi_a
            self._put(H, "acc_bias", cma)                                # Ĉ M̂_a⁻¹
            self._put(H, "acc_scale", cma * f_bar)                       # Ĉ M̂_a⁻¹ diag(f)
            self._put(H, "acc_nonorth", cma @ jacobian_nonorthogonality(f_bar))   # Ĉ M̂_a⁻¹ J_G(f)
            self._put(H, "acc_temp_bias", cma * dtemp_c)                 # Ĉ M̂_a⁻¹ (T − T₀): c_a
        if lay.models_acc_delay:
            self._put(H, "acc_delay", -(c * acc_rate))                   # −Ĉ diag(ḟ): f̃ = f − δ ḟ
        if lay.has("lever_arm"):
            self._put(H, "lever_arm", c @ lever)                         # Ĉ K(ω, ω̇)
            if lever_jac is not None:                                    # Ĉ J: the lever arm term via the rate's errors
                cj = c @ J
                f_k = np.zeros(3) if force is None else force[1]
                self._put(H, "gyro_scale", cj[:, 0:3])                   # Ĉ ∂(K r̂)/∂S
                self._put(H, "gyro_nonorth", cj[:, 3:6])                 # Ĉ ∂(K r̂)/∂G
                self._put(H, "gyro_bias", cj[:, 6:9])                    # Ĉ ∂(K r̂)/∂b
                self._put(H, "gyro_temp_scale", cj[:, 0:3] * dtemp_c)    # s_T: S's column × (T − T₀)
                self._put(H, "gyro_temp_bias", cj[:, 6:9] * dtemp_c)     # c_b: b's column × (T − T₀)
                self._put(H, "gyro_g_sens", cj[:, 6:9] * f_k)            # k: b's column j × f_j
                if J.shape[1] > 9:
                    self._put(H, "gyro_misalign", cj[:, 9:12])           # Ĉ ∂(K r̂)/∂α
        self._ae.measurement(H)                                          # ∂â_e/∂x on a_e's states
        return z, H

    def _lever_shift(self, dtemp_c: float, force: tuple[np.ndarray, np.ndarray] | None) -> np.ndarray:
        """θ̂ − θ₀ for (S, G, b) (9,), S and b at this sample's temperature (and force): the lever arm regressor's
        change since it was built."""
        lay = self.layout
        d = self.theta[0:9] - self.theta_lin[0:9]                        # (S, G, b) − their θ₀
        if lay.models_misalignment:                                      # α̂ − α₀ (J's columns 9:12)
            d = np.concatenate([d, self._block("gyro_misalign") - self.sensor_lin[_SENSOR_AT["gyro_misalign"]]])
        if lay.has("gyro_temp_scale"):
            d[0:3] += self._block("gyro_temp_scale") * dtemp_c           # S(T) = S + s_T ΔT
        if lay.has("gyro_temp_bias"):
            d[6:9] += self._block("gyro_temp_bias") * dtemp_c            # b(T) = b + c_b ΔT
        if lay.has("gyro_g_sens"):
            d[6:9] += self._block("gyro_g_sens") * force[1]              # … + k ⊙ f
        return d

    def _put(self, H: np.ndarray, block: str, cols: np.ndarray) -> None:
        o = self.layout.offset(block)
        if o >= 0:
            H[:, o:o + 3] = cols

    def _inject(self) -> None:
        """Step 4: θ̂ += δθ̂, the extra nominals += their δ, Ĉ ← (I + [φ×]) Ĉ, x ← 0."""
        x = self.kf.x.ravel()
        for b in self.layout.blocks[1:]:
            o = self.layout.offset(b)
            if b in _SENSOR_AT:
                self.sensor[_SENSOR_AT[b]] += x[o:o + 3]                 # c_b, s_T, k, c_a, δ, α += their δ
            elif b == "lever_arm":
                self.hand[0:3] += x[o:o + 3]                             # r̂ += δr
            elif b not in EXT_ACC_BLOCKS:
                self.theta[theta_slice(b)] += x[o:o + 3]                 # θ̂ += δθ̂
        self._ae.inject(self.hand, x)                                   # â_e += δa_e
        self.quat = q_unit(q_mul(q_exp(x[0:3]), self.quat))             # Ĉ ← (I + [φ×]) Ĉ
        self.kf.x = np.zeros((self.layout.n, 1))


class _ExternalAcceleration:
    """The hand's external acceleration a_e per nav axis j (the layout's ``ext_acc`` … blocks): the Gauss–Markov x
    high-passed into z, z₂ (a_e = x − z − z₂; :class:`calib.session.model.FilterConfig`), or with ``ext_acc_s3`` …
    the general shaping filter (ẋ = A x + w, a_e = C x, :meth:`calib.session.model.FilterConfig.ext_acc_model`).
    Component i of axis j: state ``offset(EXT_ACC_BLOCKS[i]) + j``, nominal ``hand[3 + 3i + j]``."""

    def __init__(self, layout: StateLayout, config: FilterConfig) -> None:
        self.config = config
        self.general = any(layout.has(b) for b in EXT_ACC_BLOCKS[3:])
        if self.general:
            self.a, self.qc, c = config.ext_acc_model()
            self.c = np.asarray(c, float)
        else:                                                            # x, its low-pass z, and z₂ (order 2)
            k = 0
            if layout.has("ext_acc"):
                k = 1 + int(layout.has("ext_acc_lp"))                    # z inert (β = 1) without a high-pass
                if k == 2 and layout.has("ext_acc_lp2") and config.ext_acc_highpass_order >= 2:
                    k = 3                                                # z₂ inert for a first-order high-pass
            self.c = np.array([1.0, -1.0, -1.0])[:k]                     # a_e = x − z − z₂
        self.offsets = [layout.offset(b) for b in EXT_ACC_BLOCKS[:self.c.size]]
        self._table: dict[float, tuple[np.ndarray, np.ndarray]] = {}

    def _phi_q(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """(Φ_ae, Q_d) of one axis over ``dt``."""
        if self.general:                                                 # exact: Van Loan's matrix exponential
            if dt not in self._table:
                phi, q = ext_acc_discrete(self.a, self.qc, np.array([dt]))
                self._table[dt] = (phi[0], q[0])
            return self._table[dt]
        cfg, k = self.config, self.c.size
        al, be = math.exp(-dt / cfg.ext_acc_tau_s), math.exp(-dt / cfg.ext_acc_highpass_tau_s)
        phi = np.zeros((k, k))
        q = np.zeros((k, k))
        if k >= 1:
            phi[0, 0] = al                                               # x ← α x,  α = e^{−Δt/τ}
            q[0, 0] = cfg.ext_acc_rms_m_s2**2 * (1.0 - al * al)          # Q = σ² (1 − α²)
        if k >= 2:
            phi[1, 0], phi[1, 1] = 1.0 - be, be                          # z ← β z + (1 − β) x,  β = e^{−Δt/τ_h}
        if k >= 3:
            phi[2, 0], phi[2, 1], phi[2, 2] = 1.0 - be, -(1.0 - be), be  # z₂ ← β z₂ + (1 − β)(x − z)
        return phi, q

    def transition(self, F: np.ndarray, Q: np.ndarray, dt: float) -> None:
        """a_e's blocks of Φ and Q for this step, axis by axis."""
        if self.c.size == 0:
            return
        phi, q = self._phi_q(dt)
        for j in range(3):
            idx = [o + j for o in self.offsets]
            F[np.ix_(idx, idx)] = phi
            Q[np.ix_(idx, idx)] = q

    def propagate_nominal(self, hand: np.ndarray, dt: float) -> None:
        """â_e ← Φ_ae â_e, axis by axis."""
        if self.c.size == 0:
            return
        phi, _ = self._phi_q(dt)
        for j in range(3):
            idx = [3 + 3 * i + j for i in range(self.c.size)]
            hand[idx] = phi @ hand[idx]

    def nominal(self, hand: np.ndarray) -> np.ndarray:
        """â_e = Σ_i c_i x̂_i (nav, 3)."""
        return np.array([sum(self.c[i] * hand[3 + 3 * i + j] for i in range(self.c.size)) for j in range(3)])

    def measurement(self, H: np.ndarray) -> None:
        """∂â_e/∂x: c_i I on component i's block (nav)."""
        for i, o in enumerate(self.offsets):
            if self.c[i] != 0.0:
                H[:, o:o + 3] = self.c[i] * np.eye(3)

    def inject(self, hand: np.ndarray, x: np.ndarray) -> None:
        """â_e += δa_e."""
        for i, o in enumerate(self.offsets):
            hand[3 + 3 * i:6 + 3 * i] += x[o:o + 3]


def _padded(x: np.ndarray | None, size: int) -> np.ndarray:
    v = np.zeros(size)
    if x is not None:
        x = np.asarray(x, float)
        v[:x.size] = x
    return v


def run_reference(gyro: np.ndarray, acc: np.ndarray, t_s: np.ndarray, quat0: np.ndarray, theta0: np.ndarray,
                  p0: np.ndarray, layout: StateLayout, config: FilterConfig, rate_hz: float, **options) -> FilterRun:
    """:func:`calib.session.kernel.run_filter`'s runs (same arguments, same :class:`FilterRun`) with
    :class:`ZhouFilter`: slow (~0.2–1 ms a step), for reading and for testing the kernel (no ``record``)."""
    if options.get("record"):
        raise ValueError("the reference filter does not record the linear error model (record=True): use run_filter")
    inp = filter_inputs(gyro, acc, t_s, quat0, theta0, p0, layout, config, rate_hz, **options)
    s, st, t = inp.signals, inp.settings, inp.t
    B, N = s.gyro.shape[:2]
    runs = []
    for b in range(B):
        f = ZhouFilter(config, inp.start.quat[b], rate_hz, layout, inp.start.theta[b], inp.start.P[b],
                       inp.start.x[b], hand0=inp.start.hand[b], sensor0=inp.start.sensor[b], rows=st.rows,
                       gate_nis=st.gate)

        def at(x: np.ndarray, k: int) -> np.ndarray | None:
            return x[b, k] if x.shape[1] > 1 else None

        for k in range(1, N):
            jac = None if s.jac_rate.shape[1] == 1 else (s.jac_rate[b, k], s.jac_d_rate[b, k], s.jac_d_rate_dot[b, k])
            force = None if s.force.shape[1] == 1 else (s.force[b, k - 1], s.force[b, k])
            f.step(float(t[k]), float(t[k] - t[k - 1]), s.gyro[b, k - 1], s.gyro[b, k], s.acc[b, k],
                   update=bool(s.update[b, k]), w_reg=s.gyro_reg[b, k], still=bool(s.still[b, k]),
                   r_var=float(s.r_var[b, k]), dtemp_c=(float(s.temp_rel[b, k - 1]), float(s.temp_rel[b, k])),
                   force=force, acc_rate=at(s.acc_rate, k), lever=at(s.lever, k), lever_jac=jac)
        runs.append(f)
    h = [f.history for f in runs]
    extra = (layout.models_temperature or layout.models_g_sensitivity or layout.models_acc_delay
             or layout.models_misalignment)
    return FilterRun(layout, np.stack([f.theta for f in runs]), np.stack([np.asarray(f.kf.P) for f in runs]),
                     np.stack([f.quat for f in runs]), np.stack([x.nis for x in h]),
                     np.stack([x.innovation for x in h]),
                     np.stack([x.sd for x in h]) if st.keep else None,
                     np.stack([x.theta for x in h]) if st.keep else None,
                     np.stack([f.hand for f in runs]) if layout.models_hand else None,
                     np.stack([f.whitened for f in runs]),
                     np.stack([f.sensor for f in runs]) if extra else None)
