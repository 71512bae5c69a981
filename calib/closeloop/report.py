"""Write a closeloop result: ``report.json``, ``report.md`` with plots, and ``closeloop.rrd``.

report.json keys (a promise to scripts): ``declared``, ``found`` (list of {``effect``, ``params``,
``evidence``, ``model``, ``trace``}), ``unexplained``, ``error_before``, ``error_after`` (both on
held-out rows), plus ``reference``, ``notes``, ``not_tested`` (kind → why: not buildable, not
identifiable, or refused by the acceptance), ``not_distinguished`` (confounded groups: ``round``,
``chosen``, ``rivals``, ``why``, ``members`` with each one's evidence, ``rule``, ``separate_by``),
``checks``, ``rounds`` (every candidate's held-out score per round), ``metrics`` (every held-out
metric, declared → after the loop, with its noise z), ``rejected`` (additions refused by the
acceptance, with their metrics), ``disagreements``, ``tested`` (candidates that passed the
identifiability gate), ``identifiability`` (the gate's verdict per candidate and round) and
``recording``; with a magnetometer channel also ``magnetometer`` (the same keys for the
magnetometer's own loop, :mod:`calib.closeloop.mag.loop`; ``unexplained.disturbances`` lists local
anomalies).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from gyrosim.recording import Recording
from gyrosim.units import RAD2DEG

from calib.closeloop.loop import CloseloopResult
from calib.closeloop.mag.loop import MagLoopResult

__all__ = ["write_closeloop_report"]

AXES = "xyz"


def _clean(o):
    if isinstance(o, dict):
        return {str(k): _clean(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_clean(v) for v in o]
    if isinstance(o, np.ndarray):
        return _clean(o.tolist())
    if isinstance(o, (np.floating, float)):
        return float(o) if math.isfinite(o) else None
    if isinstance(o, np.integer):
        return int(o)
    return o


def _row_scale(res: CloseloopResult) -> tuple[float, str]:
    return (RAD2DEG, "°/s") if res.reference in ("truth", "optical", "static") else (1.0, "weighted")


def _plot_residual_time(res: CloseloopResult, path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scale, unit = _row_scale(res)
    fig, axes = plt.subplots(3, 1, figsize=(10, 7), sharex=True)
    held = res.held_out_rows
    for a, ax in enumerate(axes):
        m = (res.row_axis == a) & held
        t = res.row_time_s[m]
        ax.plot(t, res.residual_before[m] * scale, ".", ms=1.5, alpha=0.5, label="declared model")
        ax.plot(t, res.residual_after[m] * scale, ".", ms=1.5, alpha=0.5, label="after the loop")
        ax.set_ylabel(f"{AXES[a]} residual ({unit})")
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right", markerscale=6)
    axes[0].set_title("held-out residual before and after the loop")
    axes[-1].set_xlabel("time (s)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _plot_vs_regressor(res: CloseloopResult, rows_of, effect: str, series: np.ndarray, path: Path) -> Path:
    """Held-out residual before/after vs the signal the effect follows, binned means per axis."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scale, unit = _row_scale(res)
    reg = rows_of(np.asarray(series, float))
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.6))
    for a, ax in enumerate(axes):
        m = (res.row_axis == a) & res.held_out_rows
        x = reg[m]
        for r, lab in ((res.residual_before[m], "declared"), (res.residual_after[m], "after")):
            edges = np.quantile(x, np.linspace(0, 1, 31))
            idx = np.clip(np.searchsorted(edges, x) - 1, 0, 29)
            cnt = np.bincount(idx, minlength=30)
            mean = np.bincount(idx, r, 30) / np.maximum(cnt, 1)
            centre = 0.5 * (edges[:-1] + edges[1:])
            ax.plot(centre[cnt > 0], mean[cnt > 0] * scale, "o-", ms=3, label=lab)
        ax.set_title(f"axis {AXES[a]}")
        ax.set_xlabel(f"regressor of {effect}")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel(f"binned residual ({unit})")
    axes[0].legend()
    fig.suptitle(f"residual vs what {effect} follows (held-out rows)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _write_rrd(res: CloseloopResult, path: Path) -> Path:
    """closeloop.rrd with its designed blueprint (:mod:`calib.closeloop.rrd`)."""
    from calib.closeloop.rrd import write_closeloop_rrd

    return write_closeloop_rrd(res, path)


def write_closeloop_report(out: str | Path, rec: Recording, res: CloseloopResult) -> dict[str, Path]:
    """Write report.json, report.md (+ PNG plots) and closeloop.rrd into ``out``; returns their paths."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    paths: dict[str, Path] = {}
    data = res.to_json_dict()
    data["recording"] = {"samples": int(rec.t_s.size), "duration_s": float(rec.t_s[-1] - rec.t_s[0]),
                         "source": rec.meta.get("source", rec.meta.get("dataset", "")),
                         "licence": rec.meta.get("licence", "")}
    paths["json"] = out / "report.json"
    paths["json"].write_text(json.dumps(_clean(data), indent=2, ensure_ascii=False))
    plots = []
    if res.residual_before is not None and res.reference != "none":
        plots.append(_plot_residual_time(res, out / "residual_time.png"))
        if res.rows_of is not None:
            for f in res.found:
                series = res.follows_series.get(f.effect)
                if series is not None:
                    plots.append(
                        _plot_vs_regressor(res, res.rows_of, f.effect, series, out / f"residual_vs_{f.effect}.png")
                    )
    # written for every result: with no reference it opens on the text saying why nothing was analysed
    paths["rrd"] = _write_rrd(res, out / "closeloop.rrd")
    paths["md"] = out / "report.md"
    paths["md"].write_text(_markdown(res, data["recording"], plots))
    return paths


def mag_markdown(m: MagLoopResult) -> list[str]:
    """The magnetometer section of report.md (:class:`calib.closeloop.mag.loop.MagLoopResult`)."""
    lines = ["", "## Magnetometer", "", f"Reference: **{m.reference}** — {m.reference_description}.",
             f"Declared magnetometer model: {', '.join(m.declared) or 'none (the output taken as calibrated)'}.", ""]
    lines += [f"{i + 1}. {f.trace}" for i, f in enumerate(m.found)] or [
        f"Nothing added (tested: {', '.join(m.tested) or 'none'})."]
    if m.error_before:
        lines += ["", "| held-out metric | declared | after the loop |", "|---|---|---|"]
        lines += [f"| {k} | {v:.4g} | {m.error_after.get(k, float('nan')):.4g} |" for k, v in m.error_before.items()]
    lines += ["", f"Unexplained structure: {m.unexplained.summary if m.unexplained.analysed else '—'}"]
    lines += [f"- not tested: {k}: {v}" for k, v in m.not_tested.items()]
    lines += [f"- refused: round {r.round}: {r.effect} — {r.why}" for r in m.rejected]
    lines += [
        f"- confounded: round {g.round}: {g.chosen} vs {', '.join(g.rivals)} — {g.why}" for g in m.not_distinguished
    ]
    lines += [f"- note: {n}" for n in m.notes]
    return lines


def _fmt_err(e: dict) -> str:
    return ", ".join(f"{k} = {v:.4g}" if isinstance(v, float) else f"{k} = {v}" for k, v in e.items()) or "—"


def _markdown(res: CloseloopResult, recinfo: dict, plots: list[Path]) -> str:
    lines = [
        "# Close-the-loop report",
        "",
        f"Recording: {recinfo['source'] or '(unnamed)'} — {recinfo['samples']} samples, {recinfo['duration_s']:.1f} s.",
        f"Reference: **{res.reference}** — {res.reference_description}.",
        "",
        f"Declared model: {', '.join(res.declared)}.",
        "",
        "## What the residual says",
        "",
    ]
    if res.found:
        lines += [f"{i + 1}. {f.trace}" for i, f in enumerate(res.found)]
    elif not res.tested:
        lines.append("Nothing could be tested on this recording: no candidate is identifiable here. Why, for each "
                     "(see also \"Not tested\"):")
        lines += [f"- {k}: {v}" for k, v in res.not_tested.items()]
    else:
        lines.append(f"Nothing: no candidate explains a significant part of the held-out residual (tested: "
                     f"{', '.join(res.tested)}).")
    lines += ["", f"## Error on held-out data ({res.error_before.get('unit', '')} unless named)", "",
              "| | before (declared) | after the loop |", "|---|---|---|"]
    for k in [k for k in res.error_before if k != "unit"]:
        b, a = res.error_before.get(k), res.error_after.get(k, "—")
        fb = f"{b:.4g}" if isinstance(b, float) else str(b)
        fa = f"{a:.4g}" if isinstance(a, float) else str(a)
        lines.append(f"| {k} | {fb} | {fa} |")
    lines += ["", "## Structure no candidate explains", "", res.unexplained.summary, ""]
    for l in res.unexplained.spectral_lines[:5]:
        lines.append(f"- line at {l.frequency_hz:.2f} Hz on {l.axis}: amplitude {l.amplitude_rad_s * RAD2DEG:.3g} °/s "
                     f"({l.ratio:.1f}× background, threshold {l.threshold:.1f})")
    for c in res.unexplained.channel_correlations[:5]:
        lines.append(f"- residual {c.axis} vs {c.channel}: ρ = {c.rho:.3f} ({c.z:.1f}σ, threshold {c.threshold:.1f})")
    if res.metrics:
        lines += ["", "## Every held-out metric, declared → after the loop", "",
                  "| metric | declared | after | change | z (noise) | verdict |", "|---|---|---|---|---|---|"]
        lines += [f"| {m.name} ({m.unit}) | {m.before:.4g} | {m.after:.4g} | {m.relative_change:+.1%} | {m.z:+.1f} | "
                  f"{m.verdict} |" for m in res.metrics]
    if res.disagreements:
        lines += ["", "## Metrics that disagree", ""] + [f"- {d}" for d in res.disagreements]
    if res.rejected:
        lines += ["", "## Additions refused (a held-out metric got worse beyond its noise)", ""]
        lines += [f"- round {r.round}: {r.effect} — {r.why}" for r in res.rejected]
    if res.not_distinguished:
        lines += ["", "## Confounded (not distinguished)", ""]
        for g in res.not_distinguished:
            lines.append(f"- round {g.round}: {g.chosen} vs {', '.join(g.rivals)} — {g.why}. "
                         f"What would separate them: {g.separate_by}")
            lines += [f"  - {m.effect}: G = {m.gain:.1f}, explains {m.explained_fraction:.1%} alone, overlap with the "
                      f"best {m.overlap_with_best:.0%}, contribution correlation {m.contribution_correlation:.2f}"
                      for m in g.members]
    lines += ["", "## Not tested", ""] + [f"- {k}: {v}" for k, v in res.not_tested.items()]
    lines += [
        "",
        "## Candidate scores (round 1)",
        "",
        "| effect | held-out gain G | added parameters |",
        "|---|---|---|",
    ]
    for r in (res.rounds[0].scores if res.rounds else ()):
        lines.append(f"| {r.effect} | {r.gain:.1f} | {r.added_parameters} |" if r.gain is not None
                     else f"| {r.effect} | — | {r.added_parameters} |")
    lines += ["", "## Notes", ""] + [f"- {n}" for n in res.notes]
    lines.append(f"- quantization step per axis (rad/s): {res.checks.quantization_lsb}; saturated samples: "
                 f"{res.checks.saturated_samples}")
    if res.magnetometer is not None:
        lines += mag_markdown(res.magnetometer)
    if plots:
        lines += ["", "## Plots", ""] + [f"![{p.stem}]({p.name})" for p in plots]
    return "\n".join(lines) + "\n"
