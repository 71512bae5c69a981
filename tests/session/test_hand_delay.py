"""kf_hand's accelerometer-delay state on an independent generator (tests/independent_generator.py delays the gyro
output its own way: linear interpolation of the noise-free output at t − d).

A gyro that lags the accelerometer by d is an accelerometer delay δ = −d behind the gyro.  The filter's attitude comes
from the gyro and its levelling from the accelerometer, so the skew reads as an attitude error δ ω × g_b during every
turn — at the generator's 1-rad/s turns and d = 2 ms, 20 mm/s², the size of a 2e-3 scale-factor error's.  kf_hand
estimates δ (one state for the triad) and must (1) find it honestly, (2) keep S, G honest with it, (3) not invent
one where there is none.

Tolerances.  Under an honest σ, each session's z = (δ̂ − δ)/σ_δ is N(0, 1): Σz² over 6 sessions is χ²(6), two-sided
99.9 % interval [0.30, 24.1]; the summed NEES of S, G over the same 6 sessions is χ²(36), interval [14.4, 70.6]
(scipy.stats.chi2.ppf(0.0005 / 0.9995, dof)).  Without the skew δ̂ must be within 3.3 σ of 0 (99.9 % two-sided).
"""

from __future__ import annotations

import independent_generator as ig
import numpy as np
import pytest
from scipy import stats

from gyrosim.recording import Recording

from calib.session.hand.filter import kf_hand

HAND_KW = dict(lever_arm_m=(0.01, 0.07, 0.02), tremor_acc_rms_m_s2=0.07, sway_acc_rms_m_s2=0.02)
NOISE = dict(gyro_noise_deg_s=0.05, acc_noise_g=0.001)
ITEMS = [("gyro", "scale_factor"), ("gyro", "nonorthogonality")]
SEEDS = range(6)


@pytest.fixture(scope="module")
def kin():
    return ig.kinematics(100.0)


def _lo_hi(dof: int) -> tuple[float, float]:
    return float(stats.chi2.ppf(0.0005, dof)), float(stats.chi2.ppf(0.9995, dof))


def _nees_sg(cal, d) -> float:
    est = np.concatenate([cal.value(t, k) for t, k in ITEMS])
    e = est - np.concatenate([d["scale_factor"], d["nonorthogonality"]])
    return float(e @ np.linalg.solve(cal.block_covariance(ITEMS), e))


def test_kf_hand_finds_a_gyro_accelerometer_skew_and_stays_honest(kin):
    d_s = 0.002
    z2, nees = [], []
    for seed in SEEDS:
        d = ig.generate_arrays(seed=seed, kin=kin, delay_s=d_s, **NOISE, **HAND_KW)
        cal = kf_hand(Recording(d["t_s"], d["gyro_rad_s"], d["acc_m_s2"], meta={"rate_hz": 100.0}))
        assert cal.status == "ok", (seed, cal.warnings)
        rep = cal.diagnostics["acc_delay"]
        z2.append(((rep["delay_s"] - (-d_s)) / rep["std_s"]) ** 2)
        nees.append(_nees_sg(cal, d))
        assert any("timing: the accelerometer samples" in w for w in cal.warnings)
    lo, hi = _lo_hi(len(z2))
    assert lo < sum(z2) < hi, z2
    lo, hi = _lo_hi(6 * len(nees))
    assert lo < sum(nees) < hi, nees


def test_kf_hand_without_the_delay_state_is_not_ok_on_a_skewed_session(kin):
    """The same skew with the state switched off (``delay=False``, the filter before it): a 5-ms lag is beyond what the
    hand's model absorbs, so the result must not be a plain "ok" with S, G off by more than σ says — the reason the
    state is on by default."""
    d = ig.generate_arrays(seed=0, kin=kin, delay_s=0.005, **NOISE)
    rec = Recording(d["t_s"], d["gyro_rad_s"], d["acc_m_s2"], meta={"rate_hz": 100.0})
    old = kf_hand(rec, delay=False)
    new = kf_hand(rec)
    assert old.status != "ok" or _nees_sg(old, d) < _lo_hi(6)[1]
    assert new.status == "ok" and _nees_sg(new, d) < _lo_hi(6)[1]
    assert abs(new.diagnostics["acc_delay"]["delay_s"] + 0.005) < 3.3 * new.diagnostics["acc_delay"]["std_s"]


def test_kf_hand_does_not_invent_a_skew(kin):
    for seed in (0, 1):
        d = ig.generate_arrays(seed=seed, kin=kin, **NOISE, **HAND_KW)
        cal = kf_hand(Recording(d["t_s"], d["gyro_rad_s"], d["acc_m_s2"], meta={"rate_hz": 100.0}))
        rep = cal.diagnostics["acc_delay"]
        assert abs(rep["delay_s"]) < 3.3 * rep["std_s"], rep
