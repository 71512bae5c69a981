"""Session report (Markdown + JSON + PNG): what the hand did, what the sensor was, what the
calibration found, and how far from the truth it is when the truth is known."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from gyrosim.outputs import write_json_atomic
from gyrosim.recording import Recording

from calib.session.defaults import method_label

__all__ = ["write_session_report", "plot_convergence"]


def import_plotting():
    """matplotlib's pyplot on its file backend (Agg), imported on first use: ~1 s, which the demo spends while the
    filter compiles instead of after it."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_convergence(result, truth: dict | None, path: Path) -> Path:
    """Estimates and ±√P of S and G over time (PNG): the picture of Zhou 2020 Figs. 2–3."""
    plt = import_plotting()

    h = result.history.arrays()
    t, sd = h["t_s"], np.sqrt(h["p_diag"])
    fig, axes = plt.subplots(2, 2, figsize=(11, 6), sharex=True)
    for row, (name, key, cols) in enumerate(
        (("scale factor S", "scale", slice(3, 6)), ("non-orthogonality G", "nonorthogonality", slice(6, 9)))
    ):
        est = h[key]
        for i, c in enumerate("xyz"):
            axes[row, 0].plot(t, est[:, i], label=f"{c}")
            if truth is not None:
                tv = truth["scale_factor" if key == "scale" else "nonorthogonality"][i]
                axes[row, 0].axhline(tv, color=f"C{i}", ls="--", lw=0.8)
            axes[row, 1].semilogy(t, sd[:, cols][:, i], label=c)
        axes[row, 0].set_ylabel(name)
        axes[row, 1].set_ylabel(f"√P {name.split()[-1]}")
        axes[row, 0].legend(fontsize=8)
    for ax in axes[-1]:
        ax.set_xlabel("t (s)")
    fig.suptitle(f"{method_label(result.method)}: estimates (dashed: truth) and √P")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def write_session_report(out: Path, rec: Recording, result, truth: dict | None, *, schedule, hand, sensor, seed: int,
                         validation=None) -> Path:
    """Write ``report.md``, ``report.json`` and ``convergence.png`` into ``out``."""
    expected = hand.expected_disturbance(schedule)
    t = rec.truth
    ext, rate = t.disturbance_rms() if t is not None else (float("nan"), float("nan"))
    cal = result.to_dict()
    report: dict[str, Any] = {
        "recording": "session.h5",
        "schedule": schedule.name,
        "hand": hand.name,
        "sensor": sensor.name,
        "seed": seed,
        "rate_hz": rec.rate_hz,
        "duration_s": rec.duration_s,
        "external_acc_rms_m_s2": {"measured": ext, "expected": expected["external_acc_rms_m_s2"]},
        "rate_disturbance_rms_rad_s": {"measured": rate, "expected": expected["rate_disturbance_rms_rad_s"]},
        "calibration": cal,
    }
    if truth is not None:
        report["truth"] = {k: v.tolist() for k, v in truth.items()}
    write_json_atomic(out / "report.json", report)
    png = plot_convergence(result, truth, out / "convergence.png")
    g = cal["gyro"]
    lines = [
        f"# Hand-held calibration session: {schedule.name}, hand `{hand.name}`, sensor `{sensor.name}`, seed {seed}",
        "",
        f"{rec.n} samples at {rec.rate_hz:g} Hz ({rec.duration_s:.1f} s) simulated in MuJoCo (`session.h5`), "
        "calibrated with "
        f"the {method_label(result.method)} (method `{result.method}`). Open `session.rrd` with `rerun session.rrd` "
        "to watch P converge.",
        "",
        "## What the hand did",
        "",
        "| disturbance at the IMU (RMS) | measured | expected from the hand preset |",
        "|---|---|---|",
        f"| external acceleration (m/s²) | {ext:.4f} | {expected['external_acc_rms_m_s2']:.4f} |",
        f"| rate disturbance (°/s) | {math.degrees(rate):.3f} | "
        f"{math.degrees(expected['rate_disturbance_rms_rad_s']):.3f} |",
        "",
        "## What the calibration found",
        "",
        "| parameter | axis | estimate | 1σ | truth | error / σ |",
        "|---|---|---|---|---|---|",
    ]
    for label, key, scale in (("bias (°/s)", "bias_rad_s", 180 / math.pi), ("scale factor", "scale_factor", 1.0),
                              ("non-orthogonality", "nonorthogonality", 1.0)):
        for i, ax in enumerate("xyz"):
            est, sd = g[key][i] * scale, g["std"][key][i] * scale
            tv = truth[key][i] * scale if truth is not None else float("nan")
            z = (est - tv) / sd if truth is not None and sd > 0 else float("nan")
            lines.append(f"| {label} | {ax} | {est:+.5f} | {sd:.5f} | {tv:+.5f} | {z:+.1f} |")
    lines += ["", f"Rest segments (s): {cal['rest_segments']}", ""]
    lines += [f"- warning: {w}" for w in cal["warnings"]] or ["No warnings."]
    lines += ["", f"![convergence]({png.name})", ""]
    if validation is not None:
        lines += [
            "## Attitude validation (Zhou 2020 §5.2, Table 12)",
            "",
            "The same device turns freely for 70 s (schedule `freestyle`); the gyro is integrated from the true "
            "initial attitude with the bias removed only, and fully compensated, and compared with the truth:",
            "",
            validation.table(),
            "",
        ]
        report["attitude_validation_deg"] = {
            "without": {"mean": validation.without_mean_deg.tolist(), "rms": validation.without_rms_deg.tolist()},
            "with": {"mean": validation.with_mean_deg.tolist(), "rms": validation.with_rms_deg.tolist()},
            "order": ["roll", "pitch", "heading"],
        }
        write_json_atomic(out / "report.json", report)
    path = out / "report.md"
    path.write_text("\n".join(lines))
    return path
