"""The closeloop's magnetometer part on BROAD trials 30 and 34, as in docs/magnetometer.md.

    OMP_NUM_THREADS=1 python benchmarks/closeloop_mag_broad.py > out.json
    python benchmarks/closeloop_mag_broad.py --table out.json           # its Markdown table

(``python -m benchmarks.results --only magnetometer_closeloop_broad,magnetometer_closeloop_broad_table`` runs both
and stamps what they write.)

Runs the whole loop (gyro + magnetometer) on both trials as ``calib closeloop`` does, and the
magnetometer loop alone on trial 34's stretch with the magnet on the board (44–101 s, found by
``calib mag``); prints one JSON object.  Needs the BROAD files in ../shared/data (GYROSIM_DATA).
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

from gyrosim.loaders import data_root, load_broad
from gyrosim.recording import Recording, Truth

from calib.closeloop import run_closeloop
from calib.closeloop.mag.loop import run_mag_loop

KEYS = (
    "reference",
    "found",
    "unexplained",
    "not_tested",
    "not_distinguished",
    "error_before",
    "error_after",
    "metrics",
    "rejected",
    "notes",
)


def table(path: str) -> str:
    """The JSON this script prints, as the Markdown table of docs/magnetometer.md: per recording what the
    magnetometer loop found, each held-out metric declared → after (its verdict), and the disturbances reported."""
    data = json.loads(Path(path).read_text())
    units = {"held_out_field_residual_rms": "field residual µT", "held_out_field_magnitude_rms": "|B| µT",
             "held_out_heading_rms_deg": "heading °", "held_out_inclination_rms_deg": "inclination °"}
    lines = ["| recording | found (magnetometer) | " + " | ".join(units.values()) + " | disturbances reported |",
             "|" + "---|" * (len(units) + 3)]
    for name, rec in data.items():
        if name == "provenance":
            continue
        m = rec["magnetometer"]
        found = "; ".join(
            f"{f['effect']} (" + ", ".join(f"{k} {v['value']:+.3g} ± {v['sigma']:.2g}" for k, v in f["params"].items())
            + ")" for f in m["found"]) or "nothing"
        metrics = {x["name"]: x for x in m["metrics"]}
        cells = [f"{metrics[k]['before']:.2f} → {metrics[k]['after']:.2f} ({metrics[k]['verdict']})" if k in metrics
                 else "—" for k in units]
        dist = m.get("unexplained", {}).get("disturbances", [])
        spans = ", ".join(f"{d['t_start_s']:.0f}–{d['t_end_s']:.0f} s" for d in dist)
        peak = max((d["max_field_deviation_uT"] for d in dist), default=0.0)
        lines.append(f"| {name} | {found} | " + " | ".join(cells)
                     + f" | {len(dist)}{': ' + spans + f'; up to {peak:.0f} µT' if dist else ''} |")
    return "\n".join(lines)


def main() -> int:
    if len(sys.argv) == 3 and sys.argv[1] == "--table":
        print(table(sys.argv[2]))
        return 0
    out = {}
    for name in ("30_disturbed_stationary_magnet_C", "34_disturbed_attached_magnet_3cm"):
        rec = load_broad(data_root() / "broad" / f"{name}.hdf5")
        t0 = time.perf_counter()
        res = run_closeloop(rec)
        m = res.magnetometer.to_json()
        out[name] = {"seconds": time.perf_counter() - t0, "gyro_found": [f.effect for f in res.found],
                     "magnetometer": {k: m[k] for k in KEYS}}
        if name.startswith("34"):
            s = (rec.t_s >= 44.0) & (rec.t_s <= 101.0)
            tr = rec.truth
            cut = Recording(
                t_s=rec.t_s[s],
                gyro_rad_s=rec.gyro_rad_s[s],
                acc_m_s2=rec.acc_m_s2[s],
                mag_ut=rec.mag_ut[s],
                truth=Truth(
                    quat_nb=tr.quat_nb[s], position_nav_m=None if tr.position_nav_m is None else tr.position_nav_m[s]
                ),
            )
            m = run_mag_loop(cut).to_json()
            out[name + " (44-101 s, magnet on)"] = {"magnetometer": {k: m[k] for k in KEYS}}
    json.dump(out, sys.stdout, indent=1, default=float)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
