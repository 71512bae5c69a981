"""What a person sees on opening our .rrd files: the blueprint read back from the file.

Each recording is written by the same function its command uses, then read back with
``gyrosim.viewer.read_blueprint`` (the blueprint store inside the .rrd, via rerun's RrdReader) and
``read_texts`` (the story).  Facts asserted: the views a person needs are there; every time-series
view's visible range and x axis cover the whole recording (the viewer's default showed only the
last ~60 s); compared series share a view or a y range; the 3-D camera is on the board; a session
with no rest segment / no finding / no reference still opens on views and a story that says so.
Tolerances: times to one sample period (the range is the recording's first and last sample time);
ranges compared exactly (one range object is written for the views that share it).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import session

from gyrosim.viewer import Span, board_eye, read_blueprint, read_texts, shared_range


def _by_origin(views, kind=None):
    return {v.origin: v for v in views if kind is None or v.kind == kind}


def _covers(view, t0: float, t1: float, dt: float, timeline: str = "sensor_time") -> bool:
    a, b = view.time_ranges[timeline]
    xa, xb = view.x_range
    return a <= t0 + dt and b >= t1 - dt and xa <= t0 + dt and xb >= t1 - dt


@pytest.fixture(scope="module")
def calibrated():
    from gyrosim.sensor_model import load_sensor
    from gyrosim.simulate import apply_sensor

    from calib.session.paper import calibrate, true_gyro_parameters

    rec = apply_sensor(session("typical"), load_sensor("mpu9250"), np.random.default_rng(4))
    return rec, calibrate(rec, "kf_joint"), true_gyro_parameters(rec)


@pytest.fixture(scope="module")
def session_rrd(calibrated, tmp_path_factory):
    from calib.app.rerun import save_calibration_rrd

    rec, result, truth = calibrated
    return save_calibration_rrd(tmp_path_factory.mktemp("rrd") / "session.rrd", rec, result, truth)


def test_calibration_recording_opens_on_convergence_over_the_whole_session(calibrated, session_rrd):
    rec, result, truth = calibrated
    path = session_rrd
    views = read_blueprint(path)
    ts = _by_origin(views, "TimeSeries")
    need = {"calib/log10_sqrtP/S", "calib/log10_sqrtP/G", "calib/log10_sqrtP/phi", "calib/estimate/S",
            "calib/estimate/G", "calib/nis", "imu/gyro", "imu/acc"}
    assert need <= set(ts), set(ts)
    dt = 1.0 / rec.rate_hz
    for v in ts.values():  # the whole session on every plot, not the viewer's last minute
        assert _covers(v, rec.t_s[0], rec.t_s[-1], dt), (v.name, v.time_ranges, v.x_range)
    # log10 √P of S and G on one y scale that holds every value of both (they are compared)
    assert ts["calib/log10_sqrtP/S"].y_range == ts["calib/log10_sqrtP/G"].y_range
    lsd = np.log10(result.history.sd[:, 3:9])  # S_x..G_z (STATE_NAMES order: phi, S, G)
    lo, hi = ts["calib/log10_sqrtP/S"].y_range
    assert lo <= lsd.min() and hi >= lsd.max()
    # the story and the rest segments: the text counts what the marks show
    text = read_texts(path)["story"]
    rest = result.diagnostics["rest_segments"]
    assert rest and f"{len(rest)} rest segment(s)" in text and f"status {result.status}" in text  # as the result says
    assert any("marks/rest/gyro" in c for c in ts["imu/gyro"].contents)
    assert {v.kind for v in views} >= {"TextDocument", "3D"}


def test_the_3d_camera_is_on_the_board_with_the_arm_in_view(calibrated, session_rrd):
    from calib.app.rerun import SHOULDER_M

    rec = calibrated[0]
    (view,) = [v for v in read_blueprint(session_rrd) if v.kind == "3D"]
    pos = rec.truth.position_nav_m
    eye, target = np.array(view.eye[0]), np.array(view.eye[1])
    # looks at the board: the target is the board's median position (1 mm: float32 storage)
    assert np.linalg.norm(target - np.median(pos, axis=0)) < 1e-3
    # the 4 cm board subtends ≥ 5° (distance ≤ 0.46 m), while the board's whole path (95 %) is inside a
    # 60° cone around the view axis
    d = np.linalg.norm(eye - target)
    assert d <= 0.46
    axis = (target - eye) / d
    rays = (pos - eye) / np.linalg.norm(pos - eye, axis=1)[:, None]
    assert np.quantile(np.degrees(np.arccos(np.clip(rays @ axis, -1, 1))), 0.95) < 30.0
    assert view.eye[2] == "world/board"  # and follows it when it moves further
    # the arm leaves the board toward the shoulder across the view, not along the line of sight
    to_shoulder = (SHOULDER_M - target) / np.linalg.norm(SHOULDER_M - target)
    assert abs(float(to_shoulder @ axis)) < 0.5


def test_a_session_with_no_rest_segment_says_so_and_still_opens_on_the_plots(calibrated, tmp_path):
    from calib.app.rerun import save_calibration_rrd

    rec, result, truth = calibrated
    bare = dataclasses.replace(result, diagnostics={**result.diagnostics, "rest_segments": []})
    path = save_calibration_rrd(tmp_path / "norest.rrd", rec, bare, None)
    text = read_texts(path)["story"]
    assert "No rest segment was found" in text
    ts = _by_origin(read_blueprint(path), "TimeSeries")
    assert {"calib/log10_sqrtP/S", "imu/gyro"} <= set(ts)
    assert all(_covers(v, rec.t_s[0], rec.t_s[-1], 1.0 / rec.rate_hz) for v in ts.values())
    assert ts["calib/estimate/S"].name == "scale factor"  # no truth: no "(— true)" promised
    from gyrosim.viewer import _store_chunks  # the marks are absent, not empty entities

    entities = {c.entity_path for c in _store_chunks(path, blueprint=False)}
    assert not any(e.startswith("/marks/rest") for e in entities)


def test_closeloop_without_a_reference_opens_on_a_story_that_says_so(calibrated, tmp_path, monkeypatch):
    from calib.closeloop import loop, run_closeloop
    from calib.closeloop.reference import NoReferenceError
    from calib.closeloop.rrd import write_closeloop_rrd

    def no_reference(*args, **kwargs):
        raise NoReferenceError("no rest long enough for a gravity reference")

    monkeypatch.setattr(loop, "build_reference", no_reference)  # the loop's own path for such a recording
    res = run_closeloop(calibrated[0])
    assert res.reference == "none"
    path = write_closeloop_rrd(res, tmp_path / "none.rrd")
    texts = read_texts(path)
    assert "Nothing analysed" in texts["story"] and "no rest long enough" in texts["closeloop/notes"]
    assert {v.kind for v in read_blueprint(path)} == {"TextDocument"}  # text views, not empty plots


def test_blueprint_helpers():
    # the span of a time vector, and one y range that ignores a lone spike but holds the truth
    assert Span.of(np.array([2.0, 3.0, 7.5])) == Span(2.0, 7.5)
    x = np.r_[np.zeros(999), 1e6]
    lo, hi = shared_range(x, np.ones(1000), include=[2.0])
    assert lo < 0 and 2.0 <= hi < 10
    # a board path with no context: the camera still looks at it from above the horizon
    eye = board_eye(np.zeros((5, 3)))
    assert eye.position.as_arrow_array().to_pylist()[0][2] > 0
    # a long path (a board carried 1 m) keeps the camera close: it follows the board instead
    far = board_eye(np.c_[np.linspace(0, 1, 50), np.zeros((50, 2))], tracking_entity="world/board")
    assert np.linalg.norm(np.subtract(far.position.as_arrow_array().to_pylist()[0], [0.5, 0, 0])) <= 0.3 + 1e-6
