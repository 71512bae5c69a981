"""Everything calib shows in rerun lives here; estimators never import rerun.

Timeline ``sensor_time`` (s, the recording's own clock).  Entities:

* ``imu/gyro/{x,y,z}`` (rad/s) and ``imu/acc/{x,y,z}`` (m/s²): the recorded samples, body frame;
* ``truth/external_acc/{x,y,z}`` (m/s², body) when the recording has truth;
* ``world/board``: the board's pose (truth attitude body→ENU, position of the accelerometer site)
  with a box the size of the IMU board; ``world/arm``: shoulder–elbow–wrist line of the hand model;
* ``calib/P/{phi,S,G}/{x,y,z}``: √diag(P) of the filter (rad; 1) after each update, and with the
  accelerometer estimated ``calib/P/{bg,ba,Sa,Ga}/{x,y,z}`` (rad/s; m/s²; 1; 1);
* ``calib/estimate/{S,G}/{x,y,z}``: the estimates; ``calib/estimate/{S,G}/{x,y,z}_true``: the true
  values as flat lines when the recording knows them (simulation); ``calib/estimate/{ba,Sa,Ga}``
  the accelerometer's;
* ``calib/nis``: normalised innovation squared of the two attitude rows (expected 2).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from gyrosim.recording import Recording

TIMELINE = "sensor_time"
AXES = ("x", "y", "z")


def _series(stream: rr.RecordingStream, path: str, t: np.ndarray, values: np.ndarray) -> None:
    for i, ax in enumerate(AXES):
        stream.send_columns(
            f"{path}/{ax}",
            indexes=[rr.TimeColumn(TIMELINE, duration=t)],
            columns=rr.Scalars.columns(scalars=values[:, i]),
        )


def log_recording(stream: rr.RecordingStream, rec: Recording, pose_rate_hz: float = 25.0) -> None:
    """Log raw samples, truth disturbances and the 3-D pose of board and arm."""
    t = rec.t_s
    _series(stream, "imu/gyro", t, rec.gyro_rad_s)
    _series(stream, "imu/acc", t, rec.acc_m_s2)
    truth = rec.truth
    if truth is None or truth.quat_nb is None:
        return
    if "external_acc" in truth.extra:
        _series(stream, "truth/external_acc", t, truth.extra["external_acc"])
    step = max(1, int(round(rec.rate_hz / pose_rate_hz)))
    sel = slice(None, None, step)
    q = truth.quat_nb[sel]
    pos = truth.position_nav_m[sel] if truth.position_nav_m is not None else np.zeros((q.shape[0], 3))
    stream.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    stream.log("world/board/pcb", rr.Boxes3D(half_sizes=[0.02, 0.015, 0.0008], colors=[20, 120, 40]), static=True)
    stream.log("world/board/axes", rr.Arrows3D(vectors=np.eye(3) * 0.05, colors=[[255, 0, 0], [0, 255, 0], [0, 0, 255]]), static=True)
    stream.send_columns(
        "world/board",
        indexes=[rr.TimeColumn(TIMELINE, duration=t[sel])],
        columns=rr.Transform3D.columns(translation=pos, quaternion=q[:, [1, 2, 3, 0]]),
    )
    if "wrist_position" in truth.extra and "elbow_position" in truth.extra:
        wrist = truth.extra["wrist_position"][sel]
        elbow = truth.extra["elbow_position"][sel]
        shoulder = np.array([0.18, 0.0, 1.42])
        for k, tk in enumerate(t[sel]):
            stream.set_time(TIMELINE, duration=float(tk))
            stream.log("world/arm", rr.LineStrips3D([[shoulder, elbow[k], wrist[k], pos[k]]], radii=0.02, colors=[200, 160, 140]))


def log_calibration(stream: rr.RecordingStream, result, truth: dict | None = None) -> None:
    """Log the filter's history: √diag(P), estimates (with truth lines) and NIS on ``sensor_time``."""
    h = result.history.arrays()
    t = h["t_s"]
    sd = np.sqrt(h["p_diag"])
    names = list(result.history.state_names)
    for i in range(0, len(names), 3):
        _series(stream, f"calib/P/{names[i].split('_')[0]}", t, sd[:, i:i + 3])
    _series(stream, "calib/estimate/S", t, h["scale"])
    _series(stream, "calib/estimate/G", t, h["nonorthogonality"])
    if "ba_x" in names:
        for block, key in (("ba", "acc_bias"), ("Sa", "acc_scale"), ("Ga", "acc_nonorthogonality")):
            _series(stream, f"calib/estimate/{block}", t, h[key])
    stream.send_columns("calib/nis", indexes=[rr.TimeColumn(TIMELINE, duration=t)], columns=rr.Scalars.columns(scalars=h["nis"]))
    if truth is not None:
        ends = np.array([t[0], t[-1]])
        for name, key in (("S", "scale_factor"), ("G", "nonorthogonality")):
            for i, ax in enumerate(AXES):
                stream.send_columns(
                    f"calib/estimate/{name}/{ax}_true",
                    indexes=[rr.TimeColumn(TIMELINE, duration=ends)],
                    columns=rr.Scalars.columns(scalars=np.full(2, truth[key][i])),
                )


def calibration_blueprint() -> rrb.Blueprint:
    """Open on P converging and the estimates, with the raw signals and the 3-D view beside."""
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(
                rrb.TimeSeriesView(origin="calib/P/S", name="√P scale factor"),
                rrb.TimeSeriesView(origin="calib/P/G", name="√P non-orthogonality"),
                rrb.TimeSeriesView(origin="calib/P/phi", name="√P attitude (rad)"),
            ),
            rrb.Vertical(
                rrb.TimeSeriesView(origin="calib/estimate/S", name="scale factor (— true)"),
                rrb.TimeSeriesView(origin="calib/estimate/G", name="non-orthogonality (— true)"),
                rrb.TimeSeriesView(origin="calib/nis", name="NIS (expected 2)"),
            ),
            rrb.Vertical(
                rrb.Spatial3DView(origin="world", name="hand and board"),
                rrb.TimeSeriesView(origin="imu/gyro", name="gyro (rad/s)"),
                rrb.TimeSeriesView(origin="imu/acc", name="accelerometer (m/s²)"),
            ),
        ),
        collapse_panels=True,
    )


def save_calibration_rrd(path: str | Path, rec: Recording, result, truth: dict | None = None,
                         application_id: str = "gyrosim_calib") -> Path:
    """Write the recording and the calibration run to an .rrd (open with ``rerun PATH``)."""
    path = Path(path)
    stream = rr.RecordingStream(application_id)
    stream.save(str(path))
    stream.send_blueprint(calibration_blueprint())
    log_recording(stream, rec)
    log_calibration(stream, result, truth)
    stream.flush()
    return path


def blueprint() -> rrb.Blueprint:
    """Open on the signals and the 3-D view."""
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(
                rrb.TimeSeriesView(origin="imu/gyro", name="gyro (rad/s)"),
                rrb.TimeSeriesView(origin="imu/acc", name="accelerometer (m/s²)"),
                rrb.TimeSeriesView(origin="truth/external_acc", name="external acceleration (m/s², truth)"),
            ),
            rrb.Spatial3DView(origin="world", name="hand and board"),
        ),
        collapse_panels=True,
    )


def save_session_rrd(path: str | Path, rec: Recording, application_id: str = "gyrosim_calib") -> Path:
    """Write ``rec`` to an .rrd file (open with ``rerun PATH``)."""
    path = Path(path)
    stream = rr.RecordingStream(application_id)
    stream.save(str(path))
    stream.send_blueprint(blueprint())
    log_recording(stream, rec)
    stream.flush()
    return path


# ---------------------------------------------------------------------- magnetometer
def log_magnetometer(stream: rr.RecordingStream, rec: Recording, result, step: int | None = None) -> None:
    """Log the magnetometer before/after calibration.

    Entities: ``mag/raw/{x,y,z}`` and ``mag/calibrated/{x,y,z}`` (µT, body frame) and their
    magnitudes ``mag/magnitude/{raw,calibrated}`` on ``sensor_time``; ``mag/cloud/raw`` and
    ``mag/cloud/calibrated``: the samples as 3-D point clouds (the ellipsoid and the sphere it
    becomes, centred on the origin after calibration), disturbed samples red;
    ``mag/disturbed``: 1 where a disturbance was found."""
    t = rec.t_s
    m = np.asarray(rec.mag_ut, dtype=float)
    b = result.compensate(m)
    _series(stream, "mag/raw", t, m)
    _series(stream, "mag/calibrated", t, b)
    for name, v in (("raw", m), ("calibrated", b)):
        stream.send_columns(f"mag/magnitude/{name}", indexes=[rr.TimeColumn(TIMELINE, duration=t)],
                            columns=rr.Scalars.columns(scalars=np.linalg.norm(v, axis=1)))
    dist = np.zeros(t.size)
    for d in result.disturbances:
        dist[(t >= d.t_start_s) & (t <= d.t_end_s)] = 1.0
    stream.send_columns("mag/disturbed", indexes=[rr.TimeColumn(TIMELINE, duration=t)],
                        columns=rr.Scalars.columns(scalars=dist))
    step = step or max(1, t.size // 5000)
    colours = np.where(dist[::step, None] > 0, [[230, 40, 40]], [[40, 120, 230]]).astype(np.uint8)
    stream.log("mag/cloud/raw", rr.Points3D(m[::step], colors=colours, radii=0.3), static=True)
    stream.log("mag/cloud/calibrated", rr.Points3D(b[::step], colors=colours, radii=0.3), static=True)


def save_magnetometer_rrd(path: str | Path, rec: Recording, result, application_id: str = "gyrosim_calib") -> Path:
    """Write the magnetometer calibration (:func:`log_magnetometer`) and the board's motion to an .rrd."""
    path = Path(path)
    stream = rr.RecordingStream(application_id)
    stream.save(str(path))
    stream.send_blueprint(rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(
                rrb.Spatial3DView(origin="mag/cloud", name="field samples (µT): raw ellipsoid, calibrated sphere"),
                rrb.TimeSeriesView(origin="mag/magnitude", name="|B| raw and calibrated (µT)"),
            ),
            rrb.Vertical(
                rrb.TimeSeriesView(origin="mag/calibrated", name="calibrated field (µT, body)"),
                rrb.TimeSeriesView(origin="mag/disturbed", name="local disturbance found"),
                rrb.Spatial3DView(origin="world", name="hand and board"),
            ),
        ),
        collapse_panels=True,
    ))
    log_recording(stream, rec)
    log_magnetometer(stream, rec, result)
    stream.flush()
    return path
