"""The sensor's temperature in ``kf_hand``: the session's temperature channel, where each axis's scale factor and the
accelerometer's bias were determined, and the temperature report.

* the scale factor's temperature dependence (``gyro_temp_scale``), when the recording has a temperature channel that
  moved ≥ ``THERMAL_MIN_SPAN_C`` (a board warming after power-on): S_i(T) = S_i(T₀) + s_T,i (T − T₀), three states with
  a vague prior.  A session spanning a degree cannot measure s_T, but it does pin S_i at the temperature where axis i's
  rotations happened (:func:`scale_at_temperature`), and that is what is reported, with the temperatures, in
  ``diagnostics["temperature"]`` — a scale factor holds at a temperature (measured on the MPU-9250 preset, zhou2020
  schedule: 25.40, 25.24, 25.62 °C for x, y, z in a session warming from 25.0 to 25.85 °C; the constant-S filter's
  estimates are S at the same temperatures, it just did not say so);
* on a warming sensor the gyro bias's warm-up ramp in its own shape, b_g(T) = b_g + c_b (T − T₀), three states
  (``HandParams.gyro_temp_bias``; its prior: :func:`calib.session.hand.priors.temp_bias_prior`);
* with the accelerometer estimated (``kf_hand_joint``) and a temperature channel that moved: the accelerometer bias's
  temperature dependence, b_a(T) = b_a(T₀) + c_a (T − T₀) (``acc_temp_bias``, three states, prior σ 0.1 m/s²/°C) — the
  "zero-g level change vs. temperature" of a MEMS accelerometer (InvenSense PS-MPU-9250A-01 rev 1.1: ±1.5 mg/°C), first
  order over a session's degree as the temperature-point compensation of an IMU's acceleration-channel zero bias is
  piecewise linear (ERICCO, *Measurement Error and Calibration of FOG IMU*, §4; polynomial temperature-drift models in
  T − T_ref: Qi et al. 2020, *Modification of MTEA-Based Temperature Drift Error Compensation Model for MEMS-Gyros*, and
  the Qi et al. 2017 model for MEMS capacitive accelerometers it builds on) — and the gyro scale's s_T as above.
  Without it a warming board's bias drift (MPU-9250 preset: 0.5 mg/°C σ over 25.0 → 25.85 °C) sat in the filter's
  constant b_a and bent the attitude it levels, so σ of S, G was ~25 % small (Monte Carlo NEES 9.3 against [5.08,
  7.00]).  b_a is reported at the temperatures T_a,i where it decouples from c_a (:func:`acc_bias_at_temperature`) and
  the compensation of every sample uses b_a(T(t)); the initial tilt, levelled on the first rest's mean, carries c_a's
  error through the rest's T − T₀ in P₀.  Without a temperature channel nothing models the drift (measured: NEES(6)
  8.3 ideal hand, 7.2 typical on that preset with the channel removed; docs/hand.md).
"""

from __future__ import annotations

import numpy as np

from calib.session.model import StateLayout

__all__ = ["THERMAL_MIN_SPAN_C", "THERMAL_SMOOTH_S", "smoothed_temperature", "rest_temperature",
           "session_temperature", "scale_at_temperature", "decoupling_temperature", "acc_bias_at_temperature",
           "temperature_report"]


# the scale factor's temperature coefficient is a state when the session's temperature moved this much
THERMAL_MIN_SPAN_C = 0.2


THERMAL_SMOOTH_S = 2.0     # the temperature channel is averaged over this window (its quantisation and noise)


def smoothed_temperature(temp_c: np.ndarray, rate_hz: float) -> np.ndarray:
    """The temperature channel averaged over ``THERMAL_SMOOTH_S`` (as :func:`session_temperature`), °C."""
    from scipy.ndimage import uniform_filter1d

    return uniform_filter1d(
        np.asarray(temp_c, float), size=max(1, int(round(THERMAL_SMOOTH_S * rate_hz))), mode="nearest"
    )


def rest_temperature(temp_c: np.ndarray, rate_hz: float, a: int, b: int) -> float:
    """Mean of the smoothed temperature channel over the rest [a, b), °C."""
    return float(np.mean(smoothed_temperature(temp_c, rate_hz)[a:b]))


def session_temperature(temp_c: np.ndarray | None, rate_hz: float) -> tuple[np.ndarray, float] | None:
    """(T − T₀ (N,), T₀) of a recording's temperature channel over the filtered span, or None when it has
    none or it moved less than ``THERMAL_MIN_SPAN_C`` (then S is a constant, as before).  T is averaged over
    ``THERMAL_SMOOTH_S`` (a thermometer's LSB and noise; the sensor's temperature moves over minutes), T₀ its
    mean (the filter's reference: keeps the regressor ω (T − T₀) centred)."""
    from scipy.ndimage import uniform_filter1d

    if temp_c is None:
        return None
    t = np.asarray(temp_c, float)
    if t.size < 2 or not np.all(np.isfinite(t)):
        return None
    ts = uniform_filter1d(t, size=max(1, int(round(THERMAL_SMOOTH_S * rate_hz))), mode="nearest")
    if float(ts.max() - ts.min()) < THERMAL_MIN_SPAN_C:
        return None
    t0 = float(ts.mean())
    return ts - t0, t0


def scale_at_temperature(P: np.ndarray, layout: StateLayout, t0_c: float) -> tuple[np.ndarray, np.ndarray]:
    """The temperatures T_r (3,) at which the session determined each axis's gyro scale factor best, and the
    map J (6, n) from the error state to [S(T_r), G]: with S_i(T) = S_i(T₀) + s_T,i (T − T₀) (the
    ``gyro_temp_scale`` block),

        Var S_i(T) = P_SS,ii + 2 (T − T₀) P_Ss,ii + (T − T₀)² P_ss,ii,   minimal at T_r,i = T₀ − P_Ss,ii / P_ss,ii

    — the temperature at which axis i's rotations happened, weighted by what they taught (the centre of the
    regressor ω_i (T − T₀)'s information, where S_i and s_T,i decouple).  A gyro's scale factor moves with
    temperature (the MPU-9250's datasheet: ±4 % over −40…85 °C) and a session that warms by a degree cannot
    measure that coefficient (its σ is tens of times the coefficient itself), so the calibration is valid at a
    temperature and says which: S_i is reported at T_r,i.  Without the block: (T₀ on every axis, the plain
    selection of S, G)."""
    n = P.shape[0]
    J = np.zeros((6, n))
    J[:, 3:9] = np.eye(6)
    o = layout.offset("gyro_temp_scale")
    if o < 0:
        return np.full(3, t0_c), J
    pss = np.diag(P[o:o + 3, o:o + 3])
    psS = np.diag(P[3:6, o:o + 3])
    d = -psS / np.where(pss > 0, pss, np.inf)
    J[0:3, o:o + 3] = np.diag(d)
    return t0_c + d, J


def decoupling_temperature(P: np.ndarray, o_value: int, o_coef: int) -> np.ndarray:
    """d_i = −P_vc,ii / P_cc,ii (3,): the offset from T₀ at which the value v_i(T) = v_i(T₀) + c_i (T − T₀) has its
    smallest variance P_vv,ii + 2 (T − T₀) P_vc,ii + (T − T₀)² P_cc,ii (there v_i and c_i are uncorrelated)."""
    pcc = np.diag(P[o_coef:o_coef + 3, o_coef:o_coef + 3])
    pvc = np.diag(P[o_value:o_value + 3, o_coef:o_coef + 3])
    return -pvc / np.where(pcc > 0, pcc, np.inf)


def acc_bias_at_temperature(P: np.ndarray, layout: StateLayout, t0_c: float) -> tuple[np.ndarray, np.ndarray]:
    """The temperatures T_a (3,) at which the session determined each axis's accelerometer bias best, and the
    map J (3, n) from the error state to b_a(T_a): with the ``acc_temp_bias`` block,

        b_a(T) = b_a(T₀) + c_a (T − T₀),   T_a,i = T₀ − P_bc,ii / P_cc,ii

    (the accelerometer's "zero-g level change vs. temperature", a first-order coefficient in mg/°C: the
    MPU-9250's ±1.5 mg/°C, PS-MPU-9250A-01; linear between temperature points as in the acceleration channel's
    zero-bias temperature compensation of ERICCO's *Measurement Error and Calibration of FOG IMU* §4, the first term
    of the T − T_ref polynomial drift models of Qi et al. 2020, *Modification of MTEA-Based Temperature Drift Error
    Compensation Model for MEMS-Gyros*).  As for the gyro's scale factor (:func:`scale_at_temperature`) a session
    warming by a degree measures c_a poorly but pins b_a where its attitudes were held, and says where.
    Without the block: (T₀ on every axis, the plain selection of b_a)."""
    n = P.shape[0]
    ob, oc = layout.offset("acc_bias"), layout.offset("acc_temp_bias")
    J = np.zeros((3, n))
    if ob < 0:
        return np.full(3, t0_c), J
    J[:, ob:ob + 3] = np.eye(3)
    if oc < 0:
        return np.full(3, t0_c), J
    d = decoupling_temperature(P, ob, oc)
    J[:, oc:oc + 3] = np.diag(d)
    return t0_c + d, J


def temperature_report(thermal: tuple[np.ndarray, float] | None, t_ref_c: np.ndarray, sens: np.ndarray, P: np.ndarray,
                        layout, inflation: float, t_ref_acc_c: np.ndarray | None = None) -> dict:
    """``diagnostics["temperature"]``: the temperature S is reported at and the scale factor's temperature
    coefficient found (a finding for the user: it says how far from this temperature the calibration holds); with
    the accelerometer estimated (``acc_temp_bias``) the same for its bias: ``acc_bias_reference_temperature_c`` and
    ``acc_bias_temperature_coefficient_m_s2_per_c``.  ``modelled``: a temperature block is in the filter;
    ``scale_reference_temperature_c`` is present only when the gyro scale's is (Monte Carlo scores S there)."""
    if thermal is None:
        return {"modelled": False, "reason": f"no temperature channel, or it moved less than {THERMAL_MIN_SPAN_C} °C"}
    dT, t0 = thermal
    out: dict = {"modelled": True, "filter_reference_temperature_c": t0,
                 "span_c": [t0 + float(dT.min()), t0 + float(dT.max())]}
    note = (f"temperature: the session warmed {float(dT.max() - dT.min()):.2f} °C ({t0 + float(dT.min()):.2f}–"
            f"{t0 + float(dT.max()):.2f} °C)")
    ob = layout.offset("gyro_temp_bias")
    if ob >= 0:
        c_b = sens[0:3]
        cb_sd = np.sqrt(np.diag(P[ob:ob + 3, ob:ob + 3]) * inflation)
        out.update({"bias_temperature_coefficient_rad_s_per_c": c_b.tolist(),
                    "bias_temperature_coefficient_std_rad_s_per_c": cb_sd.tolist()})
        note += ("; the gyro bias is modelled as b_g + c_b (T − T₀): c_b = "
                 f"{np.array2string(np.degrees(c_b), precision=3)}"
                 f" ± {np.array2string(np.degrees(cb_sd), precision=3)} °/s/°C")
    o = layout.offset("gyro_temp_scale")
    if o >= 0:
        s_t = sens[3:6]
        s_sd = np.sqrt(np.diag(P[o:o + 3, o:o + 3]) * inflation)
        out.update({"scale_reference_temperature_c": np.asarray(t_ref_c).tolist(),
                    "scale_temperature_coefficient_per_c": s_t.tolist(),
                    "scale_temperature_coefficient_std_per_c": s_sd.tolist()})
        note += (
            f"; the gyro scale factor is modelled as S + s_T (T − T₀) and reported at "
            f"{np.array2string(np.asarray(t_ref_c), precision=2)} °C (x, y, z: where this session's rotations about "
            "each axis determined it; a scale factor holds at a temperature); s_T = "
            f"{np.array2string(s_t * 1e6, precision=0)} ± {np.array2string(s_sd * 1e6, precision=0)} ppm/°C (a session "
            "spanning a degree cannot measure it: a calibration at two temperatures can)"
        )
    oc = layout.offset("acc_temp_bias")
    if oc >= 0 and t_ref_acc_c is not None:
        c_a = sens[9:12]
        c_sd = np.sqrt(np.diag(P[oc:oc + 3, oc:oc + 3]) * inflation)
        out.update({"acc_bias_reference_temperature_c": np.asarray(t_ref_acc_c).tolist(),
                    "acc_bias_temperature_coefficient_m_s2_per_c": c_a.tolist(),
                    "acc_bias_temperature_coefficient_std_m_s2_per_c": c_sd.tolist()})
        mg = 1e3 / 9.80665
        note += (
            f"; the accelerometer bias is modelled as b_a + c_a (T − T₀) and reported at "
            f"{np.array2string(np.asarray(t_ref_acc_c), precision=2)} °C (x, y, z: where this session's attitudes "
            f"determined it); c_a = {np.array2string(c_a * mg, precision=2)} ± "
            f"{np.array2string(c_sd * mg, precision=2)} mg/°C"
        )
    out["note"] = note
    return out

