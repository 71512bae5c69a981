"""Every command of the README, run as written in a fresh folder, with its exit code and wall time.

    python benchmarks/readme_examples.py [--out docs/results/readme_examples.md]

The blocks are read from README.md itself (not copied here), in order:

* the set-up's main job, ``calib demo --out out``, first with an empty numba cache (``NUMBA_CACHE_DIR`` a fresh
  folder: what the first run of a fresh install costs) and then again with that cache;
* the command-line quick start, command by command (``rerun cal.rrd`` opens a viewer: listed, not run);
* the Python quick start, as a script;
* "your own IMU": its commands run on files of the shape they name — ``imu.csv``, the quick start's session written
  as a logger would (time in s, gyro in °/s, accelerometer in g) and ``static.csv``, an hour of a still board
  (white noise at an MPU-9250's datasheet densities, MEMS-class bias random walks on both triads), seeded.

The ``pip install`` halves of the set-up are measured by ``benchmarks/install_weight.sh``.  A row's time is the
wall clock of its process (the machine's load average at the start is in the stamp: on a shared machine read it
with that).  The table is written with the commit, the command line and the date.
"""

from __future__ import annotations

import argparse
import math
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks import provenance  # noqa: E402

ROOT = provenance.ROOT
VIEWERS = ("rerun",)   # commands that open a window: listed, not run


def readme_blocks(text: str) -> list[tuple[str, str]]:
    """(language, body) of every fenced block of the README, in order."""
    return [(m.group(1), m.group(2)) for m in re.finditer(r"```(\w+)\n(.*?)```", text, re.S)]


def commands(body: str) -> list[str]:
    """The commands of a bash block, comments stripped."""
    return [c for line in body.splitlines() if (c := line.split("  #", 1)[0].split(" # ", 1)[0].strip())]


def _write_own_imu_files(folder: Path, rng: np.random.Generator) -> None:
    """imu.csv (the quick start's rec.h5 in a logger's units) and static.csv (an hour still) in ``folder``."""
    from gyrosim.recording import load_hdf5

    rec = load_hdf5(folder / "rec.h5")
    rows = np.column_stack([rec.t_s, np.degrees(rec.gyro_rad_s), rec.acc_m_s2 / 9.80665])
    np.savetxt(folder / "imu.csv", rows, delimiter=",", fmt="%.7g",
               header="time_s,gyro_x_dps,gyro_y_dps,gyro_z_dps,acc_x_g,acc_y_g,acc_z_g", comments="")
    rate, n = 100.0, 360_000
    t = np.arange(n) / rate
    # white noise: rad/s/√Hz, m/s²/√Hz (MPU-9250 datasheet); bias random walks: rad/s/√s, m/s²/√s (MEMS-class)
    n_g, n_a, k_g, k_a = 1.75e-4, 2.9e-3, 2e-5, 3e-4
    gyro = rng.normal(0, n_g * math.sqrt(rate), (n, 3)) + np.cumsum(rng.normal(0, k_g / math.sqrt(rate), (n, 3)), 0)
    acc = (rng.normal(0, n_a * math.sqrt(rate), (n, 3)) + np.cumsum(rng.normal(0, k_a / math.sqrt(rate), (n, 3)), 0)
           + [0.0, 0.0, 9.80665])
    np.savetxt(folder / "static.csv", np.column_stack([t, gyro, acc]), delimiter=",", fmt="%.7g",
               header="time_s,gyro_x,gyro_y,gyro_z,acc_x,acc_y,acc_z", comments="")


def _run(cmd: str, cwd: Path, env: dict) -> tuple[int, float, str]:
    t0 = time.perf_counter()
    p = subprocess.run(cmd, shell=True, cwd=cwd, env=env, capture_output=True, text=True)
    last = (p.stderr.strip() or p.stdout.strip()).splitlines()
    return p.returncode, time.perf_counter() - t0, last[-1][:100] if last else ""


def run_all(folder: Path, seed: int = 1) -> list[dict]:
    """Run the README's examples in ``folder``; one row per command."""
    blocks = readme_blocks((ROOT / "README.md").read_text(encoding="utf-8"))
    env = {**os.environ, "NUMBA_CACHE_DIR": str(folder / "numba-cache")}
    rows: list[dict] = []

    def row(section: str, cmd: str, note: str = "") -> None:
        if cmd.split()[0] in VIEWERS:
            rows.append({"section": section, "command": cmd, "exit": None, "seconds": None, "note": "opens a viewer"})
            return
        code, sec, last = _run(cmd, folder, env)
        rows.append({"section": section, "command": cmd, "exit": code, "seconds": round(sec, 1),
                     "note": note or (last if code else "")})
        print(f"{code:>3} {sec:7.1f} s  {cmd}", flush=True)

    setup = next(body for lang, body in blocks if lang == "bash" and "calib demo" in body)
    demo = next(c.split("&&", 1)[1].strip() for c in commands(setup) if "calib demo" in c)
    row("set-up", demo, "empty numba cache (a fresh install's first run)")
    row("set-up", demo.replace("--out out", "--out out2"), "numba cache from the run above")
    cli = next(body for lang, body in blocks if lang == "bash" and "gyrosim simulate" in body)
    for cmd in commands(cli):
        row("command-line quick start", cmd)
    python = next(body for lang, body in blocks if lang == "python")
    (folder / "quickstart.py").write_text(python, encoding="utf-8")
    row("Python quick start", "python quickstart.py")
    own = next(body for lang, body in blocks if lang == "bash" and "imu.csv" in body)
    _write_own_imu_files(folder, np.random.default_rng(seed))
    for cmd in commands(own):
        row("your own IMU (imu.csv, static.csv generated)", cmd)
    return rows


def markdown(rows: list[dict]) -> str:
    out = ["# The README's examples: exit code and wall time", "",
           "Every command of README.md run as written, in order, in a fresh folder (`python "
           "benchmarks/readme_examples.py`; how: its docstring).", "",
           "| section | command | exit | wall s | note |", "|---|---|---|---|---|"]
    for r in rows:
        code = "—" if r["exit"] is None else str(r["exit"])
        sec = "—" if r["seconds"] is None else f"{r['seconds']:.1f}"
        out.append(f"| {r['section']} | `{r['command']}` | {code} | {sec} | {r['note'].replace('|', '/')} |")
    return "\n".join(out) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=str(ROOT / "docs" / "results" / "readme_examples.md"))
    ap.add_argument("--seed", type=int, default=1, help="seed of the generated static record (default 1)")
    args = ap.parse_args(argv)
    load = os.getloadavg()[0]
    with tempfile.TemporaryDirectory(prefix="readme-examples-") as tmp:
        rows = run_all(Path(tmp), args.seed)
    provenance.write_markdown(args.out, markdown(rows), load_average_at_start=round(load, 2),
                              cpu_count=os.cpu_count())
    print(f"wrote {args.out}")
    return 0 if all(r["exit"] in (0, None) for r in rows) else 1


if __name__ == "__main__":
    raise SystemExit(main())
