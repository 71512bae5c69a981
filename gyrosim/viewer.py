"""What a person sees on opening one of our rerun recordings: the blueprint vocabulary every writer uses.

A recording is written once and opened by someone who has not read the code.  The viewer's own
defaults (rerun 0.41) show the wrong thing for our recordings: a time-series view follows the last
~60 s of the timeline (where a calibration is long converged), each entity gets its own y scale
(so "before" and "after" cannot be compared), and the 3-D camera frames the whole scene (the arm
and shoulder, the board a few pixels at the edge).  Every writer therefore builds its blueprint
from these helpers:

* :func:`series_view` — a ``TimeSeriesView`` whose visible time range (the data queried,
  ``VisibleTimeRanges``) *and* x axis (``TimeAxis.view_range``) are an absolute span, by default the
  whole recording (:class:`Span`), with an optional fixed y range;
* :func:`shared_range` — one robust y range for series a person compares (quantiles, so a single
  spike does not flatten the rest), rounded outward to a step rerun labels (:func:`nice_range`: 1, 2 or 5
  × 10ⁿ, 4–10 steps), so the axis shows several labelled values, not one;
* :func:`free_corner` — the legend's corner: the one whose quarter of the plot holds the fewest samples,
  so the legend does not cover the data (e.g. the end of a run, where estimates meet the truth);
* :func:`log10_floor` — √P spans decades and rerun 0.41's plots have no log axis, so we log
  ``log10 √P`` beside the linear value;
* :func:`log_bars` — y against a quantity other than time (bar chart with abscissa);
* :func:`log_marks` — intervals (rest segments, disturbances, held-out data) or instants (events)
  drawn as a row of points at a chosen level inside the view they annotate;
* :func:`board_eye` / :func:`board_view` — a 3-D view with the camera looking at the board from a
  distance set by the board's path and the arm, so the board fills the view with the arm in context;
* :func:`log_story` / :func:`story_view` — a markdown ``TextDocument`` that says in one paragraph what
  the recording shows (and says so when something expected is missing);
* :func:`story_blueprint` — the top-level blueprint: the story above, the views below, panels collapsed;
* :func:`read_blueprint` / :func:`read_texts` — read the blueprint (and story) back from a written
  ``.rrd`` (``rerun.chunk.RrdReader``), so tests and users can check what a recording opens on.

Timeline ``sensor_time`` (duration, s) for signals.  A plot against something other than time (a
regressor, frequency, severity) is a ``BarChart`` with an ``abscissa`` in a ``BarChartView``
(:func:`log_bars`): a time-series view plots against the time panel's one active timeline, so a
view on another timeline would open empty.

Source: rerun 0.41 blueprint API (``rerun.blueprint``: TimeSeriesView, VisibleTimeRange,
TimeAxis, ScalarAxis, Spatial3DView, EyeControls3D, TextDocumentView, TimePanel).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable, Sequence

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

__all__ = ["TIMELINE", "STORY_PATH", "Span", "ViewInfo", "series_view", "shared_range", "log10_floor", "log_marks",
           "board_eye", "board_view", "log_story", "story_view", "story_blueprint", "read_blueprint", "read_texts",
           "send_series", "scalar_style", "log_bars", "PALETTE", "nice_range", "free_corner", "TRUTH_COLOUR",
           "read_series_styles"]

TIMELINE = "sensor_time"
STORY_PATH = "story"
PALETTE = [(31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189), (140, 86, 75),
           (227, 119, 194), (127, 127, 127), (188, 189, 34), (23, 190, 207)]  # matplotlib's tab10: one colour per name
# a true value drawn beside its estimate: dark grey, never one of the estimates' colours
TRUTH_COLOUR = (60, 60, 60)
MARK_COLOURS = {"rest": (40, 170, 80), "event": (230, 60, 40), "held_out": (120, 120, 220), "disturbed": (230, 40, 40)}


@dataclass(frozen=True)
class Span:
    """A span of one timeline: seconds for a duration timeline (``sequence=False``), integers for a
    sequence timeline."""

    start: float
    end: float
    timeline: str = TIMELINE
    sequence: bool = False

    @classmethod
    def of(cls, t: np.ndarray, timeline: str = TIMELINE) -> "Span":
        """The whole of a time vector (s)."""
        t = np.asarray(t, float)
        if t.size == 0:
            return cls(0.0, 1.0, timeline)
        lo, hi = float(np.min(t)), float(np.max(t))
        return cls(lo, hi if hi > lo else lo + 1.0, timeline)

    def _boundary(self, v: float) -> rrb.TimeRangeBoundary:
        return rrb.TimeRangeBoundary.absolute(seq=int(round(v))) if self.sequence else \
            rrb.TimeRangeBoundary.absolute(seconds=float(v))

    def view_kwargs(self) -> dict:
        """``time_ranges`` (what is queried) and ``axis_x`` (what is shown) for a TimeSeriesView."""
        a, b = self._boundary(self.start), self._boundary(self.end)
        return {"time_ranges": [rrb.VisibleTimeRange(self.timeline, start=a, end=b)],
                "axis_x": rrb.TimeAxis(view_range=rr.TimeRange(start=a, end=b))}


def series_view(origin: str, name: str, span: Span, *, contents: Sequence[str] | str | None = None,
                y_range: tuple[float, float] | None = None, legend: bool = True,
                legend_corner: str = "RightTop") -> rrb.TimeSeriesView:
    """A time-series view of ``origin`` (or of ``contents``) showing all of ``span`` on the x axis and,
    when given, ``y_range`` on the y axis (the same range for every view a person compares).  The
    legend sits top right by default: converging curves (√P, estimates) leave that corner free."""
    kw = span.view_kwargs()
    if y_range is not None:
        kw["axis_y"] = rrb.ScalarAxis(range=(float(y_range[0]), float(y_range[1])))
    if contents is not None:
        kw["contents"] = list(contents) if not isinstance(contents, str) else contents
    return rrb.TimeSeriesView(origin=origin, name=name, plot_legend=rrb.PlotLegend(legend_corner, visible=legend),
                              **kw)


def nice_range(lo: float, hi: float, steps: int = 5) -> tuple[float, float]:
    """[lo, hi] widened to whole multiples of a round step (1, 2 or 5 × 10ⁿ, about ``steps`` of them): the
    y axis then carries several labelled values (a range like 0.98731…1.01262 gets one label or none)."""
    if not (math.isfinite(lo) and math.isfinite(hi)) or hi <= lo:
        return (lo, hi)
    raw = (hi - lo) / steps
    mag = 10.0 ** math.floor(math.log10(raw))
    step = next(m * mag for m in (1.0, 2.0, 5.0, 10.0) if m * mag >= raw * (1 - 1e-9))
    digits = max(0, 1 - math.floor(math.log10(step)))  # the step's decimals, so 3e-05 is not 2.9999999999999997e-05
    a, b = math.floor(lo / step + 1e-9) * step, math.ceil(hi / step - 1e-9) * step
    return (round(float(a), digits), round(float(b), digits))


def free_corner(t: np.ndarray, values: np.ndarray, span: "Span", y_range: tuple[float, float]) -> str:
    """The corner ("LeftTop", "RightTop", "LeftBottom", "RightBottom") whose box — a third of the width, 40 % of
    the height of the plot of ``span`` × ``y_range`` — holds the fewest of the samples ``values`` (N,) or (N, k)
    at times ``t`` (N,): where the legend covers the least data.  Ties keep the order above."""
    t = np.asarray(t, float)
    v = np.asarray(values, float).reshape(t.size, -1)
    x = (t - span.start) / max(span.end - span.start, 1e-300)
    y = (v - y_range[0]) / max(y_range[1] - y_range[0], 1e-300)
    ok = np.isfinite(y)
    counts = {}
    for name, left, top in (("LeftTop", True, True), ("RightTop", False, True), ("LeftBottom", True, False),
                            ("RightBottom", False, False)):
        in_x = (x <= 1 / 3) if left else (x >= 2 / 3)
        in_y = (y >= 0.6) if top else (y <= 0.4)
        counts[name] = int(np.sum(ok & in_y & in_x[:, None]))
    return min(counts, key=counts.get)


def shared_range(*arrays: np.ndarray | Iterable[float], quantile: float = 0.001, pad: float = 0.08,
                 include: Iterable[float] = (), nice: bool = True) -> tuple[float, float]:
    """One y range for several series: the [q, 1−q] quantiles of all finite values together (so one
    spike does not squash the rest), widened by ``pad`` of the width on each side, and always
    containing ``include`` (e.g. the true value), then rounded outward to round steps (:func:`nice_range`;
    ``nice=False`` keeps the exact range).  Never zero width."""
    vals = [np.asarray(a, float).ravel() for a in arrays]
    v = np.concatenate(vals + [np.asarray(list(include), float)]) if vals or include else np.zeros(1)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return (-1.0, 1.0)
    lo, hi = (float(np.quantile(v, quantile)), float(np.quantile(v, 1 - quantile))) if quantile > 0 else \
        (float(v.min()), float(v.max()))
    for x in include:
        if math.isfinite(x):
            lo, hi = min(lo, float(x)), max(hi, float(x))
    w = hi - lo
    if w <= 0:
        w = max(abs(lo), 1.0) * 0.1
    out = (lo - pad * w, hi + pad * w)
    return nice_range(*out) if nice else out


def log10_floor(x: np.ndarray, floor: float = 1e-15) -> np.ndarray:
    """log10(max(x, floor)): for standard deviations spanning decades on a linear-only plot."""
    return np.log10(np.maximum(np.asarray(x, float), floor))


def send_series(stream: rr.RecordingStream, path: str, t: np.ndarray, values: np.ndarray,
                timeline: str = TIMELINE, sequence: bool = False) -> None:
    """One scalar series (N,) on ``timeline`` (duration seconds, or integer sequence)."""
    t = np.asarray(t)
    idx = rr.TimeColumn(timeline, sequence=np.asarray(np.round(t), np.int64)) if sequence else \
        rr.TimeColumn(timeline, duration=np.asarray(t, float))
    stream.send_columns(path, indexes=[idx], columns=rr.Scalars.columns(scalars=np.asarray(values, float)))


def scalar_style(stream: rr.RecordingStream, path: str, name: str, colour: Sequence[int] | None = None, *,
                 points: bool = False, width: float = 1.5, marker_size: float = 2.5) -> None:
    """Name (legend) and colour of a series, as a line or as points (static)."""
    kw = {"names": name}
    if colour is not None:
        kw["colors"] = [list(colour)]
    if points:
        stream.log(path, rr.SeriesPoints(markers="circle", marker_sizes=marker_size, **kw), static=True)
    else:
        stream.log(path, rr.SeriesLines(widths=width, **kw), static=True)


def log_bars(stream: rr.RecordingStream, path: str, x: np.ndarray, y: np.ndarray, width: np.ndarray | float,
             colour: Sequence[int]) -> None:
    """y against x as bars of ``width`` (static), for a ``BarChartView``; two entities in one view
    overlay (draw the reference wide and grey, the comparison narrow and coloured)."""
    x = np.asarray(x, float)
    w = np.broadcast_to(np.asarray(width, np.float32), x.shape)
    stream.log(path, rr.BarChart(np.asarray(y, float), abscissa=x, widths=np.array(w, np.float32), color=list(colour)),
               static=True)


def log_marks(stream: rr.RecordingStream, path: str, span: Span, level: float, *,
              intervals: Sequence[tuple[float, float]] = (), instants: Sequence[float] = (), name: str = "",
              colour: Sequence[int] = MARK_COLOURS["rest"], points_per_span: int = 500) -> int:
    """Mark intervals (a row of points every span/points_per_span inside each) and instants (one point
    each) at height ``level`` of the view they are shown in; returns the number of points logged
    (0 when there is nothing to mark: the writer's story then says so)."""
    step = (span.end - span.start) / points_per_span
    ts: list[np.ndarray] = []
    for a, b in intervals:
        a, b = max(float(a), span.start), min(float(b), span.end)
        if b >= a:
            ts.append(np.arange(a, b + 1e-12, step) if b > a else np.array([a]))
    if len(instants):
        ts.append(np.asarray(instants, float))
    if not ts:
        return 0
    t = np.unique(np.concatenate(ts))
    scalar_style(stream, path, name or path.rsplit("/", 1)[-1], colour, points=True)
    send_series(stream, path, t, np.full(t.size, float(level)), span.timeline, span.sequence)
    return int(t.size)


def board_eye(board_m: np.ndarray, context_m: np.ndarray | None = None, *, elevation_deg: float = 25.0,
              fill: float = 2.0, min_radius_m: float = 0.12, max_radius_m: float = 0.15,
              tracking_entity: str | None = None) -> rrb.EyeControls3D:
    """A camera on the board: it looks at the board's median position from the side of the arm
    (perpendicular to the horizontal line from the context point — the shoulder — to the board, so the
    arm runs across the view toward the board) and ``elevation_deg`` above, at ``fill`` × the radius of
    the board's path (95 % quantile, at least ``min_radius_m``): a hand-held session's board (a path within
    ``max_radius_m``) is large in the view with the arm near it; a board carried further (a measured
    session walking ±0.6 m) is framed with all of its path (from 1.25 × as far: every position within 25° of
    the view axis), so it is in view wherever the time cursor is — the viewer's tracking (``tracking_entity``,
    also set) did not move the camera in rerun 0.41's web viewer.  Frame: nav ENU (z up), metres."""
    board_m = np.atleast_2d(np.asarray(board_m, float))
    board_m = board_m[np.all(np.isfinite(board_m), axis=1)]
    centre = np.median(board_m, axis=0) if board_m.size else np.zeros(3)
    spread = float(np.quantile(np.linalg.norm(board_m - centre, axis=1), 0.95)) if board_m.size else 0.0
    if spread > max_radius_m:  # all of the path: its farthest point from the centre
        radius = 1.25 * float(np.max(np.linalg.norm(board_m - centre, axis=1)))
    else:
        radius = min(max_radius_m, max(min_radius_m, spread))
    side = np.array([-1.0, -1.0, 0.0])
    if context_m is not None:
        d = centre - np.atleast_2d(np.asarray(context_m, float))[0]
        if np.hypot(d[0], d[1]) > 1e-6:
            side = np.array([d[1], -d[0], 0.0])
    side /= np.linalg.norm(side)
    el = math.radians(elevation_deg)
    direction = side * math.cos(el) + np.array([0.0, 0.0, math.sin(el)])
    kw = {"tracking_entity": tracking_entity} if tracking_entity else {}
    return rrb.EyeControls3D(kind="Orbital", position=centre + fill * radius * direction, look_target=centre,
                             eye_up=[0.0, 0.0, 1.0], **kw)


def board_view(origin: str, name: str, eye: rrb.EyeControls3D | None = None, *, span: Span | None = None,
               contents: Sequence[str] | str | None = None) -> rrb.Spatial3DView:
    """A 3-D view with the camera of :func:`board_eye` (or rerun's default when ``eye`` is None)."""
    kw: dict = {}
    if eye is not None:
        kw["eye_controls"] = eye
    if contents is not None:
        kw["contents"] = contents
    return rrb.Spatial3DView(origin=origin, name=name, **kw)


def log_story(stream: rr.RecordingStream, markdown: str, path: str = STORY_PATH) -> None:
    """The recording's one-paragraph story (markdown), static."""
    stream.log(path, rr.TextDocument(markdown, media_type=rr.MediaType.MARKDOWN), static=True)


def story_view(path: str = STORY_PATH, name: str = "what this recording shows") -> rrb.TextDocumentView:
    """The view of the story logged by :func:`log_story` at ``path``, word-wrapped."""
    return rrb.TextDocumentView(
        origin=path, name=name, format_options=rrb.archetypes.TextDocumentFormat(word_wrap=True)
    )


def story_blueprint(body: rrb.Container | rrb.View, *, story: rrb.View | None = None, story_share: float = 1.0,
                    body_share: float = 4.0, timeline: str = TIMELINE) -> rrb.Blueprint:
    """The story above (``story_share`` of the height), the views below; panels collapsed, the time
    panel on ``timeline`` and paused (the plots already span the whole recording)."""
    story = story if story is not None else story_view()
    return rrb.Blueprint(
        rrb.Vertical(story, body, row_shares=[story_share, body_share]),
        rrb.TimePanel(timeline=timeline, state="collapsed", play_state="paused"),
        collapse_panels=True,
    )


# ---------------------------------------------------------------------- reading a recording back
@dataclass(frozen=True)
class ViewInfo:
    """One view of a blueprint as read back from an .rrd: ``kind`` is rerun's class ("TimeSeries",
    "Spatial3D", "TextDocument", ...); ``time_ranges`` maps a timeline to its absolute (start, end)
    (seconds for a duration timeline, raw integers for a sequence: see ``sequence``); ``x_range`` the
    x-axis view range in the same units; ``y_range`` the fixed y range or None; ``eye`` the 3-D
    camera's (position, look_target, tracked entity or None) or None; ``legend_corner`` the plot legend's corner
    ("LeftTop", …) or None."""

    kind: str
    name: str
    origin: str
    contents: tuple[str, ...] = ()
    time_ranges: dict = field(default_factory=dict)
    x_range: tuple | None = None
    y_range: tuple | None = None
    eye: tuple | None = None
    legend_corner: str | None = None


def _store_chunks(path: Path, blueprint: bool):
    from rerun.chunk import RrdReader

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # "no footer/manifest": a file written by RecordingStream.save
        reader = RrdReader(str(path))
        stores = reader.blueprints() if blueprint else reader.recordings()
        if not stores:
            return []
        return list(reader.stream(store=stores[-1]).to_chunks())


def _columns(chunk) -> dict[str, list]:
    """The component columns of a chunk as Python lists.  Timeline columns (log_time is a
    nanosecond timestamp) are skipped: pyarrow converts those to Python only with pandas installed,
    which is not a dependency, and no blueprint property lives in them."""
    import pyarrow as pa

    rb = chunk.to_record_batch()
    return {f.name: rb.column(i).to_pylist() for i, f in enumerate(rb.schema)
            if not (pa.types.is_timestamp(f.type) or pa.types.is_duration(f.type))}


def read_blueprint(path: str | Path, sequence_timelines: Iterable[str] = ()) -> list[ViewInfo]:
    """The views of the blueprint stored in an .rrd (the last blueprint store in the file), in no
    particular order; empty when the file has no blueprint (rerun would then lay it out itself).
    Duration ranges are returned in seconds; timelines listed in ``sequence_timelines`` raw."""
    seq = set(sequence_timelines)
    views: dict[str, dict] = {}
    for chunk in _store_chunks(Path(path), blueprint=True):
        ep = chunk.entity_path.strip("/")
        parts = ep.split("/")
        if parts[0] != "view" or len(parts) < 2:
            continue
        v = views.setdefault(parts[1], {})
        for k, col in _columns(chunk).items():
            if not col or col[-1] is None:
                continue
            val = col[-1]
            if k.endswith("class_identifier"):
                v["kind"] = val[0]
            elif k.endswith("display_name"):
                v["name"] = val[0]
            elif k.endswith("space_origin"):
                v["origin"] = val[0]
            elif k == "ViewContents:query":
                v["contents"] = tuple(val)
            elif k == "VisibleTimeRanges:ranges":
                v["time_ranges"] = {r["timeline"]: (r["range"]["start"], r["range"]["end"]) for r in val}
            elif k == "TimeAxis:view_range":
                v["x_range"] = (val[0]["start"], val[0]["end"])
            elif k == "ScalarAxis:range":
                v["y_range"] = tuple(val[0])
            elif k == "EyeControls3D:position":
                v["eye_position"] = tuple(val[0])
            elif k == "EyeControls3D:look_target":
                v["eye_target"] = tuple(val[0])
            elif k == "EyeControls3D:tracking_entity":
                v["eye_tracking"] = val[0]
            elif k == "PlotLegend:corner":
                v["legend_corner"] = rrb.components.Corner2D(val[0]).name
    out = []
    for v in views.values():
        if "kind" not in v:
            continue
        tr = v.get("time_ranges", {})

        def conv(tl: str, pair):
            return pair if tl in seq else (pair[0] / 1e9, pair[1] / 1e9)

        time_ranges = {tl: conv(tl, p) for tl, p in tr.items()}
        x = v.get("x_range")
        tl0 = next(iter(tr), TIMELINE)
        eye = (v["eye_position"], v["eye_target"], v.get("eye_tracking")) if "eye_position" in v and "eye_target" in v \
            else None
        out.append(ViewInfo(v["kind"], v.get("name", ""), v.get("origin", ""), v.get("contents", ()), time_ranges,
                            conv(tl0, x) if x is not None else None, v.get("y_range"), eye, v.get("legend_corner")))
    return out


def read_texts(path: str | Path) -> dict[str, str]:
    """Every TextDocument in the recording store of an .rrd: entity path → its (last) text."""
    out = {}
    for chunk in _store_chunks(Path(path), blueprint=False):
        rb = chunk.to_record_batch()
        if "TextDocument:text" in rb.schema.names:  # convert only the text column, not the signals
            col = rb.column("TextDocument:text").to_pylist()
            if col and col[-1]:
                out[chunk.entity_path.strip("/")] = col[-1][0]
    return out


def read_series_styles(path: str | Path) -> dict[str, tuple[str | None, tuple[int, ...] | None, float | None]]:
    """Every series' legend name, colour (RGB) and line width in the recording store of an .rrd: entity path →
    (name, colour, width); None where the writer left it to the viewer."""
    out = {}
    for chunk in _store_chunks(Path(path), blueprint=False):
        rb = chunk.to_record_batch()
        cols = set(rb.schema.names)
        for prefix in ("SeriesLines", "SeriesPoints"):
            names, colours, widths = f"{prefix}:names", f"{prefix}:colors", f"{prefix}:widths"
            if names in cols or colours in cols:
                def last(col: str):
                    v = rb.column(col).to_pylist()[-1] if col in cols else None
                    return v[0] if v else None

                rgba = last(colours)
                width = last(widths)
                out[chunk.entity_path.strip("/")] = (
                    last(names), tuple((int(rgba) >> sh) & 0xFF for sh in (24, 16, 8)) if rgba is not None else None,
                    float(width) if width is not None else None)
    return out
