"""Start-up of the ``calib`` command line: ``--version``, ``--help``, the refusal of a bad file, and the main job
(``calib demo``) with a cold and a warm numba cache, for one or more source trees side by side.

    python benchmarks/startup.py [--tree before=@COMMIT] [--tree after=.] [--repeats 5] [--no-demo]
                                 [--out benchmarks/startup.md]

A tree is a folder or ``@COMMIT``, a commit of this repository (extracted with ``git archive`` into a temporary
folder), e.g. ``--tree before=@main --tree after=.``.

Each row runs ``python -m calib ARGS`` in a fresh process with the tree first on ``PYTHONPATH`` (the same import
path as the ``calib`` script), the trees interleaved per repeat so that a change in the machine's load falls on
all of them.  Two numbers per run: the wall clock and the CPU time of the process (user + system, from
``getrusage``).  On a shared machine the wall clock measures the scheduler as much as the program, so the CPU time
is the number to compare; the load average at the start is in the stamp.  Medians over the repeats.

The demo runs once per tree with an empty numba cache (``NUMBA_CACHE_DIR`` a fresh folder: every kernel it uses is
compiled) and once more with that cache (the kernels are loaded); the difference is what the first run of a fresh
install costs.  The table is written with the commit, the command line and the date; nothing in it is edited by
hand.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from datetime import datetime, timezone
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BAD_CSV = "t,gyro_x\n0,1\n"  # a header without the accelerometer: every command refuses it (exit code 2)
ROWS = (
    ("calib --version", ["--version"], 0),
    ("calib --help", ["--help"], 0),
    ("calib run bad.csv (refused)", ["run", "bad.csv"], 2),
    ("calib allan bad.csv (refused)", ["allan", "bad.csv"], 2),
    ("calib temperature bad.csv (refused)", ["temperature", "bad.csv"], 2),
)


def _git(*args: str) -> str:
    out = subprocess.run(["git", "-C", str(ROOT), *args], capture_output=True, text=True)
    return out.stdout.strip() if out.returncode == 0 else ""


def stamp() -> dict[str, str]:
    """Commit (+ "-dirty"), command line, UTC date and the load average at the start."""
    commit = (_git("rev-parse", "HEAD") or "unknown") + ("-dirty" if _git("status", "--porcelain") else "")
    return {"commit": commit, "command": "python benchmarks/startup.py " + " ".join(sys.argv[1:]),
            "date": datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
            "load_average_1min": f"{os.getloadavg()[0]:.2f}", "cpu_count": str(os.cpu_count())}


def timed(tree: Path, argv: list[str], cwd: Path, env_extra: dict[str, str] | None = None) -> tuple[float, float, int]:
    """(wall s, CPU s, exit code) of ``python -m calib argv`` in a fresh process with ``tree`` on the path."""
    env = {**os.environ, "PYTHONPATH": str(tree), **(env_extra or {})}
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "calib", *argv], cwd=cwd, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, proc.returncode


def measure(trees: dict[str, Path], repeats: int, demo: bool) -> dict:
    """Every row for every tree: {row: {tree: {"wall_s", "cpu_s", "exit"}}}."""
    work = Path(tempfile.mkdtemp(prefix="calib-startup-"))
    (work / "bad.csv").write_text(BAD_CSV, encoding="utf-8")
    runs: dict[str, dict[str, list]] = {label: {t: [] for t in trees} for label, _, _ in ROWS}
    try:
        for _ in range(repeats):
            for label, argv, _ in ROWS:
                for name, tree in trees.items():
                    runs[label][name].append(timed(tree, argv, work))
        if demo:
            for name, tree in trees.items():
                cache = work / f"numba-cache-{name}"
                for label in ("calib demo, cold numba cache", "calib demo, warm numba cache"):
                    out = work / f"demo-{name}"
                    shutil.rmtree(out, ignore_errors=True)
                    runs.setdefault(label, {t: [] for t in trees})
                    runs[label][name].append(timed(tree, ["demo", "--out", str(out)], work,
                                                   {"NUMBA_CACHE_DIR": str(cache)}))
    finally:
        shutil.rmtree(work, ignore_errors=True)
    table = {}
    for label, per_tree in runs.items():
        table[label] = {name: {"wall_s": statistics.median([r[0] for r in rs]),
                               "cpu_s": statistics.median([r[1] for r in rs]),
                               "exit": sorted({r[2] for r in rs}), "runs": len(rs)} for name, rs in per_tree.items()}
    return table


def markdown(table: dict, where: dict[str, str], st: dict[str, str], repeats: int) -> str:
    names = list(where)
    head = "| command | " + " | ".join(f"{n}: CPU s | {n}: wall s" for n in names) + " |"
    lines = [
        "# Start-up of the calib command line",
        "",
        f"Commit `{st['commit']}`; `{st['command']}`; {st['date']}; load average {st['load_average_1min']} on "
        f"{st['cpu_count']} CPUs at the start.  Generated by benchmarks/startup.py: nothing here is edited by hand.",
        "",
        f"Medians of {repeats} runs (the demo: one run each), each in a fresh `python -m calib` process.  CPU s = user "
        "+ system time of the process: the number to compare on a shared machine, where the wall clock also "
        "measures the other jobs.  Trees: " + ", ".join(f"{n} = {w}" for n, w in where.items()) + ".",
        "",
        head,
        "|---|" + "---:|---:|" * len(names),
    ]
    for label, per_tree in table.items():
        cells = []
        for n in names:
            r = per_tree[n]
            bad = "" if r["exit"] == [_expected(label)] else f" (exit {r['exit']})"
            cells.append(f"{r['cpu_s']:.2f}{bad} | {r['wall_s']:.2f}")
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _expected(label: str) -> int:
    return next((code for lab, _, code in ROWS if lab == label), 0)


def _tree(spec: str, scratch: Path) -> tuple[Path, str]:
    """(folder to put on the path, how the table names it) for ``spec``: a folder, or ``@COMMIT`` of this repository
    extracted into ``scratch``."""
    if spec.startswith("@"):
        commit = _git("rev-parse", "--short", spec[1:])
        if not commit:
            raise SystemExit(f"--tree: {spec[1:]!r} is not a commit of this repository")
        scratch.mkdir(parents=True)
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", commit], capture_output=True, check=True).stdout
        subprocess.run(["tar", "-x", "-C", str(scratch)], input=archive, check=True)
        return scratch, f"commit {commit}"
    path = Path(spec).resolve()
    try:
        rel = str(path.relative_to(ROOT))
        return path, "this checkout" if rel == "." else rel
    except ValueError:
        return path, "a checkout given by path"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tree", action="append", help="NAME=PATH of a source tree (repeatable; default this one)")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--no-demo", action="store_true", help="leave out the demo rows (minutes each)")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "startup.md"))
    a = ap.parse_args()
    specs = dict(t.split("=", 1) for t in a.tree) if a.tree else {"this tree": "."}
    st = stamp()
    with tempfile.TemporaryDirectory(prefix="calib-trees-") as tmp:
        trees, where = {}, {}
        for name, spec in specs.items():
            trees[name], where[name] = _tree(spec, Path(tmp) / name)
        table = measure(trees, a.repeats, not a.no_demo)
    out = Path(a.out)
    out.write_text(markdown(table, where, st, a.repeats), encoding="utf-8")
    out.with_suffix(".json").write_text(json.dumps({"provenance": st, "trees": where, "rows": table}, indent=1) + "\n",
                                        encoding="utf-8")
    print(out.read_text(encoding="utf-8"))


if __name__ == "__main__":
    main()
