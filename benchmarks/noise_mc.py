"""Monte Carlo campaigns behind docs/noise.md.  Noise drawn with the effect vocabulary's
own code (``Effect.delta``: static record, no MuJoCo needed), identified by calib.noise.

    python benchmarks/noise_mc.py avr --seeds 20 --out docs/results/noise_avr.json
    python benchmarks/noise_mc.py selection --seeds 70 --out docs/results/noise_selection.json

* ``avr``: allan_variance_ros's simulation configuration (config/simulation/imu_simulator.yaml,
  400 Hz, 11 000 s, white noise + bias random walk on both triads; ori-drs/allan_variance_ros,
  github.com/ori-drs/allan_variance_ros/issues/28, reports −28 %, −27 %, −29 %, −9 % on its own data).
  Each seed: both triads, three axes; fitted with the model fixed to white+rw (what their tool assumes) and
  chosen by WIC.
* ``selection``: four true models on a 1-hour 100 Hz record (3 axes per seed, each axis one
  realisation): how often WIC picks the true model; coverage of the 95 % intervals when the true
  model is fitted; and calib plan's predicted σ(log θ̂) against the Monte Carlo spread.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from gyrosim.effects import BiasInstability, GaussMarkov, RandomWalk, SignalContext, WhiteNoise  # noqa: E402

from calib.noise.gmwm import identify_axis, parse_model  # noqa: E402
from calib.noise.plan import noise_terms_of, predicted_relative_sigma  # noqa: E402

# ori-drs/allan_variance_ros config/simulation/imu_simulator.yaml (Kalibr continuous units)
AVR = {"accelerometer": {"white_noise": 0.0025019929573561175, "random_walk": 6.972435158192731e-05},
       "gyro": {"white_noise": 0.0001888339269965301, "random_walk": 2.5565313322052523e-06}}
# github.com/ori-drs/allan_variance_ros/issues/28: their estimates from one simulated bag
AVR_THEIRS = {"accelerometer": {"white_noise": 0.0017989768146338795, "random_walk": 5.073249247970349e-05},
              "gyro": {"white_noise": 0.00013494835013762752, "random_walk": 2.324462789522549e-06}}

TRUTHS = {
    "white": (WhiteNoise(density=np.full(3, 0.01)),),
    "white+rw": (WhiteNoise(density=np.full(3, 0.01)), RandomWalk(value=np.full(3, 8.7e-4))),
    "white+flicker+rw": (WhiteNoise(density=np.full(3, 0.01)), BiasInstability(value=np.full(3, 0.015)),
                         RandomWalk(value=np.full(3, 3.2e-3))),
    "white+gm+gm": (WhiteNoise(density=np.full(3, 0.01)), GaussMarkov(sigma=np.full(3, 0.05), tau_s=np.full(3, 0.5)),
                    GaussMarkov(sigma=np.full(3, 0.02), tau_s=np.full(3, 50.0))),
}


def draw(effects, n: int, rate_hz: float, rng: np.random.Generator) -> np.ndarray:
    t = np.arange(n) / rate_hz
    ctx = SignalContext(t, np.zeros((n, 3)), np.zeros((n, 3)), dt_s=1.0 / rate_hz)
    y = np.zeros((n, 3))
    for e in effects:
        y += e.delta(y, ctx, rng)
    return y


def avr(seeds: int, first: int) -> dict:
    rate, dur = 400.0, 11000.0
    n = int(rate * dur)
    fixed = [parse_model("white+rw")]
    rows = {tri: {"fixed": [], "auto": [], "auto_models": {}, "pred": []} for tri in AVR}
    for s in tqdm(range(first, first + seeds), desc="avr seeds"):
        rng = np.random.default_rng(s)
        for tri, par in AVR.items():
            effs = (
                WhiteNoise(density=np.full(3, par["white_noise"])),
                RandomWalk(value=np.full(3, par["random_walk"])),
            )
            y = draw(effs, n, rate, rng)
            for ax in range(3):
                f = identify_axis(y[:, ax], 1 / rate, fixed).chosen
                rows[tri]["fixed"].append(np.exp(f.log_params).tolist())
                rows[tri]["pred"].append(np.sqrt(np.diag(f.cov_log)).tolist())
                a = identify_axis(y[:, ax], 1 / rate, wv=None).chosen
                rows[tri]["auto_models"][a.name] = rows[tri]["auto_models"].get(a.name, 0) + 1
                if a.kinds == fixed[0]:
                    rows[tri]["auto"].append(np.exp(a.log_params).tolist())
            del y
    out = {"config": {"rate_hz": rate, "duration_s": dur, "seeds": seeds, "first_seed": first,
                      "source": "ori-drs/allan_variance_ros config/simulation/imu_simulator.yaml; "
                                "github.com/ori-drs/allan_variance_ros/issues/28"},
           "triads": {}}
    for tri, r in rows.items():
        est = np.array(r["fixed"])                          # (3·seeds, 2): N, K per axis realisation
        truth = np.array([AVR[tri]["white_noise"], AVR[tri]["random_walk"]])
        rel = est / truth
        per_seed = rel.reshape(seeds, 3, 2).mean(axis=1)    # mean of the three axes, as one IMU's figure
        out["triads"][tri] = {
            "truth": truth.tolist(),
            "theirs": [AVR_THEIRS[tri]["white_noise"], AVR_THEIRS[tri]["random_walk"]],
            "theirs_rel_error": (
                np.array([AVR_THEIRS[tri]["white_noise"], AVR_THEIRS[tri]["random_walk"]]) / truth - 1
            ).tolist(),
            "mean_rel_error": (rel.mean(axis=0) - 1).tolist(),
            "mean_rel_error_se": (rel.std(axis=0, ddof=1) / math.sqrt(rel.shape[0])).tolist(),
            "sd_rel_per_axis": rel.std(axis=0, ddof=1).tolist(),
            "sd_rel_three_axis_mean": per_seed.std(axis=0, ddof=1).tolist(),
            "rms_rel_error_three_axis_mean": np.sqrt(np.mean((per_seed - 1) ** 2, axis=0)).tolist(),
            "predicted_sd_log_per_axis": np.mean(r["pred"], axis=0).tolist(),
            "coverage95": np.mean(np.abs(np.log(rel)) <= 1.959964 * np.array(r["pred"]), axis=0).tolist(),
            "auto_models": r["auto_models"],
        }
    return out


def selection(seeds: int, first: int, rate: float = 100.0, dur: float = 3600.0) -> dict:
    n = int(rate * dur)
    out = {"config": {"rate_hz": rate, "duration_s": dur, "seeds": seeds, "axes_per_seed": 3, "first_seed": first},
           "models": {}}
    for name, effs in TRUTHS.items():
        kinds, logp_true = noise_terms_of(effs)
        pred = predicted_relative_sigma(kinds, logp_true, rate, dur)
        chosen, est, sds = {}, [], []
        t0 = time.process_time()
        for s in tqdm(range(first, first + seeds), desc=name):
            y = draw(effs, n, rate, np.random.default_rng(s))
            for ax in range(3):
                sel = identify_axis(y[:, ax], 1 / rate)
                chosen[sel.chosen.name] = chosen.get(sel.chosen.name, 0) + 1
                f = identify_axis(y[:, ax], 1 / rate, [kinds], wv=sel.wv).chosen
                est.append(f.log_params.tolist())
                sds.append(np.sqrt(np.diag(f.cov_log)).tolist())
        est, sds = np.array(est), np.array(sds)
        z = (est - logp_true) / sds
        from calib.noise.gmwm import model_name

        out["models"][name] = {
            "true_model": model_name(kinds),
            "parameters": [
                f"{k}.{f}"
                for k, f in __import__("calib.noise.gmwm", fromlist=["WaveletModel"])
                .WaveletModel(kinds, np.ones(1), 1.0)
                .names
            ],
            "true_values": np.exp(logp_true).tolist(),
            "chosen": chosen,
            "correct_fraction": chosen.get(model_name(kinds), 0) / (3 * seeds),
            "coverage95": np.mean(np.abs(z) <= 1.959964, axis=0).tolist(),
            "coverage68": np.mean(np.abs(z) <= 1.0, axis=0).tolist(),
            "mean_rel_error": (np.exp(est).mean(axis=0) / np.exp(logp_true) - 1).tolist(),
            "mc_sd_log": est.std(axis=0, ddof=1).tolist(),
            "plan_predicted_sd_log": pred.tolist(),
            "plan_over_mc": (pred / est.std(axis=0, ddof=1)).tolist(),
            "cpu_s_per_axis": (time.process_time() - t0) / (3 * seeds),
        }
        print(json.dumps({name: out["models"][name]}, indent=1), file=sys.stderr, flush=True)
    return out


KALIBR = {("accelerometer", 0): "accelerometer_noise_density", ("accelerometer", 1): "accelerometer_random_walk",
          ("gyro", 0): "gyroscope_noise_density", ("gyro", 1): "gyroscope_random_walk"}


def _pct(x: float) -> str:
    return f"{100 * x:+.2f} %"


def avr_table(d: dict) -> str:
    """``avr``'s JSON as a Markdown table (Kalibr's parameter names)."""
    c = d["config"]
    lines = [f"{c['seeds']} seeds × 3 axes per triad, {c['rate_hz']:g} Hz, {c['duration_s']:g} s; white noise + "
             "random walk fitted with the model fixed to white+rw, and the model WIC chooses", "",
             "| parameter (Kalibr) | true | allan_variance_ros (one bag) | ours: mean error ± se | ours: 1σ per axis | "
             "ours: 1σ of the 3-axis mean | predicted 1σ (sandwich) | 95 % coverage | model chosen by WIC |",
             "|" + "---|" * 9]
    for tri in ("accelerometer", "gyro"):
        t = d["triads"][tri]
        chosen = ", ".join(f"{k} {v}" for k, v in sorted(t["auto_models"].items(), key=lambda kv: -kv[1]))
        for i in (0, 1):
            lines.append(f"| {KALIBR[(tri, i)]} | {t['truth'][i]:.4g} | {t['theirs'][i]:.4g} "
                         f"({_pct(t['theirs_rel_error'][i])}) | {_pct(t['mean_rel_error'][i])} ± "
                         f"{100 * t['mean_rel_error_se'][i]:.2f} % | {100 * t['sd_rel_per_axis'][i]:.2f} % | "
                         f"{100 * t['sd_rel_three_axis_mean'][i]:.2f} % | "
                         f"{100 * t['predicted_sd_log_per_axis'][i]:.2f} % | {100 * t['coverage95'][i]:.0f} % | "
                         f"{chosen if i == 0 else ''} |")
    return "\n".join(lines)


def selection_table(d: dict) -> str:
    """``selection``'s JSON as two Markdown tables: the model chosen and the intervals' coverage; calib plan's
    predicted σ(log θ̂) against the Monte Carlo spread."""
    c = d["config"]
    n = c["seeds"] * c["axes_per_seed"]
    lines = [f"{c['seeds']} seeds × {c['axes_per_seed']} axes = {n} records per model, {c['duration_s']:g} s at "
             f"{c['rate_hz']:g} Hz", "",
             "| true model | chosen correctly | other choices | parameter | mean error | 95 % coverage | "
             "68 % coverage |", "|" + "---|" * 7]
    plan = ["| true model | parameter | predicted σ(log θ̂) | Monte Carlo σ(log θ̂) | predicted / MC |",
            "|" + "---|" * 5]
    for name, m in d["models"].items():
        others = ", ".join(f"{k} {v}" for k, v in sorted(m["chosen"].items(), key=lambda kv: -kv[1])
                           if k != m["true_model"])
        for i, par in enumerate(m["parameters"]):
            head = (f"| {name} | {100 * m['correct_fraction']:.1f} % | {others} |" if i == 0 else "| | | |")
            lines.append(f"{head} {par} | {_pct(m['mean_rel_error'][i])} | {100 * m['coverage95'][i]:.1f} % | "
                         f"{100 * m['coverage68'][i]:.1f} % |")
            plan.append(f"| {name} | {par} | {m['plan_predicted_sd_log'][i]:.4f} | {m['mc_sd_log'][i]:.4f} | "
                        f"{m['plan_over_mc'][i]:.2f} |")
    return "\n".join(lines + ["", "`calib plan`'s prediction against the spread of the fits of the true model:", ""]
                     + plan)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("what", choices=("avr", "selection"))
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--out", help="write the run's JSON here")
    ap.add_argument("--table", help="print the Markdown table of this JSON instead of running")
    a = ap.parse_args()
    if a.table:
        d = json.loads(Path(a.table).read_text())
        print(avr_table(d) if a.what == "avr" else selection_table(d))
        return
    res = avr(a.seeds, a.first_seed) if a.what == "avr" else selection(a.seeds, a.first_seed)
    res["command"] = " ".join(["python benchmarks/noise_mc.py"] + sys.argv[1:])
    if a.out:
        Path(a.out).write_text(json.dumps(res, indent=1))
    print(avr_table(res) if a.what == "avr" else selection_table(res))


if __name__ == "__main__":
    main()
