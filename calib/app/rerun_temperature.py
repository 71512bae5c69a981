"""The temperature comparison as a rerun recording (``calib temperature --rrd``).

A static board in a thermal chamber: the gyro output is its bias b(T, Ṫ) plus noise, so what a person
wants to see is the drift with temperature before compensation and what each model leaves of it on
the cycles it was not trained on.  Entities (timeline ``sensor_time``, s):

* ``chamber/temperature``: the sensor's temperature (°C, 10 s means); ``chamber/held_out``: the held-out cycles;
* ``temperature/raw/{x,y,z}``: 10 s means of the gyro minus the training mean (°/h): the drift an
  uncompensated (one-temperature) calibration leaves;
* ``temperature/residual/{x,y,z}/{method}``: 10 s means of gyro − b̂ for each fitted model (°/h);
* ``temperature/vs_temp/{x,y,z}/{raw,model}``: bar charts of the 10 s means against temperature
  (1 °C bins): the measured bias (grey) and the best model's b̂ (colour).

Blueprint: story on top; temperature and raw drift (whole recording); one view per axis with every
model's residual on one y range shared by the three axes; bias against temperature per axis.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from gyrosim.recording import Recording
from gyrosim.units import RAD_S_TO_DEG_H as DEG_H
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

from calib.temperature.compensation import Metrics, ThermalCompensation
from calib.temperature.timeblocks import block_means, time_block_index

__all__ = ["temperature_blueprint", "temperature_story", "save_temperature_rrd"]

AXES = "xyz"
BLOCK_S = 10.0
METHOD_COLOURS = [(220, 60, 50), (40, 160, 70), (40, 90, 220), (200, 130, 20), (150, 60, 200), (20, 170, 170),
                  (120, 120, 120)]


def _segment(name: str) -> str:
    """A method's name as one entity-path segment ("polynomial+dT/dt" → "polynomial+dT_dt")."""
    return re.sub(r"[^A-Za-z0-9_+.-]", "_", name)


def _blocks(t: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """10 s block means of t and y (blocks with no sample dropped)."""
    idx = time_block_index(t, BLOCK_S)
    tb, counts = block_means(idx, np.asarray(t, float))
    yb, _ = block_means(idx, np.asarray(y, float))
    keep = counts > 0
    return tb[keep], yb[keep]


def temperature_story(rows: list[Metrics], held_out: list[tuple[float, float]], train_desc: str) -> str:
    """The comparison in one paragraph: the best model, how much better than none, per method BS."""
    def when(a: float, b: float) -> str:
        return f"{a / 3600:.1f}–{b / 3600:.1f} h" if b - a > 3 * 3600 else f"{a:.0f}–{b:.0f} s"

    lines = [f"**Temperature models compared on held-out data** — trained on {train_desc}; "
             f"held out: {', '.join(when(a, b) for a, b in held_out) or 'the whole recording'}.", ""]
    if not rows:
        return "\n".join(lines + ["No model was fitted."])
    base = next((r for r in rows if r.method == "none"), rows[0])
    best = min(rows, key=lambda r: r.bias_stability_deg_h)
    lines.append(
        f"Best: **{best.method}**, bias stability {best.bias_stability_deg_h:.2f} °/h against "
        f"{base.bias_stability_deg_h:.2f} °/h uncompensated "
        f"(×{base.bias_stability_deg_h / best.bias_stability_deg_h:.1f} "
        f"better; held-out RMS {best.held_out_rms_deg_s:.4f} °/s). All: "
        + "; ".join(f"{r.method} {r.bias_stability_deg_h:.2f} °/h" for r in rows)
        + "."
    )
    lines.append("Left: the temperature (held-out cycles marked) and the uncompensated drift. Middle: what each model "
                 "leaves, 10 s means, one y scale for the three axes. Right: bias against temperature, measured "
                 "(grey) and the best model (colour).")
    return "\n".join(lines)


def temperature_blueprint(span: Span, methods: list[str], residual_range: tuple[float, float] | None,
                          raw_range: tuple[float, float] | None) -> rrb.Blueprint:
    """The viewer layout of the comparison (module docstring): the story on top; the temperature and raw
    drift, the models' residuals per axis on the shared ``residual_range`` (°/h), and bias against
    temperature per axis side by side."""
    left = rrb.Vertical(
        series_view("chamber", "sensor temperature (°C), held-out cycles ●", span),
        series_view("temperature/raw", "uncompensated drift, 10 s means (°/h)", span, y_range=raw_range),
    )
    middle = rrb.Vertical(*[series_view(f"temperature/residual/{a}", f"{a}: residual of each model (°/h)", span,
                                        y_range=residual_range) for a in AXES])
    right = rrb.Vertical(*[rrb.BarChartView(origin=f"temperature/vs_temp/{a}", name=f"{a}: bias (°/h) vs temperature "
                                                                                    "(°C)",
                                            plot_legend=rrb.PlotLegend(visible=False)) for a in AXES])
    return story_blueprint(
        rrb.Horizontal(left, middle, right, column_shares=[2, 3, 2]), story_share=1.0, body_share=5.0
    )


def save_temperature_rrd(path: str | Path, rec: Recording, fitted: dict[str, ThermalCompensation], rows: list[Metrics],
                         held_out: list[tuple[float, float]], train_desc: str,
                         application_id: str = "gyrosim_calib_temperature") -> Path:
    """Write the comparison (module docstring) for the static chamber recording ``rec``; ``fitted``
    the models (name → model, trained elsewhere), ``rows`` their held-out metrics, ``held_out`` the
    held-out time spans of ``rec`` (s)."""
    path = Path(path)
    stream = rr.RecordingStream(application_id)
    stream.save(str(path))
    span = Span.of(rec.t_s)
    temp = np.asarray(rec.temp_c, float)
    g = np.asarray(rec.gyro_rad_s, float)
    tb, raw = _blocks(rec.t_s, g - (fitted["none"].bias_rad_s(rec) if "none" in fitted else g.mean(axis=0)))
    raw = raw * DEG_H
    _, tblk = _blocks(rec.t_s, temp)
    residuals = {name: _blocks(rec.t_s, g - comp.bias_rad_s(rec))[1] * DEG_H
                 for name, comp in fitted.items() if name != "none"}
    res_range = shared_range(*residuals.values(), quantile=0.002) if residuals else None
    # the blueprint first: a viewer that opens the file while it loads lays it out at once
    stream.send_blueprint(temperature_blueprint(span, list(residuals), res_range, shared_range(raw, quantile=0.0)))
    log_story(stream, temperature_story(rows, held_out, train_desc))
    scalar_style(stream, "chamber/temperature", "temperature (°C)", (200, 80, 30))
    send_series(stream, "chamber/temperature", tb, tblk)
    lo, hi = float(np.min(temp)), float(np.max(temp))
    log_marks(stream, "chamber/held_out", span, hi + 0.03 * max(hi - lo, 1.0), intervals=held_out, name="held out",
              colour=MARK_COLOURS["held_out"], points_per_span=300)
    for a in range(3):
        scalar_style(stream, f"temperature/raw/{AXES[a]}", AXES[a])
        send_series(stream, f"temperature/raw/{AXES[a]}", tb, raw[:, a])
    for k, (name, comp) in enumerate(fitted.items()):
        if name in residuals:
            for a in range(3):
                p = f"temperature/residual/{AXES[a]}/{_segment(name)}"
                scalar_style(stream, p, name, METHOD_COLOURS[k % len(METHOD_COLOURS)])
                send_series(stream, p, tb, residuals[name][:, a])
    best = min((r for r in rows if r.method in residuals), key=lambda r: r.bias_stability_deg_h, default=None)
    _, gblk = _blocks(rec.t_s, g * DEG_H)
    edges = np.arange(math.floor(lo), math.ceil(hi) + 1.0, 1.0)
    if edges.size >= 2:
        idx = np.clip(np.searchsorted(edges, tblk, side="right") - 1, 0, edges.size - 2)
        cnt = np.bincount(idx, minlength=edges.size - 1)
        keep = cnt > 0
        centre = 0.5 * (edges[:-1] + edges[1:])[keep]
        model = None if best is None else _blocks(rec.t_s, fitted[best.method].bias_rad_s(rec) * DEG_H)[1]
        for a in range(3):
            mean = (np.bincount(idx, gblk[:, a], edges.size - 1) / np.maximum(cnt, 1))[keep]
            log_bars(stream, f"temperature/vs_temp/{AXES[a]}/measured", centre, mean, 0.9, (150, 150, 150))
            if model is not None:
                mm = (np.bincount(idx, model[:, a], edges.size - 1) / np.maximum(cnt, 1))[keep]
                log_bars(stream, f"temperature/vs_temp/{AXES[a]}/{_segment(best.method)}", centre, mm, 0.4,
                         METHOD_COLOURS[list(fitted).index(best.method) % len(METHOD_COLOURS)])
    stream.flush()
    return path
