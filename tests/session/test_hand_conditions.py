"""kf_hand (the 24-state hand-aware filter) in the user's conditions, not only the paper's (developers'
guide: "noise-free and extreme noise, odd rates and files"; "an estimate that fails its own consistency
check is returned with a non-ok status and a non-zero exit code, never as a normal answer").

Data from the independent generator (tests/independent_generator.py: imports nothing of ours), always
with a hand: a 7 cm lever arm, tremor (8–12 Hz) and sway (0.2–1 Hz).  The contract checked per case:
either status ``ok`` and the error inside its σ, or a non-ok status (and exit code 1 from ``calib run``).

Tolerances: with an honest σ the NEES e·C⁻¹·e of the 6 gyro S, G is χ²(6); one seed must lie below its
99.9 % quantile 22.46 (a false alarm 0.1 % per case), which also bounds every |e/σ| < 4.74 — so an ``ok``
with an error beyond 5 σ always fails.  The slow multi-seed version sums 10 seeds: χ²(60), two-sided
99.9 % interval [30.3, 102.7] (σ neither understated nor grossly overstated).
"""

from __future__ import annotations

import json

import independent_generator as ig
import numpy as np
import pytest
from scipy import stats

from gyrosim.recording import Recording

from calib.app.cli import main as calib_main
from calib.session import registry as estimators
from calib.session.hand.checks import DISPLACEMENT_MAX_M

HAND_KW = dict(lever_arm_m=(0.01, 0.07, 0.02), tremor_acc_rms_m_s2=0.07, sway_acc_rms_m_s2=0.02)
NOISE = dict(gyro_noise_deg_s=0.05, acc_noise_g=0.001)          # the consumer sensor of tests/session/test_hand.py
NOISE_X10 = dict(gyro_noise_deg_s=0.5, acc_noise_g=0.01)
NOISE_FREE = dict(gyro_noise_deg_s=0.0, acc_noise_g=0.0)
# half the rotations: the first rest, the vertical z turns, the tip and the x turns, the final rest (no y turn)
SHORT_STEPS = ig.STEPS[:6] + [ig.STEPS[-1]]
ITEMS = [("gyro", "scale_factor"), ("gyro", "nonorthogonality")]
NEES_MAX_6 = float(stats.chi2.ppf(0.999, 6))
# known limits, measured: σ at most this many times optimistic (NEES bound × factor²) — docs/hand.md, "What is not done"
# (empty since the lever arm term's Jacobian: the half-rotation session's ~1.4× was its absence)
KNOWN_OPTIMISM: dict[str, float] = {}

CASES = {   # name: (rate Hz, schedule, noise, hand)
    "noise-free sensor, hand": (100.0, ig.STEPS, NOISE_FREE, HAND_KW),
    "10x consumer noise": (100.0, ig.STEPS, NOISE_X10, HAND_KW),
    "50 Hz": (50.0, ig.STEPS, NOISE, HAND_KW),
    "200 Hz": (200.0, ig.STEPS, NOISE, HAND_KW),
    "119.7 Hz": (119.7, ig.STEPS, NOISE, HAND_KW),
    "half the rotations": (100.0, SHORT_STEPS, NOISE, HAND_KW),
}


def _run(rate_hz, steps, noise, hand, seed=0):
    d = ig.generate_arrays(rate_hz=rate_hz, steps=steps, kin=ig.kinematics(rate_hz, steps), seed=seed, **noise, **hand)
    cal = estimators.kf_hand(Recording(d["t_s"], d["gyro_rad_s"], d["acc_m_s2"], meta={"rate_hz": rate_hz}))
    est = np.concatenate([cal.value(t, k) for t, k in ITEMS])
    e = est - np.concatenate([d["scale_factor"], d["nonorthogonality"]])
    c = cal.block_covariance(ITEMS)
    return cal, e, c


@pytest.mark.parametrize("case", list(CASES))
def test_kf_hand_is_ok_and_within_its_sigma_in_the_users_conditions(case):
    """Every case answers ``ok`` (measured: all six do) with NEES below χ²₆'s 99.9 % quantile (module
    docstring); measured NEES 2–16.  Noise-free *sensor* here still has the hand's tremor and sway as its
    only random input, which the filter models, so its σ must hold too.  The slow-acceleration check
    (calib.session.hand.checks check 4) stays silent: this hand's sway (0.2–1 Hz) implies no displacement at 5–20 s,
    and the white noise's share is 1.3 √W m (0.02 m with 10× the consumer noise, measured 0.020): below a
    fifth of the 0.30-m bound in every case (measured ≤ 0.020 m).

    The half-rotation session turns about z and x only while each is vertical: S, G are pinned weakly (σ of S_x, S_z ~1
    %), so K(ω̂, ω̂̇) built from the rate compensated at the pass's S, G is off by a share of that and the lever arm
    term carries it into the innovations.  Until the update's H carried ∂(K r̂)/∂(S, G, b)
    (tests/session/test_hand_lever_jacobian.py) that left σ ~1.4× optimistic there (seed 0 NEES 24.3; ten seeds 125.1
    against χ²(60)'s 102.7, a strict xfail below); with it seed 0 measures 4.7 and the ten seeds 102.0."""
    cal, e, c = _run(*CASES[case])
    assert cal.status == "ok", cal.warnings
    assert cal.diagnostics["assumptions"]["slow_displacement_rms_m"] < DISPLACEMENT_MAX_M / 5
    nees = float(e @ np.linalg.solve(c, e))
    assert nees < NEES_MAX_6 * KNOWN_OPTIMISM.get(case, 1.0) ** 2, (nees, e / np.sqrt(np.diag(c)))


def test_half_the_rotations_gives_a_larger_honest_sigma_where_information_is_missing():
    """The short session turns about z and x only while each is vertical: a turn about the vertical
    does not move gravity in the body, so a calibrated accelerometer cannot see its rate error and S_x,
    S_z keep (nearly) their prior σ — ≥ 50× the full session's (measured ×200); S_y is seen only through
    the one 90° tip, so its σ grows too (≥ 2×, measured ×7): information only adds, fewer rotations never
    give a smaller σ.  Its error stays inside that σ (the parametrised test above)."""
    _, _, cf = _run(100.0, ig.STEPS, NOISE, HAND_KW)
    _, _, cs = _run(*CASES["half the rotations"])
    sf, ss = np.sqrt(np.diag(cf)), np.sqrt(np.diag(cs))
    assert np.all(ss[[0, 2]] > 50 * sf[[0, 2]]) and ss[1] > 2 * sf[1], (ss, sf)
    assert np.all(ss >= sf), (ss, sf)


def test_every_draw_zero_is_refused_with_a_named_reason_not_diverged():
    """No sensor noise, no tremor, no sway (a lever arm only): the noise levels sit at their floors and the innovations
    are the rate integration's deterministic error.  The estimate is within the discretisation error (measured 5.2e-6,
    below; bound 1e-5 ≈ (ω_peak Δt)²/24, a second-order integrator's relative error per step at these turns' peak 1.57
    rad/s and 100 Hz), but the floor-level σ is ~4e-7, so the error is ~6 σ: the answer must not be ``ok`` (nor
    ``diverged``) and must say it is noise-free input.  With the lever arm term's Jacobian in H the lever arm's path
    informs S, G too and the error is 5.2e-6 (2.6e-6 without): the regressor's own discretisation (K of the low-passed
    rate, not the low-pass of K) is in the innovations at the floor's scale, mean NIS 36 — beyond the divergence test's
    limit, which noise-free input cannot be judged by (calib.session.consistency ``verdict(noise_free=True)``:
    "inconsistent")."""
    cal, e, c = _run(100.0, ig.STEPS, NOISE_FREE, dict(lever_arm_m=HAND_KW["lever_arm_m"]))
    assert np.max(np.abs(e)) < 1e-5, e
    assert cal.status not in ("ok", "diverged"), cal.status
    assert any(w.startswith("noise-free input") for w in cal.warnings), cal.warnings
    assert np.allclose(cal.diagnostics["hand"]["lever_arm_m"], HAND_KW["lever_arm_m"], atol=1e-4)


@pytest.mark.parametrize("case, code", [("noise-free", 1), ("119.7 Hz", 0)])
def test_calib_run_hand_exit_code_matches_the_status(case, code, tmp_path, capsys):
    """`calib run --method hand --accelerometer calibrated` on a CSV: the noise-free (every draw zero)
    file is refused with exit code 1 and status non-ok; the 119.7 Hz file (a non-integer rate, times
    rounded to 1 µs in the CSV) exits 0 with its error inside χ²₆'s 99.9 % NEES bound."""
    if case == "noise-free":
        kw = dict(**NOISE_FREE, lever_arm_m=HAND_KW["lever_arm_m"])
    else:
        kw = dict(rate_hz=119.7, kin=ig.kinematics(119.7), **NOISE, **HAND_KW)
    truth = ig.generate(tmp_path / "s.csv", **kw)
    rc = calib_main(["run", str(tmp_path / "s.csv"), "--gyro-unit", "deg/s", "--acc-unit", "g", "--method", "hand",
                     "--accelerometer", "calibrated", "--json", str(tmp_path / "out.json")])
    capsys.readouterr()
    d = json.loads((tmp_path / "out.json").read_text())
    assert rc == code and (d["status"] == "ok") == (code == 0), (rc, d["status"], d["warnings"])
    if code == 0:
        est = np.concatenate([d["gyro"]["scale_factor"], d["gyro"]["nonorthogonality"]])
        e = est - np.concatenate([truth["scale_factor"], truth["nonorthogonality"]])
        sd = np.concatenate([d["gyro"]["std"]["scale_factor"], d["gyro"]["std"]["nonorthogonality"]])
        assert np.all(np.abs(e / sd) < np.sqrt(NEES_MAX_6)), e / sd


SLOW_CASES = [c if c not in KNOWN_OPTIMISM else pytest.param(c, marks=pytest.mark.xfail(strict=True, reason=(
    "known limit, measured: summed NEES 125.1 > 102.7 over seeds 0–9 (113.6 before the spectral correction's "
    "prefilter reference, 103.6 two rounds ago) — the weakly excited S_x, S_z of the short session are ~1.4× "
    "optimistic, seen only through the lever arm's centripetal term; max |e/σ| 3.0, so never beyond 5 σ")))
    for c in CASES]


@pytest.mark.slow
@pytest.mark.parametrize("case", SLOW_CASES)
def test_kf_hand_nees_over_ten_seeds_in_the_users_conditions(case):
    """Ten seeds per case: the summed NEES inside χ²(60)'s two-sided 99.9 % interval; every seed ``ok``."""
    total = 0.0
    for seed in range(10):
        cal, e, c = _run(*CASES[case], seed=seed)
        assert cal.status == "ok", (seed, cal.warnings)
        total += float(e @ np.linalg.solve(c, e))
    lo, hi = stats.chi2.ppf([0.0005, 0.9995], 60)
    assert lo < total < hi, total
