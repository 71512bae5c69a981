"""The calibration filter's model: its equations, state layout, configuration and priors.

Zhou et al. 2020 §3.3 estimate gyro scale factor and non-orthogonality with a 9-state error-state
Kalman filter whose measurement is the accelerometer's gravity residual.  That assumes a
calibrated accelerometer (§3.3.2).  Here the same filter carries, when asked, the gyro bias and
the accelerometer's bias, scale factor and non-orthogonality as further states, so one session
calibrates both triads.  Frames: body RFU, navigation ENU; SI units.

**Sensor models** (the vocabulary's effects, :mod:`gyrosim.effects`; Zhou eq. 1–2):

    ω̃ = M_g ω + b_g + ε,   f̃ = M_a f + b_a + v,   M = I + diag(S) + N(G),
    N(G) = [[0, Gz, Gy], [Gz, 0, Gx], [Gy, Gx, 0]]  (symmetric, Zhou eq. 2)

with ε, v white (densities N_g rad/s/√Hz, N_a m/s²/√Hz).  The symmetric M_a is no restriction for
the accelerometer: |M_a f| = g is invariant to a rotation of the triad, so gravity can identify
only the symmetric part of a general 3×3 matrix (6 parameters) plus the bias (3): the 9 parameters
of Ferraris 1995 / Tedaldi 2014's multi-position calibration after fixing the frame.

**Nominal / error state.** The nominal (attitude Ĉ = C(q̂) body→ENU, θ̂ = [Ŝ_g, Ĝ_g, b̂_g, b̂_a, Ŝ_a, Ĝ_a])
compensates the samples, ω̂ = M̂_g⁻¹(ω̃ − b̂_g), f̂ = M̂_a⁻¹(f̃ − b̂_a), and integrates q̂ (trapezoid
+ coning, :meth:`calib.session.reference.ZhouFilter.step`).  The error state x = [φ, δθ] (blocks of
:class:`StateLayout`),
Ĉ = (I − [φ×]) C (Zhou eq. 10), δθ = θ − θ̂.  To first order (δM = diag(δS) + N(δG),
δM ω = X(ω) [δS; δG], X(ω) = [diag(ω), J_G(ω)], J_G(ω) = ∂(N(G)ω)/∂G = N with G → ω):

    δω = ω̂ − ω = M̂_g⁻¹ (X(ω̂) [δS_g; δG_g] + δb_g − ε)
    φ̇ = −Ĉ δω                                                        (Zhou eq. 7–9)
    F = [[0, −Ĉ M̂_g⁻¹ diag(ω̂), −Ĉ M̂_g⁻¹ J_G(ω̂), −Ĉ M̂_g⁻¹, 0, 0, 0], 0, …]

**Correction to Zhou eq. 9**: the paper writes [ω×] for the non-orthogonality block; for its own
symmetric N_g of eq. 2 the block is the symmetric J_G (tested).  F² = 0 (only the φ rows are
non-zero and F's φ columns are zero), so Φ = I + F Δt exactly, F at the step's midpoint.
Process noise Q_φφ = N_g² Δt I (ε isotropic: Ĉ M̂⁻¹ N_g² M̂⁻ᵀ Ĉᵀ ≈ N_g² I); the parameters are
random constants (Q = 0), except the gyro bias when ``FilterConfig.gyro_bias_rw_rad_s_sqrt_s`` > 0
(a random walk, Q_bb = q_b Δt I: the drift of a consumer gyro's bias during the session).

**Measurement** (Zhou eq. 11–12, extended): z = Ĉ f̂ − g_up, g_up = (0, 0, g):

    z = (I − [φ×]) C (f + δf) − g_up ≈ [g_up×] φ + Ĉ M̂_a⁻¹ (δb_a + X(f̂) [δS_a; δG_a]) + a + v'
    H = [[g_up×], 0, 0, 0, Ĉ M̂_a⁻¹, Ĉ M̂_a⁻¹ diag(f̂), Ĉ M̂_a⁻¹ J_G(f̂)]

a = the hand's external acceleration (nav).  Without accelerometer states (the paper's filter)
the third row of H is zero and only the two levelling rows are used; with them the vertical row
is the |f| = g check of Ferraris/Tedaldi, made at every sample and tied to the gyro's attitude.
R = (σ_f² + a_ext²) I, σ_f² = N_a² f_s per sample, a_ext the allowance for the hand (m/s² RMS).

**Regressors without the sample's own noise.** The KF derivation needs F and H independent of
the noises of the same step.  ω̂ in F is built from the very gyro samples whose noise ε drives φ
over that step; f̂ in H from the accelerometer sample whose noise v is the measurement noise.
Measured on an independent generator with a gyro noisier than the accelerometer (per step), the
filter then "learns" δS from noise at the start of every rotation (where ω ≈ ε): the innovations
of 1-s windows left their χ² band at each new rotation axis even with the true parameters as the
starting point (errors-in-variables, not divergence).  So the Jacobians use leave-out means: the
rate of step k−1 → k averaged over ±L samples around t_{k−½} *without* samples k−1 and k; the
specific force at k averaged over ±L samples without sample k (L = 0.05 s).  The nominal
integration and the measurement use the raw samples as before.  The averaging bias
(≈ ω̈ (L Δt)²/6) multiplies δθ only: second order, gone as δθ → 0.

**Reset** after every update: θ̂ += δθ̂, Ĉ ← (I + [φ̂×]) Ĉ, x ← 0.  Joseph-form covariance update,
re-symmetrised.  :class:`calib.session.reference.ZhouFilter` runs this one sample at a time (readable,
slow); :func:`calib.session.kernel.run_filter` is the same arithmetic compiled and batched (the one every
method uses; the two agree on every layout, tested).

**Adding states** (e.g. a lever arm or a coloured external acceleration): add a block name to
``BLOCKS`` (its nominal to ``THETA``, or beside it as the hand's and the sensor's extra blocks are), its
prior to :func:`initial_covariance`, its columns of F / H and its reset in both implementations
(:mod:`calib.session.kernel`, :mod:`calib.session.reference`).  The layout of any run is a :class:`StateLayout`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from gyrosim.effects import nonortho_matrix
from gyrosim.rotations import quat_normalize, skew

from calib.compat import moved_attribute

__all__ = [
    "FilterConfig",
    "FilterHistory",
    "STATE_NAMES",
    "StateLayout",
    "PAPER",
    "JOINT",
    "HAND",
    "HAND_BIAS",
    "HAND_JOINT",
    "HAND_BLOCKS",
    "THERMAL_BLOCKS",
    "G_SENS_BLOCKS",
    "ACC_THERMAL_BLOCKS",
    "SENSOR_EXTRA_BLOCKS",
    "EXT_ACC_BLOCKS",
    "EXT_ACC_EXTRA_BLOCKS",
    "HAND_BIAS_TS",
    "ACC_DELAY_BLOCKS",
    "MISALIGN_BLOCKS",
    "gyro_axis_matrix",
    "HAND_BIAS_THERMAL",
    "BLOCKS",
    "THETA",
    "jacobian_nonorthogonality",
    "nonorthogonality_jacobians",
    "ext_acc_discrete",
    "initial_covariance",
    "leave_out_means",
    "m_matrix",
    "BLOCK_LABELS",
    "theta_slice",
    "acc_theta",
    "q_mul",
    "q_exp",
    "q_unit",
    "q_matrix",
    "cross3",
]

__getattr__ = moved_attribute(__name__)   # ZhouFilter: calib.session.reference

STATE_NAMES = ("phi_x", "phi_y", "phi_z", "S_x", "S_y", "S_z", "G_x", "G_y", "G_z")

# error-state blocks (3 states each) in their fixed order; θ (the nominal parameters) has one 3-vector per block after
# "phi" after them the hand's blocks (compiled filter only, :mod:`calib.session.hand.filter`): the lever arm r (body, m;
# a constant) and the external acceleration a_e = x − z (nav, m/s²): x a first-order Gauss–Markov process ("ext_acc"), z
# its own first-order low-pass ("ext_acc_lp"), so that a_e's PSD falls to zero at 0 Hz as a bounded hand translation's
# does (z ≡ 0 when the high-pass time constant is infinite: the plain Gauss–Markov a_e); a second-order high-pass adds
# z₂, the low-pass of x − z ("ext_acc_lp2"), a_e = x − z − z₂ (z₂ ≡ 0 for the first order); their nominals live beside
# θ, not in it (θ keeps its 18 sensor parameters) then the gyro's temperature blocks (compiled filter only,
# :mod:`calib.session.hand.filter`): the bias's and the scale factor's temperature coefficients, b_g(T) = b_g + c_b (T −
# T₀), S(T) = S + s_T (T − T₀), with T the recording's own temperature channel and T₀ the filter's reference (random
# constants; nominals beside θ); last the accelerometer bias's temperature coefficient, b_a(T) = b_a + c_a (T − T₀)
# ("acc_temp_bias", kf_hand_joint)
BLOCKS = ("phi", "gyro_scale", "gyro_nonorth", "gyro_bias", "acc_bias", "acc_scale", "acc_nonorth",
          "lever_arm", "ext_acc", "ext_acc_lp", "ext_acc_lp2", "gyro_temp_bias", "gyro_temp_scale",
          "gyro_g_sens", "ext_acc_s3", "ext_acc_s4", "ext_acc_s5", "ext_acc_s6", "ext_acc_s7", "ext_acc_s8",
          "acc_temp_bias", "acc_delay", "gyro_misalign")
THETA = BLOCKS[1:7]
HAND_BLOCKS = BLOCKS[7:11]
THERMAL_BLOCKS = BLOCKS[11:13]
G_SENS_BLOCKS = BLOCKS[13:14]   # the gyro's g-sensitivity, diagonal K = diag(k) (rad/s per m/s²): b_g,i += k_i f_i
# a band-limited sway (FilterConfig.ext_acc_band_hz): a_e per nav axis is a general shaping filter (A, B, C) of
# up to nine states, component i of axis j at offset(EXT_ACC_BLOCKS[i]) + j (FilterConfig.ext_acc_model)
EXT_ACC_EXTRA_BLOCKS = tuple(f"ext_acc_s{i}" for i in range(3, 9))     # by name: blocks added to BLOCKS later keep it
EXT_ACC_BLOCKS = ("ext_acc", "ext_acc_lp", "ext_acc_lp2") + EXT_ACC_EXTRA_BLOCKS
assert all(b in BLOCKS for b in EXT_ACC_BLOCKS)
# the accelerometer bias's temperature coefficient c_a (m/s²/°C): b_a += c_a (T − T₀)
ACC_THERMAL_BLOCKS = ("acc_temp_bias",)
assert all(b in BLOCKS for b in ACC_THERMAL_BLOCKS)
# the accelerometer's delay behind the gyro, one state per axis, δ_i (s): f̃_i(t) = f_i(t − δ_i), to first order
# f_i(t) = f̃_i(t) + δ_i ḟ̃_i(t) — two sensors' anti-alias filters of different bandwidth (MPU-9250: 41 Hz gyro,
# 44.8 Hz accelerometer DLPF) or a sampling skew; kf_hand ties the three into one δ with a rank-one prior
# (calib.session.hand.priors.common_delay_prior)
ACC_DELAY_BLOCKS = ("acc_delay",)
assert all(b in BLOCKS for b in ACC_DELAY_BLOCKS)
# the gyro triad's rotation against the accelerometer's, α (rad, about the body axes; gyrosim.effects.
# GyroAccMisalignment): ω̃ = (M_g − [α×]) ω + b_g — the antisymmetric part of the gyro's axis matrix that the symmetric
# S, N(G) cannot hold.  The body frame is the accelerometer's (gravity fixes it), so α is observable once the session
# turns about two axes that gravity does not hide; δω = M̂⁻¹ [ω×] δα (−[δα×] ω = ω × δα)
MISALIGN_BLOCKS = ("gyro_misalign",)
assert all(b in BLOCKS for b in MISALIGN_BLOCKS)
# their nominals: calib.session.kernel.FilterRun.sensor_extra (c_b, s_T, k, c_a, δ, α)
SENSOR_EXTRA_BLOCKS = THERMAL_BLOCKS + G_SENS_BLOCKS + ACC_THERMAL_BLOCKS + ACC_DELAY_BLOCKS + MISALIGN_BLOCKS
_SHORT = {
    "phi": "phi",
    "gyro_scale": "S",
    "gyro_nonorth": "G",
    "gyro_bias": "bg",
    "acc_bias": "ba",
    "acc_scale": "Sa",
    "acc_nonorth": "Ga",
    "lever_arm": "r",
    "ext_acc": "ae",
    "ext_acc_lp": "ael",
    "ext_acc_lp2": "ael2",
    "gyro_temp_bias": "cb",
    "gyro_temp_scale": "sT",
    "gyro_g_sens": "kg",
    **{f"ext_acc_s{i}": f"ae{i}" for i in range(3, 9)},
    "acc_temp_bias": "ca",
    "acc_delay": "dt",
    "gyro_misalign": "al",
}
BLOCK_LABELS = {"phi": "attitude error", "gyro_scale": "gyro scale factor", "gyro_nonorth": "gyro non-orthogonality",
                "gyro_bias": "gyro bias", "acc_bias": "accelerometer bias", "acc_scale": "accelerometer scale factor",
                "acc_nonorth": "accelerometer non-orthogonality", "lever_arm": "lever arm",
                "ext_acc": "external acceleration", "ext_acc_lp": "external acceleration's low-pass",
                "ext_acc_lp2": "external acceleration's second low-pass",
                "gyro_temp_bias": "gyro bias temperature coefficient",
                "gyro_temp_scale": "gyro scale factor temperature coefficient",
                "gyro_g_sens": "gyro g-sensitivity (diagonal)",
                **{f"ext_acc_s{i}": f"external acceleration's band-pass state {i}" for i in range(3, 9)},
                "acc_temp_bias": "accelerometer bias temperature coefficient",
                "acc_delay": "accelerometer delay behind the gyro",
                "gyro_misalign": "gyro-to-accelerometer misalignment"}
# (triad, vocabulary effect kind) of each parameter block
BLOCK_EFFECT = {"gyro_scale": ("gyro", "scale_factor"), "gyro_nonorth": ("gyro", "nonorthogonality"),
                "gyro_bias": ("gyro", "bias"), "acc_bias": ("accelerometer", "bias"),
                "acc_scale": ("accelerometer", "scale_factor"), "acc_nonorth": ("accelerometer", "nonorthogonality")}


@dataclass(frozen=True)
class StateLayout:
    """Which error-state blocks a filter carries (always "phi", "gyro_scale", "gyro_nonorth" first)."""

    blocks: tuple[str, ...]

    def __post_init__(self) -> None:
        if self.blocks[:3] != BLOCKS[:3]:
            raise ValueError(f"a layout starts with {BLOCKS[:3]}, got {self.blocks[:3]}")
        bad = [b for b in self.blocks if b not in BLOCKS]
        if bad or list(self.blocks) != sorted(self.blocks, key=BLOCKS.index):
            raise ValueError(f"layout blocks must be a subsequence of {BLOCKS}, got {self.blocks}")

    @property
    def n(self) -> int:
        return 3 * len(self.blocks)

    def has(self, block: str) -> bool:
        return block in self.blocks

    def offset(self, block: str) -> int:
        """First state index of ``block``, −1 if the layout lacks it."""
        return 3 * self.blocks.index(block) if block in self.blocks else -1

    def offsets(self) -> np.ndarray:
        """Offset of every block of ``BLOCKS`` (−1 where absent), for the compiled kernel."""
        return np.array([self.offset(b) for b in BLOCKS], dtype=np.int64)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(f"{_SHORT[b]}_{a}" for b in self.blocks for a in "xyz")

    @property
    def estimates_accelerometer(self) -> bool:
        return self.has("acc_bias")

    @property
    def models_hand(self) -> bool:
        return self.has("lever_arm") or self.has("ext_acc")

    @property
    def models_temperature(self) -> bool:
        return self.has("gyro_temp_bias") or self.has("gyro_temp_scale") or self.has("acc_temp_bias")

    @property
    def models_g_sensitivity(self) -> bool:
        return self.has("gyro_g_sens")

    @property
    def models_acc_delay(self) -> bool:
        return self.has("acc_delay")

    @property
    def models_misalignment(self) -> bool:
        return self.has("gyro_misalign")


PAPER = StateLayout(BLOCKS[:3])          # Zhou 2020's 9 states (calibrated accelerometer, static bias)
JOINT = StateLayout(BLOCKS[:7])          # + gyro bias and the accelerometer's 9 parameters: 21 states
HAND = StateLayout(BLOCKS[:3] + HAND_BLOCKS)  # the paper's 9 + lever arm + external acceleration (x, z, z₂): 21 states
HAND_BIAS = StateLayout(BLOCKS[:4] + HAND_BLOCKS)  # kf_hand: HAND + the gyro bias (a random walk): 24 states
# kf_hand on a recording whose temperature moved: + the scale factor's temperature coefficient s_T: 27 states
HAND_BIAS_TS = StateLayout(BLOCKS[:4] + HAND_BLOCKS + ("gyro_temp_scale",))
HAND_BIAS_THERMAL = StateLayout(BLOCKS[:4] + HAND_BLOCKS + THERMAL_BLOCKS)   # + c_b too: 30 states
HAND_JOINT = StateLayout(BLOCKS[:11])    # kf_hand_joint: HAND_BIAS + the accelerometer's 9 parameters: 33 states


def theta_slice(block: str) -> slice:
    """Where ``block``'s nominal sits in θ (18, ``THETA`` order)."""
    i = THETA.index(block)
    return slice(3 * i, 3 * i + 3)


def acc_theta(theta: np.ndarray) -> np.ndarray:
    """θ_a = [b_a, S_a, G_a] (9,) of an 18-vector θ (``THETA`` order): the accelerometer's part, as
    :func:`calib.session.gravityfit.compensate_acc` takes it."""
    return np.concatenate([theta[theta_slice("acc_bias")], theta[theta_slice("acc_scale")],
                           theta[theta_slice("acc_nonorth")]])


# ---- single-quaternion helpers for the per-sample reference filter (the vectorised gyrosim.rotations versions
#      cost ~10 µs of array bookkeeping per call on one vector); the compiled kernel has its own
def q_mul(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """p ⊗ q of two quaternions (w, x, y, z)."""
    pw, px, py, pz = p
    qw, qx, qy, qz = q
    return np.array([pw * qw - px * qx - py * qy - pz * qz, pw * qx + px * qw + py * qz - pz * qy,
                     pw * qy - px * qz + py * qw + pz * qx, pw * qz + px * qy - py * qx + pz * qw])


def q_exp(v: np.ndarray) -> np.ndarray:
    """Exp(v): the unit quaternion of the rotation vector ``v`` (rad; series below 1e-6 rad)."""
    th = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    k = 0.5 - th * th / 48.0 if th < 1e-6 else math.sin(0.5 * th) / th
    return np.array([math.cos(0.5 * th), k * v[0], k * v[1], k * v[2]])


def q_unit(q: np.ndarray) -> np.ndarray:
    """``q`` normalised to unit length."""
    return q / math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])


def q_matrix(q: np.ndarray) -> np.ndarray:
    """C(q) (3, 3), body → navigation, of a unit quaternion."""
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a × b of two 3-vectors."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def jacobian_nonorthogonality(omega: np.ndarray) -> np.ndarray:
    """J_G(ω) = ∂(N(G) ω)/∂G: the same symmetric pattern as N with G → ω (see module docstring)."""
    return nonortho_matrix(np.asarray(omega, dtype=float))


def nonorthogonality_jacobians(w: np.ndarray) -> np.ndarray:
    """J_G(ω) of every row of ``w`` (B, 3) → (B, 3, 3) (:func:`jacobian_nonorthogonality`, vectorised)."""
    z = np.zeros(w.shape[0])
    wx, wy, wz = w[:, 0], w[:, 1], w[:, 2]
    return np.stack([np.stack([z, wz, wy], -1), np.stack([wz, z, wx], -1), np.stack([wy, wx, z], -1)], -2)


def m_matrix(scale: np.ndarray, nonortho: np.ndarray) -> np.ndarray:
    """M = I + diag(S) + N(G)."""
    return np.eye(3) + np.diag(scale) + nonortho_matrix(np.asarray(nonortho, float))


def gyro_axis_matrix(scale: np.ndarray, nonortho: np.ndarray, misalign_rad: np.ndarray | None = None) -> np.ndarray:
    """The gyro's axis matrix M_g = I + diag(S) + N(G) − [α×] (α: the gyro-to-accelerometer misalignment, rad)."""
    m = m_matrix(scale, nonortho)
    return m if misalign_rad is None else m - skew(np.asarray(misalign_rad, float))


def leave_out_means(x: np.ndarray, half_window: int, midpoint: bool) -> np.ndarray:
    """Regressors without the samples' own noise (module docstring), (N, 3).

    ``midpoint``: row k is the mean of x over [k−1−L, k−2] ∪ [k+1, k+L] (centred at t_{k−½}, the
    step k−1 → k, without samples k−1 and k); else over [k−L, k−1] ∪ [k+1, k+L] (centred at t_k,
    without sample k).  Windows are cut at the ends of the record.
    """
    x = np.asarray(x, dtype=float)
    n, L = x.shape[0], int(half_window)
    c = np.concatenate([np.zeros((1,) + x.shape[1:]), np.cumsum(x, axis=0)])
    k = np.arange(n)
    lo_end = np.clip(k - 1 if midpoint else k, 0, n)          # exclusive end of the left part
    lo_start = np.clip(lo_end - L, 0, n)
    hi_start = np.clip(k + 1, 0, n)
    hi_end = np.clip(k + 1 + L, 0, n)
    s = (c[lo_end] - c[lo_start]) + (c[hi_end] - c[hi_start])
    m = (lo_end - lo_start) + (hi_end - hi_start)
    out = s / np.maximum(m, 1)[:, None]
    empty = m == 0
    out[empty] = x[empty]
    return out


@dataclass(frozen=True)
class FilterConfig:
    """Noise and prior of the filter (SI). Paper §5.1: P₀ = diag(3°, 3°, 3°, 0.05 × 6)².

    The accelerometer and gyro-bias priors apply when the layout has those blocks:
    ``prior_gyro_bias_rad_s`` is the static bias's standard error (per axis), the accelerometer
    priors span consumer parts (±100 mg bias, ±5 % scale and axis errors at 1σ).  The hand's blocks
    (:data:`HAND`): the lever arm's prior σ ``prior_lever_arm_m`` (a wrist 30 cm away covers any hand-held
    grip), and the external acceleration a first-order Gauss–Markov process per nav axis with
    stationary RMS ``ext_acc_rms_m_s2`` and time constant ``ext_acc_tau_s`` (:mod:`calib.session.hand.filter`).
    ``ext_acc_highpass_tau_s`` τ_h, ``ext_acc_highpass_order`` m (1 or 2): a_e = x − z (− z₂), ż = (x − z)/τ_h,
    ż₂ = (x − z − z₂)/τ_h (∞: a_e = x, the plain Gauss–Markov process); the one-sided PSD of a_e is
    4σ²τ/(1 + (2πfτ)²) · [(2πfτ_h)²/(1 + (2πfτ_h)²)]^m.
    ``gyro_bias_rw_rad_s_sqrt_s``: with a ``gyro_bias`` block, the bias is a random walk,
    ḃ_g = w_b, E[w_b w_bᵀ] = q_b I δ(t), q_b = this² (rad²/s³): Q_bb = q_b Δt per step (IEEE 952's rate
    random walk K; 0: a random constant, the paper's model).
    ``prior_gyro_temp_bias_rad_s_c``, ``prior_gyro_temp_scale_per_c``: prior σ of the temperature blocks
    (rad/s/°C, 1/°C; 0.01 each: vague — 0.6 °/s/°C and 1 %/°C, thirty times a consumer MEMS gyro's datasheet
    spread — so that the session's data, not a sensor's datasheet, decides them).
    ``prior_acc_temp_bias_m_s2_c``: prior σ of the accelerometer bias's temperature coefficient c_a (m/s²/°C;
    0.1: vague, ~10 mg/°C, seven times the MPU-9250's ±1.5 mg/°C datasheet limit).
    """

    arw_rad_s_sqrt_hz: float
    vrw_m_s2_sqrt_hz: float
    external_acc_allowance_m_s2: float = 0.0
    gravity_m_s2: float = 9.80665
    prior_attitude_rad: float = math.radians(3.0)
    prior_scale: float = 0.05
    prior_nonorthogonality: float = 0.05
    scale0: tuple[float, float, float] = (0.0, 0.0, 0.0)
    nonorthogonality0: tuple[float, float, float] = (0.0, 0.0, 0.0)
    prior_gyro_bias_rad_s: tuple[float, float, float] = (1e-3, 1e-3, 1e-3)
    prior_acc_bias_m_s2: float = 1.0
    prior_acc_scale: float = 0.05
    prior_acc_nonorthogonality: float = 0.05
    prior_lever_arm_m: float = 0.3
    ext_acc_rms_m_s2: float = 0.0
    ext_acc_tau_s: float = 1.0
    gyro_bias_rw_rad_s_sqrt_s: float = 0.0
    ext_acc_highpass_tau_s: float = math.inf
    ext_acc_highpass_order: int = 1
    prior_gyro_temp_bias_rad_s_c: float = 0.01
    prior_gyro_temp_scale_per_c: float = 0.01
    prior_gyro_g_sens_rad_s_per_m_s2: float = 1e-3
    prior_acc_temp_bias_m_s2_c: float = 0.1
    prior_acc_delay_s: float = 0.01
    prior_gyro_misalign_rad: float = 0.035   # 2°: an assembly's rotation between two dies or chips (1° typical)
    ext_acc_band_hz: tuple[float, float] | None = None
    ext_acc_band_rms_m_s2: float = 0.0
    ext_acc_band_order: int = 2

    def ext_acc_model(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The continuous shaping filter of one nav axis of a_e: (A (d, d), Q_c (d, d), C (d,)) with
        ẋ = A x + w, E w(t) w(s)ᵀ = Q_c δ(t − s), a_e = C x.

        Without ``ext_acc_band_hz``: the Gauss–Markov x (σ = ``ext_acc_rms_m_s2``, τ = ``ext_acc_tau_s``),
        high-passed by ż = (x − z)/τ_h (, ż₂ = (x − z − z₂)/τ_h) as documented on the class.  With
        ``ext_acc_band_hz`` = (f₁, f₂): a broadband Gauss–Markov floor x₀ (σ₀ = ``ext_acc_rms_m_s2``,
        τ₀ = ``ext_acc_tau_s``, no high-pass) plus an analog Butterworth band-pass of ``ext_acc_band_order`` poles
        per edge (2N states) driven by white noise, scaled so that the band component's RMS is
        ``ext_acc_band_rms_m_s2``: one-sided PSD

            S_a(f) = 4σ₀²τ₀ / (1 + (2πfτ₀)²) + S_b / (1 + ((f² − f₁f₂) / (f (f₂ − f₁)))^{2N})

        (the band-pass's |H|² from its low-pass prototype, Butterworth 1930; S_b its in-band level) — a sway
        concentrated in a band with steep skirts, which the high-passed Gauss–Markov family could not follow
        (docs/hand.md, "The sway model").  State 0 is the floor (``ext_acc``), 1 … 2N the band-pass's."""
        tau, s2 = self.ext_acc_tau_s, self.ext_acc_rms_m_s2**2
        if self.ext_acc_band_hz is None:
            th = self.ext_acc_highpass_tau_s
            k = 1 if not math.isfinite(th) else 1 + int(self.ext_acc_highpass_order)
            a = np.zeros((k, k))
            a[0, 0] = -1.0 / tau
            for i in range(1, k):
                a[i, 0] = 1.0 / th
                a[i, 1:i + 1] = -1.0 / th
            q = np.zeros((k, k))
            q[0, 0] = 2.0 * s2 / tau
            return a, q, np.array([1.0] + [-1.0] * (k - 1))
        ab, bb, cb = _butter_band_ss(float(self.ext_acc_band_hz[0]), float(self.ext_acc_band_hz[1]),
                                     int(self.ext_acc_band_order))
        d = 1 + ab.shape[0]
        a = np.zeros((d, d))
        a[0, 0] = -1.0 / tau
        a[1:, 1:] = ab
        q = np.zeros((d, d))
        q[0, 0] = 2.0 * s2 / tau
        qb = np.outer(bb, bb)
        from scipy.linalg import solve_continuous_lyapunov
        v1 = float(cb @ solve_continuous_lyapunov(ab, -qb) @ cb)      # the band's variance for unit white input
        q[1:, 1:] = qb * (self.ext_acc_band_rms_m_s2**2 / max(v1, 1e-300))
        return a, q, np.concatenate([[1.0], cb])

    def r_var(self, rate_hz: float) -> float:
        """R per axis, (m/s²)²: σ_f² + a_ext²."""
        return self.vrw_m_s2_sqrt_hz**2 * rate_hz + self.external_acc_allowance_m_s2**2

    def prior_sigma(self, block: str) -> np.ndarray:
        return {"phi": np.full(3, self.prior_attitude_rad), "gyro_scale": np.full(3, self.prior_scale),
                "gyro_nonorth": np.full(3, self.prior_nonorthogonality),
                "gyro_bias": np.asarray(self.prior_gyro_bias_rad_s, float),
                "acc_bias": np.full(3, self.prior_acc_bias_m_s2), "acc_scale": np.full(3, self.prior_acc_scale),
                "acc_nonorth": np.full(3, self.prior_acc_nonorthogonality),
                "lever_arm": np.full(3, self.prior_lever_arm_m),
                "ext_acc": np.full(3, self.ext_acc_rms_m_s2),
                "ext_acc_lp": np.zeros(3), "ext_acc_lp2": np.zeros(3),
                **{b: np.zeros(3) for b in EXT_ACC_EXTRA_BLOCKS},
                "gyro_temp_bias": np.full(3, self.prior_gyro_temp_bias_rad_s_c),
                "gyro_temp_scale": np.full(3, self.prior_gyro_temp_scale_per_c),
                "gyro_g_sens": np.full(3, self.prior_gyro_g_sens_rad_s_per_m_s2),
                "acc_temp_bias": np.full(3, self.prior_acc_temp_bias_m_s2_c),
                "acc_delay": np.full(3, self.prior_acc_delay_s),
                "gyro_misalign": np.full(3, self.prior_gyro_misalign_rad)}[block]   # with ext_acc: ext_acc_stationary

    def ext_acc_stationary(self) -> np.ndarray:
        """Stationary covariance (k, k) of one nav axis's (x, z[, z₂]) (k = 1 + high-pass order; k = 1 for
        τ_h = ∞): the continuous Lyapunov equation A Σ + Σ Aᵀ + Q = 0 of ẋ = −x/τ + w (E w² = 2σ²/τ),
        ż = (x − z)/τ_h, ż₂ = (x − z − z₂)/τ_h (Gelb 1974, §4.4).  a_e = x − z − z₂ has variance vΣvᵀ,
        v = (1, −1, −1)."""
        from scipy.linalg import solve_continuous_lyapunov

        if not math.isfinite(self.ext_acc_highpass_tau_s) and self.ext_acc_band_hz is None:
            return np.array([[self.ext_acc_rms_m_s2**2]])
        a, q, _ = self.ext_acc_model()      # with a band: the same equation for the floor + band-pass states
        return solve_continuous_lyapunov(a, -q)

    @property
    def ext_acc_rms_a_m_s2(self) -> float:
        """RMS of one axis of a_e = C x (:meth:`ext_acc_stationary`, :meth:`ext_acc_model`)."""
        c = self.ext_acc_stationary()
        v = self.ext_acc_model()[2][:c.shape[0]]
        return float(math.sqrt(max(v @ c @ v, 0.0)))


def _butter_band_ss(f1_hz: float, f2_hz: float, order: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """State space (A (2N, 2N), B (2N,), C (2N,)) of the analog Butterworth band-pass f₁ … f₂ (Hz) of N poles per
    edge, |H| = 1 at √(f₁f₂) (scipy.signal.butter's analog band-pass transformation), in a balanced modal form:
    the real block-diagonal form of A (one 2 × 2 block per pole pair, scipy.linalg.cdf2rdf) with every state
    scaled to unit stationary variance for unit white input.  The controllable canonical form that zpk2ss gives
    has states ω⁰ … ω⁷ apart in scale (10⁵ at 1 Hz): the filter's covariance lost its precision and the filter
    diverged (measured: NIS 12 against 2)."""
    from scipy import signal as sps
    from scipy.linalg import cdf2rdf, solve_continuous_lyapunov

    z, p, k = sps.butter(order, [2 * math.pi * f1_hz, 2 * math.pi * f2_hz], btype="bandpass", analog=True, output="zpk")
    a, b, c, _ = sps.zpk2ss(z, p, k)
    w, v = np.linalg.eig(a)
    wr, vr = cdf2rdf(w, v)
    ti = np.linalg.inv(vr)
    a, b, c = wr, (ti @ b)[:, 0].real, (c @ vr)[0].real
    sd = np.sqrt(np.diag(solve_continuous_lyapunov(a, -np.outer(b, b))))
    return a * sd[None, :] / sd[:, None], b / sd, c * sd


def ext_acc_discrete(a: np.ndarray, qc: np.ndarray, dt_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Exact discretisation (Φ (U, d, d), Q_d (U, d, d)) of ẋ = A x + w, E w wᵀ = Q_c δ, over the steps
    ``dt_s`` (U,): Φ = e^{AΔt}, Q_d = ∫₀^Δt e^{As} Q_c e^{Aᵀs} ds, both from one matrix exponential of Van Loan's
    block [[−A, Q_c], [0, Aᵀ]]Δt (Van Loan 1978, IEEE TAC 23(3); Brown & Hwang 4th ed. §3.9)."""
    from scipy.linalg import expm

    d = a.shape[0]
    m = np.zeros((2 * d, 2 * d))
    m[:d, :d] = -a
    m[:d, d:] = qc
    m[d:, d:] = a.T
    e = expm(np.asarray(dt_s, float)[:, None, None] * m[None])
    phi = np.transpose(e[:, d:, d:], (0, 2, 1))
    q = phi @ e[:, :d, d:]
    return phi, 0.5 * (q + np.transpose(q, (0, 2, 1)))


def initial_covariance(layout: StateLayout, config: FilterConfig, quat0_nb: np.ndarray | None = None,
                       f0_body: np.ndarray | None = None, acc_m_inv: np.ndarray | None = None,
                       acc_covariance: np.ndarray | None = None, tilt_sigma_rad: float | None = None) -> np.ndarray:
    """P₀ (n, n): independent priors of the blocks, and — with accelerometer states — the tilt's
    dependence on them.

    The initial attitude comes from the accelerometer at rest, f̂₀ = M̂_a⁻¹(f̃₀ − b̂_a), so its
    roll/pitch error is not independent of the accelerometer error δf₀ = M̂_a⁻¹(δb_a + X(f̂₀)[δS_a; δG_a]):
    levelling Ĉ₀ f̂₀ ∥ g_up makes the horizontal part of [g_up×]φ₀ + Ĉ₀ δf₀ vanish, so
    φ₀ = [g_up×] Ĉ₀ δf₀ / g² + n₀ = A δθ_a + n₀.  P₀ carries that: P_φφ = A P_a Aᵀ + diag(σ_φ²),
    P_φa = A P_a.  n₀: roll and pitch ``tilt_sigma_rad`` — the noise of the rest mean, when the filter
    starts after that rest and so does not see its samples again — else the paper's 3°; heading 3°
    (unobservable).  ``acc_covariance`` (9, 9): P_a from the |f| = g stage (:mod:`calib.session.gravityfit`)
    instead of the independent priors.
    """
    n = layout.n
    p = np.zeros((n, n))
    for b in layout.blocks:
        o = layout.offset(b)
        p[o:o + 3, o:o + 3] = np.diag(config.prior_sigma(b) ** 2)
    if layout.has("ext_acc"):                    # (x, z, z₂) start stationary (FilterConfig.ext_acc_stationary)
        c = config.ext_acc_stationary()
        idx = [layout.offset(b) for b in EXT_ACC_BLOCKS][:c.shape[0]]
        for j in range(3):
            for u, ou in enumerate(idx):
                for v, ov in enumerate(idx):
                    if ou >= 0 and ov >= 0:
                        p[ou + j, ov + j] = c[u, v]
    if tilt_sigma_rad is not None:
        p[0, 0] = p[1, 1] = tilt_sigma_rad**2
    if layout.estimates_accelerometer and acc_covariance is not None:
        oa = layout.offset("acc_bias")
        p[oa:oa + 9, oa:oa + 9] = acc_covariance
    if layout.estimates_accelerometer and quat0_nb is not None and f0_body is not None:
        c0 = q_matrix(quat_normalize(np.asarray(quat0_nb, float)))
        mi = np.eye(3) if acc_m_inv is None else acc_m_inv
        g = config.gravity_m_s2
        cm = c0 @ mi
        x_a = np.hstack([cm, cm * f0_body[None, :], cm @ jacobian_nonorthogonality(f0_body)])  # (3, 9)
        a = skew(np.array([0.0, 0.0, g])) @ x_a / g**2
        oa = layout.offset("acc_bias")
        cols = slice(oa, oa + 9)
        pa = p[cols, cols]
        p[0:3, 0:3] += a @ pa @ a.T
        p[0:3, cols] = a @ pa
        p[cols, 0:3] = (a @ pa).T
    return p


@dataclass
class FilterHistory:
    """Per-sample record of a run (for rerun and diagnostics): times (s), √P per state, the nominal
    parameters θ̂ (``THETA`` order, 18), innovations (m/s², nav) and NIS; P after each update."""

    t_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    sd: np.ndarray = field(default_factory=lambda: np.zeros((0, 9)))
    theta: np.ndarray = field(default_factory=lambda: np.zeros((0, 18)))
    innovation: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    nis: np.ndarray = field(default_factory=lambda: np.zeros(0))
    state_names: tuple[str, ...] = STATE_NAMES

    def arrays(self) -> dict[str, np.ndarray]:
        th = np.asarray(self.theta)
        return {
            "t_s": np.asarray(self.t_s),
            "p_diag": np.asarray(self.sd) ** 2,
            "sd": np.asarray(self.sd),
            "scale": th[:, theta_slice("gyro_scale")],
            "nonorthogonality": th[:, theta_slice("gyro_nonorth")],
            "gyro_bias": th[:, theta_slice("gyro_bias")],
            "acc_bias": th[:, theta_slice("acc_bias")],
            "acc_scale": th[:, theta_slice("acc_scale")],
            "acc_nonorthogonality": th[:, theta_slice("acc_nonorth")],
            "innovation": np.asarray(self.innovation),
            "nis": np.asarray(self.nis),
        }
