"""The noise-inflation figure on an independent record: white + flicker + random walk, 1 h at 100 Hz (docs/noise.md).

    python benchmarks/noise_example.py --csv rec.csv            # the record (tests/independent_noise.py, numpy only)
    calib noise rec.csv --gyro-unit deg/s --acc-unit g --json ex.json --png ex.png
    python benchmarks/noise_example.py --table ex.json         # the inflation table of that JSON

The record is drawn without gyrosim or calib (Kasdin–Walter flicker, Kalibr's random-walk recursion), seed 0,
gyro N = 0.01 rad/s/√Hz, B = 0.015 rad/s, K = 3.2e-3 rad/s²/√Hz (the white + flicker + rw truth of
benchmarks/noise_mc.py: flicker floor at 1–30 s).  The table is ``calib noise``'s ``inflation`` block: the factor on
the white density that a filter aided every h seconds needs, for a white-only model, white + random walk (Kalibr's
two numbers) and the chosen model.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))  # the independent generator

import independent_noise as inoise  # noqa: E402

RATE_HZ, HOURS, SEED = 100.0, 1.0, 0
N, B, K = 0.01, 0.015, 3.2e-3


def record(path: str) -> None:
    n = int(RATE_HZ * 3600 * HOURS)
    rng = np.random.default_rng(SEED)
    noise = (inoise.white(n, RATE_HZ, N, rng) + inoise.flicker(n, B, rng)
             + inoise.random_walk(n, RATE_HZ, K, rng))
    inoise.write_csv(path, RATE_HZ, noise, triad="gyro")


def table(path: str) -> str:
    """The inflation factor per axis and aiding interval h (max over Allan τ ≤ h) for the three filter models."""
    d = json.loads(Path(path).read_text())
    inf = d["inflation"]
    models = d.get("axes", [])
    hs = [h for h in next(iter(inf["axes"]))["white_only"]["max_over_horizon"]]
    lines = ["| axis | model of the filter | " + " | ".join(f"aided every {float(h):g} s" for h in hs) + " |",
             "|" + "---|" * (len(hs) + 2)]
    for i, ax in enumerate(inf["axes"]):
        chosen = models[i].get("model", "chosen") if i < len(models) and isinstance(models[i], dict) else "chosen"
        for label, key in (("white only", "white_only"), ("white + random walk (Kalibr)", "white_plus_random_walk"),
                           (f"the chosen model ({chosen})", "chosen_model")):
            lines.append(f"| {ax['axis']} | {label} | "
                         + " | ".join(f"{ax[key]['max_over_horizon'][h]['factor']:.2f}" for h in hs) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--csv", help="write the record here")
    ap.add_argument("--table", help="print the inflation table of calib noise's JSON")
    a = ap.parse_args(argv)
    if a.csv:
        record(a.csv)
    if a.table:
        print(table(a.table))
    if not (a.csv or a.table):
        ap.error("--csv or --table")
    return 0


if __name__ == "__main__":
    sys.exit(main())
