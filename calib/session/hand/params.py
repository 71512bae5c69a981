"""``kf_hand``'s parameters (:class:`HandParams`) and its state layouts (:func:`hand_layout`, :func:`joint_layout`).

An experiment on the hand-aware method is a changed field of :class:`HandParams` passed to
:func:`calib.session.hand.filter.kf_hand` — ``kf_hand(rec, params=HandParams(spectral_sigma=False))`` — never an edit
of a module constant; the defaults are the validated method (docs/hand.md measures each).
"""

from __future__ import annotations

from dataclasses import dataclass

from calib.session.drift import DRIFT_QUANTILE
from calib.session.hand.lowpass import CUTOFF_HZ, ORDER
from calib.session.hand.sway import BAND_ORDER, SWAY_MODELS
from calib.session.model import (
    ACC_DELAY_BLOCKS,
    EXT_ACC_EXTRA_BLOCKS,
    G_SENS_BLOCKS,
    HAND_BIAS,
    HAND_JOINT,
    MISALIGN_BLOCKS,
    StateLayout,
)

__all__ = ["HandParams", "hand_layout", "joint_layout"]


@dataclass(frozen=True)
class HandParams:
    """The hand-aware method's parameters (defaults: the validated ``kf_hand`` / ``kf_hand_joint``).

    ``cutoff_hz``, ``order``: the tremor pre-filter (:mod:`calib.session.hand.lowpass`), a zero-phase Butterworth of
    ``order`` poles at ``cutoff_hz`` (Hz) — below the tremor band (8–12 Hz), above the rotations (< 1 Hz).
    ``passes``: the filter passes, each linearised at the previous one's estimate (the a_e model fitted from pass 2).
    ``sway``: the a_e family fitted from pass 2 on — "gauss_markov" (the high-passed Gauss–Markov,
    :func:`calib.session.hand.sway.fit_gauss_markov`) or "band" (opt-in, calibrated accelerometer only: a Gauss–Markov
    floor + a Butterworth band-pass, :func:`calib.session.hand.sway.fit_band`).
    ``g_sensitivity``: the gyro's g-sensitivity is a state (opt-in: on the measured x-IMU3 hand-held session it took
    the lever arm's information, r̂ 5.3 → 2.0 cm, σ ×2.5–3; on the MPU-9250 preset it brought NEES into its band).
    ``delay``: the accelerometer's delay behind the gyro is a state (one δ for the triad).
    ``spectral_sigma``: P corrected to the slow residual's measured spectrum (:mod:`calib.session.spectral`); False:
    the model's P, for the before/after measurements of docs/hand.md.  ``prefilter_reference``: the correction's
    reference is the a_e model as the low-passed data can carry it (no aliases); False: the filter's folded model, as
    before (docs/hand.md).
    ``gyro_temp_bias``: kf_hand on a warming sensor (the temperature moved ≥
    :data:`calib.session.hand.thermal.THERMAL_MIN_SPAN_C`) carries the gyro bias's temperature coefficient c_b,
    b_g(T) = b_g + c_b (T − T₀) — the warm-up's ramp in its own shape, not a random walk fitted to its end-to-end
    change.  ``qb_ladder``: with c_b a state the random walk keeps what c_b does not explain, which two rests cannot
    measure (three degrees of freedom, c_b has three): the last pass tries q_b = λ q̂_b for λ in this ladder and keeps
    the first whose innovations pass κ̂'s test (:func:`calib.session.consistency.innovation_inflation`; the last λ when
    none does).  Measured (MPU-9250 preset, ideal hand, kf_hand, 4 × 50 seeds, NEES(6), 200-seed band [5.52, 6.48]):
    the random walk alone 4.75; c_b with (1,) 4.75, (0.5, 1) 5.75, (0.25, 1) 6.34, (1/16, 1/4, 1) 6.9 over 100 seeds;
    fixed λ = 0.25 6.13 with 3 of 100 seeds "inconsistent", λ = 0 5.3 with 45 of 100 (docs/hand.md, "The warm-up's
    ramp as a state").
    ``joint_gyro_thermal``: kf_hand_joint on a warming sensor carries the gyro scale's s_T as well as the
    accelerometer bias's c_a (docs/hand.md, "kf_hand_joint").  ``joint_gyro_temp_bias``: … and the gyro bias's c_b
    (off): measured (MPU-9250, 50 seeds per hand) it took kf_hand_joint's NEES(6) from 5.59, 5.60, 5.67, 5.88 to 6.58,
    6.59, 6.70, 6.89 — in band — but its NEES(15) with the accelerometer from 15.85, 16.18, 16.26, 14.35 to 17.14,
    17.42, 17.63, 15.74 against [13.52, 16.56]: the accelerometer's own σ is ~1.2× small there (z RMS of b_a, S_a,x,
    S_a,y 1.13–1.33, unchanged by c_b), which the gyro's cautious σ had hidden (docs/hand.md, "The warm-up's ramp as a
    state").  S_a's share was its scoring at ±g instead of the force the session saw (acc_scale_reference_force since:
    NEES(15) without c_b 14.93, 15.30, 15.56, 13.85); b_a's share of the accelerometer's nonlinearity remains (z RMS
    1.21 on x), so c_b stays off there until that is stated too.
    ``drift_quantile``: the rests' bias differences must exceed their white-noise χ² quantile to be modelled as drift
    (:func:`calib.session.drift.bias_drift`).
    ``misalignment``: the gyro triad's rotation against the accelerometer's, α (rad), is a state (three angles,
    prior σ :attr:`calib.session.model.FilterConfig.prior_gyro_misalign_rad`): ω̃ = (I + diag(S) + N(G) − [α×]) ω + b,
    kept when the motion determines it (:data:`calib.session.hand.filter.MISALIGNMENT_OBSERVED_RAD`).  None
    (default): on with the accelerometer estimated (kf_hand_joint, ``calib run``'s default: the accelerometer's frame
    is then the body's, and the independent generator's hand cells hold α's σ honest — NEES(3) 6.9 over 4 seeds),
    except on noise-free input (its floor lets α take the discretisation error); off with it calibrated (kf_hand: its
    NEES cells are not yet measured with α).
    ``accelerometer_source``: what calibrated the accelerometer the recording is read through (e.g. a protocol's
    six box-face poses), for the check of kf_hand's calibrated-accelerometer assumption to name; None: the
    accelerometer is assumed calibrated (by its maker, or by the user before the session).
    """

    cutoff_hz: float = CUTOFF_HZ
    order: int = ORDER
    passes: int = 3
    sway: str = "gauss_markov"
    g_sensitivity: bool = False
    delay: bool = True
    spectral_sigma: bool = True
    prefilter_reference: bool = True
    gyro_temp_bias: bool = True
    qb_ladder: tuple[float, ...] = (0.5, 1.0)
    joint_gyro_thermal: bool = True
    joint_gyro_temp_bias: bool = False
    drift_quantile: float = DRIFT_QUANTILE
    misalignment: bool | None = None
    accelerometer_source: str | None = None

    def __post_init__(self) -> None:
        if self.sway not in SWAY_MODELS:
            raise ValueError(f"sway must be one of {SWAY_MODELS}, got {self.sway!r}")
        if self.passes < 1:
            raise ValueError(f"passes must be at least 1, got {self.passes}")
        if not self.qb_ladder:
            raise ValueError("qb_ladder needs at least one factor (1.0: the rests' q_b as measured)")


def hand_layout(temperature: bool, g_sensitivity: bool = False, band: bool = False, delay: bool = True,
                gyro_temp_bias: bool = True, misalignment: bool = False) -> StateLayout:
    """kf_hand's states: :data:`calib.session.model.HAND_BIAS` (attitude, S, G, gyro bias, lever arm, x, z, z₂), then
    the bias's and the scale factor's temperature coefficients c_b (``gyro_temp_bias``, :class:`HandParams`) and s_T
    when the session's temperature moved (``temperature``), then with ``g_sensitivity`` the gyro's g-sensitivity
    (diagonal: b_g,i = b_i + k_i f_i, f the specific force), then with ``delay`` (default) the accelerometer's delay
    behind the gyro (``acc_delay``: one δ, :func:`calib.session.hand.priors.common_delay_prior`) — 27 to 36 states
    (24 to 33 without δ).  ``band``: the band-limited sway's extra shaping-filter states
    (:data:`calib.session.model.EXT_ACC_EXTRA_BLOCKS`; with x, z, z₂ they hold the floor and the band-pass's
    2·``BAND_ORDER`` states per nav axis).  ``misalignment``: the gyro triad's rotation against the accelerometer's
    (``gyro_misalign``, 3 states; :data:`calib.session.model.MISALIGN_BLOCKS`)."""
    return StateLayout(
        HAND_BIAS.blocks
        + (("gyro_temp_bias",) if temperature and gyro_temp_bias else ())
        + (("gyro_temp_scale",) if temperature else ())
        + (G_SENS_BLOCKS if g_sensitivity else ())
        + (EXT_ACC_EXTRA_BLOCKS[: 2 * BAND_ORDER - 2] if band else ())
        + (ACC_DELAY_BLOCKS if delay else ())
        + (MISALIGN_BLOCKS if misalignment else ())
    )


def joint_layout(temperature: bool, gyro_thermal: bool | None = None, delay: bool = True,
                 gyro_temp_bias: bool | None = None, misalignment: bool = False) -> StateLayout:
    """kf_hand_joint's states: :data:`calib.session.model.HAND_JOINT` (33), and when the session's temperature moved
    (``temperature``) the accelerometer bias's temperature coefficient c_a (``acc_temp_bias``, 3 states) and —
    ``gyro_thermal``, default :class:`HandParams`'s ``joint_gyro_thermal`` (on) — the gyro scale's s_T
    (``gyro_temp_scale``, as kf_hand), and with ``gyro_temp_bias`` (default ``joint_gyro_temp_bias``, off) the gyro
    bias's c_b as kf_hand, and with ``delay`` (default) the accelerometer's delay δ (as kf_hand): 36, 39 or 42 states
    (33, 36 or 39 without δ; 3 more with c_b; 3 more with the gyro's ``misalignment`` against the accelerometer)."""
    dl = (ACC_DELAY_BLOCKS if delay else ()) + (MISALIGN_BLOCKS if misalignment else ())
    if not temperature:
        return StateLayout(HAND_JOINT.blocks + dl)
    defaults = HandParams()
    gt = defaults.joint_gyro_thermal if gyro_thermal is None else gyro_thermal
    cb = defaults.joint_gyro_temp_bias if gyro_temp_bias is None else gyro_temp_bias
    return StateLayout(HAND_JOINT.blocks + (("gyro_temp_bias",) if cb else ())
                       + (("gyro_temp_scale",) if gt else ()) + ("acc_temp_bias",) + dl)
