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
* ``calib/nis``: normalised innovation squared of the attitude update (expected: its rows, 2 or 3), at the steps
  with an update (NaN steps left out, so the values join up).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from gyrosim.recording import Recording
from gyrosim.viewer import (
    PALETTE,
    TRUTH_COLOUR,
    Span,
    board_eye,
    board_view,
    free_corner,
    log10_floor,
    log_marks,
    log_story,
    nice_range,
    scalar_style,
    series_view,
    shared_range,
    story_blueprint,
)

from calib.session.defaults import method_label

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
    if truth.external_acc_m_s2 is not None:
        _series(stream, "truth/external_acc", t, truth.external_acc_m_s2)
    step = max(1, int(round(rec.rate_hz / pose_rate_hz)))
    sel = np.arange(0, rec.n, step)
    q = truth.quat_nb[sel]
    pos = truth.position_nav_m[sel] if truth.position_nav_m is not None else np.zeros((q.shape[0], 3))
    ok = np.all(np.isfinite(q), axis=1) & np.all(np.isfinite(pos), axis=1)  # optical references have gaps
    sel, q, pos = sel[ok], q[ok], pos[ok]
    stream.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    stream.log("world/board/pcb", rr.Boxes3D(half_sizes=[0.02, 0.015, 0.0008], colors=[20, 120, 40]), static=True)
    stream.log(
        "world/board/axes",
        rr.Arrows3D(vectors=np.eye(3) * 0.05, colors=[[255, 0, 0], [0, 255, 0], [0, 0, 255]]),
        static=True,
    )
    # the board's whole path, thin and grey: where the board goes, seen from any time
    stream.log("world/path", rr.LineStrips3D([pos], radii=[0.002], colors=[[150, 150, 150]]), static=True)
    stream.send_columns(
        "world/board",
        indexes=[rr.TimeColumn(TIMELINE, duration=t[sel])],
        columns=rr.Transform3D.columns(translation=pos, quaternion=q[:, [1, 2, 3, 0]]),
    )
    if "wrist_position" in truth.extra and "elbow_position" in truth.extra:
        wrist = truth.extra["wrist_position"][sel]
        elbow = truth.extra["elbow_position"][sel]
        n = wrist.shape[0]
        strips = np.stack([np.broadcast_to(SHOULDER_M, (n, 3)), elbow, wrist, pos], axis=1)  # (n, 4, 3)
        stream.log("world/arm", rr.LineStrips3D.from_fields(radii=[0.02], colors=[[200, 160, 140]]), static=True)
        stream.send_columns("world/arm", indexes=[rr.TimeColumn(TIMELINE, duration=t[sel])],
                            columns=rr.LineStrips3D.columns(strips=list(strips)).partition(np.ones(n, int)))


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
    for name in ("S", "G"):  # one colour per axis; the truths in their own colour (below), never an estimate's
        for i, ax in enumerate(AXES):
            scalar_style(stream, f"calib/estimate/{name}/{ax}", f"{name} {ax}", PALETTE[i])
    if "ba_x" in names:
        for block, key in (("ba", "acc_bias"), ("Sa", "acc_scale"), ("Ga", "acc_nonorthogonality")):
            _series(stream, f"calib/estimate/{block}", t, h[key])
    nis = np.asarray(h["nis"], float)
    ok = np.isfinite(nis)  # NaN where the filter made no attitude update: left out, so the finite values join up
    if ok.any():
        stream.send_columns(
            "calib/nis", indexes=[rr.TimeColumn(TIMELINE, duration=t[ok])], columns=rr.Scalars.columns(scalars=nis[ok])
        )
    if truth is not None:
        ends = np.array([t[0], t[-1]])
        for name, key in (("S", "scale_factor"), ("G", "nonorthogonality")):
            for i, ax in enumerate(AXES):
                scalar_style(stream, f"calib/estimate/{name}/{ax}_true", f"{ax} true", TRUTH_COLOUR, width=1.0)
                stream.send_columns(
                    f"calib/estimate/{name}/{ax}_true",
                    indexes=[rr.TimeColumn(TIMELINE, duration=ends)],
                    columns=rr.Scalars.columns(scalars=np.full(2, truth[key][i])),
                )


SHOULDER_M = np.array([0.18, 0.0, 1.42])  # the hand model's shoulder (nav ENU, m), drawn as the arm's first point


def _board_positions(rec: Recording) -> np.ndarray | None:
    """The board's positions (nav, m) where its pose is known (finite), or None without a pose."""
    truth = rec.truth
    if truth is None or truth.quat_nb is None:
        return None
    pos = truth.position_nav_m if truth.position_nav_m is not None else np.zeros((rec.n, 3))
    ok = np.all(np.isfinite(truth.quat_nb), axis=1) & np.all(np.isfinite(pos), axis=1)
    return pos[ok] if ok.any() else None


def _eye(rec: Recording, pos: np.ndarray | None) -> rrb.EyeControls3D | None:
    """The camera on the board; from the side of the arm when the recording has the hand model's arm."""
    if pos is None:
        return None
    arm = rec.truth is not None and "wrist_position" in rec.truth.extra
    return board_eye(pos[:: max(1, pos.shape[0] // 2000)], SHOULDER_M[None, :] if arm else None,
                     tracking_entity="world/board")


def _rest_segments(result) -> list[tuple[float, float]]:
    return [(float(a), float(b)) for a, b in (getattr(result, "diagnostics", {}) or {}).get("rest_segments", [])]


def _first_within(t: np.ndarray, sd: np.ndarray, factor: float = 1.1) -> float:
    """First time after which √P stays within ``factor`` of its final value."""
    above = np.nonzero(sd > factor * sd[-1])[0]
    return float(t[above[-1] + 1]) if above.size and above[-1] + 1 < t.size else float(t[0])


def calibration_story(rec: Recording, result, truth: dict | None) -> str:
    """One paragraph (markdown): what converged, by when, to what; the rest segments; the status."""
    h = result.history.arrays() if result.history is not None else None
    dur = float(rec.t_s[-1] - rec.t_s[0]) if rec.n else 0.0
    lines = [f"**{'Simulated' if truth is not None else 'Recorded'} session, {dur:.0f} s at {rec.rate_hz:.0f} Hz — "
             f"{method_label(result.method)} (`{result.method}`), status {result.status}.**", ""]
    if h is not None and h["t_s"].size > 1:
        names = list(result.history.state_names)
        sd, t = h["sd"], h["t_s"]
        parts = []
        for blk, label in (("S", "scale factor"), ("G", "non-orthogonality")):
            idx = [i for i, n in enumerate(names) if n.split("_")[0] == blk]
            if idx:
                s = sd[:, idx].max(axis=1)
                parts.append(f"√P of the {label} falls from {s[0]:.2g} to {s[-1]:.2g} "
                             f"(×{s[0] / max(s[-1], 1e-300):.0f}), "
                             f"within 10 % of its final value from {_first_within(t, s):.0f} s")
        lines.append("Left: log10 √P per state over the whole session — " + "; ".join(parts) + ".")
    sf, g = result.value("gyro", "scale_factor"), result.value("gyro", "nonorthogonality")
    sfs, gs = result.std("gyro", "scale_factor"), result.std("gyro", "nonorthogonality")
    est = ("Middle: the estimates" + (" against the truth (flat lines)" if truth is not None else "") +
           f"; final S = {', '.join(f'{a:+.5f}±{b:.5f}' for a, b in zip(sf, sfs))}, "
           f"G = {', '.join(f'{a:+.5f}±{b:.5f}' for a, b in zip(g, gs))}")
    if truth is not None:
        es = (sf - np.asarray(truth["scale_factor"])) / np.maximum(sfs, 1e-300)
        eg = (g - np.asarray(truth["nonorthogonality"])) / np.maximum(gs, 1e-300)
        est += f"; error/σ: S {np.round(es, 1).tolist()}, G {np.round(eg, 1).tolist()}"
    if h is not None and h["nis"].size:
        nis = np.asarray(h["nis"], float)
        ok = np.isfinite(nis)
        expected = nis_expected(result)
        est += (f"; NIS mean {float(np.mean(nis[ok])):.2f} (expected {expected:g}) over the {int(ok.sum())} of "
                f"{nis.size} steps with an attitude update" if ok.any() else
                "; no NIS: the filter made no attitude update")
    lines.append(est + ".")
    rest = _rest_segments(result)
    if rest:
        lines.append(f"Right: the raw signals; green dots mark the {len(rest)} rest segment(s) the filter found "
                     f"({', '.join(f'{a:.0f}–{b:.0f} s' for a, b in rest[:6])}{' …' if len(rest) > 6 else ''}).")
    else:
        lines.append("Right: the raw signals. **No rest segment was found** in this recording: the gyro bias has "
                     "no static average to start from (see the warnings).")
    if _board_positions(rec) is None:
        lines.append("No 3-D view: the recording carries no attitude truth.")
    if result.warnings:
        lines.append("Warnings: " + "; ".join(result.warnings[:4]))
    return "\n".join(lines)


def nis_expected(result) -> float:
    """The NIS a consistent filter averages: its attitude update's rows (2 for the paper's filter, 3 with a
    heading row), as the consistency check recorded it."""
    return float(((getattr(result, "diagnostics", {}) or {}).get("consistency") or {}).get("nis_expected", 2.0))


def calibration_blueprint(span: Span | None = None, *, has_pose: bool = True, has_truth: bool = True,
                          acc_estimated: bool = False, ranges: dict | None = None,
                          eye: rrb.EyeControls3D | None = None, legends: dict | None = None,
                          nis_expected: float = 2.0, has_nis: bool = True) -> rrb.Blueprint:
    """Open on P converging (log10 √P, the whole session on every plot) and the estimates, with the raw
    signals (rest segments marked) and the board in 3-D beside, under the story text.

    ``ranges``: y ranges by key ``logP`` (S and G share it), ``phi``, ``S``, ``G``, ``nis``, ``gyro``,
    ``acc`` (computed by :func:`save_calibration_rrd` from the data); ``legends``: the legend corner by the same
    keys (:func:`gyrosim.viewer.free_corner`), top right where not given."""
    span = span or Span(0.0, 1.0)
    r = ranges or {}
    lg = legends or {}
    nis_name = f"NIS (expected {nis_expected:g})" if has_nis else "NIS: none (no attitude update)"
    true = " (— true)" if has_truth else ""
    cols = [
        rrb.Vertical(
            series_view("calib/log10_sqrtP/S", "log10 √P scale factor", span, y_range=r.get("logP"),
                        contents=["$origin/**", "marks/rest/logP_S"], legend_corner=lg.get("logP_S", "RightTop")),
            series_view("calib/log10_sqrtP/G", "log10 √P non-orthogonality", span, y_range=r.get("logP"),
                        contents=["$origin/**", "marks/rest/logP_G"], legend_corner=lg.get("logP_G", "RightTop")),
            series_view("calib/log10_sqrtP/phi", "log10 √P attitude (rad)", span, y_range=r.get("phi"),
                        legend_corner=lg.get("phi", "RightTop")),
        ),
        rrb.Vertical(
            series_view("calib/estimate/S", "scale factor" + true, span, y_range=r.get("S"),
                        legend_corner=lg.get("S", "RightTop")),
            series_view("calib/estimate/G", "non-orthogonality" + true, span, y_range=r.get("G"),
                        legend_corner=lg.get("G", "RightTop")),
            series_view("calib/nis", nis_name, span, y_range=r.get("nis"), legend_corner=lg.get("nis", "RightTop")),
        ),
    ]
    right = [board_view("world", "hand and board (ENU, m)", eye)] if has_pose else []
    right += [series_view("imu/gyro", "gyro (rad/s), rest ●", span, y_range=r.get("gyro"),
                          contents=["$origin/**", "marks/rest/gyro"], legend_corner="LeftBottom"),
              series_view("imu/acc", "accelerometer (m/s²), rest ●", span, y_range=r.get("acc"),
                          contents=["$origin/**", "marks/rest/acc"], legend_corner="LeftBottom")]
    cols.append(rrb.Vertical(*right))
    if acc_estimated:
        cols.append(rrb.Vertical(*[series_view(f"calib/log10_sqrtP/{b}", f"log10 √P {label}", span)
                                   for b, label in (("ba", "acc bias (m/s²)"), ("Sa", "acc scale factor"),
                                                    ("Ga", "acc non-orthogonality"))]))
    return story_blueprint(rrb.Horizontal(*cols), story_share=1.0, body_share=5.0)


def save_calibration_rrd(path: str | Path, rec: Recording, result, truth: dict | None = None,
                         application_id: str = "gyrosim_calib") -> Path:
    """Write the recording and the calibration run to an .rrd (open with ``rerun PATH``): the data of
    :func:`log_recording` and :func:`log_calibration`, ``calib/log10_sqrtP/...`` (log10 √P),
    ``marks/rest/...`` (rest segments) and ``story`` (the text), opened by :func:`calibration_blueprint`."""
    path = Path(path)
    stream = rr.RecordingStream(application_id)
    stream.save(str(path))
    span = Span.of(rec.t_s)
    h = result.history.arrays() if result.history is not None else None
    ranges = {"gyro": shared_range(rec.gyro_rad_s), "acc": shared_range(rec.acc_m_s2)}
    names = list(result.history.state_names) if h is not None else []
    legends: dict[str, str] = {}
    if h is not None and h["t_s"].size:
        lsd = log10_floor(h["sd"])
        blk = np.array([n.split("_")[0] for n in names])
        sg = np.isin(blk, ["S", "G"])
        ranges["logP"] = shared_range(lsd[:, sg], quantile=0, pad=0.15)
        ranges["phi"] = shared_range(lsd[:, blk == "phi"], quantile=0)
        inc_s = [] if truth is None else list(np.asarray(truth["scale_factor"], float))
        inc_g = [] if truth is None else list(np.asarray(truth["nonorthogonality"], float))
        ranges["S"] = shared_range(h["scale"], quantile=0.005, include=inc_s)
        ranges["G"] = shared_range(h["nonorthogonality"], quantile=0.005, include=inc_g)
        nis = np.asarray(h["nis"], float)
        nis = nis[np.isfinite(nis)]
        ranges["nis"] = nice_range(0.0, max(10.0, float(np.quantile(nis, 0.99)) if nis.size else 10.0))
        for i in range(0, len(names), 3):
            _series(stream, f"calib/log10_sqrtP/{names[i].split('_')[0]}", h["t_s"], lsd[:, i:i + 3])
        legends = _legend_corners(h, lsd, blk, ranges, span, truth)
    rest = _rest_segments(result)
    for view, lo_hi, at_top in (("gyro", ranges["gyro"], True), ("acc", ranges["acc"], True),
                                ("logP_S", ranges.get("logP"), False), ("logP_G", ranges.get("logP"), False)):
        if lo_hi is not None:
            level = lo_hi[1] - 0.04 * (lo_hi[1] - lo_hi[0]) if at_top else lo_hi[0] + 0.03 * (lo_hi[1] - lo_hi[0])
            log_marks(stream, f"marks/rest/{view}", span, level, intervals=rest, name="rest")
    pos = _board_positions(rec)
    eye = _eye(rec, pos)
    has_nis = h is not None and bool(np.isfinite(np.asarray(h["nis"], float)).any())
    stream.send_blueprint(calibration_blueprint(span, has_pose=pos is not None, has_truth=truth is not None,
                                                acc_estimated="ba_x" in names, ranges=ranges, eye=eye,
                                                legends=legends,
                                                nis_expected=nis_expected(result), has_nis=has_nis))
    log_story(stream, calibration_story(rec, result, truth))
    log_recording(stream, rec)
    if h is not None:
        log_calibration(stream, result, truth)
    stream.flush()
    return path


def _legend_corners(h: dict, lsd: np.ndarray, blk: np.ndarray, ranges: dict, span: Span,
                    truth: dict | None) -> dict[str, str]:
    """Each plot's legend in the corner its data leave free (:func:`gyrosim.viewer.free_corner`), the true values'
    flat lines counted with the estimates."""
    t = h["t_s"]
    out = {"logP_S": free_corner(t, lsd[:, blk == "S"], span, ranges["logP"]),
           "logP_G": free_corner(t, lsd[:, blk == "G"], span, ranges["logP"]),
           "phi": free_corner(t, lsd[:, blk == "phi"], span, ranges["phi"]),
           "nis": free_corner(t, h["nis"], span, ranges["nis"])}
    for key, arr, tkey in (("S", h["scale"], "scale_factor"), ("G", h["nonorthogonality"], "nonorthogonality")):
        flat = np.tile(np.asarray(truth[tkey], float), (t.size, 1)) if truth is not None else np.empty((t.size, 0))
        out[key] = free_corner(t, np.hstack([arr, flat]), span, ranges[key])
    return out


def blueprint(span: Span | None = None, eye: rrb.EyeControls3D | None = None) -> rrb.Blueprint:
    """Open on the signals (the whole recording) and the 3-D view framed on the board."""
    span = span or Span(0.0, 1.0)
    return story_blueprint(rrb.Horizontal(
        rrb.Vertical(
            series_view("imu/gyro", "gyro (rad/s)", span),
            series_view("imu/acc", "accelerometer (m/s²)", span),
            series_view("truth/external_acc", "external acceleration (m/s², truth)", span),
        ),
        board_view("world", "hand and board (ENU, m)", eye),
    ), story_share=1.0, body_share=6.0)


def save_session_rrd(path: str | Path, rec: Recording, application_id: str = "gyrosim_calib") -> Path:
    """Write ``rec`` to an .rrd file (open with ``rerun PATH``)."""
    path = Path(path)
    stream = rr.RecordingStream(application_id)
    stream.save(str(path))
    pos = _board_positions(rec)
    eye = _eye(rec, pos)
    stream.send_blueprint(blueprint(Span.of(rec.t_s), eye))
    log_story(
        stream,
        f"**Recorded session, {rec.t_s[-1] - rec.t_s[0]:.0f} s at {rec.rate_hz:.0f} Hz:** the raw gyro and "
        "accelerometer (body frame), the external acceleration the hand adds (truth) and the hand and board "
        "in 3-D" + ("" if pos is not None else " (no attitude truth: no 3-D pose)") + ".",
    )
    log_recording(stream, rec)
    stream.flush()
    return path


# ---------------------------------------------------------------------- magnetometer
def log_magnetometer(stream: rr.RecordingStream, rec: Recording, result, step: int | None = None) -> None:
    """Log the magnetometer before/after calibration.

    Entities: ``mag/raw/{x,y,z}`` and ``mag/calibrated/{x,y,z}`` (µT, body frame) and their
    magnitudes ``mag/magnitude/{raw,calibrated}`` on ``sensor_time``; ``mag/cloud/raw`` and
    ``mag/cloud/calibrated``: the samples as 3-D point clouds (the ellipsoid, amber, and the sphere
    it becomes, blue, centred on the origin after calibration), disturbed samples red;
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
    bad = dist[::step, None] > 0
    raw_c = np.where(bad, [[230, 40, 40]], [[200, 140, 40]]).astype(np.uint8)   # raw: amber, disturbed red
    cal_c = np.where(bad, [[230, 40, 40]], [[40, 120, 230]]).astype(np.uint8)   # calibrated: blue, disturbed red
    stream.log("mag/cloud/raw", rr.Points3D(m[::step], colors=raw_c, radii=0.3), static=True)
    stream.log("mag/cloud/calibrated", rr.Points3D(b[::step], colors=cal_c, radii=0.3), static=True)


def magnetometer_story(rec: Recording, result) -> str:
    """One paragraph: the fit, |B| spread before/after, the disturbances found (or that none were)."""
    m = np.asarray(rec.mag_ut, float)
    b = result.compensate(m)
    raw, cal = np.linalg.norm(m, axis=1), np.linalg.norm(b, axis=1)
    lines = [
        f"**Magnetometer calibration (`{result.method}`), status {result.status}** — {rec.t_s[-1] - rec.t_s[0]:.0f} s "
        f"at {rec.rate_hz:.0f} Hz.",
        "",
        f"Hard iron {np.round(result.hard_iron_ut, 2).tolist()} µT (±{np.round(result.hard_iron_std_ut, 2).tolist()}); "
        f"field {result.field_ut:.2f} ± {result.field_std_ut:.2f} µT, inclination {result.inclination_deg:.2f}° "
        f"({result.field_reference}).",
        f"Left: the samples in 3-D — the raw ellipsoid (off-centre) becomes the calibrated sphere on the origin. "
        f"Middle: |B| raw (spread {np.std(raw):.2f} µT RMS) vs calibrated ({np.std(cal):.2f} µT), one y scale.",
    ]
    if result.disturbances:
        d = result.disturbances
        lines.append(
            f"Red dots mark the {len(d)} local disturbance(s) found: "
            + ", ".join(f"{x.t_start_s:.0f}–{x.t_end_s:.0f} s (up to {x.max_field_deviation_ut:.1f} µT)" for x in d[:5])
            + (" …" if len(d) > 5 else "")
            + "; their samples are red in the cloud."
        )
    else:
        lines.append("**No local disturbance was found** in this recording (no red marks).")
    if result.warnings:
        lines.append("Warnings: " + "; ".join(result.warnings[:4]))
    return "\n".join(lines)


def magnetometer_blueprint(span: Span, *, has_pose: bool, mag_range: tuple[float, float] | None = None,
                           eye: rrb.EyeControls3D | None = None, field_ut: float = 50.0) -> rrb.Blueprint:
    """Story; the field cloud in 3-D; |B| raw and calibrated on one scale with disturbances marked; the
    calibrated field; the board in 3-D when the recording has its pose."""
    right = [series_view("mag/calibrated", "calibrated field (µT, body)", span)]
    if has_pose:
        right.append(board_view("world", "hand and board (ENU, m)", eye))
    return story_blueprint(rrb.Horizontal(
        rrb.Spatial3DView(origin="mag/cloud", name="field samples (µT): raw ellipsoid → calibrated sphere",
                          # outside the sphere of radius |B|, looking at the origin (the calibrated centre)
                          eye_controls=rrb.EyeControls3D(kind="Orbital", position=[2.2 * field_ut, -2.2 * field_ut,
                                                                                   1.4 * field_ut],
                                                         look_target=[0.0, 0.0, 0.0], eye_up=[0.0, 0.0, 1.0])),
        rrb.Vertical(
            series_view("mag/magnitude", "|B| raw and calibrated (µT), disturbances ●", span, y_range=mag_range,
                        contents=["$origin/**", "marks/disturbed"]),
            series_view("mag/disturbed", "local disturbance found (1 = yes)", span, y_range=(-0.1, 1.1)),
        ),
        rrb.Vertical(*right)), story_share=1.0, body_share=4.0)


def save_magnetometer_rrd(path: str | Path, rec: Recording, result, application_id: str = "gyrosim_calib") -> Path:
    """Write the magnetometer calibration (:func:`log_magnetometer`), the board's motion, ``story`` and
    ``marks/disturbed`` to an .rrd, opened by :func:`magnetometer_blueprint`."""
    path = Path(path)
    stream = rr.RecordingStream(application_id)
    stream.save(str(path))
    span = Span.of(rec.t_s)
    m = np.asarray(rec.mag_ut, float)
    mags = np.linalg.norm(m, axis=1), np.linalg.norm(result.compensate(m), axis=1)
    rng = shared_range(*mags, quantile=0.0)  # the whole range: the disturbances' excursions are the point
    log_marks(stream, "marks/disturbed", span, rng[1] - 0.04 * (rng[1] - rng[0]), name="disturbed",
              intervals=[(d.t_start_s, d.t_end_s) for d in result.disturbances], colour=(230, 40, 40))
    pos = _board_positions(rec)
    eye = _eye(rec, pos)
    stream.send_blueprint(magnetometer_blueprint(span, has_pose=pos is not None, mag_range=rng, eye=eye,
                                                 field_ut=float(np.median(mags[1]))))
    log_story(stream, magnetometer_story(rec, result))
    log_recording(stream, rec)
    log_magnetometer(stream, rec, result)
    stream.flush()
    return path
