"""Monte Carlo of the calibration against the Cramér–Rao bound (the accuracy tables of the docs).

For one schedule, hand and sensor preset: R sessions (seeds), each a device drawn from the preset
with its own noise, calibrated by each method asked (below); per parameter the
mean error, RMSE, √CRLB, the efficiency RMSE/√CRLB and the RMS of err/σ (1 when σ is honest);
the paper's Table 8–9 absolute errors beside the gyro's; and the normalised estimation error
squared (NEES) against its χ² band, over the 6 gyro filter parameters (S, G) and over all
parameters the calibration reports (gyro b, S, G and, when estimated, the accelerometer's).

* The ideal hand's motion is deterministic, so its MuJoCo truth is simulated once and only the
  sensor differs between seeds; other hands simulate a session per seed.
* ``calibrated_accelerometer``: keep only the accelerometer's white noise, as Zhou §3.3.2 assumes
  ("the accelerometer has been well calibrated"); with the raw MPU-9250 accelerometer and
  ``accelerometer="calibrated"`` the gravity reference is tilted by up to 3.5° and the result is
  flagged (status ``inconsistent``).
* CRLB: :func:`calib.session.bounds.crlb_joint` at the truth trajectory of the first seed and the first
  device, with the noise levels the calibration estimated (all three measurement rows: the bound
  of the full model); for the static bias σ²/n of the rest average.  With the accelerometer
  calibrated the layout is the paper's and the bias is the static average.
* Methods: every registered estimator (:data:`gyrosim.estimator.BUILTIN_ESTIMATORS`: ``kf`` is the
  paper's filter, ``iterated`` it in three re-linearised passes, ``kf_hand`` the hand-aware one, …,
  or ``package.module:attribute``) and ``kf_session`` / ``iterated_session`` (``calib run``'s filter,
  :func:`calib.session.paper.calibrate`, with the ``accelerometer`` mode asked).  A name means the same
  algorithm here, in ``calib run`` and in a campaign.  Each sees only the recording, as a user's file would be
  (:func:`as_user_file`: samples and rate; no truth, no sensor model, no hand).
* The hand-aware bound (with the accelerometer estimated: when a hand-aware method ran, with the
  accelerometer's nine states vague — :func:`calib.session.bounds.hand_crlb`'s ``estimate_accelerometer``): the
  same Riccati recursion with the :data:`calib.session.model.HAND` layout — the lever arm as three nuisance
  parameters with a vague prior, the slow external acceleration a Gauss–Markov process with the PSD ``kf_hand``
  estimated on the first seed (median σ_s, τ over the seeds), the measurement the tremor-free, decimated one
  ``kf_hand`` uses (:func:`calib.session.bounds.hand_crlb`).  Efficiency is reported against both bounds: the ideal
  one (the sensor's white noise only, no hand: what a perfect hand would allow) and the hand-aware one (what this
  hand allows any unbiased estimator).
* Each method's hand bound is that of the quantity it is scored on (``sqrt_crlb_hand_by_method``): on a sensor
  whose scale factor moves with the session's temperature, a method that states S at temperatures T_r
  (``kf_hand``) is scored and bounded there; one that states none (``kf``) is scored at the oracle's S, the
  device's at its reference temperature, and bounded there — the Bayesian bound with the preset's per-device
  spread of the coefficient (:func:`_with_population_prior`; the filter's vague prior would make it the prior's
  extrapolation, not the data's).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np
from scipy import stats

from gyrosim.calibration import truth_calibration
from gyrosim.errors import GyrosimError, RecordingError
from gyrosim.estimator import as_user_file, estimated_triads, load_estimator
from gyrosim.hand import Hand, load_hand
from gyrosim.rotations import quat_conjugate, quat_rotate
from gyrosim.schedule import load_schedule
from gyrosim.sensor_model import load_sensor
from gyrosim.simulate import apply_sensor, simulate_truth
from gyrosim.strapdown import integrate_gyro

from calib.session.bounds import crlb_joint, hand_crlb, hand_crlb_layout
from calib.session.hand.thermal import acc_bias_at_temperature, scale_at_temperature, session_temperature
from calib.session.model import (
    HAND_JOINT,
    JOINT,
    PAPER,
    FilterConfig,
)
from calib.session.paper import METHODS, REGISTERED_NAME, calibrate, prepare

__all__ = ["MonteCarloResult", "MethodStats", "monte_carlo", "PAPER_ABS_ERROR", "PARAMS", "as_user_file", "hand_crlb",
           "hand_crlb_layout"]

GYRO_PARAMS = ("bias_x", "bias_y", "bias_z", "S_x", "S_y", "S_z", "G_x", "G_y", "G_z")
ACC_PARAMS = ("acc_b_x", "acc_b_y", "acc_b_z", "acc_S_x", "acc_S_y", "acc_S_z", "acc_G_x", "acc_G_y", "acc_G_z")
PARAMS = GYRO_PARAMS
# Zhou 2020 Table 8 (bias, °/s → rad/s) and Table 9 (S, G): absolute errors of their one run
PAPER_ABS_ERROR = np.array([math.radians(0.05), math.radians(0.04), math.radians(0.06),
                            0.00196, 0.0005, 0.0011, 0.0017, 0.0002, 0.0004])


@dataclass(frozen=True)
class MethodStats:
    """Per-parameter statistics of one method over the seeds (SI: rad/s and m/s² for biases)."""

    mean_error: np.ndarray
    rmse: np.ndarray
    efficiency: np.ndarray
    nees_mean: float
    nees_band: tuple[float, float]
    z_rms: np.ndarray = field(default_factory=lambda: np.zeros(0))
    nees_all_mean: float = float("nan")
    nees_all_band: tuple[float, float] = (float("nan"), float("nan"))
    statuses: dict[str, int] = field(default_factory=dict)
    efficiency_hand: np.ndarray = field(default_factory=lambda: np.zeros(0))
    # NEES of every parameter but the gyro bias (the filter's estimates: 15 with the accelerometer estimated —
    # S, G and the accelerometer's nine; the gyro bias is the rest's average, scored apart)
    nees_filter_mean: float = float("nan")
    nees_filter_band: tuple[float, float] = (float("nan"), float("nan"))
    # seeds whose status is "ok" but whose S, G error its own σ does not cover: NEES(6) above χ²₆'s 99.9 %
    # quantile (22.5; an honest σ puts 1 seed in 1000 there) — an answer a user would trust and should not
    ok_wrong: int = 0


@dataclass(frozen=True)
class MonteCarloResult:
    """What :func:`monte_carlo` found for one schedule, hand and sensor: the parameters' mean truth, the
    ideal and hand-aware √CRLB, and each method's statistics over the seeds (SI)."""

    schedule: str
    hand: str
    sensor: str
    seeds: int
    truth_mean: np.ndarray
    sqrt_crlb: np.ndarray
    methods: dict[str, MethodStats] = field(default_factory=dict)
    accelerometer: str = "calibrated"
    names: tuple[str, ...] = GYRO_PARAMS
    sqrt_crlb_hand: np.ndarray = field(default_factory=lambda: np.zeros(0))
    hand_psd: dict = field(default_factory=dict)
    # per method, the hand bound of the quantity that method is scored against (differs from sqrt_crlb_hand only
    # for S on a warming sensor: S at the temperatures a method states, else at the oracle's reference)
    sqrt_crlb_hand_by_method: dict = field(default_factory=dict)

    def summary(self) -> str:
        """One line per method: max RMSE of S and G, max efficiency (ideal / hand bound) over S, G, NEES."""
        rows = [f"{'method':<18} {'S,G RMSE max':>12} {'eff. ideal':>10} {'eff. hand':>10} {'NEES(6)':>8} "
                f"{'95 % band':>13} {'statuses':<}"]
        for m, st in self.methods.items():
            eh = float(np.max(st.efficiency_hand[3:9])) if st.efficiency_hand.size else float("nan")
            rows.append(f"{m:<18} {float(np.max(st.rmse[3:9])):>12.2e} {float(np.max(st.efficiency[3:9])):>10.2f} "
                        f"{eh:>10.2f} {st.nees_mean:>8.2f} [{st.nees_band[0]:.2f}, {st.nees_band[1]:.2f}] "
                        + ", ".join(f"{k} {v}" for k, v in sorted(st.statuses.items())))
        return "\n".join(rows)

    def table(self) -> str:
        """A plain-text table (gyro bias in °/s, accelerometer bias in mg)."""
        scale = np.array(
            [180 / math.pi] * 3 + [1.0] * 6 + ([1000 / 9.80665] * 3 + [1.0] * 6 if len(self.names) > 9 else [])
        )
        hand = self.sqrt_crlb_hand.size > 0
        head = f"{'param':<9} {'true':>9} {'√CRLB':>9} " + (f"{'√CRLB hand':>10} " if hand else "") + " ".join(
            f"{m + ' mean err':>13} {m + ' RMSE':>10} {m + ' eff.':>8} " + (f"{m + ' eff.h':>9} " if hand else "")
            + f"{m + ' z RMS':>9}" for m in self.methods) + f" {'paper |err|':>11}"
        rows = [f"Monte Carlo: {self.schedule}, hand {self.hand}, sensor {self.sensor}, accelerometer "
                f"{self.accelerometer}, "
                f"{self.seeds} seeds (gyro bias °/s, accelerometer bias mg; efficiency = RMSE/√CRLB; z = err/σ)", head]
        for i, name in enumerate(self.names):
            cells = [f"{name:<9} {self.truth_mean[i] * scale[i]:>9.5f} {self.sqrt_crlb[i] * scale[i]:>9.5f}"
                     + (f" {self.sqrt_crlb_hand[i] * scale[i]:>10.5f}" if hand else "")]
            for st in self.methods.values():
                cells.append(f"{st.mean_error[i] * scale[i]:>13.5f} {st.rmse[i] * scale[i]:>10.5f} "
                             f"{st.efficiency[i]:>8.2f} "
                             + (f"{st.efficiency_hand[i]:>9.2f} " if hand else "") + f"{st.z_rms[i]:>9.2f}")
            cells.append(f"{PAPER_ABS_ERROR[i] * scale[i]:>11.5f}" if i < 9 else f"{'':>11}")
            rows.append(" ".join(cells))
        for m, st in self.methods.items():
            rows.append(
                f"NEES ({m}, 6 gyro filter parameters): mean {st.nees_mean:.2f}, 95 % band "
                f"[{st.nees_band[0]:.2f}, {st.nees_band[1]:.2f}]; all {len(self.names)} parameters: mean "
                f"{st.nees_all_mean:.2f}, band [{st.nees_all_band[0]:.2f}, {st.nees_all_band[1]:.2f}]; "
                + (
                    f"{len(self.names) - 3} without the gyro bias: mean {st.nees_filter_mean:.2f}, band "
                    f"[{st.nees_filter_band[0]:.2f}, {st.nees_filter_band[1]:.2f}]; "
                    if len(self.names) > 9
                    else ""
                )
                + "status "
                + ", ".join(f"{k} {v}" for k, v in sorted(st.statuses.items()))
                + f" (ok with NEES(6) above χ²₆ 99.9 %: {st.ok_wrong})"
            )
        if hand:
            rows.append(
                f"hand-aware bound: lever arm as nuisance, slow external acceleration σ_s "
                f"{self.hand_psd.get('rms_m_s2', float('nan')):.4f} m/s², τ "
                f"{self.hand_psd.get('tau_s', float('nan')):.2f} s "
                "(kf_hand's estimate, median over seeds)"
            )
            for m, v in self.sqrt_crlb_hand_by_method.items():
                if not np.array_equal(v, self.sqrt_crlb_hand):
                    rows.append(
                        f"{m}'s eff.h uses the bound of S at the oracle's reference temperature "
                        f"{self.hand_psd.get('oracle_reference_temperature_c', float('nan')):.2f} °C, where it is "
                        f"scored (it states no temperature): √CRLB hand S " + ", ".join(f"{x:.5f}" for x in v[3:6])
                    )
        return "\n".join(rows)

    def to_dict(self) -> dict:
        return {"schedule": self.schedule, "hand": self.hand, "sensor": self.sensor, "seeds": self.seeds,
                "accelerometer": self.accelerometer, "parameters": list(self.names),
                "truth_mean": self.truth_mean.tolist(), "sqrt_crlb": self.sqrt_crlb.tolist(),
                "sqrt_crlb_hand": self.sqrt_crlb_hand.tolist(), "hand_psd": self.hand_psd,
                "sqrt_crlb_hand_by_method": {m: v.tolist() for m, v in self.sqrt_crlb_hand_by_method.items()},
                "methods": {m: {"mean_error": st.mean_error.tolist(), "rmse": st.rmse.tolist(),
                                "efficiency": st.efficiency.tolist(), "efficiency_hand": st.efficiency_hand.tolist(),
                                "z_rms": st.z_rms.tolist(),
                                "nees_mean": st.nees_mean, "nees_band": list(st.nees_band),
                                "nees_all_mean": st.nees_all_mean, "nees_all_band": list(st.nees_all_band),
                                "nees_filter_mean": st.nees_filter_mean, "nees_filter_band": list(st.nees_filter_band),
                                "ok_wrong": st.ok_wrong,
                                "statuses": st.statuses} for m, st in self.methods.items()}}


_GYRO_ONLY = ("--accelerometer estimate scores the accelerometer's parameters, but {} does not estimate them "
              "(it assumes a calibrated accelerometer: no σ for them). Use a joint method (kf_session, "
              "iterated_session: calib run's filter; kf_joint, iterated_joint) or --accelerometer calibrated")


def _estimator(method: str, accelerometer: str) -> Callable:
    """The callable behind a method name (module docstring, "Methods")."""
    if method in METHODS:   # calib run's filter, in the accelerometer mode asked
        def run(rec):
            return calibrate(rec, REGISTERED_NAME[method, accelerometer], keep_history=False)
        run.estimates = ("gyro", "accelerometer") if accelerometer == "estimate" else ("gyro",)
        return run
    return load_estimator(method)


def truth_scale_at_temperature(rec, t_c: np.ndarray) -> np.ndarray:
    """The simulated device's gyro scale factor change (3,) at the temperatures ``t_c`` (°C, one per axis) relative to
    the oracle's S: Σ ∂δ_i/∂x_i at x = 0 of its deterministic, non-affine error effects (a temperature-dependent scale —
    the MPU-9250's ``temperature_scale`` — contributes its polynomial in T − T_ref; a nonlinearity k x|x| or a bias-like
    term nothing), evaluated at T_i (scoring only: it reads the truth).  A calibration that says at which temperature
    its S holds (``diagnostics["temperature"]``, :func:`calib.session.hand.thermal.scale_at_temperature`) is scored
    against the device's S at that temperature; the oracle's S (:func:`gyrosim.calibration.truth_calibration`) is the
    one at the preset's reference."""
    from gyrosim.sensor_model import stored_sensor_model

    return _scale_change(stored_sensor_model(rec.meta or {}), t_c)


def _deterministic_errors(effects) -> list:
    """The deterministic, non-affine, pointwise error effects of a triad (scoring only): what the oracle's affine
    calibration (:func:`gyrosim.calibration.truth_calibration`) leaves out and a stated reference condition
    (temperature, specific force, operating point) brings in."""
    return [e for e in effects if e.stage == "error" and not e.stochastic and e.pointwise and e.affine() is None]


def _two_sample_context(temperature_c: float | None = None, specific_force_m_s2: np.ndarray | None = None):
    """A two-sample :class:`gyrosim.effects.SignalContext` at rest (a context's rate needs a step) at one
    temperature (°C) and specific force (m/s², body), for evaluating an effect at a condition."""
    from gyrosim.effects import SignalContext

    zero = np.zeros((2, 3))
    f = zero if specific_force_m_s2 is None else np.tile(np.asarray(specific_force_m_s2, float), (2, 1))
    return SignalContext(np.array([0.0, 0.01]), zero, f,
                         temperature_c=None if temperature_c is None else np.full(2, float(temperature_c)))


def _per_axis_at_temperatures(effects, t_c: np.ndarray, read: Callable) -> np.ndarray:
    """Σ over ``effects``' deterministic, non-affine, pointwise error terms of ``read(effect, ctx, i)`` for axis
    i at the temperature ``t_c[i]`` (°C) — the shared loop of the truth-at-a-temperature scorers (scoring only).
    ``read`` returns the term's value for axis i, or None where the effect has none."""
    out = np.zeros(3)
    for i, t in enumerate(np.asarray(t_c, float)):
        ctx = _two_sample_context(t)
        for e in _deterministic_errors(effects):
            v = read(e, ctx, i)
            if v is not None:
                out[i] += v
    return out


def _scale_change(model, t_c: np.ndarray) -> np.ndarray:
    """:func:`truth_scale_at_temperature` of a (realised) sensor model; zeros for None."""
    if model is None:
        return np.zeros(3)
    zero = np.zeros((2, 3))

    def slope(e, ctx, i):
        d = e.delta_dx(zero, ctx)
        return None if d is None else float(d[0, i, i])
    return _per_axis_at_temperatures(model.gyro, t_c, slope)


def truth_gyro_scale_at_rate(rec, rate_rad_s: np.ndarray, t_c: np.ndarray) -> np.ndarray:
    """The simulated device's gyro scale factor change (3,) at the rates a calibration states its S for
    (``diagnostics["scale_reference_rate"]``, :func:`calib.session.hand.reports.scale_reference_rate`): axis i's chord
    slope over ±m_i, (δ_i(+m_i e_i) − δ_i(−m_i e_i)) / 2m_i, minus its slope at 0 rad/s (which
    :func:`truth_scale_at_temperature` already counts), of the deterministic, non-affine, pointwise error effects at the
    temperature T_i (scoring only: it reads the truth).  A nonlinearity k ω|ω| reads k m_i; a temperature- dependent
    scale, linear in the rate, nothing — the accelerometer's counterpart is :func:`truth_acc_scale_at_gravity`."""
    from gyrosim.sensor_model import stored_sensor_model

    model = stored_sensor_model(rec.meta or {})
    if model is None:
        return np.zeros(3)
    m = np.asarray(rate_rad_s, float)
    zero = np.zeros((2, 3))

    def chord_minus_slope(e, ctx, i):
        chord = _chord_slope(e, ctx, i, m[i]) if m[i] > 0 else None
        if chord is None:
            return None
        s0 = e.delta_dx(zero, ctx)
        return chord - (0.0 if s0 is None else float(s0[0, i, i]))
    return _per_axis_at_temperatures(model.gyro, t_c, chord_minus_slope)


def _chord_slope(e, ctx, i: int, amplitude: float) -> float | None:
    """Axis i's chord slope of effect ``e`` over ±``amplitude`` (its input's unit), (δ_i(+a e_i) − δ_i(−a e_i)) / 2a,
    or None where the effect has no δ — the scale a calibration measures at that operating point (scoring only)."""
    x = np.zeros((2, 3))
    x[0, i], x[1, i] = amplitude, -amplitude
    d = e.delta(x, ctx)
    return None if d is None else float(np.asarray(d)[0, i] - np.asarray(d)[1, i]) / (2.0 * amplitude)


def truth_acc_bias_at_temperature(rec, t_c: np.ndarray) -> np.ndarray:
    """The simulated device's accelerometer bias change (3,) at the temperatures ``t_c`` (°C, one per axis) relative to
    the oracle's bias: the value at zero input of its deterministic, non-affine, pointwise error effects (the MPU-9250's
    ``temperature_bias``: its polynomial in T − T_ref; a nonlinearity k x|x| gives 0), axis i at T_i (scoring only: it
    reads the truth).  A calibration that states the temperature its b_a holds at
    (``diagnostics["temperature"]["acc_bias_reference_temperature_c"]``,
    :func:`calib.session.hand.thermal.acc_bias_at_temperature`) is scored against the device's bias there, as S is by
    :func:`truth_scale_at_temperature`."""
    from gyrosim.sensor_model import stored_sensor_model

    model = stored_sensor_model(rec.meta or {})
    if model is None:
        return np.zeros(3)
    zero = np.zeros((2, 3))

    def at_zero(e, ctx, i):
        d = e.delta(zero, ctx)
        return None if d is None else float(np.asarray(d)[0, i])
    return _per_axis_at_temperatures(model.accelerometer, t_c, at_zero)


def truth_acc_scale_at_gravity(rec, t_c: np.ndarray, gravity_m_s2: float = 9.80665,
                               force_m_s2: np.ndarray | None = None) -> np.ndarray:
    """The simulated device's accelerometer scale factor change (3,) at the operating point a gravity calibration
    measures it: the chord slope over ±g of its deterministic, non-affine, pointwise error effects,
    (δ_i(+g e_i) − δ_i(−g e_i)) / 2g, axis i at the temperature T_i (scoring only: it reads the truth).  Every
    method here sees the accelerometer only through |f| = g, so what it can estimate is the scale at g, not the
    oracle's small-signal slope: a nonlinearity k x|x| (the MPU-9250's ±0.5 % of 4 g, k σ 4.25e-5 per m/s²) reads
    k g (σ 4.2e-4, five to nine times the filter's σ of S_a) on this sphere and nothing at 0 m/s²; a temperature-
    dependent scale reads its polynomial at T_i; a temperature-dependent bias cancels in the chord.  ``force_m_s2``
    (3,): the chord over ±force_m_s2[i] instead, where a calibration states its S_a holds
    (``diagnostics["acc_scale_reference_force"]``, :func:`calib.session.hand.reports.acc_scale_reference_force`)."""
    from gyrosim.sensor_model import stored_sensor_model

    model = stored_sensor_model(rec.meta or {})
    if model is None:
        return np.zeros(3)

    amp = np.full(3, gravity_m_s2) if force_m_s2 is None else np.asarray(force_m_s2, float)
    return _per_axis_at_temperatures(model.accelerometer, t_c,
                                     lambda e, ctx, i: _chord_slope(e, ctx, i, amp[i]) if amp[i] > 0 else None)


def truth_bias_at_reference(rec, index_range: tuple[int, int], slow_bias_rad_s: np.ndarray | None = None) -> np.ndarray:
    """The simulated device's gyro bias during the rest ``index_range`` = [a, b) minus the oracle's (3,), rad/s
    (scoring only: it reads the truth): its deterministic, non-affine error effects at zero rate, evaluated at the
    rest's mean temperature and mean true specific force — the MPU-9250's ``temperature_bias`` c (T_r − T_ref)
    and ``g_sensitivity`` K f_r — plus ``slow_bias_rad_s``, the mean of the sensor's slow stochastic bias (bias
    instability, rate random walk) over the rest (:func:`slow_gyro_bias`).  A calibration that states where its
    bias holds (``diagnostics["gyro_bias"]``, :mod:`calib.session.rest_bias`) is scored against the device's bias there;
    the oracle's (:func:`gyrosim.calibration.truth_calibration`) is the one at T_ref with zero specific force."""
    from gyrosim.sensor_model import stored_sensor_model

    model = stored_sensor_model(rec.meta or {})
    out = np.zeros(3) if slow_bias_rad_s is None else np.asarray(slow_bias_rad_s, float).copy()
    if model is None or rec.truth is None:
        return out
    a, b = index_range
    f_r = np.mean(rec.truth.specific_force_body_m_s2[a:b], axis=0)
    t_r = None if rec.temp_c is None else float(np.mean(rec.temp_c[a:b]))
    ctx = _two_sample_context(t_r, f_r)
    for e in _deterministic_errors(model.gyro):           # the affine ones are the oracle's
        out += e.delta(np.zeros((2, 3)), ctx)[0]
    return out


def slow_gyro_bias(rec, truth, model, rng_seed: int, index_range: tuple[int, int]) -> np.ndarray:
    """Mean over [a, b) of the gyro's slow stochastic bias (its non-white stochastic error terms: the MPU-9250's
    bias instability and rate random walk) as
    :func:`gyrosim.simulate.apply_sensor` drew it in ``rec`` = apply_sensor(truth, model, default_rng(rng_seed))
    (scoring only): the same sensor
    run twice on the same streams (every effect keeps its own, :meth:`gyrosim.sensor_model.SensorModel.apply_triad`;
    the white noise stays on, since the slow terms' coarse grid depends on it), once with the slow terms' values
    (parameters) set to 0, differenced (the output quantisation is dithered by the white noise)."""
    def slow(e) -> bool:   # a stochastic error term that is not white: bias instability, random walk, …
        return e.stage == "error" and e.stochastic and not e.is_white_noise

    if not any(slow(e) for e in model.gyro):
        return np.zeros(3)

    def variant(drop_slow: bool):
        g = tuple(e.with_params(np.zeros_like(e.params())) if drop_slow and slow(e) else e for e in model.gyro)
        return replace(model, gyro=g)

    a, b = index_range
    y1 = rec.gyro_rad_s[a:b]
    y0 = apply_sensor(truth, variant(True), np.random.default_rng(rng_seed)).gyro_rad_s[a:b]
    return np.mean(y1 - y0, axis=0)


def _oracle_reference_temperature_c(rec) -> float | None:
    """The temperature (°C) at which the oracle's gyro S (:func:`gyrosim.calibration.truth_calibration`) holds on
    a device whose scale factor depends on temperature over this recording — the reference ``t_ref_c`` of its
    temperature-dependent scale effects (:func:`truth_scale_at_temperature` is 0 there) — or None when the
    device's S does not change over the recording's temperatures (or it has none).  Scoring only: reads the truth."""
    if rec.temp_c is None or not np.all(np.isfinite(rec.temp_c)):
        return None
    lo, hi = float(np.min(rec.temp_c)), float(np.max(rec.temp_c))
    if not np.any(
        np.abs(truth_scale_at_temperature(rec, np.full(3, hi)) - truth_scale_at_temperature(rec, np.full(3, lo))) > 0.0
    ):
        return None
    from gyrosim.sensor_model import stored_sensor_model

    refs = {float(e.t_ref_c) for e in stored_sensor_model(rec.meta or {}).gyro if hasattr(e, "t_ref_c")}
    return refs.pop() if len(refs) == 1 else None


def _scale_temperature_sigma_per_c(model, lo_c: float, hi_c: float, draws: int = 400) -> np.ndarray:
    """σ (3,) of the preset's per-device spread of the gyro scale factor's temperature coefficient (1/°C) over
    [``lo_c``, ``hi_c``]: the slope (ΔS(hi) − ΔS(lo)) / (hi − lo) of ``draws`` devices realised from the preset
    (seeded; whatever effects make S depend on temperature — no effect named here).  400 draws: σ to ±7 % (95 %,
    √(2/400) relative), enough for a bound.  Scoring only."""
    rng = np.random.default_rng(0)
    lo, hi = np.full(3, lo_c), np.full(3, hi_c)
    slopes = np.array([(_scale_change(m, hi) - _scale_change(m, lo)) / (hi_c - lo_c)
                       for m in (model.realize(rng) for _ in range(draws))])
    return slopes.std(axis=0)


def _with_population_prior(p: np.ndarray, offset: int, sigma_filter: float, sigma_pop: np.ndarray) -> np.ndarray:
    """The bound ``p`` (computed with the filter's vague prior σ_v = ``sigma_filter`` on the s_T block at
    ``offset``) with that prior replaced by the Monte Carlo's population prior σ_pop (the preset's per-device
    spread): in information form P⁻¹ + Hᵀ(σ_pop⁻² − σ_v⁻²)H, done as a Kalman update with a pseudo-measurement
    s_T = 0 of variance R = 1 / (σ_pop⁻² − σ_v⁻²) (no inverse of the ill-conditioned P).  The Bayesian CRLB
    (Van Trees 1968, §2.4) of the population the Monte Carlo draws its devices from."""
    var = 1.0 / np.maximum(1.0 / np.maximum(sigma_pop, 1e-30) ** 2 - 1.0 / sigma_filter**2, 1e-300)
    h = np.zeros((3, p.shape[0]))
    h[:, offset:offset + 3] = np.eye(3)
    s = h @ p @ h.T + np.diag(var)
    k = p @ h.T @ np.linalg.inv(s)
    out = p - k @ h @ p
    return 0.5 * (out + out.T)


def _stats(est: np.ndarray, cov: np.ndarray, truth: np.ndarray, sqrt_crlb: np.ndarray, statuses: list[str],
           filter_cols: slice, sqrt_crlb_hand: np.ndarray | None = None, refused: int = 0) -> MethodStats:
    """Statistics over the scored seeds (``statuses`` theirs); ``refused`` sessions (RecordingError) are counted in
    the statuses as "refused" and scored nowhere — the NEES band is that of the scored seeds."""
    err = est - truth
    n, p = err.shape
    rmse = np.sqrt(np.mean(err**2, axis=0))
    sd = np.sqrt(np.einsum("bii->bi", cov))
    z = err / sd
    e6 = err[:, filter_cols]
    c6 = cov[:, filter_cols, filter_cols]
    nees6 = np.einsum("bi,bij,bj->b", e6, np.linalg.inv(c6), e6)
    nees = np.einsum("bi,bij,bj->b", err, np.linalg.inv(cov), err)
    k6 = e6.shape[1]
    band6 = (stats.chi2.ppf(0.025, k6 * n) / n, stats.chi2.ppf(0.975, k6 * n) / n)
    band = (stats.chi2.ppf(0.025, p * n) / n, stats.chi2.ppf(0.975, p * n) / n)
    counts: dict[str, int] = {}
    for s in statuses:
        counts[s] = counts.get(s, 0) + 1
    if refused:
        counts["refused"] = refused
    ef, cf = err[:, 3:], cov[:, 3:, 3:]       # every parameter but the gyro bias (the rest's average)
    nees_f = np.einsum("bi,bij,bj->b", ef, np.linalg.inv(cf), ef)
    band_f = (stats.chi2.ppf(0.025, (p - 3) * n) / n, stats.chi2.ppf(0.975, (p - 3) * n) / n)
    return MethodStats(err.mean(axis=0), rmse, rmse / sqrt_crlb, float(nees6.mean()), band6,
                       np.sqrt(np.mean(z**2, axis=0)), float(nees.mean()), band, counts,
                       rmse / sqrt_crlb_hand if sqrt_crlb_hand is not None and sqrt_crlb_hand.size else np.zeros(0),
                       float(nees_f.mean()), band_f,
                       int(np.sum((np.asarray(statuses) == "ok") & (nees6 > stats.chi2.ppf(0.999, k6)))))


@dataclass
class _Seeds:
    """What the seeds gave, per method: estimates, covariances, statuses, refusals and the truth each is scored
    against (S at the temperature/rate the method states, b at its rest, …), the temperatures it stated, whether it
    estimated the g-sensitivity; the kf_hand PSDs and drifts for the hand-aware bound; the first scored seed."""

    est: dict
    cov: dict
    status: dict
    refused: dict
    truths: list
    truth_m: dict
    t_ref_m: dict
    t_ref_a_m: dict
    gs_m: dict
    psd: list
    drift: list
    first: tuple | None = None


def monte_carlo(
    schedule: str = "zhou2020",
    hand: str | Hand = "ideal",
    sensor: str = "zhou2020_sim",
    seeds: int = 50,
    rate_hz: float = 100.0,
    methods: tuple[str, ...] | None = None,
    first_seed: int = 0,
    progress: Callable[[int], None] | None = None,
    calibrated_accelerometer: bool = False,
    accelerometer: str = "calibrated",
) -> MonteCarloResult:
    """Run the Monte Carlo (module docstring) and return its statistics.  ``methods`` defaults to the
    paper's filter and calib run's three-pass one (``kf``, ``iterated_session``); with
    ``accelerometer="estimate"`` to calib run's two (``kf_session``, ``iterated_session``): the paper's
    ``kf`` assumes a calibrated accelerometer and has no σ for its parameters."""
    if methods is None:
        methods = ("kf_session" if accelerometer == "estimate" else "kf", "iterated_session")
    # ``sensor``: a preset name or path, or a SensorModel (an ablation: benchmarks/mpu9250_ablation.py)
    # ``hand``: a preset name or TOML path, or a Hand (a variant: Hand.without, benchmarks/hand_variants.py)
    sched, hnd = load_schedule(schedule), (hand if isinstance(hand, Hand) else load_hand(hand))
    model = load_sensor(sensor) if isinstance(sensor, (str, bytes)) or hasattr(sensor, "__fspath__") else sensor
    if calibrated_accelerometer:
        model = replace(model, name=f"{model.name} (accelerometer calibrated)",
                        accelerometer=tuple(e for e in model.accelerometer if e.is_white_noise))
    estimate = accelerometer == "estimate"
    names = GYRO_PARAMS + (ACC_PARAMS if estimate else ())
    runners = {m: _estimator(m, accelerometer) for m in methods}   # unknown names fail before any simulation
    if estimate:   # a method that declares it estimates the gyro only is refused before any simulation too
        blind = [m for m, r in runners.items() if (d := estimated_triads(r)) is not None and "accelerometer" not in d]
        if blind:
            raise GyrosimError(_GYRO_ONLY.format(", ".join(repr(m) for m in blind)))
    sd = _run_seeds(sched, hnd, model, runners, seeds, first_seed, rate_hz, estimate, progress)
    for m in methods:
        if not sd.est[m]:
            raise RecordingError(f"{m} refused every one of the {seeds} sessions; the first: {sd.refused[m][0]}")
    truths_arr = np.stack(sd.truths)
    bound = _ideal_bound(sd.first[0], truths_arr, accelerometer, rate_hz, hnd)
    sqrt_hand, hand_psd, sqrt_hand_m = np.zeros(0), {}, {}
    if sd.psd or not estimate:   # with the accelerometer estimated: when a hand-aware method gave the hand's PSD
        sqrt_hand, hand_psd, sqrt_hand_m = _hand_bounds(sd, bound, model, methods, estimate, rate_hz)
    result = {m: _stats(np.stack(sd.est[m]), np.stack(sd.cov[m]), np.stack(sd.truth_m[m]), bound.sqrt_crlb,
                        sd.status[m], slice(3, 9), sqrt_hand_m.get(m, sqrt_hand), refused=len(sd.refused[m]))
              for m in methods}
    return MonteCarloResult(schedule, hnd.name if isinstance(hand, Hand) else hand, model.name, seeds,
                            truths_arr.mean(axis=0), bound.sqrt_crlb, result, accelerometer, names, sqrt_hand,
                            hand_psd, sqrt_hand_m)


def _run_seeds(sched, hnd: Hand, model, runners: dict, seeds: int, first_seed: int, rate_hz: float, estimate: bool,
               progress: Callable[[int], None] | None) -> _Seeds:
    """Every seed: a device drawn from the preset with its own noise, each method on the user's file of it."""
    methods = tuple(runners)
    def per_method() -> dict:
        return {m: [] for m in methods}

    sd = _Seeds(est=per_method(), cov=per_method(), status=per_method(), refused=per_method(), truths=[],
                truth_m=per_method(), t_ref_m=per_method(), t_ref_a_m=per_method(), gs_m={m: False for m in methods},
                psd=[], drift=[])
    truth_fixed = simulate_truth(sched, hnd, rate_hz, seed=first_seed) if hnd.is_ideal else None
    for k in range(seeds):
        seed = first_seed + k
        truth = truth_fixed if truth_fixed is not None else simulate_truth(sched, hnd, rate_hz, seed=seed)
        rec = apply_sensor(truth, model, np.random.default_rng(10_000 + seed))
        tc = truth_calibration(rec)
        sd.truths.append(np.concatenate([tc.vector("gyro")] + ([tc.vector("accelerometer")] if estimate else [])))
        user = as_user_file(rec)
        slow_cache: dict = {}
        t_session = float(np.mean(rec.temp_c)) if rec.temp_c is not None else 25.0
        for m in methods:
            try:
                c = runners[m](user)
            except RecordingError as exc:   # this session is bad input for the method: a status, not a crash
                sd.refused[m].append(str(exc))
                continue
            if "hand" in c.diagnostics and "external_acc_psd" in c.diagnostics["hand"]:
                sd.psd.append(c.diagnostics["hand"]["external_acc_psd"])
            if "gyro_bias_drift" in c.diagnostics:
                sd.drift.append(c.diagnostics["gyro_bias_drift"]["rate_random_walk_rad_s_sqrt_s"])
            items = [("gyro", "bias"), ("gyro", "scale_factor"), ("gyro", "nonorthogonality")]
            if estimate:
                items += [
                    ("accelerometer", "bias"),
                    ("accelerometer", "scale_factor"),
                    ("accelerometer", "nonorthogonality"),
                ]
            block = c.block_covariance(items)
            if estimate and k == 0 and not np.all(np.diag(block)[len(GYRO_PARAMS):] > 0):
                raise GyrosimError(_GYRO_ONLY.format(repr(m)))
            tm = _method_truth(sd, m, c, rec, truth, model, seed, sd.truths[-1], t_session, slow_cache, estimate)
            sd.truth_m[m].append(tm)
            sd.gs_m[m] = sd.gs_m[m] or "gyro_g_sensitivity" in c.diagnostics
            sd.est[m].append(np.concatenate([c.value(t, kd) for t, kd in items]))
            sd.cov[m].append(block)
            sd.status[m].append(c.status)
            if sd.first is None:
                sd.first = (rec, c)
        if progress is not None:
            progress(1)
    return sd


def _method_truth(sd: _Seeds, m: str, c, rec, truth, model, seed: int, oracle: np.ndarray, t_session: float,
                  slow_cache: dict, estimate: bool) -> np.ndarray:
    """The truth ``c`` (method ``m``'s calibration of this seed) is scored against: the oracle's parameters moved to
    the conditions the calibration states — S at its temperatures and rates, b at its rest, b_a and S_a at their
    temperatures and force (scoring only: reads the truth).  Records the stated temperatures in ``sd``."""
    tm = oracle.copy()
    temp = c.diagnostics.get("temperature", {})
    if temp.get("modelled") and "scale_reference_temperature_c" in temp:
        t_r = np.asarray(temp["scale_reference_temperature_c"], float)
        tm[3:6] += truth_scale_at_temperature(rec, t_r)
        sd.t_ref_m[m].append(t_r)
    srate = c.diagnostics.get("scale_reference_rate", {})
    if "rate_rad_s" in srate:   # S as the chord slope over the session's rates (a nonlinearity's share)
        t_s = np.asarray(temp["scale_reference_temperature_c"], float) if (
            temp.get("modelled") and "scale_reference_temperature_c" in temp) else np.full(3, t_session)
        tm[3:6] += truth_gyro_scale_at_rate(rec, np.asarray(srate["rate_rad_s"], float), t_s)
    gb = c.diagnostics.get("gyro_bias", {})
    # the bias at the rest it states (calib.session.rest_bias), not at T_ref, f = 0
    if "rest_index_range" in gb:
        rng_ = tuple(gb["rest_index_range"])
        if rng_ not in slow_cache:
            slow_cache[rng_] = truth_bias_at_reference(
                rec, rng_, slow_gyro_bias(rec, truth, model, 10_000 + seed, rng_)
            )
        tm[0:3] += slow_cache[rng_]
    t_acc = np.full(3, t_session)
    if estimate and temp.get("modelled") and "acc_bias_reference_temperature_c" in temp:
        # the accelerometer bias at the temperatures its calibration states (kf_hand_joint on a warming sensor)
        t_acc = np.asarray(temp["acc_bias_reference_temperature_c"], float)
        tm[9:12] += truth_acc_bias_at_temperature(rec, t_acc)
        sd.t_ref_a_m[m].append(t_acc)
    # the accelerometer's scale where a gravity calibration measures it: at ±g, or at the specific
    if estimate:
        # force the method states (kf_hand_joint), at the stated temperature (else the session's mean)
        fref = c.diagnostics.get("acc_scale_reference_force", {}).get("specific_force_m_s2")
        tm[12:15] += truth_acc_scale_at_gravity(rec, t_acc, force_m_s2=fref)
    return tm


@dataclass(frozen=True)
class _Bound:
    """The ideal bound (the sensor's white noise only, no hand) and what the hand-aware bound reuses: the first
    scored seed, its noise config, the integrated true attitude and gravity from the filter's start, θ_true."""

    sqrt_crlb: np.ndarray
    bias_crlb: np.ndarray
    rec0: object
    config: FilterConfig
    start: int
    q_int: np.ndarray
    f_g: np.ndarray
    th: np.ndarray


def _ideal_bound(rec0, truths_arr: np.ndarray, accelerometer: str, rate_hz: float, hnd: Hand) -> _Bound:
    """:func:`calib.session.bounds.crlb_joint` at the first seed's truth with the noise levels the calibration
    estimated (module docstring, "CRLB"); the static bias's σ²/n."""
    estimate = accelerometer == "estimate"
    prep0 = prepare(rec0, accelerometer=accelerometer)
    noise = prep0.config
    if hnd.is_ideal:   # the calibration's own noise levels, as before
        config = noise
    else:              # a hand's rest is not still: the sensor's white noise from above the tremor band (both
        # accelerometer modes: with the rest's spread the bounds counted the tremor as sensor noise, efficiency < 1)
        arw, vrw = prep0.noise.gyro_density_rad_s_sqrt_hz, prep0.noise.acc_density_m_s2_sqrt_hz
        config = replace(noise, external_acc_allowance_m_s2=0.0, arw_rad_s_sqrt_hz=arw or noise.arw_rad_s_sqrt_hz,
                         vrw_m_s2_sqrt_hz=vrw or noise.vrw_m_s2_sqrt_hz)
    tr = rec0.truth
    start = prep0.start
    # the attitude the filter's own integration (trapezoid + coning) gives from the true rate: a truth whose
    # rate does not integrate exactly to its attitude (a hand's wobble and tremor, simulated finer) would
    # feed the recursion a non-zero residual, and with its vague prior the nominal would leave the truth
    q_int = integrate_gyro(rec0.t_s[start:], tr.omega_body_rad_s[start:], tr.quat_nb[start])
    f_g = quat_rotate(quat_conjugate(q_int), np.array([0.0, 0.0, config.gravity_m_s2]))
    th = np.zeros(18)
    th[0:3], th[3:6], th[6:9] = truths_arr[0, 3:6], truths_arr[0, 6:9], truths_arr[0, 0:3]
    if estimate:
        th[9:12], th[12:15], th[15:18] = truths_arr[0, 9:12], truths_arr[0, 12:15], truths_arr[0, 15:18]
    layout = JOINT if estimate else PAPER
    p = crlb_joint(tr.omega_body_rad_s[start:], f_g, q_int, rec0.t_s[start:], th, layout, config, rate_hz)
    a, b = prep0.rest_range
    bias_crlb = np.full(3, config.arw_rad_s_sqrt_hz * math.sqrt(rate_hz) / math.sqrt(max(b - a, 1)))
    sd = np.sqrt(np.diag(p))
    crlb = [bias_crlb if not estimate else sd[9:12], sd[3:9]]
    if estimate:
        crlb.append(sd[12:21])
    return _Bound(np.concatenate(crlb), bias_crlb, rec0, config, start, q_int, f_g, th)


def _hand_psd(psd: list[dict], drift: list[float]) -> dict:
    """The hand-aware bound's a_e model: the median over the seeds of kf_hand's fitted PSD (its band-limited sway
    when most seeds fitted one); the ideal hand's zero sway without a hand-aware method."""
    if not psd:
        return {"rms_m_s2": 0.0, "tau_s": 1.0, "highpass_tau_s": math.inf, "highpass_order": 1,
                "bias_rw_rad_s_sqrt_s": 0.0}
    hp = [d.get("highpass_tau_s") for d in psd]
    hand_psd = {"rms_m_s2": float(np.median([d["rms_m_s2"] for d in psd])),
                "tau_s": float(np.median([d["tau_s"] for d in psd])),
                "highpass_tau_s": float(np.median([math.inf if h is None else h for h in hp])),
                "highpass_order": int(round(float(np.median([d.get("highpass_order", 1) for d in psd])))),
                "bias_rw_rad_s_sqrt_s": float(np.median(drift)) if drift else 0.0}
    bands = [d for d in psd if d.get("band_hz")]
    # kf_hand's band-limited sway in most seeds: the bound's a_e is its median
    if bands and len(bands) * 2 > len(psd):
        hand_psd.update({"psd_model": bands[0].get("psd_model"),
                         "band_hz": [float(np.median([d["band_hz"][i] for d in bands])) for i in (0, 1)],
                         "band_rms_m_s2": float(np.median([d["band_rms_m_s2"] for d in bands])),
                         "band_order": int(bands[0].get("band_order", 2))})
    return hand_psd


def _hand_bounds(sd: _Seeds, bound: _Bound, model, methods: tuple[str, ...], estimate: bool,
                 rate_hz: float) -> tuple[np.ndarray, dict, dict[str, np.ndarray]]:
    """The hand-aware bound (module docstring) of the quantity each method is scored on: (the bound, the hand's
    PSD it assumed, per method its bound)."""
    rec0, start, config = bound.rec0, bound.start, bound.config
    tr = rec0.truth
    hand_psd = _hand_psd(sd.psd, sd.drift)
    # a method that models the scale factor's temperature dependence (kf_hand on a session that warmed) reports
    # S at the temperatures the session determined it: the bound is that of the same quantity, with s_T nuisance
    # — and, for a method that states none, that of S at the oracle's reference temperature, where it is scored
    t_oracle = None if estimate else _oracle_reference_temperature_c(rec0)
    thermal = (
        session_temperature(rec0.temp_c[start:], rate_hz)
        if (rec0.temp_c is not None and (any(sd.t_ref_m[m] or sd.t_ref_a_m[m] for m in methods)
                                         or t_oracle is not None))
        else None
    )
    # and its g-sensitivity, when a method estimated it (kf_hand): three nuisance states of the same model
    g_sens = any(sd.gs_m[m] for m in methods)

    def bound_of(temperature_rel_c, band: bool = True, accel: bool = estimate) -> np.ndarray:
        return hand_crlb(tr.omega_body_rad_s[start:], bound.f_g, bound.q_int, rec0.t_s[start:], bound.th, config,
                         rate_hz, hand_psd["rms_m_s2"], hand_psd["tau_s"], highpass_tau_s=hand_psd["highpass_tau_s"],
                         bias_rw_rad_s_sqrt_s=hand_psd["bias_rw_rad_s_sqrt_s"],
                         highpass_order=hand_psd["highpass_order"], temperature_rel_c=temperature_rel_c,
                         g_sensitivity=g_sens, estimate_accelerometer=accel,
                         **({"band_hz": hand_psd.get("band_hz"), "band_rms_m_s2": hand_psd.get("band_rms_m_s2", 0.0),
                             "band_order": hand_psd.get("band_order", 2)} if band else {}))

    ph = bound_of(None if thermal is None else thermal[0])
    sdh = np.sqrt(np.diag(ph))
    sd_sg = sdh[3:9]
    oa = HAND_JOINT.offset("acc_bias")
    sd_acc = sdh[oa:oa + 9] if estimate else None
    sd_plain_joint = None
    sd_sg_oracle = None
    if thermal is not None and not estimate:
        sd_sg, sd_sg_oracle = _thermal_bound_calibrated(sd, ph, hand_psd, thermal, t_oracle, g_sens, model, rec0,
                                                        start, config, methods)
    if thermal is not None and estimate:
        # kf_hand_joint on a warming session: S and b_a at the temperatures it states, c_a and s_T nuisance
        lay = hand_crlb_layout(hand_psd["bias_rw_rad_s_sqrt_s"] > 0, True, g_sens, True)
        t_r, jt = scale_at_temperature(ph, lay, thermal[1])
        t_a, ja = acc_bias_at_temperature(ph, lay, thermal[1])
        sd_sg = np.sqrt(np.diag(jt @ ph @ jt.T))
        sd_acc = sd_acc.copy()
        sd_acc[0:3] = np.sqrt(np.diag(ja @ ph @ ja.T))
        hand_psd["acc_bias_reference_temperature_c"] = t_a.tolist()
        if any(sd.t_ref_m[m] for m in methods):
            hand_psd["scale_reference_temperature_c"] = t_r.tolist()
            hand_psd["scale_reference_temperature_c_estimates"] = np.median(
                np.concatenate([np.stack(v) for v in sd.t_ref_m.values() if v]), axis=0).tolist()
        if not all(sd.t_ref_a_m[m] for m in methods):
            # a joint method that states no temperature (kf_session) keeps the bound of the model without the
            # temperature blocks, as before them (one more recursion, ~1 s)
            sdp = np.sqrt(np.diag(bound_of(None, band=False, accel=True)))
            sd_plain_joint = np.concatenate([bound.bias_crlb, sdp[3:9], sdp[oa:oa + 9]])
    if not math.isfinite(hand_psd["highpass_tau_s"]):
        hand_psd["highpass_tau_s"] = None                 # JSON: no high-pass
    # kf_hand(_joint) reports the rest-average gyro bias: its bound is the static one in both modes
    sqrt_hand = np.concatenate([bound.bias_crlb, sd_sg] + ([sd_acc] if estimate else []))
    sqrt_hand_m: dict[str, np.ndarray] = {}
    for m in methods:   # each method's bound is that of the quantity it is scored against
        sqrt_hand_m[m] = sqrt_hand
        if sd_sg_oracle is not None and not sd.t_ref_m[m]:
            sqrt_hand_m[m] = np.concatenate([bound.bias_crlb, sd_sg_oracle] + ([sdh[oa:oa + 9]] if estimate else []))
        if sd_plain_joint is not None and not sd.t_ref_a_m[m]:
            sqrt_hand_m[m] = sd_plain_joint
    return sqrt_hand, hand_psd, sqrt_hand_m


def _thermal_bound_calibrated(sd: _Seeds, ph: np.ndarray, hand_psd: dict, thermal, t_oracle: float | None,
                              g_sens: bool, model, rec0, start: int, config: FilterConfig,
                              methods: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray | None]:
    """kf_hand on a warming session (accelerometer calibrated): the bound of S at the temperatures it states, and of
    S at the oracle's reference temperature for a method that states none (with the preset's population prior on
    s_T).  Returns (σ of S, G at T_r; σ of S, G at the oracle's reference or None); records them in ``hand_psd``."""
    lay_t = hand_crlb_layout(hand_psd["bias_rw_rad_s_sqrt_s"] > 0, True, g_sens, False,
                             2 * hand_psd["band_order"] - 2 if hand_psd.get("band_hz") else 0)   # hand_crlb's
    t_r, jt = scale_at_temperature(ph, lay_t, thermal[1])
    sd_sg = np.sqrt(np.diag(jt @ ph @ jt.T))
    sd_sg_oracle = None
    if t_oracle is not None:   # S(T) = S(T₀) + s_T (T − T₀) at T = the oracle's reference, every axis
        j_or = jt.copy()
        o = lay_t.offset("gyro_temp_scale")
        j_or[0:3, o:o + 3] = np.eye(3) * (t_oracle - thermal[1])
        t_all = rec0.temp_c[start:]
        p_pop = _with_population_prior(
            ph,
            o,
            config.prior_gyro_temp_scale_per_c,
            _scale_temperature_sigma_per_c(model, float(np.min(t_all)), float(np.max(t_all))),
        )
        sd_sg_oracle = np.sqrt(np.diag(j_or @ p_pop @ j_or.T))
        hand_psd["oracle_reference_temperature_c"] = t_oracle
        # for a file of methods that state no temperature to borrow (benchmarks/hand_campaign.py)
        hand_psd["sqrt_crlb_hand_sg_at_oracle_reference"] = sd_sg_oracle.tolist()
    if any(sd.t_ref_m[m] for m in methods):
        # the bound's; the estimates' median beside it
        hand_psd["scale_reference_temperature_c"] = t_r.tolist()
        hand_psd["scale_reference_temperature_c_estimates"] = np.median(
            np.concatenate([np.stack(v) for v in sd.t_ref_m.values() if v]), axis=0).tolist()
    else:
        sd_sg = sd_sg_oracle
    return sd_sg, sd_sg_oracle
