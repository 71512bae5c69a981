"""Noise identification: wavelet variance, GMWM model selection, intervals, units, plan, inflation, bad input.

Data come from tests/independent_noise.py (numpy only, no gyrosim); the wavelet-variance theory is
checked against gyrosim's own draws too, because the simulator and the estimator must agree on
each effect.  Tolerances come from the estimator's own covariance Σ (wavelet.wv_covariance),
itself checked against the spread of realisations.  Big campaigns: benchmarks/noise_mc.py (docs).
"""

from __future__ import annotations

import json
import math

import independent_noise as ind
import numpy as np
import pytest

from gyrosim.effects import (
    BiasInstability,
    GaussMarkov,
    QuantizationNoise,
    RandomWalk,
    RateRamp,
    SignalContext,
    WhiteNoise,
)
from gyrosim.sensor_model import load_sensor

from calib.app.cli import main as calib_main
from calib.noise import identify_noise, parse_model
from calib.noise.gmwm import identify_axis
from calib.noise.plan import noise_terms_of, predicted_relative_sigma
from calib.noise.wavelet import scales_for, wavelet_variance, wv_covariance, wv_covariance_dense

FS = 100.0
DT = 1 / FS


def _theory_check(draw, effect, n=2**14, reps=8, skip_small=0):
    """Mean ν̂² over reps×3 realisations vs the effect's ν²: within 4 standard errors of the mean
    at every scale (se from Σ/√(3 reps), Σ at the effect's own PSD; 4σ over ~10 scales keeps the
    false-failure rate < 1e-3)."""
    m = scales_for(n)
    est = np.array([wavelet_variance(draw()[:, i], DT, m).nu2 for _ in range(reps) for i in range(3)])
    theory = effect.haar_wavelet_variance(m, DT)[0]
    coeff = n - 2.0 * m + 1
    sd = (
        np.sqrt(np.diag(wv_covariance(lambda f: effect.discrete_psd(f, DT)[0], m, coeff)))
        if effect.kind != "rate_ramp"
        else np.full(m.size, 1e-300)
    )
    z = (est.mean(axis=0) - theory) / (sd / math.sqrt(est.shape[0]) + 1e-12 * theory)
    assert np.all(np.abs(z[skip_small:]) < 4), (effect.kind, np.round(z, 2))


@pytest.mark.parametrize("make", ["white", "rw", "gm", "qn"])
def test_wavelet_variance_theory_matches_independent_generator(make):
    rng = np.random.default_rng(11)
    n = 2**14
    eff, draw = {
        "white": (WhiteNoise(density=np.full(3, 0.01)), lambda: ind.white(n, FS, 0.01, rng)),
        "rw": (RandomWalk(value=np.full(3, 1e-3)), lambda: ind.random_walk(n, FS, 1e-3, rng)),
        "gm": (
            GaussMarkov(sigma=np.full(3, 0.05), tau_s=np.full(3, 0.3)),
            lambda: ind.gauss_markov(n, FS, 0.05, 0.3, rng),
        ),
        "qn": (QuantizationNoise(value=np.full(3, 1e-4)), lambda: ind.quantization(n, FS, 1e-4, rng)),
    }[make]
    _theory_check(draw, eff, n)


def test_flicker_theory_matches_kasdin_generator_above_the_smallest_scales():
    # Kasdin's 1/|2 sin πf| spectrum equals B²/(2πf) only at low f: compare from m = 4 on
    rng = np.random.default_rng(12)
    _theory_check(lambda: ind.flicker(2**14, 0.01, rng), BiasInstability(value=np.full(3, 0.01)), skip_small=2)


@pytest.mark.parametrize("effect", [GaussMarkov(sigma=np.full(3, 0.02), tau_s=np.full(3, 1.0)),
                                    QuantizationNoise(value=np.full(3, 2e-4)), RateRamp(value=np.full(3, 1e-4)),
                                    BiasInstability(value=np.full(3, 0.005), model="gauss_markov", tau_s=2.0)])
def test_gyrosim_draws_match_their_own_wavelet_variance(effect):
    n = 2**14
    ctx = SignalContext(np.arange(n) * DT, np.zeros((n, 3)), np.zeros((n, 3)), dt_s=DT)
    rng = np.random.default_rng(3)
    if effect.kind == "rate_ramp":  # deterministic: exact
        y = effect.delta(np.zeros((n, 3)), ctx, rng)
        m = scales_for(n)
        np.testing.assert_allclose(
            wavelet_variance(y[:, 0], DT, m).nu2, effect.haar_wavelet_variance(m, DT)[0], rtol=1e-9
        )
        return
    _theory_check(lambda: effect.delta(np.zeros((n, 3)), ctx, rng), effect, n)


def test_banded_covariance_equals_dense_rule():
    # the octave-band rule with averaged fast oscillations against the exact dense midpoint rule
    n = 2**16
    m = scales_for(n)
    effs = [
        WhiteNoise(density=np.full(3, 0.01)),
        RandomWalk(value=np.full(3, 1e-3)),
        BiasInstability(value=np.full(3, 0.01)),
    ]
    psd = lambda f: sum(e.discrete_psd(f, DT)[0] for e in effs)  # noqa: E731
    a, b = wv_covariance(psd, m, n - 2.0 * m + 1), wv_covariance_dense(psd, m, n - 2.0 * m + 1)
    d = np.sqrt(np.diag(b))
    assert np.max(np.abs(a - b) / np.outer(d, d)) < 0.01


def test_covariance_matches_spread_of_realisations():
    # Σ_jj against the sample variance of 60 realisations of white + RW: relative se of a sample
    # sd from 60 draws is 1/√118 = 9 %: each ratio within 0.7–1.3 (3.3σ)
    rng = np.random.default_rng(4)
    n = 2**13
    m = scales_for(n)
    est = np.array(
        [
            wavelet_variance(x[:, i], DT, m).nu2
            for x in (ind.white(n, FS, 0.01, rng) + ind.random_walk(n, FS, 2e-3, rng) for _ in range(20))
            for i in range(3)
        ]
    )
    effs = [WhiteNoise(density=np.full(3, 0.01)), RandomWalk(value=np.full(3, 2e-3))]
    sd = np.sqrt(np.diag(wv_covariance(lambda f: sum(e.discrete_psd(f, DT)[0] for e in effs), m, n - 2.0 * m + 1)))
    ratio = est.std(axis=0, ddof=1) / sd
    assert np.all((ratio > 0.7) & (ratio < 1.3)), np.round(ratio, 2)


@pytest.mark.parametrize("truth", ["white+rw", "white+gm+gm"])
def test_selection_and_intervals_on_independent_data(truth):
    """One 30-min record, three axes: the true model is chosen on at least two of three axes (the
    campaign's rate is ≥ 90 %, docs/noise.md), and each true parameter lies in the 99.9 % interval
    (|z| < 3.3) of the fitted true model."""
    rng = np.random.default_rng(21)
    n = int(1800 * FS)
    if truth == "white+rw":
        x = ind.white(n, FS, 0.01, rng) + ind.random_walk(n, FS, 1.5e-3, rng)
        true = np.log([0.01, 1.5e-3])
    else:
        x = (
            ind.white(n, FS, 0.01, rng)
            + ind.gauss_markov(n, FS, 0.05, 0.5, rng)
            + ind.gauss_markov(n, FS, 0.02, 50.0, rng)
        )
        true = np.log([0.01, 0.05, 0.5, 0.02, 50.0])
    kinds = parse_model(truth)
    right = 0
    for ax in range(3):
        sel = identify_axis(x[:, ax], DT)
        right += sel.chosen.kinds == kinds
        f = identify_axis(x[:, ax], DT, [kinds], wv=sel.wv).chosen
        z = (f.log_params - true) / np.sqrt(np.diag(f.cov_log))
        assert np.all(np.abs(z) < 3.3), (ax, np.round(z, 2))
    assert right >= 2


def test_plan_prediction_matches_spread_of_fits():
    # predicted σ(log θ̂) vs the sd over 45 fitted realisations (relative se of an sd: 1/√88 = 11 %;
    # within ±35 %, 3σ)
    rng = np.random.default_rng(5)
    n = int(300 * FS)
    kinds, logp = noise_terms_of((WhiteNoise(density=np.full(3, 0.01)), RandomWalk(value=np.full(3, 3e-3))))
    pred = predicted_relative_sigma(kinds, logp, FS, n / FS)
    est = []
    for _ in range(15):
        x = ind.white(n, FS, 0.01, rng) + ind.random_walk(n, FS, 3e-3, rng)
        est += [identify_axis(x[:, i], DT, [kinds]).chosen.log_params for i in range(3)]
    ratio = pred / np.std(est, axis=0, ddof=1)
    assert np.all(np.abs(ratio - 1) < 0.35), ratio


def test_inflation_is_one_for_white_and_grows_with_random_walk():
    rng = np.random.default_rng(6)
    n = int(1200 * FS)
    white = identify_noise(ind.white(n, FS, 0.01, rng), FS, models=[parse_model("white")])
    for ax in white.inflation["axes"]:
        f, sf = np.array(ax["white_only"]["factor"]), np.array(ax["white_only"]["sigma"])
        assert np.all(np.abs(f - 1) < 4 * sf)  # σ(F) = F σ(ν̂)/(2ν̂) from Σ, per scale
    rw = identify_noise(ind.white(n, FS, 0.01, rng) + ind.random_walk(n, FS, 3e-3, rng), FS,
                        models=[parse_model("white+rw")])
    for ax in rw.inflation["axes"]:
        # white-only model at τ = 100 s: √(1 + K²τ²/(3N²)) = √(1 + 300) ≈ 17; the chosen model stays ≈ 1
        assert ax["white_only"]["max_over_horizon"]["100.0"]["factor"] > 8
        f, sf = np.array(ax["chosen_model"]["factor"]), np.array(ax["chosen_model"]["sigma"])
        assert np.all(np.abs(f - 1) < 4 * sf)


def test_cli_noise_json_units_and_sensor_round_trip(tmp_path):
    rng = np.random.default_rng(7)
    n = int(300 * FS)
    csv = ind.write_csv(tmp_path / "static.csv", FS, ind.white(n, FS, 0.002, rng) + ind.random_walk(n, FS, 6e-4, rng))
    out = tmp_path / "noise.json"
    assert calib_main(["noise", str(csv), "--gyro-unit", "deg/s", "--acc-unit", "g", "--model", "white+rw",
                       "--json", str(out), "--png", str(tmp_path / "n.png")]) == 0
    res = json.loads(out.read_text())
    p = res["axes"][0]["parameters"]
    wn = next(q for q in p if q["term"] == "white_noise")
    # units: °/√h = N·(180/π)·60; per-sample σ = N √f_s; one-sided = √2 N
    assert wn["units"]["deg/sqrt(h)"] == pytest.approx(wn["value_si"] * 180 / math.pi * 60)
    assert wn["units"]["discrete_sigma_per_sample"] == pytest.approx(wn["value_si"] * math.sqrt(FS))
    assert wn["units"]["one_sided"] == pytest.approx(math.sqrt(2) * wn["value_si"])
    assert (
        wn["ci95_si"][0] < 0.002 < wn["ci95_si"][1] or abs(math.log(wn["value_si"] / 0.002)) < 4 * wn["relative_sigma"]
    )
    # the result file is a sensor: simulate from it and identify again (within 4σ of the first fit)
    sensor = load_sensor(out)
    ctx = SignalContext(np.arange(n) * DT, np.zeros((n, 3)), np.zeros((n, 3)), dt_s=DT)
    y = sensor.apply_triad("gyro", np.zeros((n, 3)), ctx, np.random.default_rng(8))
    again = identify_noise(y, FS, models=[parse_model("white+rw")])
    for q in p:
        v = again.axes[0].value(q["term"], q["parameter"])
        assert abs(math.log(v / q["value_si"])) < 4 * math.hypot(q["relative_sigma"], q["relative_sigma"])


def test_cli_refuses_moving_short_and_temperature_trend(tmp_path, capsys):
    rng = np.random.default_rng(9)
    n = 400
    short = ind.write_csv(tmp_path / "short.csv", FS, ind.white(n, FS, 0.01, rng))
    assert calib_main(["noise", str(short), "--gyro-unit", "deg/s", "--acc-unit", "g", "--model", "white+2gm+rw"]) == 2
    err = capsys.readouterr().err
    assert "needs at least 1024 samples = 10.2 s" in err
    n = 60_000
    temp = 25 + np.linspace(0, 3, n)
    warm = ind.write_csv(tmp_path / "warm.csv", FS, ind.white(n, FS, 0.01, rng), temp_c=temp)
    assert calib_main(["noise", str(warm), "--gyro-unit", "deg/s", "--acc-unit", "g", "--model", "white+rw"]) == 2
    assert "temperature changes by +3.00 °C" in capsys.readouterr().err
    # a hand tipping the board about x by ±90° every 10 s (rate and gravity direction change)
    t = np.arange(n) / FS
    rate = 0.5 * np.pi / 2 * np.sign(np.sin(2 * np.pi * t / 20)) * (np.sin(np.pi * t / 5) ** 2)
    theta = np.cumsum(rate) / FS
    gyro = ind.white(n, FS, 0.01, rng)
    gyro[:, 0] += rate
    acc = np.stack([np.zeros(n), np.sin(theta), np.cos(theta)], axis=1) * ind.G
    mv = tmp_path / "moving.csv"
    np.savetxt(mv, np.hstack([t[:, None], np.degrees(gyro), acc / ind.G]), delimiter=",", comments="",
               header="t,gyro_x,gyro_y,gyro_z,acc_x,acc_y,acc_z", fmt="%.9e")
    assert calib_main(["noise", str(mv), "--gyro-unit", "deg/s", "--acc-unit", "g"]) == 2
    assert "static" in capsys.readouterr().err


def test_inconsistent_when_no_candidate_fits(tmp_path):
    # white noise plus a 0.2 Hz sinusoid 20× the white noise's Allan deviation at 2.5 s: no term
    # of the vocabulary has a peaked wavelet variance, so the objective's p-value collapses
    rng = np.random.default_rng(10)
    n = int(1200 * FS)
    x = ind.white(n, FS, 0.01, rng)
    x += 0.1 * np.sin(2 * np.pi * 0.2 * np.arange(n) / FS)[:, None]
    res = identify_noise(x, FS)
    assert res.status == "inconsistent"


def test_measured_static_stretches(tmp_path):
    from gyrosim.loaders import data_root

    if not (data_root() / "imu_tk_xsens").exists():
        pytest.skip("measured data absent (../shared/data or GYROSIM_DATA)")
    # Xsens MTi initial rest (~50 s): our white density against calib allan's N on the same span
    # (a peer estimator on the same data): within 3 combined σ
    out = tmp_path / "x.json"
    calib_main(["noise", "dataset:imu_tk_xsens", "--longest-still", "--model", "white", "--json", str(out)])
    res = json.loads(out.read_text())
    from gyrosim.loaders import load_dataset

    from calib.noise.allan import allan_deviation, fit_noise_terms

    rec = load_dataset("imu_tk_xsens")
    keep = (rec.t_s >= rec.t_s[0] + 1) & (rec.t_s <= rec.t_s[0] + 50)
    for i, ax in enumerate(res["axes"][:2]):
        n_ours = ax["parameters"][0]["value_si"]
        fit = fit_noise_terms([allan_deviation(rec.gyro_rad_s[keep, i], rec.rate_hz)], terms=("arw",))
        sig = math.hypot(ax["parameters"][0]["relative_sigma"] * n_ours, fit.arw_std)
        assert abs(n_ours - fit.arw) < 3 * sig + 0.03 * fit.arw, (n_ours, fit.arw, sig)
