"""The candidate families of the gyro vocabulary (see :mod:`calib.closeloop.candidates`).

One class per effect kind (or kinds that share everything), registered with
:func:`~calib.closeloop.candidates.register_family`.  Each states what the effect claims to depend
on (``driver``), through which channel that reaches its regressor (for the confounding rule), and
its *largest plausible size* — about 2–3× the worst consumer-MEMS datasheet value.  The
identifiability gate (:mod:`calib.closeloop.identify`) asks whether an effect of that size would be
seen on this recording at all: if not, anything the candidate "finds" is something else.  And a
fitted value beyond it by more than 3σ is refused as a proxy (:meth:`CandidateFamily.implausible`):

| kind | largest plausible size | datasheet order |
|---|---|---|
| bias | 5 °/s | turn-on bias 1–3 °/s |
| scale factor, non-orthogonality, misalignment | 0.05 (5 %, 50 mrad) | 1–3 %, 1–2 % cross-axis |
| gyro-to-accelerometer misalignment | 3° per axis | not on datasheets: 0.3–1° measured (imucal, imu_tk) |
| scale nonlinearity | 5e-3 /(rad/s) (0.5 % at 1 rad/s) | 0.1–0.5 % FS |
| time offset | 50 ms | 1–10 ms filter/bus latency, up to 20 ms over a bus |
| g-sensitivity | 0.5 °/s/g | 0.1 °/s/g (MPU-9250) |
| temperature bias | 0.5 °/s/°C (first order) | ±0.24 °/s/°C (MPU-9250 worst) |
| temperature scale | 1e-3 /°C | 2–3e-4 /°C (MPU-9255 ±4 % over 125 °C) |
| thermal hysteresis | 100 (°/s)/(°C/s) | 10 (°/s)/(°C/s) (consumer_thermal) |
| temperature points (bias, scale) | 30 °/s, 0.05 | ±30 °/s ZRO over −40…85 °C (Zhou 2020 Table 2) |
| Earth rate | 1.5 Ω per ENU component | Ω = 15.04 °/h (a known size) |
| magnetic sensitivity | 0.01 °/s/µT | 6e-4 °/s/µT (suite, a gyro beside a magnetised part) |
| bias drift (each knot) | 5 °/s | consumer drift K ≤ 1 °/s/√h |
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from gyrosim.effects import (
    EARTH_RATE_RAD_S,
    Bias,
    EarthRate,
    Effect,
    GSensitivity,
    GyroAccMisalignment,
    MagneticSensitivity,
    Misalignment,
    NonOrthogonality,
    RandomWalk,
    RateRamp,
    ScaleAsymmetry,
    ScaleFactor,
    ScaleNonlinearity,
    SignalContext,
    TemperatureBias,
    TemperaturePiecewise,
    TemperatureRBF,
    TemperatureScale,
    ThermalHysteresis,
    TimeOffset,
    nonortho_matrix,
)
from gyrosim.rotations import quat_conjugate, quat_rotate
from gyrosim.units import G0, RAD2DEG

from calib.closeloop.candidates import Candidate, CandidateFamily, Channel, ReportedTerm, Untestable, register_family
from calib.closeloop.drift import random_walk_mle
from calib.closeloop.reference import Reference, motion_field, motion_specific_force
from calib.temperature.timeblocks import block_means, time_block_index

__all__ = ["earth_rate_summary"]



def _class_candidate(family: CandidateFamily, ctx: SignalContext, follows: str, series: np.ndarray | None) -> Candidate:
    """The candidate of the family's effect class as the class builds it (``Effect.candidate_regressor``)."""
    proto, reg = family.effects[0].candidate_regressor(ctx)
    return Candidate(family, proto.kind, tuple(proto.param_names()), proto.with_params, follows, series, reg)


# ================================================================ a constant
@register_family
class ConstantBias(CandidateFamily):
    effects = (Bias,)
    driver = "nothing (a constant)"
    quantity = "constant"
    channel = Channel.RATE
    separated_by = "—"

    def build(self, kind, ctx, ref, options):
        return _class_candidate(self, ctx, "a constant", np.ones_like(ctx.omega_true_rad_s))

    def plausible_max(self, kind, ctx):
        return math.radians(5.0)


# ================================================================ the rate
class _RateDriven(CandidateFamily):
    quantity = "rate"
    channel = Channel.RATE
    separated_by = "rotations at several rates about every axis"

    def unexcited(self, kind, ref):
        if ref.kind == "static":
            return "the recording is at rest: a rate-proportional term has no excitation"
        return super().unexcited(kind, ref)


class _AxisMatrix(_RateDriven):
    """Dimensionless axis errors: a real one is a few %, so fits are boxed at ±0.3 (the pose-to-pose
    equations of the gravity reference have far-away spurious solutions)."""

    bound = 0.3
    follows_text = ""

    def build(self, kind, ctx, ref, options):
        return _class_candidate(self, ctx, self.follows_text, ctx.omega_true_rad_s)

    def plausible_max(self, kind, ctx):
        return 0.05

    def implausible(self, kind, theta, sigma, ctx):
        if np.any(np.abs(theta) >= 0.99 * self.bound):
            return (f"fitted {kind} reaches ±{self.bound:g} (a {self.bound * 100:.0f} % axis error): not a sensor "
                    "defect but a different solution of the self-consistency equations")
        return super().implausible(kind, theta, sigma, ctx)


@register_family
class ScaleFactorFamily(_AxisMatrix):
    effects = (ScaleFactor,)
    driver = "the rate on the same axis"
    follows_text = "the rate on the same axis"


@register_family
class NonOrthogonalityFamily(_AxisMatrix):
    effects = (NonOrthogonality,)
    driver = "the rate on the other axes"
    follows_text = "the rate on the other axes (symmetric)"


def _off_diagonal_vs_truth(effect_cls, finding_params, declared_params, true_effect, device):
    """The total off-diagonal axis matrix N(G) + the finding's (``effect_cls``'s ``matrix()``) against the device's
    N(G) + the true effect's: (estimate, truth, σ) over the six off-diagonal entries (what a misalignment-like
    finding is scored by when its symmetric part trades with the declared non-orthogonality)."""
    vals = np.array([v["value"] for v in finding_params.values()])
    sig = np.array([v["sigma"] for v in finding_params.values()])
    n_hat = np.array([declared_params[f"nonorthogonality.value[{i}]"]["value"] for i in range(3)])
    n_sig = np.array([declared_params[f"nonorthogonality.value[{i}]"]["sigma"] for i in range(3)])
    n_true = device["nonorthogonality"].params() if "nonorthogonality" in device else np.zeros(3)
    tot_hat = nonortho_matrix(n_hat) + effect_cls(value=vals).matrix()
    tot_true = nonortho_matrix(n_true) + true_effect.matrix()
    sig_tot = np.hypot(nonortho_matrix(n_sig), np.abs(effect_cls(value=sig).matrix()))
    off = ~np.eye(3, dtype=bool)
    return tot_hat[off], tot_true[off], sig_tot[off]


@register_family
class MisalignmentFamily(_AxisMatrix):
    effects = (Misalignment,)
    driver = "the rate on the other axes"
    follows_text = "the rate on the other axes"

    def caveat(self, kind, reference_kind):
        if reference_kind == "optical":
            return ("a rotation between the IMU and the optical body frame (the reference's alignment) looks exactly "
                    "like this")
        return None

    def compare_with_truth(self, kind, finding_params, declared_params, true_effect, device):
        """The misalignment's symmetric part trades with the declared non-orthogonality: compare the
        total off-diagonal matrix N + M."""
        return _off_diagonal_vs_truth(self.effects[0], finding_params, declared_params, true_effect, device)


@register_family
class GyroAccMisalignmentFamily(MisalignmentFamily):
    """The gyro triad turned against the accelerometer's by small angles α: the antisymmetric part of the gyro's axis
    matrix (regressor [ω×]), three parameters where the general misalignment has six — its symmetric half trades with
    the declared non-orthogonality, this one with nothing the linear model holds.  Against the gravity reference the
    body frame is the accelerometer's (gravity's direction at each pose), so α is what a filter needs to carry the
    accelerometer's gravity with the gyro.  Scored against a true α or a true general misalignment M alike: the total
    off-diagonal matrix N − [α×] against N_true + M_true."""

    effects = (GyroAccMisalignment,)
    driver = "the rate on the other axes (antisymmetric)"
    follows_text = "the rate on the other axes, antisymmetric (the gyro's axes turned against the accelerometer's)"
    bound = GyroAccMisalignment.max_rad

    def plausible_max(self, kind, ctx):
        return math.radians(3.0)


class _SameAxisRegressor(_RateDriven):
    """A rate-driven error that each axis makes from its own rate through a fixed function (``regressor`` of ω,
    per axis; ``regressor_text`` says which): the candidate regresses on it, plausible up to ``max_value``."""

    regressor_text = ""
    max_value = 0.0

    @staticmethod
    def regressor(w: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def build(self, kind, ctx, ref, options):
        return _class_candidate(self, ctx, self.regressor_text, self.regressor(ctx.omega_true_rad_s))

    def plausible_max(self, kind, ctx):
        return self.max_value


@register_family
class ScaleNonlinearityFamily(_SameAxisRegressor):
    effects = (ScaleNonlinearity,)
    driver = regressor_text = "ω·|ω| on the same axis"
    separated_by = "rotations at several rates, slow and fast, in both directions"
    max_value = 5e-3

    @staticmethod
    def regressor(w):
        return w * np.abs(w)


@register_family
class ScaleAsymmetryFamily(_SameAxisRegressor):
    effects = (ScaleAsymmetry,)
    driver = "|ω| on the same axis"
    regressor_text = "|ω| on the same axis (the scale differs with the turn's sign)"
    separated_by = "turns of the same size in both directions about every axis"
    max_value = 0.02

    @staticmethod
    def regressor(w):
        return np.abs(w)


@register_family
class TimeOffsetFamily(CandidateFamily):
    """A time offset d, linear around the value found so far: the delay found is undone on the
    measured gyro (the exact Fourier shift of :meth:`TimeOffset.inverse`) and the model keeps the
    small remainder δd with regressor −ẋ, evaluated on the error-stage output (I + S + N) ω + b
    (``BuildOptions.modelled_rate``), which is what the output stage delays; without it the delay
    would absorb the scale factor (d̂ = d (1 + s))."""

    effects = (TimeOffset,)
    driver = "the angular acceleration dω/dt"
    quantity = "angular_acceleration"
    channel = Channel.RATE
    output_stage = True
    separated_by = ("fast reversals (large dω/dt) at several rates; against an external reference, a synchronisation "
                    "event recorded by both systems")

    def build(self, kind, ctx, ref, options):
        if options.modelled_rate is not None:
            ctx = replace(ctx, omega_true_rad_s=options.modelled_rate)
        dw = np.gradient(ctx.omega_true_rad_s, ctx.t_s, axis=0)
        return _class_candidate(self, ctx, "dω/dt", dw)

    def plausible_max(self, kind, ctx):
        return 50e-3

    def driver_signal(self, cand, ref):
        """dω/dt of the reference rate: the regressor is dω/dt of the modelled output, which the
        model's own slow terms (a thermal bias) also move — on a board at rest, only they do."""
        return np.gradient(ref.ctx.omega_true_rad_s, ref.ctx.t_s, axis=0)

    def proxy_reason(self, share, ref):
        if not np.any(ref.ctx.omega_true_rad_s):
            return ("the board is at rest (reference rate 0): dω/dt = 0, and the modelled output's derivative comes "
                    "only from the model's own slow terms (e.g. a thermal bias), not from motion")
        return (f"the reference's angular acceleration explains only {share:.0%} of the modelled output's dω/dt (needs "
                "≥ 50 %): the rest is the model's own slow terms (e.g. a thermal bias), not motion")

    def undo(self, kind, total, gyro_rad_s, ctx):
        return TimeOffset(delay_s=float(total[0])).inverse(gyro_rad_s, ctx)

    def unexcited(self, kind, ref):
        if ref.kind == "static":
            return "the recording is at rest: a time offset has no excitation (dω/dt = 0)"
        return super().unexcited(kind, ref)

    def summary(self, kind, values, sigmas):
        d, s = values[0], sigmas[0]
        fc = 1 / (2 * math.pi * abs(d)) if d else math.inf
        return f"time offset of {d * 1e3:.2f} ± {s * 1e3:.2f} ms (≡ first-order bandwidth {fc:.0f} Hz)"

    def report(self, kind, fitted):
        d = float(fitted.values[0] + (fitted.total[0] if fitted.total is not None else 0.0))
        params = {"time_offset.delay_s": {"value": d, "sigma": float(fitted.sigmas[0])}}
        return ReportedTerm(params, TimeOffset(delay_s=d), self.summary(kind, np.array([d]), fitted.sigmas))

    def caveat(self, kind, reference_kind):
        if reference_kind == "optical":
            return ("against an optical reference this is the IMU's own delay plus the synchronisation of the two "
                    "systems; one recording cannot separate them")
        return None


# ================================================================ sensed through another sensor
@register_family
class GSensitivityFamily(CandidateFamily):
    """δ = K f: the regressor is the specific force, which a recording without truth measures with
    the accelerometer — whose own errors (thermal drift) would make it a thermometer.  The driver is
    the specific force that *motion* explains (truth, or gravity turned by the reference attitude
    plus the optical position's acceleration, or the rest poses of the gravity reference)."""

    effects = (GSensitivity,)
    driver = "the specific force through motion and attitude"
    quantity = "specific_force"
    channel = Channel.OTHER_SENSOR
    separated_by = "rotations through different attitudes at constant temperature (a multi-position test)"

    def build(self, kind, ctx, ref, options):
        return _class_candidate(self, ctx, "the specific force", ctx.specific_force_true_m_s2)

    def plausible_max(self, kind, ctx):
        return math.radians(0.5) / G0

    def driver_signal(self, cand, ref):
        return motion_specific_force(ref)

    def proxy_reason(self, share: float, ref: Reference) -> str:
        if ref.kind == "static":
            return ("the board does not move (static reference): the specific force is constant and varies only "
                    "through the accelerometer's own errors (e.g. its thermal drift), so g-sensitivity is not "
                    "identifiable here")
        return (f"motion and attitude explain only {share:.0%} of the specific force's variation (needs ≥ 50 %): "
                "the rest is the accelerometer's own error or unmeasured acceleration, a proxy for other causes")


@register_family
class MagneticSensitivityFamily(CandidateFamily):
    effects = (MagneticSensitivity,)
    driver = "the magnetic field through the attitude"
    quantity = "magnetic_field"
    channel = Channel.OTHER_SENSOR
    separated_by = "rotations through different headings at constant temperature, or a field changed on purpose"

    def build(self, kind, ctx, ref, options):
        if ctx.mag_body_ut is None:
            return Untestable(kind, "the recording has no magnetometer channel")
        return _class_candidate(self, ctx, "the magnetic field", ctx.mag_body_ut)

    def plausible_max(self, kind, ctx):
        return math.radians(0.01)

    def driver_signal(self, cand, ref):
        return motion_field(ref)

    def proxy_reason(self, share: float, ref: Reference) -> str:
        if ref.kind == "static":
            return ("the board does not rotate: the field in the body frame varies only through the magnetometer's "
                    "own errors or a moving disturbance, so magnetic sensitivity is not identifiable here")
        return (f"the attitude explains only {share:.0%} of the measured field's variation (needs ≥ 50 %): the rest "
                "is a disturbance or the magnetometer's own error")


# ================================================================ temperature (the thermometer at the gyro)
class _Temperature(CandidateFamily):
    quantity = "temperature"
    channel = Channel.DEDICATED
    driver = "the temperature at the gyro"
    separated_by = "the same motion at another temperature, or a temperature cycle with the board at rest"

    def _range(self, ctx):
        temp = ctx.temperature_c
        return float(np.mean(temp)), float(np.min(temp)), float(np.max(temp))

    def build(self, kind, ctx, ref, options):
        if ctx.temperature_c is None:
            return Untestable(kind, "the recording has no temperature channel")
        span = float(np.ptp(ctx.temperature_c))
        if span < 0.05:
            return Untestable(kind, f"the temperature is constant ({span:.2f} °C span): nothing for a temperature "
                                    "term to follow")
        return self._build(kind, ctx)

    def measurement_check(self, ctx):
        """The thermometer must resolve the span: span ≥ 10 × its noise (the RMS of second differences
        / √6 for white noise) and ≥ 10 × its step (LSB), else the regressor follows the quantization."""
        temp = np.asarray(ctx.temperature_c, float)
        span = float(np.ptp(temp))
        d2 = np.diff(temp, 2)
        noise = float(1.4826 * np.median(np.abs(d2 - np.median(d2)))) / math.sqrt(6.0)
        steps = np.abs(np.diff(temp))
        lsb = float(np.min(steps[steps > 0])) if np.any(steps > 0) else 0.0
        floor = max(noise, lsb)
        if span < 10 * floor:
            return (f"the temperature spans {span:.2f} °C, less than 10× its own resolution ({floor:.3g} °C): a "
                    "temperature term would follow the thermometer's steps, not the temperature")
        return None

    def _build(self, kind, ctx) -> Candidate:
        raise NotImplementedError


@register_family
class TemperatureBiasFamily(_Temperature):
    effects = (TemperatureBias,)

    def _build(self, kind, ctx):
        t_ref, _, _ = self._range(ctx)
        temp = np.broadcast_to((ctx.temperature_c - t_ref)[:, None], ctx.omega_true_rad_s.shape)
        return _class_candidate(self, ctx, "the temperature", temp)

    def plausible_max(self, kind, ctx):
        return math.radians(0.5)


@register_family
class TemperatureScaleFamily(_Temperature):
    effects = (TemperatureScale,)
    driver = "the temperature times the rate"

    def _build(self, kind, ctx):
        t_ref, _, _ = self._range(ctx)
        w = ctx.omega_true_rad_s
        return _class_candidate(self, ctx, "temperature × rate", (ctx.temperature_c - t_ref)[:, None] * w)

    def plausible_max(self, kind, ctx):
        return 1e-3

    def unexcited(self, kind, ref):
        if ref.kind == "static":
            return "the recording is at rest: a temperature-dependent scale factor has no excitation (rate 0)"
        return super().unexcited(kind, ref)


@register_family
class ThermalHysteresisFamily(_Temperature):
    effects = (ThermalHysteresis,)
    driver = "the low-passed temperature rate dT/dt"
    separated_by = "a heating and a cooling pass over the same temperatures"

    def _build(self, kind, ctx):
        series = np.broadcast_to(ThermalHysteresis.candidate_prototype(ctx).regressor(ctx)[:, None],
                                 ctx.omega_true_rad_s.shape)
        return _class_candidate(self, ctx, "the low-passed temperature rate dT/dt", series)

    def plausible_max(self, kind, ctx):
        return math.radians(100.0)


@register_family
class TemperaturePiecewiseFamily(_Temperature):
    """ERICCO, *Measurement Error and Calibration of FOG IMU*: bias and scale at 5 temperature points, linear
    between."""

    effects = (TemperaturePiecewise,)

    def _build(self, kind, ctx):
        temp = np.broadcast_to((ctx.temperature_c - np.mean(ctx.temperature_c))[:, None], ctx.omega_true_rad_s.shape)
        return _class_candidate(self, ctx, "the temperature (piecewise linear)", temp)

    def plausible_max(self, kind, ctx):
        return np.concatenate([np.full(15, math.radians(30.0)), np.full(15, 0.05)])


@register_family
class TemperatureRBFFamily(_Temperature):
    """Qi et al., *Modification of MTEA-Based Temperature Drift Error Compensation Model for MEMS-Gyros*: Gaussian
    RBF on ΔT and ΔT², 6 centres."""

    effects = (TemperatureRBF,)

    def _build(self, kind, ctx):
        t_ref, _, _ = self._range(ctx)
        temp = np.broadcast_to((ctx.temperature_c - t_ref)[:, None], ctx.omega_true_rad_s.shape)
        return _class_candidate(self, ctx, "the temperature (RBF of ΔT, ΔT²)", temp)

    def plausible_max(self, kind, ctx):
        return math.radians(30.0)


# ================================================================ the attitude
def earth_rate_summary(theta: np.ndarray) -> dict[str, float]:
    """Latitude (°) and |ω_ie| relative to the WGS-84 value from the fitted ENU vector."""
    return {"latitude_deg": math.degrees(math.atan2(theta[2], theta[1])),
            "magnitude_over_wgs84": float(np.linalg.norm(theta) / EARTH_RATE_RAD_S)}


@register_family
class EarthRateFamily(CandidateFamily):
    """δ = C_nᵇ ω_ieⁿ, fitted as the 3-vector ω_ieⁿ (ENU) so that it is linear; latitude
    L = atan2(ω_U, ω_N) and |ω_ie| are reported from it, and a size far from Ω is refused."""

    effects = (EarthRate,)
    driver = "the attitude (a rate fixed in ENU)"
    quantity = "attitude"
    channel = Channel.DEDICATED
    display = (RAD2DEG * 3600, "°/h")  # the fitted ENU components, not the effect's latitude
    separated_by = "rotations through different headings and tilts (the Earth rate turns with the attitude)"

    def build(self, kind, ctx, ref, options):
        q = ctx.quat_nb
        if q is None:
            return Untestable(kind, "needs an attitude (truth or optical orientation) to project the Earth rate")
        reg = np.stack([quat_rotate(quat_conjugate(q), np.broadcast_to(e, (q.shape[0], 3))) for e in np.eye(3)], axis=2)

        def to_effect(theta: np.ndarray) -> Effect:
            return EarthRate(latitude_rad=float(math.atan2(theta[2], theta[1])))

        names = tuple(f"earth_rate.omega_ie_enu[{i}]" for i in range(3))
        return Candidate(self, kind, names, to_effect, "the attitude (a constant rate fixed in the ENU frame)",
                         reg[:, :, 2], reg)

    def plausible_max(self, kind, ctx):
        return 1.5 * EARTH_RATE_RAD_S

    def unexcited(self, kind, ref):
        return ("the attitude does not change enough: the Earth rate is a constant in the body frame, "
                "indistinguishable from the bias")

    def implausible(self, kind, theta, sigma, ctx):
        ratio = float(np.linalg.norm(theta)) / EARTH_RATE_RAD_S
        if not 0.5 <= ratio <= 1.5:
            return (f"the rate fixed in ENU is {ratio:.2g} × the Earth rate: not the Earth's rotation (something "
                    "else that follows the attitude, e.g. gravity or the magnetic field)")
        return None

    def summary(self, kind, values, sigmas):
        e = earth_rate_summary(values)
        return (
            f"a rate fixed in ENU: latitude {e['latitude_deg']:.1f}°, "
            f"|ω| = {e['magnitude_over_wgs84']:.2f} × Earth rate"
        )


# ================================================================ time (the catch-all)
@register_family
class BiasDriftFamily(CandidateFamily):
    """Bias drift (``random_walk``, also standing for ``bias_instability``: on one recording the two
    only differ in the spectrum of the same slow bias): a piecewise-linear bias with knots every
    ``drift_knot_s`` (≤ 40 intervals); its random-walk coefficient K is estimated afterwards by
    restricted maximum likelihood (:func:`calib.closeloop.drift.random_walk_mle`).  A spline in time
    can mimic any slow term, so it is the catch-all: chosen only when no candidate tied to a
    measured channel helps."""

    effects = (RandomWalk,)
    driver = "time (a slowly wandering bias)"
    quantity = "time"
    channel = Channel.TIME
    catch_all = True
    separated_by = "a second recording: a drift does not repeat, a deterministic term does"
    display = (RAD2DEG, "°/s")  # the knot biases, not the walk's K

    @staticmethod
    def _hat_index(t: np.ndarray, knots: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        j = np.clip(np.searchsorted(knots, t, side="right") - 1, 0, knots.size - 2)
        w = np.clip((t - knots[j]) / (knots[j + 1] - knots[j]), 0.0, 1.0)
        return j, w

    def build(self, kind, ctx, ref, options):
        t = ctx.t_s
        span = float(t[-1] - t[0])
        if span < 2 * options.drift_knot_s:
            return Untestable(kind, f"the recording ({span:.0f} s) is shorter than two drift knot intervals "
                                    f"({2 * options.drift_knot_s:g} s): a drift cannot be told from the bias")
        k = min(max(2, int(math.ceil(span / options.drift_knot_s)) + 1), 41)
        knots = np.linspace(t[0], t[-1], k)
        names = tuple(f"random_walk.knot[{i}][{j}]" for i in range(3) for j in range(k))
        j_s, w_s = self._hat_index(t, knots)

        def lazy() -> np.ndarray:
            hats = np.zeros((t.size, k))
            rows = np.arange(t.size)
            hats[rows, j_s] = 1 - w_s
            hats[rows, j_s + 1] += w_s
            reg = np.zeros((t.size, 3, 3 * k))
            for i in range(3):
                reg[:, i, i * k : (i + 1) * k] = hats
            return reg

        def apply(theta: np.ndarray) -> np.ndarray:
            th = theta.reshape(3, k)
            return ((1 - w_s)[:, None] * th[:, j_s].T) + (w_s[:, None] * th[:, j_s + 1].T)

        rows = None
        if ref.linear and getattr(ref, "row_time_s", None) is not None and ref.row_axis.min() >= 0:
            j_r, w_r = self._hat_index(ref.row_time_s, knots)
            rows = np.zeros((ref.row_time_s.size, 3 * k))
            m = np.arange(ref.row_time_s.size)
            rows[m, ref.row_axis * k + j_r] = 1 - w_r
            rows[m, ref.row_axis * k + j_r + 1] += w_r

        def to_effect(theta: np.ndarray) -> Effect:  # K is set by the maximum-likelihood step afterwards
            return RandomWalk(value=np.zeros(3))

        cand = Candidate(self, kind, names, to_effect,
                         f"time (piecewise-linear bias, knots every {knots[1] - knots[0]:.0f} s)",
                         np.broadcast_to(t[:, None], (t.size, 3)), None, rows, lazy, apply)
        cand._cache["knots"] = knots
        return cand

    def _k_hat(self, cand: Candidate, fitted_residual) -> tuple[float, float]:
        if "k" not in cand._cache:
            k, sk = math.nan, math.nan
            series = fitted_residual()
            if series is not None:
                t, r = series
                block_s = max(1.0, (t[-1] - t[0]) / 400.0)
                b = time_block_index(t, block_s)
                nb = int(b.max())  # drop the last partial block
                keep = b < nb
                if nb >= 8:
                    means, _ = block_means(b[keep], r[keep], nb)
                    k, sk = random_walk_mle(list(means.T), block_s)
            cand._cache["k"] = (k, sk)
        return cand._cache["k"]

    def extra_covariance(self, cand, influence, ref, residual_without):
        """The drift the spline leaves between its knots, in every parameter's covariance.

        Between knots a and b = a + Δ the linear interpolation of a Wiener process of coefficient K
        leaves a Brownian bridge, Cov(x_t, x_s) = K² (min − a)(b − max)/Δ.  The least-squares θ̂ = U r
        then has the extra covariance K² Σ_axes Σ_intervals Σ_{t,s} U_t U_sᵀ B(t, s): a slow residual
        that Sokal's τ misses and that biased slow regressors (a misalignment over 9 s turns) by
        2–4σ of their white-noise σ next to a drift (suite, 10 seeds).  For sorted x = t − a:
        Σ_{t,s} u_t v_s B = [Σ_s (Δ − x_s)(u_s C^v_s + v_s C^u_s) − Σ_t u_t v_t x_t (Δ − x_t)] / Δ,
        C^u_s = Σ_{t ≤ s} u_t x_t (cumulative sums: O(M P²))."""
        if not ref.linear or getattr(ref, "row_time_s", None) is None:
            return None
        k, _ = self._k_hat(cand, residual_without)
        if not math.isfinite(k) or k <= 0:
            return None
        knots = cand._cache["knots"]
        p = influence.shape[0]
        out = np.zeros((p, p))
        for a in range(3):
            sel = np.flatnonzero(ref.row_axis == a)
            t = ref.row_time_s[sel]
            seg = np.clip(np.searchsorted(knots, t, side="right") - 1, 0, knots.size - 2)
            for i in np.unique(seg):
                rows = sel[seg == i]
                d = knots[i + 1] - knots[i]
                x = ref.row_time_s[rows] - knots[i]
                u = influence[:, rows]                   # (P, n), rows sorted in time
                c = np.cumsum(u * x, axis=1)
                w = u * (d - x)
                out += (w @ c.T + c @ w.T - (u * (x * (d - x))) @ u.T) / d
        return k**2 * out

    def plausible_max(self, kind, ctx):
        return math.radians(5.0)

    def report(self, kind, fitted):
        """K of the drift: restricted ML on the block means of the residual of the final model without
        the drift (rate references; ≤ 400 blocks, the REML is O(n³) in them); the knot biases are a
        realisation, not parameters of the device."""
        k, sk = self._k_hat(fitted.candidate, fitted.residual_without)
        if not math.isfinite(k):
            return ReportedTerm(fitted.params(), RandomWalk(value=np.zeros(3)),
                                self.summary(kind, fitted.values, fitted.sigmas))
        per = RAD2DEG * 3600 * 60
        text = (f"bias drift with random-walk coefficient K = {k * per:.3g} ± {sk * per:.2g} °/h/√h "
                "(restricted ML on the residual)")
        return ReportedTerm({"random_walk.value": {"value": k, "sigma": sk}}, RandomWalk(value=np.full(3, k)), text)

    def summary(self, kind, values, sigmas):
        return f"bias drift: knot biases RMS {np.std(values) * RAD2DEG:.4f} °/s"

    def compare_with_truth(self, kind, finding_params, declared_params, true_effect, device):
        p = finding_params["random_walk.value"]
        return np.array([p["value"]]), np.array([float(true_effect.value[0])]), np.array([p["sigma"]])


@register_family
class RateRampFamily(CandidateFamily):
    """``rate_ramp`` (IEEE 952 R, a straight-line bias drift) is never a separate loop candidate: the
    drift term (``random_walk``, a piecewise-linear bias) contains every straight line, and a ramp
    proposed beside it would take the random walk's place on the one recording the loop sees (a
    drift does not repeat between recordings, so a line fitted to one is one path of the walk).
    ``calib noise`` identifies R from the wavelet variance of a long static record instead."""

    effects = (RateRamp,)
    driver = "time (a straight-line bias drift)"
    quantity = "time"
    channel = Channel.TIME
    separated_by = "a long static record (calib noise): a ramp's Allan deviation grows as τ, a walk's as √τ"

    def build(self, kind, ctx, ref, options):
        return Untestable(kind, "a straight-line drift is contained in the drift term (random_walk); identify a rate "
                                "ramp from a long static record with calib noise")
