"""``calib mag``: hard and soft iron (and misalignment) of a recording's magnetometer
(:func:`calib.mag.calibrate_magnetometer`); its statuses live in the JSON, the exit code is 0 for ok, 1 else."""

from __future__ import annotations

import argparse
import json
import math

import numpy as np

from gyrosim.cliargs import number

from calib.app.commands.common import input_files, input_options, open_input, print_input_warnings, status_exit
from calib.app.outputs import atomic_path, check_output_paths, write_json_atomic

__all__ = ["add_parsers", "cmd_mag"]


def _mag_reference(args: argparse.Namespace) -> tuple[float | None, float | None, str]:
    """(field µT, inclination °, provenance) from --field-ut/--inclination-deg or --location (WMM)."""
    if args.location:
        from gyrosim.magnetic import environment_from_text

        env = environment_from_text(location=args.location)
        return env.magnitude_ut, env.inclination_deg, env.source
    return args.field_ut, args.inclination_deg, "given" if args.field_ut else ""


def cmd_mag(args: argparse.Namespace) -> int:
    """Hard and soft iron (and misalignment) of a recording's magnetometer (calib.mag)."""
    from calib.inputs import MAG
    from calib.mag import calibrate_magnetometer, true_magnetometer
    from calib.mag.heading import (
        compass_quaternion,
        heading_error_rad,
        heading_noise_floor_rad,
        magnetic_reference,
        up_from_quat,
    )

    check_output_paths({"--json": args.json, "--rrd": args.rrd}, input_files(args.recording))
    loaded = open_input(args, MAG)
    rec = loaded.recording
    print_input_warnings(loaded.report)
    field_ut, incl_deg, ref = _mag_reference(args)
    window = (args.t_from if args.t_from is not None else -math.inf, args.t_to if args.t_to is not None else math.inf)
    # the calibration sees what a user's file carries (samples and rate) and the options; a reference
    # position in the file (an optical tracker's) only labels where a disturbance was
    from gyrosim.estimator import as_user_file

    ref_pos = rec.truth.position_nav_m if rec.truth is not None else None
    res = calibrate_magnetometer(as_user_file(rec), args.method, mag_unit=args.mag_unit, field_ut=field_ut,
                                 inclination_deg=incl_deg, range_ut=args.range_ut, position_nav_m=ref_pos,
                                 time_range_s=window if (args.t_from is not None or args.t_to is not None) else None)
    mg = res.to_dict()["magnetometer"]

    def fmt(v, s, d=2):
        return "  ".join("—" if v_ is None else f"{v_:+.{d}f}±{(s_ if s_ is not None else float('nan')):.{d}f}"
                         for v_, s_ in zip(v, s))

    print(f"{args.recording}: method {res.method}, status {res.status}; samples {res.samples}")
    print(f"  hard iron     {fmt(mg['hard_iron_uT'], mg['std']['hard_iron_uT'])} µT")
    for i in range(3):
        print(f"  soft iron {'xyz'[i]}   {fmt(mg['soft_iron'][i], mg['std']['soft_iron'][i], 4)}")
    print(f"  field         {res.field_ut:.3f} ± {res.field_std_ut:.3f} µT ({res.field_reference})"
          + (f"; reference {ref}" if ref and ref != "given" else ""))
    print(f"  inclination   {res.inclination_deg:.3f} ± {res.inclination_std_deg:.3f} °")
    if mg["misalignment_deg"] is not None:
        print(f"  misalignment  {fmt(mg['misalignment_deg'], mg['std']['misalignment_deg'], 3)} ° (sensor axes vs IMU)")
    for d in res.disturbances:
        where = f" near {np.round(d.position_nav_m, 2).tolist()} m (ENU)" if d.position_nav_m else ""
        print(f"  disturbance   t = {d.t_start_s:.2f}–{d.t_end_s:.2f} s: |B| off by up to "
              f"{d.max_field_deviation_ut:.2f} µT{where}")
    d = res.to_dict()
    truth = true_magnetometer(rec)
    if truth is not None and rec.truth is not None and rec.truth.quat_nb is not None and res.ok:
        up = up_from_quat(rec.truth.quat_nb)
        env = rec.meta.get("magnetic_field")
        env = json.loads(env) if isinstance(env, str) else env
        earth = np.asarray(env["earth_enu_ut"]) if isinstance(env, dict) else np.array([1.5, 20.0, -44.0])
        q_ref = magnetic_reference(rec.truth.quat_nb, earth)
        before = heading_error_rad(compass_quaternion(up, rec.mag_ut), q_ref)
        after = heading_error_rad(compass_quaternion(up, res.compensate(rec.mag_ut)), q_ref)
        from gyrosim.sensor_model import stored_sensor_model

        mag_effects = stored_sensor_model(rec.meta).magnetometer
        var = [v for v in (e.sample_noise_variance(rec.rate_hz) for e in mag_effects) if v is not None]
        sig = math.sqrt(float(np.mean(sum(var)))) if any(e.is_white_noise for e in mag_effects) else 0.0
        floor = math.degrees(heading_noise_floor_rad(rec.truth.extra["mag_field"], up, sig, truth["soft_iron"]))
        rms_b, rms_a = (math.degrees(math.sqrt(float(np.mean(e**2)))) for e in (before, after))
        print(f"  vs truth: hard iron error {np.round(res.hard_iron_ut - truth['hard_iron_uT'], 3).tolist()} µT; "
              f"heading RMS (true tilt) {rms_b:.2f}° → {rms_a:.3f}°, noise floor {floor:.3f}°")
        d["truth"] = {k: np.asarray(v).tolist() for k, v in truth.items()}
        d["truth"].update(heading_rms_before_deg=rms_b, heading_rms_after_deg=rms_a, heading_noise_floor_deg=floor)
    for w in res.warnings:
        print(f"  warning: {w}")
    d["warnings"] = list(loaded.report.warnings) + list(d.get("warnings", []))
    d["input"] = loaded.report.to_dict()
    if args.json:
        write_json_atomic(args.json, d)
        print(f"wrote {args.json}")
    if args.rrd:
        from calib.app.rerun import save_magnetometer_rrd

        with atomic_path(args.rrd) as tmp:
            save_magnetometer_rrd(tmp, rec, res)
        print(f"wrote {args.rrd}; open it with:  rerun {args.rrd}")
    return status_exit(res.ok, f"magnetometer calibration {res.status}: see the warnings above for what to try")


def add_parsers(sub) -> None:
    """``mag`` on the command line's subparsers ``sub``."""
    mg = sub.add_parser("mag", help="magnetometer: hard and soft iron, misalignment",
                        description="Magnetometer calibration: hard and soft iron, misalignment, local disturbances; "
                                    "its status (ok, hard_iron_only, inconsistent, disturbed) is in the JSON, and "
                                    "the exit code is 0 for ok, 1 for the others.")
    mg.add_argument("recording", help="gyrosim .h5 (with /mag), BROAD .hdf5, CSV with mag_x,mag_y,mag_z (µT) or "
                                      "dataset:NAME")
    mg.add_argument(
        "--method",
        default="ellipsoid",
        choices=("ellipsoid", "aided"),
        help="ellipsoid: field magnitude only; aided: also the inclination against gravity (sees the misalignment)",
    )
    mg.add_argument("--json", help="write the result as JSON (magnetometer.hard_iron_uT, soft_iron, field_uT, ...)")
    mg.add_argument("--rrd", help="write a rerun recording (raw ellipsoid, calibrated sphere, |B|, disturbances)")
    mg.add_argument("--mag-unit", default="uT", help="unit of the magnetometer channel (uT, gauss, mgauss, nT)")
    mg.add_argument("--field-ut", type=number(0, 1e4, lo_open=True, unit="µT"),
                    help="true field magnitude, µT, in (0, 10000] (fixes the scale of A)")
    mg.add_argument("--inclination-deg", type=number(-90, 90, unit="°"),
                    help="true inclination, °, in [-90, 90] (resolves a one-axis session's hard iron)")
    mg.add_argument("--location", help="field and inclination from the World Magnetic Model: "
                                       "LAT,LON[,HEIGHT_M[,YYYY-MM-DD]]")
    mg.add_argument("--range-ut", type=number(0, 1e7, lo_open=True, unit="µT"),
                    help="magnetometer range (datasheet full scale), µT, > 0: samples at it are excluded; without it "
                         "only flat tops beyond 200 µT are found from the data")
    mg.add_argument("--from", dest="t_from", type=number(unit="s"), help="calibrate from this time, s (finite)")
    mg.add_argument("--to", dest="t_to", type=number(unit="s"), help="calibrate up to this time, s (finite)")
    input_options(mg)
    mg.set_defaults(func=cmd_mag)
