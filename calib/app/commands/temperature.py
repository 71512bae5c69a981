"""Temperature: ``calib temperature`` (models compared on held-out chamber cycles) and ``calib ratetable``
(bias and scale per temperature point of a rate-table recording; ``gyrosim ratetable`` simulates one)."""

from __future__ import annotations

import argparse
import math

from gyrosim.cliargs import integer
from gyrosim.errors import GyrosimError

from calib.app.commands.common import input_files, input_options, open_input, print_input_warnings
from calib.app.outputs import atomic_path, check_output_paths, write_json_atomic

__all__ = ["add_parsers", "cmd_temperature", "cmd_ratetable"]


def cmd_temperature(args: argparse.Namespace) -> int:
    """Compare temperature models on held-out chamber cycles; optionally write a compensated copy."""
    from gyrosim.recording import save_hdf5

    from calib.inputs import RATETABLE, TEMPERATURE
    from calib.temperature.compensation import (
        METHODS,
        ThermalCompensation,
        compare_methods,
        fit_compensation,
        fit_methods,
        split_cycles,
    )

    if args.compensate and not args.out:
        raise GyrosimError("--compensate needs --out PATH for the compensated recording")
    check_output_paths({"--json": args.json, "--out": args.out, "--rrd": args.rrd},
                       input_files(args.recording, args.train, args.ratetable))
    loaded = open_input(args, TEMPERATURE)
    rec = loaded.recording
    print_input_warnings(loaded.report)
    if args.train:
        train, test = [open_input(args, TEMPERATURE, args.train).recording], [rec]
    else:
        cycles = split_cycles(rec)
        if len(cycles) <= args.train_cycles:
            raise GyrosimError(f"{len(cycles)} chamber cycle(s): cannot train on {args.train_cycles} and hold any out; "
                               "pass --train-cycles smaller or --train RECORDING")
        train, test = cycles[: args.train_cycles], cycles[args.train_cycles :]
    methods = tuple(m.strip() for m in args.methods.split(",")) if args.methods else METHODS
    extra = {}
    if args.ratetable:
        from calib.temperature.ratetable import calibrate_rate_table, piecewise_model

        rt = open_input(args, RATETABLE, args.ratetable).recording
        extra["piecewise_linear (rate-table points)"] = ThermalCompensation(
            "piecewise_linear (rate-table points)", (piecewise_model(calibrate_rate_table(rt)),))
    fitted = fit_methods(train, methods, extra)
    rows = compare_methods(train, test, methods, fitted=fitted)
    base = rows[0]
    print(f"held out: {len(test)} record(s)/cycle(s); trained on {len(train)}")
    print(f"{'method':<38} {'RMS °/s':>9} {'BS °/h':>9} {'ADEV min °/h':>13} {'ADEV 1000 s °/h':>16} "
          f"{'× better (BS)':>14}")
    for r in rows:
        print(f"{r.method:<38} {r.held_out_rms_deg_s:9.4f} {r.bias_stability_deg_h:9.2f} {r.adev_min_deg_h:13.2f} "
              f"{r.adev_1000s_deg_h:16.2f} {base.bias_stability_deg_h / r.bias_stability_deg_h:14.1f}")
    if args.json:
        write_json_atomic(args.json, [r.__dict__ for r in rows])
    if args.rrd:
        from calib.app.rerun_temperature import save_temperature_rrd

        held = [(float(c.t_s[0]), float(c.t_s[-1])) for c in test] if not args.train else \
            [(float(rec.t_s[0]), float(rec.t_s[-1]))]
        desc = f"{args.train}" if args.train else f"the first {args.train_cycles} chamber cycle(s)"
        with atomic_path(args.rrd) as tmp:
            save_temperature_rrd(tmp, rec, fitted, rows, held, desc)
        print(f"wrote {args.rrd}; open it with:  rerun {args.rrd}")
    if args.compensate:
        comp = fit_compensation(train, args.compensate)
        save_hdf5(comp.compensate(rec), args.out)
        print(f"wrote {args.out}: gyro compensated with {comp.method} ({comp.detail})")
    return 0


def cmd_ratetable(args: argparse.Namespace) -> int:
    """Bias and scale per axis at every calibration temperature of a rate-table recording ("Measurement Error and
    Calibration of FOG IMU")."""
    from calib.inputs import RATETABLE
    from calib.temperature.ratetable import calibrate_rate_table

    points = calibrate_rate_table(open_input(args, RATETABLE).recording)
    print(f"{'T °C':>7} {'axis':>4} {'bias °/s':>10} {'±1σ':>8} {'scale ppm':>10} {'±1σ':>7}")
    for p in points:
        for i, a in enumerate("xyz"):
            print(f"{p.temp_c[i]:7.2f} {a:>4} {math.degrees(p.bias_rad_s[i]):10.4f} "
                  f"{math.degrees(p.bias_sigma[i]):8.4f} "
                  f"{p.scale[i] * 1e6:10.0f} {p.scale_sigma[i] * 1e6:7.0f}")
    return 0


def add_parsers(sub) -> None:
    """``temperature``, ``ratetable`` on the command line's subparsers ``sub``."""
    tp = sub.add_parser("temperature", help="temperature models on held-out chamber cycles",
                        description="Temperature models compared on held-out chamber cycles (gyrosim chamber simulates "
                                    "such a recording); optionally a compensated copy.")
    tp.add_argument("recording", help="static recording with /temp (gyrosim chamber) or CSV with a temp column")
    tp.add_argument("--train-cycles", type=integer(1, 10_000), default=2,
                    help="chamber cycles to train on, ≥ 1; the rest are held out (default 2)")
    tp.add_argument("--train", help="a separate training recording instead of cycles")
    tp.add_argument("--methods", help="comma-separated subset of: none, polynomial, piecewise_linear, rbf, "
                                      "polynomial+dT/dt")
    tp.add_argument("--ratetable", help="also evaluate the piecewise-linear model between calibration points from this "
                                        "rate-table recording")
    tp.add_argument("--compensate", help="method whose compensation to write (needs --out)")
    tp.add_argument("--out", help="compensated recording (.h5); never the input")
    tp.add_argument("--json", help="write the comparison table as JSON")
    tp.add_argument(
        "--rrd", help="write a rerun recording: temperature, drift, each model's held-out residual, bias vs temperature"
    )
    input_options(tp)
    tp.set_defaults(func=cmd_temperature)
    rtc = sub.add_parser("ratetable", help="analyse a rate-table record (gyrosim ratetable simulates)",
                         description="Bias and scale per axis at each temperature point of a rate-table recording "
                                     "(analysis: gyrosim ratetable simulates such a recording).")
    rtc.add_argument("recording", help="rate-table recording (gyrosim ratetable)")
    input_options(rtc)
    rtc.set_defaults(func=cmd_ratetable)
