"""What a 2-hour static record tells through the Allan deviation: the MPU-9250 gyro's noise terms over seeds.

    python benchmarks/allan_mc.py [--seeds 12] [--hours 2] [--json out.json]

Each seed draws the ``mpu9250`` preset's gyro noise (its stochastic effects only: white, flicker, random walk) as
gyrosim simulates it, 3 axes at 100 Hz, and fits N, B, K to the three axes' overlapping Allan deviations pooled
(:func:`calib.noise.allan.fit_noise_terms`, what ``calib allan`` runs).  Prints, per term, the preset's value, the
mean of fitted/true over the seeds with its standard error, and the relative 1σ of one record's fit
(docs/error-model.md; tests/gyrosim/test_effects.py holds one seed to it).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

from gyrosim.effects import SignalContext
from gyrosim.sensor_model import SensorModel, load_sensor

from calib.noise.allan import allan_deviation, fit_noise_terms

DEG = math.pi / 180


def run(seeds: int, hours: float, rate_hz: float = 100.0) -> dict:
    preset = load_sensor("mpu9250")
    noise = SensorModel("noise", gyro=tuple(e for e in preset.gyro if e.stochastic))
    truth = {e.kind: e for e in noise.gyro}
    true = {"arw": truth["white_noise"].density[0], "bias_instability": truth["bias_instability"].value[0],
            "rate_random_walk": truth["random_walk"].value[0]}
    n = int(hours * 3600 * rate_hz)
    ctx = SignalContext(np.arange(n) / rate_hz, np.zeros((n, 3)), np.zeros((n, 3)))
    ratios = {k: [] for k in true}
    for seed in range(seeds):
        y = noise.apply_triad("gyro", ctx.omega_true_rad_s, ctx, np.random.default_rng(seed))
        fit = fit_noise_terms([allan_deviation(y[:, i], rate_hz) for i in range(3)])
        for k in true:
            ratios[k].append(getattr(fit, k) / true[k])
        print(f"seed {seed}: " + ", ".join(f"{k} {ratios[k][-1]:.3f}" for k in true), file=sys.stderr, flush=True)
    out = {"preset": "mpu9250", "seeds": seeds, "hours": hours, "rate_hz": rate_hz, "terms": {}}
    for k, r in ratios.items():
        r = np.array(r)
        out["terms"][k] = {"true_si": float(true[k]), "mean_ratio": float(r.mean()),
                           "mean_ratio_se": float(r.std(ddof=1) / math.sqrt(len(r))),
                           "relative_sigma": float(r.std(ddof=1)), "ratios": r.tolist()}
    return out


def table(d: dict) -> str:
    label = {"arw": ("white noise N (ARW)", 180 / math.pi * 60, "°/√h"),
             "bias_instability": ("bias instability B", 180 / math.pi * 3600, "°/h"),
             "rate_random_walk": ("rate random walk K", 180 / math.pi * 3600 * 60, "°/h/√h")}
    lines = [f"`{d['preset']}` gyro noise, {d['hours']:g} h at {d['rate_hz']:g} Hz, 3 axes pooled, {d['seeds']} seeds",
             "", "| term | preset value | mean fitted / true ± se | 1σ of one record's fit |", "|---|---|---|---|"]
    for k, t in d["terms"].items():
        name, scale, unit = label[k]
        lines.append(f"| {name} | {t['true_si'] * scale:.3g} {unit} | {t['mean_ratio']:.3f} ± "
                     f"{t['mean_ratio_se']:.3f} | {100 * t['relative_sigma']:.1f} % |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=12)
    ap.add_argument("--hours", type=float, default=2.0)
    ap.add_argument("--json", help="write the run's JSON here")
    a = ap.parse_args(argv)
    d = run(a.seeds, a.hours)
    if a.json:
        Path(a.json).write_text(json.dumps(d, indent=1))
    print(table(d))
    return 0


if __name__ == "__main__":
    sys.exit(main())
