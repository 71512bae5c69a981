"""kf_hand's fourth assumption check (calib.session.hand.checks, check 4): the slow acceleration it attributes to the
hand must be one a hand can make — a displacement RMS below ``DISPLACEMENT_MAX_M`` (30 cm, a forearm) at periods of 5–20
s.  Measured on the x-IMU3 hand-held session (``ok`` before, fitted a_e 2.85 m/s² RMS, τ 6.3 s): 3.7 m.

The estimator of the displacement is checked against displacements made here, of known RMS; the check's false
alarm rate on gyrosim's hands is under ``slow`` (20-seed screening, every hand and both sensors: max 0.010 m),
on the independent generator's sessions in tests/session/test_hand_conditions.py (≤ 0.02 m).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from calib.session.hand.checks import DISPLACEMENT_MAX_M, SLOW_BAND_HZ, check_hand_assumptions, slow_displacement

RATE_HZ = 100.0
T_S = np.arange(0.0, 180.0, 1.0 / RATE_HZ)       # a 3-minute session, as the zhou2020 schedule's


def _sway(rms_m: float, band_hz: tuple[float, float], seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A displacement x(t) = Σ A_k sin(2π f_k t + φ_k) of RMS ``rms_m`` (40 tones in ``band_hz``, random phases)
    and its exact acceleration ẍ = −Σ A_k (2π f_k)² sin(…)."""
    rng = np.random.default_rng(seed)
    f = rng.uniform(*band_hz, 40)
    ph = rng.uniform(0, 2 * math.pi, 40)
    amp = np.full(40, rms_m * math.sqrt(2.0 / 40))
    arg = 2 * math.pi * f[:, None] * T_S[None] + ph[:, None]
    return amp @ np.sin(arg), -(amp * (2 * math.pi * f) ** 2) @ np.sin(arg)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_slow_displacement_recovers_a_displacement_made_in_the_band(seed):
    """A 10-cm RMS displacement at 0.06–0.18 Hz (inside the band, away from its edges) is read back from its
    acceleration alone.  Tolerance: Welch's Hann window spreads each tone over ±1 bin (0.025 Hz), where the
    1/f⁴ weight differs — a tone at 0.1 Hz reads ×1.12 (2/3 of its power in its bin, 1/6 each side weighted
    (0.1/0.075)⁴ and (0.1/0.125)⁴), at the band's inner edges ±20 % — so ±25 % on the RMS."""
    x, a = _sway(0.10, (0.06, 0.18), seed)
    res = slow_displacement(a, T_S, RATE_HZ)
    assert res is not None
    assert 0.75 < res.rms_m / float(np.std(x)) < 1.25, res.rms_m


def test_a_hand_sway_above_the_band_implies_no_slow_displacement():
    """gyrosim's and a real hand's sway sits at 0.2–1 Hz: a 1-cm RMS sway at 0.3–1 Hz (0.3–2 m/s² peaks, far more
    acceleration than the check's 0.03 m/s² at 0.05 Hz) implies < 1 mm in the band (Hann side lobes fall fast; a linear
    detrend instead read 3 mm: calib.session.hand.checks.slow_displacement; measured 0.04 mm) — the check reads
    displacement, not acceleration."""
    x, a = _sway(0.01, (0.3, 1.0), 3)
    res = slow_displacement(a, T_S, RATE_HZ)
    assert res.rms_m < 1e-3, res.rms_m


def test_check_flags_a_travelling_device_and_says_where():
    """A 1-m RMS displacement at 0.06–0.18 Hz (the device carried, not turned in the hand) makes the check
    fail (1 m ≫ 0.30 m, beyond the ±25 % of the estimator) with a warning that names it, what it means and
    what to do; a 5-cm one (a hand) passes.  The worst window's time: the burst put at 100–130 s is found
    there (±10 s, the window's half-length plus the filter's spread)."""
    _, a = _sway(1.0, (0.06, 0.18), 4)
    common = dict(acc_m_s2=np.tile([0.0, 0.0, 9.80665], (T_S.size, 1)), t_s=T_S, rests=[], sigma_sg=np.full(6, 1e-3),
                  tremor_band_rms_m_s2=0.1, lever_arm_m=np.zeros(3), lever_arm_std_m=np.full(3, 0.01), rate_hz=RATE_HZ)
    burst = np.where((T_S > 100) & (T_S < 130), a, 0.0)
    bad = check_hand_assumptions(slow_residual_m_s2=burst, slow_residual_t_s=T_S, **common)
    assert not bad.trustworthy
    (w,) = [w for w in bad.warnings if "slow content" in w]
    assert "calib closeloop" in w and "accelerometer" in w and "time offset" in w
    assert bad.details["slow_displacement_rms_m"] > DISPLACEMENT_MAX_M
    t_worst = float(w.split("around t = ")[1].split(" s")[0])
    assert 105 <= t_worst <= 125, w
    _, a_hand = _sway(0.05, (0.06, 0.18), 5)
    good = check_hand_assumptions(slow_residual_m_s2=a_hand, slow_residual_t_s=T_S, **common)
    assert good.trustworthy and good.warnings == ()


def test_the_accelerometers_white_noise_is_taken_off_and_a_travelling_device_still_shows():
    """A noisy accelerometer reads as displacement too: white noise of density N gives x_noise² = 2N² Σ Δf/(2πf)⁴
    over the band's bins.  The paper's simulated sensor (15 mg/√Hz) reads ~0.38 m with the hand still — above the
    0.30-m bound, so the check called 43 of 50 of the demo's own sessions inconsistent.  Over 40 draws of that noise
    alone: the mean of rms²/noise² is 1 within 3 standard errors of its own scatter (the noise term is unbiased),
    and the check fires on at most 2 (it allows the noise's scatter: z = 3 on ~7 Welch segments, ~1 % one-sided,
    so 2 of 40 is a 5 % tail).  With a 1-m RMS displacement added the check still fires."""
    n = 15e-3 * 9.80665                                     # m/s²/√Hz: per-sample σ = N √f_s
    rng = np.random.default_rng(7)
    ratios, fired = [], 0
    for _ in range(40):
        res = slow_displacement(rng.normal(0.0, n * math.sqrt(RATE_HZ), T_S.size), T_S, RATE_HZ, n)
        ratios.append(res.rms_m**2 / res.noise_m**2)
        fired += res.exceeds(DISPLACEMENT_MAX_M)
    assert 0.3 < res.noise_m < 0.5, res.noise_m
    r = np.asarray(ratios)
    assert abs(r.mean() - 1.0) < 3 * r.std(ddof=1) / math.sqrt(r.size), (r.mean(), r.std())
    assert fired <= 2, fired
    _, a = _sway(1.0, (0.06, 0.18), 8)
    res = slow_displacement(a + rng.normal(0.0, n * math.sqrt(RATE_HZ), T_S.size), T_S, RATE_HZ, n)
    assert res.exceeds(DISPLACEMENT_MAX_M) and res.beyond_noise_m > 2 * DISPLACEMENT_MAX_M, res


def test_too_short_a_recording_is_not_judged():
    """Below two periods of the band's lowest frequency (40 s) there is no bin to read: no verdict."""
    _, a = _sway(1.0, SLOW_BAND_HZ, 6)
    n = int(39 * RATE_HZ)
    assert slow_displacement(a[:n], T_S[:n], RATE_HZ) is None


@pytest.mark.slow
@pytest.mark.parametrize("sensor", ["zhou2020_sim_consumer", "mpu9250"])
@pytest.mark.parametrize("hand", ["ideal", "steady", "typical", "shaky"])
def test_no_false_alarm_on_gyrosims_hands(sensor, hand):
    """20 seeds per cell (zhou2020, 100 Hz, accelerometer calibrated, as docs/hand.md's campaign): the check never
    fires and the implied displacement stays below a tenth of the bound (measured max 0.010 m on the mpu9250,
    0.005 m on the consumer sensor: the accelerometer's white noise, 1.3 √W, not the hand — the ideal hand reads
    the same as the shaky one, whose sway lies at 0.2–1 Hz)."""
    from dataclasses import replace

    from gyrosim.estimator import as_user_file
    from gyrosim.hand import load_hand
    from gyrosim.schedule import load_schedule
    from gyrosim.sensor_model import load_sensor
    from gyrosim.simulate import apply_sensor, simulate_truth

    from calib.session.hand.filter import kf_hand

    sched, hnd = load_schedule("zhou2020"), load_hand(hand)
    model = load_sensor(sensor)
    model = replace(model, accelerometer=tuple(e for e in model.accelerometer if e.is_white_noise))
    worst = 0.0
    for seed in range(20):
        truth = simulate_truth(sched, hnd, 100.0, seed=0 if hnd.is_ideal else seed)
        cal = kf_hand(as_user_file(apply_sensor(truth, model, np.random.default_rng(10_000 + seed))))
        assert not any("slow content" in w for w in cal.warnings), (seed, cal.warnings)
        worst = max(worst, cal.diagnostics["assumptions"]["slow_displacement_rms_m"])
    assert worst < DISPLACEMENT_MAX_M / 10, worst
