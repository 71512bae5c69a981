"""Orientation estimators under test on the virtual hand: ``gyrosim campaign --orientation``.

A task is one simulated session (schedule × hand × severity × sensor × seed), simulated **once**
and shared by every estimator and variant:

* ``raw``: the recording as the sensor delivers it;
* ``calibrated``: the same recording compensated by ``calib``'s estimate from it (``kf_joint`` by
  default — ``calib run``'s method: gyro bias, scale, non-orthogonality and the accelerometer's),
  and for a 9-axis sensor the magnetometer by ``calib mag``'s ellipsoid fit.  The calibration sees
  the whole session, as a user who calibrates on the data they then process.

Both variants get the same **disturbance** near the end: a rate pulse the truth does not have
(``disturbance_deg_s`` about body x for ``disturbance_s``: a knock or a saturated gyro), which
throws every filter's tilt off by up to disturbance_deg_s × disturbance_s; its recovery is the
convergence time.  Scores (:mod:`gyrosim.attitude_errors`, BROAD's error decomposition) against
``/truth/quat``: tilt error RMS and heading (6-axis: drift rate °/min and RMS after removing the
start's offset; 9-axis: absolute heading RMS, after turning magnetic into geographic north by the
field's declination as a user would with the World Magnetic Model) over [settle, disturbance),
then the peak tilt and the convergence time after the disturbance.

Each estimator is run through :func:`gyrosim.orientation.run_orientation`: one that raises or
returns NaN or non-unit quaternions is a ``failed`` row with its message; the campaign goes on.
Results stream into ``orientation_results.csv``; a re-run skips tasks already complete.
"""

from __future__ import annotations

import csv
import json
import math
import os
import platform
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Callable

import numpy as np

from .errors import GyrosimError

__all__ = ["OrientationSpec", "OrientationTask", "make_tasks", "run_task", "run_orientation_campaign",
           "summarise_orientation", "ORIENTATION_COLUMNS", "SCORES"]

SCORES = ["tilt_rms_deg", "heading_rms_deg", "heading_drift_deg_min", "tilt_max_deg",
          "tilt_peak_after_disturbance_deg", "convergence_s"]
ORIENTATION_COLUMNS = (["task_id", "hand", "severity", "seed", "sensor", "schedule", "rate_hz", "variant", "estimator",
                        "axes", "status", "error", "ext_acc_rms_m_s2", "gyro_bias_max_deg_s", "calibration_status",
                        "estimator_seconds"] + SCORES)
RESULTS = "orientation_results.csv"
SUMMARY = "orientation_summary.csv"
VARIANTS = ("raw", "calibrated")


@dataclass(frozen=True)
class OrientationSpec:
    """What to run (see the module docstring); ``severity`` as in :class:`gyrosim.campaign.CampaignSpec`."""

    hands: tuple[str, ...] = ("ideal", "steady", "typical", "shaky")
    seeds: int = 50
    first_seed: int = 0
    sensor: str = "mpu9250"
    estimators: tuple[str, ...] = ("vqf", "madgwick", "mahony", "fusion")
    variants: tuple[str, ...] = VARIANTS
    calibration: str = "kf_joint"
    schedule: str = "zhou2020"
    rate_hz: float = 100.0
    severity: tuple[float, ...] = (1.0,)
    disturbance_deg_s: float = 60.0
    disturbance_s: float = 0.5
    disturbance_before_end_s: float = 25.0
    settle_s: float = 2.0
    align_s: float = 5.0
    name: str = "orientation"

    def validate(self) -> None:
        from .campaign import validate_session_grid
        from .estimator import load_estimator
        from .orientation import load_orientation_estimator

        bad = set(self.variants) - set(VARIANTS)
        if bad or not self.variants:
            raise GyrosimError(f"variants must be among {VARIANTS}, got {self.variants}")
        sensor = validate_session_grid(self, "an orientation campaign")
        for e in self.estimators:  # a missing optional package is named here, before any work
            load_orientation_estimator(e)
        if any(e.endswith("_9d") for e in self.estimators) and not sensor.magnetometer:
            raise GyrosimError(f"9-axis estimators need a sensor with a magnetometer; {self.sensor!r} has none "
                               "(use e.g. --sensor mpu9250_9axis)")
        if "calibrated" in self.variants:
            load_estimator(self.calibration)


@dataclass(frozen=True)
class OrientationTask:
    """One session of an orientation campaign: the hand at a severity and a seed, under the campaign's
    spec; ``task_id`` is ``hand|severity|seed``."""

    task_id: str
    hand: str
    severity: float
    seed: int
    spec: OrientationSpec


def make_tasks(spec: OrientationSpec) -> list[OrientationTask]:
    """The campaign's sessions: one :class:`OrientationTask` per hand × severity × seed, in that order."""
    return [
        OrientationTask(f"{h}|{sev:g}|{seed}", h, float(sev), seed, spec)
        for h in spec.hands
        for sev in spec.severity
        for seed in range(spec.first_seed, spec.first_seed + spec.seeds)
    ]


def _calibrated(rec, spec: OrientationSpec):
    """The recording compensated by calib's estimate from it (and the magnetometer's, 9-axis)."""
    from .estimator import as_user_file, load_estimator

    cal = load_estimator(spec.calibration)(as_user_file(rec))  # the estimator sees a user's file
    out = cal.compensate(rec)
    if rec.mag_ut is not None:  # calib's ellipsoid fit, found by entry point (gyrosim does not import calib)
        from .plugins import load

        calibrate_magnetometer = load("gyrosim.magnetometer_calibrators", "ellipsoid", what="magnetometer calibration")
        out = calibrate_magnetometer(as_user_file(out)).compensate_recording(out)  # it, too, sees a user's file
    return out, cal.status


def _disturb(rec, spec: OrientationSpec, q_true: np.ndarray) -> tuple[object, float, float]:
    """``rec`` with the rate pulse added to the gyro; returns it and the pulse's start and end (s).

    The pulse turns about the body axis closest to horizontal at its start (from the truth: the
    campaign's design, not information the estimator gets), so that the whole pulse is tilt."""
    from .rotations import quat_rotate

    t = rec.t_s
    t_d = float(t[-1]) - spec.disturbance_before_end_s
    t_e = t_d + spec.disturbance_s
    k = int(np.searchsorted(t, t_d))
    up_in_body = quat_rotate(
        np.array([q_true[k, 0], -q_true[k, 1], -q_true[k, 2], -q_true[k, 3]]), np.array([0.0, 0.0, 1.0])
    )
    axis = int(np.argmin(np.abs(up_in_body)))
    pulse = np.zeros_like(rec.gyro_rad_s)
    pulse[(t >= t_d) & (t < t_e), axis] = math.radians(spec.disturbance_deg_s)
    return rec.with_signals(gyro_rad_s=rec.gyro_rad_s + pulse), t_d, t_e


def declination_rad(rec) -> float:
    """The magnetic declination of the session's field (east of north positive): atan2(B_E, B_N) of
    the true field (``/truth/mag_field``, body) turned into ENU by the true attitude, averaged.  A
    9-axis filter can only find magnetic north; a user corrects it with their location's declination
    (World Magnetic Model), and so does the scoring: q ← q_z(−D) ⊗ q."""
    from .rotations import quat_rotate

    b = quat_rotate(rec.truth.quat_nb, rec.truth.extra["mag_field"]).mean(axis=0)
    return math.atan2(float(b[0]), float(b[1]))


def to_geographic(q: np.ndarray, declination: float) -> np.ndarray:
    from .rotations import quat_multiply

    return quat_multiply(np.array([math.cos(-declination / 2), 0.0, 0.0, math.sin(-declination / 2)]), q)


def run_task(task: OrientationTask) -> list[dict]:
    """Simulate once; calibrate once; every estimator on every variant; score.  Failures are rows."""
    from .attitude_errors import score_session
    from .campaign import _scaled_hand
    from .orientation import OrientationFailure, load_orientation_estimator, run_orientation
    from .sensor_model import load_sensor
    from .simulate import simulate

    spec = task.spec
    base = {"task_id": task.task_id, "hand": task.hand, "severity": task.severity, "seed": task.seed,
            "sensor": spec.sensor, "schedule": spec.schedule, "rate_hz": spec.rate_hz}
    pairs = [(v, e) for v in spec.variants for e in spec.estimators]
    try:
        rec = simulate(spec.schedule, _scaled_hand(task.hand, task.severity), load_sensor(spec.sensor), spec.rate_hz,
                       seed=task.seed, pipeline=False)
    except Exception as exc:  # noqa: BLE001 - a failed task is recorded, not lost
        return [{**base, "variant": v, "estimator": e, "status": "failed",
                 "error": f"simulation: {type(exc).__name__}: {exc}"} for v, e in pairs]
    from .calibration import truth_calibration

    truth = truth_calibration(rec)
    base["ext_acc_rms_m_s2"] = rec.truth.disturbance_rms()[0]
    base["gyro_bias_max_deg_s"] = math.degrees(float(np.max(np.abs(truth.bias_rad_s)))) if truth is not None else ""
    inputs: dict[str, tuple] = {}
    for v in spec.variants:
        if v == "raw":
            inputs[v] = (rec, "")
            continue
        try:
            cal_rec, status = _calibrated(rec, spec)
            inputs[v] = (cal_rec, status)
        except Exception as exc:  # noqa: BLE001
            inputs[v] = (None, f"calibration failed: {type(exc).__name__}: {exc}"[:300])
    rows = []
    estimators = {e: load_orientation_estimator(e) for e in spec.estimators}
    for v, e in pairs:
        src, cal_status = inputs[v]
        row = {**base, "variant": v, "estimator": e, "calibration_status": cal_status if src is not None else "failed"}
        if src is None:
            rows.append({**row, "status": "failed", "error": cal_status})
            continue
        disturbed, t_d, t_e = _disturb(src, spec, rec.truth.quat_nb)
        t1 = time.perf_counter()
        try:
            att = run_orientation(estimators[e], disturbed, e)
            q_est = to_geographic(att.quat_nb, declination_rad(rec)) if att.magnetometer else att.quat_nb
            sc = score_session(src.t_s, q_est, rec.truth.quat_nb, magnetometer=att.magnetometer,
                               settle_s=spec.settle_s, align_s=spec.align_s, disturbance_start_s=t_d,
                               disturbance_end_s=t_e)
            row.update({"status": "ok", "error": "", "axes": 9 if att.magnetometer else 6, **asdict(sc)})
        except OrientationFailure as exc:
            row.update({"status": "failed", "error": str(exc).replace("\n", " ")[:500]})
        row["estimator_seconds"] = time.perf_counter() - t1
        rows.append(row)
    return rows


def _read_done(path: Path) -> dict[str, list[dict]]:
    """Tasks whose rows are all in results (failed estimator rows count: they are results)."""
    from .campaign import read_rows

    done: dict[str, list[dict]] = {}
    for r in read_rows(path):
        done.setdefault(r["task_id"], []).append(r)
    return {k: v for k, v in done.items() if not any(r["error"].startswith("simulation:") for r in v)}


def run_orientation_campaign(spec: OrientationSpec, out: str | Path, *, scheduler: str | None = "local",
                             workers: int | None = None, connect_timeout_s: float = 10.0,
                             progress: Callable[[int, int], None] | None = None) -> Path:
    """Run every task not yet in ``out/orientation_results.csv``; returns its path."""
    from .campaign import run_tasks, write_rows

    spec.validate()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / RESULTS
    want = {(v, e) for v in spec.variants for e in spec.estimators}
    done = {k: v for k, v in _read_done(path).items() if {(r["variant"], r["estimator"]) for r in v} >= want}
    tasks = [t for t in make_tasks(spec) if t.task_id not in done]
    _write_provenance(out, spec, scheduler, workers)
    rows_all = [r for v in done.values() for r in v if (r["variant"], r["estimator"]) in want]
    order = {t.task_id: i for i, t in enumerate(make_tasks(spec))}

    def flush() -> None:
        rows_all.sort(key=lambda r: (order.get(r["task_id"], 1 << 30), r["variant"], r["estimator"]))
        write_rows(path, rows_all, ORIENTATION_COLUMNS)

    run_tasks(tasks, run_task, rows_all, flush, scheduler=scheduler, workers=workers,
              connect_timeout_s=connect_timeout_s, progress=progress, key_prefix="orientation")
    return path


def _write_provenance(out: Path, spec: OrientationSpec, scheduler, workers) -> None:
    from importlib import metadata

    from . import __version__

    versions = {"gyrosim": __version__, "numpy": np.__version__, "python": platform.python_version()}
    for pkg in ("vqf", "imufusion", "AHRS", "mujoco", "dask"):
        try:
            versions[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            pass
    prov = {"spec": asdict(spec), "scheduler": scheduler, "workers": workers, "versions": versions,
            "host": platform.node(), "cpu_count": os.cpu_count()}
    (out / "orientation_provenance.json").write_text(json.dumps(prov, indent=2))


def _mean_ci(x: np.ndarray) -> tuple[float, float, float]:
    """Mean with its 95 % t-interval."""
    from scipy import stats

    n = x.size
    m = float(np.mean(x))
    if n < 2:
        return m, float("nan"), float("nan")
    h = float(stats.t.ppf(0.975, n - 1) * np.std(x, ddof=1) / math.sqrt(n))
    return m, m - h, m + h


def _median_ci(x: np.ndarray) -> tuple[float, float, float]:
    """Median with its distribution-free 95 % interval (order statistics, binomial(n, ½))."""
    from scipy import stats

    x = np.sort(x)
    n = x.size
    if n == 0:
        return float("nan"), float("nan"), float("nan")
    lo = int(stats.binom.ppf(0.025, n, 0.5))
    hi = int(min(n - 1, stats.binom.isf(0.025, n, 0.5)))
    return float(np.median(x)), float(x[max(lo - 1, 0)]), float(x[hi])


def summarise_orientation(results: str | Path, out: str | Path | None = None) -> list[dict]:
    """Per (hand, severity, sensor, variant, estimator): failures (Wilson 95 %), tilt RMS and heading
    RMS (mean over sessions, t 95 %), heading drift rate (RMS over sessions, χ² 95 %), convergence
    (median, order-statistic 95 %; sessions that never converge count as +inf) and how many never
    converge.  Writes orientation_summary.csv and the plots when ``out`` is given."""
    from .campaign import _rms_ci, _wilson

    with Path(results).open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        groups.setdefault((r["hand"], float(r["severity"]), r["sensor"], r["variant"], r["estimator"]), []).append(r)
    summary = []
    for (hand, sev, sensor, variant, est), rs in groups.items():
        ok = [r for r in rs if r["status"] == "ok"]
        row = {"hand": hand, "severity": sev, "sensor": sensor, "variant": variant, "estimator": est, "n": len(rs),
               "failed": len(rs) - len(ok)}
        row["failed_lo"], row["failed_hi"] = _wilson(len(rs) - len(ok), len(rs))
        errors = sorted({r["error"][:160] for r in rs if r["status"] != "ok"})
        row["first_error"] = errors[0] if errors else ""
        if ok:
            f = {k: np.array([float(r[k]) for r in ok]) for k in SCORES}
            row["axes"] = int(float(ok[0]["axes"]))
            row["ext_acc_rms_m_s2"] = float(np.mean([float(r["ext_acc_rms_m_s2"]) for r in ok]))
            row["tilt_rms_deg"], row["tilt_rms_deg_lo"], row["tilt_rms_deg_hi"] = _mean_ci(f["tilt_rms_deg"])
            row["heading_rms_deg"], row["heading_rms_deg_lo"], row["heading_rms_deg_hi"] = _mean_ci(
                f["heading_rms_deg"]
            )
            row["drift_rms_deg_min"], row["drift_rms_deg_min_lo"], row["drift_rms_deg_min_hi"] = _rms_ci(
                f["heading_drift_deg_min"])
            conv = f["convergence_s"]
            row["convergence_s"], row["convergence_s_lo"], row["convergence_s_hi"] = _median_ci(conv)
            row["not_converged"] = int(np.sum(~np.isfinite(conv)))
            row["peak_tilt_deg"] = float(np.median(f["tilt_peak_after_disturbance_deg"]))
        summary.append(row)
    summary.sort(key=lambda r: (r["sensor"], r["estimator"], r["variant"], r.get("ext_acc_rms_m_s2", 0.0)))
    if out is not None:
        out = Path(out)
        keys = list(dict.fromkeys(k for r in summary for k in r))
        with (out / SUMMARY).open("w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=keys)
            w.writeheader()
            w.writerows(summary)
        plot_orientation(summary, out)
        (out / "orientation_summary.md").write_text(summary_markdown(summary))
        (out / "orientation_by_bias.md").write_text(drift_by_bias_markdown(drift_by_bias(results)))
    return summary


BIAS_BINS_DEG_S = (0.0, 1.0, 2.0, 3.0, math.inf)
BROKEN_DRIFT_DEG_MIN = 5.0


def drift_by_bias(results: str | Path) -> list[dict]:
    """6-axis heading drift against the device's largest gyro bias (°/s, from the truth), per
    variant and estimator: where a filter's own bias estimation stops coping.  A session counts as
    broken when |drift| > 5 °/min: four times the drift RMS calibrated sessions keep (the 0.02 °/s
    bias residual of the calibration, 1.2 °/min)."""
    with Path(results).open(newline="") as fh:
        rows = [r for r in csv.DictReader(fh) if r["status"] == "ok" and r["gyro_bias_max_deg_s"] not in ("", None)
                and r.get("axes") in ("6", "6.0")]
    out = []
    for key in sorted({(r["variant"], r["estimator"]) for r in rows}):
        rs = [r for r in rows if (r["variant"], r["estimator"]) == key]
        b = np.array([float(r["gyro_bias_max_deg_s"]) for r in rs])
        d = np.abs(np.array([float(r["heading_drift_deg_min"]) for r in rs]))
        for lo, hi in zip(BIAS_BINS_DEG_S[:-1], BIAS_BINS_DEG_S[1:]):
            m = (b >= lo) & (b < hi)
            if m.any():
                out.append({"variant": key[0], "estimator": key[1], "bias_lo_deg_s": lo, "bias_hi_deg_s": hi,
                            "n": int(m.sum()), "median_abs_drift_deg_min": float(np.median(d[m])),
                            "broken": int(np.sum(d[m] > BROKEN_DRIFT_DEG_MIN))})
    return out


def drift_by_bias_markdown(rows: list[dict]) -> str:
    lines = ["| estimator | variant | largest gyro bias of the device (°/s) | sessions | median \\|drift\\| °/min | "
             f"broken (\\|drift\\| > {BROKEN_DRIFT_DEG_MIN:g} °/min) |", "|---|---|---|---|---|---|"]
    for r in rows:
        hi = "∞" if math.isinf(r["bias_hi_deg_s"]) else f"{r['bias_hi_deg_s']:g}"
        lines.append(f"| `{r['estimator']}` | {r['variant']} | [{r['bias_lo_deg_s']:g}, {hi}) | {r['n']} | "
                     f"{r['median_abs_drift_deg_min']:.2f} | {r['broken']}/{r['n']} |")
    return "\n".join(lines) + "\n"


def summary_markdown(summary: list[dict]) -> str:
    """The summary as a markdown table (docs/orientation.md), one row per hand × variant × estimator."""
    nine = any(r.get("axes") == 9 for r in summary)
    head = "heading RMS ° [95 %]" if nine else "heading drift RMS °/min [95 %]"
    lines = [f"| estimator | hand (ext. acc. RMS) | variant | n | failed | tilt RMS ° [95 %] | {head} | "
             "convergence s, median [95 %] (never) |", "|---|---|---|---|---|---|---|---|"]
    for r in sorted(
        summary, key=lambda r: (r["estimator"], r.get("ext_acc_rms_m_s2", 0.0), r["hand"], r["variant"] != "raw")
    ):
        if "tilt_rms_deg" not in r:
            lines.append(
                f"| `{r['estimator']}` | {r['hand']} | {r['variant']} | {r['n']} | {r['failed']} | all failed: "
                f"{r['first_error'][:80]} | | |"
            )
            continue
        hk = "heading_rms_deg" if nine else "drift_rms_deg_min"
        lines.append(
            f"| `{r['estimator']}` | {r['hand']} ({r['ext_acc_rms_m_s2']:.3f} m/s²) | {r['variant']} | {r['n']} | "
            f"{r['failed']} | "
            f"{r['tilt_rms_deg']:.3g} [{r['tilt_rms_deg_lo']:.3g}, {r['tilt_rms_deg_hi']:.3g}] | "
            f"{r[hk]:.3g} [{r[hk + '_lo']:.3g}, {r[hk + '_hi']:.3g}] | "
            f"{r['convergence_s']:.3g} [{r['convergence_s_lo']:.3g}, {r['convergence_s_hi']:.3g}] "
            f"({r['not_converged']}) |"
        )
    return "\n".join(lines) + "\n"


def plot_orientation(summary: list[dict], out: Path) -> list[Path]:
    """``orientation_vs_severity.png``: tilt RMS, heading drift (or 9-axis heading RMS) and
    convergence against the hand's external acceleration, per estimator, raw dashed / calibrated
    solid; ``orientation_raw_vs_calibrated.png``: the same scores as bars per estimator and hand."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ok = [r for r in summary if "tilt_rms_deg" in r]
    nine = any(r.get("axes") == 9 for r in ok)
    head_key, head_label = (("heading_rms_deg", "heading error RMS (°)") if nine
                            else ("drift_rms_deg_min", "heading drift RMS over sessions (°/min)"))
    panels = [("tilt_rms_deg", "tilt error RMS (°)"), (head_key, head_label), ("convergence_s", "convergence after the "
                                                                                                "disturbance (s, "
                                                                                                "median)")]
    ests = sorted({r["estimator"] for r in ok})
    colors = {e: f"C{i}" for i, e in enumerate(ests)}
    fig, axes = plt.subplots(1, 3, figsize=(16, 4.5))
    for e in ests:
        for v, ls in (("raw", "--"), ("calibrated", "-")):
            rs = sorted(
                [r for r in ok if r["estimator"] == e and r["variant"] == v], key=lambda r: r["ext_acc_rms_m_s2"]
            )
            if not rs:
                continue
            x = np.array([r["ext_acc_rms_m_s2"] for r in rs])
            for ax, (k, label) in zip(axes, panels):
                y = np.array([r[k] for r in rs])
                lo = np.array([r[f"{k}_lo"] for r in rs])
                hi = np.array([r[f"{k}_hi"] for r in rs])
                hi = np.where(np.isfinite(hi), hi, y)
                ax.errorbar(x, y, yerr=[np.clip(y - lo, 0, None), np.clip(hi - y, 0, None)], ls=ls, marker="o",
                            capsize=3, color=colors[e], label=f"{e} ({v})")
                ax.set_xlabel("hand: external acceleration RMS (m/s²)")
                ax.set_ylabel(label)
                ax.set_yscale("log")
    for ax in axes:
        ax.grid(alpha=0.3, which="both")
    axes[0].legend(fontsize=7, ncol=2)
    fig.suptitle("orientation error vs hand imperfection (95 % intervals; dashed raw, solid calibrated with calib)")
    fig.tight_layout()
    p1 = out / "orientation_vs_severity.png"
    fig.savefig(p1, dpi=100)
    plt.close(fig)

    hands = list(dict.fromkeys(r["hand"] for r in sorted(ok, key=lambda r: r["ext_acc_rms_m_s2"])))
    fig, axes = plt.subplots(1, 2, figsize=(14, 4.5))
    width = 0.8 / max(1, 2 * len(ests))
    for ax, (k, label) in zip(axes, panels[:2]):
        for i, e in enumerate(ests):
            for j, v in enumerate(("raw", "calibrated")):
                ys = [next((r[k] for r in ok if r["estimator"] == e and r["variant"] == v and r["hand"] == h), np.nan)
                      for h in hands]
                pos = np.arange(len(hands)) + (2 * i + j) * width - 0.4
                ax.bar(pos, ys, width, color=colors[e], alpha=0.45 if v == "raw" else 1.0,
                       hatch="//" if v == "raw" else None, label=f"{e} {v}")
        ax.set_xticks(np.arange(len(hands)) - width / 2)
        ax.set_xticklabels(hands)
        ax.set_ylabel(label)
        ax.set_yscale("log")
        ax.grid(alpha=0.3, axis="y", which="both")
    axes[0].legend(fontsize=7, ncol=2)
    fig.suptitle("raw (hatched) vs calibrated with calib (solid)")
    fig.tight_layout()
    p2 = out / "orientation_raw_vs_calibrated.png"
    fig.savefig(p2, dpi=100)
    plt.close(fig)
    return [p1, p2]


def bench_throughput(sessions: int = 4, spec: OrientationSpec | None = None) -> dict:
    """In-process cost per session after a warm-up task (numba compile, imports): wall and CPU
    seconds (``time.process_time``: on a shared machine the wall clock measures the other users),
    split into the simulation + calibration and each estimator; and the same tasks with the raw
    variant only.  For extrapolating a campaign honestly (docs/orientation.md)."""
    spec = spec or OrientationSpec(hands=("typical",), seeds=sessions + 1)
    out = {"sessions": sessions}
    for label, variants in (("raw_and_calibrated", ("raw", "calibrated")), ("raw_only", ("raw",))):
        s = replace(spec, variants=variants, seeds=sessions + 1)
        tasks = make_tasks(s)
        run_task(tasks[0])
        w0, c0 = time.perf_counter(), time.process_time()
        rows = [r for t in tasks[1:] for r in run_task(t)]
        wall, cpu = time.perf_counter() - w0, time.process_time() - c0
        est_cpu = sum(float(r.get("estimator_seconds") or 0.0) for r in rows) * cpu / max(wall, 1e-9)
        out[label] = {"wall_s_per_session": wall / sessions, "cpu_s_per_session": cpu / sessions,
                      "estimators_cpu_s_per_session": est_cpu / sessions}
    return out


def replace_spec(spec: OrientationSpec, **kw) -> OrientationSpec:
    return replace(spec, **{k: v for k, v in kw.items() if v is not None})
