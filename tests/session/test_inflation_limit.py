"""The inflation's "inconsistent" limit follows from κ̂'s own sampling distribution (calib.session.consistency,
:func:`inconsistent_sigma_limit`).

κ̂, the whitened innovations' long-run variance from d block sums, is κ χ²(d)/d for a true long-run variance κ.  The
rule "σ had to grow more than ×1.5" compared κ̂ itself with 1.5² = 2.25, so a session at the limit was called
inconsistent half the time and sessions below it often (gyrosim's typical hand with kf_hand_joint: κ̂ 2.5 on 80
degrees of freedom, every error within 1.8 inflated σ — benchmarks/false_alarm.py).  Now the limit is κ̂'s 95 %
quantile at κ = 2.25: at the limit the rule fires in 5 % of draws; a σ understated ×2 (κ = 4) still fires nearly
always.
"""

from __future__ import annotations

import numpy as np
from scipy import signal, stats

from calib.session.consistency import (
    INFLATION_INCONSISTENT_SIGMA,
    INFLATION_QUANTILE,
    Inflation,
    apply_inflation,
    inconsistent_sigma_limit,
    innovation_inflation,
)

RATE_HZ = 100.0
N = 18000          # 180 s: 44 blocks of 4 s per row, 88 degrees of freedom (zhou2020's length)


def _ar1(rng: np.random.Generator, kappa: float, phi: float = 0.8) -> np.ndarray:
    """Two rows of AR(1) with long-run variance ``kappa`` (2π S(0) = σ_e²/(1 − φ)²)."""
    e = rng.normal(size=(N, 2)) * np.sqrt(kappa) * (1 - phi)
    return signal.lfilter([1.0], [1.0, -phi], e, axis=0)


def _fires(u: np.ndarray) -> bool:
    t = np.arange(N) / RATE_HZ
    return apply_inflation("ok", [], innovation_inflation(u, t), hand_aware=True, accelerometer="estimate") != "ok"


def test_limit_is_the_quantile_of_kappa_hat_at_the_limit():
    for d in (20, 80, 400):
        lim = inconsistent_sigma_limit(d)
        assert lim > INFLATION_INCONSISTENT_SIGMA
        # P(κ_max χ²(d)/d > lim²) = 1 − INFLATION_QUANTILE, to rounding
        p = stats.chi2.sf(lim**2 / INFLATION_INCONSISTENT_SIGMA**2 * d, d)
        assert abs(p - (1 - INFLATION_QUANTILE)) < 1e-9
    assert inconsistent_sigma_limit(400) < inconsistent_sigma_limit(80) < inconsistent_sigma_limit(20)
    assert inconsistent_sigma_limit(0) == INFLATION_INCONSISTENT_SIGMA


def test_rule_fires_at_its_size_at_the_limit_and_on_an_understated_sigma():
    """200 sessions each at κ = 2.25 (σ understated exactly ×1.5) and at κ = 4 (×2).  At the limit the rule fires
    with probability 5 % (binomial σ 1.5 % over 200: below 12 % is 4.6σ; the AR(1)'s block-edge bias,
    ~2φ/((1 − φ)² · 400) = 2 % of κ, moves the rate by < 1 %); at ×2 in 98 % at 88 degrees of freedom (χ²: P(4 χ²₈₈/88
    > 2.84) = 0.98; above 90 % is 4σ of the binomial)."""
    rng = np.random.default_rng(7)
    at_limit = sum(_fires(_ar1(rng, INFLATION_INCONSISTENT_SIGMA**2)) for _ in range(200))
    assert at_limit < 24, at_limit
    understated = sum(_fires(_ar1(rng, 4.0)) for _ in range(200))
    assert understated > 180, understated


def test_the_readme_sessions_statistic_is_inflated_but_not_inconsistent():
    """κ̂ 2.50 on 80 degrees of freedom (gyrosim simulate --seed 1, typical hand, mpu9250; kf_hand_joint): σ is
    inflated ×1.58 and the result stays ok; κ̂ 4 on 40 (σ ×2) is inconsistent, with the limit in the message."""
    notes: list[str] = []
    infl = Inflation(kappa=2.498, dof=80, threshold=float(stats.chi2.ppf(0.95, 80) / 80), factor=2.498)
    assert apply_inflation("ok", notes, infl, hand_aware=True, accelerometer="estimate") == "ok"
    assert len(notes) == 1 and "σ inflated ×1.6" in notes[0]
    notes = []
    infl = Inflation(kappa=4.0, dof=40, threshold=float(stats.chi2.ppf(0.95, 40) / 40), factor=4.0)
    assert apply_inflation("ok", notes, infl, hand_aware=True, accelerometer="estimate") == "inconsistent"
    assert f"×{inconsistent_sigma_limit(40):.2f} at 40 degrees of freedom" in notes[-1]
    assert infl.to_dict()["inconsistent_above_sigma_factor"] == inconsistent_sigma_limit(40)
