"""Robustness campaigns: many simulated sessions × estimators, scored against the truth.

A campaign is a grid of tasks.  Each task simulates one session (schedule × hand × sensor × seed),
runs every estimator on it (:mod:`gyrosim.estimator`) and scores each estimate against the
device the simulator drew (stored in the recording).  Tasks are pure functions of their spec:
the session seed is ``SeedSequence([campaign seed, task index])``-free — simply the seed number
of the task — so results are identical whatever runs them (in-process, one Dask worker or many).

Execution (``run_campaign``): ``scheduler=None`` runs in-process; ``"local"`` starts a Dask
``LocalCluster`` on 127.0.0.1 with one single-threaded worker process per core; ``tcp://HOST:PORT``
uses an existing cluster (connect timeout ``connect_timeout_s``).  Results stream into
``results.csv`` (one row per task × estimator; failed tasks keep their error text); a re-run
skips what is already there, so adding an estimator to a finished campaign runs only it
(failed rows are retried).  ``provenance.json`` holds versions, the spec and the host.

Scores per estimator (SI → reported units):

* ``err_bias_{x,y,z}_deg_s`` = b̂ − b;  ``err_S_{x,y,z}_pct`` = 100 (Ŝ − S);
  ``err_G_{x,y,z}_pct`` = 100 (Ĝ − G): errors of relative quantities, in % of the nominal sensitivity;
* ``ext_acc_rms_m_s2``: RMS of the hand's external acceleration at the accelerometer site (truth),
  the severity axis of the plots; ``rate_disturbance_rms_deg_s`` likewise for the rate;
* ``calibration_status``: the estimate's own verdict (``ok``, ``inconsistent``, ``diverged``;
  :class:`gyrosim.calibration.Calibration`), beside ``status`` (ran / failed).

``summarise`` writes ``summary.csv``, ``error_vs_severity.png`` and ``summary.rrd``: the same summary
as rerun plots (:func:`save_summary_rrd`; timeline ``ext_acc_rms_mm_s2``, the severity axis;
``campaign/log10_rms_{S_pct,G_pct,bias_deg_s}/{estimator}`` log10 of the RMS errors (one curve per
estimator, every hand and severity a point along x), ``campaign/failed_pct/{estimator}``, and the ``story`` text).

The truth is the simulated device (:func:`gyrosim.calibration.truth_calibration`); estimators come
through :mod:`gyrosim.estimator` and return a :class:`~gyrosim.calibration.Calibration`.
"""

from __future__ import annotations

import csv
import json
import math
import os
import platform
import time
import tomllib
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Callable

import numpy as np

from .errors import GyrosimError

__all__ = [
    "CampaignSpec",
    "CampaignRow",
    "Task",
    "load_campaign",
    "make_tasks",
    "run_task",
    "run_campaign",
    "summarise",
    "RESULT_COLUMNS",
    "read_rows",
    "write_rows",
]

PARAMS = [f"err_bias_{a}_deg_s" for a in "xyz"] + [f"err_S_{a}_pct" for a in "xyz"] + [f"err_G_{a}_pct" for a in "xyz"]
RESULT_COLUMNS = (["task_id", "hand", "severity", "seed", "sensor", "schedule", "rate_hz", "estimator", "status",
                   "error", "ext_acc_rms_m_s2", "rate_disturbance_rms_deg_s", "task_seconds"] + PARAMS
                  + [f"sd_{p}" for p in PARAMS] + ["calibration_status"])



@dataclass(frozen=True)
class CampaignRow:
    """One row of ``results.csv``: a task × estimator.  The CSV's columns (:data:`RESULT_COLUMNS`) are
    a promise; this is their typed form for the code that writes and reads them.

    ``status``: "ok" (the estimator ran) or "failed" (``error`` says why; the scores are then None).
    ``err`` and ``sd``: the estimate's error against the truth and its reported σ, in :data:`PARAMS`
    order and units (°/s for the bias, % for S and G).  ``calibration_status``: the estimate's own
    verdict (ok / inconsistent / diverged).
    """

    task_id: str
    hand: str
    severity: float
    seed: int
    sensor: str
    schedule: str
    rate_hz: float
    estimator: str
    status: str
    error: str = ""
    ext_acc_rms_m_s2: float | None = None
    rate_disturbance_rms_deg_s: float | None = None
    task_seconds: float | None = None
    err: tuple[float, ...] | None = None
    sd: tuple[float, ...] | None = None
    calibration_status: str = ""

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    def to_csv(self) -> dict[str, object]:
        """The row keyed by :data:`RESULT_COLUMNS` ("" for what a failed row lacks)."""
        d: dict[str, object] = {f: getattr(self, f) for f in _SCALAR_FIELDS}
        for prefix, values in (("", self.err), ("sd_", self.sd)):
            d.update({f"{prefix}{p}": v for p, v in zip(PARAMS, values)} if values is not None else {})
        return {k: ("" if d.get(k) is None else d[k]) for k in RESULT_COLUMNS}

    @classmethod
    def from_csv(cls, r: dict[str, str]) -> "CampaignRow":
        """Parse a ``results.csv`` row (:func:`csv.DictReader`); ``to_csv`` writes it back unchanged."""
        def num(k: str) -> float | None:
            return float(r[k]) if r.get(k, "") != "" else None

        def vec(prefix: str) -> tuple[float, ...] | None:
            return tuple(float(r[prefix + p]) for p in PARAMS) if r.get(prefix + PARAMS[0], "") != "" else None

        return cls(r["task_id"], r["hand"], float(r["severity"]), int(r["seed"]), r["sensor"], r["schedule"],
                   float(r["rate_hz"]), r["estimator"], r["status"], r.get("error", ""), num("ext_acc_rms_m_s2"),
                   num("rate_disturbance_rms_deg_s"), num("task_seconds"), vec(""), vec("sd_"),
                   r.get("calibration_status", ""))


_SCALAR_FIELDS = ("task_id", "hand", "severity", "seed", "sensor", "schedule", "rate_hz", "estimator", "status",
                  "error", "ext_acc_rms_m_s2", "rate_disturbance_rms_deg_s", "task_seconds", "calibration_status")


def read_rows(path: Path) -> list[dict[str, str]]:
    """The rows of a campaign's CSV (empty when the file does not exist yet)."""
    if not path.is_file():
        return []
    with path.open(newline="") as fh:
        return list(csv.DictReader(fh))


def write_rows(path: Path, rows: list[dict], columns: list[str]) -> None:
    """Rewrite a campaign's results CSV atomically (``.csv.part`` then rename): an interrupted run
    keeps the previous complete file.  Keys missing from a row are written as ""."""
    tmp = path.with_suffix(".csv.part")
    with tmp.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=columns)
        w.writeheader()
        for r in rows:
            w.writerow({k: r.get(k, "") for k in columns})
    tmp.replace(path)


_SPEC_KEYS = {"name", "schedule", "hands", "seeds", "first_seed", "sensor", "estimators", "rate_hz",
              "calibrated_accelerometer", "severity"}


@dataclass(frozen=True)
class CampaignSpec:
    """What to run.  ``severity``: factors applied to every imperfection of each hand preset
    (tremor, sway, wobble, pivot offset), a continuous sweep; 1.0 = the preset as written."""

    hands: tuple[str, ...] = ("ideal", "steady", "typical", "shaky")
    seeds: int = 10
    first_seed: int = 0
    sensor: str = "mpu9250"
    estimators: tuple[str, ...] = ("kf", "iterated")
    schedule: str = "zhou2020"
    rate_hz: float = 100.0
    calibrated_accelerometer: bool = False
    severity: tuple[float, ...] = (1.0,)
    name: str = "campaign"

    def validate(self) -> None:
        from .estimator import load_estimator

        validate_session_grid(self, "a campaign")
        for e in self.estimators:
            load_estimator(e)


def validate_session_grid(spec, what: str):
    """The checks every campaign spec shares, before any work: seeds, hands × estimators not empty,
    severity factors finite and ≥ 0, and every hand, the sensor and the schedule loadable.  ``spec``
    has ``seeds``, ``hands``, ``estimators``, ``severity``, ``sensor``, ``schedule``; ``what`` names
    the campaign in the messages ("a campaign").  Returns the loaded sensor model."""
    from .hand import load_hand
    from .schedule import load_schedule
    from .sensor_model import load_sensor

    if spec.seeds < 1:
        raise GyrosimError(f"{what} needs --seeds ≥ 1")
    if not spec.hands or not spec.estimators:
        raise GyrosimError(f"{what} needs at least one hand and one estimator")
    if any(not (math.isfinite(s) and s >= 0) for s in spec.severity):
        raise GyrosimError(f"severity factors must be finite and ≥ 0, got {spec.severity}")
    for h in spec.hands:
        load_hand(h)
    sensor = load_sensor(spec.sensor)
    load_schedule(spec.schedule)
    return sensor


def load_campaign(path: str | Path, **overrides) -> CampaignSpec:
    """A campaign TOML (keys: see ``_SPEC_KEYS``); unknown keys are an error before any work."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise GyrosimError(f"campaign file {path}: {exc}") from exc
    bad = set(data) - _SPEC_KEYS
    if bad:
        raise GyrosimError(f"campaign file {path}: unknown key(s) {sorted(bad)}; allowed: {sorted(_SPEC_KEYS)}")
    for k in ("hands", "estimators", "severity"):
        if k in data:
            data[k] = tuple(data[k])
    data.setdefault("name", path.stem)
    return replace(CampaignSpec(**data), **{k: v for k, v in overrides.items() if v is not None})


@dataclass(frozen=True)
class Task:
    """One session of a campaign: the hand at a severity, a seed, the sensor, schedule and rate, and the
    estimators to run on it; ``task_id`` is ``hand|severity|seed``."""

    task_id: str
    hand: str
    severity: float
    seed: int
    sensor: str
    schedule: str
    rate_hz: float
    estimators: tuple[str, ...]
    calibrated_accelerometer: bool


def make_tasks(spec: CampaignSpec) -> list[Task]:
    """The campaign's sessions: one :class:`Task` per hand × severity × seed, in that order."""
    return [
        Task(
            f"{h}|{sev:g}|{seed}",
            h,
            float(sev),
            seed,
            spec.sensor,
            spec.schedule,
            spec.rate_hz,
            spec.estimators,
            spec.calibrated_accelerometer,
        )
        for h in spec.hands
        for sev in spec.severity
        for seed in range(spec.first_seed, spec.first_seed + spec.seeds)
    ]


def _scaled_hand(name: str, factor: float):
    from .hand import load_hand

    h = load_hand(name)
    if factor == 1.0:
        return h
    return replace(
        h,
        name=f"{h.name}×{factor:g}",
        tremor_acc_rms_m_s2=h.tremor_acc_rms_m_s2 * factor,
        tremor_rate_rms_rad_s=h.tremor_rate_rms_rad_s * factor,
        sway_acc_rms_m_s2=h.sway_acc_rms_m_s2 * factor,
        axis_wobble_rms_deg=h.axis_wobble_rms_deg * factor,
        pivot_offset_m=tuple(v * factor for v in h.pivot_offset_m),
    )


def _sensor(task: Task):
    from .sensor_model import load_sensor

    s = load_sensor(task.sensor)
    if task.calibrated_accelerometer:  # Zhou §3.3.2: a calibrated accelerometer keeps only its noise
        s = replace(s, accelerometer=tuple(e for e in s.accelerometer if e.is_white_noise))
    return s


def run_task(task: Task) -> list[CampaignRow]:
    """Simulate, estimate with every estimator, score; a failure becomes rows with its error."""
    from .estimator import as_user_file, load_estimator
    from .simulate import simulate

    t0 = time.perf_counter()
    base = {"task_id": task.task_id, "hand": task.hand, "severity": task.severity, "seed": task.seed,
            "sensor": task.sensor + (" (calibrated acc)" if task.calibrated_accelerometer else ""),
            "schedule": task.schedule, "rate_hz": task.rate_hz}
    try:
        # one thread per task: the campaign keeps every core busy with its own worker processes
        rec = simulate(task.schedule, _scaled_hand(task.hand, task.severity), _sensor(task), task.rate_hz,
                       seed=task.seed, pipeline=False)
    except Exception as exc:  # noqa: BLE001 - a failed task is recorded, not lost
        return [CampaignRow(**base, estimator=e, status="failed", error=f"simulation: {type(exc).__name__}: {exc}")
                for e in task.estimators]
    from .calibration import truth_calibration

    truth = truth_calibration(rec)
    ext_rms, dw_rms = rec.truth.disturbance_rms()
    common = {**base, "ext_acc_rms_m_s2": ext_rms, "rate_disturbance_rms_deg_s": math.degrees(dw_rms)}
    true_vec = truth.vector("gyro")
    units = np.array([180 / math.pi] * 3 + [100.0] * 6)
    rows = []
    user = as_user_file(rec)  # what the estimators see: samples and rate, as a user's file
    for name in task.estimators:
        t1 = time.perf_counter()
        try:
            est = load_estimator(name)(user)
            err = (est.vector("gyro") - true_vec) * units
            sd = np.sqrt(np.clip(np.diag(est.linear_covariance("gyro")), 0, None)) * units
            row = {**common, "estimator": name, "status": "ok", "calibration_status": est.status,
                   "err": tuple(float(v) for v in err), "sd": tuple(float(v) for v in sd)}
        except Exception as exc:  # noqa: BLE001
            row = {**common, "estimator": name, "status": "failed",
                   "error": f"{type(exc).__name__}: {exc}".replace("\n", " ")[:500]}
        rows.append(CampaignRow(**row, task_seconds=time.perf_counter() - t1 + (t1 - t0) / len(task.estimators)))
    return rows


def _read_done(path: Path) -> dict[str, list[CampaignRow]]:
    """The successful rows already in results.csv, by task (failed rows are dropped: retried)."""
    done: dict[str, list[CampaignRow]] = {}
    for r in map(CampaignRow.from_csv, read_rows(path)):
        if r.ok:
            done.setdefault(r.task_id, []).append(r)
    return done


# Dask starts workers with MALLOC_TRIM_THRESHOLD_=65536 so that freed memory goes back to the OS at
# once.  Setting that variable at all (any value) also switches off glibc's dynamic mmap threshold:
# every array above 128 KiB is then a fresh mmap/munmap with its page faults.  A session allocates
# and frees many such temporaries: measured 240 000 minor page faults and 2.07 s CPU per session in
# a worker with the variable set (even to 32 MiB), 8 000 and 1.3–1.7 s with it unset — the same as
# in-process.  ``None`` unsets it (Dask's documented way), so workers run with glibc's own defaults.
# The statistical profiler (a GIL-taking stack sample every 10 ms) is off: uniform long tasks.
DASK_CONFIG = {"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,
               "distributed.worker.profile.enabled": False}


def _require_dask() -> None:
    """Dask is the ``campaign`` extra: without it, say how to install it or run in this process."""
    try:
        import dask.distributed  # noqa: F401
    except ImportError as exc:
        raise GyrosimError("campaigns on a scheduler run on Dask, which is not installed: pip install "
                           "'gyrosim-calib[campaign]', or pass --scheduler none to run them in this process") from exc


def _local_cluster(n: int):
    import dask
    from dask.distributed import LocalCluster

    with dask.config.set(DASK_CONFIG):
        return LocalCluster(host="127.0.0.1", n_workers=n, threads_per_worker=1, processes=True,
                            dashboard_address=":0")


def _client(scheduler: str, workers: int | None, connect_timeout_s: float):
    from dask.distributed import Client

    if scheduler == "local":
        cluster = _local_cluster(workers or os.cpu_count() or 1)
        return Client(cluster), cluster
    if not scheduler.startswith("tcp://"):
        raise GyrosimError(f"scheduler {scheduler!r}: use 'local', 'none' or tcp://HOST:PORT")
    try:
        return Client(scheduler, timeout=f"{connect_timeout_s}s"), None
    except (OSError, TimeoutError) as exc:
        raise GyrosimError(f"the Dask scheduler at {scheduler} did not answer within {connect_timeout_s:g} s ({exc}); "
                           "start it (dask scheduler) or use --scheduler local") from exc


def run_campaign(spec: CampaignSpec, out: str | Path, *, scheduler: str | None = "local", workers: int | None = None,
                 connect_timeout_s: float = 10.0, progress: Callable[[int, int], None] | None = None) -> Path:
    """Run every task not yet in ``out/results.csv``; returns the results path (module docstring)."""
    spec.validate()  # unknown hand/sensor/estimator: an error before any work
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "results.csv"
    done = _read_done(path)
    tasks = []
    for t in make_tasks(spec):  # a task runs only the estimators it has no successful row for
        have = {r.estimator for r in done.get(t.task_id, [])}
        missing = tuple(e for e in t.estimators if e not in have)
        if missing:
            tasks.append(replace(t, estimators=missing))
    _write_provenance(out, spec, scheduler, workers)
    rows_all = [r for v in done.values() for r in v]

    def flush() -> None:
        order = {t.task_id: i for i, t in enumerate(make_tasks(spec))}
        rows_all.sort(key=lambda r: (order.get(r.task_id, 1 << 30), r.task_id, spec.estimators.index(r.estimator)
                                     if r.estimator in spec.estimators else 99))
        write_rows(path, [r.to_csv() for r in rows_all], RESULT_COLUMNS)

    run_tasks(tasks, run_task, rows_all, flush, scheduler=scheduler, workers=workers,
              connect_timeout_s=connect_timeout_s, progress=progress, key_prefix="task")
    return path


def run_tasks(tasks: list, run: Callable[[object], list], rows: list, flush: Callable[[], None], *,
              scheduler: str | None, workers: int | None, connect_timeout_s: float,
              progress: Callable[[int, int], None] | None, key_prefix: str) -> None:
    """Run ``run(task)`` for every task, in-process (``scheduler`` None/"none") or on Dask, appending
    each task's rows to ``rows`` as they complete and calling ``flush`` every 20 tasks and at the end
    (the campaigns' results files are rewritten then, so an interrupted run keeps what finished)."""
    total = len(tasks)
    if scheduler in (None, "none"):
        for i, t in enumerate(tasks):
            rows.extend(run(t))
            if progress:
                progress(i + 1, total)
            if (i + 1) % 20 == 0:
                flush()
    else:
        _require_dask()
        from dask.distributed import as_completed

        client, cluster = _client(scheduler, workers, connect_timeout_s)
        try:
            futures = [client.submit(run, t, pure=False, key=f"{key_prefix}-{t.task_id}") for t in tasks]
            for i, fut in enumerate(as_completed(futures)):
                rows.extend(fut.result())
                if progress:
                    progress(i + 1, total)
                if (i + 1) % 20 == 0:
                    flush()
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
    flush()


def _write_provenance(out: Path, spec: CampaignSpec, scheduler, workers) -> None:
    import mujoco
    import scipy

    from . import __version__

    prov = {"spec": asdict(spec), "scheduler": scheduler, "workers": workers, "versions": {
        "gyrosim": __version__, "numpy": np.__version__, "scipy": scipy.__version__, "mujoco": mujoco.__version__,
        "python": platform.python_version()}, "host": platform.node(), "cpu_count": os.cpu_count()}
    try:
        import dask

        prov["versions"]["dask"] = dask.__version__
    except ImportError:
        pass
    (out / "provenance.json").write_text(json.dumps(prov, indent=2))


# a scale or axis error estimated 50 % off is no calibration (real ones are a few %): the filter
# diverged.  Counted as a failure of the task, and kept in the RMS (it is what the user would get).
DIVERGED_PCT = 50.0


def _rms_ci(x: np.ndarray) -> tuple[float, float, float]:
    """RMS with its 95 % interval (χ² on n degrees of freedom for a zero-mean Gaussian error)."""
    from scipy import stats

    n = x.size
    ms = float(np.mean(x**2))
    lo = math.sqrt(n * ms / stats.chi2.ppf(0.975, n))
    hi = math.sqrt(n * ms / stats.chi2.ppf(0.025, n))
    return math.sqrt(ms), lo, hi


def _wilson(k: int, n: int) -> tuple[float, float]:
    if n == 0:
        return float("nan"), float("nan")
    z = 1.959964
    p = k / n
    d = 1 + z * z / n
    c = (p + z * z / (2 * n)) / d
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / d
    return max(0.0, c - h), min(1.0, c + h)


def summarise(results: str | Path, out: str | Path | None = None) -> list[dict]:
    """Per (hand, severity, estimator): RMS error of each parameter group with 95 % intervals,
    failure rate (Wilson 95 %; a failure = a crashed task or a diverged estimate, any S or G error
    > 50 %), mean external-acceleration RMS; writes summary.csv and plots."""
    results = Path(results)
    groups: dict[tuple, list[CampaignRow]] = {}
    for r in map(CampaignRow.from_csv, read_rows(results)):
        groups.setdefault((r.hand, r.severity, r.estimator), []).append(r)
    summary = []
    for (hand, sev, est), rs in groups.items():
        ok = [r for r in rs if r.ok]
        diverged = [r for r in ok if max(abs(v) for v in r.err[3:]) > DIVERGED_PCT]
        bad = len(rs) - len(ok) + len(diverged)
        row = {"hand": hand, "severity": sev, "estimator": est, "n": len(rs), "failed": bad,
               "crashed": len(rs) - len(ok), "diverged": len(diverged)}
        row["failure_rate_lo"], row["failure_rate_hi"] = _wilson(bad, len(rs))
        if ok:
            row["ext_acc_rms_m_s2"] = float(np.mean([r.ext_acc_rms_m_s2 for r in ok]))
            for group, cols in (("bias_deg_s", slice(0, 3)), ("S_pct", slice(3, 6)), ("G_pct", slice(6, 9))):
                x = np.array([r.err[cols] for r in ok]).ravel()
                row[f"rms_{group}"], row[f"rms_{group}_lo"], row[f"rms_{group}_hi"] = _rms_ci(x)
        summary.append(row)
    if out is not None:
        out = Path(out)
        keys = sorted(
            {k for r in summary for k in r}, key=lambda k: (k not in ("hand", "severity", "estimator", "n"), k)
        )
        with (out / "summary.csv").open("w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=keys)
            w.writeheader()
            w.writerows(summary)
        _plot(summary, out / "error_vs_severity.png")
        save_summary_rrd(summary, out / "summary.rrd")
    return summary


CAMPAIGN_TIMELINE = "ext_acc_rms_mm_s2"
_GROUPS = (("S_pct", "scale factor error RMS (%)"), ("G_pct", "non-orthogonality error RMS (%)"),
           ("bias_deg_s", "bias error RMS (°/s)"))


def _segment(name: str) -> str:
    return "".join(c if c.isalnum() or c in "_-+." else "_" for c in str(name))


def summary_story(summary: list[dict]) -> str:
    """The campaign in one paragraph: per estimator, error at the mildest and the worst hand."""
    if not summary:
        return "**Campaign summary:** no task finished: nothing to show (see results.csv for the errors)."
    ests = sorted({r["estimator"] for r in summary})
    n = sum(int(r["n"]) for r in summary)
    lines = [f"**Campaign: {n} calibrations, {len(ests)} estimator(s) ({', '.join(ests)}), hands "
             f"{', '.join(sorted({r['hand'] for r in summary}))}** — error against the truth as the hand's external "
             "acceleration grows (x: its RMS in mm/s²). Plots show log10 of the RMS error (one y scale for S and G), "
             "and the failed-or-diverged rate.", ""]
    parts = []
    for est in ests:
        rs = sorted(
            [r for r in summary if r["estimator"] == est and "rms_S_pct" in r], key=lambda r: r["ext_acc_rms_m_s2"]
        )
        if not rs:
            parts.append(f"{est}: every task crashed")
            continue
        a, b = rs[0], rs[-1]
        parts.append(f"{est}: S error {a['rms_S_pct']:.3g} % at {a['ext_acc_rms_m_s2'] * 1000:.0f} mm/s² → "
                     f"{b['rms_S_pct']:.3g} % at {b['ext_acc_rms_m_s2'] * 1000:.0f} mm/s², failed "
                     f"{max(int(r['failed']) for r in rs)}/{max(int(r['n']) for r in rs)} at worst")
    lines.append("; ".join(parts) + ".")
    same = _same_curves(summary)
    if same:
        lines.append("Identical numbers (their lines lie on each other, the first drawn wider): "
                     + ", ".join(f"{a} = {b}" for a, b in same) + ".")
    return "\n".join(lines)


def summary_blueprint(x_span: tuple[float, float], log_range: dict | tuple[float, float] | None):
    """One view per error group (S and G on one log10 y range), the failure rate; x = the external
    acceleration RMS over the whole span of the campaign (a sequence timeline, so the unit is in each view's name).
    ``log_range``: the y range by group (``S_pct``, ``G_pct``, ``bias_deg_s``), or one range for S and G."""
    import rerun.blueprint as rrb

    from .viewer import Span, series_view, story_blueprint

    span = Span(x_span[0], x_span[1], CAMPAIGN_TIMELINE, sequence=True)
    ranges = log_range if isinstance(log_range, dict) else {"S_pct": log_range, "G_pct": log_range}
    x = " vs external acc. RMS (mm/s²)"  # the x axis is a sequence timeline: rerun labels it #0 … #N, no unit
    views = [series_view(f"campaign/log10_rms_{g}", f"log10 {label}{x}", span, y_range=ranges.get(g))
             for g, label in _GROUPS]
    views.append(series_view("campaign/failed_pct", f"failed or diverged (%){x}", span, y_range=(0.0, 100.0)))
    return story_blueprint(rrb.Grid(*views, grid_columns=2), timeline=CAMPAIGN_TIMELINE)


def _log_ranges(summary: list[dict], min_decades: float = 0.5) -> dict[str, tuple[float, float]]:
    """The y range of each error group's log10 plot: S and G share one, bias its own; each at least ``min_decades``
    wide (a factor of 3), so a 5 % change stays a small step instead of filling the plot as a V."""
    from .viewer import nice_range, shared_range

    def rng(groups: tuple[str, ...]) -> tuple[float, float] | None:
        v = [np.log10(max(r[f"rms_{g}"], 1e-12)) for r in summary for g in groups if f"rms_{g}" in r]
        if not v:
            return None
        lo, hi = shared_range(v, quantile=0.0, nice=False)
        mid, half = (lo + hi) / 2, max(hi - lo, min_decades) / 2
        return nice_range(mid - half, mid + half)

    out = {"S_pct": rng(("S_pct", "G_pct")), "bias_deg_s": rng(("bias_deg_s",))}
    out["G_pct"] = out["S_pct"]
    return {k: v for k, v in out.items() if v is not None}


def _same_curves(summary: list[dict]) -> list[tuple[str, str]]:
    """Pairs of estimators whose rows give the same numbers in every cell (one line would hide the other)."""
    by_est: dict[str, list] = {}
    for r in sorted(summary, key=lambda r: (r["estimator"], r.get("hand", ""))):
        by_est.setdefault(r["estimator"], []).append(tuple(r.get(f"rms_{g}") for g, _ in _GROUPS))
    names = sorted(by_est)
    return [(a, b) for i, a in enumerate(names) for b in names[i + 1:] if by_est[a] == by_est[b]]


def save_summary_rrd(summary: list[dict], path: str | Path) -> Path:
    """``summary.rrd``: the summary's plots (module docstring) with a story; open with ``rerun PATH``."""
    import rerun as rr

    from .viewer import PALETTE, log_story, scalar_style, send_series

    path = Path(path)
    stream = rr.RecordingStream("gyrosim_campaign")
    stream.save(str(path))
    x_all = [r["ext_acc_rms_m_s2"] * 1000.0 for r in summary if "ext_acc_rms_m_s2" in r]
    x_span = (min(x_all), max(x_all)) if x_all else (0.0, 1.0)
    if x_span[1] - x_span[0] < 1:
        x_span = (x_span[0], x_span[0] + 1.0)
    stream.send_blueprint(summary_blueprint(x_span, _log_ranges(summary)))
    log_story(stream, summary_story(summary))
    ests = sorted({r["estimator"] for r in summary})
    for k, est in enumerate(ests):
        colour = PALETTE[k % len(PALETTE)]  # the same colour for an estimator in every view
        # drawn first is widest: an estimator with the same numbers as another stays visible around it
        width = 2.0 + 2.0 * (len(ests) - 1 - k)
        # one curve per estimator: the hands (and their severities) are points along the x axis
        ok = sorted([r for r in summary if r["estimator"] == est and "ext_acc_rms_m_s2" in r and "rms_S_pct" in r],
                    key=lambda r: r["ext_acc_rms_m_s2"])
        if not ok:
            continue
        x = np.array([r["ext_acc_rms_m_s2"] * 1000.0 for r in ok])
        for g, _ in _GROUPS:
            p = f"campaign/log10_rms_{g}/{_segment(est)}"
            scalar_style(stream, p, est, colour, width=width)
            send_series(stream, p, x, np.log10(np.maximum([r[f"rms_{g}"] for r in ok], 1e-12)), CAMPAIGN_TIMELINE,
                        sequence=True)
        p = f"campaign/failed_pct/{_segment(est)}"
        scalar_style(stream, p, est, colour, width=width)
        send_series(stream, p, x, [100.0 * r["failed"] / r["n"] for r in ok], CAMPAIGN_TIMELINE, sequence=True)
    stream.flush()
    return path


def _plot(summary: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 4, figsize=(16, 4))
    for est in sorted({r["estimator"] for r in summary}):
        rs = sorted([r for r in summary if r["estimator"] == est and "ext_acc_rms_m_s2" in r],
                    key=lambda r: r["ext_acc_rms_m_s2"])
        if not rs:
            continue
        x = np.array([r["ext_acc_rms_m_s2"] for r in rs])
        for ax, group, label in zip(
            axes[:3],
            ("S_pct", "G_pct", "bias_deg_s"),
            ("scale factor error RMS (%)", "non-orthogonality error RMS (%)", "bias error RMS (°/s)"),
        ):
            y = np.array([r[f"rms_{group}"] for r in rs])
            lo = np.array([r[f"rms_{group}_lo"] for r in rs])
            hi = np.array([r[f"rms_{group}_hi"] for r in rs])
            ax.errorbar(x, y, yerr=[y - lo, hi - y], marker="o", capsize=3, label=est)
            ax.set_xlabel("external acceleration RMS (m/s²)")
            ax.set_ylabel(label)
            ax.set_yscale("log")
        fr = np.array([r["failed"] / r["n"] for r in rs])
        axes[3].plot(x, fr * 100, marker="o", label=est)
    axes[3].set_xlabel("external acceleration RMS (m/s²)")
    axes[3].set_ylabel("failed or diverged (%)")
    axes[0].legend(fontsize=8)
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.suptitle("calibration error vs hand imperfection (95 % intervals)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def bench_scaling(sessions: int = 12, spec: CampaignSpec | None = None) -> list[dict]:
    """Sessions per second in-process, on a 1-worker and a 2-worker LocalCluster, same tasks, same run
    (the clusters are started before timing; each timing covers submit → last result)."""
    _require_dask()
    from dask.distributed import Client, wait

    spec = spec or CampaignSpec(hands=("typical",), seeds=sessions, estimators=("kf",), calibrated_accelerometer=True)
    tasks = make_tasks(spec)
    run_task(tasks[0])  # compile and cache numba kernels, load presets
    t0 = time.perf_counter()
    local_rows = [run_task(t) for t in tasks]
    t_local = time.perf_counter() - t0
    compute = sum(r[0].task_seconds for r in local_rows)
    out = [{"runner": "in-process (no Dask)", "workers": 1, "seconds": t_local, "sessions_per_s": len(tasks) / t_local}]
    for n in (1, 2):
        with _local_cluster(n) as cluster, Client(cluster) as client:
            client.run(lambda: run_task(tasks[0]))  # warm every worker (imports, numba cache)
            t0 = time.perf_counter()
            futs = [client.submit(run_task, t, pure=False) for t in tasks]
            wait(futs)
            dt = time.perf_counter() - t0
            out.append({"runner": "Dask LocalCluster", "workers": n, "seconds": dt, "sessions_per_s": len(tasks) / dt})
    base = out[1]["sessions_per_s"]
    for r in out:
        r["speedup_vs_1_worker"] = r["sessions_per_s"] / base
    out[1]["overhead_per_task_s"] = (out[1]["seconds"] - compute) / len(tasks)
    return out
