"""The false-alarm rate of ``calib run``'s default: how often a session whose truth lies within the σ the result
states comes back not ``ok`` (exit 1), on the README's own session (zhou2020 schedule, hand ``typical``, sensor
``mpu9250``, 100 Hz), one seed after another as ``gyrosim simulate --seed K`` draws them.

    nice python benchmarks/false_alarm.py --seeds 50 --out docs/results/false_alarm.json
    python benchmarks/false_alarm.py --table docs/results/false_alarm_before.json docs/results/false_alarm.json \
        --markdown docs/results/false_alarm.md                # the table of runs, one row each (no runs)

Each seed: :func:`gyrosim.simulate` (the seeding of ``gyrosim simulate --seed``), then
:func:`calib.session.run.run_session` with the default options (what ``calib run rec.h5`` does), scored on the gyro's
scale factor S and non-orthogonality G — the six parameters the filter estimates (the bias is the rest's average; its
truth depends on the slow bias at that rest, not scored here).  S is scored at the temperatures and rates the result
says it holds at (:func:`calib.scoring.montecarlo.truth_scale_at_temperature`, ``truth_gyro_scale_at_rate``), as the
campaigns do.

"The truth is within the stated σ" (``truth_within``): NEES of (S, G) with the covariance the result states
≤ χ²₆'s 99 % quantile (16.8), or every one of the six errors within 3σ.  A false alarm: status not ``ok`` and
``truth_within``; a miss: status ``ok`` and not ``truth_within``.  Under an honest σ ``truth_within`` fails in
≲ 1 % of seeds, so a miss rate well above that says the stated σ is too small.

Per seed the JSON keeps the inflation statistic (κ̂, its degrees of freedom, the σ factor), the errors over σ, both
NEES (stated σ; σ before the inflation) and the status, so a change of the verdict's rule can be scored offline.
The JSON is stamped with the commit, the command line and the date (:func:`benchmarks.measured.provenance`).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
from scipy import stats

from gyrosim.calibration import truth_calibration
from gyrosim.simulate import simulate

from calib.app.outputs import write_json_atomic
from calib.scoring.montecarlo import truth_gyro_scale_at_rate, truth_scale_at_temperature
from calib.session.run import RunOptions, run_session

sys.path.insert(0, str(Path(__file__).resolve().parent))
from measured import provenance  # noqa: E402  (the benchmarks' one stamp: commit, command line, date)

from benchmarks.provenance import stamp as stamp_file  # noqa: E402  (measured put the checkout on the path)

NEES_QUANTILE = 0.99
Z_LIMIT = 3.0
ITEMS = (("gyro", "scale_factor"), ("gyro", "nonorthogonality"))


def score_seed(schedule: str, hand: str, sensor: str, seed: int, rate_hz: float = 100.0) -> dict:
    """One seed: simulate, calibrate as ``calib run`` does by default, score S and G against the truth."""
    rec = simulate(schedule, hand, sensor, rate_hz, seed=seed)
    t0 = time.process_time()
    cal = run_session(rec, RunOptions())
    cpu_s = time.process_time() - t0
    truth = truth_calibration(rec)
    tm = np.concatenate([truth.value("gyro", "scale_factor"), truth.value("gyro", "nonorthogonality")])
    temp = cal.diagnostics.get("temperature", {})
    t_s = (np.asarray(temp["scale_reference_temperature_c"], float)
           if temp.get("modelled") and "scale_reference_temperature_c" in temp
           else np.full(3, float(np.mean(rec.temp_c)) if rec.temp_c is not None else 25.0))
    if temp.get("modelled") and "scale_reference_temperature_c" in temp:
        tm[0:3] += truth_scale_at_temperature(rec, t_s)
    srate = cal.diagnostics.get("scale_reference_rate", {})
    if "rate_rad_s" in srate:
        tm[0:3] += truth_gyro_scale_at_rate(rec, np.asarray(srate["rate_rad_s"], float), t_s)
    est = np.concatenate([cal.value(t, k) for t, k in ITEMS])
    cov = cal.block_covariance(list(ITEMS))
    err = est - tm
    infl = (cal.diagnostics.get("consistency") or {}).get("sigma_inflation") or {}
    factor = float(infl.get("covariance_factor", 1.0))
    nees = float(err @ np.linalg.solve(cov, err))
    return {
        "seed": seed, "status": cal.status, "cpu_s": cpu_s,
        "error": err.tolist(), "sigma": np.sqrt(np.diag(cov)).tolist(),
        "z": (err / np.sqrt(np.diag(cov))).tolist(), "nees": nees, "nees_before_inflation": nees * factor,
        "kappa": infl.get("long_run_variance"), "dof": infl.get("dof"), "threshold_95": infl.get("threshold_95"),
        "sigma_factor": float(np.sqrt(factor)),
        "reasons": [w.split(":")[0] for w in cal.warnings if w.split(":")[0] in ("inconsistent", "diverged")],
    }


def truth_within(row: dict, dof: int = 6) -> bool:
    """NEES ≤ χ²(dof) 99 % or every |error/σ| ≤ 3 (module docstring)."""
    return row["nees"] <= stats.chi2.ppf(NEES_QUANTILE, dof) or max(abs(z) for z in row["z"]) <= Z_LIMIT


def summary(rows: list[dict]) -> dict:
    """The rates of the module docstring over ``rows``."""
    n = len(rows)
    within = [truth_within(r) for r in rows]
    ok = [r["status"] == "ok" for r in rows]
    false_alarm = sum(w and not o for w, o in zip(within, ok))
    miss = sum(o and not w for w, o in zip(within, ok))
    statuses = {s: sum(r["status"] == s for r in rows) for s in sorted({r["status"] for r in rows})}
    return {"seeds": n, "false_alarms": false_alarm, "false_alarm_rate": false_alarm / n if n else None,
            "misses": miss, "miss_rate": miss / n if n else None, "truth_within": int(sum(within)),
            "statuses": statuses, "nees_mean": float(np.mean([r["nees"] for r in rows])) if n else None,
            "nees_band_95": [float(stats.chi2.ppf(q, 6 * n) / n) for q in (0.025, 0.975)] if n else None,
            "sigma_factor_median": float(np.median([r["sigma_factor"] for r in rows])) if n else None}


def table(docs: list[dict]) -> str:
    """The Markdown table of result files, one row each, with the commit and command each was run at."""
    lines = ["| run | method | hand | sensor | seeds | not ok although truth within σ | ok although truth outside | "
             "statuses | NEES(6) mean (95 % band) | σ factor median |", "|" + "---|" * 10]
    notes = []
    for i, doc in enumerate(docs, 1):
        s, pv = doc["summary"], doc["provenance"]
        notes.append(f"{i}. commit `{pv['commit']}`; `{pv['command']}`; {pv['date']}")
        lines.append(
            f"| {i} | {doc['method']} | {doc['hand']} | {doc['sensor']} | {s['seeds']} | {s['false_alarms']} "
            f"({100 * s['false_alarm_rate']:.0f} %) | {s['misses']} ({100 * s['miss_rate']:.0f} %) | "
            + ", ".join(f"{k} {v}" for k, v in s["statuses"].items())
            + f" | {s['nees_mean']:.2f} ({s['nees_band_95'][0]:.2f}–{s['nees_band_95'][1]:.2f}) | "
            f"{s['sigma_factor_median']:.2f} |")
    return "\n".join(lines + [""] + notes)


def run(out: str, seeds: int, first_seed: int, schedule: str, hand: str, sensor: str) -> dict:
    """Score ``seeds`` seeds from ``first_seed``; seeds already in ``out`` (same setting, same commit) are kept, so
    an interrupted run resumes — a file written by other code is run again, not resumed.  Writes ``out`` after every
    seed."""
    rows: dict[int, dict] = {}
    stamp = provenance()   # the code that ran: taken before the first seed
    setting = {"schedule": schedule, "hand": hand, "sensor": sensor, "method": "calib run (default)"}
    resumed: list = []
    if Path(out).exists():
        old = json.loads(Path(out).read_text())
        if all(old.get(k) == v for k, v in setting.items()) and old["provenance"]["commit"] == stamp["commit"]:
            rows = {r["seed"]: r for r in old["per_seed"]}
            # the seeds kept were run at the file's stamp; a resumed run's own stamp is listed beside it
            stamp, resumed = old["provenance"], old.get("resumed", []) + [stamp]
    for seed in range(first_seed, first_seed + seeds):
        if seed in rows:
            continue
        rows[seed] = score_seed(schedule, hand, sensor, seed)
        r = rows[seed]
        print(f"seed {seed}: {r['status']}, σ ×{r['sigma_factor']:.2f}, NEES {r['nees']:.1f}, "
              f"max |z| {max(abs(z) for z in r['z']):.1f}, {r['cpu_s']:.0f} s", flush=True)
        kept = [rows[k] for k in sorted(rows)]
        doc = {"provenance": stamp, **setting, "definition": {
            "truth_within": f"NEES(S, G) ≤ χ²₆ {NEES_QUANTILE:.0%} or every |error/σ| ≤ {Z_LIMIT}",
            "false_alarm": "status not ok and truth within", "miss": "status ok and truth not within"},
            "summary": summary(kept), "per_seed": kept, **({"resumed": resumed} if resumed else {})}
        write_json_atomic(out, doc)
    doc = json.loads(Path(out).read_text())
    doc["method"] = doc.get("method", "calib run (default)")
    return doc


def main(argv: list[str] | None = None) -> int:
    """Command line (module docstring)."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seeds", type=int, default=50)
    p.add_argument("--first-seed", type=int, default=1)
    p.add_argument("--schedule", default="zhou2020")
    p.add_argument("--hand", default="typical")
    p.add_argument("--sensor", default="mpu9250")
    p.add_argument("--out", default="docs/results/false_alarm.json")
    p.add_argument("--table", metavar="JSON", nargs="+", help="print the table of result files (one row each) and "
                   "exit; with --markdown, write it there too")
    p.add_argument("--markdown", metavar="MD", help="with --table: write the table to this Markdown file")
    args = p.parse_args(argv)
    if args.table:
        text = table([json.loads(Path(t).read_text()) for t in args.table])
        print(text)
        if args.markdown:
            pv = provenance()
            Path(args.markdown).write_text(
                "# False alarms of calib run's default\n\nGenerated by `benchmarks/false_alarm.py` (its docstring "
                f"defines the columns) at commit `{pv['commit']}`, `{pv['command']}`, {pv['date']}; nothing here is "
                "edited by hand. The runs' own stamps are listed under the table.\n\n" + text + "\n")
            stamp_file(args.markdown, pv)   # the first-line comment every Markdown result carries
        return 0
    doc = run(args.out, args.seeds, args.first_seed, args.schedule, args.hand, args.sensor)
    print(table([doc]))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
