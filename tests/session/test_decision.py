"""The decision layer above the session methods (calib.session.decision): the prior and what a recording
determines, the motion's class, the held-out check, and what ``calib run`` / ``calib apply`` then apply."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from gyrosim.calibration import Calibration
from gyrosim.schedule import Schedule, Segment
from gyrosim.simulate import simulate

from calib.app.cli import main as calib_main
from calib.session.decision.motion import classify_motion
from calib.session.decision.prior import MAKER_TOLERANCE, Gate, Prior, combine, compose, determine
from calib.session.run import RunOptions, run_session


def _carried(seed: int = 1, sensor: str = "mpu9250"):
    """A board carried back and forth (±0.22 m in 1 s along East, then Up: 0.5 Hz, inside the classifier's
    0.2–2 Hz band) with a 15° turn between moves: a path without the turns that determine S and G."""
    segs = [Segment("rest", 10.0)]
    for k in range(36):
        d = [0.22, -0.44, 0.22][k % 3] * np.eye(3)[[0, 2][(k // 3) % 2]]
        segs.append(Segment("translate", 1.0, displacement_m=tuple(d)))
        segs.append(Segment("rotate", 0.8, axis_body=tuple(np.eye(3)[k % 3]), angle_rad=math.radians(15 * (-1) ** k)))
    segs.append(Segment("rest", 10.0))
    return simulate(Schedule("carried", tuple(segs)), "typical", sensor, 100.0, seed=seed)


@pytest.fixture(scope="module")
def zhou_run():
    rec = simulate("zhou2020", "typical", "mpu9250", 100.0, seed=1)
    return rec, run_session(rec)


# ----------------------------------------------------------------------------------------------- the prior
def test_determined_is_the_sigma_ratio_and_a_gate_outranks_it():
    prior = Prior.maker()
    sigma = np.r_[np.full(3, 1e-5), np.full(6, 0.004), np.full(9, 0.006)]   # S, G: 0.4 σ_prior; acc S: 0.6
    sigma[9:12] = 0.1                                                       # acc b: 0.4 × 0.25 m/s²
    det = determine(np.zeros(18), sigma, prior)
    assert det.determined[:12].all() and not det.determined[12:].any()
    assert det.reasons[12].startswith("σ 0.60")
    gate = np.zeros(18, bool)
    gate[3:9] = True
    det = determine(np.zeros(18), sigma, prior, (Gate(gate, "the motion breaks the model"),))
    assert not det.determined[3:9].any() and det.determined[:3].all()
    assert det.reasons[4] == "the motion breaks the model"
    assert not determine(np.full(18, np.nan), sigma, prior).determined.any()   # not estimated


def test_prior_tolerance_text_and_bad_text():
    p = Prior.from_tolerance("S=0.02,acc_bias=0.3")
    assert p.sigma[3] == 0.02 and p.sigma[6] == MAKER_TOLERANCE["gyro_nonorth"] and p.sigma[9] == 0.3
    assert math.isinf(p.sigma[0])                                            # the bias: no prior
    assert Prior.from_tolerance("0.05").sigma[15] == 0.05
    for bad in ("S=abc", "Q=0.1", "S=-1", "0"):
        with pytest.raises(ValueError, match="prior tolerance"):
            Prior.from_tolerance(bad)


def test_combine_and_compose():
    v, s = combine(np.array([1.0]), np.array([1.0]), np.array([0.0]), np.array([math.inf]))
    assert v[0] == 1.0 and s[0] == 1.0                                       # no prior: the estimate
    v, s = combine(np.array([1.0]), np.array([1.0]), np.array([0.0]), np.array([1.0]))
    assert v[0] == pytest.approx(0.5) and s[0] == pytest.approx(math.sqrt(0.5))
    theta = np.r_[0.01, -0.02, 0.03, 0.02, -0.01, 0.005, 0.003, -0.002, 0.001]
    np.testing.assert_allclose(compose(np.zeros(9), theta), theta, atol=1e-15)
    np.testing.assert_allclose(compose(theta, np.zeros(9)), theta, atol=1e-15)


# ----------------------------------------------------------------------------------------------- the motion
def test_motion_a_hand_turning_and_a_board_carried():
    hand = classify_motion(simulate("zhou2020", "typical", "mpu9250", 100.0, seed=1))
    assert hand.model_holds and hand.kind == "a hand turning the device" and hand.reason == ""
    carried = classify_motion(_carried())
    # the classifier's band displacement of ±0.22-m moves at 0.5 Hz: ~10 cm RMS per 4-s window against the 8-cm
    # threshold (gyrosim's hands turning: below a few cm)
    assert not carried.model_holds and carried.kind == "carried along a path"
    assert carried.moving_fraction("carried") > 0.8
    assert "carried along a path" in carried.reason and "turning it in the hand" in carried.advice


def test_motion_takes_off_what_a_noisy_accelerometer_reads_as_a_path():
    """The paper's simulated accelerometer (15 mg/√Hz) reads, with the hand turning the device, ~6 cm of band
    displacement per window from its noise alone: x_n² = 3 ∫ 2N² df/(2πf)⁴ over 0.2–2 Hz (5.9 cm; the filters take
    a little off).  Against the 8-cm threshold that called over a fifth of this session's windows carried (seed 9:
    S, G left at the prior); with the density given the noise's share is taken off and the hand is a hand.  A board
    carried on the same sensor is still carried."""
    n = 15e-3 * 9.80665                                   # the preset's density, m/s²/√Hz
    rec = simulate("zhou2020", "typical", "zhou2020_sim", 100.0, seed=9)
    blind = classify_motion(rec)
    aware = classify_motion(rec, params=blind.params, acc_noise_density_m_s2_sqrt_hz=n)
    closed = math.sqrt(3 * 2 * n**2 * (0.2**-3 - 2.0**-3) / 3 / (2 * math.pi) ** 4)
    assert 0.8 * closed < aware.noise_displacement_m <= closed, (aware.noise_displacement_m, closed)
    assert not blind.model_holds and blind.moving_fraction("carried") > 0.2
    assert aware.model_holds and aware.moving_fraction("carried") < 0.1
    carried = classify_motion(_carried(sensor="zhou2020_sim"), acc_noise_density_m_s2_sqrt_hz=n)
    assert not carried.model_holds and carried.moving_fraction("carried") > 0.8


# ----------------------------------------------------------------------------------------------- run and apply
def test_zhou2020_typical_mpu9250_every_s_g_determined_and_applied(zhou_run):
    """A designed session on a sensor with percent-size S, G: the prior must not hide what it determines."""
    rec, cal = zhou_run
    a = cal.applied
    assert a is not None and a.determined[3:9].all() and a.from_session[3:9].all(), a.notes
    # the decision adds no reason of its own against it (the method's own consistency check is another matter)
    assert cal.report["motion"]["model_holds"] and cal.report["held_out_check"]["verdicts"]["gyro"] == "agrees"
    assert not any("one half" in w or "motion is not" in w for w in cal.warnings)
    # what is applied is the estimate: the maker prior's pull is ≤ (σ/σ_prior)² of the way back, here < 1e-3 of it
    np.testing.assert_allclose(a.value("gyro", "scale_factor"), cal.value("gyro", "scale_factor"),
                               atol=3 * float(np.max(cal.std("gyro", "scale_factor"))))


def test_json_keys_round_trip_and_compensate_applies_only_what_is_applied(zhou_run, tmp_path):
    rec, cal = zhou_run
    path = tmp_path / "c.json"
    cal.save(path)
    d = json.loads(path.read_text())
    for key in ("bias_rad_s", "scale_factor", "nonorthogonality", "std", "determined"):   # old keys and the new one
        assert key in d["gyro"]
    assert d["gyro"]["determined"]["scale_factor"] == [True] * 3
    assert set(d["applied"]) >= {"gyro", "accelerometer", "prior", "summary", "notes"}
    assert set(d) >= {"motion", "prior", "held_out_check"}
    back = Calibration.load(path)
    np.testing.assert_array_equal(back.applied.from_session, cal.applied.from_session)
    np.testing.assert_allclose(back.applied.values, cal.applied.values)
    if cal.applied.gyro_misalignment_rad is not None:   # the gyro's rotation, applied with S, G, round-trips too
        np.testing.assert_allclose(back.applied.gyro_misalignment_rad, cal.applied.gyro_misalignment_rad)
        assert "gyro_acc_misalignment" in [e.kind for e in back.sensor_model().gyro]
    # compensate: with the applied block, its values; a file edited to apply nothing beyond the bias leaves S, G raw
    d["applied"]["gyro"]["scale_factor"] = [0.0, 0.0, 0.0]
    d["applied"]["gyro"]["nonorthogonality"] = [0.0, 0.0, 0.0]
    for block in (d["applied"]["gyro"], d["applied"]["gyro"]["std"], d["applied"]["gyro"]["from_session"]):
        block.pop("misalignment_rad", None)
    bias_only = Calibration.from_dict(d)
    out = bias_only.compensate(rec)
    np.testing.assert_allclose(out.gyro_rad_s, rec.gyro_rad_s - bias_only.applied.value("gyro", "bias"), atol=1e-12)
    assert "applied" in out.meta["compensated_by"]
    # a file without the block compensates with every estimate, as before
    del d["applied"]
    assert Calibration.from_dict(d).applied is None


def test_s_g_hidden_by_a_raw_accelerometer_are_judged_on_top_of_the_calibrated_one():
    """The README's session drawn with seed 11: S, G with the raw accelerometer do not predict the second half's
    gravity pairs better than raw (its accelerometer error, 0.9° of 2.0°, sets the gravity they are scored
    against), so the former rule left them at the prior and called a session whose errors are within 2.1σ
    inconsistent.  On top of the calibrated accelerometer they cut its 0.89° to 0.27°: applied, ok.  The rule
    still needs the accelerometer's own part to agree, and that comparison to agree, so a wrong S, G still fails
    it (the carried board above; the held-out check's own tests)."""
    rec = simulate("zhou2020", "typical", "mpu9250", 100.0, seed=11)
    cal = run_session(rec)
    v = cal.report["held_out_check"]["verdicts"]
    assert v["gyro"] == "disagrees" and v["accelerometer"] == "agrees", v   # what this test is about
    assert v["gyro_given_accelerometer"] == "agrees" and cal.applied.from_session[3:9].all()
    assert cal.status == "ok"
    # what is applied is the estimate (benchmarks/false_alarm.py scores it against the truth: max |z| 2.1 here)
    np.testing.assert_allclose(cal.applied.vector()[3:6], cal.scale_factor, atol=0.1 * cal.scale_factor_std.max())


def test_an_accelerometer_with_nothing_to_correct_is_left_at_the_prior_and_the_result_is_ok():
    """The demo's sensor (``zhou2020_sim``: an accelerometer with white noise only) calibrated by ``calib run``'s
    default: the session determines the accelerometer, but with nothing to correct it cannot predict the held-out
    poses better than raw — the former rule rejected it and called every such session inconsistent (20 of 20 seeds,
    benchmarks/false_alarm.py).  Now: within 3σ of the prior's values on every parameter and nowhere significantly
    worse → left at the prior, said so, and ``ok``.  A fitted accelerometer that is worse, or a correction beyond
    3σ that does not predict better, is still rejected (the rest-pose test below; the carried board above)."""
    rec = simulate("zhou2020", "typical", "zhou2020_sim", 100.0, seed=1)
    cal = run_session(rec)
    a = cal.applied
    assert a.determined[9:18].all() and not a.from_session[9:18].any(), a.notes
    np.testing.assert_array_equal(a.values[9:18], 0.0)                    # the maker prior's accelerometer
    theta = cal.vector("accelerometer")
    assert np.all(np.abs(theta) <= 3 * np.sqrt(np.diag(cal.linear_covariance("accelerometer"))))
    assert cal.report["held_out_check"]["no_correction"] == "accelerometer b, S, G"
    assert any(n.startswith("not applied: accelerometer b, S, G — nothing to correct") for n in a.notes), a.notes
    assert cal.status == "ok", cal.warnings
    assert a.from_session[3:9].all()                                       # S, G are this session's


def test_a_carried_board_leaves_s_g_at_the_prior_and_is_not_ok():
    cal = run_session(_carried(), RunOptions(accelerometer="calibrated"))
    a = cal.applied
    assert not a.determined[3:9].any() and not a.from_session[3:9].any()
    np.testing.assert_array_equal(a.values[3:9], 0.0)                       # the maker prior's S, G
    assert a.from_session[0:3].all()                                         # the bias is applied
    assert cal.status != "ok" and cal.report["motion"]["model_holds"] is False


def test_calib_run_prior_options(tmp_path, capsys):
    rec = simulate("zhou2020", "typical", "mpu9250", 100.0, seed=2)
    src = tmp_path / "s.h5"
    from gyrosim.recording import save_hdf5

    save_hdf5(rec, src)
    assert calib_main(["run", str(src), "--prior-tolerance", "S=abc"]) == 2
    assert "prior tolerance" in capsys.readouterr().err
    first = tmp_path / "a.json"
    assert calib_main(["run", str(src), "--json", str(first)]) == 0
    second = tmp_path / "b.json"
    # the first calibration as the prior, on the same recording: the data add nothing to it (σ ≈ the prior's), so
    # S, G stay at the prior — the first calibration's values
    assert calib_main(["run", str(src), "--prior", str(first), "--json", str(second)]) in (0, 1)
    a, b = Calibration.load(first).applied, Calibration.load(second).applied
    assert Calibration.load(second).report["prior"]["previous_calibration"] is True
    assert not b.from_session[3:9].any() and b.from_session[0:3].all()
    np.testing.assert_allclose(b.values[3:9], a.values[3:9], atol=1e-12)
    out = tmp_path / "c.csv"
    assert calib_main(["apply", str(second), str(src), "--out", str(out)]) == 0
    assert "applied from this session" in capsys.readouterr().out


# ----------------------------------------------------------------------------------------------- a real recording
def test_broad_translation_trial_bias_only_and_a_message_on_one_screen(capsys):
    """BROAD trial 12 (translation without rotation, trials.json): the default runs (no refusal), S and G are not
    determined and not applied, the status is not ok (exit 1), and what it prints fits on one screen with each
    line at most about two terminal lines and no internal identifiers."""
    import re

    from gyrosim.loaders import data_root

    path = data_root() / "broad" / "12_undisturbed_slow_translation_C.hdf5"
    if not path.is_file():
        pytest.skip("measured data not found (set GYROSIM_DATA)")
    assert calib_main(["run", str(path)]) == 1
    out = capsys.readouterr().out
    lines = out.splitlines()[1:]   # the first names the file
    assert len(lines) <= 25, out
    assert all(len(line) <= 2 * 120 for line in lines), max(lines, key=len)
    assert not re.search(r"\bcalib\.[a-z]|\bdiagnostics\.|\b[a-z]+_[a-z]+\.[a-z]", out), out
    assert "S, G cannot be read from it" in out and "applied: from this session: gyro bias;" in out
    assert "status: inconsistent" in out


@pytest.mark.slow
def test_every_broad_trial_through_the_harness():
    """The rules on BROAD, through the measured-data harness (calib run and calib apply as a user runs them, the
    orientation filters users run, BROAD's optical reference): no ``ok`` result makes a filter more than 10 % worse
    than raw unless the plain reference calibration (S = G = 0, the first rest's bias) does too; over the trials the
    median full-vs-raw change is ≤ 0 % for VQF 9D total and ≤ +5 % for VQF 6D inclination, and Madgwick and Mahony
    are no worse with the full calibration than with the bias alone; the translations determine no S, G."""
    from gyrosim.loaders import data_root

    from calib.scoring.measured import validate

    if not (data_root() / "broad").is_dir():
        pytest.skip("measured data not found (set GYROSIM_DATA)")
    v = validate(data_root(), only="broad/")
    trials = [r for r in v.recordings if r.kind == "broad"]
    assert trials and v.ok, v.failed
    four = ("vqf_9d.total_rmse_deg", "vqf_6d.inclination_rmse_deg", "madgwick_c2011_9d.total_rmse_deg",
            "mahony_9d.total_rmse_deg")
    for r in trials:
        c = r.calibration
        if c.get("status") == "ok":
            for key in four:
                f = r.figures[key]
                if f.get("full", 0.0) > 1.1 * f["raw"]:
                    assert f["plain_reference"] > 1.1 * f["raw"], (r.name, key, f)
        if "translation" in r.name:   # trials.json: translation without rotation
            assert sum(c["gyro_sg_determined"]) == 0 and sum(c["gyro_sg_applied"]) == 0, (r.name, c)
    m = v.medians
    # ≤ 0 % at the table's precision (0.05 %): subtracting the bias alone moves VQF 9D by +0.002 % (VQF estimates
    # its own gyro bias), and equal variants differ by round-off (1e-14 %)
    assert m["vqf_9d.total_rmse_deg"]["full_vs_raw_pct"] <= 0.05, m
    assert m["vqf_6d.inclination_rmse_deg"]["full_vs_raw_pct"] <= 5.0, m
    for key in ("madgwick_c2011_9d.total_rmse_deg", "mahony_9d.total_rmse_deg"):
        assert m[key]["full_vs_bias_only_pct"] <= 0.05, (key, m[key])


def _poses(acc_theta: np.ndarray, seed: int = 0, n_poses: int = 12, noise_m_s2: float = 0.01):
    """Static poses only (2 s each at 100 Hz, gravity in random body directions) through an accelerometer with
    bias, S, G ``acc_theta`` and white noise; the rests as (t0, t1) in s."""
    from gyrosim.effects import nonortho_matrix
    from gyrosim.recording import Recording

    rng = np.random.default_rng(seed)
    m = np.eye(3) + np.diag(acc_theta[3:6]) + nonortho_matrix(acc_theta[6:9])
    f, rests = [], []
    for k in range(n_poses):
        u = rng.normal(size=3)
        g = 9.80665 * u / np.linalg.norm(u)
        f.append(np.tile(m @ g + acc_theta[0:3], (200, 1)) + rng.normal(0, noise_m_s2, (200, 3)))
        rests.append((2.0 * k + 0.05, 2.0 * k + 1.95))
    acc = np.concatenate(f)
    t = np.arange(acc.shape[0]) / 100.0
    return Recording(t, rng.normal(0, 1e-3, acc.shape), acc, meta={"rate_hz": 100.0}), rests


def test_rest_pose_check_applies_a_fitted_accelerometer_and_refuses_a_calibrated_one():
    """Leave-one-pose-out: an accelerometer with 0.3 m/s² biases and 2 % scale errors is predicted at each held-out
    pose far better than raw (|f| − g raw ~0.3 m/s², fit ~ the noise over 200 samples, ~1e-3); a calibrated one
    cannot be improved on, so the fit does not agree (it only adds its own scatter)."""
    from calib.session.decision.decide import rest_pose_check

    truth = np.r_[0.3, -0.2, 0.25, 0.02, -0.015, 0.01, 0.004, -0.003, 0.002]
    rec, rests = _poses(truth)
    out = rest_pose_check(rec, rests, Prior.maker(), 9.80665)
    assert out["verdict"] == "agrees" and out["poses"] == 12
    assert out["rms_m_s2"]["fit"] < 0.1 * out["rms_m_s2"]["raw"]
    # the fit on every pose is the truth within 5σ of its own σ (+1e-4: the prior's ridge pull)
    assert np.all(np.abs(out["theta"] - truth) < 5 * out["sigma"] + 1e-4), (out["theta"], truth)
    rec, rests = _poses(np.zeros(9), seed=1)
    out = rest_pose_check(rec, rests, Prior.maker(), 9.80665)
    assert out["verdict"] == "disagrees" and not out["worse"]   # no better than raw, and not significantly worse
    assert rest_pose_check(rec, rests[:5], Prior.maker(), 9.80665) is None   # too few poses to spare
