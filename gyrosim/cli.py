"""``gyrosim`` command line: thin wrappers over library calls (each is a function a user can call)."""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import sys
from pathlib import Path

import numpy as np

from . import __version__
from .cliargs import integer, number, positive_list, seed
from .errors import GyrosimError
from .hand import hand_preset_names, load_hand
from .outputs import check_output_paths
from .recording import save_hdf5
from .schedule import builtin_schedule_names, load_schedule

MAX_RATE_HZ = 1e6  # beyond any IMU; a larger --rate is a typo, and would only exhaust memory


def _check_writable(out: Path, *inputs: str | None, option: str = "--out") -> None:
    """The output path is writable, not a folder, and none of the inputs (TOML files given by path)."""
    check_output_paths({option: out}, inputs)


def cmd_simulate(args: argparse.Namespace) -> int:
    """Simulate a hand-held session (schedule, hand, optionally a sensor) and write it as an HDF5
    recording; prints what was written and the hand's disturbance RMS (m/s², °/s)."""
    from tqdm import tqdm

    from .magnetic import environment_from_text
    from .sensor_model import load_sensor
    from .simulate import simulate, simulation_grid

    out = Path(args.out)
    _check_writable(out, args.schedule, args.hand, args.sensor)  # fail before minutes of simulation, not after
    schedule = load_schedule(args.schedule)
    hand = load_hand(args.hand)
    sensor = load_sensor(args.sensor) if args.sensor else None
    magnetic = environment_from_text(args.mag_field, args.location, args.anomaly or ())
    grid = simulation_grid(schedule.duration_s, args.rate, args.physics_rate)
    with tqdm(total=grid.t_physics_s.size + 1, unit="step", desc="simulating", disable=args.quiet, leave=False) as bar:
        rec = simulate(
            schedule, hand, sensor, args.rate, seed=args.seed, physics_rate_hz=args.physics_rate, progress=bar.update,
            magnetic=magnetic,
        )
    save_hdf5(rec, out)
    if not args.quiet:
        ext_rms, dw_rms = rec.truth.disturbance_rms()
        print(
            f"wrote {out}: {rec.n} samples at {rec.rate_hz:g} Hz ({rec.duration_s:.1f} s), "
            f"schedule {schedule.name}, hand {hand.name}, sensor {sensor.name if sensor else 'none (truth)'}, "
            f"seed {args.seed}; "
            f"external acc RMS {ext_rms:.4f} m/s², "
            f"rate disturbance RMS {math.degrees(dw_rms):.3f} °/s"
        )
    return 0


def cmd_hands(args: argparse.Namespace) -> int:
    """List the hand presets with the external acceleration (m/s²) and rate disturbance (°/s) each is
    expected to produce over a schedule, smallest first."""
    schedule = load_schedule(args.schedule)
    print(f"hand presets on schedule {schedule.name} (expected RMS over the session)")
    print(f"{'preset':<9} {'ext acc m/s²':>13} {'of which pivot':>15} {'rate dist °/s':>14}  description")
    rows = [(load_hand(name), ) for name in hand_preset_names()]
    rows = sorted(((h, h.expected_disturbance(schedule)) for (h,) in rows), key=lambda r: r[1]["external_acc_rms_m_s2"])
    for hand, e in rows:
        name = hand.name
        print(
            f"{name:<9} {e['external_acc_rms_m_s2']:>13.4f} {e['pivot_acc_rms_m_s2']:>15.4f} "
            f"{math.degrees(e['rate_disturbance_rms_rad_s']):>14.3f}  {hand.description}"
        )
    return 0


def cmd_schedules(args: argparse.Namespace) -> int:
    """List the built-in schedules (duration, segments, description); ``--show`` prints one as JSON."""
    for name in builtin_schedule_names():
        s = load_schedule(name)
        print(f"{name:<14} {s.duration_s:7.1f} s  {len(s.segments):3d} segments  {s.description}")
    if args.show:
        s = load_schedule(args.show)
        print(json.dumps(s.to_dict(), indent=2))
    return 0


def cmd_sensors(args: argparse.Namespace) -> int:
    """List the sensor presets with each triad's effects; ``--show`` prints one as JSON."""
    from .sensor_model import load_sensor, sensor_preset_names

    for name in sensor_preset_names():
        m = load_sensor(name)
        print(f"{name:<22} gyro: {', '.join(e.kind for e in m.gyro)}")
        print(f"{'':<22} accelerometer: {', '.join(e.kind for e in m.accelerometer)}")
        if m.magnetometer:
            print(f"{'':<22} magnetometer: {', '.join(e.kind for e in m.magnetometer)}")
        print(f"{'':<22} {m.description}")
    if args.show:
        print(json.dumps(load_sensor(args.show).to_dict(), indent=2))
    return 0


def cmd_bench(args: argparse.Namespace) -> int:
    """Simulation speed: the MuJoCo scene, the sensor error model, or both (gyrosim.bench)."""
    from .bench import run_bench, run_sensor_bench

    if args.what in ("all", "scene"):
        run_bench(repeats=args.repeats, schedule=args.schedule, hand=args.hand, rate_hz=args.rate)
    if args.what in ("all", "sensor"):
        run_sensor_bench(repeats=max(args.repeats, 3), sensor=args.sensor)
    return 0


def cmd_chamber(args: argparse.Namespace) -> int:
    """A board fixed in a thermal chamber for a whole profile (gyrosim.chamber.simulate_chamber)."""
    from .chamber import load_chamber, simulate_chamber

    out = Path(args.out)
    _check_writable(out, args.profile, args.sensor)
    profile = load_chamber(args.profile)
    rec = simulate_chamber(profile, args.sensor, args.rate, seed=args.seed, up_axis=args.up)
    save_hdf5(rec, out)
    print(f"wrote {out}: {rec.n} samples at {args.rate:g} Hz over {profile.duration_s / 3600:.1f} h "
          f"({len(profile.cycle_starts_s)} cycle(s) of {profile.name}); sensor temperature "
          f"{rec.temp_c.min():.1f}…{rec.temp_c.max():.1f} °C")
    return 0


def cmd_ratetable(args: argparse.Namespace) -> int:
    """The ±rate / one-position scheme of "Measurement Error and Calibration of FOG IMU" on the virtual rate table
    inside a chamber profile (``calib ratetable`` analyses the recording)."""
    from .chamber import load_chamber
    from .ratetable import RateTableSequence, simulate_rate_table

    out = Path(args.out)
    _check_writable(out, args.profile, args.sensor)
    seq = RateTableSequence(rate_deg_s=args.table_rate, turns=args.turns, settle_s=args.settle)
    rec = simulate_rate_table(load_chamber(args.profile), args.sensor, args.rate, seq=seq, seed=args.seed)
    save_hdf5(rec, out)
    holds = sorted({s["ambient_c"] for s in rec.meta["segments"]})
    print(f"wrote {out}: {rec.n} samples at {args.rate:g} Hz; calibration temperatures {holds} °C, six faces each, "
          f"±{args.table_rate:g} °/s")
    return 0


def _knocks(specs: list[str] | None):
    """``HOLD[:DEG[:AXIS]]`` → Knock(hold, amplitude_deg, axis)."""
    from .rig import Knock

    out = []
    for spec in specs or []:
        parts = spec.split(":")
        try:
            out.append(
                Knock(int(parts[0]), float(parts[1]) if len(parts) > 1 else 0.5, parts[2] if len(parts) > 2 else "x")
            )
        except ValueError as exc:
            raise GyrosimError(f"--knock {spec!r}: use HOLD[:DEG[:AXIS]], e.g. 2:0.5:x ({exc})") from exc
    return tuple(out)


def cmd_northfind(args: argparse.Namespace) -> int:
    """A north-finding (gyrocompassing) record on the virtual indexing table (gyrosim.northfind; ``calib northfind``
    analyses it)."""
    from .northfind import NorthFindSequence, shielded, simulate_northfind
    from .sensor_model import load_sensor

    out = Path(args.out)
    _check_writable(out, args.sensor)
    seq = NorthFindSequence(positions=args.positions, hold_s=args.hold, index_rate_deg_s=args.index_rate)
    model = shielded(load_sensor(args.sensor), args.shield)
    rec = simulate_northfind(model, args.latitude, args.heading, args.rate, seq=seq, seed=args.seed,
                             tilt_deg=args.tilt, tilt_azimuth_deg=args.tilt_azimuth, knocks=_knocks(args.knock))
    save_hdf5(rec, out)
    nf = rec.meta["northfind"]
    print(
        f"wrote {out}: {rec.n} samples at {args.rate:g} Hz ({rec.duration_s / 60:.1f} min), {args.sensor} at latitude "
        f"{args.latitude:g}°, {seq.positions} position(s) × {seq.hold_s:g} s, true headings "
        + ", ".join(f"{h['truth_heading_deg']:.3f}°" for h in nf["holds"])
    )
    return 0


def cmd_tilttable(args: argparse.Namespace) -> int:
    """The static tilt-sensor test of "Static Capacitance Test of MEMS Tilt Sensor" on a dividing head
    (gyrosim.tilttable; ``calib tilt`` analyses the recording)."""
    from .tilttable import SEED_001_ANGLES_DEG, TiltSequence, simulate_tilttable

    out = Path(args.out)
    _check_writable(out, args.sensor)
    if args.angles:
        try:
            lo, hi, step = (float(x) for x in args.angles.split(":"))
        except ValueError as exc:
            raise GyrosimError(f"--angles {args.angles!r}: give FROM:TO:STEP in °, e.g. -15:15:2.5") from exc
        if not step > 0:
            raise GyrosimError("--angles: STEP must be > 0")
        angles = tuple(np.round(np.arange(lo, hi + step / 2, step), 6).tolist())
    else:
        angles = SEED_001_ANGLES_DEG
    seq = TiltSequence(angles_deg=angles, hold_s=args.hold, zero_hold_s=args.zero_hold, flip=not args.no_flip)
    rec = simulate_tilttable(args.sensor, args.rate, seq=seq, knocks=_knocks(args.knock), seed=args.seed)
    save_hdf5(rec, out)
    holds = rec.meta["tilttable"]["holds"]
    print(f"wrote {out}: {rec.n} samples at {args.rate:g} Hz ({rec.duration_s / 60:.1f} min), {args.sensor}, "
          f"{len(holds)} holds: sweeps {','.join(seq.sweeps)} over {angles[0]:g}…{angles[-1]:g}° "
          f"({len(angles)} steps){' + 180°' if seq.flip else ''}, level {seq.zero_hold_s:g} s")
    return 0


def _csv_list(v: str | None) -> tuple[str, ...] | None:
    return tuple(x.strip() for x in v.split(",") if x.strip()) if v else None


@contextlib.contextmanager
def session_progress(desc: str):
    """A tqdm bar over a campaign's sessions; yields the ``progress(done, total)`` callback the
    campaign runners call as tasks finish (the total is known only once the runner has read what
    is already done)."""
    from tqdm import tqdm

    with tqdm(total=1, unit="session", desc=desc) as bar:
        def progress(done: int, total: int) -> None:
            bar.total = total
            bar.n = done
            bar.refresh()

        yield progress


def cmd_orientation_campaign(args: argparse.Namespace) -> int:
    """Orientation estimators × hands × raw/calibrated, scored against the truth (gyrosim.orientation_campaign)."""
    from .orientation_campaign import OrientationSpec, replace_spec, run_orientation_campaign, summarise_orientation

    if args.campaign:
        raise GyrosimError("a campaign TOML describes a calibration campaign; an orientation campaign (--orientation) "
                           "takes its settings as flags")
    check_output_paths({"--out": args.out}, [], folders=["--out"],
                       folder_files={"--out": ("orientation_results.csv", "orientation_summary.csv",
                                               "orientation_provenance.json", "orientation_vs_severity.png",
                                               "orientation_raw_vs_calibrated.png")})
    spec = replace_spec(OrientationSpec(), hands=_csv_list(args.hand), seeds=args.seeds, first_seed=args.first_seed,
                        sensor=args.sensor, estimators=_csv_list(args.orientation), schedule=args.schedule,
                        rate_hz=args.rate, severity=args.severity, variants=_csv_list(args.variants),
                        calibration=args.calibration)
    with session_progress("orientation campaign") as progress:
        path = run_orientation_campaign(spec, args.out, scheduler=args.scheduler, workers=args.workers,
                                        connect_timeout_s=args.timeout, progress=progress)
    summary = summarise_orientation(path, args.out)
    print(f"{'hand':<9} {'sev':>4} {'variant':<10} {'estimator':<14} {'n':>4} {'fail':>4} {'tilt RMS ° [95%]':>22} "
          f"{'heading RMS °':>13} {'drift RMS °/min [95%]':>24} {'conv. s [95%]':>20} {'never':>5}")
    for r in summary:
        if "tilt_rms_deg" not in r:
            print(f"{r['hand']:<9} {r['severity']:4g} {r['variant']:<10} {r['estimator']:<14} {r['n']:4d} "
                  f"{r['failed']:4d}"
                  f"  (all failed: {r['first_error'][:80]})")
            continue
        print(f"{r['hand']:<9} {r['severity']:4g} {r['variant']:<10} {r['estimator']:<14} {r['n']:4d} {r['failed']:4d} "
              f"{r['tilt_rms_deg']:7.3f} [{r['tilt_rms_deg_lo']:.3f}, {r['tilt_rms_deg_hi']:.3f}] "
              f"{r['heading_rms_deg']:13.3f} {r['drift_rms_deg_min']:8.3f} [{r['drift_rms_deg_min_lo']:.3f}, "
              f"{r['drift_rms_deg_min_hi']:.3f}] {r['convergence_s']:6.2f} [{r['convergence_s_lo']:.2f}, "
              f"{r['convergence_s_hi']:.2f}] {r['not_converged']:5d}")
    print(f"wrote {path}, {Path(args.out) / 'orientation_summary.csv'} and the plots")
    failed = sum(r["failed"] for r in summary)
    return status_exit(not failed, f"{failed} session(s) failed: the fail column above and {path} say which and why")


def cmd_orientation_broad(args: argparse.Namespace) -> int:
    """BROAD trials scored with BROAD's error definitions, beside the published numbers."""
    from .orientation_broad import format_table, score_broad

    if args.json:
        check_output_paths({"--json": args.json}, [])
    result = score_broad(estimators=_csv_list(args.estimators))
    print(format_table(result))
    if args.json:
        from .outputs import write_json_atomic

        write_json_atomic(args.json, result)
        print(f"wrote {args.json}")
    return status_exit(bool(result["within_tolerance"]),
                       "outside the tolerance of BROAD's published numbers: see the table above")


def cmd_orientation_view(args: argparse.Namespace) -> int:
    """One simulated session in rerun: truth vs each estimator's attitude and the error series."""
    from .orientation_rerun import view_session

    check_output_paths({"--rrd": args.rrd}, [])
    path = view_session(hand=args.hand, sensor=args.sensor, seed=args.seed, schedule=args.schedule,
                        estimators=_csv_list(args.estimators) or ("vqf", "madgwick", "mahony", "fusion"),
                        variant=args.variant, rrd=args.rrd)
    print(f"wrote {path} (open with: rerun {path})")
    return 0


def cmd_campaign(args: argparse.Namespace) -> int:
    """Simulate × calibrate × score many sessions on Dask (gyrosim.campaign)."""
    if args.orientation:
        return cmd_orientation_campaign(args)

    from .campaign import CampaignSpec, load_campaign, run_campaign, summarise

    check_output_paths({"--out": args.out}, [args.campaign], folders=["--out"],
                       folder_files={"--out": ("results.csv", "summary.csv", "provenance.json", "error_vs_severity.png",
                                               "summary.rrd")})
    over = {"hands": _csv_list(args.hand), "seeds": args.seeds, "first_seed": args.first_seed, "sensor": args.sensor,
            "estimators": _csv_list(args.method), "schedule": args.schedule, "rate_hz": args.rate,
            "calibrated_accelerometer": True if args.calibrated_accelerometer else None,
            "severity": args.severity}
    spec = load_campaign(args.campaign, **over) if args.campaign else CampaignSpec(
        **{k: v for k, v in over.items() if v is not None})
    with session_progress("campaign") as progress:
        path = run_campaign(spec, args.out, scheduler=args.scheduler, workers=args.workers,
                            connect_timeout_s=args.timeout, progress=progress)
    summary = summarise(path, args.out)
    print(f"{'hand':<10} {'sev':>4} {'estimator':<18} {'n':>4} {'fail':>4} {'ext acc m/s²':>12} "
          f"{'S err % RMS [95%]':>22} {'G err % RMS [95%]':>22} {'bias °/s RMS':>12}")
    for r in summary:
        if "rms_S_pct" not in r:
            print(
                f"{r['hand']:<10} {r['severity']:4g} {r['estimator']:<18} {r['n']:4d} {r['failed']:4d}  (all crashed)"
            )
            continue
        print(f"{r['hand']:<10} {r['severity']:4g} {r['estimator']:<18} {r['n']:4d} {r['failed']:4d} "
              f"{r['ext_acc_rms_m_s2']:12.4f} {r['rms_S_pct']:8.4f} [{r['rms_S_pct_lo']:.4f}, {r['rms_S_pct_hi']:.4f}] "
              f"{r['rms_G_pct']:8.4f} [{r['rms_G_pct_lo']:.4f}, {r['rms_G_pct_hi']:.4f}] {r['rms_bias_deg_s']:12.4f}")
    print(f"wrote {path}, {Path(args.out) / 'summary.csv'}, {Path(args.out) / 'error_vs_severity.png'} and "
          f"{Path(args.out) / 'summary.rrd'} (open it with:  rerun {Path(args.out) / 'summary.rrd'})")
    return 0


def cmd_campaign_bench(args: argparse.Namespace) -> int:
    """Campaign throughput: sessions per second in-process and on 1 and 2 Dask workers; with
    ``--orientation``, the orientation campaign's CPU seconds per session."""
    if args.orientation:
        from .orientation_campaign import bench_throughput

        r = bench_throughput(args.sessions)
        print(json.dumps(r, indent=2))
        for label in ("raw_and_calibrated", "raw_only"):
            cpu = r[label]["cpu_s_per_session"]
            print(f"{label}: {cpu:.2f} CPU s/session in-process; 1000 sessions on 2 cores ≈ {1000 * cpu / 2 / 60:.1f} "
                  f"min (× 1.3 for Dask workers, README: {1000 * cpu / 2 / 60 * 1.3:.1f} min)")
        return 0
    from .campaign import bench_scaling

    rows = bench_scaling(args.sessions)
    print(f"{args.sessions} sessions (zhou2020, typical, mpu9250, estimator kf), timed in the same run")
    print(f"{'runner':<24} {'workers':>7} {'s':>8} {'sessions/s':>11} {'× 1 worker':>11}")
    for r in rows:
        print(f"{r['runner']:<24} {r['workers']:7d} {r['seconds']:8.2f} {r['sessions_per_s']:11.3f} "
              f"{r['speedup_vs_1_worker']:11.2f}")
    print(f"Dask overhead per task (1 worker − in-process compute): {rows[1]['overhead_per_task_s'] * 1e3:.0f} ms")
    return 0


def _add_sessions(sub) -> None:
    """``simulate`` and the preset listings (``hands``, ``schedules``, ``sensors``)."""
    s = sub.add_parser("simulate", help="simulate a hand-held session and write an HDF5 recording")
    s.add_argument("--schedule", default="zhou2020", help="built-in name or TOML path (default zhou2020)")
    s.add_argument("--hand", default="typical", help="ideal|steady|typical|shaky or a TOML path")
    s.add_argument("--rate", type=number(0, MAX_RATE_HZ, lo_open=True, unit="Hz"), default=100.0,
                   help="output sample rate, Hz, in (0, 1e6] and ≤ --physics-rate (default 100)")
    s.add_argument("--physics-rate", type=number(0, MAX_RATE_HZ, lo_open=True, unit="Hz"), default=1000.0,
                   help="MuJoCo step rate, Hz, in (0, 1e6] (default 1000)")
    s.add_argument("--sensor", default=None, help="sensor preset or TOML path (default: none, /gyro = truth)")
    s.add_argument("--seed", type=seed, default=0, help="seed of the random generator, 0 … 2³²−1 (default 0)")
    s.add_argument("--out", required=True, help="output .h5 path (written atomically; never one of the input TOML "
                                                "files)")
    s.add_argument("--mag-field", help="Earth field E,N,U in µT (default 1.5,20,-44: 48° N)")
    s.add_argument("--location", help="Earth field from the World Magnetic Model: LAT,LON[,HEIGHT_M[,YYYY-MM-DD]]")
    s.add_argument(
        "--anomaly",
        action="append",
        help="ferrous sphere X,Y,Z,RADIUS_M in the room (m, ENU; the hand starts at 0.18,0.30,1.15); repeatable",
    )
    s.add_argument("--quiet", action="store_true", help="no progress bar and no summary line")
    s.set_defaults(func=cmd_simulate)

    h = sub.add_parser("hands", help="list hand presets with the disturbances they produce")
    h.add_argument(
        "--schedule",
        default="zhou2020",
        help="schedule the expected disturbances are computed over: built-in name or TOML path (default zhou2020)",
    )
    h.set_defaults(func=cmd_hands)

    sc = sub.add_parser("schedules", help="list built-in schedules")
    sc.add_argument("--show", help="print one schedule as JSON")
    sc.set_defaults(func=cmd_schedules)

    se = sub.add_parser("sensors", help="list sensor presets and their effects")
    se.add_argument("--show", help="print one preset (SI values) as JSON")
    se.set_defaults(func=cmd_sensors)


def _add_rigs(sub) -> None:
    """The test rigs: ``chamber``, ``ratetable``, ``northfind``, ``tilttable`` (each writes a recording a calib
    command analyses)."""
    ch = sub.add_parser("chamber", help="a static board through a thermal-chamber profile (HDF5 with /temp)")
    ch.add_argument("--profile", default="tde_cycles_003", help="built-in chamber profile or TOML path")
    ch.add_argument("--sensor", default="consumer_thermal", help="sensor preset or TOML path")
    ch.add_argument("--rate", type=number(0, 1e4, lo_open=True, unit="Hz"), default=1.0,
                    help="output rate, Hz, in (0, 1e4] (default 1: 10 s blocks are analysed)")
    ch.add_argument("--up", default="z", choices=("x", "y", "z"), help="board axis pointing up")
    ch.add_argument("--seed", type=seed, default=0, help="seed of the random generator, 0 … 2³²−1 (default 0)")
    ch.add_argument("--out", required=True, help="output .h5 path (written atomically; never an input TOML)")
    ch.set_defaults(func=cmd_chamber)

    rt = sub.add_parser("ratetable", help="simulate a rate-table record: ±rate / one-position on six faces at each "
                        "chamber hold (calib ratetable analyses it)")
    rt.add_argument("--profile", default="points_001", help="chamber profile whose holds are the calibration points")
    rt.add_argument(
        "--sensor", default="consumer_thermal", help="sensor preset or TOML path (default consumer_thermal)"
    )
    rt.add_argument("--rate", type=number(0, 1e4, lo_open=True, unit="Hz"), default=100.0,
                    help="output rate, Hz, in (0, 1e4] (default 100)")
    rt.add_argument("--table-rate", type=number(0, 2000, lo_open=True, unit="°/s"), default=30.0,
                    help="table rate Ω, °/s, in (0, 2000] (default 30)")
    rt.add_argument("--turns", type=number(0, 1000, lo_open=True), default=2.0,
                    help="full turns per direction, in (0, 1000] (default 2)")
    rt.add_argument("--settle", type=number(0, 1e6, unit="s"), default=3600.0,
                    help="soak before the sequence, s, in [0, 1e6] (default 3600)")
    rt.add_argument("--seed", type=seed, default=0, help="seed of the random generator, 0 … 2³²−1 (default 0)")
    rt.add_argument("--out", required=True, help="output .h5 path (written atomically; never an input TOML)")
    rt.set_defaults(func=cmd_ratetable)

    nf = sub.add_parser(
        "northfind", help="simulate a north-finding record: a board held still in 2/4 positions on the indexing "
        "table at a latitude (calib northfind analyses it)"
    )
    nf.add_argument("--sensor", default="fog_tactical", help="sensor preset or TOML path (its Earth rate is set to "
                                                             "--latitude)")
    nf.add_argument("--latitude", type=number(-90, 90, unit="°"), default=48.0, help="site latitude, °, in [-90, 90] "
                                                                                     "(default 48)")
    nf.add_argument("--heading", type=number(-360, 360, unit="°"), default=30.0,
                    help="true heading of the forward axis in position 1, ° from North, in [-360, 360]")
    nf.add_argument("--positions", type=integer(2, 360), default=4,
                    help="equally spaced positions, 2 … 360 (2: 0/180°, 4: 0/90/180/270°)")
    nf.add_argument(
        "--hold",
        type=number(0, 1e7, lo_open=True, unit="s"),
        default=300.0,
        help="rest per position, s, > 0 (default 300)",
    )
    nf.add_argument("--index-rate", type=number(0, 2000, lo_open=True, unit="°/s"), default=20.0,
                    help="table rate during the index moves, °/s, in (0, 2000]")
    nf.add_argument("--rate", type=number(0, 500, lo_open=True, unit="Hz"), default=100.0,
                    help="output rate, Hz (a divisor of 500; default 100)")
    nf.add_argument("--tilt", type=number(-90, 90, unit="°"), default=0.0,
                    help="tilt of the table axis from the vertical, °, in [-90, 90] (tripod not level)")
    nf.add_argument("--tilt-azimuth", type=number(-360, 360, unit="°"), default=0.0, help="azimuth the axis leans "
                                                                                          "towards, °")
    nf.add_argument("--knock", action="append", metavar="HOLD[:DEG[:AXIS]]", help="knock the board during a hold "
                                                                                  "(repeatable)")
    nf.add_argument(
        "--shield",
        type=number(0, None, lo_open=True),
        default=1.0,
        help="divide the gyro's magnetic sensitivity by this (1e3: a shielded FOG; default 1: as the preset)",
    )
    nf.add_argument("--seed", type=seed, default=0, help="seed of the random generator, 0 … 2³²−1 (default 0)")
    nf.add_argument("--out", required=True, help="output .h5 path (written atomically; never an input TOML)")
    nf.set_defaults(func=cmd_northfind)

    tt = sub.add_parser(
        "tilttable", help="simulate a tilt-sensor static test: tilt steps about each axis on a dividing head, held "
        "still (calib tilt analyses it)"
    )
    tt.add_argument("--sensor", default="tilt_001", help="sensor preset or TOML path (default tilt_001, the chip of "
                                                         "'Static Capacitance Test of MEMS Tilt Sensor')")
    tt.add_argument("--angles", default=None, help="FROM:TO:STEP in ° (default -15:15:2.5, the test's ±15° range)")
    tt.add_argument("--hold", type=number(0, 1e7, lo_open=True, unit="s"), default=30.0, help="hold per step, s, > 0")
    tt.add_argument("--zero-hold", type=number(0, 1e7, unit="s"), default=3600.0,
                    help="final level hold for the zero stability, s, ≥ 0 (seed: 1 h)")
    tt.add_argument("--no-flip", action="store_true", help="leave out the 180° positions (0°/180° two-point method)")
    tt.add_argument("--rate", type=number(0, 1e4, lo_open=True, unit="Hz"), default=10.0,
                    help="output rate, Hz, in (0, 1e4] (default 10, the chip's)")
    tt.add_argument("--knock", action="append", metavar="HOLD[:DEG[:AXIS]]", help="knock the board during a hold "
                                                                                  "(repeatable)")
    tt.add_argument("--seed", type=seed, default=0, help="seed of the random generator, 0 … 2³²−1 (default 0)")
    tt.add_argument("--out", required=True, help="output .h5 path (written atomically; never an input TOML)")
    tt.set_defaults(func=cmd_tilttable)


def _add_campaigns(sub) -> None:
    """Campaigns, orientation scoring and the speed tables."""
    cp = sub.add_parser("campaign", help="robustness campaign: sessions × estimators scored against the truth, on Dask")
    cp.add_argument("campaign", nargs="?", help="campaign TOML (flags override its keys)")
    cp.add_argument("--hand", help="comma-separated hand presets (default ideal,steady,typical,shaky)")
    cp.add_argument("--seeds", type=integer(1, 1_000_000), help="sessions per hand and severity, 1 … 1e6 (default 10)")
    cp.add_argument("--first-seed", type=seed, help="seed of the first session, 0 … 2³²−1")
    cp.add_argument("--sensor", help="sensor preset (default mpu9250)")
    cp.add_argument("--method", help="comma-separated estimators: names registered in the gyrosim.estimators entry "
                                     "points (calib's kf, "
                         "iterated, kf_hand, kf_adaptive, ...) or import paths package.module:attribute")
    cp.add_argument("--schedule", help="schedule of every session: built-in name or TOML path (default zhou2020)")
    cp.add_argument("--rate", type=number(0, MAX_RATE_HZ, lo_open=True, unit="Hz"), help="sample rate, Hz, in (0, 1e6]")
    cp.add_argument("--severity", type=positive_list(),
                    help="comma-separated factors > 0 on every hand imperfection (default 1)")
    cp.add_argument("--calibrated-accelerometer", action="store_true",
                    help="keep only the accelerometer's white noise (Zhou §3.3.2)")
    cp.add_argument("--scheduler", default="local", help="local (LocalCluster on 127.0.0.1), none (in-process) or "
                                                         "tcp://HOST:PORT")
    cp.add_argument("--workers", type=integer(1, 1024), help="LocalCluster workers, 1 … 1024 (default: cores)")
    cp.add_argument("--timeout", type=number(0, 3600, lo_open=True, unit="s"), default=10.0,
                    help="seconds to wait for a remote scheduler, in (0, 3600] (default 10)")
    cp.add_argument("--orientation", help="comma-separated orientation estimators (vqf, madgwick, mahony, fusion, "
                    "*_9d, or package.module:attribute): score attitude instead of calibration")
    cp.add_argument("--variants", help="with --orientation: raw,calibrated (default both)")
    cp.add_argument("--calibration", help="with --orientation: the calib estimator of the calibrated variant "
                    "(default kf_joint, calib run's)")
    cp.add_argument("--out", required=True, help="results folder (results.csv, summary.csv, plots, provenance.json)")
    cp.set_defaults(func=cmd_campaign)

    ob = sub.add_parser("orientation-broad", help="orientation estimators on the BROAD trials, BROAD's error "
                        "definitions, beside the published numbers")
    ob.add_argument("--estimators", help="comma-separated (default vqf_9d,vqf,madgwick_9d,mahony_9d,fusion_9d)")
    ob.add_argument("--json", help="write the table as JSON (atomically)")
    ob.set_defaults(func=cmd_orientation_broad)

    ov = sub.add_parser("orientation-view", help="rerun view of one session: truth vs each estimator's attitude")
    ov.add_argument("--hand", default="typical", help="hand preset or TOML path (default typical)")
    ov.add_argument("--sensor", default="mpu9250", help="sensor preset or TOML path (default mpu9250)")
    ov.add_argument("--schedule", default="zhou2020", help="built-in schedule or TOML path (default zhou2020)")
    ov.add_argument("--seed", type=seed, default=0, help="seed of the random generator, 0 … 2³²−1 (default 0)")
    ov.add_argument("--estimators", help="comma-separated (default vqf,madgwick,mahony,fusion)")
    ov.add_argument("--variant", choices=("raw", "calibrated"), default="raw",
                    help="raw: the recording as the sensor delivers it; calibrated: compensated by calib first")
    ov.add_argument("--rrd", required=True, help="output .rrd file")
    ov.set_defaults(func=cmd_orientation_view)

    cb = sub.add_parser("campaign-bench", help="campaign scaling: sessions/s in-process, on 1 and 2 Dask workers")
    cb.add_argument("--sessions", type=integer(1, 100_000), default=12, help="sessions to time, 1 … 1e5 (default 12)")
    cb.add_argument(
        "--orientation",
        action="store_true",
        help="time the orientation campaign's session (simulation, calibration, vqf/madgwick/mahony/fusion)",
    )
    cb.set_defaults(func=cmd_campaign_bench)

    b = sub.add_parser("bench", help="simulation speed: our simulation vs bare mujoco.rollout (calibration speed: "
                       "calib lab bench)")
    b.add_argument("what", nargs="?", choices=("all", "scene", "sensor"), default="all",
                   help="scene: simulation vs bare mujoco.rollout; sensor: error model vs bare numpy")
    b.add_argument("--repeats", type=integer(1, 1000), default=5, help="timing repeats, 1 … 1000 (default 5)")
    b.add_argument("--sensor", default="mpu9250", help="sensor preset or TOML path timed in the sensor row (default "
                                                       "mpu9250)")
    b.add_argument("--schedule", default="zhou2020", help="schedule simulated: built-in name or TOML path (default "
                                                          "zhou2020)")
    b.add_argument("--hand", default="typical", help="hand preset or TOML path (default typical)")
    b.add_argument("--rate", type=number(0, MAX_RATE_HZ, lo_open=True, unit="Hz"), default=100.0,
                   help="sample rate, Hz, in (0, 1e6] (default 100)")
    b.set_defaults(func=cmd_bench)


def build_parser() -> argparse.ArgumentParser:
    """The ``gyrosim`` command line's parser: one subcommand per job (``simulate``, ``campaign``, ``chamber``,
    …), each bound to the ``cmd_*`` function that runs it."""
    p = argparse.ArgumentParser(prog="gyrosim", description="Virtual hand-held IMU in MuJoCo: gyrosim simulates "
                                "recordings, calib analyses them\n(gyrosim northfind, ratetable and tilttable write "
                                "what calib northfind, ratetable\nand tilt read).", epilog=EXIT_CODES_HELP,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--version", action="version", version=f"gyrosim {__version__}")
    sub = p.add_subparsers(dest="command", required=True)
    _add_sessions(sub)
    _add_rigs(sub)
    _add_campaigns(sub)
    return p


# The exit codes of every command of both command lines (gyrosim and calib), in one place.
EXIT_OK, EXIT_NOT_OK, EXIT_BAD_INPUT, EXIT_INTERNAL = 0, 1, 2, 3
EXIT_CODES = {EXIT_OK: "done and ok", EXIT_NOT_OK: "done, not ok (said on stderr)",
              EXIT_BAD_INPUT: "bad input (what is wrong, what to do)",
              EXIT_INTERNAL: "internal error (a bug)"}
# the table as the two lines each command line's --help ends with
EXIT_CODES_HELP = ("exit codes: " + " · ".join(f"{c} {EXIT_CODES[c]}" for c in (EXIT_OK, EXIT_NOT_OK)) + "\n"
                   + " " * 12 + " · ".join(f"{c} {EXIT_CODES[c]}" for c in (EXIT_BAD_INPUT, EXIT_INTERNAL)))


def status_exit(ok: bool, message: str) -> int:
    """The exit code of a command that finished: 0 when its result is ok, else 1 with ``message`` (one line
    saying what was found and where to look) on stderr.  Bad input (2) and internal errors (3) are
    :func:`run_cli`'s."""
    if ok:
        return EXIT_OK
    print(message, file=sys.stderr)
    return EXIT_NOT_OK


def run_cli(parser: argparse.ArgumentParser, argv: list[str] | None) -> int:
    """Parse, run the chosen command and return its exit code (the same in-process and as a script).

    0: done; 1: done, but the result is not "ok" (e.g. a diverged filter, said on stderr);
    2: bad input or bad arguments (one line on stderr saying what is wrong and what to do);
    3: an internal error (a bug: one line; ``GYROSIM_TRACEBACK=1`` shows the traceback)."""
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # argparse: --help/--version (0) or a usage error (2, message printed)
        return exc.code if isinstance(exc.code, int) else EXIT_BAD_INPUT
    try:
        return int(args.func(args))
    except GyrosimError as exc:
        print(f"{parser.prog}: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except OSError as exc:  # the file system refused (disk full, permissions changed meanwhile, ...)
        print(f"{parser.prog}: error: {exc.strerror or exc}{f': {exc.filename}' if exc.filename else ''}",
              file=sys.stderr)
        return EXIT_BAD_INPUT
    except Exception as exc:  # noqa: BLE001 - the last line of defence: one line, not a traceback
        if os.environ.get("GYROSIM_TRACEBACK"):
            raise
        print(f"{parser.prog}: internal error (a bug, please report it with the command line): "
              f"{type(exc).__name__}: {exc}; set GYROSIM_TRACEBACK=1 to see the traceback", file=sys.stderr)
        return EXIT_INTERNAL


def main(argv: list[str] | None = None) -> int:
    """Run the ``gyrosim`` command line on ``argv`` (default ``sys.argv[1:]``) and return its exit code
    (:func:`run_cli`)."""
    return run_cli(build_parser(), argv)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
