"""Cost of one campaign session, stage by stage, against a baseline checkout in the same run.

    python benchmarks/campaign_speed.py --sessions 8 [--baseline /path/to/other/checkout]
        [--hand typical] [--method kf_hand] [--json out.json]
    python benchmarks/campaign_speed.py --dask --sessions 4     # the Dask worker's malloc setting

One session = what a campaign worker does for a task (:func:`gyrosim.campaign.run_task`): simulate
(MuJoCo physics + the hand's motion, arm and controls + the sensor model), run the estimator on the
user's view of the recording, score.  Each code tree runs in its own Python process, sessions
alternate between them (A, B, A, B, …) so that a shared machine's load hits both alike, and the
time is the process's CPU time (``time.process_time``: what a single-threaded worker pays).  Stages
are timed by wrapping the functions in the worker process (no change to the code measured):

* ``physics``: :meth:`gyrosim.scene.HandScene.step_chunk` (MuJoCo rollouts);
* ``motion + controls``: the rest of :func:`gyrosim.simulate.simulate_truth` (hand noise, commanded
  motion, arm IK, control rows, truth assembly);
* ``sensor model``: :func:`gyrosim.simulate.apply_sensor`;
* ``estimator``: the method itself;
* ``scoring + rest``: the session minus the above.

The table prints CPU s/session per tree and the ratio this/baseline per stage, and the projected
wall time of 1000 sessions on 2 single-threaded workers (CPU s × 1000 / 2: the campaign keeps both
cores busy; Dask's own overhead is measured by ``gyrosim campaign-bench``).  Without ``--baseline``
the ratio column is against this tree's own physics stage (what no Python change can remove).
The first session of each process (imports, numba compilation) is run and not counted.

``--dask``: the same sessions in two 1-worker Dask LocalClusters, one spawned with
``MALLOC_TRIM_THRESHOLD_`` set (as Dask's default config does; the campaign set 32 MiB before) and
one as the campaign spawns its workers now (unset: glibc's dynamic mmap threshold stays on); CPU
and minor page faults of the worker process per session (``getrusage`` in the worker).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

STAGES = ("physics", "motion + controls", "sensor model", "estimator", "scoring + rest", "session")


def _worker(hand: str, method: str) -> None:
    """Run sessions named by seed on stdin; print one JSON line of stage CPU seconds each."""
    import functools
    import importlib

    from gyrosim import campaign, scene
    from gyrosim import estimator as est_mod

    sim = importlib.import_module("gyrosim.simulate")
    acc: dict[str, float] = {}

    def timed(owner, name: str, label: str) -> None:
        f = getattr(owner, name)

        @functools.wraps(f)
        def wrapper(*a, **k):
            t0 = time.process_time()
            try:
                return f(*a, **k)
            finally:
                acc[label] = acc.get(label, 0.0) + time.process_time() - t0
        setattr(owner, name, wrapper)

    timed(scene.HandScene, "step_chunk", "physics")
    timed(sim, "simulate_truth", "truth")
    timed(sim, "apply_sensor", "sensor model")
    load = est_mod.load_estimator

    def load_timed(name):
        f = load(name)

        def run(rec):
            t0 = time.process_time()
            try:
                return f(rec)
            finally:
                acc["estimator"] = acc.get("estimator", 0.0) + time.process_time() - t0
        return run
    est_mod.load_estimator = load_timed
    spec = campaign.CampaignSpec(hands=(hand,), seeds=1, estimators=(method,), calibrated_accelerometer=True)
    task = campaign.make_tasks(spec)[0]
    from dataclasses import replace

    campaign.run_task(replace(task, seed=10_000, task_id="warm-up"))
    print(json.dumps({"ready": True}), flush=True)
    for line in sys.stdin:
        seed = int(line)
        acc.clear()
        t0 = time.process_time()
        rows = campaign.run_task(replace(task, seed=seed, task_id=f"{hand}|1|{seed}"))
        total = time.process_time() - t0
        first = rows[0] if isinstance(rows[0], dict) else rows[0].to_csv()  # a checkout from before typed rows
        out = {"physics": acc.get("physics", 0.0),
               "motion + controls": acc.get("truth", 0.0) - acc.get("physics", 0.0),
               "sensor model": acc.get("sensor model", 0.0), "estimator": acc.get("estimator", 0.0),
               "session": total, "status": first["status"], "error": first.get("error", "")}
        out["scoring + rest"] = total - sum(out[k] for k in STAGES[:4])
        print(json.dumps(out), flush=True)


def _worker_usage() -> tuple[int, float]:
    """(minor page faults, user + system CPU s) of the calling process."""
    import resource

    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_minflt, r.ru_utime + r.ru_stime


def dask_worker_table(sessions: int, hand: str, method: str) -> list[dict]:
    """CPU and page faults per session inside a 1-worker Dask LocalCluster, with the worker spawned
    as Dask's default config would (MALLOC_TRIM_THRESHOLD_ set; 32 MiB as the campaign set it
    before) and as the campaign's :data:`gyrosim.campaign.DASK_CONFIG` spawns it (unset); the two
    clusters alternate round by round (same sessions, same run)."""
    import dask
    from dask.distributed import Client, LocalCluster, wait

    from gyrosim import campaign

    spec = campaign.CampaignSpec(hands=(hand,), seeds=sessions + 1, estimators=(method,), calibrated_accelerometer=True)
    tasks = campaign.make_tasks(spec)
    # the campaign's cluster first: a Nanny spawned with the variable set also writes it into this
    # process's environment (Dask's "pre-spawn" poisoning), which a later spawn would inherit
    configs = {
        "campaign (unset)": campaign.DASK_CONFIG,
        "MALLOC_TRIM_THRESHOLD_=32 MiB": {
            **campaign.DASK_CONFIG,
            "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": 32 << 20,
        },
    }
    if "MALLOC_TRIM_THRESHOLD_" in os.environ:
        raise RuntimeError("MALLOC_TRIM_THRESHOLD_ is set in this environment: every worker would inherit it")
    clients = {}
    for name, cfg in configs.items():
        with dask.config.set(cfg):
            cluster = LocalCluster(host="127.0.0.1", n_workers=1, threads_per_worker=1, processes=True,
                                   dashboard_address=":0")
        clients[name] = (Client(cluster), cluster)
    acc = {name: [0, 0.0] for name in configs}
    try:
        for c, _ in clients.values():
            c.run(campaign.run_task, tasks[0])   # warm-up: imports, numba caches
        for t in tasks[1:]:
            for name, (c, _) in clients.items():
                u0 = next(iter(c.run(_worker_usage).values()))
                wait([c.submit(campaign.run_task, t, pure=False)])
                u1 = next(iter(c.run(_worker_usage).values()))
                acc[name][0] += u1[0] - u0[0]
                acc[name][1] += u1[1] - u0[1]
    finally:
        for c, cluster in clients.values():
            c.close()
            cluster.close()
    return [{"worker": name, "cpu_s_per_session": v[1] / sessions, "page_faults_per_session": v[0] / sessions}
            for name, v in acc.items()]


def _start(tree: Path, hand: str, method: str) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": str(tree), "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
           "NUMBA_NUM_THREADS": "1"}
    p = subprocess.Popen(
        [sys.executable, str(Path(__file__).resolve()), "--worker", "--hand", hand, "--method", method],
        cwd=str(tree),
        env=env,
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    if json.loads(p.stdout.readline()).get("ready") is not True:
        raise RuntimeError(f"worker for {tree} did not start")
    return p


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sessions", type=int, default=8, help="sessions per tree (seeds 0..N-1), after one warm-up")
    ap.add_argument("--hand", default="typical", help="hand preset of every session")
    ap.add_argument("--method", default="kf_hand", help="estimator of every session")
    ap.add_argument("--baseline", type=Path, help="another checkout (e.g. a git worktree of main) to compare with")
    ap.add_argument("--json", type=Path, help="also write the per-stage means here")
    ap.add_argument(
        "--dask",
        action="store_true",
        help="instead: CPU and page faults per session in a Dask worker, malloc trim threshold set vs unset",
    )
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.worker:
        _worker(args.hand, args.method)
        return 0
    if args.dask:
        rows = dask_worker_table(args.sessions, args.hand, args.method)
        print(f"{args.sessions} sessions per worker ({args.hand} hand, {args.method}), 1-worker LocalCluster each; "
              f"1-min load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
        print(f"{'worker spawned with':<32} {'CPU s/session':>14} {'page faults/session':>20} {'÷ campaign':>11}")
        ref = rows[0]["cpu_s_per_session"]
        for r in rows:
            print(f"{r['worker']:<32} {r['cpu_s_per_session']:14.3f} {r['page_faults_per_session']:20.0f} "
                  f"{r['cpu_s_per_session'] / ref:11.2f}")
        if args.json:
            args.json.write_text(json.dumps({"sessions": args.sessions, "dask_workers": rows}, indent=2))
        return 0
    here = Path(__file__).resolve().parents[1]
    trees = {"this": here} | ({"baseline": args.baseline.resolve()} if args.baseline else {})
    procs = {k: _start(t, args.hand, args.method) for k, t in trees.items()}
    sums = {k: dict.fromkeys(STAGES, 0.0) for k in trees}
    load = os.getloadavg()[0]
    try:
        for seed in range(args.sessions):
            for k, p in procs.items():
                p.stdin.write(f"{seed}\n")
                p.stdin.flush()
                r = json.loads(p.stdout.readline())
                if r["status"] != "ok":
                    raise RuntimeError(f"{k} session {seed} failed: {r['error']}")
                for s in STAGES:
                    sums[k][s] += r[s] / args.sessions
    finally:
        for p in procs.values():
            p.stdin.close()
            p.wait()
    load = max(load, os.getloadavg()[0])
    ref = sums.get("baseline")
    head = f"{'stage':<20} {'this CPU s':>11}"
    head += f" {'baseline CPU s':>15} {'this/baseline':>14}" if ref else f" {'÷ physics':>10}"
    print(f"{args.sessions} sessions per tree ({args.hand} hand, {args.method}); 1-min load average ≤ {load:.1f} "
          f"on {os.cpu_count()} cores")
    print(head)
    for s in STAGES:
        a = sums["this"][s]
        print(f"{s:<20} {a:11.3f}" + (f" {ref[s]:15.3f} {a / ref[s]:14.2f}" if ref else
                                       f" {a / sums['this']['physics']:10.2f}"))
    for k in trees:
        print(f"projected 1000 sessions on 2 workers ({k}): {sums[k]['session'] * 1000 / 2 / 60:.1f} min")
    if args.json:
        args.json.write_text(json.dumps({"sessions": args.sessions, "hand": args.hand, "method": args.method,
                                         "load_average_max": load, "cpu_s_per_session": sums}, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
