"""Zhou 2020 in-self calibration: accuracy, data from outside gyrosim, outputs, bad input."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest
import rerun as rr
from independent_generator import generate

from gyrosim.calibration import truth_calibration
from gyrosim.effects import Bias, NonOrthogonality, ScaleFactor
from gyrosim.errors import RecordingError
from gyrosim.hand import Hand, load_hand
from gyrosim.sensor_model import SensorModel
from gyrosim.simulate import simulate

from calib.app.cli import main as calib_main
from calib.inputs import load_recording
from calib.session.model import jacobian_nonorthogonality
from calib.session.paper import calibrate
from calib.session.rest import detect_rest


@pytest.fixture(scope="module")
def independent_csv(tmp_path_factory) -> tuple[Path, dict]:
    path = tmp_path_factory.mktemp("ind") / "imu.csv"
    return path, generate(path, seed=3)


def test_jacobian_of_the_symmetric_nonorthogonality_is_symmetric_not_skew():
    # ∂(N(G) ω)/∂G by finite differences equals J_G(ω), which is symmetric (Zhou eq. 9's [ω×] is not)
    from gyrosim.effects import nonortho_matrix

    w = np.array([0.3, -1.2, 0.7])
    num = np.stack([(nonortho_matrix(np.eye(3)[j] * 1e-6) @ w) / 1e-6 for j in range(3)], axis=1)
    np.testing.assert_allclose(jacobian_nonorthogonality(w), num, atol=1e-9)
    np.testing.assert_allclose(num, num.T)


def test_noise_free_ideal_hand_recovers_every_parameter():
    """Noise-free gyrosim session, raw accelerometer, no noise level given: the floors of
    calib.session.noiselevels keep the filter well-posed.  Limit: the trapezoid's attitude error between
    samples, ≤ Δt²|ω̇|/12 = 4e-7 rad for zhou2020 at 100 Hz, over rotations of ≥ π gives S, G to
    ~1e-6 and the accelerometer bias to ~g·4e-7·(a few) ≈ 1e-5 m/s²; the static bias is exact (the gyro
    at rest is the bias) and the filter moves it by less than 1e-7 rad/s."""
    sensor = SensorModel("clean", gyro=(Bias(value=np.radians([2.0, 2.0, 2.0])), ScaleFactor(value=[0.05, 0.04, 0.03]),
                                        NonOrthogonality(value=[0.025, 0.02, 0.01])),  # Table 7 values
                         accelerometer=(Bias(value=[0.5, -0.4, 0.6]), ScaleFactor(value=[0.02, -0.025, 0.03]),
                                        NonOrthogonality(value=[0.01, -0.012, 0.015])))
    rec = simulate("zhou2020", "ideal", sensor, 100.0, seed=1)
    res = calibrate(rec, "kf_joint")
    truth = truth_calibration(rec)
    err = res.parameters() - truth.parameters()
    assert np.abs(err[3:9]).max() < 1e-5 and np.abs(err[12:18]).max() < 1e-5  # gyro and accelerometer S, G
    assert np.abs(err[0:3]).max() < 1e-7                                      # gyro bias, rad/s
    assert np.abs(err[9:12]).max() < 1e-4                                     # accelerometer bias, m/s² (1e-5 g)
    # σ finite; MuJoCo's ideal hand leaves ~5e-5 m/s² of acceleration the kinematic model lacks (the
    # site is not exactly on the turning axis), above the numerical floor: ok or inconsistent, never diverged
    assert np.all(np.isfinite(res.covariance)) and res.status in ("ok", "inconsistent")


def test_data_from_an_independent_generator(independent_csv, tmp_path):
    path, truth = independent_csv
    digest = hashlib.sha256(path.read_bytes()).hexdigest()
    out_json, out_rrd = tmp_path / "r.json", tmp_path / "r.rrd"
    assert calib_main(["run", str(path), "--gyro-unit", "deg/s", "--acc-unit", "g", "--method", "kf_session",
                       "--json", str(out_json), "--rrd", str(out_rrd)]) == 0
    assert hashlib.sha256(path.read_bytes()).hexdigest() == digest  # the input is never modified
    d = json.loads(out_json.read_text())
    g = d["gyro"]
    for key in ("bias_rad_s", "scale_factor", "nonorthogonality"):
        est, std = np.asarray(g[key]), np.asarray(g["std"][key])
        # errors within 4σ of the filter's own standard deviation (and σ is small: < 1e-3 rel.)
        assert np.all(np.abs(est - truth[key]) < 4 * std + 1e-12), (key, est, truth[key], std)
    assert d["method"] == "kf_joint" and d["warnings"] == []
    assert d["rest_segments"][0][0] == 0.0 and 7.0 < d["rest_segments"][0][1] < 8.5  # 8 s initial rest
    # the .rrd holds √P per state: its last S_x value is the JSON's std
    last = None
    for chunk in rr.chunk.RrdReader(str(out_rrd)).stream():
        if chunk.entity_path == "/calib/P/S/x":
            col = chunk.to_record_batch().column("Scalars:scalars")
            last = float(np.asarray(col.to_pylist()[-1]).ravel()[0])
    assert last == pytest.approx(g["std"]["scale_factor"][0], rel=1e-12)


def test_rest_detection_finds_the_initial_static_period():
    rec = simulate("zhou2020", "typical", "mpu9250", 100.0, seed=2)
    rest = detect_rest(rec)
    t0, t1 = rest.times_s[0]
    # zhou2020 rests 0-9 s; the minimum-jerk start of the rotation is indistinguishable from rest
    # for ~0.4 s (rate < noise), and the window blurs the edge by ±0.25 s
    assert t0 == 0.0 and 8.5 < t1 < 9.6


def test_schedule_without_horizontal_rotations_warns_by_name():
    rec = simulate("vertical_only", "ideal", "zhou2020_sim_consumer", 100.0, seed=1)
    res = calibrate(rec, "kf_session_r", accelerometer="calibrated")
    (w,) = [w for w in res.warnings if w.startswith("unobservable")]
    # Zhou 2020 §4.2.1: rotation about the vertical z observes Gx, Gy only
    for name in ("S_x", "S_y", "S_z", "G_z"):
        assert name in w
    assert "G_x" not in w and "G_y" not in w


@pytest.mark.parametrize("method, accelerometer", [("kf_session", "calibrated"), ("kf_session", "estimate"),
                                                   ("hand", "calibrated"), ("hand", "estimate")])
def test_a_session_whose_first_long_rest_comes_after_the_turns_is_refused(method, accelerometer):
    """The filter starts at the rest that gives the bias (the first ≥ 2 s).  The independent generator's session with
    its first 9 s cut off leaves only pauses < 2 s before the last rest: nothing turns after it.  Before, ``kf_session``
    with a calibrated accelerometer answered S, G = the prior 0 ± 0.05 with status ok (and a warning), with the
    accelerometer estimated it refused for the accelerometer's sake, and kf_hand crashed in its low-pass (ValueError:
    padlen); now both refuse, saying where the filter starts and how much rotation comes before it."""
    import independent_generator as ig

    from gyrosim.errors import RecordingError
    from gyrosim.recording import Recording

    from calib.session.hand.filter import kf_hand

    d = ig.generate_arrays(seed=0, gyro_noise_deg_s=0.1, acc_noise_g=0.001)
    k = d["t_s"] >= 9.0
    rec = Recording(d["t_s"][k] - d["t_s"][k][0], d["gyro_rad_s"][k], d["acc_m_s2"][k], meta={"rate_hz": 100.0})
    run = (lambda: calibrate(rec, method, accelerometer=accelerometer)) if method == "kf_session" else (
        lambda: kf_hand(rec, accelerometer=accelerometer))
    with pytest.raises(RecordingError, match=r"starts at the first rest of ≥ 2 s \(t = 93.*100 % of the session's "
                                             r"rotation"):
        run()


def test_filter_divergence_is_named():
    # a 6 cm rotation-centre offset and no tremor: the rest data allow no external acceleration,
    # the centripetal ω²r then dwarfs the accelerometer noise and the innovations leave their band
    hand = Hand(name="pivot_only", pivot_offset_m=load_hand("typical").pivot_offset_m)
    rec = simulate("zhou2020", hand, "zhou2020_sim_consumer", 100.0, seed=4)
    for mode in ("calibrated", "estimate"):
        res = calibrate(rec, ("kf_joint" if mode == "estimate" else "kf_session_r"), accelerometer=mode)
        assert res.status in ("inconsistent", "diverged"), mode
        assert any(w.startswith(res.status) for w in res.warnings), mode


def _rows(path: Path) -> tuple[str, list[list[str]]]:
    lines = path.read_text().splitlines()
    return lines[0], [l.split(",") for l in lines[1:]]


def _write(path: Path, header: str, rows: list[list[str]]) -> Path:
    path.write_text("\n".join([header] + [",".join(r) for r in rows]) + "\n")
    return path


def test_bad_inputs_get_clear_errors(independent_csv, tmp_path, capsys):
    path, _ = independent_csv
    header, rows = _rows(path)
    units = ["--gyro-unit", "deg/s", "--acc-unit", "g"]
    cases = {
        "no_rest": (rows[1000:10000], "no rest period"),  # 10-100 s: always moving (the end rest is cut)
        "gap": (rows[:500] + rows[700:], "gap"),
        "backwards": (rows[:10] + [rows[11], rows[10]] + rows[12:], "strictly increasing"),
        "nan": (rows[:50] + [[rows[50][0], "nan"] + rows[50][2:]] + rows[51:], "NaN"),
    }
    for name, (body, message) in cases.items():
        p = _write(tmp_path / f"{name}.csv", header, body)
        assert calib_main(["run", str(p), *units]) == 2, name
        assert message in capsys.readouterr().err, name
    assert calib_main(["run", str(path)]) == 2  # deg/s declared as rad/s
    assert "--gyro-unit deg/s" in capsys.readouterr().err
    assert calib_main(["run", str(path), "--gyro-unit", "deg/s"]) == 2  # g declared as m/s²
    assert "--acc-unit g" in capsys.readouterr().err
    short = _write(tmp_path / "short.csv", header, rows[:150] + rows[790:])  # 1.5 s of rest, then a jump in time
    assert calib_main(["run", str(short), *units]) == 2


def test_short_rest_is_refused_with_what_it_would_give(independent_csv, tmp_path):
    path, _ = independent_csv
    header, rows = _rows(path)
    t0 = float(rows[650][0])  # keep 1.5 s of rest before the first rotation (at 8 s), cut the final rest
    body = [[f"{float(r[0]) - t0:.6f}"] + r[1:] for r in rows[650:10000]]
    rec = load_recording(_write(tmp_path / "s.csv", header, body), "deg/s", "g")
    with pytest.raises(RecordingError, match=r"shorter than the 2 s needed; its bias would be uncertain"):
        calibrate(rec, "kf_joint")


def test_saturated_samples_are_excluded_and_reported(independent_csv, tmp_path):
    path, truth = independent_csv
    header, rows = _rows(path)
    clip = 60.0  # °/s: the raised-cosine ±2π-in-8 s rotations peak at 2A/T = 90 °/s
    body = [[r[0]] + [f"{min(max(float(v), -clip), clip):.9g}" for v in r[1:4]] + r[4:] for r in rows]
    res = calibrate(load_recording(_write(tmp_path / "sat.csv", header, body), "deg/s", "g"), "kf_joint")
    assert any(w.startswith("saturated") for w in res.warnings)


def test_attitude_validation_compensation_beats_bias_only():
    """Zhou 2020 §5.2 / Table 12 on a free-style session of the same device (reading B, ideal hand).

    Without compensation the 2-5 % scale and non-orthogonality errors integrate to degrees over
    70 s of free rotation; with it only the estimation error (σ_S ≈ 4e-5) and the rest-average
    bias error (≈ 0.003 °/s × 70 s) remain: every angle's RMS must drop at least 10×.
    """
    from calib.session.validation import validate_attitude

    rec = simulate("zhou2020", "ideal", "zhou2020_sim_consumer", 100.0, seed=6)
    v = validate_attitude(rec, calibrate(rec, "kf_joint"), hand="ideal", seed=7)
    assert np.all(v.without_rms_deg > 1.0)
    assert np.all(v.with_rms_deg < v.without_rms_deg / 10)
