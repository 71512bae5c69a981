"""Hands we did not tune for: each imperfection of a hand preset switched off alone, and the estimators' σ there.

    python benchmarks/hand_variants.py --seeds 50 --out X.json       # ~1 h (results: hand_variants)
    python benchmarks/hand_variants.py --table X.json                  # its Markdown table
    python benchmarks/hand_variants.py --seeds 2 --variants wobble --cells zhou2020_sim_consumer:kf_hand   # a smoke run

The presets (ideal, steady, typical, shaky) scale all imperfections together, and every estimator in this
repository was tuned on them.  A user's hand is not a preset: one holds the device rigidly but far from the wrist
(a lever arm and no wobble), another turns cleanly on a supported forearm (no sway).  Each row here is the base
preset (shaky by default) with one imperfection switched off (:meth:`gyrosim.hand.Hand.without`; the others keep
their exact random draws, seed for seed), or all but the pivot ("pivot only": a deterministic lever arm).

Each cell is :func:`calib.scoring.montecarlo.monte_carlo` (zhou2020 schedule, 100 Hz): ``kf_hand`` with the
accelerometer calibrated (the sensor's white noise only), ``kf_hand_joint`` with the raw sensor (its accelerometer
estimated). The table gives NEES(6) over the gyro's S and G against χ²₆'s 95 % band for the seed count, the RMS of err/σ
of each of the six (an honest σ gives 1; its 95 % band for 50 seeds is about [0.81, 1.19]), and the statuses — the cells
that matter are those where NEES is high and the status still says ``ok``.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from tqdm import tqdm

from gyrosim.hand import IMPERFECTIONS, load_hand

from calib.app.outputs import write_json_atomic
from calib.scoring.montecarlo import monte_carlo

# (sensor, method): kf_hand scores the accelerometer-calibrated sensor, the joint the raw one
CELLS = (("zhou2020_sim_consumer", "kf_hand"), ("zhou2020_sim_consumer", "kf_hand_joint"),
         ("mpu9250", "kf_hand"), ("mpu9250", "kf_hand_joint"))
VARIANTS = ("tremor", "tremor_rotation", "sway", "wobble", "pivot_only")
SG = slice(3, 9)      # the gyro's S and G in monte_carlo's parameter order (bias, S, G, …)


def variant(base: str, name: str):
    """The base preset with ``name`` switched off; ``pivot_only``: every imperfection but the pivot."""
    hand = load_hand(base)
    if name == "pivot_only":
        return hand.without(*(p for p in IMPERFECTIONS if p != "pivot"))
    return hand.without(name)


def run(base: str, seeds: int, variants: tuple[str, ...], cells: tuple[tuple[str, str], ...], out: str | None) -> dict:
    """Run every (variant, cell); rows already in ``out`` (same base and seeds) are kept, so a run can resume."""
    rows: dict = {}
    if out and Path(out).exists():
        old = json.loads(Path(out).read_text())
        if old.get("base") == base and old.get("seeds") == seeds:
            rows = old["rows"]
    for v in variants:
        hand = variant(base, v)
        for sensor, method in cells:
            key = f"{v}|{sensor}|{method}"
            if key in rows:
                continue
            joint = method == "kf_hand_joint"
            t0 = time.time()
            with tqdm(total=seeds, desc=f"{hand.name} {sensor} {method}", unit="seed") as bar:
                r = monte_carlo("zhou2020", hand, sensor, seeds, 100.0, (method,), progress=bar.update,
                                calibrated_accelerometer=not joint, accelerometer="estimate" if joint else "calibrated")
            m = r.to_dict()["methods"][method]
            rows[key] = {"variant": v, "hand": hand.name, "sensor": sensor, "method": method,
                         "nees_mean": m["nees_mean"], "nees_band": m["nees_band"], "z_rms": m["z_rms"][SG],
                         "statuses": m["statuses"], "ok_wrong": m["ok_wrong"], "seconds": time.time() - t0}
            if out:
                write_json_atomic(out, {"base": base, "seeds": seeds, "rows": rows})
    return {"base": base, "seeds": seeds, "rows": rows}


def table(data: dict) -> str:
    """The hand variants' table (docs/results/hand_variants.md): one row per (variant, sensor, method)."""
    lines = [
        f"base hand: {data['base']}, {data['seeds']} seeds per row",
        "| switched off | sensor | method | NEES(6) | 95 % band | side "
        "| err/σ RMS S_x S_y S_z G_x G_y G_z | statuses |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in data["rows"].values():
        lo, hi = r["nees_band"]
        side = "in" if lo <= r["nees_mean"] <= hi else ("high" if r["nees_mean"] > hi else "low")
        st = ", ".join(f"{k} {v}" for k, v in sorted(r["statuses"].items()))
        lines.append(f"| {r['variant']} | {r['sensor']} | {r['method']} | {r['nees_mean']:.2f} | {lo:.2f}–{hi:.2f} | "
                     f"{side} | {' '.join(f'{z:.2f}' for z in r['z_rms'])} | {st} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", default="shaky", help="hand preset the variants start from (default shaky)")
    ap.add_argument("--seeds", type=int, default=50)
    ap.add_argument("--variants", default=",".join(VARIANTS),
                    help=f"comma-separated, from {', '.join(VARIANTS)}")
    ap.add_argument("--cells", default=",".join(f"{s}:{m}" for s, m in CELLS),
                    help="comma-separated sensor:method (kf_hand: accelerometer calibrated; kf_hand_joint: raw)")
    ap.add_argument("--out", help="JSON written after every row (a run resumes from it)")
    ap.add_argument("--table", help="print the table of an earlier --out and exit")
    a = ap.parse_args(argv)
    if a.table:
        print(table(json.loads(Path(a.table).read_text())))
        return 0
    variants = tuple(v for v in a.variants.split(",") if v)
    bad = [v for v in variants if v not in VARIANTS]
    if bad:
        ap.error(f"unknown variant(s) {bad}; choose from {', '.join(VARIANTS)}")
    cells = tuple(tuple(c.split(":", 1)) for c in a.cells.split(",") if c)
    if any(len(c) != 2 or c[1] not in ("kf_hand", "kf_hand_joint") for c in cells):
        ap.error("--cells takes sensor:method pairs, method kf_hand or kf_hand_joint")
    print(table(run(a.base, a.seeds, variants, cells, a.out)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
