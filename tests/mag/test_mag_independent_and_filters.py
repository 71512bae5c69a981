"""The magnetometer calibration on data gyrosim did not make (tests/independent_mag_generator.py), and the heading
filters of "Soft Magnetic Error Compensation Method of Electronic Compass" on signals whose answer is known."""

from __future__ import annotations

import math

import numpy as np
import pytest
from independent_mag_generator import generate

from calib.app.cli import main as calib_main
from calib.inputs import load_recording
from calib.mag import calibrate_magnetometer
from calib.mag.filters import HEADING_FILTERS, FilterSettings
from calib.mag.heading import twist_heading_rad, wrap_pi


def test_independent_generator_hard_soft_iron_and_misalignment(tmp_path):
    """5 independent sessions (24 random turns, rests between; soft iron ±4 %/±2 %, misalignment
    0.5–2°, 0.4 µT noise; A = S Rᵀ as a product).  Ellipsoid: hard iron and the symmetric factor of
    A within their σ (mean z² ≤ 2.2: 5 seeds × 3 axes, the 99.9 % bound of χ²(15)/15 is 2.5);
    aided: the full A and the misalignment too (error < 0.15°, a tenth of a typical misalignment);
    field magnitude (det A = 1 normalises S Rᵀ to det 1: F = 50 · det(S)^(1/3)) and inclination
    (60°) within 4σ."""
    zh_e, zh_a, za_a, zm = [], [], [], []
    for seed in range(5):
        path = tmp_path / f"ind{seed}.h5"
        truth = generate(path, seed=seed)
        rec = load_recording(path)
        ell = calibrate_magnetometer(rec, "ellipsoid", consistency_check=False)
        aid = calibrate_magnetometer(rec, "aided", consistency_check=False)
        assert ell.status == "ok" and aid.status == "ok", (ell.warnings, aid.warnings)
        zh_e.append((ell.hard_iron_ut - truth["hard_iron_uT"]) / ell.hard_iron_std_ut)
        zh_a.append((aid.hard_iron_ut - truth["hard_iron_uT"]) / aid.hard_iron_std_ut)
        a = truth["soft_iron"]
        det = np.linalg.det(a)
        za_a.append(((aid.soft_iron - a / np.cbrt(det)) / aid.soft_iron_std).ravel())
        err = aid.misalignment_deg - truth["misalignment_deg"]
        zm.append(err / aid.misalignment_std_deg)
        assert np.abs(err).max() < 0.15, err
        f_true = truth["field_uT"] * np.cbrt(det)
        assert abs(aid.field_ut - f_true) < 4 * aid.field_std_ut + 1e-3, (aid.field_ut, f_true)
        assert abs(aid.inclination_deg - truth["inclination_deg"]) < 4 * aid.inclination_std_deg
    for z in (zh_e, zh_a, za_a, zm):
        assert np.mean(np.square(z)) <= 2.2, np.mean(np.square(z), axis=0)


def test_cli_on_the_independent_file(tmp_path, capsys):
    path = tmp_path / "ind.h5"
    generate(path, seed=11)
    assert calib_main(["mag", str(path), "--method", "aided", "--json", str(tmp_path / "o.json")]) == 0
    assert "misalignment" in capsys.readouterr().out


def _heading_signal(n: int, rate: float, noise_rad: float, rng: np.random.Generator):
    """A board turning at 20 °/s for 10 s, then back: true heading, exact gyro increments, noisy compass."""
    t = np.arange(n) / rate
    w = np.where((t % 20) < 10, math.radians(20.0), -math.radians(20.0))
    psi = np.cumsum(w) / rate
    return psi, w / rate, wrap_pi(psi + noise_rad * rng.standard_normal(n))


def test_kalman_filters_reach_their_steady_state_error():
    """Seed form (random walk q per sample, measurement R) on a *constant* heading: the KF's gain
    settles at K = P⁻/(P⁻ + R) with P⁻ = P⁺ + q, P⁺ = (−q + √(q² + 4qR))/2 (the Riccati fixed
    point), and since the truth does not walk, its error is the AR(1) e_k = (1 − K) e_{k−1} + K ε_k
    of variance K R/(2 − K).  The filtered error's variance must match that within 10 % (20 000
    samples; K ≈ 0.22 gives an AR(1) whose sample variance has ≈ 4 % relative σ).  The gyro form,
    whose increments are exact here, must beat the raw compass 3×.  The Sage–Husa AKF, started with
    R 10× too large, must still smooth once it has learnt R."""
    rng = np.random.default_rng(3)
    n, rate, sig = 20_000, 100.0, math.radians(2.0)
    z = wrap_pi(0.3 + sig * rng.standard_normal(n))
    dt = np.full(n - 1, 1 / rate)
    q = math.radians(0.5) ** 2
    s = FilterSettings(sig**2, "seed", seed_walk_rad2_s=q * rate)
    est = HEADING_FILTERS["kf"]().run(z, None, dt, s)
    p_post = (-q + math.sqrt(q * q + 4 * q * sig**2)) / 2
    k = (p_post + q) / (p_post + q + sig**2)
    err = wrap_pi(est - 0.3)[1000:]
    assert np.var(err) == pytest.approx(k * sig**2 / (2 - k), rel=0.10)
    akf = HEADING_FILTERS["akf"]()
    s_bad = FilterSettings(10 * sig**2, "seed", seed_walk_rad2_s=q * rate, forgetting=0.995)
    est_a = akf.run(z, None, dt, s_bad)
    assert np.std(wrap_pi(est_a - 0.3)[5000:]) < 0.8 * sig  # it smooths once R is learnt
    psi, dpsi, zz = _heading_signal(n, rate, sig, rng)
    sg = FilterSettings(sig**2, "gyro", arw_rad_s_sqrt_hz=math.radians(0.05))
    est_g = HEADING_FILTERS["kf"]().run(zz, dpsi, dt, sg)
    assert np.std(wrap_pi(est_g - psi)[1000:]) < 0.3 * sig


def test_particle_filter_is_seeded_and_agrees_with_the_kalman_filter():
    """Linear-Gaussian case (gyro form, exact increments): the bootstrap PF (500 particles)
    approximates the KF's posterior: RMS errors within 30 % of each other; the same rng seed gives
    the same output; no rng is refused."""
    rng = np.random.default_rng(5)
    n, rate, sig = 3000, 100.0, math.radians(3.0)
    psi, dpsi, z = _heading_signal(n, rate, sig, rng)
    dt = np.full(n - 1, 1 / rate)
    s = FilterSettings(sig**2, "gyro", arw_rad_s_sqrt_hz=math.radians(0.05))
    kf = HEADING_FILTERS["kf"]().run(z, dpsi, dt, s)
    pf1 = HEADING_FILTERS["pf"]().run(z, dpsi, dt, s, rng=np.random.default_rng(1))
    pf2 = HEADING_FILTERS["pf"]().run(z, dpsi, dt, s, rng=np.random.default_rng(1))
    np.testing.assert_array_equal(pf1, pf2)
    e_kf = np.sqrt(np.mean(wrap_pi(kf - psi)[500:] ** 2))
    e_pf = np.sqrt(np.mean(wrap_pi(pf1 - psi)[500:] ** 2))
    assert e_pf == pytest.approx(e_kf, rel=0.3) and e_kf < 0.5 * sig
    with pytest.raises(ValueError, match="rng"):
        HEADING_FILTERS["pf"]().run(z, dpsi, dt, s)


def test_twist_heading_of_a_level_turn():
    ang = np.radians([0.0, 30.0, -100.0, 179.0])
    q = np.stack([np.cos(ang / 2), 0 * ang, 0 * ang, np.sin(ang / 2)], axis=1)
    np.testing.assert_allclose(twist_heading_rad(q), wrap_pi(-ang), atol=1e-12)  # CCW about Up = heading decreases
