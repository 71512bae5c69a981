"""kf_hand's gyro bias, before and after calib.session.rest_bias, on the same sessions (results: hand_bias).

Per seed: ``kf_hand`` (accelerometer calibrated) or ``kf_hand_joint`` (``--accelerometer estimate``, raw
accelerometer).  The reported value is the first rest's mean either way; what changed is its σ and what it is
scored against:

* before: σ = the rest's 10-batch-means standard error (``prepare(...).bias_batch_std_rad_s``, as kf_hand reported it),
  scored against the oracle
  (:func:`gyrosim.calibration.truth_calibration`: the bias at the preset's T_ref with zero specific force);
* after: σ from :mod:`calib.session.rest_bias` (white noise ⊕ the hand's rotation during the rest), scored against the
  device's bias during that rest (:func:`calib.scoring.montecarlo.truth_bias_at_reference`: temperature, g-sensitivity
  at the rest's specific force, the slow stochastic bias's mean over the rest).

Prints per cell the bias RMSE (rad/s, per axis) against both truths and err/σ RMS before/after, with the
95 % band of the pooled err/σ RMS over seeds × 3 axes (√(χ²_n/n) quantiles, n = 3 seeds); exit 1 when a
cell's pooled RMS leaves it.

    nice -n 10 python benchmarks/hand_bias_campaign.py --sensors zhou2020_sim_consumer,mpu9250 \
        --hands ideal,steady,typical,shaky --seeds 50 --out docs/results/hand_bias.json

Seeds and sessions as :func:`calib.scoring.montecarlo.monte_carlo` (truth seed k, sensor draw 10 000 + k, 100 Hz,
accelerometer calibrated unless ``--accelerometer estimate``).
"""
from __future__ import annotations

import argparse
import math
from dataclasses import replace

import numpy as np
from scipy import stats
from tqdm import tqdm

from gyrosim.calibration import truth_calibration
from gyrosim.hand import load_hand
from gyrosim.schedule import load_schedule
from gyrosim.sensor_model import load_sensor

import calib.scoring.montecarlo as mc
from calib.app.outputs import write_json_atomic
from calib.session.hand.filter import kf_hand
from calib.session.paper import prepare


def z_band(n: int) -> tuple[float, float]:
    """95 % band of √(Σz²/n) for n standard normal z."""
    return math.sqrt(stats.chi2.ppf(0.025, n) / n), math.sqrt(stats.chi2.ppf(0.975, n) / n)


def cell(hand: str, sensor: str, seeds: int, accelerometer: str = "calibrated", rate_hz: float = 100.0,
         bar=None) -> dict:
    sched, hnd = load_schedule("zhou2020"), load_hand(hand)
    model = load_sensor(sensor)
    if accelerometer == "calibrated":
        model = replace(model, accelerometer=tuple(e for e in model.accelerometer if e.is_white_noise))
    truth_fixed = mc.simulate_truth(sched, hnd, rate_hz, seed=0) if hnd.is_ideal else None
    err_o, err_r, z_old, z_new, sd_new, sd_old = [], [], [], [], [], []
    for seed in range(seeds):
        truth = truth_fixed if truth_fixed is not None else mc.simulate_truth(sched, hnd, rate_hz, seed=seed)
        rec = mc.apply_sensor(truth, model, np.random.default_rng(10_000 + seed))
        oracle = truth_calibration(rec).vector("gyro")[:3]
        user = mc.as_user_file(rec)
        c = kf_hand(user, accelerometer=accelerometer)
        gb = c.diagnostics["gyro_bias"]
        rng = tuple(gb["rest_index_range"])
        ref = oracle + mc.truth_bias_at_reference(rec, rng, mc.slow_gyro_bias(rec, truth, model, 10_000 + seed, rng))
        b = c.value("gyro", "bias")
        s_new = np.sqrt(np.diag(c.block_covariance([("gyro", "bias")])))
        s_old = prepare(user, accelerometer=accelerometer).bias_batch_std_rad_s   # what kf_hand reported before
        err_o.append(b - oracle)
        err_r.append(b - ref)
        z_old.append((b - oracle) / s_old)
        z_new.append((b - ref) / s_new)
        sd_new.append(s_new)
        sd_old.append(s_old)
        if bar is not None:
            bar.update(1)
    rms = lambda a: np.sqrt(np.mean(np.square(a), axis=0)).tolist()  # noqa: E731
    lo, hi = z_band(3 * seeds)
    zn = np.asarray(z_new)
    return {"hand": hand, "sensor": sensor, "accelerometer": accelerometer, "seeds": seeds,
            "rmse_vs_oracle_rad_s": rms(err_o), "rmse_vs_reference_rad_s": rms(err_r),
            "z_rms_before": rms(z_old), "z_rms_after": rms(z_new),
            "z_rms_before_all": float(np.sqrt(np.mean(np.square(z_old)))),
            "z_rms_after_all": float(np.sqrt(np.mean(np.square(zn)))),
            "sigma_before_rms_rad_s": rms(sd_old), "sigma_after_rms_rad_s": rms(sd_new),
            "z_band_95": [lo, hi], "after_in_band": bool(lo <= float(np.sqrt(np.mean(zn**2))) <= hi)}


def table(rows: list[dict]) -> str:
    head = ("| sensor | accelerometer | hand | bias RMSE vs oracle (x, y, z) °/s | vs rest reference °/s | "
            "err/σ RMS before (vs oracle) | after (vs reference) | after, 3 axes pooled | 95 % band (pooled) |")
    lines = [head, "|" + "---|" * 9]
    d = lambda v: ", ".join(f"{math.degrees(x):.5f}" for x in v)  # noqa: E731
    z = lambda v: ", ".join(f"{x:.2f}" for x in v)  # noqa: E731
    for r in rows:
        lines.append(f"| {r['sensor']} | {r['accelerometer']} | {r['hand']} | {d(r['rmse_vs_oracle_rad_s'])} | "
                     f"{d(r['rmse_vs_reference_rad_s'])} | {z(r['z_rms_before'])} | {z(r['z_rms_after'])} | "
                     f"{r['z_rms_after_all']:.2f} | "
                     f"{r['z_band_95'][0]:.2f}–{r['z_band_95'][1]:.2f} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sensors", default="zhou2020_sim_consumer,mpu9250")
    ap.add_argument("--hands", default="ideal,steady,typical,shaky")
    ap.add_argument("--seeds", type=int, default=50)
    ap.add_argument("--accelerometer", choices=("calibrated", "estimate"), default="calibrated")
    ap.add_argument("--out", help="JSON output (a .md table beside it)")
    a = ap.parse_args(argv)
    cells = [(s, h) for s in a.sensors.split(",") for h in a.hands.split(",")]
    rows = []
    with tqdm(total=len(cells) * a.seeds, desc="sessions") as bar:
        for s, h in cells:
            rows.append(cell(h, s, a.seeds, a.accelerometer, bar=bar))
    md = table(rows)
    print(md)
    if a.out:
        import sys

        write_json_atomic(
            a.out,
            {
                "command": "python benchmarks/hand_bias_campaign.py "
                + " ".join(sys.argv[1:] if argv is None else argv),
                "cells": rows,
            },
        )
        with open(a.out.rsplit(".", 1)[0] + ".md", "w", encoding="utf-8") as fh:
            fh.write(md + "\n")
    return 0 if all(r["after_in_band"] for r in rows) else 1


if __name__ == "__main__":
    raise SystemExit(main())
