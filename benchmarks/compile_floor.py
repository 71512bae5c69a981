"""What the first compile of the calibration filter costs, and what numba's own settings take off it.

    python benchmarks/compile_floor.py [--repeats 1]

The first ``calib demo`` or ``calib run`` on a machine compiles the filter's loop (:mod:`calib.session.kernel`) into
numba's cache; later runs load it.  This prints one row per numba setting, each measured in a fresh Python process
with an empty cache folder (``NUMBA_CACHE_DIR``), so every row compiles from scratch:

* compile s: :func:`calib.session.kernel.warm_up` — what the demo's background process does;
* LLVM s: of that, the time numba held LLVM's lock (optimising and emitting machine code); the rest is numba's
  own Python: reading the bytecode, type inference, lowering to LLVM IR;
* load s, run s: a second process with the cache just written: loading the loop, then the paper's filter over
  20 000 samples (how fast the setting's code runs);
* ratio: compile s against the default row of this run.

The settings are environment variables numba reads at import (``NUMBA_OPT``: LLVM's optimisation level, 3 by
default; ``NUMBA_LOOP_VECTORIZE`` / ``NUMBA_SLP_VECTORIZE``: LLVM's vectorisers).  They change only how the loop is
compiled, not what it computes.  Printed as Markdown; ``python -m benchmarks.results --only compile_floor`` stamps
it into docs/results/compile_floor.md.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

SETTINGS = (
    ("default (NUMBA_OPT=3, vectorisers on)", {}),
    ("NUMBA_OPT=1", {"NUMBA_OPT": "1"}),
    ("NUMBA_OPT=0", {"NUMBA_OPT": "0"}),
    ("vectorisers off", {"NUMBA_LOOP_VECTORIZE": "0", "NUMBA_SLP_VECTORIZE": "0"}),
)

# the child that compiles: warm_up() with numba's LLVM-lock events recorded (top-level spans summed)
COMPILE = """
import json, time
from numba.core import event
t0 = time.perf_counter()
from calib.session.kernel import warm_up
t1 = time.perf_counter()
with event.install_recorder("numba:llvm_lock") as rec:
    warm_up()
t2 = time.perf_counter()
depth, start, llvm = 0, 0.0, 0.0
for ts, ev in rec.buffer:
    if ev.is_start:
        depth, start = depth + 1, (ts if depth == 0 else start)
    else:
        depth -= 1
        llvm += (ts - start) if depth == 0 else 0.0
print(json.dumps({"import_s": t1 - t0, "compile_s": t2 - t1, "llvm_s": llvm}))
"""

# the child that loads the loop from the cache the compile wrote, then runs the paper's filter over 20 000 samples
# (200 s at 100 Hz) of a device turning about all three axes: the per-sample speed the setting compiled
LOAD = """
import json, time
import numpy as np
from calib.session.kernel import run_filter, warm_up
from calib.session.model import PAPER, FilterConfig, initial_covariance
t0 = time.perf_counter(); warm_up(); t1 = time.perf_counter()
n, cfg = 20000, FilterConfig(arw_rad_s_sqrt_hz=1e-4, vrw_m_s2_sqrt_hz=1e-3)
t = np.arange(n) / 100.0
gyro = np.stack([np.sin(0.5 * t), np.cos(0.3 * t), 0.5 * np.sin(0.2 * t)], axis=-1)[None]
acc = np.zeros((1, n, 3)); acc[..., 2] = cfg.gravity_m_s2
run_filter(gyro, acc, t, np.array([1.0, 0.0, 0.0, 0.0]), np.zeros(18), initial_covariance(PAPER, cfg), PAPER, cfg,
           100.0)
t2 = time.perf_counter()
print(json.dumps({"load_s": t1 - t0, "run_s": t2 - t1}))
"""


def _child(code: str, env_extra: dict[str, str], cache: str) -> dict:
    """Run ``code`` in a fresh interpreter with this checkout first on the path and ``cache`` as numba's cache."""
    env = dict(os.environ, NUMBA_CACHE_DIR=cache, OMP_NUM_THREADS="1", **env_extra)
    env["PYTHONPATH"] = str(ROOT) + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    if out.returncode != 0:
        raise SystemExit(f"the child failed (exit {out.returncode}): {out.stderr.strip().splitlines()[-1:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def measure(repeats: int) -> list[dict]:
    """One dict per setting: medians over ``repeats`` compiles, each into an empty cache folder."""
    rows = []
    for label, env_extra in SETTINGS:
        runs = []
        for _ in range(repeats):
            with tempfile.TemporaryDirectory(prefix="numba-cache-") as cache:
                runs.append({**_child(COMPILE, env_extra, cache), **_child(LOAD, env_extra, cache)})
        rows.append({"setting": label, **{k: statistics.median(r[k] for r in runs) for k in runs[0]}})
        print(f"  {label}: compile {rows[-1]['compile_s']:.1f} s", file=sys.stderr, flush=True)
    return rows


def markdown(rows: list[dict], repeats: int) -> str:
    base = rows[0]["compile_s"]
    lines = [f"Medians of {repeats} compile(s) per row, each in a fresh process into an empty numba cache; load and "
             "run in a second process from that cache: the paper's filter over 20 000 samples.  "
             f"{os.cpu_count()} CPUs; load average {os.getloadavg()[0]:.2f} at the end.", "",
             "A load s near the compile s means the second process did not find the loop in the cache and compiled it "
             "again.",
             "",
             "| numba setting | compile s | of which LLVM s | ratio | load s | run s |",
             "|---|---:|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['setting']} | {r['compile_s']:.1f} | {r['llvm_s']:.1f} | {r['compile_s'] / base:.2f} | "
                     f"{r['load_s']:.2f} | {r['run_s']:.3f} |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=1, help="compiles per setting (median; default 1)")
    args = ap.parse_args()
    print(markdown(measure(max(1, args.repeats)), max(1, args.repeats)))


if __name__ == "__main__":
    main()
