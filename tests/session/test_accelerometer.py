"""Calibrating a real consumer IMU from one session: the raw accelerometer estimated with the gyro,
noise-free and odd data, honest answers (status), and a result one can apply and export.

Data from the independent generator (tests/independent_generator.py, which imports nothing of
ours) unless a test says otherwise.  "Datasheet noise" is the MPU-9250's: gyro 0.01 °/s/√Hz
(0.1 °/s per sample at 100 Hz), accelerometer 300 µg/√Hz (3 mg per sample); the raw accelerometer
has ≥ 50 mg bias, 2–3 % scale and 1–1.5 % non-orthogonality.
"""

from __future__ import annotations

import json
import math

import independent_generator as ig
import numpy as np
import pytest
from scipy import stats

from gyrosim.calibration import Calibration, truth_calibration
from gyrosim.errors import GyrosimError, RecordingError
from gyrosim.recording import Recording, load_hdf5, save_hdf5

from calib.app.cli import main as calib_main
from calib.inputs import load_recording
from calib.session.paper import calibrate

RAW = {"acc_bias_g": (0.060, -0.055, 0.070), "acc_scale": (0.02, -0.025, 0.03), "acc_nonortho": (0.01, -0.012, 0.015)}
DATASHEET = {"gyro_noise_deg_s": 0.1, "acc_noise_g": 0.003}


def _rec(d: dict) -> Recording:
    return Recording(d["t_s"], d["gyro_rad_s"], d["acc_m_s2"], meta={"rate_hz": 100.0})


def _truth_vector(d: dict) -> np.ndarray:
    return np.concatenate([d["bias_rad_s"], d["scale_factor"], d["nonorthogonality"], d["acc_bias_m_s2"],
                           d["acc_scale_factor"], d["acc_nonorthogonality"]])


@pytest.mark.parametrize("steps", ["STEPS", "MULTIPOSE_STEPS"])
def test_noise_free_independent_data_is_exact(steps, tmp_path):
    """Noise-free raw IMU from the independent generator: exact up to our discretisation limit.

    Limit: the filter integrates attitude with the trapezoid + coning rule; for the raised-cosine
    profile its error between samples is ≤ Δt²|ω̇|max/12 = 1e-4·0.62/12 = 5e-6 rad at 100 Hz (the
    accelerometer's noise floor, calib.session.noiselevels).  Turned into parameters over rotations of π–2π
    that is ≲ 1e-6 for S, G of both triads and ≲ g·5e-6 = 5e-5 m/s² for the accelerometer bias; the
    gyro bias is the rest average of a noise-free gyro (CSV rounding 1e-9 of the value).  The
    first schedule goes through the CSV a user would write (9 significant digits)."""
    kwargs = dict(steps=getattr(ig, steps), gyro_noise_deg_s=0.0, acc_noise_g=0.0, **RAW)
    if steps == "STEPS":
        truth = ig.generate(tmp_path / "clean.csv", **kwargs)
        rec = load_recording(tmp_path / "clean.csv", "deg/s", "g")
        d = {**truth}
    else:
        d = ig.generate_arrays(**kwargs)
        rec = _rec(d)
    res = calibrate(rec)
    err = res.parameters() - _truth_vector(d)
    assert np.abs(err[3:9]).max() < 1e-5, err[3:9]        # gyro S, G
    assert np.abs(err[12:18]).max() < 1e-5, err[12:18]    # accelerometer S, G
    assert np.abs(err[0:3]).max() < 1e-7, err[0:3]         # gyro bias, rad/s
    assert np.abs(err[9:12]).max() < 1e-4, err[9:12]       # accelerometer bias, m/s² (1e-5 g)
    assert np.all(np.isfinite(res.covariance)) and np.all(np.diag(res.covariance) > 0)
    assert res.status == "ok", res.warnings


# the hand cross-check's false alarms on these hand-free sessions (calib.session.crosscheck.hand_cross_check: |δ| +
# 2σ_peer against 3σ, the peer's σ 1.1–1.3× this one's, so a δ of ~1σ crosses): measured 1 of 60 on each schedule (seeds
# 1000–1059: STEPS 1010 at 3.01, MULTIPOSE 1006 at 3.14, both before and after the joint's accelerometer prior became
# its |f| = g fit's block sandwich) and, since that change, seed 110 of the STEPS set at 3.02 (2.4 median).  A flag is
# the safe direction (a right answer called inconsistent); these tests allow the measured rate and no other non-ok
# status.
CROSS_CHECK_FLAG = "inconsistent: the hand-aware estimate"


def _run_seeds(steps, seeds: int, first: int = 100, max_flags: int = 1):
    kin = ig.kinematics(100.0, steps)
    errs, zs, nees, ref, flags = [], [], [], [], []
    for s in range(first, first + seeds):
        d = ig.generate_arrays(seed=s, kin=kin, **DATASHEET, **RAW)
        c = calibrate(_rec(d), keep_history=False)
        if c.status != "ok":
            assert c.status == "inconsistent" and any(w.startswith(CROSS_CHECK_FLAG) for w in c.warnings), c.warnings
            flags.append(s)
        e = c.parameters() - _truth_vector(d)
        errs.append(e)
        zs.append(e / np.sqrt(np.diag(c.covariance)))
        nees.append(e @ np.linalg.solve(c.covariance, e))
        clean = ig.generate_arrays(seed=s, kin=kin, **DATASHEET)  # the same device and noise, accelerometer calibrated
        # the reference needs no hand cross-check (the first call above keeps it: its false alarms are part of
        # this test, CROSS_CHECK_FLAG)
        cp = calibrate(_rec(clean), accelerometer="calibrated", keep_history=False, hand_check=False)
        ref.append(np.r_[cp.scale_factor - clean["scale_factor"], cp.nonorthogonality - clean["nonorthogonality"]])
    assert len(flags) <= max_flags, flags
    return np.array(errs), np.array(zs), np.array(nees), np.array(ref)


@pytest.mark.parametrize("steps", ["STEPS", "MULTIPOSE_STEPS"])
def test_raw_accelerometer_is_estimated_with_honest_sigma(steps):
    """20 seeds, datasheet noise, raw accelerometer, Zhou-like and multi-position schedules.

    * gyro S, G: RMS error within 1.5× of the calibrated-accelerometer case (the paper's 9 states on
      the same device and noise with the accelerometer's errors removed): estimating 9 more
      parameters from the same data may cost a little, not a factor;
    * accelerometer bias and scale: RMS of err/σ over 20 seeds in [0.7, 1.4]. For honest σ, 20·RMS²
      is χ²(20): its 99 % interval is [0.61, 1.41]²·… i.e. RMS ∈ [0.64, 1.38] — the issue's band is
      the same width;
    * NEES over all 18 parameters: the mean over 20 seeds of χ²(18) lies in its 95 % band
      [χ²₀.₀₂₅(360), χ²₀.₉₇₅(360)]/20 = [15.5, 20.7] (the seeds are fixed: the test is deterministic);
    * status ``ok`` in every seed but at most one that the hand cross-check flags (its measured false-alarm
      rate on hand-free sessions, ``CROSS_CHECK_FLAG``); nothing else non-ok.
    """
    errs, zs, nees, ref = _run_seeds(getattr(ig, steps), 20)
    rms_joint = np.sqrt(np.mean(errs[:, 3:9] ** 2, axis=0))
    rms_ref = np.sqrt(np.mean(ref**2, axis=0))
    assert np.all(rms_joint < 1.5 * rms_ref), (rms_joint, rms_ref)
    z_rms = np.sqrt(np.mean(zs**2, axis=0))
    assert np.all((z_rms[9:15] > 0.7) & (z_rms[9:15] < 1.4)), z_rms[9:15]  # accelerometer bias and scale
    lo, hi = stats.chi2.ppf([0.025, 0.975], 18 * 20) / 20
    assert lo < nees.mean() < hi, nees.mean()


@pytest.mark.slow
@pytest.mark.parametrize("steps", ["STEPS", "MULTIPOSE_STEPS"])
def test_raw_accelerometer_statistics_over_60_seeds(steps):
    """The same statistics over 60 seeds (docs/real_imu.md): every one of the 18 parameters has RMS
    err/σ in [0.75, 1.3] (χ²(60) 99 % band of an honest σ: [0.79, 1.23], widened for 18 tests); at most two
    sessions flagged by the hand cross-check (measured: one per schedule, ``CROSS_CHECK_FLAG``)."""
    errs, zs, nees, ref = _run_seeds(getattr(ig, steps), 60, first=1000, max_flags=2)
    z_rms = np.sqrt(np.mean(zs**2, axis=0))
    assert np.all((z_rms > 0.75) & (z_rms < 1.3)), z_rms
    lo, hi = stats.chi2.ppf([0.025, 0.975], 18 * 60) / 60
    assert lo < nees.mean() < hi, nees.mean()
    assert np.all(np.sqrt(np.mean(errs[:, 3:9] ** 2, axis=0)) < 1.5 * np.sqrt(np.mean(ref**2, axis=0)))


def test_windowed_nis_stays_quiet_on_clean_data():
    """The regime that made the last round's divergence test fire on clean data: a gyro noisier per
    step than the accelerometer (Zhou's reading B, 0.5 °/√h and 15 µg/√Hz).  With the Jacobians free
    of the samples' own noise the 1-s NIS windows leave their 99.9 % band as rarely as chance says
    (0.1 % per window; ≤ 1 window of ~150 per session at the 95 % level over 5 seeds)."""
    kin = ig.kinematics(100.0, ig.STEPS)
    for s in range(5):
        d = ig.generate_arrays(seed=s, kin=kin, gyro_noise_deg_s=0.0833, acc_noise_g=15e-6 * 10)
        c = calibrate(_rec(d), accelerometer="calibrated", keep_history=False)
        cons = c.diagnostics["consistency"]
        assert cons["fraction_above"] * cons["windows"] <= 1, cons
        assert c.status == "ok", c.warnings


def test_a_session_that_cannot_separate_the_accelerometer_is_refused_with_poses():
    """Turning about the vertical only: gravity stays on body z, so |f| = g sees b_z + g·S_z alone
    and the horizontal accelerometer errors stay tied to the unknown tilt — an error that names the
    parameters and the poses (x up/down, y up/down, the 45° poses) to add."""
    steps = [("rest", None, 0.0, 8.0), ("rot", 2, 2 * math.pi, 8.0), ("rot", 2, -2 * math.pi, 8.0),
             ("rest", None, 0.0, 8.0)]
    d = ig.generate_arrays(steps=steps, **DATASHEET, **RAW)
    with pytest.raises(RecordingError) as err:
        calibrate(_rec(d))
    msg = str(err.value)
    for name in ("accelerometer b_x", "accelerometer S_x", "accelerometer G_z"):
        assert name in msg
    for pose in ("x up", "x down", "y up", "y down", "z down"):
        assert pose in msg
    assert "--accelerometer calibrated" in msg
    # the paper's filter on the same data: a calibrated-accelerometer assumption is the user's to make
    res = calibrate(_rec(d), accelerometer="calibrated")
    assert any(w.startswith("unobservable") for w in res.warnings)


def test_a_raw_accelerometer_declared_calibrated_is_not_a_silent_answer(tmp_path, capsys):
    """Last round: S off by 3.4e-2 with no warning.  Now the rest poses' |f| − g (or the innovations)
    fail their check: status inconsistent, exit code 1, and the message says what to pass."""
    truth = ig.generate(tmp_path / "raw.csv", steps=ig.MULTIPOSE_STEPS, **DATASHEET, **RAW)
    out = tmp_path / "cal.json"
    assert calib_main(["run", str(tmp_path / "raw.csv"), "--gyro-unit", "deg/s", "--acc-unit", "g",
                       "--accelerometer", "calibrated", "--json", str(out)]) == 1
    d = json.loads(out.read_text())
    assert d["status"] == "inconsistent"
    assert "--accelerometer estimate" in capsys.readouterr().out
    # the default estimates it: ok, exit 0, and the accelerometer block is the truth within 4σ
    assert calib_main(["run", str(tmp_path / "raw.csv"), "--gyro-unit", "deg/s", "--acc-unit", "g",
                       "--json", str(out)]) == 0
    d = json.loads(out.read_text())
    assert d["status"] == "ok"
    acc = d["accelerometer"]
    for key, tkey in (("bias_m_s2", "acc_bias_m_s2"), ("scale_factor", "acc_scale_factor"),
                      ("nonorthogonality", "acc_nonorthogonality")):
        assert np.all(np.abs(np.asarray(acc[key]) - truth[tkey]) < 4 * np.asarray(acc["std"][key])), key
    # every key the last round's JSON had is still there
    assert {"method", "gyro", "rest_segments", "warnings", "noise", "consistency", "frames"} <= set(d)
    assert set(d["noise"]) >= {"arw_rad_s_sqrt_hz", "vrw_m_s2_sqrt_hz", "external_acc_allowance_m_s2"}
    assert set(d["consistency"]) >= {"nis_mean", "nis_expected"}


def test_the_estimator_does_not_read_the_simulators_noise_model():
    """calibrate() sees only what a real file carries: stripping the stored sensor model changes nothing."""
    from gyrosim.simulate import simulate

    rec = simulate("zhou2020", "steady", "mpu9250_linear", 100.0, seed=3)
    bare = rec.with_signals(meta={"rate_hz": rec.rate_hz})
    a, b = calibrate(rec, keep_history=False), calibrate(bare, keep_history=False)
    np.testing.assert_array_equal(a.parameters(), b.parameters())
    np.testing.assert_array_equal(a.covariance, b.covariance)


def test_calibration_json_round_trip_and_versions(tmp_path):
    d = ig.generate_arrays(steps=ig.STEPS, **DATASHEET, **RAW)
    cal = calibrate(_rec(d))
    back = Calibration.from_json(cal.to_json())
    np.testing.assert_array_equal(back.parameters(), cal.parameters())
    np.testing.assert_array_equal(back.covariance, cal.covariance)
    assert (back.status, back.warnings, back.method) == (cal.status, cal.warnings, cal.method)
    assert back.parameter_names() == cal.parameter_names()
    assert back.to_dict() == cal.to_dict()
    path = cal.save(tmp_path / "cal.json")
    assert Calibration.load(path).to_dict() == cal.to_dict()
    # NaN is never written: an estimator without covariance gives null with the reason in warnings
    from gyrosim.estimator import Estimate

    bare = Estimate(np.zeros(3), np.full(3, 0.01), np.zeros(3))
    text = bare.to_json()
    assert "NaN" not in text and json.loads(text)["gyro"]["std"]["scale_factor"] == [None] * 3
    assert any(w.startswith("no uncertainty") for w in json.loads(text)["warnings"])
    assert Calibration.from_json(text).to_dict() == bare.to_dict()
    future = dict(cal.to_dict(), version=99)
    with pytest.raises(GyrosimError, match="version 99"):
        Calibration.from_dict(future)
    with pytest.raises(GyrosimError, match="not a calibration"):
        Calibration.from_dict({"format": "something else"})


def test_apply_round_trip_gives_zero_errors(tmp_path, capsys):
    """calib run → calib apply → calib run on the compensated file: what is left is within the first
    calibration's own uncertainty (4σ of the first run's σ plus 4σ of the second's)."""
    rec_path = tmp_path / "raw.h5"
    d = ig.generate_arrays(steps=ig.MULTIPOSE_STEPS, seed=7, **DATASHEET, **RAW)
    save_hdf5(_rec(d), rec_path)
    cal_path = tmp_path / "cal.json"
    assert calib_main(["run", str(rec_path), "--json", str(cal_path)]) == 0
    first = Calibration.load(cal_path)
    for suffix in (".h5", ".csv"):
        out = tmp_path / f"compensated{suffix}"
        assert calib_main(["apply", str(cal_path), str(rec_path), "--out", str(out)]) == 0
        second = calibrate(load_recording(out))
        for triad, kind in (("gyro", "scale_factor"), ("gyro", "nonorthogonality"), ("accelerometer", "bias"),
                            ("accelerometer", "scale_factor"), ("accelerometer", "nonorthogonality")):
            tol = 4 * (first.std(triad, kind) + second.std(triad, kind))
            assert np.all(np.abs(second.value(triad, kind)) < tol), (suffix, triad, kind, second.value(triad, kind))
        assert np.all(
            np.abs(second.value("gyro", "bias")) < 4 * (first.std("gyro", "bias") + second.std("gyro", "bias"))
        )
    # the compensated HDF5 names what it was compensated with; the input is untouched
    comp = load_hdf5(tmp_path / "compensated.h5")
    # calib run labels its result with the registered name it equals (the default --method hand: kf_hand_joint)
    assert comp.meta["compensated_by"]["method"] == "kf_hand_joint"
    capsys.readouterr()
    assert calib_main(["apply", str(cal_path), str(rec_path), "--out", str(rec_path)]) == 2
    assert "never overwritten" in capsys.readouterr().err


def test_kalibr_export_and_import_as_a_sensor(tmp_path):
    """Export: Kalibr's continuous-time densities are our N (per-sample σ = N √f_s); random walks are
    given by the user.  Import: the imu.yaml is a sensor preset, and a static session simulated with it
    has per-sample σ = N √f_s (1000 samples per axis: the sample σ is within ±5 % at 3.5σ)."""
    from gyrosim.cli import main as gyrosim_main

    d = ig.generate_arrays(steps=ig.STEPS, **DATASHEET, **RAW)
    cal = calibrate(_rec(d))
    cal_path = cal.save(tmp_path / "cal.json")
    yaml_path = tmp_path / "imu.yaml"
    assert calib_main(["export", str(cal_path), "--format", "kalibr", "--out", str(yaml_path)]) == 2  # no random walk
    assert calib_main(["export", str(cal_path), "--format", "kalibr", "--out", str(yaml_path),
                       "--gyro-random-walk", "2e-5", "--acc-random-walk", "3e-4"]) == 0
    import yaml

    y = yaml.safe_load(yaml_path.read_text())
    assert y["gyroscope_noise_density"] == pytest.approx(cal.diagnostics["noise"]["arw_rad_s_sqrt_hz"], rel=1e-5)
    assert y["accelerometer_noise_density"] == pytest.approx(cal.diagnostics["noise"]["vrw_m_s2_sqrt_hz"], rel=1e-5)
    assert (y["gyroscope_random_walk"], y["accelerometer_random_walk"], y["update_rate"]) == (2e-5, 3e-4, 100)
    # the generator's noise: 0.1 °/s and 3 mg per sample at 100 Hz
    assert y["gyroscope_noise_density"] == pytest.approx(math.radians(0.1) / 10, rel=0.1)
    h5 = tmp_path / "static.h5"
    assert gyrosim_main(["simulate", "--schedule", "static", "--hand", "ideal", "--sensor", str(yaml_path),
                         "--seed", "1", "--out", str(h5), "--quiet"]) == 0
    rec = load_hdf5(h5)
    sd = np.std(np.diff(rec.gyro_rad_s[1000:2000], axis=0), axis=0) / math.sqrt(2)  # white part (differences)
    assert np.allclose(sd, y["gyroscope_noise_density"] * math.sqrt(rec.rate_hz), rtol=0.08)
    bad = tmp_path / "bad.yaml"
    bad.write_text("gyroscope_noise_density: 1e-4\n")
    assert gyrosim_main(["simulate", "--sensor", str(bad), "--out", str(tmp_path / "x.h5"), "--quiet"]) == 2


def test_imucal_export_gives_the_same_compensation(tmp_path):
    """imucal (optional 'peers' extra) loads our export and compensates exactly as we do."""
    pytest.importorskip("imucal", reason="imucal is the optional 'peers' extra (pip install .[peers])")
    from imucal.management import load_calibration_info

    d = ig.generate_arrays(steps=ig.STEPS, **DATASHEET, **RAW)
    rec = _rec(d)
    cal = calibrate(rec)
    path = tmp_path / "imucal.json"
    assert calib_main(["export", str(cal.save(tmp_path / "c.json")), "--format", "imucal", "--out", str(path)]) == 0
    info = load_calibration_info(path)
    acc, gyr = info.calibrate(acc=rec.acc_m_s2, gyr=np.degrees(rec.gyro_rad_s), acc_unit="m/s^2", gyr_unit="deg/s")
    ours = cal.compensate(rec)
    np.testing.assert_allclose(acc, ours.acc_m_s2, atol=1e-9)
    np.testing.assert_allclose(np.radians(gyr), ours.gyro_rad_s, atol=1e-11)


def test_mpu9250_with_its_raw_accelerometer_calibrates(tmp_path):
    """gyrosim simulate --sensor mpu9250 (raw accelerometer, typical hand, every undeclared effect of the
    preset) → calib run: no divergence, and gyro S, G at the accuracy of the calibrated-accelerometer
    case (same seed, the preset with the accelerometer reduced to its white noise, the paper's 9
    states): the worst error within 2× of it.  (The typical hand's 6 cm pivot dominates both: ~3e-3.)"""
    from dataclasses import replace

    from gyrosim.cli import main as gyrosim_main
    from gyrosim.sensor_model import load_sensor
    from gyrosim.simulate import simulate

    h5 = tmp_path / "mpu.h5"
    assert gyrosim_main(["simulate", "--sensor", "mpu9250", "--seed", "0", "--out", str(h5), "--quiet"]) == 0
    out = tmp_path / "cal.json"
    code = calib_main(["run", str(h5), "--json", str(out)])
    d = json.loads(out.read_text())
    assert code in (0, 1) and d["status"] != "diverged"
    rec = load_hdf5(h5)
    truth = truth_calibration(rec)
    err = np.r_[np.asarray(d["gyro"]["scale_factor"]) - truth.scale_factor,
                np.asarray(d["gyro"]["nonorthogonality"]) - truth.nonorthogonality]
    raw = load_sensor("mpu9250")
    calibrated = replace(raw, accelerometer=tuple(e for e in raw.accelerometer if e.kind == "white_noise"))
    rec_c = simulate("zhou2020", "typical", calibrated, 100.0, seed=0)
    ref = calibrate(rec_c, accelerometer="calibrated")
    t_c = truth_calibration(rec_c)
    err_ref = np.r_[ref.scale_factor - t_c.scale_factor, ref.nonorthogonality - t_c.nonorthogonality]
    assert np.abs(err).max() < 2 * np.abs(err_ref).max(), (err, err_ref)


def test_schedule_observability_covers_the_accelerometer():
    """calib observability names what a schedule leaves undetermined for the accelerometer (|f| = g):
    Zhou's Table 6 sweeps gravity through every body plane (all nine determined, posterior σ below 1 %
    of the prior at datasheet noise); vertical_only keeps gravity on z (only b_z + g·S_z is seen)."""
    from gyrosim.schedule import load_schedule

    from calib.session.observability import schedule_accelerometer_observability

    for name in ("zhou2020", "zhou2020_multipose"):
        verdict, poses = schedule_accelerometer_observability(load_schedule(name))
        assert not verdict.unobservable and not verdict.weak and np.all(verdict.ratio < 0.01), name
        assert poses == []
    verdict, poses = schedule_accelerometer_observability(load_schedule("vertical_only"))
    assert {"ba_x", "ba_y", "Sa_x", "Sa_y", "Ga_x", "Ga_y", "Ga_z"} <= set(verdict.unobservable + verdict.weak)
    assert {"x up", "x down", "y up", "y down", "z down"} <= set(poses)
