"""calib closeloop names causes, not proxies: identifiability, confounding, acceptance on every
held-out metric, and the harder suite.

Tolerances and counts:
* parameters: |θ̂ − θ| ≤ 4σ̂ per identifiable parameter (σ̂ the fit's own standard error, inflated by
  the residual's autocorrelation time): a Gaussian 4σ miss has probability 6e-5 per parameter, so
  over the ≤ 12 parameters of a pair the chance of a false failure is < 1e-3.
* pairs "named completely in ≥ 9/10 seeds" (the issue's bound, slow test); one seed in the default
  suite, where the named-completely rate measured over 10 seeds (docs/closeloop.md) makes a failure a regression.
* negative control ≤ 1/20 (the issue's 95 %), static chamber 0/20 g-sensitivity (the issue's bound).
* BROAD: every held-out metric after the loop ≤ 1.10 × before (the issue's bound).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np
import pytest

from gyrosim.effects import Effect, unregister_effect
from gyrosim.loaders import available_datasets, load_dataset
from gyrosim.recording import Recording, Truth
from gyrosim.simulate import apply_sensor
from gyrosim.units import G0

from calib.closeloop import run_closeloop
from calib.closeloop.candidates import Candidate, CandidateFamily, Channel, register_family, unregister_family
from calib.closeloop.suite import HARD_SUITE, run_case, run_suite, sensor_with

PAIRS = [k for k in HARD_SUITE if "+" in k]
SEED = 100


@pytest.mark.parametrize("case", PAIRS)
def test_pairs_of_undeclared_effects_are_both_named_and_estimated_within_4_sigma(case, typical_session):
    c = run_case(case, typical_session, SEED)
    assert c.named_all, f"{case}: the loop added {c.found}"
    assert c.z_max < 4.0, f"{case}: estimate {c.estimate} vs truth {c.truth} (σ {c.sigma})"
    assert c.error_loop <= 1.01 * c.error_correct   # the loop's model is as good as the correct one


def test_static_chamber_with_accelerometer_drift_names_temperature_and_never_g_sensitivity():
    """The issue's proxy: on a static board the accelerometer's thermal drift makes the specific force a
    thermometer.  g-sensitivity must be refused by the identifiability gate, with the reason."""
    c = run_case("chamber_acc_drift", None, SEED)
    res = c.result
    assert res.reference == "static"
    assert c.named_all and c.named_first, c.found          # a temperature family first
    assert "g_sensitivity" not in c.found
    assert "does not move" in res.not_tested["g_sensitivity"], res.not_tested["g_sensitivity"]
    assert "accelerometer" in res.not_tested["g_sensitivity"]
    assert res.error_after["held_out_residual_rms"] < 0.05 * res.error_before["held_out_residual_rms"]


def test_a_confounded_group_reports_each_members_evidence_the_rule_and_what_separates_them(typical_session):
    """A monotonic warm-up: temperature and its low-passed rate rise together, so temperature bias and
    thermal hysteresis explain the same residual; both thermometer-driven (same channel), the rule
    falls to the gain, and the separating recording is a heating *and* cooling pass."""
    from gyrosim import effects as E

    from calib.closeloop.suite import WARM_UP

    base = sensor_with(None)
    sensor = replace(base, gyro=base.gyro + (E.ThermalHysteresis(value=np.radians([3.0, -2.5, 3.0]), tau_s=300.0),),
                     thermal=WARM_UP)
    res = run_closeloop(apply_sensor(typical_session, sensor, np.random.default_rng(6)))
    group = next(
        g for g in res.not_distinguished if {"thermal_hysteresis", "temperature_bias"} <= {g.chosen, *g.rivals}
    )
    assert all(m.gain > 0 and 0 < m.explained_fraction < 1 for m in group.members)
    assert "direct channel" in group.rule and "heating and a cooling" in group.separate_by
    first = res.found[0]
    assert first.effect == group.chosen and "Confounded with" in first.trace and "What would separate" in first.trace
    js = group.to_json()
    assert set(js) >= {"round", "chosen", "rivals", "why", "members", "rule", "separate_by"}


def test_an_addition_that_fits_a_flawed_rate_reference_is_refused_because_orientation_gets_worse(typical_session):
    """A rate reference with a 5 mrad cross-axis flaw (a rate table whose axes are not the attitude
    reference's): a misalignment "explains" the rate rows but makes the orientation integrated from
    the gyro worse against the attitude reference.  The acceptance must refuse it, report that the
    metrics disagree, and name the rate reference as the likely fault."""
    rec = apply_sensor(typical_session, sensor_with(None), np.random.default_rng(8))
    m = np.array([[0.0, 0.005, -0.004], [-0.003, 0.0, 0.006], [0.004, -0.005, 0.0]])
    tr = rec.truth
    flawed = replace(tr, omega_body_rad_s=np.asarray(tr.omega_body_rad_s) @ (np.eye(3) + m).T)
    res = run_closeloop(replace(rec, truth=flawed))
    assert "misalignment" not in [f.effect for f in res.found]
    rej = next(r for r in res.rejected if r.effect == "misalignment")
    verdicts = {c.name: c.verdict for c in rej.metrics}
    assert verdicts["held_out_residual_rms"] == "better"
    assert verdicts["held_out_strapdown_orientation_rms_deg"] == "worse"
    assert rej.disagreement and "the metrics disagree" in rej.disagreement
    assert "truth rate rows" in rej.disagreement          # the reference that gains is the one at fault
    assert "misalignment" in res.not_tested and "refused" in res.not_tested["misalignment"]
    assert any("misalignment" in d for d in res.disagreements)


def test_nothing_identifiable_says_so_with_reasons_and_exit_0(tmp_path):
    """30 s at rest, no temperature channel: nothing can be tested — the report says why for each
    candidate, ``found`` is empty and the command exits 0."""
    from gyrosim.recording import save_hdf5

    from calib.app.cli import main

    t = np.arange(0.0, 30.0, 0.01)
    f = np.tile([0.0, 0.0, G0], (t.size, 1))
    zero = np.zeros((t.size, 3))
    truth = Recording(
        t_s=t,
        gyro_rad_s=zero,
        acc_m_s2=f,
        truth=Truth(omega_body_rad_s=zero, specific_force_body_m_s2=f),
        meta={"rate_hz": 100.0},
    )
    rec = apply_sensor(truth, sensor_with(None), np.random.default_rng(3))
    bare = Recording(t_s=rec.t_s, gyro_rad_s=rec.gyro_rad_s, acc_m_s2=rec.acc_m_s2)
    path = save_hdf5(bare, tmp_path / "rest.h5")
    assert main(["closeloop", str(path), "--out", str(tmp_path / "cl")]) == 0
    data = json.loads((tmp_path / "cl" / "report.json").read_text())
    assert data["found"] == [] and data["tested"] == []
    assert data["notes"][0].startswith("nothing could be tested on this recording")
    nt = data["not_tested"]
    assert "at rest" in nt["scale_nonlinearity"] and "does not move" in nt["g_sensitivity"]
    assert "shorter than two drift knot intervals" in nt["random_walk"]
    assert "no temperature channel" in nt["temperature_bias"]
    assert "Nothing could be tested" in (tmp_path / "cl" / "report.md").read_text()


def _cross_square_family() -> type[CandidateFamily]:
    """The toy effect and its family, defined at test time: an effect class registers itself in the
    vocabulary when defined, and no other test module should see it there."""

    @dataclass(frozen=True)
    class _CrossSquare(Effect):
        """Toy effect for the registration test: δ_y = k ω_x |ω_x| (rad/s, k in 1/(rad/s))."""

        kind: ClassVar[str] = "toy_cross_square"
        param_fields: ClassVar[tuple[str, ...]] = ("k",)
        k: float = 0.0

        def delta(self, x, ctx, rng=None):
            out = np.zeros_like(x)
            out[:, 1] = self.k * x[:, 0] * np.abs(x[:, 0])
            return out

    class _CrossSquareFamily(CandidateFamily):
        kinds = ("toy_cross_square",)
        driver = "ω_x·|ω_x| on the y axis"
        quantity = "rate"
        channel = Channel.RATE
        separated_by = "rotations about x at several rates"

        def build(self, kind, ctx, ref, options):
            proto = _CrossSquare()
            reg = proto.sensitivity(ctx.omega_true_rad_s, ctx)
            return Candidate(self, kind, tuple(proto.param_names()), proto.with_params, "ω_x|ω_x| on y", None, reg)

        def plausible_max(self, kind, ctx):
            return 0.01

    return _CrossSquareFamily


def test_a_new_candidate_family_registers_itself_and_is_proposed(typical_session):
    """Adding a candidate family touches one place: a class registered with register_family."""
    rec = apply_sensor(typical_session, sensor_with(None), np.random.default_rng(5))
    gyro = np.array(rec.gyro_rad_s)
    w = np.asarray(rec.truth.omega_body_rad_s)
    gyro[:, 1] += 3e-3 * w[:, 0] * np.abs(w[:, 0])
    try:
        register_family(_cross_square_family())
        res = run_closeloop(rec.with_signals(gyro_rad_s=gyro))
    finally:
        unregister_family("toy_cross_square")
        unregister_effect("toy_cross_square")
    assert [f.effect for f in res.found] == ["toy_cross_square"]
    p = res.found[0].params["toy_cross_square.k"]
    assert abs(p["value"] - 3e-3) < 4 * p["sigma"]


DATA = available_datasets()
BROAD = [n for n in DATA if n.startswith("broad/")]


@pytest.mark.skipif("broad/02_undisturbed_slow_rotation_B" not in DATA, reason="BROAD trial 02 not present")
def test_broad_slow_rotation_makes_no_held_out_metric_worse():
    """The issue's case: slow rotation, where a time offset helped the rate residual but hurt the
    orientation.  Every held-out metric after the loop ≤ 1.10 × before."""
    res = run_closeloop(load_dataset("broad/02_undisturbed_slow_rotation_B"))
    assert res.metrics and all(m.after <= 1.10 * m.before for m in res.metrics), [m.describe() for m in res.metrics]
    assert {m.name for m in res.metrics} == {"held_out_residual_rms", "held_out_strapdown_orientation_rms_deg"}


# ----------------------------------------------------------------------------------- slow: the counts
@pytest.mark.slow
def test_suite_pairs_named_completely_in_9_of_10_seeds():
    rows = run_suite(PAIRS, range(100, 110))
    for r in rows:
        assert r.named_all >= 9, (r.case, r.found)
        assert r.z_max < 4.0, (r.case, r.z_max)


@pytest.mark.slow
def test_suite_static_chamber_never_adds_g_sensitivity_in_20_seeds():
    (r,) = run_suite(["chamber_acc_drift"], range(100, 120))
    assert r.forbidden_added == 0, r.found
    assert r.named_all == 20, r.found


@pytest.mark.slow
def test_suite_negative_control_adds_nothing_in_19_of_20_seeds():
    (r,) = run_suite(["negative"], range(100, 120))
    assert r.added_anything <= 1, r.found


@pytest.mark.slow
def test_suite_slow_motion_names_nothing_that_was_not_injected():
    for r in run_suite(["slow_time_offset", "slow_scale_nonlinearity"], range(100, 110)):
        injected = set(HARD_SUITE[r.case].expected)
        assert all(set(f) <= injected for f in r.found), (r.case, r.found)


@pytest.mark.slow
@pytest.mark.skipif(not BROAD, reason="BROAD trials not present under $GYROSIM_DATA or ../shared/data")
@pytest.mark.parametrize("trial", BROAD)
def test_every_broad_trial_makes_no_held_out_metric_worse_by_more_than_10_percent(trial):
    res = run_closeloop(load_dataset(trial))
    assert all(m.after <= 1.10 * m.before for m in res.metrics), [m.describe() for m in res.metrics]


def test_independent_generator_with_an_attitude_reference_names_g_sensitivity_and_time_offset():
    """Data from outside our simulator (tests/independent_generator.py imports nothing from gyrosim:
    raised-cosine rates, closed-form attitude, its own error model) with a g-sensitivity and a 5 ms
    delay, and only the attitude as reference (the optical path: rates from consecutive
    orientations).  Both are named and estimated within 4σ."""
    from independent_generator import generate_arrays

    k = np.diag([0.12, -0.10, 0.15]) * math.radians(1.0) / G0
    d = generate_arrays(seed=4, g_sensitivity=k, delay_s=0.005)
    rec = Recording(t_s=d["t_s"], gyro_rad_s=d["gyro_rad_s"], acc_m_s2=d["acc_m_s2"], truth=Truth(quat_nb=d["quat_nb"]))
    res = run_closeloop(rec)
    assert res.reference == "optical"
    found = {f.effect: f for f in res.found}
    assert {"g_sensitivity", "time_offset"} <= set(found), list(found)
    p = found["time_offset"].params["time_offset.delay_s"]
    assert abs(p["value"] - 0.005) < 4 * p["sigma"], p
    g = found["g_sensitivity"].params
    diag = [g[f"g_sensitivity.value[{4 * i}]"] for i in range(3)]
    for est, true in zip(diag, np.diag(k)):
        assert abs(est["value"] - true) < 4 * est["sigma"], (est, true)
