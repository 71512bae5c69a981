"""A sensor behind an output low-pass (a DLPF) below the white-noise band: the rest bias's and S, G's σ (results:
output_lowpass; docs/hand.md, "The assumptions it checks on measured data").

    python benchmarks/output_lowpass.py --cutoffs 41,20,10,5 --seeds 30 --out docs/results/output_lowpass.json
    python benchmarks/output_lowpass.py --method kf_hand_joint --cutoffs 10 --seeds 30 --out X.json
    python benchmarks/output_lowpass.py --table docs/results/output_lowpass.json X.json    # the Markdown table

gyrosim's MPU-9250 preset, its accelerometer calibrated (white noise only) unless the method estimates it, with both
triads' ``bandwidth`` effect at each cut-off (the preset's own effects, both set to the same
cut-off), the ideal hand (one MuJoCo truth), zhou2020 schedule, 100 Hz: :func:`calib.scoring.montecarlo.monte_carlo` per
cut-off.  Prints the rest bias's err/σ RMS per axis, NEES of S, G against its band and the statuses.
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from gyrosim.sensor_model import load_sensor

from calib.app.outputs import write_json_atomic
from calib.scoring.montecarlo import monte_carlo


def with_output_lowpass(cutoff_hz: float, estimate_accelerometer: bool):
    """The MPU-9250 preset with both triads' output low-pass at ``cutoff_hz`` (Hz)."""
    # its accelerometer has a bandwidth effect: kept (calibrated: with the white noise only)
    m = load_sensor("mpu9250")
    acc = tuple(replace(e, cutoff_hz=cutoff_hz) if e.kind == "bandwidth" else e for e in m.accelerometer
                if estimate_accelerometer or e.is_white_noise or e.kind == "bandwidth")
    gyro = tuple(replace(e, cutoff_hz=cutoff_hz) if e.kind == "bandwidth" else e for e in m.gyro)
    calibrated = "" if estimate_accelerometer else ", accelerometer calibrated"
    return replace(m, accelerometer=acc, gyro=gyro, name=f"mpu9250 (output low-pass {cutoff_hz:g} Hz{calibrated})")


def table(paths: list[str]) -> str:
    """The runs of ``paths`` as one Markdown table, a row per method and cut-off."""
    lines = ["| method | output low-pass f_c (Hz) | seeds | rest bias err/σ RMS x, y, z | NEES(6) S, G | 95 % band | "
             "statuses |", "|" + "---|" * 7]
    for p in paths:
        d = json.loads(Path(p).read_text())
        for r in d["rows"].values():
            st = ", ".join(f"{k} {v}" for k, v in sorted(r["statuses"].items()))
            lines.append(f"| {d['method']} | {r['cutoff_hz']:g} | {d['seeds']} | "
                         f"{', '.join(f'{v:.2f}' for v in r['bias_z_rms'])} | {r['nees']:.2f} | "
                         f"{r['nees_band'][0]:.2f}–{r['nees_band'][1]:.2f} | {st} |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cutoffs", default="41,20,10,5", help="output low-pass cut-offs (Hz), comma-separated")
    ap.add_argument("--seeds", type=int, default=30)
    ap.add_argument("--method", default="kf_hand")
    ap.add_argument("--out")
    ap.add_argument("--table", nargs="+", help="print the Markdown table of these runs' JSON instead")
    a = ap.parse_args()
    if a.table:
        print(table(a.table))
        return
    if not a.out:
        ap.error("--out is required for a run")
    estimate = a.method in ("kf_hand_joint", "kf_session")
    rows = {}
    print(f"{'f_c (Hz)':>8}  {'bias err/σ RMS x, y, z':>24}  {'NEES(6)':>7}  {'band':>11}  statuses", flush=True)
    for fc in (float(x) for x in a.cutoffs.split(",")):
        t0 = time.time()
        r = monte_carlo("zhou2020", "ideal", with_output_lowpass(fc, estimate), a.seeds, 100.0, (a.method,),
                        accelerometer="estimate" if estimate else "calibrated")
        st = r.methods[a.method]
        rows[f"{fc:g}"] = {"cutoff_hz": fc, "bias_z_rms": st.z_rms[:3].tolist(), "sg_z_rms": st.z_rms[3:9].tolist(),
                           "nees": st.nees_mean, "nees_band": list(st.nees_band), "statuses": st.statuses,
                           "rmse": st.rmse.tolist(), "seconds": time.time() - t0}
        print(f"{fc:8g}  {', '.join(f'{v:.2f}' for v in st.z_rms[:3]):>24}  {st.nees_mean:7.2f}  "
              f"{st.nees_band[0]:.2f}–{st.nees_band[1]:.2f}  {st.statuses}", flush=True)
        write_json_atomic(a.out, {"seeds": a.seeds, "hand": "ideal", "method": a.method, "rows": rows})


if __name__ == "__main__":
    np.seterr(all="ignore")
    main()
