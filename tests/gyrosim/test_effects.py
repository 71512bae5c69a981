"""The effect vocabulary and sensor model: round trips, sensitivities, units, noise
statistics, temperature, immutability and bad input."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from conftest import session

from gyrosim import effects as E
from gyrosim.effects import (
    EFFECTS,
    Bandwidth,
    Bias,
    EarthRate,
    Effect,
    GSensitivity,
    MagneticSensitivity,
    Misalignment,
    NonOrthogonality,
    Quantization,
    Saturation,
    ScaleFactor,
    ScaleNonlinearity,
    SignalContext,
    TemperatureBias,
    TemperatureScale,
    ThermalHysteresis,
    TimeOffset,
    WhiteNoise,
)
from gyrosim.errors import GyrosimError, PresetError
from gyrosim.sensor_model import SensorModel, load_sensor, sensor_preset_names
from gyrosim.simulate import apply_sensor, signal_context, simulate
from gyrosim.thermal import ThermalModel
from gyrosim.units import G0, to_si

DEG = math.pi / 180


@pytest.fixture(scope="module")
def ctx() -> SignalContext:
    """Truth of a typical zhou2020 session with a power-on warm-up temperature."""
    rec = session("typical")
    temp = ThermalModel(ambient_c=20.0, self_heating_c=6.0, self_heating_tau_s=60.0, case_tau_s=20.0).temperature(
        rec.t_s
    )
    return signal_context(rec.with_signals(temp_c=temp))


def deterministic_effects():
    """One non-trivial instance of every deterministic, invertible effect (SI)."""
    return [
        ("gyro", Bias(value=[0.03, -0.02, 0.035])),
        ("gyro", ScaleFactor(value=[0.05, 0.04, -0.03])),
        ("gyro", NonOrthogonality(value=[0.025, 0.02, 0.01])),
        ("gyro", Misalignment(value=[0.01, -0.02, 0.005, 0.01, -0.01, 0.02])),
        ("gyro", E.GyroAccMisalignment(value=[0.015, -0.0075, 0.004])),
        ("gyro", ScaleNonlinearity(value=[2e-3, -1e-3, 1.5e-3])),
        ("gyro", E.ScaleAsymmetry(value=[2e-3, -1e-3, 1.5e-3])),
        ("gyro", GSensitivity(value=np.arange(9).reshape(3, 3) * 1e-4)),
        ("gyro", TemperatureBias(coefficients=[[1e-3, 2e-5], [-2e-3, 0.0], [5e-4, -1e-5]])),
        ("gyro", TemperatureScale(coefficients=[[3e-4], [-2e-4], [1e-4]])),
        ("gyro", ThermalHysteresis(value=[0.05, -0.03, 0.02], tau_s=30.0)),
        (
            "gyro",
            E.TemperaturePiecewise(
                points_c=[18.0, 21.0, 24.0, 27.0],
                bias=[[1e-3, 2e-3, 0.0, -1e-3], [0.0, 5e-4, 1e-3, 2e-3], [-1e-3, 0.0, 1e-3, 0.0]],
                scale=[[1e-3, 0.0, -1e-3, 2e-3], [0.0, 1e-3, 0.0, 1e-3], [2e-3, 1e-3, 0.0, 0.0]],
            ),
        ),
        (
            "gyro",
            E.TemperatureRBF(
                centres_c=[18.0, 22.0, 26.0],
                width_c=3.0,
                t_ref_c=22.0,
                weights=[[1e-3, -2e-3, 1e-3], [0.0, 1e-3, 0.0], [2e-3, 0.0, -1e-3]],
            ),
        ),
        ("gyro", EarthRate(latitude_rad=48 * DEG)),
        ("gyro", MagneticSensitivity(value=np.eye(3) * 1e-5)),
        ("gyro", Bandwidth(cutoff_hz=41.0)),
        ("gyro", TimeOffset(delay_s=0.0034)),
        ("gyro", E.RateRamp(value=[1e-5, -2e-5, 3e-6])),
        ("accelerometer", Bias(value=[0.3, -0.2, 0.5])),
        ("accelerometer", ScaleFactor(value=[0.01, -0.02, 0.03])),
        ("accelerometer", Misalignment(value=[0.01, -0.02, 0.005, 0.01, -0.01, 0.02])),
        ("accelerometer", ScaleNonlinearity(value=[1e-4, -2e-4, 5e-5])),
        ("accelerometer", Bandwidth(cutoff_hz=44.8)),
        ("accelerometer", E.RateRamp(value=[2e-5, 1e-5, -3e-5])),
        ("magnetometer", E.HardIron(value=[40.0, -25.0, 60.0])),
        ("magnetometer", E.SoftIron(matrix=[[1.05, 0.03, -0.02], [0.03, 0.96, 0.01], [-0.02, 0.01, 1.02]])),
        ("magnetometer", E.FrameRotation(angles=[0.01, -0.02, 0.015])),
        ("magnetometer", E.AttachedMagnet(value=[4.0, -9.0, 14.0], soft_iron=[[0.02, 0.01, 0.0], [0.01, -0.01, 0.0],
                                                                              [0.0, 0.0, 0.015]],
                                          t_on_s=40.0, t_off_s=120.0)),
    ]


def _truth_of(ctx: SignalContext, triad: str) -> np.ndarray:
    return {"gyro": ctx.omega_true_rad_s, "accelerometer": ctx.specific_force_true_m_s2,
            "magnetometer": ctx.mag_body_ut}[triad]


def test_every_kind_is_covered_or_declared_random_or_lossy():
    covered = {e.kind for _, e in deterministic_effects()}
    for kind, cls in EFFECTS.items():
        assert kind in covered or cls.stochastic or not cls.invertible, kind


@pytest.mark.parametrize("triad, effect", deterministic_effects(), ids=lambda v: getattr(v, "kind", v))
def test_round_trip_compensate_apply_is_identity(ctx, triad, effect):
    x = _truth_of(ctx, triad)
    model = SensorModel("one", **{triad: (effect,)})
    y = model.apply_triad(triad, x, ctx, np.random.default_rng(0))
    assert np.abs(y - x).max() > 1e-7  # the effect does something
    back = model.compensate_triad(triad, y, ctx)
    assert np.abs(back - x).max() <= 1e-12 * np.abs(x).max()


def test_whole_deterministic_model_round_trips_together(ctx):
    effs = deterministic_effects()
    model = SensorModel("all", gyro=tuple(e for t, e in effs if t == "gyro"),
                        accelerometer=tuple(e for t, e in effs if t == "accelerometer"),
                        magnetometer=tuple(e for t, e in effs if t == "magnetometer"))
    for triad in ("gyro", "accelerometer", "magnetometer"):
        x = _truth_of(ctx, triad)
        y = model.apply_triad(triad, x, ctx, np.random.default_rng(0))
        assert np.abs(model.compensate_triad(triad, y, ctx) - x).max() <= 1e-12 * np.abs(x).max()


def test_lossy_effects_compensate_as_far_as_information_allows(ctx):
    x = ctx.omega_true_rad_s
    lsb = 0.015267 * DEG
    q = SensorModel("q", gyro=(Quantization(lsb=[lsb] * 3),))
    y = q.apply_triad("gyro", x, ctx, np.random.default_rng(0))
    assert np.abs(q.compensate_triad("gyro", y, ctx) - x).max() <= lsb / 2 + 1e-15
    sat = SensorModel("s", gyro=(Saturation(range=[1.0, 1.0, 1.0]),))  # zhou2020 peaks at 1.31 rad/s
    y = sat.apply_triad("gyro", x, ctx, np.random.default_rng(0))
    with pytest.raises(GyrosimError, match="saturated"):
        sat.compensate_triad("gyro", y, ctx)


@pytest.mark.parametrize(
    "triad, effect",
    [p for p in deterministic_effects() if p[1].stage == "error" and type(p[1]).sensitivity is not Effect.sensitivity],
    ids=lambda v: getattr(v, "kind", v),
)
def test_analytic_sensitivity_matches_finite_differences(ctx, triad, effect):
    """Effects with a closed-form ∂y/∂θ (the others use the generic central differences)."""
    x = _truth_of(ctx, triad)[::50]
    sub = SignalContext(ctx.t_s[::50], ctx.omega_true_rad_s[::50], ctx.specific_force_true_m_s2[::50],
                        ctx.temperature_c[::50], ctx.quat_nb[::50], ctx.mag_body_ut[::50])
    analytic = effect.sensitivity(x, sub)
    numeric = Effect.sensitivity(effect, x, sub)  # the base class: central differences
    # linear-in-θ effects: central differences are exact up to rounding (h = 1e-6 relative)
    np.testing.assert_allclose(analytic, numeric, atol=1e-8 * max(1.0, np.abs(analytic).max()))


def test_noise_statistics_match_the_density():
    # white noise: per-sample σ = N √f_s (IEEE-952 coefficient); 200 000 samples give σ to 0.16 %
    fs, n = 200.0, 200_000
    t = np.arange(n) / fs
    ctx = SignalContext(t, np.zeros((n, 3)), np.zeros((n, 3)))
    N = to_si(0.01, "deg/s/sqrt(Hz)", "rate_density")
    y = WhiteNoise(density=[N] * 3).delta(np.zeros((n, 3)), ctx, np.random.default_rng(1))
    assert np.std(y, axis=0) == pytest.approx(np.full(3, N * math.sqrt(fs)), rel=0.01)  # 6σ bound


def test_allan_deviation_recovers_the_mpu9250_noise_terms(tmp_path):
    """2 h static at 100 Hz, all three gyro axes pooled.

    Expected Allan confidence for this length (Monte Carlo over 12 seeds, docs/error-model.md, "Allan deviation"):
    N ±0.1 %, B ±2.8 %, K ±10.7 % (1σ), unbiased within the Monte Carlo error.  N and B are held
    to the 10 % asked for (≥ 3.5σ).  K cannot be: its information in 2 h is ~T/τ_cross ≈ 100
    RRW-dominated samples, so "within 10 %" holds for only ~65 % of 2-hour records; it is held to
    32 % (3σ) here.
    """
    from calib.noise.allan import allan_deviation, fit_noise_terms, plot_allan

    preset = load_sensor("mpu9250")
    noise = SensorModel("noise", gyro=tuple(e for e in preset.gyro if e.stochastic))
    fs, n = 100.0, 2 * 3600 * 100
    ctx = SignalContext(np.arange(n) / fs, np.zeros((n, 3)), np.zeros((n, 3)))
    y = noise.apply_triad("gyro", ctx.omega_true_rad_s, ctx, np.random.default_rng(7))
    curves = [allan_deviation(y[:, i], fs) for i in range(3)]
    fit = fit_noise_terms(curves)
    truth = {e.kind: e for e in noise.gyro}
    assert fit.arw == pytest.approx(truth["white_noise"].density[0], rel=0.10)
    assert fit.bias_instability == pytest.approx(truth["bias_instability"].value[0], rel=0.10)
    assert fit.rate_random_walk == pytest.approx(truth["random_walk"].value[0], rel=0.32)
    png = plot_allan(curves, fit, tmp_path / "allan.png", unit_scale=3600 / DEG, unit="°/h")
    assert png.stat().st_size > 10_000


@pytest.mark.parametrize(
    "value, unit, quantity, si",
    [
        (1.0, "deg/s/sqrt(Hz)", "rate_density", DEG),
        (60.0, "deg/sqrt(h)", "rate_density", DEG),        # 1 °/s/√Hz = 60 °/√h
        (60.0, "°/√h", "rate_density", DEG),
        (1.0, "m/s/sqrt(h)", "acceleration_density", 1 / 60),
        (1000.0, "µg/√Hz", "acceleration_density", 1e-3 * G0),
        (1.0, "mg/sqrt(Hz)", "acceleration_density", 1e-3 * G0),
        (3600.0, "deg/h", "rate", DEG),
        (1.0, "dps", "rate", DEG),
        (1.0, "g", "acceleration", G0),
        (1000.0, "mg", "acceleration", G0),
        (1e4, "ppm", "fraction", 0.01),
        (1.0, "%", "fraction", 0.01),
        (60.0, "deg/h/sqrt(h)", "rate_random_walk", DEG / 3600),
        (1.0, "deg/s/sqrt(h)", "rate_random_walk", DEG / 60),
        (1.0, "deg/s/g", "rate_per_acceleration", DEG / G0),
        (1e6, "deg/h/T", "rate_per_tesla", DEG / 3600),
        (1.0, "ms", "time", 1e-3),
    ],
)
def test_units_convert_exactly(value, unit, quantity, si):
    assert to_si(value, unit, quantity) == pytest.approx(si, rel=1e-12)


def test_wrong_unit_is_rejected_with_the_accepted_list():
    with pytest.raises(GyrosimError, match=r"use one of: .*deg/s/sqrt\(hz\)"):
        to_si(0.01, "deg/s", "rate_density")
    with pytest.raises(GyrosimError, match="not accepted for acceleration"):
        to_si(1.0, "deg/s", "acceleration")


def test_one_sided_density_convention(tmp_path):
    base = '[[gyro]]\neffect = "white_noise"\ndensity = [0.01, 0.01, 0.01]\nunit = "deg/s/sqrt(Hz)"\n'
    (tmp_path / "a.toml").write_text(base)
    (tmp_path / "b.toml").write_text(base + 'convention = "one-sided"\n')
    a, b = load_sensor(tmp_path / "a.toml").gyro[0], load_sensor(tmp_path / "b.toml").gyro[0]
    assert a.density[0] == pytest.approx(0.01 * DEG) and b.density[0] == pytest.approx(0.01 * DEG / math.sqrt(2))


def test_warm_up_produces_the_declared_bias_of_temperature():
    """Power-on warm-up at rest: the gyro output follows the drawn bias(T) coefficient.

    Only temperature bias + white noise, so the regression slope has standard error
    σ/(√n · std(T)) (σ = N√f_s); we require |ĉ − c| < 5 standard errors.
    """
    preset = load_sensor("mpu9250")
    model = SensorModel("warmup", gyro=tuple(e for e in preset.gyro if e.kind in ("temperature_bias", "white_noise")),
                        thermal=preset.thermal)
    device = model.realize(np.random.default_rng(11))
    fs, n = 50.0, 50 * 1800
    t = np.arange(n) / fs
    temp = device.thermal.temperature(t)
    assert temp[-1] - temp[0] > 2.5  # warms by most of the preset's 5 °C self-heating in 30 min
    ctx = SignalContext(t, np.zeros((n, 3)), np.zeros((n, 3)), temperature_c=temp)
    y = device.apply_triad("gyro", ctx.omega_true_rad_s, ctx, np.random.default_rng(12))
    dT = temp - 25.0
    declared = [e for e in device.gyro if e.kind == "temperature_bias"][0].coefficients[:, 0]
    sigma = [e for e in device.gyro if e.kind == "white_noise"][0].density * math.sqrt(fs)
    for i in range(3):
        slope = np.polyfit(dT, y[:, i], 1)[0]
        se = sigma[i] / (math.sqrt(n) * dT.std())
        assert abs(slope - declared[i]) < 5 * se, (i, slope, declared[i], se)


def test_nothing_mutates_its_inputs(ctx):
    rec = session("typical")
    x = np.array(ctx.omega_true_rad_s)  # writeable copy
    before = x.copy()
    model = load_sensor("mpu9250").realize(np.random.default_rng(0))
    c = SignalContext(
        ctx.t_s, x, np.array(ctx.specific_force_true_m_s2), ctx.temperature_c, ctx.quat_nb, ctx.mag_body_ut
    )
    y = model.apply_triad("gyro", x, c, np.random.default_rng(1))
    y_before = y.copy()
    model.compensate_triad("gyro", y, c)
    np.testing.assert_array_equal(x, before)
    np.testing.assert_array_equal(y, y_before)
    gyro_before = rec.gyro_rad_s.copy()
    apply_sensor(rec, "mpu9250", np.random.default_rng(2))
    np.testing.assert_array_equal(rec.gyro_rad_s, gyro_before)


@pytest.mark.parametrize(
    "make, message",
    [
        (lambda: Bias(value=[np.nan, 0, 0]), "NaN"),
        (lambda: WhiteNoise(density=[-1.0, 0, 0]), ">= 0"),
        (lambda: NonOrthogonality(value=[0.9, 0.9, 0.9]), "singular"),  # det(I + N) = 0.028
        (lambda: Misalignment(value=[1, 1, 1, 1, 1, 1]), "singular"),
        (lambda: E.GyroAccMisalignment(value=[3.0, 0.0, 0.0]), "small-angle"),
        (lambda: ScaleFactor(value=[np.inf, 0, 0]), "NaN/inf"),
    ],
)
def test_bad_parameters_are_rejected(make, message):
    with pytest.raises(GyrosimError, match=message):
        make()


def test_temperature_outside_the_preset_range_is_an_error():
    model = SensorModel("t", gyro=(TemperatureBias(coefficients=[[1e-3]] * 3, range_c=(-40.0, 85.0)),),
                        temperature_range_c=(-40.0, 85.0))
    n = 10
    ctx = SignalContext(np.arange(n) * 0.1, np.zeros((n, 3)), np.zeros((n, 3)), temperature_c=np.full(n, 95.0))
    with pytest.raises(GyrosimError, match="85"):
        model.apply(ctx, np.random.default_rng(0))


def test_bad_preset_files(tmp_path):
    cases = {
        "unit": '[[gyro]]\neffect = "bias"\nvalue = [1, 1, 1]\nunit = "furlongs"\n',
        "kind": '[[gyro]]\neffect = "wobble"\nvalue = 1\nunit = "deg/s"\n',
        "triad": '[[accelerometer]]\neffect = "earth_rate"\nlatitude = 10\nunit = "deg"\n',
        "key": 'colour = "blue"\n',
    }
    for name, text in cases.items():
        p = tmp_path / f"{name}.toml"
        p.write_text(text)
        with pytest.raises(PresetError):
            load_sensor(p)
    with pytest.raises(PresetError, match="mpu9250"):
        load_sensor("mpu9999")


def test_every_preset_loads_realizes_and_round_trips_through_json():
    for name in sensor_preset_names():
        m = load_sensor(name)
        d = m.realize(np.random.default_rng(0))
        back = SensorModel.from_dict(json.loads(d.to_json()))
        assert back.to_json() == d.to_json()


def test_recording_stores_the_drawn_device_and_is_reproducible():
    rec = simulate("vertical_only", "steady", "mpu9250", 100.0, seed=5)
    stored = SensorModel.from_dict(json.loads(rec.meta["sensor_model"]))
    drawn_bias = [e for e in stored.gyro if e.kind == "bias"][0].value
    assert np.any(drawn_bias != 0)  # the turn-on bias was drawn and recorded
    # re-applying the stored device with the same noise stream reproduces the file's gyro exactly
    truth = simulate("vertical_only", "steady", None, 100.0, seed=5)
    _, sensor_rng = np.random.default_rng(5).spawn(2)
    again = apply_sensor(truth, stored, sensor_rng, realize=False)
    np.testing.assert_array_equal(again.gyro_rad_s, rec.gyro_rad_s)
    np.testing.assert_array_equal(again.acc_m_s2, rec.acc_m_s2)
    np.testing.assert_array_equal(truth.truth.omega_body_rad_s, rec.truth.omega_body_rad_s)
    assert rec.temp_c is not None and rec.temp_c[-1] > rec.temp_c[0]


def test_fast_kernels_equal_the_numpy_reference(ctx):
    """Every effect's in-place fast path (gyrosim._kernels) equals its numpy definition."""
    from scipy import signal as sp_signal

    from gyrosim.effects import Saturation

    x = np.ascontiguousarray(ctx.omega_true_rad_s)
    for _, e in deterministic_effects():
        if e.stage != "error":
            continue
        y = x.copy()
        e.add_delta(y, x, ctx, None)
        np.testing.assert_allclose(y, x + e.delta(x, ctx), rtol=0, atol=1e-15 * max(1.0, np.abs(x).max()))
    bw = Bandwidth(cutoff_hz=41.0)
    a = math.exp(-2 * math.pi * 41.0 * ctx.dt_s)
    ref = sp_signal.lfilter([1 - a], [1, -a], x, axis=0, zi=a * x[:1])[0]
    np.testing.assert_allclose(bw.transform(x, ctx), ref, rtol=0, atol=1e-14)
    lsb = np.full(3, 0.015267 * DEG)
    np.testing.assert_array_equal(Quantization(lsb=lsb).transform(x, ctx), np.rint(x * (1.0 / lsb)) * lsb)
    np.testing.assert_array_equal(Saturation(range=[1.0] * 3).transform(x, ctx), np.clip(x, -1.0, 1.0))
    # white noise: the kernel adds exactly σ·w for the same normals
    wn = WhiteNoise(density=[1e-3, 2e-3, 3e-3])
    y = np.zeros_like(x)
    wn.add_delta(y, x, ctx, np.random.default_rng(4))
    np.testing.assert_allclose(y, wn.delta(x, ctx, np.random.default_rng(4)), rtol=1e-15)


def test_gyro_acc_misalignment_is_the_rotation_of_the_gyro_axes_to_first_order():
    """The gyro's axes turned by α against the body (accelerometer) frame read R(α)ᵀ ω; the effect is its linear
    part ω × α, and what it leaves out is symmetric (½[α×]², the share of S and G) and second order: at 1° per axis
    |½[α×]²| ≤ α² = 3e-4 (the bound below, with room for the cubic term)."""
    alpha = np.radians([1.0, -0.5, 0.8])
    e = E.GyroAccMisalignment(value=alpha)
    rest = E.rotation_matrix(alpha).T - (np.eye(3) + e.matrix())
    a = float(np.linalg.norm(alpha))
    assert np.abs(rest - rest.T).max() < a**3             # antisymmetric parts agree to third order: 2(a − sin a)/a·|α|
    assert np.abs(rest).max() < float(alpha @ alpha)
    w = np.array([[0.3, -1.2, 0.7]])
    ctx = SignalContext(np.zeros(1), w, np.zeros((1, 3)), dt_s=0.01)
    np.testing.assert_allclose(e.delta(w, ctx), np.cross(w, alpha), atol=1e-15)
    # a preset in degrees reads as radians
    raw = E.GyroAccMisalignment.preset_to_si({"value": [1.0, 0.0, 0.0], "value_sigma": [0.5, 0.5, 0.5]}, "deg", "angle")
    np.testing.assert_allclose(raw["value"], [DEG, 0, 0])
    np.testing.assert_allclose(raw["value_sigma"], [DEG / 2] * 3)
