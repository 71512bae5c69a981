"""``closeloop.rrd``: the loop's one comparison, laid out so a person sees it on open.

Entities (timeline ``sensor_time``, s, unless named):

* ``story``: the findings in words (or why there are none);
* ``closeloop/residual_before/{x,y,z}`` and ``closeloop/residual_after/{x,y,z}``: the residual of the
  declared model and after the loop (°/s for a rate reference, weighted otherwise), every row;
  ``marks/held_out/{x,y,z}``: the held-out rows the scores are computed on;
* ``closeloop/vs/{effect}/{x,y,z}/{before,after}``: bar charts of the held-out residual binned (30
  quantile bins, bar = bin) against the regressor of each found effect (x = the regressor's value,
  the bins' centres as ``abscissa``: rerun's time-series views plot against a timeline only);
* ``closeloop/spectrum/{x,y,z}/{before,after}``: bar charts of the amplitude spectral density of the
  residual (Welch, Hann, 16 segments; °/s/√Hz, x = frequency in Hz);
  ``closeloop/spectrum/{x,y,z}/unexplained``: the lines no candidate explains (``unexplained.spectral_lines``),
  red bars at their frequency.

The blueprint (:func:`closeloop_blueprint`): story on top; one view per axis with before and after
overlaid on one y range shared by the three axes and the whole recording on x; per found effect one
row of three bar charts (x, y, z) against its regressor, before (grey, wide) and after (colour, narrow)
overlaid; the same for the spectrum, with the unexplained lines in red.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb
from scipy import signal as sp_signal

from gyrosim.units import RAD2DEG
from gyrosim.viewer import (
    MARK_COLOURS,
    Span,
    log_bars,
    log_marks,
    log_story,
    scalar_style,
    send_series,
    series_view,
    shared_range,
    story_blueprint,
)

from calib.closeloop.loop import CloseloopResult

__all__ = ["closeloop_blueprint", "closeloop_story", "write_closeloop_rrd"]

AXES = "xyz"
BEFORE, AFTER = (150, 150, 150), (30, 110, 220)
AXIS_COLOURS = {"x": (220, 60, 50), "y": (40, 160, 70), "z": (40, 90, 220)}


def _scale(res: CloseloopResult) -> tuple[float, str]:
    return (RAD2DEG, "°/s") if res.reference in ("truth", "optical", "static") else (1.0, "weighted")


def _has_rows(res: CloseloopResult) -> bool:
    return res.residual_before is not None and res.row_time_s is not None and res.reference != "none"


def _is_time_series(res: CloseloopResult) -> bool:
    """Rate references give one row per axis per time block (a time series); a static reference gives
    one row per pose (no spectrum)."""
    return _has_rows(res) and res.rows_of is not None


def _intervals(t: np.ndarray) -> list[tuple[float, float]]:
    """Contiguous runs of sorted times (a gap > 3 median steps starts a new run)."""
    t = np.unique(np.asarray(t, float))
    if t.size == 0:
        return []
    dt = float(np.median(np.diff(t))) if t.size > 1 else 1.0
    cuts = np.nonzero(np.diff(t) > 3 * dt)[0]
    starts = np.r_[0, cuts + 1]
    ends = np.r_[cuts, t.size - 1]
    return [(float(t[a]), float(t[b])) for a, b in zip(starts, ends)]


def _binned(
    x: np.ndarray, r: np.ndarray, bins: int = 25, min_count: int = 20
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean of r in equal-width bins of x between its 1 % and 99 % quantiles (bins with fewer than
    ``min_count`` rows dropped: their mean is noise): (bin centres, means, bin widths)."""
    lo, hi = np.quantile(x, [0.01, 0.99])
    if not hi > lo:
        return np.array([float(np.mean(x))]), np.array([float(np.mean(r))]), np.array([1.0])
    edges = np.linspace(lo, hi, bins + 1)
    inside = (x >= lo) & (x <= hi)
    idx = np.clip(np.searchsorted(edges, x[inside], side="right") - 1, 0, bins - 1)
    cnt = np.bincount(idx, minlength=bins)
    mean = np.bincount(idx, r[inside], bins) / np.maximum(cnt, 1)
    keep = cnt >= min_count
    return 0.5 * (edges[:-1] + edges[1:])[keep], mean[keep], np.diff(edges)[keep]


def _spectrum(blocks: np.ndarray, fs_hz: float) -> tuple[np.ndarray, np.ndarray]:
    n = blocks.shape[0]
    nper = int(2 ** math.floor(math.log2(max(16, 2 * n // 17))))
    nper = min(nper, n)
    f, pxx = sp_signal.welch(blocks, fs=fs_hz, nperseg=nper, noverlap=0, axis=0, detrend="constant")
    return f[1:], np.sqrt(pxx[1:])


def _short(trace: str) -> str:
    """A finding's trace up to what it cut ("the residual follows X → effect; adding it cut ... from a to b"),
    so that several fit the story pane; the rest (confounding, metrics) stays in report.md."""
    return "; ".join(trace.split("; ")[:2]).split(" (G = ")[0].rstrip(".")


def closeloop_story(res: CloseloopResult) -> str:
    """The findings in one paragraph (markdown), or why there are none."""
    _, unit = _scale(res)
    head = (
        f"**Close-the-loop, reference {res.reference}** — {res.reference_description}. "
        f"Declared: {', '.join(res.declared)}."
    )
    lines = [head, ""]
    if not _has_rows(res):
        lines.append("**Nothing analysed:** this recording has no reference the residual could be computed against, so "
                     "there is no before/after to show. " + res.unexplained.summary)
        return "\n".join(lines)
    if res.found:
        lines.append("**Found:** " + " ".join(f"({i + 1}) {_short(f.trace)}." for i, f in enumerate(res.found)) +
                     " (each finding's full evidence: report.md)")
    elif not res.tested:
        lines.append("**Found nothing — nothing could be tested here:** " +
                     "; ".join(f"{k}: {v}" for k, v in list(res.not_tested.items())[:4]))
    else:
        lines.append(f"**Found nothing:** no candidate explains a significant part of the held-out residual "
                     f"(tested: {', '.join(res.tested)}). The before and after curves coincide.")
    b, a = res.error_before.get("held_out_residual_rms"), res.error_after.get("held_out_residual_rms")
    if isinstance(b, float) and isinstance(a, float):
        lines.append(f"Held-out residual RMS {b:.4g} → {a:.4g} {res.error_before.get('unit', '')} "
                     "(grey: declared model, blue: after the loop; dots on top: held-out rows).")
    lines.append("Unexplained: " + (res.unexplained.summary or "nothing significant") + ".")
    mag = getattr(res, "magnetometer", None)
    if mag is not None:  # the magnetometer's own loop (report.json "magnetometer"): its findings in words
        lines.append(
            "Magnetometer: "
            + (
                " ".join(f"({i + 1}) {_short(f.trace)}." for i, f in enumerate(mag.found))
                or "found nothing beyond the declared model."
            )
            + (
                f" {len(mag.disturbances)} local disturbance(s) left as unexplained structure."
                if mag.disturbances
                else ""
            )
        )
    if _is_time_series(res):
        n = len(res.unexplained.spectral_lines)
        lines.append(
            f"Right: per found effect, the held-out residual ({unit}) binned against what it follows (grey "
            f"wide bars: declared model, coloured narrow bars: after the loop); below, the residual's amplitude "
            f"spectrum (°/s/√Hz against Hz), before and after"
            f"{f', {n} unexplained line(s) in red' if n else ' (no unexplained line)'}."
        )
    return "\n".join(lines)


def closeloop_blueprint(res: CloseloopResult, span: Span, y_range: tuple[float, float] | None,
                        regressors: dict[str, str], has_spectrum: bool) -> rrb.Blueprint:
    """Story; per axis residual before/after overlaid (one shared y range); residual vs each found
    effect's regressor (``regressors``: effect → what it follows, in words); the spectrum with the
    unexplained lines."""
    if not _has_rows(res):
        return story_blueprint(rrb.TextDocumentView(origin="closeloop/notes", name="notes"), story_share=3.0,
                               body_share=1.0)
    _, unit = _scale(res)
    axes = rrb.Vertical(
        *[
            series_view(
                "closeloop",
                f"residual {a} ({unit}): declared (grey) vs after the loop (blue)",
                span,
                y_range=y_range,
                contents=[f"closeloop/residual_before/{a}", f"closeloop/residual_after/{a}", f"marks/held_out/{a}"],
            )
            for a in AXES
        ]
    )
    right = []
    for effect in regressors:
        right.append(rrb.Horizontal(*[rrb.BarChartView(
            origin=f"closeloop/vs/{effect}/{a}", name=f"{a} vs {regressors[effect]}",
            plot_legend=rrb.PlotLegend(visible=False)) for a in AXES], name=effect))
    if has_spectrum:
        right.append(rrb.Horizontal(*[rrb.BarChartView(
            origin=f"closeloop/spectrum/{a}", name=f"{a} spectrum (°/s/√Hz vs Hz)",
            plot_legend=rrb.PlotLegend(visible=False)) for a in AXES], name="spectrum"))
    if not right:
        right.append(rrb.TextDocumentView(origin="closeloop/notes", name="no effect found, no spectrum"))
    return story_blueprint(rrb.Horizontal(axes, rrb.Vertical(*right), column_shares=[3, 2]), story_share=1.0,
                           body_share=4.0)


def write_closeloop_rrd(
    res: CloseloopResult, path: str | Path, application_id: str = "gyrosim_calib_closeloop"
) -> Path:
    """Write ``closeloop.rrd`` (module docstring) for ``res``; a result with no reference still gets
    its story and a sensible (text) view."""
    path = Path(path)
    stream = rr.RecordingStream(application_id)
    stream.save(str(path))
    scale, _ = _scale(res)
    log_story(stream, closeloop_story(res))
    notes = "\n".join(f"- {n}" for n in res.notes) or "—"
    stream.log("closeloop/notes", rr.TextDocument("### Notes\n" + notes, media_type=rr.MediaType.MARKDOWN), static=True)
    if not _has_rows(res):
        stream.send_blueprint(closeloop_blueprint(res, Span(0.0, 1.0), None, {}, False))
        stream.flush()
        return path
    span = Span.of(res.row_time_s)
    y_range = shared_range(res.residual_before * scale, res.residual_after * scale, quantile=0.001)
    held = res.held_out_rows if res.held_out_rows is not None else np.zeros(res.row_axis.size, bool)
    for name, r, colour in (("before", res.residual_before, BEFORE), ("after", res.residual_after, AFTER)):
        for a in range(3):
            m = res.row_axis == a
            if not m.any():
                continue
            p = f"closeloop/residual_{name}/{AXES[a]}"
            scalar_style(stream, p, "declared model" if name == "before" else "after the loop", colour, width=1.0)
            send_series(stream, p, res.row_time_s[m], r[m] * scale)
            level = y_range[1] - 0.04 * (y_range[1] - y_range[0])
            if name == "before":
                log_marks(
                    stream,
                    f"marks/held_out/{AXES[a]}",
                    span,
                    level,
                    intervals=_intervals(res.row_time_s[m & held]),
                    name="held out",
                    colour=MARK_COLOURS["held_out"],
                    points_per_span=300,
                )
    regressors: dict[str, str] = {}
    if res.rows_of is not None:
        for f in res.found:
            series = res.follows_series.get(f.effect)
            if series is None:
                continue
            reg = res.rows_of(np.asarray(series, float))
            regressors[f.effect] = str(f.evidence.get("follows", f"the regressor of {f.effect}"))
            for a in range(3):
                m = (res.row_axis == a) & held
                if m.sum() < 10:
                    continue
                for name, r, colour, w in (("before", res.residual_before, BEFORE, 0.9),
                                           ("after", res.residual_after, AXIS_COLOURS[AXES[a]], 0.45)):
                    x, y, width = _binned(reg[m], r[m] * scale)
                    log_bars(stream, f"closeloop/vs/{f.effect}/{AXES[a]}/{name}", x, y, width * w, colour)
    has_spectrum = False
    if _is_time_series(res):
        t0 = res.row_time_s[res.row_axis == 0]
        n = min(int((res.row_axis == a).sum()) for a in range(3))
        if n >= 64:
            fs = 1.0 / float(np.median(np.diff(t0)))
            for name, r, w in (("before", res.residual_before, 0.9), ("after", res.residual_after, 0.45)):
                blocks = np.stack([r[res.row_axis == a][:n] for a in range(3)], axis=1) * RAD2DEG
                f, asd = _spectrum(blocks, fs)
                df = float(f[1] - f[0]) if f.size > 1 else 1.0
                for a in range(3):
                    colour = AXIS_COLOURS[AXES[a]] if name == "after" else BEFORE
                    log_bars(
                        stream, f"closeloop/spectrum/{AXES[a]}/{name}", f, asd[:, a], np.full(f.size, w * df), colour
                    )
            for a in AXES:  # the unexplained lines, on the spectrum after the loop
                lines = [l for l in res.unexplained.spectral_lines if l.axis == a]
                if lines:
                    fl = np.array([l.frequency_hz for l in lines])
                    log_bars(stream, f"closeloop/spectrum/{a}/unexplained", fl, np.interp(fl, f, asd[:, AXES.index(a)]),
                          np.full(fl.size, 2.0 * df), MARK_COLOURS["event"])
            has_spectrum = True
    stream.send_blueprint(closeloop_blueprint(res, span, y_range, regressors, has_spectrum))
    stream.flush()
    return path
