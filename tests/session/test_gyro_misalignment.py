"""The gyro triad's rotation against the accelerometer's, α (``HandParams(misalignment=True)``: three filter states,
ω̃ = (I + diag(S) + N(G) − [α×]) ω + b), on the independent generator (tests/independent_generator.py, which writes
the rotation its own way: ``gyro_rotation_rad``) with kf_hand's typical hand (lever arm 7 cm, tremor, sway) and a raw
accelerometer — ``kf_hand_joint``'s case.

α of 0.7°, −0.46°, 0.29° (datasheet class: an assembly's 0.5–1°).  Under an honest σ the error over a seed is
χ²(3) in NEES; asserted per seed below its 99.9 % quantile (16.3), and α̂ − α within 4 σ per axis.  Measured (seeds
0–1, the lever arm's Jacobian through α in the update): σ ≈ 8e-5 rad (0.005°), errors within 1 σ.  Without a
rotation in the data the estimate is zero within its σ (never a rotation claimed that is not there).  The result
carries α in the JSON (``gyro.misalignment_rad`` with its std) and ``calib apply``'s compensation inverts it.
"""

from __future__ import annotations

import independent_generator as ig
import numpy as np
import pytest
from scipy import stats
from test_hand import HAND_KW, NOISE, _rec, kin  # noqa: F401  (kin: the fixture)
from test_hand_joint import ACC_KW

from calib.session.hand.filter import kf_hand
from calib.session.hand.params import HandParams
from calib.session.model import gyro_axis_matrix

ALPHA = np.array([0.012, -0.008, 0.005])     # rad
KIND = "gyro_acc_misalignment"


def _run(kin, seed: int, alpha: np.ndarray):
    d = ig.generate_arrays(seed=seed, kin=kin, gyro_rotation_rad=alpha, **NOISE, **HAND_KW, **ACC_KW)
    rec = _rec(d)
    return rec, kf_hand(rec, accelerometer="estimate", params=HandParams(misalignment=True))


def _nees(cal, alpha) -> tuple[np.ndarray, float]:
    e = cal.value("gyro", KIND) - alpha
    return e / cal.std("gyro", KIND), float(e @ np.linalg.solve(cal.block_covariance([("gyro", KIND)]), e))


def test_the_rotation_is_recovered_with_an_honest_sigma(kin):
    q = stats.chi2.ppf(0.999, 3)
    for seed in range(2):
        rec, cal = _run(kin, seed, ALPHA)
        assert cal.status == "ok", cal.warnings
        assert not any(w.startswith("no uncertainty") for w in cal.warnings)   # every parameter has its σ
        z, nees = _nees(cal, ALPHA)
        assert np.all(np.abs(z) < 4) and nees < q, (seed, z, nees)
        d = cal.to_dict()
        assert np.allclose(d["gyro"]["misalignment_rad"], cal.value("gyro", KIND))
        assert len(d["gyro"]["std"]["misalignment_rad"]) == 3
        # calib apply: the compensated rate is M_g⁻¹ (ω̃ − b) with the rotation in M_g
        m = gyro_axis_matrix(cal.value("gyro", "scale_factor"), cal.value("gyro", "nonorthogonality"),
                             cal.value("gyro", KIND))
        want = (rec.gyro_rad_s[:500] - cal.value("gyro", "bias")) @ np.linalg.inv(m).T
        got = cal.compensate(rec).gyro_rad_s[:500]
        assert np.abs(got - want).max() < 1e-12


def test_without_a_rotation_none_is_claimed(kin):
    _, cal = _run(kin, 0, np.zeros(3))
    z, nees = _nees(cal, np.zeros(3))
    assert np.all(np.abs(z) < 4) and nees < stats.chi2.ppf(0.999, 3), (z, nees)


@pytest.mark.slow
def test_the_rotation_over_20_seeds():
    """20 seeds: the summed NEES is χ²(60); inside its two-sided 99.9 % interval [30.3, 102.7] with the lower end
    halved (σ at most ×√2 cautious, as the hand's cells)."""
    k = ig.kinematics(100.0)
    total = 0.0
    for seed in range(20):
        _, cal = _run(k, seed, ALPHA)
        total += _nees(cal, ALPHA)[1]
    lo, hi = stats.chi2.ppf([0.0005, 0.9995], 60)
    assert lo / 2 < total < hi, total
