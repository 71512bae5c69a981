"""Instrument tests on static recordings: ``calib northfind`` (gyrocompassing; ``gyrosim northfind`` simulates
the recording it reads) and ``calib tilt`` (the tilt-sensor static test; ``gyrosim tilttable`` simulates one)."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from gyrosim.cliargs import number
from gyrosim.errors import GyrosimError

from calib.app.commands.common import input_files, input_options, open_input, print_input_warnings, status_exit
from calib.app.outputs import check_output_paths, write_json_atomic

__all__ = ["add_parsers", "cmd_northfind", "cmd_tilt"]


def _noise_arg(spec: str | None, preset: str | None):
    """--noise N,B,K (°/√h, °/h, °/h/√h) or --noise-from PRESET → per-axis NoiseTerms, else None."""
    from calib.noise.allan import NoiseTerms

    if spec and preset:
        raise GyrosimError("give --noise or --noise-from, not both")
    if preset:
        from gyrosim.sensor_model import load_sensor

        from calib.noise.window_means import noise_terms_from_model

        return noise_terms_from_model(load_sensor(preset), "gyro")
    if not spec:
        return None
    try:
        n, b, k = (float(x) for x in spec.split(","))
    except ValueError as exc:
        raise GyrosimError(f"--noise {spec!r}: give N,B,K in °/√h, °/h, °/h/√h, e.g. 0.012,0.05,0") from exc
    if min(n, b, k) < 0 or n <= 0:
        raise GyrosimError("--noise: N must be > 0 and B, K ≥ 0")
    d = math.radians(1.0)
    t = NoiseTerms(n * d / 60, b * d / 3600, k * d / 3600 / 60, 0.0, 0.0, 0.0)
    return (t, t, t)


def cmd_northfind(args: argparse.Namespace) -> int:
    """Gyrocompassing on a static multi-position record: heading, σ, the limit, refusal."""
    from calib.inputs import NORTHFIND
    from calib.instruments.northfind import find_north

    check_output_paths({"--json": args.json}, input_files(args.recording))
    loaded = open_input(args, NORTHFIND)
    rec = loaded.recording
    print_input_warnings(loaded.report)
    res, _ = find_north(
        rec,
        args.latitude_deg,
        accuracy_deg=args.accuracy_deg,
        noise=_noise_arg(args.noise, args.noise_from),
        min_hold_s=args.min_hold,
        index=args.index,
    )
    d = res.to_dict()
    print(f"{args.recording}: {res.status} — {res.reason}")
    if res.heading_deg is not None:
        print(
            f"  heading of the forward axis (position 1): {res.heading_deg:.3f}° ± {res.heading_sigma_deg:.3f}° (1σ) "
            f"from true North, latitude {res.latitude_deg:g}°" + ("" if res.ok else f"  [{res.status}: not to be used]")
        )
        print(
            f"  bias residual σ_res = {res.bias_residual_sigma_deg_h:.4f} °/h ⊥ North; limit σ_ψ = σ_res/(Ω_E cos L); "
            f"horizontal rate {res.horizontal_rate_deg_h:.4f} ± {res.horizontal_rate_sigma_deg_h:.4f} °/h "
            f"(Earth: {res.horizontal_rate_expected_deg_h:.4f}); table tilt {res.table_tilt_deg:.4f}°; "
            f"index angles from the {res.index_source}; noise {res.noise_source}"
        )
    if res.max_latitude_deg is not None or res.accuracy_deg is not None:
        print(f"  to {res.accuracy_deg:g}° this record's procedure reaches up to latitude "
              + (f"{res.max_latitude_deg:.1f}°" if res.max_latitude_deg is not None else "— (not even at the equator)"))
    if res.rest_time_note:
        print(f"  rest time: {res.rest_time_note}")
    for w in res.warnings:
        print(f"  warning: {w}")
    nf = rec.meta.get("northfind")
    if isinstance(nf, dict) and nf.get("holds") and res.heading_deg is not None:
        true = float(nf["holds"][0]["truth_heading_deg"])
        err = (res.heading_deg - true + 180.0) % 360.0 - 180.0
        d["truth"] = {"heading_deg": true, "error_deg": err, "error_over_sigma": err / res.heading_sigma_deg}
        print(f"  truth (simulation): {true:.3f}°, error {err:+.3f}° = {err / res.heading_sigma_deg:+.2f}σ")
    if args.json:
        write_json_atomic(args.json, d)
        print(f"wrote {args.json}")
    return status_exit(res.ok, f"north-finding {res.status}: the heading is not to be used (the reason is above)")


def _tilt_holds_csv(path: str, rec) -> list:
    """Holds of an external tilt test: CSV sweep,kind,angle_deg,t_start_s,t_stop_s (one row a hold)."""
    import csv

    from calib.instruments.tilt import TiltHold

    rows = list(csv.DictReader(Path(path).open(newline="")))
    need = {"sweep", "kind", "angle_deg", "t_start_s", "t_stop_s"}
    if not rows or need - set(rows[0]):
        raise GyrosimError(f"{path}: needs a header {','.join(sorted(need))} and one row per hold")
    out = []
    for r in rows:
        a, b = np.searchsorted(rec.t_s, [float(r["t_start_s"]), float(r["t_stop_s"])])
        out.append(TiltHold(r["sweep"].strip(), r["kind"].strip(), float(r["angle_deg"]), int(a), int(b)))
    return out


def cmd_tilt(args: argparse.Namespace) -> int:
    """The tilt-sensor static test of "Static Capacitance Test of MEMS Tilt Sensor": per axis sensitivity,
    linearity, cross-axis, zero offset/stability."""
    from calib.inputs import TILT
    from calib.instruments.tilt import plot_tilt, tilt_test

    check_output_paths({"--json": args.json, "--png": args.png}, input_files(args.recording, args.holds))
    loaded = open_input(args, TILT)
    rec = loaded.recording
    print_input_warnings(loaded.report)
    holds = _tilt_holds_csv(args.holds, rec) if args.holds else None
    res = tilt_test(rec, holds)
    print(f"{args.recording}: {res.status} — {res.reason}")
    for h in res.excluded:
        print(f"  left out: sweep {h.sweep} {h.kind} {h.angle_deg:g}° — {h.excluded}")

    def fmt(v, sd, spec):
        return "—" if v is None else (f"{v:{spec}} ± {sd:{spec}}" if sd is not None else f"{v:{spec}}")

    print(f"{'axis':>4} {'scale g/g':>22} {'nonlinearity %FS':>20} {'(°)':>7} {'cross-axis %':>16} "
          f"{'zero offset µg':>16} "
          f"{'mech. zero °':>18} {'Allan min µg (τ s)':>22} {'std µg':>14}")
    for a in res.axes.values():
        print(
            f"{a.axis:>4} {fmt(a.scale_factor, a.scale_factor_sigma, '.6f'):>22} "
            f"{fmt(a.nonlinearity_pct_fs, a.nonlinearity_pct_fs_sigma, '.4f'):>20} "
            f"{(a.nonlinearity_deg if a.nonlinearity_deg is not None else float('nan')):7.4f} "
            f"{fmt(a.cross_axis_pct, a.cross_axis_pct_sigma, '.3f'):>16} "
            f"{fmt(a.zero_offset_ug, a.zero_offset_ug_sigma, '.1f'):>16} "
            f"{fmt(a.mechanical_zero_deg, a.mechanical_zero_deg_sigma, '.4f'):>18} "
            f"{fmt(a.zero_stability_ug, a.zero_stability_ug_sigma, '.2f'):>14} "
            f"({a.zero_stability_tau_s or float('nan'):.0f}) "
            f"{fmt(a.zero_std_ug, a.zero_std_ug_sigma, '.1f'):>14}"
        )
    for a in res.axes.values():
        if a.linearity_table:
            print(
                f"  linearity, axis {a.axis} (seed Tables A.1–A.3): angle °, input g, output g, residual µg, residual °"
            )
            for r in a.linearity_table:
                print(f"    {r['angle_deg']:7.2f} {r['input_g']:+.6f} {r['output_g']:+.6f} {r['residual_ug']:+9.2f} "
                      f"{r['residual_deg']:+.5f}")
        if a.cross_axis_table:
            print(
                f"  cross-axis, axis {a.axis} against sweep {a.cross_axis_table[0]['sweep']} (seed Table A.4): "
                f"horizontal {a.cross_axis_horizontal_pct:+.3f} %, vertical "
                f"{a.cross_axis_vertical_pct if a.cross_axis_vertical_pct is not None else float('nan'):+.3f} %"
            )
    if args.png:
        plot_tilt(res, args.png)
        print(f"wrote {args.png}")
    if args.json:
        write_json_atomic(args.json, res.to_dict())
        print(f"wrote {args.json}")
    return status_exit(res.ok, f"tilt test {res.status}: not every figure was measured (the reason is above)")


def add_parsers(sub) -> None:
    """``northfind``, ``tilt`` on the command line's subparsers ``sub``."""
    nf = sub.add_parser("northfind", help="gyrocompassing of a static record (gyrosim northfind simulates)",
                        description="Gyrocompassing: true heading from a static 2/4-position record, with σ and its "
                                    "limit (analysis: gyrosim northfind simulates such a recording).")
    nf.add_argument("recording", help="gyrosim .h5 (gyrosim northfind) or CSV t,gyro_x..,acc_x..")
    nf.add_argument("--latitude-deg", type=number(-90, 90, unit="°"), default=None,
                    help="site latitude, °, in [-90, 90] (default: the recording's metadata)")
    nf.add_argument(
        "--accuracy-deg",
        type=number(0, 180, lo_open=True, unit="°"),
        default=None,
        help="refuse (exit 1) when the limit σ_ψ is worse than this; prints the rest time needed and the highest "
             "latitude",
    )
    nf.add_argument(
        "--noise", default=None, help="gyro noise N,B,K in °/√h, °/h, °/h/√h (default: fitted on the holds)"
    )
    nf.add_argument("--noise-from", default=None, help="take the gyro noise from a sensor preset (a datasheet prior)")
    nf.add_argument("--index", default="auto", choices=("auto", "encoder", "gyro"),
                    help="angles between positions: the table encoder (metadata) or the integrated gyro")
    nf.add_argument("--min-hold", type=number(0, 1e6, lo_open=True, unit="s"), default=10.0,
                    help="shortest usable hold, s, > 0 (default 10)")
    nf.add_argument("--json", help="write the result (status, heading, σ, limit, holds) as JSON")
    input_options(nf)
    nf.set_defaults(func=cmd_northfind)
    tl = sub.add_parser("tilt", help="tilt-sensor static test",
                        description="Tilt-sensor static test: sensitivity, linearity, cross-axis, zero offset and "
                                    "stability (gyrosim tilttable simulates such a recording).")
    tl.add_argument("recording", help="gyrosim .h5 (gyrosim tilttable), or a CSV with --holds")
    tl.add_argument("--holds", help="CSV sweep,kind,angle_deg,t_start_s,t_stop_s for a recording without tilt-table "
                                    "metadata")
    tl.add_argument("--json", help="write the figures, tables and excluded holds as JSON")
    tl.add_argument("--png", help="write output against input angle with the residuals")
    input_options(tl)
    tl.set_defaults(func=cmd_tilt)
