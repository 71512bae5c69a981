"""Which of the MPU-9250 preset's gyro effects sets kf_hand's excess over the hand-aware bound (results:
mpu9250_ablation, mpu9250_warm_ablation; docs/hand.md, "What the campaigns show").

    python benchmarks/mpu9250_ablation.py --seeds 50 --out docs/results/mpu9250_ablation.json
    python benchmarks/mpu9250_ablation.py --base warmup,g_sensitivity --method kf_hand --seeds 200 \
        --variants full,-bias_instability,-scale_nonlinearity,-scale_nonlinearity-bias_instability,... --out X.json

The ideal hand (its MuJoCo truth is simulated once), the preset with its accelerometer calibrated (white noise
only), zhou2020 schedule, 100 Hz, kf_hand on the user's view of each file; one row per variant, each removing one
effect.  An effect is *neutralised in place* (zero coefficients and spreads, an infinite bandwidth, a 1e-12 LSB,
no self-heating) rather than dropped, so that every other draw of a seed (device and noise streams are spawned
per effect, by position) stays the same: the rows are paired.  Each row is :func:`calib.scoring.montecarlo.monte_carlo`
(its bound included, with that variant's own median q_b).
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

ALL = ("g_sensitivity", "temperature_bias", "temperature_scale", "scale_nonlinearity", "bias_instability",
       "random_walk", "bandwidth", "quantization")
VARIANTS = {
    "full": (),
    "-g_sensitivity": ("g_sensitivity",),
    "-temperature_bias": ("temperature_bias",),
    "-temperature_scale": ("temperature_scale",),
    "-warm-up": ("warmup",),
    "-scale_nonlinearity": ("scale_nonlinearity",),
    "-bias_instability": ("bias_instability",),
    "-random_walk": ("random_walk",),
    "-bandwidth": ("bandwidth",),
    "-quantization": ("quantization",),
    "-scale_nonlinearity-bias_instability": ("scale_nonlinearity", "bias_instability"),
    "-scale_nonlinearity-bias_instability-random_walk": ("scale_nonlinearity", "bias_instability", "random_walk"),
    "white noise + bandwidth": tuple(e for e in ALL if e != "bandwidth"),
    "white noise + quantization": tuple(e for e in ALL if e != "quantization"),
    "white noise only": ALL,
}


def neutral(e):
    """The effect with no effect, same position in the preset (module docstring)."""
    k = e.kind
    if k in ("g_sensitivity", "scale_nonlinearity"):
        return replace(e, value=np.zeros_like(e.value), value_sigma=np.zeros_like(e.value_sigma))
    if k in ("temperature_bias", "temperature_scale"):
        return replace(
            e, coefficients=np.zeros_like(e.coefficients), coefficients_sigma=np.zeros_like(e.coefficients_sigma)
        )
    if k in ("bias_instability", "random_walk"):
        return replace(e, value=np.zeros(3))
    if k == "bandwidth":
        return replace(e, cutoff_hz=1e9)
    if k == "quantization":
        return replace(e, lsb=np.full(3, 1e-12))
    raise ValueError(k)


def variant(drop: tuple[str, ...]):
    m = load_sensor("mpu9250")
    m = replace(m, accelerometer=tuple(e for e in m.accelerometer if e.is_white_noise))
    for d in drop:
        if d == "warmup":
            m = replace(m, thermal=replace(m.thermal, self_heating_c=0.0))
        else:
            m = replace(m, gyro=tuple(neutral(e) if e.kind == d else e for e in m.gyro))
    return replace(m, name=f"mpu9250 (accelerometer calibrated) {'-'.join(drop) or 'full'}")


def table(path: str) -> str:
    """A run's JSON as a Markdown table, one row per variant."""
    d = json.loads(Path(path).read_text())
    base = f" (removed from every row: {d['base_removed']})" if d.get("base_removed") else ""
    lines = [f"{d['sensor']}, {d['hand']} hand, {d['seeds']} paired seeds, {d['method']}{base}", "",
             "| variant | S, G RMSE max | eff. vs hand bound, max S, G | NEES(6) | 95 % band | err/σ RMS S_x … G_z | "
             "q_b (rad/s/√s) | statuses |", "|" + "---|" * 8]
    for name, r in d["rows"].items():
        st = ", ".join(f"{k} {v}" for k, v in sorted(r["statuses"].items()))
        qb = r.get("bias_rw_rad_s_sqrt_s")
        lines.append(f"| {name} | {max(r['rmse']):.2e} | {max(r['efficiency_hand']):.2f} | {r['nees']:.2f} | "
                     f"{r['nees_band'][0]:.2f}–{r['nees_band'][1]:.2f} | {' '.join(f'{v:.2f}' for v in r['z_rms'])} | "
                     f"{qb if qb is None else f'{qb:.1e}'} | {st} |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--table", help="print the Markdown table of this run's JSON instead")
    ap.add_argument("--seeds", type=int, default=50)
    ap.add_argument("--variants", default=",".join(VARIANTS))
    ap.add_argument("--base", default="",
                    help="effects removed from every row too, e.g. 'warmup,g_sensitivity': the warmed-up MPU-9250 of "
                         "docs/hand.md (a board powered long before the session, without its g-sensitivity)")
    ap.add_argument("--out")
    ap.add_argument("--method", default="calib.session.hand.filter:kf_hand_g_sensitivity",
                    help="the estimator (default: kf_hand with the g-sensitivity block on)")
    a = ap.parse_args()
    if a.table:
        print(table(a.table))
        return
    if not a.out:
        ap.error("--out is required for a run")
    rows = {}
    for name in a.variants.split(","):
        t0 = time.time()
        base = tuple(x for x in a.base.split(",") if x)
        r = monte_carlo("zhou2020", "ideal", variant(base + tuple(d for d in VARIANTS[name] if d not in base)), a.seeds,
                        100.0, (a.method,))
        st = r.methods[a.method]
        rows[name] = {"rmse": st.rmse[3:9].tolist(), "efficiency_hand": st.efficiency_hand[3:9].tolist(),
                      "sqrt_crlb_hand": r.sqrt_crlb_hand[3:9].tolist(), "z_rms": st.z_rms[3:9].tolist(),
                      "nees": st.nees_mean, "nees_band": list(st.nees_band), "statuses": st.statuses,
                      "bias_rw_rad_s_sqrt_s": r.hand_psd.get("bias_rw_rad_s_sqrt_s"), "seconds": time.time() - t0}
        print(
            f"{name:20s} RMSE "
            + " ".join(f"{v:.2e}" for v in st.rmse[3:9])
            + " | eff. hand "
            + " ".join(f"{v:.2f}" for v in st.efficiency_hand[3:9])
            + f" | NEES {st.nees_mean:.2f} | z RMS "
            + " ".join(f"{v:.2f}" for v in st.z_rms[3:9])
            + " | q_b "
            f"{r.hand_psd.get('bias_rw_rad_s_sqrt_s', 0):.2e}",
            flush=True,
        )
        write_json_atomic(a.out, {"seeds": a.seeds, "hand": "ideal", "sensor": "mpu9250 (accelerometer calibrated)",
                                  "base_removed": a.base,
                                  "method": a.method, "rows": rows})


if __name__ == "__main__":
    np.seterr(all="ignore")
    main()
