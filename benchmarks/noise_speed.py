"""Speed of ``calib noise`` against ``calib allan`` on the same record, in one run.

    OMP_NUM_THREADS=1 python benchmarks/noise_speed.py [--repeats 3] [--hours 2] [--rate 100]

A static record of the ``mpu9250`` gyro's noise terms (white + flicker + random walk, drawn by
the effect vocabulary), 3 axes.  Rows, interleaved per repeat, CPU time (``time.process_time``:
on the shared machine the wall clock measures the scheduler), median over the repeats:

* allan — what ``calib allan`` computes: overlapping Allan deviation of 3 axes (calib.noise.allan) and the
  IRLS fit of N, B, K;
* noise — what ``calib noise`` computes: wavelet variance, 32 candidates fitted per axis, WIC, Σ,
  intervals, inflation figure (:func:`calib.noise.identify_noise`).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from gyrosim.effects import SignalContext  # noqa: E402
from gyrosim.sensor_model import load_sensor  # noqa: E402

from calib.noise import identify_noise  # noqa: E402
from calib.noise.allan import allan_deviation, fit_noise_terms  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--hours", type=float, default=2.0)
    ap.add_argument("--rate", type=float, default=100.0)
    a = ap.parse_args()
    n = int(a.hours * 3600 * a.rate)
    effs = [e for e in load_sensor("mpu9250").gyro if e.kind in ("white_noise", "bias_instability", "random_walk")]
    ctx = SignalContext(np.arange(n) / a.rate, np.zeros((n, 3)), np.zeros((n, 3)), dt_s=1 / a.rate)
    rng = np.random.default_rng(0)
    y = sum(e.delta(np.zeros((n, 3)), ctx, rng) for e in effs)
    times = {"allan": [], "noise": []}
    for _ in range(a.repeats):
        t0 = time.process_time()
        fit_noise_terms([allan_deviation(y[:, i], a.rate) for i in range(3)])
        t1 = time.process_time()
        res = identify_noise(y, a.rate, "gyro")
        t2 = time.process_time()
        times["allan"].append(t1 - t0)
        times["noise"].append(t2 - t1)
    al, no = statistics.median(times["allan"]), statistics.median(times["noise"])
    print(f"{a.hours:g} h at {a.rate:g} Hz × 3 axes ({n} samples per axis), CPU s, median of {a.repeats}")
    print("| step | CPU s | ratio to calib allan |\n|---|---|---|")
    print(f"| calib allan (OADEV + IRLS N, B, K) | {al:.2f} | 1.00 |")
    print(f"| calib noise (WV + 32-model GMWM + WIC + Σ + intervals) | {no:.2f} | {no / al:.2f} |")
    print("models chosen:", ", ".join(ax.model for ax in res.axes))


if __name__ == "__main__":
    main()
