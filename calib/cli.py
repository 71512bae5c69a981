"""``calib`` command line: thin wrappers over library calls."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

from gyrosim.errors import GyrosimError

from . import __version__


def _rms(x: np.ndarray) -> float:
    return math.sqrt(float(np.mean(np.sum(np.asarray(x) ** 2, axis=1))))


def cmd_demo(args: argparse.Namespace) -> int:
    """The main job: simulate the hand-held session, calibrate it, write recording, report and .rrd."""
    from tqdm import tqdm

    from gyrosim.hand import load_hand
    from gyrosim.recording import save_hdf5
    from gyrosim.schedule import load_schedule
    from gyrosim.sensor_model import load_sensor
    from gyrosim.simulate import simulate, simulation_grid

    from .calibrate import calibrate, true_gyro_parameters
    from .report import write_session_report
    from .viz_rerun import save_calibration_rrd

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    schedule = load_schedule(args.schedule)
    hand = load_hand(args.hand)
    sensor = load_sensor(args.sensor)
    grid = simulation_grid(schedule.duration_s, args.rate)
    with tqdm(total=grid.t_physics_s.size + 1, unit="step", desc="simulating session", leave=False) as bar:
        rec = simulate(schedule, hand, sensor, args.rate, seed=args.seed, progress=bar.update)
    rec_path = save_hdf5(rec, out / "session.h5")
    print(f"calibrating {rec.n} samples (Zhou 2020 filter) …", flush=True)
    result = calibrate(rec, "kf")
    truth = true_gyro_parameters(rec)
    from .validation import validate_attitude

    print("validating the attitude on a free-style session of the same device …", flush=True)
    validation = validate_attitude(rec, result, hand=hand.name, seed=args.seed + 1000)
    report = write_session_report(out, rec, result, truth, schedule=schedule, hand=hand, sensor=sensor, seed=args.seed,
                                  validation=validation)
    rrd = save_calibration_rrd(out / "session.rrd", rec, result, truth)
    print(f"wrote {rec_path}, {report}, {out / 'report.json'} and {rrd}")
    print(f"open the recording with:  rerun {rrd}")
    return 0


def cmd_run(args: argparse.Namespace) -> int:
    """Calibrate a recording; print the result; write JSON and .rrd if asked."""
    from .calibrate import calibrate, true_gyro_parameters
    from .inputs import load_recording

    for out in (args.json, args.rrd):
        if out and not Path(out).resolve().parent.is_dir():
            raise GyrosimError(f"cannot write {out}: its folder does not exist")
    rec = load_recording(args.recording, gyro_unit=args.gyro_unit, acc_unit=args.acc_unit)
    result = calibrate(rec, args.method, external_acc_allowance_m_s2=args.external_acc)
    d = result.to_dict()
    g = d["gyro"]
    print(f"{args.recording}: method {result.method}, rest {d['rest_segments'][:3]}{' …' if len(d['rest_segments']) > 3 else ''}")
    for name, key, scale, unit in (("bias", "bias_rad_s", 180 / math.pi, "°/s"), ("scale factor", "scale_factor", 1, ""),
                                   ("non-orthogonality", "nonorthogonality", 1, "")):
        v = np.asarray(g[key]) * scale
        s = np.asarray(g["std"][key]) * scale
        print(f"  {name:<18} " + "  ".join(f"{a:+.5f}±{b:.5f}" for a, b in zip(v, s)) + f" {unit}")
    truth = true_gyro_parameters(rec)
    if truth is not None:
        err_s = result.scale_factor - truth["scale_factor"]
        err_g = result.nonorthogonality - truth["nonorthogonality"]
        print(f"  error vs truth: S {np.round(err_s, 5).tolist()}, G {np.round(err_g, 5).tolist()}")
        d["truth"] = {k: v.tolist() for k, v in truth.items()}
    for w in result.warnings:
        print(f"  warning: {w}")
    if args.json:
        Path(args.json).write_text(json.dumps(d, indent=2) + "\n")
        print(f"wrote {args.json}")
    if args.rrd:
        from .viz_rerun import save_calibration_rrd

        save_calibration_rrd(args.rrd, rec, result, truth)
        print(f"wrote {args.rrd}; open it with:  rerun {args.rrd}")
    return 0


def cmd_montecarlo(args: argparse.Namespace) -> int:
    """Monte Carlo against the Cramér–Rao bound: prints the table, writes JSON if asked."""
    from tqdm import tqdm

    from .montecarlo import monte_carlo

    with tqdm(total=args.seeds, desc="sessions", unit="seed", leave=False) as bar:
        r = monte_carlo(args.schedule, args.hand, args.sensor, args.seeds, args.rate, tuple(args.methods.split(",")),
                        progress=bar.update, calibrated_accelerometer=args.calibrated_accelerometer)
    print(r.table())
    if args.json:
        out = {"schedule": r.schedule, "hand": r.hand, "sensor": r.sensor, "seeds": r.seeds,
               "truth_mean": r.truth_mean.tolist(), "sqrt_crlb": r.sqrt_crlb.tolist(),
               "methods": {m: {"mean_error": st.mean_error.tolist(), "rmse": st.rmse.tolist(),
                               "efficiency": st.efficiency.tolist(), "nees_mean": st.nees_mean,
                               "nees_band": list(st.nees_band)} for m, st in r.methods.items()}}
        Path(args.json).write_text(json.dumps(out, indent=2) + "\n")
    return 0


# Zhou 2020 Tables 10–11: the rotations they analyse and the states they remove
TABLE_10_11 = {
    "z vertical": (("G_x", "G_y"), [9.8, 9.8, 8.524092, 8.50978], [9.8, 9.8, 0.61935, 0.375294]),
    "x vertical": (("G_y", "G_z"), [9.8, 9.8, 9.23949, 9.23464], [9.8, 9.8, 0.395472, 0.255418]),
    "x horizontal": (("S_x", "G_y", "G_z"), [9.8, 9.8, 4.792952, 4.644314], [9.8, 9.8, 0.525420, 0.000069]),
    "y horizontal": (("S_y", "G_x", "G_z"), [9.8, 9.8, 8.065646, 8.017878], [9.8, 9.8, 0.236580, 0.000045]),
    "z horizontal": (("S_z", "G_x", "G_y"), [9.8, 9.8, 8.096383, 7.994556], [9.8, 9.8, 0.715018, 0.000171]),
}


def cmd_observability(args: argparse.Namespace) -> int:
    """Per-segment SOM singular values and observable parameters; Tables 10–11 side by side."""
    from gyrosim.schedule import load_schedule

    from .observability import segment_observability

    sched = load_schedule(args.schedule)
    without = {}
    for i, seg in enumerate(sched.segments):
        for key, (states, _, _) in TABLE_10_11.items():
            if seg.label.startswith(key):
                without[i] = [states]
    rows = segment_observability(sched, args.rate, without)
    print(f"stripped observability per segment of {sched.name} (singular values in m/s², RMS over the segment)")
    for i, r in enumerate(rows):
        sv = r.singular_values[r.singular_values > 1e-9]
        print(f"{i:2d} {r.label[:44]:<44} σ = {np.round(sv, 3).tolist()}  observable: {', '.join(r.observable) or '—'}")
        for states, v in r.without.items():
            key = next(k for k in TABLE_10_11 if r.label.startswith(k))
            _, paper_full, paper_wo = TABLE_10_11[key]
            print(f"{'':47}without {', '.join(states)}: σ = {np.round(v[v > 1e-9], 3).tolist()}"
                  f"   paper: full {paper_full}, without {paper_wo}")
    return 0


def cmd_bench(args: argparse.Namespace) -> int:
    """Filter speed: filterpy against the compiled batched kernel, same data, same run."""
    import time

    from gyrosim.simulate import simulate

    from .calibrate import calibrate, prepare
    from .fastkf import run_batch

    rec = simulate("zhou2020", "ideal", "zhou2020_sim", 100.0, seed=0)
    prep = prepare(rec)
    a = prep.start
    g = (rec.gyro_rad_s - prep.bias.value_rad_s)[None, a:]
    acc = rec.acc_m_s2[None, a:]
    n = g.shape[1]
    run_batch(g[:, :100], acc[:, :100], rec.t_s[a : a + 100], prep.quat0_nb[None], prep.config, rec.rate_hz)  # compile
    t0 = time.perf_counter()
    ref = calibrate(rec, "kf")
    t_fp = time.perf_counter() - t0
    rows = [("filterpy filter (whole calibrate)", t_fp, 1)]
    for b in (1, args.batch):
        t0 = time.perf_counter()
        out = run_batch(np.repeat(g, b, 0), np.repeat(acc, b, 0), rec.t_s[a:], np.repeat(prep.quat0_nb[None], b, 0),
                        prep.config, rec.rate_hz)
        rows.append((f"compiled kernel, batch {b}", time.perf_counter() - t0, b))
    diff = max(np.abs(out.scale[0] - ref.scale_factor).max(), np.abs(out.nonorthogonality[0] - ref.nonorthogonality).max())
    print(f"Zhou filter on zhou2020 ({n} samples); max |fast − filterpy| = {diff:.1e}")
    print(f"{'':<36} {'s':>8} {'µs/filter-sample':>17} {'× filterpy':>11}")
    base = t_fp / n
    for name, sec, b in rows:
        per = sec / (n * b)
        print(f"{name:<36} {sec:8.3f} {per * 1e6:17.2f} {base / per:11.1f}")
    return 0


def cmd_allan(args: argparse.Namespace) -> int:
    """Allan deviation of a static recording's gyro: fitted N, B, K per IEEE 952, and a plot."""
    from .allan import allan_deviation, fit_noise_terms, plot_allan
    from .inputs import load_recording

    rec = load_recording(args.recording, gyro_unit=args.gyro_unit, acc_unit=args.acc_unit)
    curves = [allan_deviation(rec.gyro_rad_s[:, i], rec.rate_hz) for i in range(3)]
    fit = fit_noise_terms(curves)
    deg = 180 / math.pi
    print(f"{args.recording}: {rec.duration_s:.0f} s at {rec.rate_hz:g} Hz, three gyro axes pooled")
    print(f"  angle random walk   N = {fit.arw * deg * 60:.4f} ± {fit.arw_std * deg * 60:.4f} °/√h")
    print(f"  bias instability    B = {fit.bias_instability * deg * 3600:.3f} ± {fit.bias_instability_std * deg * 3600:.3f} °/h")
    print(f"  rate random walk    K = {fit.rate_random_walk * deg * 3600 * 60:.3f} ± {fit.rate_random_walk_std * deg * 3600 * 60:.3f} °/h/√h")
    print("  (± is the fit's 1σ from the Allan confidence; the recording must be static)")
    if args.png:
        plot_allan(curves, fit, args.png, unit_scale=deg * 3600, unit="°/h", title=f"Allan deviation: {Path(str(args.recording)).name}")
        print(f"wrote {args.png}")
    return 0


def cmd_inspect(args: argparse.Namespace) -> int:
    """Summarise a recording: length, rate, channels, truth and the hand's disturbance if known."""
    from gyrosim.recording import load_hdf5

    rec = load_hdf5(args.recording)
    dt = np.diff(rec.t_s)
    print(f"{args.recording}: {rec.n} samples, {rec.duration_s:.2f} s, rate {rec.rate_hz:g} Hz "
          f"(Δt {dt.min() * 1e3:.3f}–{dt.max() * 1e3:.3f} ms)")
    print(f"  gyro |ω| max {np.linalg.norm(rec.gyro_rad_s, axis=1).max():.3f} rad/s, "
          f"acc |f| mean {np.linalg.norm(rec.acc_m_s2, axis=1).mean():.4f} m/s²")
    print(f"  temperature: {'yes' if rec.temp_c is not None else 'no'}, "
          f"magnetometer: {'yes' if rec.mag_ut is not None else 'no'}, "
          f"truth: {', '.join(rec.truth.channels()) if rec.truth else 'none'}")
    for key in ("schedule", "hand", "sensor", "seed", "source", "version"):
        if key in rec.meta:
            v = rec.meta[key]
            print(f"  {key}: {v['name'] if isinstance(v, dict) and 'name' in v else v}")
    return 0


def cmd_closeloop(args: argparse.Namespace) -> int:
    """Fit the declared model, find what the residual lacks, add it, report before/after (issue 5)."""
    from tqdm import tqdm

    from .closeloop import run_closeloop
    from .closeloop.report import write_closeloop_report
    from .inputs import load_recording

    rec = load_recording(args.recording, args.gyro_unit, args.acc_unit)
    declared = tuple(k.strip() for k in args.declared.split(",") if k.strip())
    with tqdm(desc="closeloop", unit="test", leave=False) as bar:
        def progress(msg: str) -> None:
            bar.set_postfix_str(msg, refresh=False)
            bar.update()

        res = run_closeloop(rec, declared, reference=args.reference, holdout_s=args.holdout, progress=progress)
    paths = write_closeloop_report(args.out, rec, res)
    print(f"reference: {res.reference} ({res.reference_description})")
    for f in res.found:
        print(f"  found: {f.trace}")
    if not res.found:
        print("  found nothing beyond the declared model")
    print(f"  unexplained: {res.unexplained.get('summary', '')}")
    print(f"  error before: {res.error_before}\n  error after:  {res.error_after}")
    print("wrote " + ", ".join(str(p) for p in paths.values()))
    return 0


def cmd_closeloop_bench(args: argparse.Namespace) -> int:
    """closeloop wall time on ~3-minute recordings against the Zhou filter on the same data, same run."""
    import time

    from gyrosim.loaders import available_datasets, load_dataset
    from gyrosim.simulate import simulate

    from .calibrate import calibrate
    from .closeloop import run_closeloop
    from .closeloop.suite import BASE_SENSOR

    cases = [("zhou2020, typical hand, 100 Hz (simulated)", simulate("zhou2020", "typical", BASE_SENSOR, 100.0, seed=0))]
    if "broad/07_undisturbed_fast_rotation_B" in available_datasets():
        cases.append(("BROAD 07 fast rotation, 285.7 Hz (measured)", load_dataset("broad/07_undisturbed_fast_rotation_B")))
    print(f"{'recording':<46} {'samples':>8} {'closeloop s':>12} {'Zhou filter s':>14} {'ratio':>7}")
    for name, rec in cases:
        run_closeloop(rec)  # warm caches (numba, FFT plans) so both timings are steady-state
        t0 = time.perf_counter()
        run_closeloop(rec)
        t_cl = time.perf_counter() - t0
        t0 = time.perf_counter()
        calibrate(rec, "kf")
        t_kf = time.perf_counter() - t0
        print(f"{name:<46} {rec.t_s.size:8d} {t_cl:12.2f} {t_kf:14.2f} {t_cl / t_kf:7.2f}")
    return 0


def cmd_closeloop_suite(args: argparse.Namespace) -> int:
    """The undeclared-effect suite over seeds (README table)."""
    from tqdm import tqdm

    from gyrosim.simulate import apply_sensor, simulate_truth

    from .closeloop import run_closeloop
    from .closeloop.suite import SUITE, run_case, sensor_with

    truth = simulate_truth("zhou2020", args.hand, 100.0, rng=np.random.default_rng(args.truth_seed))
    seeds = range(args.first_seed, args.first_seed + args.seeds)
    print(f"{'undeclared effect':<22} {'named first':>11} {'max |z|':>8} {'declared °/s':>13} {'loop °/s':>9} "
          f"{'loop/correct':>13}")
    for kind in SUITE:
        res = [run_case(kind, truth, s) for s in tqdm(seeds, desc=kind, leave=False)]
        first = sum(r.named_first for r in res)
        z = max(r.z_max for r in res)
        print(f"{kind:<22} {first:>5}/{len(res):<5} {z:8.2f} {np.mean([r.error_declared for r in res]):13.4f} "
              f"{np.mean([r.error_loop for r in res]):9.4f} {max(r.ratio_to_correct for r in res):13.3f}")
    added = sum(bool(run_closeloop(apply_sensor(truth, sensor_with(None), np.random.default_rng(s))).found)
                for s in tqdm(seeds, desc="negative control", leave=False))
    print(f"{'(nothing undeclared)':<22} {'added in':>11} {added}/{len(seeds)} seeds")
    return 0


def cmd_temperature(args: argparse.Namespace) -> int:
    """Compare temperature models on held-out chamber cycles; optionally write a compensated copy."""
    from gyrosim.recording import save_hdf5

    from .inputs import load_recording
    from .thermal_comp import METHODS, ThermalCompensation, compare_methods, fit_compensation, split_cycles

    rec = load_recording(args.recording, args.gyro_unit, args.acc_unit)
    if args.train:
        train, test = [load_recording(args.train, args.gyro_unit, args.acc_unit)], [rec]
    else:
        cycles = split_cycles(rec)
        if len(cycles) <= args.train_cycles:
            raise GyrosimError(f"{len(cycles)} chamber cycle(s): cannot train on {args.train_cycles} and hold any out; "
                               "pass --train-cycles smaller or --train RECORDING")
        train, test = cycles[: args.train_cycles], cycles[args.train_cycles :]
    methods = tuple(m.strip() for m in args.methods.split(",")) if args.methods else METHODS
    extra = {}
    if args.ratetable:
        from .ratetable import calibrate_rate_table, piecewise_model

        rt = load_recording(args.ratetable)
        extra["piecewise_linear (rate-table points)"] = ThermalCompensation(
            "piecewise_linear (rate-table points)", (piecewise_model(calibrate_rate_table(rt)),))
    rows = compare_methods(train, test, methods, extra)
    base = rows[0]
    print(f"held out: {len(test)} record(s)/cycle(s); trained on {len(train)}")
    print(f"{'method':<38} {'RMS °/s':>9} {'BS °/h':>9} {'ADEV min °/h':>13} {'ADEV 1000 s °/h':>16} {'× better (BS)':>14}")
    for r in rows:
        print(f"{r.method:<38} {r.held_out_rms_deg_s:9.4f} {r.bias_stability_deg_h:9.2f} {r.adev_min_deg_h:13.2f} "
              f"{r.adev_1000s_deg_h:16.2f} {base.bias_stability_deg_h / r.bias_stability_deg_h:14.1f}")
    if args.json:
        Path(args.json).write_text(json.dumps([r.__dict__ for r in rows], indent=2))
    if args.compensate:
        if not args.out:
            raise GyrosimError("--compensate needs --out PATH for the compensated recording")
        if Path(args.out).resolve() == Path(args.recording).resolve():
            raise GyrosimError("--out must differ from the input: the recording you gave is never overwritten")
        comp = fit_compensation(train, args.compensate)
        save_hdf5(comp.compensate(rec), args.out)
        print(f"wrote {args.out}: gyro compensated with {comp.method} ({comp.detail})")
    return 0


def cmd_ratetable(args: argparse.Namespace) -> int:
    """Bias and scale per axis at every calibration temperature of a rate-table recording (seed 001)."""
    from .inputs import load_recording
    from .ratetable import calibrate_rate_table

    points = calibrate_rate_table(load_recording(args.recording))
    print(f"{'T °C':>7} {'axis':>4} {'bias °/s':>10} {'±1σ':>8} {'scale ppm':>10} {'±1σ':>7}")
    for p in points:
        for i, a in enumerate("xyz"):
            print(f"{p.temp_c[i]:7.2f} {a:>4} {math.degrees(p.bias_rad_s[i]):10.4f} {math.degrees(p.bias_sigma[i]):8.4f} "
                  f"{p.scale[i] * 1e6:10.0f} {p.scale_sigma[i] * 1e6:7.0f}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="calib", description="Gyroscope calibration from hand rotation.")
    p.add_argument("--version", action="version", version=f"calib {__version__}")
    sub = p.add_subparsers(dest="command", required=True)
    d = sub.add_parser("demo", help="main job: simulate the hand-held session, write recording, report, .rrd")
    d.add_argument("--out", default="out", help="output folder (default ./out)")
    d.add_argument("--schedule", default="zhou2020")
    d.add_argument("--hand", default="typical")
    d.add_argument("--sensor", default="zhou2020_sim", help="sensor preset or TOML (default: Zhou 2020 Table 7)")
    d.add_argument("--rate", type=float, default=100.0)
    d.add_argument("--seed", type=int, default=1)
    d.set_defaults(func=cmd_demo)
    r = sub.add_parser("run", help="calibrate a recording (HDF5 or CSV): bias, scale factor, non-orthogonality")
    r.add_argument("recording")
    r.add_argument("--method", default="kf", choices=("kf", "iterated"),
                   help="kf: Zhou 2020's single filter pass; iterated: the filter re-run from its own estimates (reaches the CRLB)")
    r.add_argument("--json", help="write the result as JSON")
    r.add_argument("--rrd", help="write a rerun recording (P converging, estimates, signals)")
    r.add_argument("--gyro-unit", default="rad/s", help="unit of the gyro columns (rad/s, deg/s)")
    r.add_argument("--acc-unit", default="m/s^2", help="unit of the accelerometer columns (m/s^2, g)")
    r.add_argument("--external-acc", type=float, default=None,
                   help="allowance for the hand's external acceleration, m/s² RMS (default: from the rest data)")
    r.set_defaults(func=cmd_run)
    mc = sub.add_parser("montecarlo", help="Monte Carlo of the calibration against the Cramér–Rao bound")
    mc.add_argument("--schedule", default="zhou2020")
    mc.add_argument("--hand", default="ideal")
    mc.add_argument("--sensor", default="zhou2020_sim")
    mc.add_argument("--seeds", type=int, default=50)
    mc.add_argument("--rate", type=float, default=100.0)
    mc.add_argument("--methods", default="kf,iterated")
    mc.add_argument("--calibrated-accelerometer", action="store_true",
                    help="keep only the accelerometer's white noise (Zhou §3.3.2 assumes a calibrated accelerometer)")
    mc.add_argument("--json")
    mc.set_defaults(func=cmd_montecarlo)
    ob = sub.add_parser("observability", help="observability of each schedule segment (Zhou 2020 §4, Tables 5, 10, 11)")
    ob.add_argument("--schedule", default="zhou2020")
    ob.add_argument("--rate", type=float, default=100.0)
    ob.set_defaults(func=cmd_observability)
    be = sub.add_parser("bench", help="filter speed: filterpy vs the compiled batched kernel (same run)")
    be.add_argument("--batch", type=int, default=50)
    be.set_defaults(func=cmd_bench)
    al = sub.add_parser("allan", help="Allan deviation of a static recording: ARW, bias instability, rate random walk")
    al.add_argument("recording")
    al.add_argument("--png", help="write the Allan plot")
    al.add_argument("--gyro-unit", default="rad/s")
    al.add_argument("--acc-unit", default="m/s^2")
    al.set_defaults(func=cmd_allan)
    cl = sub.add_parser("closeloop", help="find the effects the declared model lacks, add them, report before/after")
    cl.add_argument("recording", help="gyrosim .h5, BROAD .hdf5, CSV (t,gyro_x..,acc_x..[,temp]) or dataset:NAME")
    cl.add_argument("--out", required=True, help="output folder: report.json, report.md, plots, closeloop.rrd")
    cl.add_argument("--declared", default="bias,scale_factor,nonorthogonality",
                    help="effects of the declared model (vocabulary names, comma-separated)")
    cl.add_argument("--reference", default=None, choices=("truth", "optical", "static", "gravity"),
                    help="force a reference (default: the best the recording has)")
    cl.add_argument("--holdout", type=float, default=4.0, help="length of the alternating fit/held-out stretches, s")
    cl.add_argument("--gyro-unit", default="rad/s")
    cl.add_argument("--acc-unit", default="m/s^2")
    cl.set_defaults(func=cmd_closeloop)
    tp = sub.add_parser("temperature", help="temperature models compared on held-out chamber cycles (issue 7)")
    tp.add_argument("recording", help="static recording with /temp (gyrosim chamber) or CSV with a temp column")
    tp.add_argument("--train-cycles", type=int, default=2, help="chamber cycles to train on; the rest are held out")
    tp.add_argument("--train", help="a separate training recording instead of cycles")
    tp.add_argument("--methods", help="comma-separated subset of: none, polynomial, piecewise_linear, rbf, polynomial+dT/dt")
    tp.add_argument("--ratetable", help="also evaluate seed 001's piecewise-linear model from this rate-table recording")
    tp.add_argument("--compensate", help="method whose compensation to write (needs --out)")
    tp.add_argument("--out", help="compensated recording (.h5); never the input")
    tp.add_argument("--json", help="write the comparison table as JSON")
    tp.add_argument("--gyro-unit", default="rad/s")
    tp.add_argument("--acc-unit", default="m/s^2")
    tp.set_defaults(func=cmd_temperature)
    rtc = sub.add_parser("ratetable", help="bias and scale at each temperature point of a rate-table recording")
    rtc.add_argument("recording")
    rtc.set_defaults(func=cmd_ratetable)
    cb = sub.add_parser("closeloop-bench", help="closeloop wall time vs the Zhou filter on the same ~3-min recordings")
    cb.set_defaults(func=cmd_closeloop_bench)
    cs = sub.add_parser("closeloop-suite", help="undeclared-effect suite over seeds (named first, |z|, error ratio)")
    cs.add_argument("--seeds", type=int, default=10)
    cs.add_argument("--first-seed", type=int, default=100)
    cs.add_argument("--truth-seed", type=int, default=1)
    cs.add_argument("--hand", default="typical")
    cs.set_defaults(func=cmd_closeloop_suite)
    i = sub.add_parser("inspect", help="summarise a recording")
    i.add_argument("recording")
    i.set_defaults(func=cmd_inspect)
    return p


def main(argv: list[str] | None = None) -> int:
    from gyrosim.cli import run_cli

    return run_cli(build_parser(), argv)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
