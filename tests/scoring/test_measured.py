"""The measured-data harness (calib.scoring.measured): its arithmetic on constructed signals, its command's
bad inputs, one BROAD trial end to end (default suite), and every recording against BROAD's published
numbers (slow)."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from gyrosim.attitude_errors import broad_rmse_deg
from gyrosim.loaders import data_root, load_broad
from gyrosim.orientation import run_orientation
from gyrosim.orientation_broad import PUBLISHED_AS, PUBLISHED_TAGP, TOLERANCE_DEG, TOLERANCE_REL
from gyrosim.units import G0

from calib.orientation import builtin
from calib.scoring.measured import main, validate
from calib.scoring.measured_format import markdown, text_block, text_medians
from calib.scoring.measured_result import FIGURES, VARIANTS, MeasuredValidation, RecordingResult, broad_medians
from calib.scoring.measured_runs import ACC_REFUSAL, CliRun
from calib.scoring.measured_statics import (
    StaticDetector,
    carried_gravity_errors_deg,
    integrate_rk4,
    rest_norm_rms,
    static_intervals,
)

DATA = data_root()
FAST_TRIAL = "34_disturbed_attached_magnet_3cm"  # the shortest BROAD trial (169 s)
HAVE_TRIAL = (DATA / "broad" / f"{FAST_TRIAL}.hdf5").is_file()


# ------------------------------------------------------------------ arithmetic on constructed signals
def _rot_z(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _poses(rng: np.random.Generator, rate_hz: float = 100.0, turn_deg: float = 90.0, noise_m_s2: float = 0.0):
    """Rest 3 s, turn about x by ``turn_deg`` in 1 s at a smooth rate, rest 3 s, turn about z likewise, rest 3 s:
    (t, gyro, acc).  Gravity along body z at the start, then (90°) along y, which the z turn moves to x."""
    n_rest, n_move = int(3 * rate_hz), int(rate_hz)
    t = np.arange(3 * n_rest + 2 * n_move) / rate_hz
    gyro = np.zeros((t.size, 3))
    profile = np.sin(np.pi * np.arange(n_move) / n_move) ** 2
    rate = math.radians(turn_deg) * profile / (profile.sum() / rate_hz)
    gyro[n_rest:n_rest + n_move, 0] = rate
    gyro[2 * n_rest + n_move:2 * n_rest + 2 * n_move, 2] = rate
    # the attitude (body → nav) from the exact rate, and the specific force it implies at rest
    r, acc = np.eye(3), np.zeros((t.size, 3))
    for k in range(t.size):
        acc[k] = r.T @ np.array([0.0, 0.0, G0])
        w = gyro[k] / rate_hz
        angle = np.linalg.norm(w)
        if angle > 0:
            axis = w / angle
            kx = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
            r = r @ (np.eye(3) + math.sin(angle) * kx + (1 - math.cos(angle)) * kx @ kx)
    acc += noise_m_s2 * rng.standard_normal(acc.shape)
    return t, gyro, acc


def test_rk4_is_exact_for_a_constant_rate():
    # a constant rate about z for 2 s: the rotation is R_z(ω T); RK4 on a constant rate has no truncation
    # error beyond round-off (the exponential's series is reproduced to 4th order at each tiny step, 1e-12)
    t = np.arange(201) / 100.0
    w = np.tile([0.0, 0.0, 0.7], (201, 1))
    np.testing.assert_allclose(integrate_rk4(w, t, 0, 200), _rot_z(0.7 * 2.0), atol=1e-9)
    np.testing.assert_allclose(integrate_rk4(w, t, 50, 50), np.eye(3))


def test_static_intervals_and_the_two_figures_on_constructed_poses():
    rng = np.random.default_rng(7)
    t, gyro, acc = _poses(rng, noise_m_s2=0.01)
    det = StaticDetector.for_rate(100.0, init_s=2.0)
    iv = static_intervals(acc, det)
    assert len(iv) == 3
    # each rest is found within the window's half-width (0.5 s) of where it is
    for (s, e), (a, b) in zip(iv, [(0, 300), (400, 700), (800, 1100)]):
        assert abs(s - a) <= 51 and abs(e - b) <= 51
    # exact gyro: gravity is carried to within the direction error of the rests' mean specific force
    # (σ/g = 0.001 rad per axis and sample, two transverse axes, ≥ 210 samples: 0.006° per rest, 0.008° RMS
    # for a pair; seeded: 0.009° and 0.006°) plus the constructed attitude's left-rectangle steps against
    # RK4's (≤ 0.001°, the rate profile starting and ending near 0)
    err = carried_gravity_errors_deg(acc, gyro, t, iv)
    assert err.shape == (2,) and err.max() < 0.02
    # a 2 % scale error on x mis-turns the first 90° move by 1.8° (and the z move not at all)
    bad = carried_gravity_errors_deg(acc, gyro * [1.02, 1.0, 1.0], t, iv)
    assert abs(bad[0] - 1.8) < 0.03 and bad[1] < 0.02
    # |f| − g: the noise alone (σ 0.01 m/s² per axis, its radial part ~0.01 RMS over 300 samples: ±10 %),
    # and a 0.1 % scale (0.0098 m/s²) adds in quadrature
    base = rest_norm_rms(acc, iv, 100, G0)
    assert 0.007 < base < 0.013
    assert rest_norm_rms(acc * 1.001, iv, 100, G0) == pytest.approx(math.hypot(base, 0.0098), abs=0.001)


def test_imu_tk_detector_settings():
    d = StaticDetector.imu_tk()
    assert (d.window, d.multiplier, d.init, d.min_samples) == (101, 6.0, 5000, 100)
    assert StaticDetector.for_rate(285.7).window % 2 == 1


def _result(name: str, figures: dict) -> RecordingResult:
    return RecordingResult(name, "broad", "ref", 10, 1.0, (CliRun(("calib", "run", "x"), 1, 0.5, "ok"),),
                           {"status": "ok", "gyro_bias_rad_s": [0.0, 0.0, 0.0]}, {}, figures, {}, ())


def test_medians_and_the_result_round_trip():
    recs = [_result(f"broad/{i}", {"vqf_9d.total_rmse_deg": {"raw": 1.0, "bias_only": b, "full": f,
                                                              "plain_reference": 1.0}})
            for i, (b, f) in enumerate([(0.9, 2.0), (1.0, 0.5), (0.8, 1.5)])]
    m = broad_medians(recs)["vqf_9d.total_rmse_deg"]
    assert m["full_vs_raw_pct"] == pytest.approx(50.0)          # +100, −50, +50
    assert m["bias_only_vs_raw_pct"] == pytest.approx(-10.0)    # −10, 0, −20
    assert m["full_vs_bias_only_pct"] == pytest.approx(87.5)   # +122.2, −50, +87.5
    assert (m["full_worse_than_raw"], m["full_trials"]) == (2, 3)
    v = MeasuredValidation(tuple(recs), broad_medians(recs), 1.0, 1.0, "x")
    back = MeasuredValidation.from_dict(json.loads(json.dumps(v.to_dict())))
    assert back.to_dict() == v.to_dict() and back.recordings[0].runs[0].exit_code == 1
    assert "VQF 9D total RMSE" in text_medians(v) and "## Medians over the BROAD trials" in markdown(v)


def test_bad_inputs_exit_2(tmp_path, capsys):
    assert main([str(tmp_path / "nowhere")]) == 2
    assert "no data folder" in capsys.readouterr().err
    assert main([str(tmp_path)]) == 2  # a folder with no recording
    assert "no recording with a reference" in capsys.readouterr().err
    assert main([str(tmp_path), "--json", str(tmp_path / "no" / "out.json")]) == 2
    assert "does not exist" in capsys.readouterr().err


# ------------------------------------------------------------------ one BROAD trial, end to end
@pytest.fixture(scope="module")
def one_trial():
    if not HAVE_TRIAL:
        pytest.skip(f"BROAD trial {FAST_TRIAL} not found (set GYROSIM_DATA to the measured-data folder)")
    return validate(DATA, only=f"broad/{FAST_TRIAL}")


def test_one_trial_structure(one_trial):
    assert one_trial.ok and len(one_trial.recordings) == 1
    rec = one_trial.recordings[0]
    assert rec.name == f"broad/{FAST_TRIAL}" and rec.kind == "broad"
    verbs = [r.command[1] for r in rec.runs]
    assert verbs[0] == "run" and "mag" in verbs
    first = rec.runs[0]
    if first.exit_code == 2 and ACC_REFUSAL in first.message:  # the refusal is answered as its message says
        assert rec.runs[1].command[1] == "run" and "--accelerometer" in rec.runs[1].command
    # commands and messages name files as the user typed them, no machine path
    assert all("/" not in part or part.startswith("broad/") for r in rec.runs for part in r.command[2:])
    assert not any(str(DATA.resolve()) in r.message for r in rec.runs)
    assert set(rec.figures) == {k for k in FIGURES if "." in k}
    for key, values in rec.figures.items():
        if key == "vqf_9d_mag.heading_rmse_deg":
            continue
        assert set(values) == set(VARIANTS)
        for variant in ("raw", "plain_reference"):
            assert math.isfinite(values[variant]) and 0 < values[variant] < 90
        if rec.calibration:  # a calibration was written: its variants are scored too (else a note says why)
            assert math.isfinite(values["bias_only"]) and math.isfinite(values["full"])
        else:
            assert any("no calibration" in n for n in rec.notes)
    assert math.isfinite(rec.figures["vqf_9d_mag.heading_rmse_deg"]["raw"])
    assert set(one_trial.medians) == set(rec.figures)
    assert rec.name in text_block(rec) and "## BROAD trials" in markdown(one_trial)


def test_one_trial_raw_figures_match_a_direct_computation(one_trial):
    rec = one_trial.recordings[0]
    raw = load_broad(DATA / "broad" / f"{FAST_TRIAL}.hdf5")
    movement = raw.truth.extra["movement"].astype(bool)
    for name, prefix in (("vqf_9d", "vqf_9d"), ("vqf", "vqf_6d"), ("madgwick_c2011_9d", "madgwick_c2011_9d"),
                         ("mahony_9d", "mahony_9d")):
        got = broad_rmse_deg(run_orientation(builtin(name), raw, name).quat_nb, raw.truth.quat_nb, movement)
        for m, v in got.items():
            if f"{prefix}.{m}" in rec.figures:  # the same deterministic computation: equal to round-off
                assert rec.figures[f"{prefix}.{m}"]["raw"] == pytest.approx(v, rel=1e-12)
    # bias only: the raw gyro less exactly the bias the calibration file states
    if rec.calibration:
        b = np.asarray(rec.calibration["gyro_bias_rad_s"])
        q = run_orientation(builtin("mahony_9d"), raw.with_signals(gyro_rad_s=raw.gyro_rad_s - b), "mahony_9d")
        assert rec.figures["mahony_9d.total_rmse_deg"]["bias_only"] == pytest.approx(
            broad_rmse_deg(q.quat_nb, raw.truth.quat_nb, movement)["total_rmse_deg"], rel=1e-12)


def test_the_command_runs_as_a_module(tmp_path):
    # the entry point users run, python -m calib.scoring.measured, on a folder with one (empty) trial
    (tmp_path / "broad").mkdir()
    (tmp_path / "broad" / "01_trial.hdf5").write_bytes(b"")
    proc = subprocess.run([sys.executable, "-m", "calib.scoring.measured", str(tmp_path), "--only", "nomatch"],
                          capture_output=True, text=True, cwd=Path(__file__).resolve().parents[2])
    assert proc.returncode == 2 and "no recording matches 'nomatch'; found: broad/01_trial" in proc.stderr, proc.stderr


# ------------------------------------------------------------------ everything (slow)
@pytest.mark.slow
def test_every_recording_and_broads_published_numbers():
    if not (DATA / "broad").is_dir():
        pytest.skip("measured data not found (set GYROSIM_DATA)")
    v = validate(DATA)
    assert v.ok, v.failed
    broad = {r.name.split("/")[1]: r for r in v.recordings if r.kind == "broad"}
    assert broad
    # BROAD's published Madgwick (C form) and Mahony RMSEs on the raw data: the harness's scoring cannot
    # drift from BROAD's (gyrosim.orientation_broad: float32 C vs float64 and the first-sample attitude, a
    # priori max(0.1°, 10 %))
    checked = 0
    for ours, theirs in PUBLISHED_AS.items():
        for trial, pub in PUBLISHED_TAGP[theirs].items():
            if trial not in broad:
                continue
            for m, p in zip(("total_rmse_deg", "heading_rmse_deg", "inclination_rmse_deg"), pub):
                got = broad[trial].figures[f"{ours}.{m}"]["raw"]
                assert abs(got - p) <= max(TOLERANCE_DEG, TOLERANCE_REL * p), (trial, ours, m, got, p)
                checked += 1
    assert checked >= 3
    by_name = {r.name: r for r in v.recordings}
    if "imu_tk_xsens" in by_name:  # imu_tk's detection on its session: 38 intervals of 100 samples, 37 moves
        d = by_name["imu_tk_xsens"].details
        assert (d["static_intervals"], d["rest_samples"], d["moves"]) == (38, 3800, 37)
    for r in v.recordings:
        for key, values in r.figures.items():
            assert math.isfinite(values["raw"]) or r.kind == "xio", (r.name, key)


@pytest.mark.skipif(not (DATA / "imucal_ferraris").is_dir(), reason="imucal's session is not in the data folder")
def test_imucal_in_our_parameters_splits_its_accelerometer_matrix_into_symmetric_and_rotation():
    """A = K_a R_a = P U with P symmetric (ours to compare) and U a rotation.  scipy's polar returns (U, P) whatever
    the side: read the other way round, the comparison had S_a ≈ 0 (the rotation's diagonal) and its gyro S_z off by
    the accelerometer's 2.4 % z scale.  The gyro S then is imucal's own K_g diagonal up to the second-order share
    of R_g and U (|K_g R_g Uᵀ − K_g|'s diagonal, < 1e-3 here)."""
    pytest.importorskip("imucal", reason="imucal is the optional 'peers' extra")
    import pandas as pd
    from imucal import FerrarisCalibration, ferraris_regions_from_section_list

    from calib.scoring.measured_imucal import imucal_ferraris

    folder = DATA / "imucal_ferraris"
    res = imucal_ferraris(folder)
    df = pd.read_csv(folder / "example_ferraris_session.csv")
    sections = pd.DataFrame(json.loads((folder / "example_ferraris_session_list.json").read_text())).T
    info = FerrarisCalibration(grav=G0).compute(ferraris_regions_from_section_list(df, sections), 102.4, "m/s^2",
                                                "deg/s")
    np.testing.assert_allclose(res.parameters["gyro_scale_factor"], np.diag(info.K_g) - 1, atol=1e-3)
    np.testing.assert_allclose(res.parameters["acc_scale_factor"], np.diag(info.K_a) - 1, atol=1e-3)
    assert np.linalg.norm(res.gyro_rotation_deg) > 0.3    # the gyro triad turned against the accelerometer's


@pytest.mark.skipif(not (DATA / "imu_tk_xsens").is_dir(), reason="imu_tk's session is not in the data folder")
def test_imu_tk_session_as_applied_within_1_2_of_imu_tks_own_figures():
    """imu_tk's own session, scored imu_tk's way (its static detector, its two figures) on what ``calib apply``
    writes: both within 1.2× of imu_tk's calibration of the same file.  The gyro figure needs the gyro triad's
    rotation against the accelerometer's in the applied block (without it 1.06°, 2×); the accelerometer's, the
    |f| = g fit over the 38 rest poses in place of the motion filter's estimate (without it 0.0101 m/s², 1.27×).
    1.2×: the figures' own spread is small against it (3800 samples, 37 moves: a figure's relative standard error
    about 1/√(2·37) ≈ 12 % for the moves, 1 % for the samples), so 1.2× fails on a model that lacks either."""
    from calib.scoring.measured_sessions import IMU_TK_PUBLISHED

    v = validate(DATA, only="imu_tk")
    rec = v.recordings[0]
    assert rec.calibration["applied_gyro_misalignment_rad"] is not None
    for key, theirs in IMU_TK_PUBLISHED.items():
        assert rec.figures[key]["full"] <= 1.2 * theirs, (key, rec.figures[key]["full"], theirs)
