"""A rerun view of one session for the orientation estimators: ``gyrosim orientation-view``.

Self-contained (its own blueprint; the calibration views are :mod:`calib.app.rerun`).  Timeline
``sensor_time`` (s).  Entities:

* ``world/truth``: the board's true attitude (body → ENU, ``/truth/quat``), a green board with
  its body axes (x red, y green, z blue);
* ``world/<estimator>``: each estimator's attitude, the same board drawn in the estimator's
  colour, placed 0.12 m east of the previous one so they can be compared side by side (a 6-axis
  estimate is turned about the vertical by the heading offset the campaign removes, so the
  boards line up when the estimate is right);
* ``errors/tilt/<estimator>`` and ``errors/heading/<estimator>`` (°): BROAD's inclination error
  and the signed heading error (:mod:`gyrosim.attitude_errors`);
* ``events/disturbance``: the campaign's rate pulse (1 while it acts).

The session is the campaign's (:mod:`gyrosim.orientation_campaign`): same simulation, same
disturbance, raw or calibrated with ``calib``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["orientation_blueprint", "view_session"]

TIMELINE = "sensor_time"
PALETTE = [(230, 120, 20), (40, 110, 230), (200, 40, 160), (120, 120, 120), (20, 170, 170), (150, 90, 40)]


def orientation_blueprint(estimators: tuple[str, ...], span=None, eye=None):
    """Story on top; the boards in 3-D (camera on the row of boards); tilt and heading errors and the
    disturbance over the whole session (:mod:`gyrosim.viewer`)."""
    import rerun.blueprint as rrb

    from .viewer import Span, board_view, series_view, story_blueprint

    span = span or Span(0.0, 1.0)
    return story_blueprint(
        rrb.Horizontal(
            board_view("world", "truth (green) and estimators", eye),
            rrb.Vertical(
                series_view("errors/tilt", "tilt error (°)", span),
                series_view("errors/heading", "heading error (°; 6-axis: offset removed)", span),
                series_view("events", "disturbance", span, y_range=(-0.1, 1.1)),
            ),
            column_shares=[1, 1],
        ),
        story_share=1.0, body_share=6.0,
    )


def _board(stream, path: str, color: tuple[int, int, int], offset_east_m: float, t: np.ndarray, q: np.ndarray) -> None:
    import rerun as rr

    stream.log(f"{path}/pcb", rr.Boxes3D(half_sizes=[0.03, 0.02, 0.002], colors=[color]), static=True)
    stream.log(f"{path}/axes", rr.Arrows3D(vectors=np.eye(3) * 0.05, colors=[[255, 0, 0], [0, 255, 0], [0, 0, 255]]),
               static=True)
    pos = np.tile([offset_east_m, 0.0, 0.0], (t.size, 1))
    stream.send_columns(path, indexes=[rr.TimeColumn(TIMELINE, duration=t)],
                        columns=rr.Transform3D.columns(translation=pos, quaternion=q[:, [1, 2, 3, 0]]))


def view_session(*, hand: str = "typical", sensor: str = "mpu9250", seed: int = 0, schedule: str = "zhou2020",
                 estimators: tuple[str, ...] = ("vqf", "madgwick", "mahony", "fusion"), variant: str = "raw",
                 rrd: str | Path, pose_rate_hz: float = 25.0) -> Path:
    """Simulate one session, run the estimators as the campaign does, write ``rrd``; returns its path."""
    import rerun as rr

    from .attitude_errors import error_quat_earth, heading_error_rad, inclination_error_rad, remove_heading_offset
    from .campaign import _scaled_hand
    from .orientation import load_orientation_estimator, run_orientation
    from .orientation_campaign import OrientationSpec, _calibrated, _disturb
    from .sensor_model import load_sensor
    from .simulate import simulate

    spec = OrientationSpec(hands=(hand,), sensor=sensor, estimators=tuple(estimators), schedule=schedule)
    rec = simulate(schedule, _scaled_hand(hand, 1.0), load_sensor(sensor), spec.rate_hz, seed=seed, pipeline=False)
    src = _calibrated(rec, spec)[0] if variant == "calibrated" else rec
    disturbed, t_d, t_e = _disturb(src, spec, rec.truth.quat_nb)
    t = rec.t_s
    q_true = rec.truth.quat_nb
    step = max(1, int(round(rec.rate_hz / pose_rate_hz)))
    sel = slice(None, None, step)

    from .viewer import Span, board_eye, log_story

    path = Path(rrd)
    stream = rr.RecordingStream("gyrosim_orientation")
    stream.save(str(path))
    rows = np.array([[0.12 * i, 0.0, 0.0] for i in range(len(estimators) + 1)])  # the boards side by side (m, ENU)
    stream.send_blueprint(
        orientation_blueprint(
            tuple(estimators), Span.of(t), board_eye(rows, fill=2.6, max_radius_m=float(np.ptp(rows[:, 0])) / 2 + 0.1)
        )
    )
    summary = []
    stream.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    _board(stream, "world/truth", (20, 150, 40), 0.0, t[sel], q_true[sel])
    pulse = ((t >= t_d) & (t < t_e)).astype(float)
    stream.send_columns("events/disturbance", indexes=[rr.TimeColumn(TIMELINE, duration=t)],
                        columns=rr.Scalars.columns(scalars=pulse))
    for i, name in enumerate(estimators):
        att = run_orientation(load_orientation_estimator(name), disturbed, name)
        q = att.quat_nb
        if not att.magnetometer:
            align = (t >= t[0] + spec.settle_s) & (t < t[0] + spec.settle_s + spec.align_s)
            q = remove_heading_offset(q, q_true, align)
        q_e = error_quat_earth(q, q_true)
        color = PALETTE[i % len(PALETTE)]
        _board(stream, f"world/{name}", color, 0.12 * (i + 1), t[sel], q[sel])
        tilt, heading = inclination_error_rad(q_e), heading_error_rad(q_e, signed=True)
        summary.append(f"{name} RMS tilt {np.degrees(np.sqrt(np.mean(tilt ** 2))):.2f}°, heading "
                       f"{np.degrees(np.sqrt(np.mean(heading ** 2))):.2f}°")
        for kind, series in (("tilt", tilt), ("heading", heading)):
            stream.log(f"errors/{kind}/{name}", rr.SeriesLines(colors=[color], names=[name]), static=True)
            stream.send_columns(f"errors/{kind}/{name}", indexes=[rr.TimeColumn(TIMELINE, duration=t)],
                                columns=rr.Scalars.columns(scalars=np.degrees(series)))
    log_story(
        stream,
        f"**Orientation estimators on one {variant} session** ({schedule}, hand {hand}, sensor {sensor}, seed "
        f"{seed}, {t[-1] - t[0]:.0f} s): the true attitude (green board) and each estimator's, side by side "
        f"0.12 m apart; the rate disturbance acts {t_d:.1f}–{t_e:.1f} s. " + "; ".join(summary) + ".",
    )
    stream.flush()
    return path
