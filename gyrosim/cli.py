"""``gyrosim`` command line: thin wrappers over library calls (each is a function a user can call)."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

from . import __version__
from .errors import GyrosimError
from .hand import hand_preset_names, load_hand
from .recording import save_hdf5
from .schedule import builtin_schedule_names, load_schedule


def _check_writable(path: Path) -> None:
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise GyrosimError(f"cannot write {path}: folder {folder} does not exist; create it first")
    probe = folder / f".{path.name}.probe"
    try:
        probe.touch()
        probe.unlink()
    except OSError as exc:
        raise GyrosimError(f"cannot write {path}: {exc.strerror}; choose a writable folder") from exc


def cmd_simulate(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from .sensor_model import load_sensor
    from .simulate import simulate, simulation_grid

    out = Path(args.out)
    _check_writable(out)  # fail before minutes of simulation, not after
    schedule = load_schedule(args.schedule)
    hand = load_hand(args.hand)
    sensor = load_sensor(args.sensor) if args.sensor else None
    grid = simulation_grid(schedule.duration_s, args.rate, args.physics_rate)
    with tqdm(total=grid.t_physics_s.size + 1, unit="step", desc="simulating", disable=args.quiet, leave=False) as bar:
        rec = simulate(
            schedule, hand, sensor, args.rate, seed=args.seed, physics_rate_hz=args.physics_rate, progress=bar.update
        )
    save_hdf5(rec, out)
    if not args.quiet:
        ext = rec.truth.extra["external_acc"]
        dw = rec.truth.omega_body_rad_s - rec.truth.extra["omega_schedule"]
        print(
            f"wrote {out}: {rec.n} samples at {rec.rate_hz:g} Hz ({rec.duration_s:.1f} s), "
            f"schedule {schedule.name}, hand {hand.name}, sensor {sensor.name if sensor else 'none (truth)'}, "
            f"seed {args.seed}; "
            f"external acc RMS {math.sqrt(np.mean(np.sum(ext**2, 1))):.4f} m/s², "
            f"rate disturbance RMS {math.degrees(math.sqrt(np.mean(np.sum(dw**2, 1)))):.3f} °/s"
        )
    return 0


def cmd_hands(args: argparse.Namespace) -> int:
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
    for name in builtin_schedule_names():
        s = load_schedule(name)
        print(f"{name:<14} {s.duration_s:7.1f} s  {len(s.segments):3d} segments  {s.description}")
    if args.show:
        s = load_schedule(args.show)
        print(json.dumps(s.to_dict(), indent=2))
    return 0


def cmd_sensors(args: argparse.Namespace) -> int:
    from .sensor_model import load_sensor, sensor_preset_names

    for name in sensor_preset_names():
        m = load_sensor(name)
        print(f"{name:<22} gyro: {', '.join(e.kind for e in m.gyro)}")
        print(f"{'':<22} accelerometer: {', '.join(e.kind for e in m.accelerometer)}")
        print(f"{'':<22} {m.description}")
    if args.show:
        print(json.dumps(load_sensor(args.show).to_dict(), indent=2))
    return 0


def cmd_bench(args: argparse.Namespace) -> int:
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
    _check_writable(out)
    profile = load_chamber(args.profile)
    rec = simulate_chamber(profile, args.sensor, args.rate, seed=args.seed, up_axis=args.up)
    save_hdf5(rec, out)
    print(f"wrote {out}: {rec.n} samples at {args.rate:g} Hz over {profile.duration_s / 3600:.1f} h "
          f"({len(profile.cycle_starts_s)} cycle(s) of {profile.name}); sensor temperature "
          f"{rec.temp_c.min():.1f}…{rec.temp_c.max():.1f} °C")
    return 0


def cmd_ratetable(args: argparse.Namespace) -> int:
    """Seed 001's ±rate / one-position scheme on the virtual rate table inside a chamber profile."""
    from .chamber import load_chamber
    from .ratetable import RateTableSequence, simulate_rate_table

    out = Path(args.out)
    _check_writable(out)
    seq = RateTableSequence(rate_deg_s=args.table_rate, turns=args.turns, settle_s=args.settle)
    rec = simulate_rate_table(load_chamber(args.profile), args.sensor, args.rate, seq=seq, seed=args.seed)
    save_hdf5(rec, out)
    holds = sorted({s["ambient_c"] for s in rec.meta["segments"]})
    print(f"wrote {out}: {rec.n} samples at {args.rate:g} Hz; calibration temperatures {holds} °C, six faces each, "
          f"±{args.table_rate:g} °/s")
    return 0


def _csv_list(v: str | None) -> tuple[str, ...] | None:
    return tuple(x.strip() for x in v.split(",") if x.strip()) if v else None


def cmd_campaign(args: argparse.Namespace) -> int:
    """Simulate × calibrate × score many sessions on Dask (gyrosim.campaign)."""
    from tqdm import tqdm

    from .campaign import CampaignSpec, load_campaign, run_campaign, summarise

    over = {"hands": _csv_list(args.hand), "seeds": args.seeds, "first_seed": args.first_seed, "sensor": args.sensor,
            "estimators": _csv_list(args.method), "schedule": args.schedule, "rate_hz": args.rate,
            "calibrated_accelerometer": True if args.calibrated_accelerometer else None,
            "severity": tuple(float(x) for x in _csv_list(args.severity)) if args.severity else None}
    spec = load_campaign(args.campaign, **over) if args.campaign else CampaignSpec(
        **{k: v for k, v in over.items() if v is not None})
    with tqdm(total=1, unit="session", desc="campaign") as bar:
        def progress(done: int, total: int) -> None:
            bar.total = total
            bar.n = done
            bar.refresh()

        path = run_campaign(spec, args.out, scheduler=args.scheduler, workers=args.workers,
                            connect_timeout_s=args.timeout, progress=progress)
    summary = summarise(path, args.out)
    print(f"{'hand':<10} {'sev':>4} {'estimator':<18} {'n':>4} {'fail':>4} {'ext acc m/s²':>12} "
          f"{'S err % RMS [95%]':>22} {'G err % RMS [95%]':>22} {'bias °/s RMS':>12}")
    for r in summary:
        if "rms_S_pct" not in r:
            print(f"{r['hand']:<10} {r['severity']:4g} {r['estimator']:<18} {r['n']:4d} {r['failed']:4d}  (all crashed)")
            continue
        print(f"{r['hand']:<10} {r['severity']:4g} {r['estimator']:<18} {r['n']:4d} {r['failed']:4d} "
              f"{r['ext_acc_rms_m_s2']:12.4f} {r['rms_S_pct']:8.4f} [{r['rms_S_pct_lo']:.4f}, {r['rms_S_pct_hi']:.4f}] "
              f"{r['rms_G_pct']:8.4f} [{r['rms_G_pct_lo']:.4f}, {r['rms_G_pct_hi']:.4f}] {r['rms_bias_deg_s']:12.4f}")
    print(f"wrote {path}, {Path(args.out) / 'summary.csv'}, {Path(args.out) / 'error_vs_severity.png'}")
    return 0


def cmd_campaign_bench(args: argparse.Namespace) -> int:
    from .campaign import bench_scaling

    rows = bench_scaling(args.sessions)
    print(f"{args.sessions} sessions (zhou2020, typical, mpu9250, estimator kf), timed in the same run")
    print(f"{'runner':<24} {'workers':>7} {'s':>8} {'sessions/s':>11} {'× 1 worker':>11}")
    for r in rows:
        print(f"{r['runner']:<24} {r['workers']:7d} {r['seconds']:8.2f} {r['sessions_per_s']:11.3f} {r['speedup_vs_1_worker']:11.2f}")
    print(f"Dask overhead per task (1 worker − in-process compute): {rows[1]['overhead_per_task_s'] * 1e3:.0f} ms")
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="gyrosim", description="Virtual hand-held IMU in MuJoCo.")
    p.add_argument("--version", action="version", version=f"gyrosim {__version__}")
    sub = p.add_subparsers(dest="command", required=True)

    s = sub.add_parser("simulate", help="simulate a hand-held session and write an HDF5 recording")
    s.add_argument("--schedule", default="zhou2020", help="built-in name or TOML path (default zhou2020)")
    s.add_argument("--hand", default="typical", help="ideal|steady|typical|shaky or a TOML path")
    s.add_argument("--rate", type=float, default=100.0, help="output sample rate, Hz (default 100)")
    s.add_argument("--physics-rate", type=float, default=1000.0, help="MuJoCo step rate, Hz (default 1000)")
    s.add_argument("--sensor", default=None, help="sensor preset or TOML path (default: none, /gyro = truth)")
    s.add_argument("--seed", type=int, default=0, help="seed of the random generator (default 0)")
    s.add_argument("--out", required=True, help="output .h5 path")
    s.add_argument("--quiet", action="store_true")
    s.set_defaults(func=cmd_simulate)

    h = sub.add_parser("hands", help="list hand presets with the disturbances they produce")
    h.add_argument("--schedule", default="zhou2020")
    h.set_defaults(func=cmd_hands)

    sc = sub.add_parser("schedules", help="list built-in schedules")
    sc.add_argument("--show", help="print one schedule as JSON")
    sc.set_defaults(func=cmd_schedules)

    se = sub.add_parser("sensors", help="list sensor presets and their effects")
    se.add_argument("--show", help="print one preset (SI values) as JSON")
    se.set_defaults(func=cmd_sensors)

    ch = sub.add_parser("chamber", help="a static board through a thermal-chamber profile (HDF5 with /temp)")
    ch.add_argument("--profile", default="tde_cycles_003", help="built-in chamber profile or TOML path")
    ch.add_argument("--sensor", default="consumer_thermal", help="sensor preset or TOML path")
    ch.add_argument("--rate", type=float, default=1.0, help="output rate, Hz (default 1: 10 s blocks are analysed)")
    ch.add_argument("--up", default="z", choices=("x", "y", "z"), help="board axis pointing up")
    ch.add_argument("--seed", type=int, default=0)
    ch.add_argument("--out", required=True)
    ch.set_defaults(func=cmd_chamber)

    rt = sub.add_parser("ratetable", help="virtual rate table: ±rate / one-position on six faces at each chamber hold")
    rt.add_argument("--profile", default="points_001", help="chamber profile whose holds are the calibration points")
    rt.add_argument("--sensor", default="consumer_thermal")
    rt.add_argument("--rate", type=float, default=100.0, help="output rate, Hz")
    rt.add_argument("--table-rate", type=float, default=30.0, help="table rate Ω, °/s")
    rt.add_argument("--turns", type=float, default=2.0, help="full turns per direction")
    rt.add_argument("--settle", type=float, default=3600.0, help="soak before the sequence, s")
    rt.add_argument("--seed", type=int, default=0)
    rt.add_argument("--out", required=True)
    rt.set_defaults(func=cmd_ratetable)

    cp = sub.add_parser("campaign", help="robustness campaign: sessions × estimators scored against the truth, on Dask")
    cp.add_argument("campaign", nargs="?", help="campaign TOML (flags override its keys)")
    cp.add_argument("--hand", help="comma-separated hand presets (default ideal,steady,typical,shaky)")
    cp.add_argument("--seeds", type=int, help="sessions per hand and severity (default 10)")
    cp.add_argument("--first-seed", type=int)
    cp.add_argument("--sensor", help="sensor preset (default mpu9250)")
    cp.add_argument("--method", help="comma-separated estimators: built-ins or package.module:attribute")
    cp.add_argument("--schedule")
    cp.add_argument("--rate", type=float)
    cp.add_argument("--severity", help="comma-separated factors on every hand imperfection (default 1)")
    cp.add_argument("--calibrated-accelerometer", action="store_true",
                    help="keep only the accelerometer's white noise (Zhou §3.3.2)")
    cp.add_argument("--scheduler", default="local", help="local (LocalCluster on 127.0.0.1), none (in-process) or tcp://HOST:PORT")
    cp.add_argument("--workers", type=int, help="LocalCluster workers (default: cores)")
    cp.add_argument("--timeout", type=float, default=10.0, help="seconds to wait for a remote scheduler")
    cp.add_argument("--out", required=True, help="results folder (results.csv, summary.csv, plots, provenance.json)")
    cp.set_defaults(func=cmd_campaign)

    cb = sub.add_parser("campaign-bench", help="campaign scaling: sessions/s in-process, on 1 and 2 Dask workers")
    cb.add_argument("--sessions", type=int, default=12)
    cb.set_defaults(func=cmd_campaign_bench)

    b = sub.add_parser("bench", help="speed table: our simulation vs bare mujoco.rollout")
    b.add_argument("what", nargs="?", choices=("all", "scene", "sensor"), default="all",
                   help="scene: simulation vs bare mujoco.rollout; sensor: error model vs bare numpy")
    b.add_argument("--repeats", type=int, default=5)
    b.add_argument("--sensor", default="mpu9250")
    b.add_argument("--schedule", default="zhou2020")
    b.add_argument("--hand", default="typical")
    b.add_argument("--rate", type=float, default=100.0)
    b.set_defaults(func=cmd_bench)
    return p


def run_cli(parser: argparse.ArgumentParser, argv: list[str] | None) -> int:
    """Parse, run the chosen command; a bad-input error prints one line and exits 2."""
    args = parser.parse_args(argv)
    try:
        return int(args.func(args))
    except GyrosimError as exc:
        print(f"{parser.prog}: error: {exc}", file=sys.stderr)
        return 2


def main(argv: list[str] | None = None) -> int:
    return run_cli(build_parser(), argv)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
