"""The hand campaign: method × hand → RMS error, efficiency (ideal and hand-aware bound), NEES.

    python benchmarks/hand_campaign.py --sensor zhou2020_sim_consumer --methods kf_hand --seeds 50 --out X.json
    python benchmarks/hand_campaign.py --sensor mpu9250 --methods kf --seeds 20 --out Y.json
    python benchmarks/hand_campaign.py --table X.json Y.json --plot rmse.png         # the method × hand table
    python benchmarks/hand_campaign.py --sensor mpu9250 --accelerometer estimate --methods kf_hand_joint,kf_session \
        --seeds 20 --out Z.json                 # raw sensor: the joint methods (calib run's setting)
    python benchmarks/hand_campaign.py --accelerometer-table Z.json     # their gyro bias, acc., NEES(15)

The campaigns and tables of docs/hand.md are results of ``python -m benchmarks.results`` (``--list`` names them:
hand_zhou2020_sim_consumer, hand_mpu9250, hand_kf_*, hand_campaign, hand_joint_*, hand_joint), which runs these
commands and stamps what they write.

(cells already in --out are kept: a campaign can be run hand by hand; ``--methods kf_hand`` runs the
hand-aware method's cells alone — each cell's bounds cost one Riccati recursion, ~1 s, beside its seeds)

Every cell is :func:`calib.scoring.montecarlo.monte_carlo` (zhou2020 schedule, 100 Hz, the sensor with its
accelerometer calibrated — only its white noise kept — and ``accelerometer="calibrated"``).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

from calib.app.outputs import write_json_atomic
from calib.scoring.montecarlo import monte_carlo

HANDS = ("ideal", "steady", "typical", "shaky")


def run(sensor: str, seeds: int, methods: tuple[str, ...], out: str, hands: tuple[str, ...] = HANDS,
        accelerometer: str = "calibrated") -> None:
    """Run the cells of ``hands``; cells already in ``out`` (same sensor, methods, accelerometer mode) are kept.
    ``accelerometer="estimate"``: the raw sensor (its accelerometer errors kept) and the methods' joint form
    (calib run's default setting)."""
    cells = {}
    if Path(out).exists():
        old = json.loads(Path(out).read_text())
        if (old.get("sensor") == sensor and old.get("methods") == list(methods)
                and old.get("accelerometer", "calibrated") == accelerometer):
            cells = old["cells"]
    for hand in hands:
        t0 = time.time()
        with tqdm(total=seeds, desc=f"{sensor} {hand}", unit="seed") as bar:
            r = monte_carlo("zhou2020", hand, sensor, seeds, 100.0, methods, progress=bar.update,
                            calibrated_accelerometer=accelerometer == "calibrated", accelerometer=accelerometer)
        cells[hand] = {**r.to_dict(), "seconds": time.time() - t0}
        print(r.summary(), flush=True)
        write_json_atomic(out, {"sensor": sensor, "seeds": seeds, "methods": list(methods), "cells": cells,
                                "accelerometer": accelerometer})


def table(paths: list[str]) -> str:
    rows = ["| sensor | method | hand | S, G RMSE max | ÷ ideal-hand RMSE | eff. vs ideal bound (max S, G) | "
            "eff. vs hand bound (max S, G) | NEES (6) | 95 % band | NEES vs band | statuses |", "|" + "---|" * 11]
    # the hand-aware bound needs kf_hand's PSD: a file without kf_hand borrows the bound of a file with it (same sensor
    # and hand), else its column would be the hand-free bound (kf_hand's with the accelerometer calibrated,
    # kf_hand_joint's with it estimated: the key has the mode) — for S on a warming sensor, the bound of S at the
    # oracle's reference temperature, where a method that states no temperature (kf) is scored
    # (calib.scoring.montecarlo: sqrt_crlb_hand_sg_at_oracle_reference); a file that predates it lends kf_hand's bound
    # of S at its T_r, marked † (the wrong quantity for kf)
    bounds, stale = {}, set()
    for p in paths:
        d = json.load(open(p))
        mode = d.get("accelerometer", "calibrated")
        if any(m.startswith("kf_hand") for m in d["methods"]):
            for hand, c in d["cells"].items():
                if c.get("sqrt_crlb_hand"):
                    key = (d["sensor"], hand, mode)
                    psd = c.get("hand_psd", {})
                    if psd.get("sqrt_crlb_hand_sg_at_oracle_reference"):
                        bounds[key] = np.array(psd["sqrt_crlb_hand_sg_at_oracle_reference"])
                    else:
                        bounds[key] = np.array(c["sqrt_crlb_hand"][3:9])
                        if psd.get("scale_reference_temperature_c"):
                            stale.add(key)
    for p in paths:
        d = json.load(open(p))
        mode = d.get("accelerometer", "calibrated")
        for m in d["methods"]:
            base = max(d["cells"]["ideal"]["methods"][m]["rmse"][3:9]) if "ideal" in d["cells"] else float("nan")
            for hand, c in d["cells"].items():
                st = c["methods"][m]
                rm = max(st["rmse"][3:9])
                eh = max(st["efficiency_hand"][3:9]) if st["efficiency_hand"] else float("nan")
                mark = ""
                if not any(x.startswith("kf_hand") for x in d["methods"]) and (d["sensor"], hand, mode) in bounds:
                    eh = float(np.max(np.array(st["rmse"][3:9]) / bounds[(d["sensor"], hand, mode)]))
                    mark = " †" if (d["sensor"], hand, mode) in stale else ""
                sensor = d["sensor"] + (" (raw)" if mode == "estimate" else "")
                rows.append(
                    f"| {sensor} | {m} | {hand} | {rm:.2e} | {rm / base:.1f} | {max(st['efficiency'][3:9]):.2f} | "
                    f"{eh:.2f}{mark} | {st['nees_mean']:.2f} | {st['nees_band'][0]:.2f}–{st['nees_band'][1]:.2f} | "
                    f"{_where(st['nees_mean'], st['nees_band'])} | "
                    + ", ".join(f"{k} {v}" for k, v in sorted(st["statuses"].items()))
                    + f" ({c['seeds']} seeds) |"
                )
    if any(r.split(" | ")[6].endswith(" †") for r in rows[2:] if r.startswith("| ")):  # only when a row is marked
        rows.append(
            "\n† against kf_hand's bound of S at the temperatures kf_hand stated (its file predates the bound of "
            "S at the oracle's reference temperature, where this method is scored): re-run that kf_hand campaign"
        )
    return "\n".join(rows)


def accelerometer_table(paths: list[str]) -> str:
    """With the accelerometer estimated: per sensor × hand × method the RMSE (max over the axes) of the gyro bias
    (rad/s), accelerometer bias (m/s²), scale and non-orthogonality, the accelerometer's err/σ RMS range, the NEES
    of the 15 filter parameters (S, G and the accelerometer's nine) against its band, and the "ok" seeds whose
    S, G error their σ does not cover (``ok_wrong``)."""
    rows = ["| sensor | hand | method | gyro b | acc b | acc S | acc G | acc err/σ RMS | NEES (15) | 95 % band | vs "
            "band | ok but NEES(6) > χ²₆ 99.9 % |",
            "|" + "---|" * 12]
    for p in paths:
        d = json.load(open(p))
        if d.get("accelerometer") != "estimate":
            continue
        for hand in [h for h in HANDS if h in d["cells"]]:
            for m in d["methods"]:
                st = d["cells"][hand]["methods"][m]
                r, z = st["rmse"], st["z_rms"]
                nf, bf = st.get("nees_filter_mean", float("nan")), st.get("nees_filter_band", [float("nan")] * 2)
                rows.append(
                    f"| {d['sensor']} | {hand} | {m} | {max(r[0:3]):.1e} | {max(r[9:12]):.1e} | {max(r[12:15]):.1e} | "
                    f"{max(r[15:18]):.1e} | {min(z[9:18]):.1f}–{max(z[9:18]):.1f} | {nf:.2f} | {bf[0]:.2f}–{bf[1]:.2f} "
                    f"| {_where(nf, bf)} | {st.get('ok_wrong', 'n/a')} |"
                )
    return "\n".join(rows)


def _where(nees: float, band: list[float]) -> str:
    """"in", or "low" (σ pessimistic) / "high" (σ optimistic) against the 95 % band."""
    return "in" if band[0] <= nees <= band[1] else ("low" if nees < band[0] else "high")


def plot(paths: list[str], out: str) -> None:
    """RMS error of S, G (max over the six) per hand, one line per sensor × method (log scale)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.2))
    for p in paths:
        d = json.load(open(p))
        hands = [h for h in HANDS if h in d["cells"]]
        for m in d["methods"]:
            ax.plot(hands, [max(d["cells"][h]["methods"][m]["rmse"][3:9]) for h in hands], marker="o",
                    label=f"{d['sensor']}{' (raw)' if d.get('accelerometer') == 'estimate' else ''}: {m}")
    ax.set_yscale("log")
    ax.set_ylabel("RMS error, max over S and G")
    modes = {json.load(open(p)).get("accelerometer", "calibrated") for p in paths}
    ax.set_title("zhou2020 schedule, accelerometer " + (modes.pop() if len(modes) == 1 else "calibrated / estimated "
                                                                                            "(raw)"))
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out, dpi=110)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sensor", default="zhou2020_sim_consumer")
    ap.add_argument("--seeds", type=int, default=50)
    ap.add_argument("--methods", default="kf,kf_hand")
    ap.add_argument("--hands", default=",".join(HANDS), help="comma-separated hand presets (default all four)")
    ap.add_argument(
        "--accelerometer",
        default="calibrated",
        choices=("calibrated", "estimate"),
        help="calibrated: the sensor's accelerometer errors removed, the methods' calibrated form (default); "
        "estimate: the raw sensor and the joint methods (kf_session, kf_hand_joint)",
    )
    ap.add_argument("--out")
    ap.add_argument("--table", nargs="*")
    ap.add_argument("--plot", help="with --table: also write this PNG")
    ap.add_argument("--accelerometer-table", nargs="*", help="campaign JSONs with the accelerometer estimated: their "
                    "gyro bias, accelerometer and NEES(15) table")
    a = ap.parse_args()
    if a.accelerometer_table:
        print(accelerometer_table(a.accelerometer_table))
        return
    if a.table:
        print(table(a.table))
        if a.plot:
            plot(a.table, a.plot)
        return
    run(a.sensor, a.seeds, tuple(a.methods.split(",")), a.out, tuple(a.hands.split(",")), a.accelerometer)


if __name__ == "__main__":
    np.seterr(all="ignore")
    main()
