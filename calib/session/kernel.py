"""The calibration filter of :mod:`calib.session.model`, compiled (numba) and batched over B runs.

Same equations and order as the readable reference (:mod:`calib.session.reference`; every layout is tested
against it); the error state is reset after each update, so the predicted state is zero and the innovation is z
itself (before the first update the error state carries the prior's mean x₀).  The structure keeps each step O(n²)
for n states:

* propagation: Φ = I + E with E non-zero only in the three φ rows (the gyro-parameter columns), so
  Φ P Φᵀ = P + E P + (E P)ᵀ + E P Eᵀ with E P a 3 × n product; the external acceleration's shaping filter
  (the hand's blocks) is propagated on its own rows and columns first;
* update: H has non-zero entries only in the φ_x, φ_y columns, the accelerometer's, the hand's and the lever
  arm term's gyro columns (stored by column: ``H_COLS`` at most); the Joseph form (I − K H) P (I − K H)ᵀ + K R Kᵀ
  is evaluated as T = P − K (H P), T − (T Hᵀ) Kᵀ + K R Kᵀ — the same products as the dense form, in O(n² m) for m
  measurement rows.

A step costs ~2 µs for the paper's 9 states and ~5 µs for the 21 joint states, against ~160 µs of
numpy calls on small arrays in the filterpy filter (``calib bench``).

**How the arguments travel.**  :func:`run_filter` (the Python entry point) checks and broadcasts its arguments
into four typed tuples, which the compiled loop :func:`_kernel` reads by name:

* :class:`Signals` — the samples of each run and their regressors, (B, N, …);
* :class:`Start` — each run's initial nominal (attitude, θ, the hand's and the sensor's extra nominals),
  error-state mean and covariance;
* :class:`Settings` — the layout's block offsets and the noise model's numbers;
* :class:`Shaping` — the external acceleration's general shaping filter, discretised per step;

and :class:`RecordArrays` (the first run's linear error model, for :mod:`calib.session.spectral`).  Each step of
the loop is a small compiled helper — ``_step_nominal`` (the attitude), ``_transition`` (Φ's φ rows),
``_propagate_gauss_markov`` / ``_propagate_shaping`` (a_e), ``_propagate_attitude_rows`` (P), ``_corrected_force``
and ``_residual`` (z), ``_measurement`` (H), ``_innovation``, ``_update_covariance`` (Joseph), ``_inject`` (the reset)
— so the loop reads as the filter's steps; a helper reads a block's per-sample regressor only when the layout has
the block (the others are (B, 1, …) placeholders).

**Compile time.**  numba compiles the loop once per machine (``cache=True``; the helpers' code is linked into it, so
only :func:`_kernel` is cached) and most of that time is numba typing and lowering each function and each numpy
construct it meets.  So the helpers are written in scalars: quaternions and 3-vectors are tuples, 3 × 3 products
are written out (:func:`_nb_mv`, :func:`_nb_matmul`) into scratch arrays the loop allocates once — no array
allocated per step, no ``@`` (BLAS), no array expressions, no slice assignment (whose shape check compiles an error
message with string formatting), no literal constant arguments (each compiles a specialisation of its own).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numba import njit

from calib.compat import moved_attribute
from calib.session.model import (
    EXT_ACC_BLOCKS,
    PAPER,
    SENSOR_EXTRA_BLOCKS,
    FilterConfig,
    StateLayout,
    ext_acc_discrete,
    initial_covariance,
    leave_out_means,
    theta_slice,
)

# the update's H, its non-zero columns at most: φ 2 + accelerometer 9 + c_a 3 + δ 3 + lever arm 3 + a_e ≤ 27 + the lever
# arm term's gyro columns (S, G, b, c_b, s_T, k) 18
H_COLS = 65
E_COLS = 21   # Φ's φ rows: S, G, b, c_b, s_T, k, α
HAND_NOMINALS = 3 + 3 * len(EXT_ACC_BLOCKS)   # the lever arm, then a_e's shaping-filter states (3 per component)
SENSOR_NOMINALS = 3 * len(SENSOR_EXTRA_BLOCKS)  # c_b, s_T, k, c_a, δ (calib.session.model.SENSOR_EXTRA_BLOCKS)

__all__ = ["BatchResult", "FilterRecord", "FilterRun", "LeverJacobian", "Signals", "Start", "Settings", "Shaping",
           "RecordArrays", "FilterInputs", "filter_inputs", "run_batch", "run_filter", "regressor_half_window",
           "ext_acc_discrete", "HAND_NOMINALS", "SENSOR_NOMINALS", "warm_up"]


__getattr__ = moved_attribute(__name__)   # crlb, crlb_joint: calib.session.bounds


def regressor_half_window(rate_hz: float) -> int:
    """L of the leave-out regressors (:func:`calib.session.model.leave_out_means`): 0.05 s, at least 2 samples."""
    return max(2, int(round(0.05 * rate_hz)))


# ---------------------------------------------------------------------------------------------------------------------
# the compiled loop's arguments


class Signals(NamedTuple):
    """Per run b and sample k: the raw samples and the regressors the layout's blocks need.  A block's regressor
    is a (B, 1, …) placeholder when the layout lacks the block."""

    gyro: np.ndarray            # (B, N, 3) raw gyro, rad/s, body
    acc: np.ndarray             # (B, N, 3) raw accelerometer, m/s², body
    gyro_reg: np.ndarray        # (B, N, 3) leave-out rate regressor at t_{k−½} (calib.session.model, "Regressors")
    still: np.ndarray           # (B, N) bool: the step k−1 → k lies in a rest (the rate regressor is zero)
    update: np.ndarray          # (B, N) bool: update with sample k
    r_var: np.ndarray           # (B, N) measurement variance per axis, (m/s²)²
    temp_rel: np.ndarray        # (B, N) T − T₀, °C (zeros without a temperature block)
    force: np.ndarray           # (B, N | 1, 3) specific force f, body, m/s² (g-sensitivity)
    acc_rate: np.ndarray        # (B, N | 1, 3) ḟ̃, body, m/s³ (the accelerometer's delay)
    lever: np.ndarray           # (B, N | 1, 3, 3) K(ω, ω̇) = [ω̇×] + [ω×]², body (the lever arm)
    jac_rate: np.ndarray        # (B, N | 1, 3) LeverJacobian.rate_rad_s
    jac_d_rate: np.ndarray      # (B, N | 1, 3, 9 | 12) LeverJacobian.d_rate
    jac_d_rate_dot: np.ndarray  # (B, N | 1, 3, 9 | 12) LeverJacobian.d_rate_dot


class Start(NamedTuple):
    """Each run's start: nominal attitude, parameters and extra nominals, the error state's mean and covariance."""

    quat: np.ndarray            # (B, 4) body→ENU
    theta: np.ndarray           # (B, 18) nominal parameters (THETA order)
    x: np.ndarray               # (B, n) the prior's mean as an error state, θ_prior − θ̂₀
    P: np.ndarray               # (B, n, n)
    hand: np.ndarray            # (B, HAND_NOMINALS) lever arm, then a_e's shaping-filter states (i, axis j: 3 + 3i + j)
    sensor: np.ndarray          # (B, SENSOR_NOMINALS) c_b, s_T, k, c_a, δ, α


class Settings(NamedTuple):
    """The layout's offsets and the noise model's numbers (scalars of :class:`calib.session.model.FilterConfig`)."""

    offsets: np.ndarray         # (len(BLOCKS),) first state of each block, −1 where absent (StateLayout.offsets)
    sensor_offsets: np.ndarray  # (6,) offsets of SENSOR_EXTRA_BLOCKS
    arw2: float                 # N_g², (rad/s)²/Hz: Q_φφ = N_g² Δt
    bias_rw2: float             # q_b, rad²/s³: Q_bb = q_b Δt
    gravity: float              # g, m/s²
    gm_tau: float               # a_e's Gauss–Markov τ, s
    gm_var: float               # its stationary variance σ², (m/s²)²
    hp_tau: float               # its high-pass τ_h, s (inf: none)
    hp_order: int               # 1 or 2 (z, z₂)
    rows: int                   # measurement rows: 2 (levelling) or 3 (+ vertical)
    gate: float                 # skip an update whose NIS exceeds this (0: never)
    keep: bool                  # keep the per-step history of √diag P and θ̂
    record: bool                # record the first run's linear error model (RecordArrays)


class Shaping(NamedTuple):
    """a_e's general shaping filter per nav axis (``d`` > 0 replaces the x, z, z₂ code): ẋ = A x + w, a_e = C x,
    discretised exactly once per distinct step (:func:`calib.session.model.ext_acc_discrete`)."""

    d: int                      # states per axis (0: the Gauss–Markov x, z, z₂ code)
    offsets: np.ndarray         # (9,) offset of component i's block (EXT_ACC_BLOCKS)
    c: np.ndarray               # (9,) a_e = Σ c_i x_i
    step_index: np.ndarray      # (N,) step k → table row
    phi: np.ndarray             # (U, 9, 9) Φ per distinct step
    q: np.ndarray               # (U, 9, 9) Q_d per distinct step


class RecordArrays(NamedTuple):
    """The first run's linear error model, per step (filled when ``Settings.record``; :class:`FilterRecord`)."""

    gain: np.ndarray
    h: np.ndarray
    hcols: np.ndarray
    nh: np.ndarray
    e: np.ndarray
    ecols: np.ndarray
    ne: np.ndarray
    decay: np.ndarray
    updated: np.ndarray


class Outputs(NamedTuple):
    """What the compiled loop writes (:class:`FilterRun`'s arrays), allocated by :func:`run_filter`: θ̂, P, the hand's
    and the sensor's extra nominals start as copies of :class:`Start`'s; NIS, innovations and whitened innovations
    as NaN (no update); the histories (B, N − 1 | 0, …) filled when ``Settings.keep``."""

    theta: np.ndarray           # (B, 18)
    P: np.ndarray               # (B, n, n)
    hand: np.ndarray            # (B, HAND_NOMINALS)
    sensor: np.ndarray          # (B, SENSOR_NOMINALS)
    quat: np.ndarray            # (B, 4)
    nis: np.ndarray             # (B, N − 1)
    innovation: np.ndarray      # (B, N − 1, 3)
    whitened: np.ndarray        # (B, N − 1, 3)
    sd_history: np.ndarray      # (B, N − 1 | 0, n)
    theta_history: np.ndarray   # (B, N − 1 | 0, 18)


class Scratch(NamedTuple):
    """The loop's working arrays, allocated once by :func:`run_filter` (numba compiles every numpy allocation the loop
    itself would make): the shaping filter's rows, Φ's φ rows E and H by their non-zero columns, the update's
    products (P Hᵀ, T Hᵀ, K, T, S, S⁻¹, z, x, the error state's mean), 3 × 3 matrices (M̂⁻¹, Ĉ mid-step,
    −Ĉ M̂⁻¹ Δt, Ĉ, M̂_a⁻¹, Ĉ M̂_a⁻¹, two products, the identity) and Ĉ J."""

    lrow: np.ndarray
    lv: np.ndarray
    E: np.ndarray
    ecols: np.ndarray
    A: np.ndarray
    EPE: np.ndarray
    Hc: np.ndarray
    hcols: np.ndarray
    J: np.ndarray
    dlt: np.ndarray
    PHt: np.ndarray
    THt: np.ndarray
    K: np.ndarray
    T: np.ndarray
    S: np.ndarray
    Si: np.ndarray
    z: np.ndarray
    x: np.ndarray
    xs: np.ndarray
    Mi: np.ndarray
    Cm: np.ndarray
    CM: np.ndarray
    C: np.ndarray
    Mia: np.ndarray
    CMa: np.ndarray
    X: np.ndarray
    Y: np.ndarray
    I3: np.ndarray
    CJ: np.ndarray


class FilterInputs(NamedTuple):
    """Everything the compiled loop reads, checked and broadcast by :func:`filter_inputs`."""

    t: np.ndarray
    signals: Signals
    start: Start
    settings: Settings
    shaping: Shaping


# ---------------------------------------------------------------------------------------------------------------------
# small compiled helpers: 3-vectors, quaternions, 3 × 3 matrices, H stored by its non-zero columns

# the loop's helpers are called from compiled code only: no Python entry point (numba otherwise builds, optimises and
# emits one per function, a tenth of the first compile), and no cache of their own (their code is linked into
# _kernel's, which is cached)
_loop_helper = njit(no_cpython_wrapper=True, no_cfunc_wrapper=True)


@_loop_helper
def _nb_qmul(p, q):  # pragma: no cover - compiled
    """p ⊗ q, quaternions (w, x, y, z) as 4-tuples of floats."""
    return (p[0] * q[0] - p[1] * q[1] - p[2] * q[2] - p[3] * q[3],
            p[0] * q[1] + p[1] * q[0] + p[2] * q[3] - p[3] * q[2],
            p[0] * q[2] - p[1] * q[3] + p[2] * q[0] + p[3] * q[1],
            p[0] * q[3] + p[1] * q[2] - p[2] * q[1] + p[3] * q[0])


@_loop_helper
def _nb_qexp(v0, v1, v2):  # pragma: no cover - compiled
    """Exp of the rotation vector (v0, v1, v2) (rad) as a 4-tuple."""
    th = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
    k = 0.5 - th * th / 48.0 if th < 1e-6 else math.sin(0.5 * th) / th
    return (math.cos(0.5 * th), k * v0, k * v1, k * v2)


@_loop_helper
def _nb_qnormalised(q):  # pragma: no cover - compiled
    """q / |q| (4-tuple)."""
    s = math.sqrt(q[0] ** 2 + q[1] ** 2 + q[2] ** 2 + q[3] ** 2)
    return (q[0] / s, q[1] / s, q[2] / s, q[3] / s)


@_loop_helper
def _nb_qmat(q, m):  # pragma: no cover - compiled
    """m (3 × 3) = the rotation matrix of the 4-tuple q (body → nav)."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    m[0, 0], m[0, 1], m[0, 2] = 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)
    m[1, 0], m[1, 1], m[1, 2] = 2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)
    m[2, 0], m[2, 1], m[2, 2] = 2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)


@_loop_helper
def _nb_minv(s, g, a, mi):  # pragma: no cover - compiled
    """mi = (I + diag(s) + N(g) − [a×])⁻¹ (3-tuples; a = 0 without the gyro's rotation against the accelerometer):
    the adjugate over the determinant (symmetric when a = 0)."""
    m00, m01, m02 = 1.0 + s[0], g[2] + a[2], g[1] - a[1]
    m10, m11, m12 = g[2] - a[2], 1.0 + s[1], g[0] + a[0]
    m20, m21, m22 = g[1] + a[1], g[0] - a[0], 1.0 + s[2]
    c00, c01, c02 = m11 * m22 - m12 * m21, m12 * m20 - m10 * m22, m10 * m21 - m11 * m20   # cofactors
    det = m00 * c00 + m01 * c01 + m02 * c02
    mi[0, 0], mi[1, 0], mi[2, 0] = c00 / det, c01 / det, c02 / det
    mi[0, 1] = (m02 * m21 - m01 * m22) / det
    mi[1, 1] = (m00 * m22 - m02 * m20) / det
    mi[2, 1] = (m01 * m20 - m00 * m21) / det
    mi[0, 2] = (m01 * m12 - m02 * m11) / det
    mi[1, 2] = (m02 * m10 - m00 * m12) / det
    mi[2, 2] = (m00 * m11 - m01 * m10) / det


@_loop_helper
def _nb_mv(m, v):  # pragma: no cover - compiled
    """m v for a 3 × 3 array and a 3-tuple, as a 3-tuple (summed in column order)."""
    return (m[0, 0] * v[0] + m[0, 1] * v[1] + m[0, 2] * v[2],
            m[1, 0] * v[0] + m[1, 1] * v[1] + m[1, 2] * v[2],
            m[2, 0] * v[0] + m[2, 1] * v[1] + m[2, 2] * v[2])


@_loop_helper
def _nb_matmul(a, b, out):  # pragma: no cover - compiled
    """out (3 × c) = a (3 × 3) b (3 × c), summed in column order."""
    for i in range(3):
        for j in range(b.shape[1]):
            out[i, j] = a[i, 0] * b[0, j] + a[i, 1] * b[1, j] + a[i, 2] * b[2, j]


@_loop_helper
def _nb_jg(w, c, j):  # pragma: no cover - compiled
    """j = J_G(ω) = ∂(N(G) ω)/∂G (calib.session.model.jacobian_nonorthogonality) for c = +1, and [ω×] = ∂(ω × α)/∂α
    (the misalignment's column of δω) for c = −1: the same pattern with entries (0, 1), (1, 2), (2, 0) times c."""
    j[0, 0], j[0, 1], j[0, 2] = 0.0, c * w[2], w[1]
    j[1, 0], j[1, 1], j[1, 2] = w[2], 0.0, c * w[0]
    j[2, 0], j[2, 1], j[2, 2] = c * w[1], w[0], 0.0


@_loop_helper
def _nb_put(dst, cols, start, block, first, v, c, offset):  # pragma: no cover - compiled
    """Write 3 columns of ``block`` (3 × ≥ 3, from column ``first``), column j times v[j] and c, into ``dst`` from
    column ``start``, naming them state ``offset`` … ``offset + 2`` in ``cols``; returns the next free column.
    Callers pass ``start`` and ``first`` as int64 (``np.int64(3)``, not ``3``): numba compiles a literal constant
    argument into a specialisation of its own per value."""
    for j in range(3):
        for i in range(3):
            dst[i, start + j] = block[i, first + j] * v[j] * c
        cols[start + j] = offset + j
    return start + 3


@_loop_helper
def _nb_times_ht(a, hc, hcols, nh, m, out):  # pragma: no cover - compiled
    """out (n × m) = A Hᵀ for H stored by its non-zero columns ``hc`` (3 × nh) at states ``hcols``."""
    for r in range(a.shape[0]):
        for i in range(m):
            s = 0.0
            for e in range(nh):
                s += a[r, hcols[e]] * hc[i, e]
            out[r, i] = s


@_loop_helper
def _nb_hph(hc, hcols, nh, pht, m, r_var, out):  # pragma: no cover - compiled
    """out (m × m) = H (P Hᵀ) + R I for H stored by its non-zero columns (``_nb_times_ht``) and ``pht`` = P Hᵀ."""
    for i in range(m):
        for l in range(m):
            s = 0.0
            for e in range(nh):
                s += hc[i, e] * pht[hcols[e], l]
            out[i, l] = s
        out[i, i] += r_var


@_loop_helper
def _nb_inv_small(S, m, Si):  # pragma: no cover - compiled
    """Si = S⁻¹ for m = 2 or 3 (adjugate over determinant)."""
    if m == 2:
        d = S[0, 0] * S[1, 1] - S[0, 1] * S[1, 0]
        Si[0, 0], Si[0, 1] = S[1, 1] / d, -S[0, 1] / d
        Si[1, 0], Si[1, 1] = -S[1, 0] / d, S[0, 0] / d
    else:
        c00 = S[1, 1] * S[2, 2] - S[1, 2] * S[2, 1]
        c01 = S[0, 2] * S[2, 1] - S[0, 1] * S[2, 2]
        c02 = S[0, 1] * S[1, 2] - S[0, 2] * S[1, 1]
        c11 = S[0, 0] * S[2, 2] - S[0, 2] * S[2, 0]
        c12 = S[0, 2] * S[1, 0] - S[0, 0] * S[1, 2]
        c22 = S[0, 0] * S[1, 1] - S[0, 1] * S[1, 0]
        d = S[0, 0] * c00 + S[1, 0] * c01 + S[2, 0] * c02
        Si[0, 0], Si[0, 1], Si[0, 2] = c00 / d, c01 / d, c02 / d
        Si[1, 0], Si[1, 1], Si[1, 2] = c01 / d, c11 / d, c12 / d
        Si[2, 0], Si[2, 1], Si[2, 2] = c02 / d, c12 / d, c22 / d


def _lever_jacobian_columns(ws, ld, ldd, r, out):  # pragma: no cover - compiled
    """out (3 × 9 | 12) = ∂(K(ω, ω̇) r)/∂(S, G, b[, α]) at ω = ``ws`` (the low-passed compensated rate), for the rate's
    low-passed sensitivities ``ld`` = L ∂ω/∂θ (3 × 9) and ``ldd`` = d/dt of it: with a = ω̇ × r + ω × (ω × r),
    δa = δω̇ × r + δω × (ω × r) + ω × (δω × r) (:func:`calib.session.hand.lever.lever_jacobian`)."""
    u0 = ws[1] * r[2] - ws[2] * r[1]                           # u = ω × r
    u1 = ws[2] * r[0] - ws[0] * r[2]
    u2 = ws[0] * r[1] - ws[1] * r[0]
    for c in range(ld.shape[1]):
        v0, v1, v2 = ld[0, c], ld[1, c], ld[2, c]
        d0, d1, d2 = ldd[0, c], ldd[1, c], ldd[2, c]
        p0 = v1 * r[2] - v2 * r[1]                             # p = δω × r
        p1 = v2 * r[0] - v0 * r[2]
        p2 = v0 * r[1] - v1 * r[0]
        out[0, c] = (d1 * r[2] - d2 * r[1]) + (v1 * u2 - v2 * u1) + (ws[1] * p2 - ws[2] * p1)
        out[1, c] = (d2 * r[0] - d0 * r[2]) + (v2 * u0 - v0 * u2) + (ws[2] * p0 - ws[0] * p2)
        out[2, c] = (d0 * r[1] - d1 * r[0]) + (v0 * u1 - v1 * u0) + (ws[0] * p1 - ws[1] * p0)


lever_jacobian_columns = njit(cache=True)(_lever_jacobian_columns)   # from Python (the reference filter, tests)
_nb_lever_jacobian = _loop_helper(_lever_jacobian_columns)            # from the loop: no Python entry point


# ---------------------------------------------------------------------------------------------------------------------
# one step of the filter, block by block (each called from _kernel)


@_loop_helper
def _propagate_gauss_markov(Pb, xs, hd, o_ea, o_el, o_e2, al, be, gm_var):  # pragma: no cover - compiled
    """a_e = x − z (− z₂) per nav axis: x ← α x (α = e^{−Δt/τ}, Q = σ²(1 − α²)), z ← β z + (1 − β) x and
    z₂ ← β z₂ + (1 − β)(x − z) with the old x, z (β = e^{−Δt/τ_h}): nominal ``hd``, error-state mean ``xs`` and
    P ← A P Aᵀ + Q on the block's rows and columns."""
    n = Pb.shape[0]
    for j in range(3):
        c = o_ea + j
        if o_e2 >= 0:                                      # z₂ ← β z₂ + (1 − β)(x − z), old x and z
            c2, cz = o_e2 + j, o_el + j
            hd[9 + j] = be * hd[9 + j] + (1.0 - be) * (hd[3 + j] - hd[6 + j])
            xs[c2] = be * xs[c2] + (1.0 - be) * (xs[c] - xs[cz])
            for r in range(n):
                Pb[c2, r] = be * Pb[c2, r] + (1.0 - be) * (Pb[c, r] - Pb[cz, r])
            for r in range(n):
                Pb[r, c2] = be * Pb[r, c2] + (1.0 - be) * (Pb[r, c] - Pb[r, cz])
        if o_el >= 0:
            cz = o_el + j
            hd[6 + j] = be * hd[6 + j] + (1.0 - be) * hd[3 + j]
            xs[cz] = be * xs[cz] + (1.0 - be) * xs[c]
            for r in range(n):                             # P ← A P Aᵀ, A the z row (x before its decay)
                Pb[cz, r] = be * Pb[cz, r] + (1.0 - be) * Pb[c, r]
            for r in range(n):
                Pb[r, cz] = be * Pb[r, cz] + (1.0 - be) * Pb[r, c]
        hd[3 + j] *= al
        xs[c] *= al
        for r in range(n):
            Pb[r, c] *= al
            Pb[c, r] *= al
        Pb[c, c] += gm_var * (1.0 - al * al)


@_loop_helper
def _propagate_shaping(Pb, xs, hd, d, offs_ae, phi, q, lrow, lv):  # pragma: no cover - compiled
    """a_e's general shaping filter per nav axis j: x ← Φ x (nominal ``hd`` and error-state mean ``xs``),
    P ← Φ P Φᵀ + Q_d on the axis's d states (Φ block-diagonal over the axes: its zeros skipped)."""
    n = Pb.shape[0]
    for j in range(3):
        for i in range(d):                                 # nominal and error-state mean
            s1 = 0.0
            s2 = 0.0
            for l in range(d):
                s1 += phi[i, l] * hd[3 + 3 * l + j]
                s2 += phi[i, l] * xs[offs_ae[l] + j]
            lv[i] = s1
            lrow[i, 0] = s2
        for i in range(d):
            hd[3 + 3 * i + j] = lv[i]
            xs[offs_ae[i] + j] = lrow[i, 0]
        for i in range(d):                                 # rows: Φ P (Φ block-diagonal: its zeros skipped)
            for r in range(n):
                lrow[i, r] = 0.0
            for l in range(d):
                f = phi[i, l]
                if f != 0.0:
                    cl = offs_ae[l] + j
                    for r in range(n):
                        lrow[i, r] += f * Pb[cl, r]
        for i in range(d):
            for r in range(n):
                Pb[offs_ae[i] + j, r] = lrow[i, r]
        for i in range(d):                                 # columns: (Φ P) Φᵀ
            for r in range(n):
                lrow[i, r] = 0.0
            for l in range(d):
                f = phi[i, l]
                if f != 0.0:
                    cl = offs_ae[l] + j
                    for r in range(n):
                        lrow[i, r] += Pb[r, cl] * f
        for i in range(d):
            for r in range(n):
                Pb[r, offs_ae[i] + j] = lrow[i, r]
        for i in range(d):
            for l in range(d):
                Pb[offs_ae[i] + j, offs_ae[l] + j] += q[i, l]


@_loop_helper
def _transition(E, ecols, CM, wr, dtm, fm, o_sg, o_gg, o_bg, o_tb, o_ts, o_gs, o_ma, X, Y):  # pragma: no cover
    """The φ rows of Φ − I, E (3 × ne) in the columns ``ecols``, with CM = −Ĉ M̂⁻¹ Δt: the gyro error δω = M̂⁻¹ (X(ω)
    [δS; δG] + δb + …) turns the attitude by −Ĉ δω Δt (``wr``, ``fm`` 3-tuples; ``X``, ``Y`` 3 × 3 scratch).
    Returns ne."""
    one = (1.0, 1.0, 1.0)
    c0 = np.int64(0)
    ne = _nb_put(E, ecols, c0, CM, c0, wr, 1.0, o_sg)      # scale: column j × ω_j
    _nb_jg(wr, 1.0, X)
    _nb_matmul(CM, X, Y)
    ne = _nb_put(E, ecols, ne, Y, c0, one, 1.0, o_gg)      # non-orthogonality: J_G(ω)
    if o_bg >= 0:
        ne = _nb_put(E, ecols, ne, CM, c0, one, 1.0, o_bg)  # bias
    if o_tb >= 0:
        ne = _nb_put(E, ecols, ne, CM, c0, one, dtm, o_tb)  # bias temperature coefficient: (T − T₀)
    if o_ts >= 0:
        ne = _nb_put(E, ecols, ne, CM, c0, wr, dtm, o_ts)   # scale temperature coefficient: ω_j (T − T₀)
    if o_gs >= 0:
        ne = _nb_put(E, ecols, ne, CM, c0, fm, 1.0, o_gs)   # g-sensitivity: column j × f_j
    if o_ma >= 0:
        _nb_jg(wr, -1.0, X)
        _nb_matmul(CM, X, Y)
        ne = _nb_put(E, ecols, ne, Y, c0, one, 1.0, o_ma)   # misalignment: −[δα×] ω = [ω×] δα
    return ne


@_loop_helper
def _propagate_attitude_rows(Pb, xs, E, ecols, ne, A, EPE, qd, o_bg, bias_q):  # pragma: no cover - compiled
    """x ← (I + E) x (non-zero only before the first update: the prior mean x₀); P ← (I + E) P (I + E)ᵀ + Q =
    P + EP + (EP)ᵀ + E P Eᵀ + Q, Q_φφ = N_g² Δt I (``qd``), Q_bb = q_b Δt I (``bias_q``, with a bias block)."""
    n = Pb.shape[0]
    for i in range(3):
        s = 0.0
        for e in range(ne):
            s += E[i, e] * xs[ecols[e]]
        xs[i] += s
    for i in range(3):
        for c in range(n):
            s = 0.0
            for e in range(ne):
                s += E[i, e] * Pb[ecols[e], c]
            A[i, c] = s
    for i in range(3):
        for l in range(3):
            s = 0.0
            for e in range(ne):
                s += A[i, ecols[e]] * E[l, e]
            EPE[i, l] = s
    for i in range(3):
        for c in range(n):
            Pb[i, c] += A[i, c]
    for r in range(n):
        for i in range(3):
            Pb[r, i] += A[i, r]
    for i in range(3):
        for l in range(3):
            Pb[i, l] += EPE[i, l]
    Pb[0, 0] += qd
    Pb[1, 1] += qd
    Pb[2, 2] += qd
    if o_bg >= 0 and bias_q > 0.0:                         # the bias's random walk: Q_bb = q_b Δt
        for j in range(3):
            Pb[o_bg + j, o_bg + j] += bias_q


@_loop_helper
def _lever_shift(J, dlt, th, th0, sx, sx0, temp_k, force, k, o_ts, o_tb, o_gs):  # pragma: no cover - compiled
    """K r̂ was built at the pass's θ₀ and the nominal moved since: dlt = θ̂ − θ₀ for (S, G, b) (and α̂ − α₀ when J has
    the misalignment's columns), with θ̂'s S and b at this sample's temperature (and force, read at sample ``k`` with
    the g-sensitivity only); returns J dlt (a 3-tuple), the first-order change of K r̂."""
    for j in range(3):
        dlt[j] = th[j] - th0[j]
        dlt[3 + j] = th[3 + j] - th0[3 + j]
        dlt[6 + j] = th[6 + j] - th0[6 + j]
        if o_ts >= 0:
            dlt[j] += sx[3 + j] * temp_k
        if o_tb >= 0:
            dlt[6 + j] += sx[j] * temp_k
        if o_gs >= 0:
            dlt[6 + j] += sx[6 + j] * force[k, j]
        if J.shape[1] > 9:                                 # the misalignment α
            dlt[9 + j] = sx[15 + j] - sx0[15 + j]
    s0, s1, s2 = 0.0, 0.0, 0.0
    for c in range(J.shape[1]):
        s0 += J[0, c] * dlt[c]
        s1 += J[1, c] * dlt[c]
        s2 += J[2, c] * dlt[c]
    return (s0, s1, s2)


@_loop_helper
def _residual(z, C, fh, hd, gz, o_ea, o_el, o_e2, d, lti_c):  # pragma: no cover - compiled
    """z = Ĉ f̂ − g_up − â_e (nav): the levelling residual at the nominal (f̂ already compensated, lever arm removed)."""
    for i in range(3):
        z[i] = C[i, 0] * fh[0] + C[i, 1] * fh[1] + C[i, 2] * fh[2]
    z[2] -= gz
    if o_ea >= 0:                                          # minus the external acceleration's nominal (nav)
        for i in range(3):
            z[i] -= hd[3 + i]
            if o_el >= 0:
                z[i] += hd[6 + i]                          # a_e = x − z
            if o_e2 >= 0:
                z[i] += hd[9 + i]                          # a_e = x − z − z₂
    if d > 0:                                              # a_e = C x per nav axis
        for i in range(3):
            for l in range(d):
                z[i] -= lti_c[l] * hd[3 + 3 * l + i]


@_loop_helper
def _measurement(Hc, hcols, C, Mia, fr, gz, temp_k, force, acc_rate, lever, k, J, jac_on, offs, offs_x,
                 o_ea, o_el, o_e2, sh, I3, CMa, X, Y, CJ):  # pragma: no cover - compiled
    """H (rows × n) stored by its non-zero columns: [g_up×] on φ, Ĉ M̂_a⁻¹ [I, diag(f), J_G(f)] on the accelerometer,
    its temperature and delay columns, Ĉ K on the lever arm, ±I (or C_l I) on a_e's states, Ĉ J on the gyro's
    states through the lever arm term (per-run arrays read at sample ``k`` only with their block; ``fr`` a 3-tuple;
    ``I3`` the identity, ``CMa``, ``X``, ``Y`` 3 × 3 and ``CJ`` 3 × J's columns scratch).  Returns nh, the
    number of columns used."""
    for i in range(3):
        for e in range(H_COLS):
            Hc[i, e] = 0.0
    Hc[1, 0] = gz                                          # [g_up×] on φ_x
    hcols[0] = 0
    Hc[0, 1] = -gz                                         # [g_up×] on φ_y
    hcols[1] = 1
    nh = np.int64(2)
    one = (1.0, 1.0, 1.0)
    c0, c3, c6, c9 = np.int64(0), np.int64(3), np.int64(6), np.int64(9)   # H's column groups in CJ
    o_sg, o_gg, o_bg, o_ba, o_sa, o_ga, o_lv = offs[1], offs[2], offs[3], offs[4], offs[5], offs[6], offs[7]
    o_tb, o_ts, o_gs, o_ta, o_dl = offs_x[0], offs_x[1], offs_x[2], offs_x[3], offs_x[4]
    if o_ba >= 0:
        _nb_matmul(C, Mia, CMa)
        nh = _nb_put(Hc, hcols, nh, CMa, c0, one, 1.0, o_ba)   # Ĉ M̂_a⁻¹
        nh = _nb_put(Hc, hcols, nh, CMa, c0, fr, 1.0, o_sa)    # Ĉ M̂_a⁻¹ diag(f)
        _nb_jg(fr, 1.0, X)
        _nb_matmul(CMa, X, Y)
        nh = _nb_put(Hc, hcols, nh, Y, c0, one, 1.0, o_ga)     # Ĉ M̂_a⁻¹ J_G(f)
        if o_ta >= 0:
            nh = _nb_put(Hc, hcols, nh, CMa, c0, one, temp_k, o_ta)   # Ĉ M̂_a⁻¹ (T − T₀): c_a
    if o_dl >= 0:                                          # −Ĉ diag(ḟ): f̃ = f − δ ḟ
        nh = _nb_put(Hc, hcols, nh, C, c0, (acc_rate[k, 0], acc_rate[k, 1], acc_rate[k, 2]), -1.0, o_dl)
    if o_lv >= 0:
        _nb_matmul(C, lever[k], Y)
        nh = _nb_put(Hc, hcols, nh, Y, c0, one, 1.0, o_lv)     # Ĉ K(ω, ω̇)
    if o_ea >= 0:
        nh = _nb_put(Hc, hcols, nh, I3, c0, one, 1.0, o_ea)    # I (nav)
    if o_el >= 0:
        nh = _nb_put(Hc, hcols, nh, I3, c0, one, -1.0, o_el)   # −I (nav): a_e = x − z
    if o_e2 >= 0:
        nh = _nb_put(Hc, hcols, nh, I3, c0, one, -1.0, o_e2)   # −I (nav): a_e = x − z − z₂
    if sh.d > 0:
        for l in range(sh.d):
            if sh.c[l] != 0.0:
                nh = _nb_put(Hc, hcols, nh, I3, c0, one, sh.c[l], sh.offsets[l])   # C_l I (nav)
    if jac_on:                                             # Ĉ J: the lever arm term through the rate's errors
        _nb_matmul(C, J, CJ)
        nh = _nb_put(Hc, hcols, nh, CJ, c0, one, 1.0, o_sg)    # Ĉ ∂(K r̂)/∂S
        nh = _nb_put(Hc, hcols, nh, CJ, c3, one, 1.0, o_gg)    # Ĉ ∂(K r̂)/∂G
        if o_bg >= 0:
            nh = _nb_put(Hc, hcols, nh, CJ, c6, one, 1.0, o_bg)   # Ĉ ∂(K r̂)/∂b
        if o_ts >= 0:
            nh = _nb_put(Hc, hcols, nh, CJ, c0, one, temp_k, o_ts)   # s_T: S's column × (T − T₀)
        if o_tb >= 0:
            nh = _nb_put(Hc, hcols, nh, CJ, c6, one, temp_k, o_tb)   # c_b: b's column × (T − T₀)
        if o_gs >= 0:                                      # k: b's column j × f_j
            nh = _nb_put(Hc, hcols, nh, CJ, c6, (force[k, 0], force[k, 1], force[k, 2]), 1.0, o_gs)
        if offs_x[5] >= 0 and J.shape[1] > 9:
            nh = _nb_put(Hc, hcols, nh, CJ, c9, one, 1.0, offs_x[5])   # Ĉ ∂(K r̂)/∂α
    return nh


@_loop_helper
def _update_covariance(Pb, K, PHt, Si, T, THt, Hc, hcols, nh, m, r_var):  # pragma: no cover - compiled
    """K = P Hᵀ S⁻¹, then the Joseph form P ← (I − K H) P (I − K H)ᵀ + K R Kᵀ as T = P − K (P Hᵀ)ᵀ,
    P = T − (T Hᵀ) Kᵀ + K R Kᵀ, re-symmetrised."""
    n = Pb.shape[0]
    for r in range(n):                                     # K = P Hᵀ S⁻¹
        for i in range(m):
            s = 0.0
            for l in range(m):
                s += PHt[r, l] * Si[l, i]
            K[r, i] = s
    for r in range(n):                                     # T = (I − K H) P = P − K (P Hᵀ)ᵀ
        for c in range(n):
            s = Pb[r, c]
            for i in range(m):
                s -= K[r, i] * PHt[c, i]
            T[r, c] = s
    _nb_times_ht(T, Hc, hcols, nh, m, THt)                 # T Hᵀ
    for r in range(n):                                     # P = T (I − K H)ᵀ + K R Kᵀ
        for c in range(n):
            s = T[r, c]
            for i in range(m):
                s += K[c, i] * (r_var * K[r, i] - THt[r, i])
            Pb[r, c] = s
    for r in range(n):
        for c in range(r + 1, n):
            v = 0.5 * (Pb[r, c] + Pb[c, r])
            Pb[r, c] = v
            Pb[c, r] = v


@_loop_helper
def _inject(x, xs, K, z, m, th, hd, sx, offs, offs_x, o_ea, o_el, o_e2, sh):  # pragma: no cover - compiled
    """x = x⁻ + K (z − H x⁻) (``z`` already the innovation), then the reset: θ̂ += δθ̂, the hand's and the sensor's
    extra nominals += their δ, and the error state back to zero (the attitude's part is applied by the caller)."""
    n = xs.shape[0]
    for r in range(n):                                     # x = x⁻ + K (z − H x⁻)
        s = xs[r]
        for i in range(m):
            s += K[r, i] * z[i]
        x[r] = s
        xs[r] = 0.0                                        # reset after the injection below
    o_sg, o_gg, o_bg, o_ba, o_sa, o_ga, o_lv = offs[1], offs[2], offs[3], offs[4], offs[5], offs[6], offs[7]
    o_tb, o_ts, o_gs, o_ta, o_dl = offs_x[0], offs_x[1], offs_x[2], offs_x[3], offs_x[4]
    for j in range(3):                                     # reset: θ̂ += δθ̂
        th[0 + j] += x[o_sg + j]
        th[3 + j] += x[o_gg + j]
        if o_bg >= 0:
            th[6 + j] += x[o_bg + j]
        if o_ba >= 0:
            th[9 + j] += x[o_ba + j]
            th[12 + j] += x[o_sa + j]
            th[15 + j] += x[o_ga + j]
        if o_lv >= 0:
            hd[j] += x[o_lv + j]
        if o_ea >= 0:
            hd[3 + j] += x[o_ea + j]
        if o_el >= 0:
            hd[6 + j] += x[o_el + j]
        if o_e2 >= 0:
            hd[9 + j] += x[o_e2 + j]
        for l in range(sh.d):
            hd[3 + 3 * l + j] += x[sh.offsets[l] + j]
        if o_tb >= 0:
            sx[j] += x[o_tb + j]
        if o_ts >= 0:
            sx[3 + j] += x[o_ts + j]
        if o_gs >= 0:
            sx[6 + j] += x[o_gs + j]
        if o_ta >= 0:
            sx[9 + j] += x[o_ta + j]
        if o_dl >= 0:
            sx[12 + j] += x[o_dl + j]
        if offs_x[5] >= 0:
            sx[15 + j] += x[offs_x[5] + j]


@_loop_helper
def _step_nominal(q, th, sx, gyro, gyro_reg, still, force, k, dt, dtm, o_gs, o_ma, Mi, Cm, CM):  # pragma: no cover
    """The nominal's step k−1 → k (one run's arrays, sample index ``k``): M̂⁻¹ (into ``Mi``) and b̂ at the step's mid
    temperature (ΔT = ``dtm``; and mid specific force with the g-sensitivity: b_g,i += k_i f_i), the compensated rates
    at both ends, q̂ ← q̂ ⊗ Exp(φ) (trapezoid + coning), ``CM`` = −Ĉ M̂⁻¹ Δt at the step's middle (``Cm`` scratch).
    Returns (q̂, the rate regressor ω — zero at rest, else the leave-out mean at t_{k−½} —, f at the step's middle),
    quaternion and vectors as tuples."""
    a = (sx[15], sx[16], sx[17]) if o_ma >= 0 else (0.0, 0.0, 0.0)   # with the rotation against the accelerometer
    _nb_minv((th[0] + sx[3] * dtm, th[1] + sx[4] * dtm, th[2] + sx[5] * dtm), (th[3], th[4], th[5]), a, Mi)
    bg = (th[6] + sx[0] * dtm, th[7] + sx[1] * dtm, th[8] + sx[2] * dtm)
    fm = (0.0, 0.0, 0.0)
    if o_gs >= 0:
        fm = (0.5 * (force[k - 1, 0] + force[k, 0]), 0.5 * (force[k - 1, 1] + force[k, 1]),
              0.5 * (force[k - 1, 2] + force[k, 2]))
        bg = (bg[0] + sx[6] * fm[0], bg[1] + sx[7] * fm[1], bg[2] + sx[8] * fm[2])
    wp = _nb_mv(Mi, (gyro[k - 1, 0] - bg[0], gyro[k - 1, 1] - bg[1], gyro[k - 1, 2] - bg[2]))
    wn = _nb_mv(Mi, (gyro[k, 0] - bg[0], gyro[k, 1] - bg[1], gyro[k, 2] - bg[2]))
    cr = (wp[1] * wn[2] - wp[2] * wn[1], wp[2] * wn[0] - wp[0] * wn[2], wp[0] * wn[1] - wp[1] * wn[0])
    h = dt * dt / 12.0
    phi = (0.5 * (wp[0] + wn[0]) * dt + cr[0] * h, 0.5 * (wp[1] + wn[1]) * dt + cr[1] * h,
           0.5 * (wp[2] + wn[2]) * dt + cr[2] * h)
    _nb_qmat(_nb_qmul(q, _nb_qexp(0.5 * phi[0], 0.5 * phi[1], 0.5 * phi[2])), Cm)
    q = _nb_qnormalised(_nb_qmul(q, _nb_qexp(phi[0], phi[1], phi[2])))
    wr = (0.0, 0.0, 0.0)                                   # at rest the true rate is zero
    if not still[k]:
        wr = _nb_mv(Mi, (gyro_reg[k, 0] - bg[0], gyro_reg[k, 1] - bg[1], gyro_reg[k, 2] - bg[2]))   # leave-out
    _nb_matmul(Cm, Mi, CM)
    for i in range(3):
        for j in range(3):
            CM[i, j] = -dt * CM[i, j]
    return q, wr, fm


@_loop_helper
def _corrected_force(C, th, sx, th0, sx0, acc_k, temp_k, acc_rate, lever, force, jw, jd, jdd, hd, J, dlt, k, gz, offs,
                     offs_x, jac_on, Mia):  # pragma: no cover - compiled
    """The compensated specific force at sample ``k`` (body): f̂ = M̂_a⁻¹(f̃ − b̂_a − ĉ_a ΔT) + δ̂ ⊙ ḟ̃ − K r̂ − J (θ̂ − θ₀),
    and the H regressor Ĉᵀ g_up (gravity predicted in the body).  Per-run arrays (``acc_rate``, ``lever``, ``force``,
    ``jw``, ``jd``, ``jdd``) are read at ``k`` only when their block is in the layout.  Returns (f̂, the regressor) as
    3-tuples, M̂_a⁻¹ into ``Mia``."""
    o_ba, o_lv = offs[4], offs[7]
    o_tb, o_ts, o_gs, o_ta, o_dl = offs_x[0], offs_x[1], offs_x[2], offs_x[3], offs_x[4]
    if o_ba >= 0:
        _nb_minv((th[12], th[13], th[14]), (th[15], th[16], th[17]), (0.0, 0.0, 0.0), Mia)
    else:
        for i in range(3):
            for j in range(3):
                Mia[i, j] = 1.0 if i == j else 0.0
    ba = (th[9], th[10], th[11])
    if o_ta >= 0:                                          # the accelerometer bias at this sample's temperature
        ba = (th[9] + sx[9] * temp_k, th[10] + sx[10] * temp_k, th[11] + sx[11] * temp_k)
    fh = _nb_mv(Mia, (acc_k[0] - ba[0], acc_k[1] - ba[1], acc_k[2] - ba[2]))
    if o_dl >= 0:                                          # the accelerometer's delay: f(t) = f̃(t) + δ ḟ̃(t)
        fh = (fh[0] + sx[12] * acc_rate[k, 0], fh[1] + sx[13] * acc_rate[k, 1], fh[2] + sx[14] * acc_rate[k, 2])
    fr = (C[2, 0] * gz, C[2, 1] * gz, C[2, 2] * gz)        # regressor: gravity predicted in the body frame, Ĉᵀ g_up
    if o_lv >= 0:                                          # minus the lever arm's K r̂ (body)
        kr = _nb_mv(lever[k], (hd[0], hd[1], hd[2]))
        fh = (fh[0] - kr[0], fh[1] - kr[1], fh[2] - kr[2])
    if jac_on:                                             # K was built at the pass's θ₀, the nominal moved since:
        _nb_lever_jacobian(jw[k], jd[k], jdd[k], hd[0:3], J)       # J = ∂(K r̂)/∂(S, G, b) (body)
        # K(θ̂) r̂ ≈ K(θ₀) r̂ + J (θ̂ − θ₀), with θ̂'s S and b at this sample's temperature (and force)
        sh_k = _lever_shift(J, dlt, th, th0, sx, sx0, temp_k, force, k, o_ts, o_tb, o_gs)
        fh = (fh[0] - sh_k[0], fh[1] - sh_k[1], fh[2] - sh_k[2])
    return fh, fr


@_loop_helper
def _innovation(z, S, Si, Hc, hcols, nh, xs, m, inn_row, wht_row):  # pragma: no cover - compiled
    """ν = z − H x (``z`` in place), its NIS νᵀS⁻¹ν and the whitened levelling rows L⁻¹ν (S = L Lᵀ), written to
    ``inn_row``, ``wht_row``; returns the NIS."""
    for i in range(m):                                     # innovation z − H x
        s = 0.0
        for e in range(nh):
            s += Hc[i, e] * xs[hcols[e]]
        z[i] -= s
    nis = 0.0
    for i in range(m):
        for l in range(m):
            nis += z[i] * Si[i, l] * z[l]
    for i in range(m):
        inn_row[i] = z[i]
    l00 = math.sqrt(S[0, 0])                               # Cholesky S = L Lᵀ of the levelling rows: L⁻¹ν
    l10 = S[1, 0] / l00
    l11 = math.sqrt(max(S[1, 1] - l10 * l10, 1e-300))
    wht_row[0] = z[0] / l00
    wht_row[1] = (z[1] - l10 * z[0] / l00) / l11
    return nis


@_loop_helper
def _record_transition(rec, k, E, ecols, ne, gm_on, dt, gm_tau, hp_tau):  # pragma: no cover - compiled
    """Step k's propagation into the linear error model (:class:`FilterRecord`)."""
    rec.ne[k] = ne
    for e in range(ne):
        rec.ecols[k, e] = ecols[e]
        for i in range(3):
            rec.e[k, i, e] = E[i, e]
    if gm_on:
        rec.decay[k, 0] = math.exp(-dt / gm_tau)
        rec.decay[k, 1] = math.exp(-dt / hp_tau)


@_loop_helper
def _record_update(rec, k, Hc, hcols, nh, K, m):  # pragma: no cover - compiled
    """Step k's update (gain and H) into the linear error model (:class:`FilterRecord`)."""
    rec.updated[k] = True
    rec.nh[k] = nh
    for e in range(nh):
        rec.hcols[k, e] = hcols[e]
        for i in range(m):
            rec.h[k, i, e] = Hc[i, e]
    for r in range(K.shape[0]):
        for i in range(m):
            rec.gain[k, r, i] = K[r, i]


# ---------------------------------------------------------------------------------------------------------------------
# the loop


@njit(cache=True, fastmath=False)
def _kernel(t, sig, start, st, sh, rec, out, w):  # pragma: no cover - compiled
    """B runs of N samples (:func:`run_filter`) into ``out`` (:class:`Outputs`, θ̂, P and the extra nominals already
    holding the start), with the scratch ``w`` (:class:`Scratch`)."""
    B, N = sig.gyro.shape[0], sig.gyro.shape[1]
    n = start.P.shape[1]
    # hand: nominal lever arm (0:3), external acceleration x (3:6), z (6:9), z₂ (9:12) (general shaping filter,
    # sh.d > 0: component i of axis j at 3 + 3i + j); sens: the gyro's c_b (0:3), s_T (3:6), g-sensitivity k (6:9),
    # the accelerometer's c_a (9:12) and delay δ (12:15), the gyro's misalignment α (15:18) (SENSOR_EXTRA_BLOCKS)
    theta, P, hand, sens, qout = out.theta, out.P, out.hand, out.sensor, out.quat
    nis_out, inn_out, wht_out, hsd, hth = out.nis, out.innovation, out.whitened, out.sd_history, out.theta_history
    offs, offs_x = st.offsets, st.sensor_offsets
    o_sg, o_gg, o_bg, o_lv = offs[1], offs[2], offs[3], offs[7]
    o_ea, o_el = offs[8], offs[9]
    o_e2 = offs[10] if st.hp_order >= 2 else -1
    if sh.d > 0:                                               # the general shaping filter replaces the x, z, z₂ code
        o_ea, o_el, o_e2 = -1, -1, -1
    o_tb, o_ts, o_gs, o_ma = offs_x[0], offs_x[1], offs_x[2], offs_x[5]
    gz, m = st.gravity, st.rows
    jac_on = o_lv >= 0 and sig.jac_rate.shape[1] > 1           # K r̂'s dependence on the gyro's errors (LeverJacobian)
    lrow, lv, E, ecols, A, EPE, Hc, hcols = w.lrow, w.lv, w.E, w.ecols, w.A, w.EPE, w.Hc, w.hcols
    J, dlt, PHt, THt, K, T, S, Si, z, x, xs = w.J, w.dlt, w.PHt, w.THt, w.K, w.T, w.S, w.Si, w.z, w.x, w.xs
    Mi, Cm, CM, C, Mia, CMa, X, Y, I3, CJ = w.Mi, w.Cm, w.CM, w.C, w.Mia, w.CMa, w.X, w.Y, w.I3, w.CJ
    for b in range(B):
        Pb = P[b]
        th = theta[b]
        hd = hand[b]
        sx = sens[b]
        for i in range(n):                                     # the error state's mean: x0, zero after a reset
            xs[i] = start.x[b, i]
        q = _nb_qnormalised((start.quat[b, 0], start.quat[b, 1], start.quat[b, 2], start.quat[b, 3]))
        for k in range(1, N):
            dt = t[k] - t[k - 1]
            # ---- propagation: nominal attitude with the compensated rate; the temperature blocks' nominals at the
            # step's mid temperature (T − T₀; zero without them)
            dtm = 0.5 * (sig.temp_rel[b, k - 1] + sig.temp_rel[b, k])
            q, wr, fm = _step_nominal(q, th, sx, sig.gyro[b], sig.gyro_reg[b], sig.still[b], sig.force[b], k, dt,
                                      dtm, o_gs, o_ma, Mi, Cm, CM)
            ne = _transition(E, ecols, CM, wr, dtm, fm, o_sg, o_gg, o_bg, o_tb, o_ts, o_gs, o_ma, X, Y)
            if o_ea >= 0:                                      # Gauss–Markov a_e: Φ = diag(e^{−Δt/τ}), Q = σ²(1 − Φ²)
                al = math.exp(-dt / st.gm_tau)
                be = math.exp(-dt / st.hp_tau)                 # z ← β z + (1 − β) x: z the low-pass of x (τ_h)
                _propagate_gauss_markov(Pb, xs, hd, o_ea, o_el, o_e2, al, be, st.gm_var)
            if sh.d > 0:                                       # a_e's shaping filter per nav axis
                u = sh.step_index[k]
                _propagate_shaping(Pb, xs, hd, sh.d, sh.offsets, sh.phi[u], sh.q[u], lrow, lv)
            if st.record and b == 0:                           # the linear error model of this step (spectral)
                _record_transition(rec, k, E, ecols, ne, o_ea >= 0, dt, st.gm_tau, st.hp_tau)
            _propagate_attitude_rows(Pb, xs, E, ecols, ne, A, EPE, st.arw2 * dt, o_bg, st.bias_rw2 * dt)
            # ---- update with the accelerometer sample
            if sig.update[b, k]:
                _nb_qmat(q, C)
                temp_k = sig.temp_rel[b, k]
                fh, fr = _corrected_force(C, th, sx, start.theta[b], start.sensor[b], sig.acc[b, k], temp_k,
                                          sig.acc_rate[b], sig.lever[b], sig.force[b], sig.jac_rate[b],
                                          sig.jac_d_rate[b], sig.jac_d_rate_dot[b], hd, J, dlt, k, gz, offs,
                                          offs_x, jac_on, Mia)
                _residual(z, C, fh, hd, gz, o_ea, o_el, o_e2, sh.d, sh.c)
                nh = _measurement(Hc, hcols, C, Mia, fr, gz, temp_k, sig.force[b], sig.acc_rate[b], sig.lever[b], k,
                                  J, jac_on, offs, offs_x, o_ea, o_el, o_e2, sh, I3, CMa, X, Y, CJ)
                r_var = sig.r_var[b, k]
                _nb_times_ht(Pb, Hc, hcols, nh, m, PHt)        # P Hᵀ
                _nb_hph(Hc, hcols, nh, PHt, m, r_var, S)       # S = H P Hᵀ + R
                _nb_inv_small(S, m, Si)
                nis = _innovation(z, S, Si, Hc, hcols, nh, xs, m, inn_out[b, k - 1], wht_out[b, k - 1])
                nis_out[b, k - 1] = nis
                if not (st.gate > 0.0 and nis > st.gate):      # gating: skip an update whose NIS exceeds it
                    _update_covariance(Pb, K, PHt, Si, T, THt, Hc, hcols, nh, m, r_var)
                    if st.record and b == 0:                   # the update's gain and H (calib.session.spectral)
                        _record_update(rec, k, Hc, hcols, nh, K, m)
                    _inject(x, xs, K, z, m, th, hd, sx, offs, offs_x, o_ea, o_el, o_e2, sh)
                    q = _nb_qnormalised(_nb_qmul(_nb_qexp(x[0], x[1], x[2]), q))   # Ĉ ← (I + [φ×]) Ĉ
            if st.keep:
                for i in range(n):
                    hsd[b, k - 1, i] = math.sqrt(max(Pb[i, i], 0.0))
                for i in range(18):
                    hth[b, k - 1, i] = th[i]
        qout[b, 0], qout[b, 1], qout[b, 2], qout[b, 3] = q   # element by element: a slice assignment compiles
                                                               # numba's shape-mismatch error text


# ---------------------------------------------------------------------------------------------------------------------
# what a run returns, and the Python entry point


@dataclass(frozen=True)
class LeverJacobian:
    """How the lever arm term K(ω, ω̇) r moves with the gyro's errors, per sample (body frame): ``rate_rad_s``
    (N, 3) the low-passed compensated rate ω the regressor K was built from, ``d_rate`` (N, 3, 9 | 12) its low-passed
    sensitivity L ∂ω/∂(S, G, b) and ``d_rate_dot`` (N, 3, 9) that sensitivity's time derivative (1/s)
    (:func:`calib.session.hand.lever.lever_jacobian`).  With a = ω̇ × r + ω × (ω × r):
    ∂a/∂θ = ∂ω̇/∂θ × r + ∂ω/∂θ × (ω × r) + ω × (∂ω/∂θ × r), column by column (:func:`lever_jacobian_columns`)."""

    rate_rad_s: np.ndarray
    d_rate: np.ndarray
    d_rate_dot: np.ndarray


@dataclass(frozen=True)
class FilterRecord:
    """The first run's linear error model, per step k (arrays (N, …); row 0 unused), as the kernel applied it:
    the propagation x ← (I + Ê_k) Φ_ae,k x — Ê_k non-zero in the three φ rows only, ``e`` (3, ne_k) in the columns
    ``ecols`` (ne_k = ``ne[k]``), Φ_ae the Gauss–Markov a_e's decay ``decay`` [k] = (e^{−Δt/τ}, e^{−Δt/τ_h})
    (zero without that block) — and, where ``updated``, x ← (I − K_k H_k) x + K_k z_k with ``gain`` K_k (n, rows)
    and ``h`` (rows, nh_k) in the columns ``hcols``.  For :mod:`calib.session.spectral` (the weights of every
    update on the final estimate)."""

    gain: np.ndarray
    h: np.ndarray
    hcols: np.ndarray
    nh: np.ndarray
    e: np.ndarray
    ecols: np.ndarray
    ne: np.ndarray
    decay: np.ndarray
    updated: np.ndarray
    rows: int = 2


@dataclass(frozen=True)
class FilterRun:
    """B filter runs: final nominal parameters θ̂ (B, 18, ``THETA`` order) and covariance (B, n, n),
    final attitude (B, 4), per-step NIS and innovations (B, N−1[, 3]; NaN where no update), and when
    asked the history of √diag P (B, N−1, n) and θ̂ (B, N−1, 18); the hand's nominals (B, ``HAND_NOMINALS``: lever
    arm r (m, body), last external acceleration x and its low-passes z, z₂ (m/s², nav; a_e = x − z − z₂) — with a
    general shaping filter its state i of nav axis j at 3 + 3i + j) and the whitened innovations L⁻¹ν of the two
    levelling rows (B, N−1, 3; S = L Lᵀ, unit white under the model); ``sensor_extra`` (B, 18): the gyro's
    temperature coefficients c_b (rad/s/°C), s_T (1/°C) and g-sensitivity k (rad/s per m/s²), the
    accelerometer bias's temperature coefficient c_a (m/s²/°C) and its delay behind the gyro δ (s), the gyro's
    misalignment against the accelerometer α (rad), with a layout
    that has those blocks (:data:`calib.session.model.SENSOR_EXTRA_BLOCKS`)."""

    layout: StateLayout
    theta: np.ndarray
    p: np.ndarray
    quat: np.ndarray
    nis: np.ndarray
    innovation: np.ndarray
    sd_history: np.ndarray | None = None
    theta_history: np.ndarray | None = None
    hand: np.ndarray | None = None
    whitened: np.ndarray | None = None
    sensor_extra: np.ndarray | None = None
    record: "FilterRecord | None" = None

    def block(self, name: str) -> np.ndarray:
        """Nominal of a parameter block (B, 3)."""
        return self.theta[:, theta_slice(name)]

    def block_cov(self, name: str) -> np.ndarray:
        """Covariance (B, 3, 3) of a block of the layout."""
        o = self.layout.offset(name)
        return self.p[:, o:o + 3, o:o + 3]


def _shaping(layout: StateLayout, config: FilterConfig, t_s: np.ndarray) -> Shaping:
    """The kernel's general a_e arguments — d = 0 (the x, z, z₂ code) unless the layout carries ``ext_acc_s3`` …
    (the general shaping filter, :meth:`calib.session.model.FilterConfig.ext_acc_model`).  One table entry per
    distinct step (rounded to 1 ns): one for a uniformly sampled recording."""
    nb = len(EXT_ACC_BLOCKS)
    if not any(layout.has(b) for b in EXT_ACC_BLOCKS[3:]):
        if config.ext_acc_band_hz is not None and layout.has("ext_acc"):
            raise ValueError("a band-limited external acceleration (ext_acc_band_hz) needs a layout with "
                             f"{EXT_ACC_BLOCKS} (its five states per axis)")
        return Shaping(0, np.zeros(nb, np.int64), np.zeros(nb), np.zeros(t_s.size, np.int64), np.zeros((1, nb, nb)),
                       np.zeros((1, nb, nb)))
    a, qc, c = config.ext_acc_model()
    d = a.shape[0]
    if d > nb:
        raise ValueError(f"the external acceleration's model has {d} states per axis, at most {nb}")
    if any(not layout.has(b) for b in EXT_ACC_BLOCKS[:d]):
        raise ValueError(f"the external acceleration's model has {d} states per axis: the layout needs "
                         f"{EXT_ACC_BLOCKS[:d]}")
    dts = np.diff(t_s, prepend=t_s[0] - (t_s[1] - t_s[0] if t_s.size > 1 else 0.0))
    uniq, idx = np.unique(np.round(dts, 9), return_inverse=True)
    phi, q = ext_acc_discrete(a, qc, uniq)
    phi5 = np.zeros((uniq.size, nb, nb))
    q5 = np.zeros((uniq.size, nb, nb))
    phi5[:, :d, :d] = phi
    q5[:, :d, :d] = q
    c5 = np.zeros(nb)
    c5[:d] = c
    return Shaping(d, np.array([layout.offset(b) for b in EXT_ACC_BLOCKS], np.int64), c5, idx.astype(np.int64),
                   np.ascontiguousarray(phi5), np.ascontiguousarray(q5))


def _arr(x, dtype=float) -> np.ndarray:
    """A writable C-contiguous copy: numba compiles one specialisation per array type, and a Recording's arrays are
    read-only (a second compile costs ~15 s)."""
    return np.require(np.array(x, dtype=dtype, copy=True), requirements=["C", "W"])


def _per_run(x, shape: tuple, dtype=float) -> np.ndarray:
    """``x`` broadcast to ``shape`` (B, …) as a C-contiguous array."""
    return np.ascontiguousarray(np.broadcast_to(np.asarray(x, dtype), shape))


def _padded(x, size: int, B: int) -> np.ndarray:
    """Nominals (≤ size,) or (B, ≤ size) padded with zeros to (B, size): missing blocks start at 0."""
    v = np.zeros(size) if x is None else np.asarray(x, float)
    if v.shape[-1] < size:
        v = np.concatenate([v, np.zeros(v.shape[:-1] + (size - v.shape[-1],))], axis=-1)
    return _arr(np.broadcast_to(v, (B, size)))


def _block_signals(layout: StateLayout, B: int, N: int, *, lever_regressor, lever_jacobian, temperature_rel_c,
                   specific_force_m_s2, acc_rate_m_s3) -> dict:
    """The per-sample regressors of the layout's extra blocks, (B, N, …), or (B, 1, …) placeholders without them."""
    def body(used: bool, x, need: str) -> np.ndarray:
        if not used:
            return np.zeros((B, 1, 3))
        if x is None:
            raise ValueError(f"a layout with {need}")
        return _arr(np.broadcast_to(np.asarray(x, float), (B, N, 3)))

    if layout.has("lever_arm"):
        if lever_regressor is None:
            raise ValueError("a layout with the lever arm needs lever_regressor (N, 3, 3)")
        lever = _arr(np.broadcast_to(np.asarray(lever_regressor, float), (B, N, 3, 3)))
    else:
        lever = np.zeros((B, 1, 3, 3))
    if lever_jacobian is not None and layout.has("lever_arm"):
        jw = _arr(np.broadcast_to(np.asarray(lever_jacobian.rate_rad_s, float), (B, N, 3)))
        nc = np.shape(lever_jacobian.d_rate)[-1]        # 9: S, G, b; 12 with the misalignment α
        if nc not in (9, 12) or (nc == 12) != layout.models_misalignment:
            raise ValueError(f"lever_jacobian has {nc} columns: 9 (S, G, b), 12 with the layout's gyro_misalign")
        jd = _arr(np.broadcast_to(np.asarray(lever_jacobian.d_rate, float), (B, N, 3, nc)))
        jdd = _arr(np.broadcast_to(np.asarray(lever_jacobian.d_rate_dot, float), (B, N, 3, nc)))
    else:
        jw, jd, jdd = np.zeros((B, 1, 3)), np.zeros((B, 1, 3, 9)), np.zeros((B, 1, 3, 9))
    if layout.models_temperature:
        if temperature_rel_c is None:
            raise ValueError("a layout with a temperature block needs temperature_rel_c (N,), T − T₀ in °C")
        temp = _arr(np.broadcast_to(np.asarray(temperature_rel_c, float), (B, N)))
    else:
        temp = np.zeros((B, N))
    return {"temp_rel": temp,
            "force": body(layout.models_g_sensitivity, specific_force_m_s2,
                          "the gyro's g-sensitivity needs specific_force_m_s2 (N, 3), body, m/s²"),
            "acc_rate": body(layout.models_acc_delay, acc_rate_m_s3,
                             "the accelerometer's delay needs acc_rate_m_s3 (N, 3): ḟ, body, m/s³"),
            "lever": lever, "jac_rate": jw, "jac_d_rate": jd, "jac_d_rate_dot": jdd}


def filter_inputs(gyro: np.ndarray, acc: np.ndarray, t_s: np.ndarray, quat0: np.ndarray, theta0: np.ndarray,
                  p0: np.ndarray, layout: StateLayout, config: FilterConfig, rate_hz: float, *,
                  r_var_per_sample: np.ndarray | None = None, update_mask: np.ndarray | None = None,
                  keep_history: bool = False, gate_nis: float = 0.0, half_window: int | None = None,
                  rest_mask: np.ndarray | None = None, x0: np.ndarray | None = None, rows: int = 2,
                  lever_regressor: np.ndarray | None = None, hand0: np.ndarray | None = None,
                  temperature_rel_c: np.ndarray | None = None, specific_force_m_s2: np.ndarray | None = None,
                  sensor0: np.ndarray | None = None, acc_rate_m_s3: np.ndarray | None = None,
                  lever_jacobian: LeverJacobian | None = None, record: bool = False) -> FilterInputs:
    """:func:`run_filter`'s arguments checked and broadcast to B runs, as the typed tuples the compiled loop reads
    (and :func:`calib.session.reference.run_reference` steps through)."""
    if rows not in (2, 3):
        raise ValueError(f"rows must be 2 or 3, got {rows}")
    g = _arr(gyro)
    B, N = g.shape[:2]
    L = regressor_half_window(rate_hz) if half_window is None else int(half_window)
    greg = np.ascontiguousarray(np.stack([leave_out_means(gb, L, midpoint=True) for gb in g]))
    # at rest the true rate is zero: a regressor of pure gyro noise would "inform" S and G (model docstring)
    still = np.zeros((B, N), dtype=np.bool_) if rest_mask is None else _per_run(rest_mask, (B, N), bool)
    p0 = np.asarray(p0, dtype=float)
    p0 = np.ascontiguousarray(np.broadcast_to(p0, (B, layout.n, layout.n)) if p0.ndim == 2 else p0)
    r_vars = (np.full((B, N), config.r_var(rate_hz)) if r_var_per_sample is None
              else _per_run(r_var_per_sample, (B, N)))
    upd = np.ones((B, N), dtype=np.bool_) if update_mask is None else _per_run(update_mask, (B, N), bool)
    x0 = np.zeros((B, layout.n)) if x0 is None else _per_run(x0, (B, layout.n))
    signals = Signals(g, _arr(acc), _arr(greg), _arr(still, np.bool_), _arr(upd, np.bool_), _arr(r_vars),
                      **_block_signals(layout, B, N, lever_regressor=lever_regressor, lever_jacobian=lever_jacobian,
                                       temperature_rel_c=temperature_rel_c, specific_force_m_s2=specific_force_m_s2,
                                       acc_rate_m_s3=acc_rate_m_s3))
    start = Start(_arr(_per_run(quat0, (B, 4))), _arr(_per_run(theta0, (B, 18))), _arr(x0), _arr(p0),
                  _padded(hand0, HAND_NOMINALS, B), _padded(sensor0, SENSOR_NOMINALS, B))
    settings = Settings(layout.offsets(), np.array([layout.offset(b) for b in SENSOR_EXTRA_BLOCKS], dtype=np.int64),
                        config.arw_rad_s_sqrt_hz**2, float(config.gyro_bias_rw_rad_s_sqrt_s**2), config.gravity_m_s2,
                        float(config.ext_acc_tau_s), float(config.ext_acc_rms_m_s2**2),
                        float(config.ext_acc_highpass_tau_s), int(config.ext_acc_highpass_order),
                        int(rows), float(gate_nis), bool(keep_history), bool(record))
    t = _arr(t_s)
    return FilterInputs(t, signals, start, settings, _shaping(layout, config, t))


def _outputs(start: Start, N: int, keep: bool) -> Outputs:
    """The loop's outputs, before it runs (:class:`Outputs`)."""
    B, n = start.P.shape[:2]
    nk = N - 1 if keep else 0
    return Outputs(start.theta.copy(), start.P.copy(), start.hand.copy(), start.sensor.copy(), np.zeros((B, 4)),
                   np.full((B, N - 1), np.nan), np.full((B, N - 1, 3), np.nan), np.full((B, N - 1, 3), np.nan),
                   np.zeros((B, nk, n)), np.zeros((B, nk, 18)))


def _scratch(n: int, jac_columns: int) -> Scratch:
    """The loop's working arrays (:class:`Scratch`) for n states and the lever arm Jacobian's columns."""
    z33 = [np.zeros((3, 3)) for _ in range(8)]
    return Scratch(np.zeros((9, n)), np.zeros(9), np.zeros((3, E_COLS)), np.zeros(E_COLS, np.int64), np.zeros((3, n)),
                   np.zeros((3, 3)), np.zeros((3, H_COLS)), np.zeros(H_COLS, np.int64), np.zeros((3, jac_columns)),
                   np.zeros(jac_columns), np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, n)),
                   np.zeros((3, 3)), np.zeros((3, 3)), np.zeros(3), np.zeros(n), np.zeros(n), *z33, np.eye(3),
                   np.zeros((3, jac_columns)))


def _record_arrays(n: int, N: int, on: bool) -> RecordArrays:
    """Room for the first run's linear error model (one row per step when ``on``, else placeholders)."""
    nr = N if on else 1
    return RecordArrays(np.zeros((nr, n, 3)), np.zeros((nr, 3, H_COLS)), np.zeros((nr, H_COLS), np.int64),
                        np.zeros(nr, np.int64), np.zeros((nr, 3, E_COLS)), np.zeros((nr, E_COLS), np.int64),
                        np.zeros(nr, np.int64), np.zeros((nr, 2)), np.zeros(nr, np.bool_))


def run_filter(gyro: np.ndarray, acc: np.ndarray, t_s: np.ndarray, quat0: np.ndarray, theta0: np.ndarray,
               p0: np.ndarray, layout: StateLayout, config: FilterConfig, rate_hz: float, **options) -> FilterRun:
    """Run B filters of ``layout`` on raw (B, N, 3) gyro (rad/s) and accelerometer (m/s²) samples.

    ``theta0`` (B, 18) nominal parameters (the static gyro bias goes in its ``gyro_bias`` slot even when the layout does
    not estimate it), ``p0`` (n, n) or (B, n, n), ``quat0`` (B, 4) body→ENU.  Keyword ``options`` (all optional):

    * ``r_var_per_sample``: measurement variance per sample (N,) or (B, N) instead of the config's constant;
      ``update_mask`` (N,) or (B, N): False skips the update of that sample (saturated); ``gate_nis`` > 0 skips every
      update whose NIS exceeds it; ``rest_mask`` (N,): samples known to be at rest, where the rate regressor is zero
      (:mod:`calib.session.model`, "Regressors"); ``half_window``: L of the leave-out rate regressor;
    * ``x0`` (n,) or (B, n): the prior mean as an error state, θ_prior − θ̂₀ (zero: the prior is centred on the
      nominal); ``rows`` = 3 adds the vertical row (the |f| = g information) — for bounds computed at the truth
      (:func:`calib.session.bounds.crlb_joint`) and kf_hand_joint, not for the hand-blind filters, where the gravity
      fit carries it;
    * ``lever_regressor`` (N, 3, 3) or (B, N, 3, 3): K(ω, ω̇) = [ω̇×] + [ω×]² per sample (body), needed by a layout
      with ``lever_arm``; ``hand0`` (≤ 30,) or (B, ≤ 30): the nominal lever arm, external acceleration x and its
      low-passes z, z₂ (missing ones start at 0; a layout with ``ext_acc`` takes the Gauss–Markov σ, τ and the
      high-pass τ_h from ``config``).  A layout with ``ext_acc_s3`` … (:data:`calib.session.model.EXT_ACC_EXTRA_BLOCKS`)
      runs a_e as the general shaping filter of :meth:`calib.session.model.FilterConfig.ext_acc_model` (the
      band-limited sway, or the same Gauss–Markov family), discretised exactly per step;
    * ``sensor0`` (≤ 18,) or (B, ≤ 18): the nominal c_b, s_T, k of the gyro's extra blocks and c_a, δ of the
      accelerometer's, then the gyro's misalignment α (default 0; missing ones 0): a layout with ``gyro_misalign``
      runs the gyro model ω̃ = (M_g − [α×]) ω + b_g (``MISALIGN_BLOCKS``; the lever arm's Jacobian J leaves α out:
      α K r̂ is second order); ``temperature_rel_c`` (N,) or (B, N): T − T₀ (°C), needed by a
      layout with ``gyro_temp_bias`` / ``gyro_temp_scale``: the gyro model is then ω̃ = (M_g + diag(s_T)(T − T₀)) ω +
      b_g + c_b (T − T₀) + ε (``THERMAL_BLOCKS``), and with ``acc_temp_bias`` f̃ = M_a f + b_a + c_a (T − T₀) + v
      (``ACC_THERMAL_BLOCKS``; T at the update's sample); ``specific_force_m_s2`` (N, 3) or (B, N, 3): f (body, m/s²),
      needed by a layout with ``gyro_g_sens``: b_g,i += k_i f_i (``G_SENS_BLOCKS``);
    * ``acc_rate_m_s3`` (N, 3) or (B, N, 3): ḟ̃, the time derivative of the (compensated) specific force (body,
      m/s³), needed by a layout with ``acc_delay``: the accelerometer samples f̃_i(t) = f_i(t − δ_i), so the update
      uses f̃ + diag(δ̂) ḟ̃ and H's δ block is −Ĉ diag(ḟ̃) (first order in δ; ``ACC_DELAY_BLOCKS``);
    * ``lever_jacobian`` (:class:`LeverJacobian`, (N, …) or (B, N, …)): how ``lever_regressor``'s K r̂ moves with the
      gyro's S, G, b — K was computed from the rate compensated at ``theta0``, so the update subtracts K r̂ +
      J (θ̂ − θ₀) and H gets Ĉ J on those states (and on c_b, s_T, k through them).  Without it K r̂ is taken as
      exact: right when S, G are already well determined, but a session that pins S, G only weakly leaves K's error
      in the innovations, correlated with the motion, and σ of S, G optimistic (docs/hand.md, "The lever arm term's
      Jacobian");
    * ``keep_history``: the per-step √diag P and θ̂; ``record``: the first run's linear error model
      (:class:`FilterRecord`, for :mod:`calib.session.spectral`).
    """
    inp = filter_inputs(gyro, acc, t_s, quat0, theta0, p0, layout, config, rate_hz, **options)
    st = inp.settings
    B, N = inp.signals.gyro.shape[:2]
    rec = _record_arrays(layout.n, N, st.record)
    out = _outputs(inp.start, N, st.keep)
    _kernel(inp.t, inp.signals, inp.start, st, inp.shaping, rec, out,
            _scratch(layout.n, inp.signals.jac_d_rate.shape[3]))
    return FilterRun(
        layout, out.theta, out.P, out.quat, out.nis, out.innovation,
        out.sd_history if st.keep else None,
        out.theta_history if st.keep else None,
        out.hand if layout.models_hand else None,
        out.whitened,
        out.sensor if (layout.models_temperature or layout.models_g_sensitivity or layout.models_acc_delay
                 or layout.models_misalignment) else None,
        FilterRecord(*rec, rows=st.rows) if st.record else None,
    )


def warm_up() -> None:
    """Compile the loop (or load it from numba's cache) by running the paper's filter on 3 still samples: every layout
    and option reaches :func:`_kernel` with the same argument types (:func:`filter_inputs` makes each array float64,
    int64 or bool, C-contiguous, of a fixed rank), so this one compile serves them all."""
    config = FilterConfig(arw_rad_s_sqrt_hz=1e-4, vrw_m_s2_sqrt_hz=1e-3)
    acc = np.zeros((1, 3, 3))
    acc[..., 2] = config.gravity_m_s2
    run_filter(np.zeros((1, 3, 3)), acc, np.arange(3) / 100.0, np.array([1.0, 0.0, 0.0, 0.0]), np.zeros(18),
               initial_covariance(PAPER, config), PAPER, config, 100.0)


@dataclass(frozen=True)
class BatchResult:
    """Final estimates (B, 3) and covariance (B, 9, 9) of B runs of the paper's filter; √diag P
    history (N−1, B, 9) when asked."""

    scale: np.ndarray
    nonorthogonality: np.ndarray
    p: np.ndarray
    sd_history: np.ndarray | None


def run_batch(
    gyro_minus_bias: np.ndarray,
    acc: np.ndarray,
    t_s: np.ndarray,
    quat0: np.ndarray,
    config: FilterConfig,
    rate_hz: float,
    *,
    scale0: np.ndarray | None = None,
    nonortho0: np.ndarray | None = None,
    keep_history: bool = False,
    r_var_per_sample: np.ndarray | None = None,
    gate_nis: float = 0.0,
) -> BatchResult:
    """Zhou 2020's 9-state filter (:data:`calib.session.model.PAPER`) on B runs of bias-removed gyro and
    accelerometer samples (B, N, 3); ``scale0``/``nonortho0`` (B, 3) initial estimates (default: the
    config's).  A thin wrapper of :func:`run_filter` (mitigations: ``r_var_per_sample``, ``gate_nis``)."""
    g = np.asarray(gyro_minus_bias, float)
    B = g.shape[0]
    theta0 = np.zeros((B, 18))
    theta0[:, theta_slice("gyro_scale")] = config.scale0 if scale0 is None else scale0
    theta0[:, theta_slice("gyro_nonorth")] = config.nonorthogonality0 if nonortho0 is None else nonortho0
    run = run_filter(g, acc, t_s, quat0, theta0, initial_covariance(PAPER, config), PAPER, config, rate_hz,
                     r_var_per_sample=r_var_per_sample, keep_history=keep_history, gate_nis=gate_nis)
    hist = None if run.sd_history is None else np.transpose(run.sd_history, (1, 0, 2))
    return BatchResult(run.block("gyro_scale"), run.block("gyro_nonorth"), run.p, hist)
