"""``calib lab …``: the research and benchmark commands — Monte Carlo against the Cramér–Rao bound, observability,
speed tables, the closeloop suites, north-finding and tilt-test Monte Carlo, the magnetometer comparisons.

They were top-level commands (``calib montecarlo`` …); those spellings still work, with a one-line note naming
the new one (:data:`COMMANDS`, :func:`calib.app.cli.main`).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

from gyrosim.cliargs import integer, number, seed

from calib.app.commands.common import RATE
from calib.app.outputs import check_output_paths, write_json_atomic

__all__ = ["add_parsers", "COMMANDS", "LAB_ONLY"]

# the commands of the group, formerly top-level (calib montecarlo → calib lab montecarlo)
COMMANDS = ("montecarlo", "observability", "bench", "closeloop-suite", "closeloop-bench", "northfind-latitude",
            "northfind-mc", "tilt-mc", "mag-compare", "mag-measured", "mag-bench")
# the group's commands that never had a top-level spelling
LAB_ONLY = ("validate",)
# calib run's former method spellings → the registered name in each accelerometer mode (calib.session.run)
REGISTERED_NAME_OF = {"kf_session": {"estimate": "kf_joint", "calibrated": "kf_session_r"},
                      "iterated_session": {"estimate": "iterated_joint", "calibrated": "iterated_session_r"}}


def cmd_montecarlo(args: argparse.Namespace) -> int:
    """Monte Carlo against the Cramér–Rao bound: prints the table, writes JSON if asked."""
    from tqdm import tqdm

    from calib.scoring.montecarlo import monte_carlo

    check_output_paths({"--json": args.json}, [args.schedule, args.hand, args.sensor])
    methods = tuple(args.methods.split(",")) if args.methods else None   # None: the library's default
    for m in methods or ():
        if m in REGISTERED_NAME_OF:   # calib run's former spelling: still runs, with a note
            name = REGISTERED_NAME_OF[m][args.accelerometer]
            print(f"warning: --methods {m} is deprecated: use {name} (the same filter with --accelerometer "
                  f"{args.accelerometer}, by its registered name; the table keeps the name asked)", file=sys.stderr)
    with tqdm(total=args.seeds, desc="sessions", unit="seed", leave=False) as bar:
        r = monte_carlo(args.schedule, args.hand, args.sensor, args.seeds, args.rate, methods,
                        progress=bar.update, calibrated_accelerometer=args.calibrated_accelerometer,
                        accelerometer=args.accelerometer, first_seed=args.first_seed)
    print(r.table())
    print(r.summary())
    if args.json:
        write_json_atomic(args.json, r.to_dict())
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

    from calib.session.observability import schedule_accelerometer_observability, segment_observability

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
    acc, poses = schedule_accelerometer_observability(sched, args.rate)
    names = ", ".join(f"{n.split('_')[0].replace('ba', 'b').replace('Sa', 'S').replace('Ga', 'G')}_{n[-1]}"
                      for n in acc.unobservable + acc.weak)
    print(f"accelerometer (|f| = g over the whole schedule, 3 mg per sample): posterior/prior σ "
          f"{np.round(acc.ratio, 4).tolist()} for b, S, G x y z")
    if names:
        print(f"  undetermined: {names}; add rest poses with gravity along: {'; '.join(poses) or 'more directions'}")
    else:
        print("  all nine accelerometer parameters determined: calib run can estimate the accelerometer")
    return 0


def cmd_bench(args: argparse.Namespace) -> int:
    """Speed of ``calib run``'s calibration against its former 9-state filter in filterpy (``kf_session_r``), on one
    3-minute 100 Hz session with a raw accelerometer; runs interleaved, best of ``--repeats``, same run."""
    from calib.scoring.speed import run_bench

    run_bench(batch=args.batch, repeats=args.repeats)
    return 0


def cmd_closeloop_bench(args: argparse.Namespace) -> int:
    """closeloop wall time on ~3-minute recordings against the Zhou filter on the same data, same run."""
    from calib.scoring.speed import closeloop_bench

    print(f"{'recording':<46} {'samples':>8} {'closeloop s':>12} {'Zhou filter s':>14} {'ratio':>7}")
    for r in closeloop_bench():
        print(f"{r.recording:<46} {r.samples:8d} {r.closeloop_s:12.2f} {r.filter_s:14.2f} {r.ratio:7.2f}")
    return 0


def cmd_closeloop_suite(args: argparse.Namespace) -> int:
    """The undeclared-effect suites over seeds (docs/closeloop.md table): a thin wrapper over ``run_suite``."""
    from tqdm import tqdm

    from calib.closeloop.suite import HARD_SUITE, MAG_SUITE, SUITE, format_suite, run_suite

    named = {"all": list(SUITE) + list(HARD_SUITE) + ["negative"] + list(MAG_SUITE), "mag": list(MAG_SUITE)}
    cases = named.get(args.cases) or [c.strip() for c in args.cases.split(",") if c.strip()]
    seeds = list(range(args.first_seed, args.first_seed + args.seeds))
    with tqdm(total=len(cases) * len(seeds), unit="run", desc="closeloop suite", leave=False) as bar:
        def progress(msg: str) -> None:
            bar.set_postfix_str(msg, refresh=False)
            bar.update()

        rows = run_suite(cases, seeds, progress, truth_seed=args.truth_seed, hand=args.hand)
    print(format_suite(rows))
    return 0


def cmd_northfind_latitude(args: argparse.Namespace) -> int:
    """The north-finding limit of "Effect of latitude on gyroscopic theodolite": against latitude for sensor presets."""
    from gyrosim.sensor_model import load_sensor

    from calib.instruments.northfind_plan import (
        latitude_curve,
        max_latitude_deg,
        plot_latitude_curve,
        procedure_sigma_res,
        rest_time_needed,
    )
    from calib.noise.window_means import noise_terms_from_model

    check_output_paths({"--png": args.png, "--json": args.json})
    lats = np.arange(0.0, 80.0 + 1e-9, 10.0)
    fine = np.linspace(0.0, 80.0, 161)
    names = [s.strip() for s in args.sensors.split(",") if s.strip()]
    rows, curves = {}, {}
    print(f"north-finding limit σ_ψ (°), {args.positions} positions × {args.hold:g} s rest")
    print(f"{'latitude °':>10} " + " ".join(f"{n:>16}" for n in names))
    for n in names:
        nz = noise_terms_from_model(load_sensor(n), "gyro")
        rows[n] = {"sigma_deg": latitude_curve(nz, lats, args.hold, args.positions).tolist(),
                   "sigma_res_deg_h": math.degrees(procedure_sigma_res(nz, args.hold, args.positions)) * 3600}
        curves[f"{n} ({args.positions} × {args.hold:g} s)"] = (
            fine,
            latitude_curve(nz, fine, args.hold, args.positions),
        )
        if args.accuracy_deg:
            rows[n]["max_latitude_deg"] = max_latitude_deg(
                math.radians(rows[n]["sigma_res_deg_h"] / 3600), args.accuracy_deg
            )
            rows[n]["rest_time_needed"] = {
                f"{lat:g}": rest_time_needed(nz, lat, args.accuracy_deg, positions=args.positions)[1]
                for lat in (0.0, 45.0, 70.0)
            }
    for i, lat in enumerate(lats):
        print(f"{lat:10.0f} " + " ".join(f"{rows[n]['sigma_deg'][i]:16.4g}" for n in names))
    if args.accuracy_deg:
        for n in names:
            lm = rows[n]["max_latitude_deg"]
            print(f"{n}: {args.accuracy_deg:g}° reachable up to latitude " + (f"{lm:.1f}°" if lm is not None else "— "
                                                                                                                  "(nowhere)")
                  + f" with this procedure; {rows[n]['rest_time_needed']['45']}")
    points = None
    if args.mc:
        points = {}
        for path in args.mc:
            for r in json.loads(Path(path).read_text())["rows"]:
                lat_l, rms_l = points.setdefault(r["sensor"], ([], []))
                lat_l.append(r["latitude_deg"])
                rms_l.append(r["rms_error_deg"])
        points = {k: (np.array(a), np.array(b)) for k, (a, b) in points.items()}
    if args.png:
        plot_latitude_curve(curves, args.png, accuracy_deg=args.accuracy_deg, points=points)
        print(f"wrote {args.png}")
    if args.json:
        write_json_atomic(args.json, {"positions": args.positions, "hold_s": args.hold, "latitudes_deg": lats.tolist(),
                                "accuracy_deg": args.accuracy_deg, "sensors": rows})
    return 0


def cmd_northfind_mc(args: argparse.Namespace) -> int:
    """North-finding error against the physical limit over many devices at several latitudes."""
    from tqdm import tqdm

    from gyrosim.northfind import NorthFindSequence, shielded
    from gyrosim.sensor_model import load_sensor

    from calib.scoring.instruments_mc import northfind_monte_carlo

    check_output_paths({"--json": args.json})
    lats = [float(x) for x in args.latitudes.split(",")]
    model = shielded(load_sensor(args.sensor), args.shield)
    seq = NorthFindSequence(positions=args.positions, hold_s=args.hold)
    with tqdm(total=args.seeds * len(lats), desc="north-finding", unit="run", leave=False) as bar:
        rows = northfind_monte_carlo(model, lats, args.seeds, first_seed=args.first_seed, seq=seq, rate_hz=args.rate,
                                     progress=bar.update)
    print(f"{args.sensor} (magnetic shield ×{args.shield:g}), {args.positions} positions × {args.hold:g} s, "
          f"{args.rate:g} Hz, "
          f"{args.seeds} devices per latitude")
    print(f"{'latitude °':>10} {'RMS err °':>10} {'limit °':>9} {'RMS/limit':>9} {'mean err °':>10} {'mean σ̂ °':>9} "
          f"{'RMS err/σ̂':>9}  status")
    for r in rows:
        print(f"{r.latitude_deg:10g} {r.rms_error_deg:10.4f} {r.limit_deg:9.4f} {r.efficiency:9.3f} "
              f"{r.mean_error_deg:10.4f} "
              f"{r.mean_sigma_deg:9.4f} {r.z_rms:9.3f}  {r.statuses}")
    if args.json:
        write_json_atomic(
            args.json,
            {
                "sensor": args.sensor,
                "shield": args.shield,
                "positions": args.positions,
                "hold_s": args.hold,
                "rate_hz": args.rate,
                "seeds": args.seeds,
                "rows": [r.to_dict() for r in rows],
            },
        )
        print(f"wrote {args.json}")
    return 0


def cmd_tilt_mc(args: argparse.Namespace) -> int:
    """Every figure of calib tilt against the drawn device's value over many devices."""
    from tqdm import tqdm

    from gyrosim.sensor_model import load_sensor
    from gyrosim.tilttable import TiltSequence

    from calib.scoring.instruments_mc import tilt_monte_carlo

    check_output_paths({"--json": args.json})
    seq = TiltSequence(hold_s=args.hold, zero_hold_s=args.zero_hold)
    with tqdm(total=args.seeds, desc="tilt test", unit="device", leave=False) as bar:
        rows = tilt_monte_carlo(load_sensor(args.sensor), args.seeds, first_seed=args.first_seed, seq=seq,
                                rate_hz=args.rate, progress=bar.update)
    print(f"{args.sensor}: {args.seeds} devices, {args.hold:g} s holds, {args.zero_hold:g} s level hold, {args.rate:g} "
          "Hz")
    print(f"{'axis':>4} {'figure':<26} {'device mean':>12} {'RMS error':>11} {'mean error':>11} {'mean σ̂':>10} "
          f"{'RMS err/σ̂':>10} {'max |err/σ̂|':>12}")
    for r in rows:
        print(f"{r.axis:>4} {r.figure:<26} {r.device_mean:12.5g} {r.rms_error:11.4g} {r.mean_error:11.3g} "
              f"{r.mean_sigma:10.4g} "
              f"{r.z_rms:10.2f} {r.max_abs_z:12.2f}")
    if args.json:
        write_json_atomic(args.json, {"sensor": args.sensor, "seeds": args.seeds, "rows": [r.to_dict() for r in rows]})
        print(f"wrote {args.json}")
    return 0


def cmd_mag_compare(args: argparse.Namespace) -> int:
    """The KF / adaptive KF / particle filter of "Soft Magnetic Error Compensation Method of Electronic Compass"
    against calibration, on a simulated device."""
    from calib.mag.compare import comparison_table, plot_heading_allan, simulated_comparison

    c = simulated_comparison(args.sensor, seed=args.seed, hand=args.hand, method=args.method)
    print(f"sensor {c.sensor} (seed {args.seed}), calibrated on multiposition ({c.calibration.status}), used on "
          "'compass'; heading error against the truth, tilt from the accelerometer:")
    print(comparison_table(c.rows))
    print("the same with the true tilt (the magnetometer alone):")
    print(comparison_table(c.rows_true_tilt))
    print(f"heading noise floor of the magnetometer (true tilt): {c.noise_floor_deg:.3f}°")
    if args.png:
        plot_heading_allan(c.rows, args.png, title=f"compass heading error, {c.sensor}: Allan deviation")
        print(f"wrote {args.png}")
    return 0


def cmd_mag_measured(args: argparse.Namespace) -> int:
    """Measured recordings' magnetometers: field spread and heading error against the optical reference."""
    from calib.mag.measured import measured_table

    print(measured_table(args.method))
    return 0


def cmd_mag_bench(args: argparse.Namespace) -> int:
    """Speed of the magnetometer fits on a 3-minute 100 Hz session (ratios against a baseline, same run)."""
    from calib.scoring.mag_speed import run_mag_bench

    run_mag_bench(repeats=args.repeats)
    return 0


def _add_calibration(lab) -> None:
    mc = lab.add_parser("montecarlo", help="Monte Carlo of the calibration against the Cramér–Rao bound")
    mc.add_argument("--schedule", default="zhou2020", help="schedule of every session: built-in name or TOML path "
                                                           "(default zhou2020)")
    mc.add_argument("--hand", default="ideal", help="hand preset or TOML path (default ideal: the paper's motion)")
    mc.add_argument("--sensor", default="zhou2020_sim", help="sensor preset or TOML path (default zhou2020_sim: Zhou "
                                                             "2020 Table 7)")
    mc.add_argument("--seeds", type=integer(2, 100_000), default=50, help="sessions, 2 … 1e5 (default 50)")
    mc.add_argument("--rate", type=number(20, 1000, unit="Hz"), default=100.0, help="sample rate, Hz, in [20, 1000] "
                                                                                    "(default 100)")
    mc.add_argument(
        "--methods",
        default=None,
        help="comma-separated registered estimators — kf (the paper's filter), iterated (it in three passes), "
        "kf_joint, iterated_joint, kf_session_r, iterated_session_r (calib run's hand-blind filter), kf_hand, "
        "kf_hand_joint (the hand-aware one), kf_adaptive, … — or package.module:attribute; kf_session, "
        "iterated_session are former spellings of calib run's hand-blind filter in the --accelerometer mode asked "
        "(deprecated; the table keeps the name asked); default kf,iterated_session, or kf_session,iterated_session "
        "with --accelerometer estimate (the paper's kf assumes a calibrated accelerometer)",
    )
    mc.add_argument("--calibrated-accelerometer", action="store_true",
                    help="simulate a calibrated accelerometer: keep only its white noise (Zhou §3.3.2's assumption)")
    mc.add_argument("--accelerometer", default="calibrated", choices=("estimate", "calibrated"),
                    help="what the calibration assumes (calib run --accelerometer; default calibrated: the paper)")
    mc.add_argument("--first-seed", type=seed, default=0, help="first seed of the sessions, 0 … 2³²−1")
    mc.add_argument("--json", help="write the table as JSON")
    mc.set_defaults(func=cmd_montecarlo)
    ob = lab.add_parser("observability", help="observability of each schedule segment (Zhou 2020 §4, Tables 5, 10, 11)")
    ob.add_argument("--schedule", default="zhou2020", help="schedule to analyse: built-in name or TOML path (default "
                                                           "zhou2020)")
    ob.add_argument("--rate", type=RATE, default=100.0, help="sample rate, Hz, in (0, 1e6] (default 100)")
    ob.set_defaults(func=cmd_observability)
    be = lab.add_parser("bench", help="calibration speed: calib run (21 states) vs the paper's filterpy kf, same run")
    be.add_argument("--batch", type=integer(1, 10_000), default=50, help="batch size of the kernel-only row, 1 … 10000 "
                                                                         "(default 50)")
    be.add_argument("--repeats", type=integer(1, 1000), default=3,
                    help="interleaved repetitions, 1 … 1000; the best of each is reported (default 3)")
    be.set_defaults(func=cmd_bench)


def _add_closeloop(lab) -> None:
    cb = lab.add_parser("closeloop-bench", help="closeloop wall time vs the Zhou filter on the same ~3-min recordings")
    cb.set_defaults(func=cmd_closeloop_bench)
    cs = lab.add_parser("closeloop-suite", help="undeclared-effect suites over seeds: single effects, pairs, a static "
                        "chamber with accelerometer drift, slow motion, magnetometer effects, negative controls")
    cs.add_argument("--seeds", type=integer(1, 100_000), default=10, help="sensor-noise seeds per case, 1 … 1e5 "
                                                                          "(default 10)")
    cs.add_argument(
        "--first-seed", type=seed, default=100, help="first seed, 0 … 2³²−1 (seeds are consecutive; default 100)"
    )
    cs.add_argument("--cases", default="all", help="comma-separated case names (calib.closeloop.suite SUITE, "
                                                   "HARD_SUITE, "
                    "'negative', MAG_SUITE), 'mag' (the magnetometer cases) or 'all'")
    cs.add_argument("--truth-seed", type=seed, default=1,
                    help="seed of the simulated truth sessions (motion, hand), 0 … 2³²−1 (default 1)")
    cs.add_argument("--hand", default="typical", help="hand of the 'typical' session (the slow session uses 'steady')")
    cs.set_defaults(func=cmd_closeloop_suite)


def _add_instruments(lab) -> None:
    nl = lab.add_parser("northfind-latitude", help="north-finding limit against latitude for sensor presets (table, "
                                                   "plot)")
    nl.add_argument("--sensors", default="fog_tactical,mpu9250", help="comma-separated sensor presets")
    nl.add_argument("--positions", type=integer(2, 360), default=4, help="positions, 2 … 360 (default 4)")
    nl.add_argument(
        "--hold", type=number(0, 1e7, lo_open=True, unit="s"), default=300.0, help="rest per position, s, > 0"
    )
    nl.add_argument("--accuracy-deg", type=number(0, 180, lo_open=True, unit="°"), default=None,
                    help="print the highest latitude reaching this accuracy, °, > 0")
    nl.add_argument("--mc", action="append", help="northfind-mc JSON whose RMS errors to draw as points (repeatable)")
    nl.add_argument("--png", help="write the latitude plot")
    nl.add_argument("--json", help="write the table as JSON")
    nl.set_defaults(func=cmd_northfind_latitude)
    nm = lab.add_parser(
        "northfind-mc", help="north-finding error vs the physical limit over many devices and latitudes"
    )
    nm.add_argument("--sensor", default="fog_tactical", help="sensor preset or TOML path (default fog_tactical)")
    nm.add_argument("--shield", type=number(0, None, lo_open=True), default=1e3,
                    help="divide the magnetic sensitivity by this, > 0 (default 1e3: shielded)")
    nm.add_argument("--latitudes", default="0,45,70", help="comma-separated site latitudes, ° (default 0,45,70)")
    nm.add_argument("--seeds", type=integer(1, 100_000), default=50, help="devices, 1 … 1e5 (default 50)")
    nm.add_argument("--first-seed", type=seed, default=0, help="first seed, 0 … 2³²−1")
    nm.add_argument("--positions", type=integer(2, 360), default=4, help="positions, 2 … 360 (default 4)")
    nm.add_argument(
        "--hold", type=number(0, 1e7, lo_open=True, unit="s"), default=300.0, help="rest per position, s, > 0"
    )
    nm.add_argument("--rate", type=number(0, 500, lo_open=True, unit="Hz"), default=20.0,
                    help="output rate, Hz (a divisor of 500; default 20)")
    nm.add_argument("--json", help="write the table as JSON (input of northfind-latitude --mc)")
    nm.set_defaults(func=cmd_northfind_mc)
    tm = lab.add_parser("tilt-mc", help="each calib tilt figure against the drawn device's value over many devices")
    tm.add_argument("--sensor", default="tilt_001", help="tilt-sensor preset or TOML path (default tilt_001, the chip "
                                                         "of 'Static Capacitance Test of MEMS Tilt Sensor')")
    tm.add_argument("--seeds", type=integer(1, 100_000), default=20, help="devices, 1 … 1e5 (default 20)")
    tm.add_argument("--first-seed", type=seed, default=0, help="first seed, 0 … 2³²−1")
    tm.add_argument("--hold", type=number(0, 1e7, lo_open=True, unit="s"), default=30.0, help="hold per angle, s, > 0")
    tm.add_argument(
        "--zero-hold", type=number(0, 1e7, lo_open=True, unit="s"), default=3600.0, help="zero hold, s, > 0"
    )
    tm.add_argument("--rate", type=number(0, 1e4, lo_open=True, unit="Hz"), default=10.0, help="output rate, Hz, > 0")
    tm.add_argument("--json", help="write the table as JSON")
    tm.set_defaults(func=cmd_tilt_mc)


def _add_mag(lab) -> None:
    mc2 = lab.add_parser(
        "mag-compare",
        help="in-motion heading compensation (Soft Magnetic Error Compensation Method "
        "of Electronic Compass): KF / adaptive KF / particle filter vs calibration (simulated)",
    )
    mc2.add_argument(
        "--sensor", default="phone", help="sensor preset with a magnetometer, or TOML path (default phone)"
    )
    mc2.add_argument("--seed", type=seed, default=7, help="seed, 0 … 2³²−1 (default 7)")
    mc2.add_argument("--hand", default="typical", help="hand preset or TOML path (default typical)")
    mc2.add_argument("--method", default="aided", choices=("ellipsoid", "aided"),
                     help="calibration method, as calib mag --method (default aided)")
    mc2.add_argument("--png", help="write the Allan plot of the heading error")
    mc2.set_defaults(func=cmd_mag_compare)
    mm = lab.add_parser("mag-measured", help="magnetometers of the measured recordings: field spread, heading vs "
                                             "optical")
    mm.add_argument("--method", default="ellipsoid", choices=("ellipsoid", "aided"),
                    help="calibration method, as calib mag --method (default ellipsoid)")
    mm.set_defaults(func=cmd_mag_measured)
    mb = lab.add_parser("mag-bench", help="speed of the ellipsoid and attitude-aided fits on a 3-minute 100 Hz session")
    mb.add_argument("--repeats", type=integer(1, 1000), default=5, help="timing repeats, 1 … 1000 (default 5)")
    mb.set_defaults(func=cmd_mag_bench)


def cmd_validate(args: argparse.Namespace) -> int:
    """The measured-data harness (:mod:`calib.scoring.measured`): calib run/apply/mag on every recording with a
    reference in the data folder, scored by the filters users run next."""
    from gyrosim.loaders import data_root

    from calib.scoring import measured

    argv = [str(args.data_dir or data_root())]
    for flag in ("only", "json", "markdown", "workdir"):
        if getattr(args, flag) is not None:
            argv += [f"--{flag}", str(getattr(args, flag))]
    return measured.main(argv)


def _add_validate(lab) -> None:
    va = lab.add_parser("validate", help="judge calib on measured recordings: calib run and apply as a user runs them, "
                                         "then VQF/Madgwick/Mahony and the peers' figures (raw, bias only, full)")
    va.add_argument("data_dir", nargs="?", default=None,
                    help="the measured-data folder (default: $GYROSIM_DATA, else ../shared/data)")
    va.add_argument("--only", metavar="NAME", help="only the recordings whose name contains NAME (e.g. broad/16_)")
    va.add_argument("--json", metavar="OUT", help="write the result as JSON")
    va.add_argument("--markdown", metavar="OUT", help="write the tables as Markdown")
    va.add_argument("--workdir", metavar="DIR", help="keep calib's files (cal.json, comp.h5, mag.json) here")
    va.set_defaults(func=cmd_validate)


def add_parsers(sub) -> None:
    """``lab`` and its commands (:data:`COMMANDS`) on the command line's subparsers ``sub``."""
    group = sub.add_parser(
        "lab", help="research and benchmark commands (calib lab --help)",
        description="Research and benchmark commands: Monte Carlo against the Cramér–Rao bound, observability, "
                    "speed tables, the closeloop suites, north-finding and tilt-test Monte Carlo, magnetometer "
                    "comparisons, and the measured-data validation (calib lab validate). Each has --help.")
    lab = group.add_subparsers(dest="lab_command", required=True, title="lab commands", metavar="COMMAND",
                               help="the research or benchmark command to run")
    _add_calibration(lab)
    _add_closeloop(lab)
    _add_instruments(lab)
    _add_mag(lab)
    _add_validate(lab)
