"""The hand-held calibration session: ``calib run`` (:func:`calib.session.run.run_session`), ``apply``,
``export``, ``inspect`` and ``demo`` (:func:`calib.app.demo.run_demo`)."""

from __future__ import annotations

import argparse
import math
import re
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

from gyrosim.cliargs import integer, number
from gyrosim.errors import GyrosimError

from calib.app.commands.common import (
    RECORDING_HELP,
    input_files,
    input_options,
    open_input,
    print_input_warnings,
    status_exit,
)
from calib.app.outputs import atomic_path, check_output_paths, write_text_atomic

__all__ = ["add_parsers", "cmd_run", "cmd_apply", "cmd_export", "cmd_inspect", "cmd_demo"]


def cmd_demo(args: argparse.Namespace) -> int:
    """The main job: simulate the hand-held session, calibrate it, write recording, report and .rrd
    (:func:`calib.app.demo.run_demo`)."""
    from tqdm import tqdm

    from gyrosim.schedule import load_schedule
    from gyrosim.simulate import simulation_grid

    from calib.app.demo import DEMO_FILES, run_demo
    from calib.session.run import RunOptions, resolve_run_method

    check_output_paths({"--out": args.out}, [args.schedule, args.hand, args.sensor], folders=["--out"],
                       folder_files={"--out": DEMO_FILES})
    # the method as calib run takes it (one default: calib.session.defaults), resolved before the simulation
    name, mode, note = resolve_run_method(RunOptions(method=args.method, accelerometer=args.accelerometer),
                                          flag="--method")
    if note:
        print(f"warning: {note}", file=sys.stderr)
    grid = simulation_grid(load_schedule(args.schedule).duration_s, args.rate)
    with tqdm(total=grid.t_physics_s.size + 1, unit="step", desc="simulating session", leave=False) as bar:
        def log(msg: str) -> None:
            bar.close()   # the simulation is over once the stages start
            print(msg, flush=True)

        res = run_demo(args.out, schedule=args.schedule, hand=args.hand, sensor=args.sensor, rate_hz=args.rate,
                       seed=args.seed, accelerometer=mode, method=name, progress=bar.update, log=log)
    print(f"wrote {res.recording}, {res.report}, {res.report_json} and {res.rrd}")
    print(f"open the recording with:  rerun {res.rrd}")
    return 0


def _print_calibration(cal, where_s_holds: bool = True) -> None:
    """The estimate with its 1σ, where the scale factor holds (unless ``where_s_holds`` is False: S is not
    applied), and the error against a simulated file's truth."""
    blocks = [("gyro", "bias", "bias", 180 / math.pi, "°/s"), ("gyro", "scale_factor", "scale factor", 1, ""),
              ("gyro", "nonorthogonality", "non-orthogonality", 1, "")]
    if cal.has("accelerometer", "bias"):
        blocks += [("accelerometer", "bias", "acc bias", 1000 / 9.80665, "mg"),
                   ("accelerometer", "scale_factor", "acc scale factor", 1, ""),
                   ("accelerometer", "nonorthogonality", "acc non-orth.", 1, "")]
    for triad, kind, name, scale, unit in blocks:
        v = cal.value(triad, kind) * scale
        sd = cal.std(triad, kind) * scale
        print(f"  {name:<18} " + "  ".join(f"{a:+.5f}±{b:.5f}" for a, b in zip(v, sd)) + f" {unit}")
    ref = (cal.diagnostics or {}).get("scale_reference_rate")
    if ref and where_s_holds:   # where S holds (calib.session.hand.filter.scale_reference_rate)
        m = np.degrees(ref["rate_rad_s"])
        top = np.degrees(ref["max_abs_rate_rad_s"])
        print(
            f"  scale factor holds at ±{', '.join(f'{v:.0f}' for v in m)} °/s (x, y, z: the chord over the rates this "
            f"session turned at, up to {', '.join(f'{v:.0f}' for v in top)} °/s); at other rates a gyro's scale "
            "nonlinearity adds to it — calibrate at the rates you will use"
        )
    truth = cal.report.get("truth")
    if truth is not None:
        err_s = cal.scale_factor - np.asarray(truth["scale_factor"])
        err_g = cal.nonorthogonality - np.asarray(truth["nonorthogonality"])
        print(f"  error vs truth: S {np.round(err_s, 5).tolist()}, G {np.round(err_g, 5).tolist()}")
        if cal.has("accelerometer", "bias"):
            acc = truth["accelerometer"]
            print(
                "  accelerometer error vs truth: b "
                f"{np.round(cal.value('accelerometer', 'bias') - np.asarray(acc['bias_m_s2']), 4).tolist()} "
                "m/s², "
                f"""S {np.round(
                    cal.value('accelerometer', 'scale_factor') - np.asarray(acc['scale_factor']), 5
                ).tolist()}"""
            )


# warnings that describe the fit rather than call for something to do: shown under --verbose (and in the JSON)
_DETAIL_HEADS = ("hand:", "timing:", "σ of S, G follows", "temperature:", "cautious:")
# warnings about S, G's own σ: moot when S, G are not applied (the decision's lines say why)
_SG_HEADS = ("unobservable", "weakly observable", "gyro bias drift and no temperature")
# a parenthesis that names internals (a module path, a variable or key name): dropped on the terminal
_IDENTIFIER = re.compile(r"\s*\([^()]*(?:\b[a-z]+_[a-z_]+\b|\b[a-z]+\.[a-z_]+\.[a-z_.]+)[^()]*\)")
_WIDTH = 210   # with "  warning: ", about two lines of a terminal


def _terminal_warning(w: str) -> str:
    """A warning for the terminal (the JSON and --verbose keep it whole): parentheses that name internals
    dropped, and at most ~two lines — its last clause (what to do) whole and as much of its first (what was
    found) as fits."""
    w = _IDENTIFIER.sub("", w)
    if len(w) <= _WIDTH:
        return w
    clauses = re.split(r"(?<=[;.]) ", w)
    first, last = clauses[0].rstrip(";."), clauses[-1]
    room = _WIDTH - len(last) - 3   # what to do comes last: keep it whole, cut what was found to fit
    if len(clauses) > 1 and room >= 60:
        return (first if len(first) <= room else first[:room].rsplit(" ", 1)[0]) + f" … {last}"
    return w[:_WIDTH].rsplit(" ", 1)[0] + " …"


def _decision_warning(w: str) -> bool:
    """One of the warnings the decision layer adds (its lines and the status line say it)."""
    from calib.session.decision.decide import CHECK_WARNING, MOTION_WARNING

    return w.startswith((MOTION_WARNING, CHECK_WARNING))


def _shown_warnings(cal, verbose: bool) -> tuple[list[str], int]:
    """The method's warnings as ``calib run`` prints them, and how many it left to --verbose."""
    from calib.session.run import method_warnings

    warnings = list(method_warnings(cal))
    if verbose:
        return warnings, 0
    sg_applied = cal.applied is None or bool(cal.applied.from_session[3:9].any())
    shown = [_terminal_warning(w) for w in warnings
             if not w.startswith(_DETAIL_HEADS) and (sg_applied or not w.startswith(_SG_HEADS))
             and not _decision_warning(w)]
    return shown, len(warnings) - len(shown) - sum(_decision_warning(w) for w in warnings)


def _print_run(recording: str, cal, verbose: bool = False) -> None:
    """What ``calib run`` prints of a :func:`~calib.session.run.run_session` result: the estimate, the input's
    lines, the coaching (when S, G are applied), the warnings (each in one or two lines; the descriptive ones
    and the whole text under ``verbose``), what is applied and why (the motion, the held-out check), and the
    status."""
    from calib.session.coach import Coaching
    from calib.session.known_turns import known_turns_lines
    from calib.session.run import SESSION_METHODS, method_warnings

    rest = cal.to_dict()["rest_segments"]
    mode = SESSION_METHODS.get(cal.method, (None, "estimate"))[1]
    print(f"{recording}: method {cal.method}, accelerometer {mode}, rest "
          + ", ".join(f"{a:.0f}–{b:.0f} s" for a, b in rest[:3]) + (" …" if len(rest) > 3 else ""))
    sg_applied = cal.applied is None or bool(cal.applied.from_session[3:9].any())
    _print_calibration(cal, verbose or sg_applied)
    print_input_warnings(cal.report["input"]["warnings"])
    for line in known_turns_lines(cal.diagnostics.get("known_turns") or {}):
        print(f"  {line}")
    if verbose or sg_applied:
        for line in Coaching.from_dict(cal.report["coaching"]).lines():
            print(f"  {line}")
    warnings, hidden = _shown_warnings(cal, verbose)
    for w in warnings:
        print(f"  warning: {w}")
    for line in (cal.applied.notes if cal.applied is not None else ()):
        print(f"  {line}")
    if hidden:
        print(f"  ({hidden} more findings: calib run --verbose, or the JSON's warnings)")
    why = next((w for w in method_warnings(cal) if _decision_warning(w)), "")
    print(f"  status: {cal.status}" + (f" — {why.partition(': ')[2]}" if why and not verbose else ""))


def cmd_run(args: argparse.Namespace) -> int:
    """Calibrate a recording (:func:`calib.session.run.run_session`); print the result; write JSON (exactly
    ``Calibration.save``'s bytes) and .rrd if asked (the JSON also when the result is not ok: the evidence is
    kept); exit 1 when the calibration failed its own consistency check (status inconsistent/diverged), 2 on
    bad input (calib.inputs: nothing is written)."""
    from calib.inputs import KF
    from calib.session.run import RunOptions, method_warnings, resolve_run_method, run_session

    check_output_paths({"--json": args.json, "--rrd": args.rrd}, input_files(args.recording, args.turns, args.prior))
    options = RunOptions(method=args.method, accelerometer=args.accelerometer, gravity_m_s2=args.gravity,
                         external_acc_allowance_m_s2=args.external_acc, keep_history=args.rrd is not None,
                         prior=_prior(args))
    name, mode, note = resolve_run_method(options, flag="--method")
    if note:  # a former spelling: still runs, with a note; the run gets the registered name
        print(f"warning: {note}", file=sys.stderr)
        options = replace(options, method=name, accelerometer=mode)
    loaded = open_input(args, KF)
    from calib.app.warmup import announce_if_slow
    from calib.session.kernel import warm_up

    with announce_if_slow(lambda msg: print(msg, file=sys.stderr, flush=True)):
        warm_up()   # every method runs the compiled filter: a cold cache compiles it here, and says so
    cal = run_session(loaded, replace(options, turns=_turns(args, loaded.recording)))
    _print_run(args.recording, cal, args.verbose)
    if args.json:
        cal.save(args.json)
        print(f"wrote {args.json}")
    if args.rrd:
        from calib.app.rerun import save_calibration_rrd

        truth = cal.report.get("truth")
        truth = None if truth is None else {k: np.asarray(truth[k]) for k in
                                            ("bias_rad_s", "scale_factor", "nonorthogonality")}
        with atomic_path(args.rrd) as tmp:
            save_calibration_rrd(tmp, loaded.recording, replace(cal, warnings=method_warnings(cal)), truth)
        print(f"wrote {args.rrd}; open it with:  rerun {args.rrd}")
    return status_exit(cal.status == "ok", f"calibration {cal.status}: see the warnings above for what to try")


def _turns(args: argparse.Namespace, rec):
    """The turns of a known angle ``--turns`` / ``--protocol`` name (None without either; both: refused)."""
    from calib.inputs.turns import TurnsError, read_turns, turns_for_protocol

    if args.turns and args.protocol:
        raise TurnsError("give the turns either as --turns FILE or by --protocol, not both")
    if args.turns:
        return read_turns(args.turns)
    if args.protocol:
        return turns_for_protocol(args.protocol, rec.meta, rec.t_s, args.recording)
    return None


def _prior(args: argparse.Namespace):
    """``--prior FILE`` (a previous calibration) and ``--prior-tolerance`` as a
    :class:`~calib.session.decision.prior.Prior` (None: the maker-calibrated default)."""
    from gyrosim.calibration import Calibration

    from calib.session.decision.prior import Prior

    if args.prior_tolerance is None and args.prior is None:
        return None
    try:
        base = Prior.maker() if args.prior_tolerance is None else Prior.from_tolerance(args.prior_tolerance)
    except ValueError as exc:
        raise GyrosimError(f"--prior-tolerance: {exc}") from None
    if args.prior is None:
        return base
    return Prior.from_calibration(Calibration.load(args.prior), f"previous calibration {Path(args.prior).name}",
                                  fallback=base)


def cmd_apply(args: argparse.Namespace) -> int:
    """Compensate a recording with a calibration file and write the result (HDF5 or CSV by suffix)."""
    from gyrosim.calibration import Calibration
    from gyrosim.recording import save_csv, save_hdf5

    from calib.inputs import GENERIC

    out = Path(args.out)
    if out.suffix.lower() not in (".h5", ".hdf5", ".csv"):
        raise GyrosimError(f"--out {out}: use a .h5/.hdf5 (HDF5, keeps truth and metadata) or .csv (SI units) name")
    check_output_paths({"--out": out}, input_files(args.recording, args.calibration))
    cal = Calibration.load(args.calibration)
    if cal.status == "diverged" and cal.applied is None and not args.force:
        raise GyrosimError(
            f"{args.calibration} has status 'diverged': its numbers are no calibration; re-run calib run "
            "(see its warnings) or pass --force to apply it anyway"
        )
    if cal.status != "ok":
        what = ("its σ does not describe its error" if cal.applied is None else
                "only what this file says it applies is applied")
        print(f"warning: {args.calibration} has status '{cal.status}': {what}", file=sys.stderr)
    loaded = open_input(args, GENERIC)
    print_input_warnings(loaded.report)
    comp = cal.compensate(loaded.recording)
    rec = loaded.recording
    (save_csv if out.suffix.lower() == ".csv" else save_hdf5)(comp, out)
    if cal.applied is not None:   # the parameters the session determined, the prior's for the rest
        print(f"wrote {out}: {rec.n} samples compensated with {args.calibration} ({cal.method}, status {cal.status})")
        print(f"  applied {cal.applied.summary}")
    else:
        print(f"wrote {out}: {rec.n} samples, gyro{' and accelerometer' if cal.has('accelerometer', 'bias') else ''} "
              f"compensated with {args.calibration} ({cal.method}, status {cal.status})")
    return 0


def cmd_export(args: argparse.Namespace) -> int:
    """Write a calibration in another tool's format: Kalibr imu.yaml or imucal JSON."""
    from gyrosim.calibration import Calibration
    from gyrosim.exchange import imucal_json, kalibr_imu_yaml

    check_output_paths({"--out": args.out}, [args.calibration, args.noise])
    cal = Calibration.load(args.calibration)
    if args.format == "kalibr":
        from calib.noise.allan_triads import read_kalibr_noise

        rate = args.rate or cal.diagnostics.get("filter", {}).get("rate_hz")
        if not rate:
            raise GyrosimError("Kalibr's imu.yaml needs the IMU rate: pass --rate HZ")
        text = kalibr_imu_yaml(cal, float(rate), rostopic=args.rostopic, gyro_random_walk=args.gyro_random_walk,
                               acc_random_walk=args.acc_random_walk,
                               noise=read_kalibr_noise(args.noise) if args.noise else None)
    else:
        text = imucal_json(cal)
    out = Path(args.out)
    write_text_atomic(out, text)
    print(f"wrote {out} ({args.format})")
    return 0


def cmd_inspect(args: argparse.Namespace) -> int:
    """Summarise a recording (any file ``calib run`` reads): format, length, rate, channels, truth,
    what the input boundary did to it and what a method would refuse (:mod:`calib.app.inspect`)."""
    from calib.app.inspect import summarise_recording
    from calib.inputs import INSPECT

    loaded = open_input(args, INSPECT)
    summary = summarise_recording(args.recording, loaded.recording, loaded.report)
    for line in summary.lines():
        print(line)
    print_input_warnings(loaded.report)
    for p in loaded.report.problems:
        print(f"  problem: {p}")
    return 0


METHOD_HELP = (
    "the method, by its registered estimator name (the same in campaigns and Monte Carlo): kf_hand_joint (the "
    "default: the hand's lever arm and coloured external acceleration in the model, accelerometer estimated; kf_hand "
    "with --accelerometer calibrated; docs/hand.md); kf_joint (one pass of the hand-blind filter with a session-wide "
    "external-acceleration allowance; kf_session_r with the accelerometer calibrated; the default when --external-acc "
    "is given); iterated_joint, iterated_session_r (its re-linearised passes: Gauss–Newton on the batch posterior). "
    "Former spellings, deprecated (a note says the new one): hand, kf_session, iterated_session, and kf, iterated "
    "(which here still run kf_joint, iterated_joint — not the paper's filter the registered kf names)"
)


def _method_name(text: str) -> str:
    """``--method``: a name :func:`calib.session.run.resolve_run_method` takes, else argparse's invalid choice."""
    from calib.session.run import FORMER_METHODS, SESSION_METHODS

    if text in SESSION_METHODS or text in FORMER_METHODS:
        return text
    raise argparse.ArgumentTypeError(f"invalid choice: {text!r} (use one of {', '.join(SESSION_METHODS)}; the other "
                                     "registered estimators are research baselines: calib lab montecarlo --methods)")


def _add_run(sub) -> None:
    r = sub.add_parser(
        "run", help="calibrate a recording: gyro and accelerometer errors, σ",
        description="Calibrate a recording (HDF5 or CSV): gyro and accelerometer bias, scale factor, "
        "non-orthogonality with their σ; exit 1 when the result fails its own check (status inconsistent/diverged).",
    )
    r.add_argument("recording", help=RECORDING_HELP)
    r.add_argument("--method", default=None, type=_method_name, metavar="NAME", help=METHOD_HELP)
    r.add_argument(
        "--accelerometer",
        default=None,
        choices=("estimate", "calibrated"),
        help="estimate: the accelerometer's bias, scale factor and non-orthogonality with the gyro's (default, unless "
        "the method's name says calibrated); calibrated: assume it calibrated (Zhou 2020 §3.3.2, the paper's 9-state "
        "filter; kf_hand, kf_session_r, iterated_session_r)",
    )
    r.add_argument(
        "--gravity",
        type=number(9.7, 9.9, unit="m/s²"),
        default=None,
        help="local gravity, m/s², in [9.7, 9.9] (default: 9.80665 with --accelerometer estimate — the "
        "accelerometer scale factors are relative to it; the mean |f| at rest with --accelerometer calibrated)",
    )
    r.add_argument(
        "--json",
        help="write the result as JSON (a Calibration file: calib apply / export read it; never an input file)",
    )
    r.add_argument("--rrd", help="write a rerun recording (P converging, estimates, signals; never an input file)")
    r.add_argument("--verbose", action="store_true",
                   help="print every finding in full (by default the descriptive ones are left to the JSON and the "
                        "rest kept to two lines each)")
    r.add_argument("--prior", metavar="CAL_JSON", default=None,
                   help="a previous calibration of this sensor (calib run --json) as the prior: this session starts "
                        "from its values and σ, and what it does not determine stays at them (calibrations accumulate)")
    r.add_argument("--prior-tolerance", metavar="SPEC", default=None,
                   help="the maker-calibrated prior's 1σ: S=0.01,G=0.01,acc_bias=0.25,acc_S=0.01,acc_G=0.01 (the "
                        "defaults; acc_bias in m/s²; any subset, or one number for S, G, acc_S, acc_G) — a parameter "
                        "is applied when this session's σ is at most half of it")
    input_options(r, decimate=True)
    r.add_argument(
        "--external-acc",
        type=number(0, 100, unit="m/s²"),
        default=None,
        help="allowance for the hand's external acceleration, m/s² RMS, in [0, 100] (default: from the rest data; "
        "the hand-blind methods only)",
    )
    r.add_argument("--turns", metavar="FILE", default=None,
                   help="turns of a known angle (CSV/JSON rows start_s, end_s, axis, angle_deg, sigma_deg): each "
                   "enters the filter as a measurement, so a turn about a vertical axis determines that axis's scale "
                   "factor")
    r.add_argument("--protocol", choices=("ferraris",), default=None,
                   help="ferraris: the turns from imucal's section list beside the recording (<name>_list.json; "
                   "x_rot, y_rot, z_rot, each −360° ± 0.5°)")
    r.set_defaults(func=cmd_run)


def _add_apply_export_inspect(sub) -> None:
    ap = sub.add_parser("apply", help="compensate a recording with a calibration JSON",
                        description="Compensate a recording with a calibration JSON (from calib run --json).")
    ap.add_argument("calibration", help="calibration JSON written by calib run --json")
    ap.add_argument("recording", help="recording to compensate (HDF5, CSV, dataset:NAME)")
    ap.add_argument("--out", required=True, help="output: .h5/.hdf5 (keeps truth, metadata) or .csv (SI units)")
    input_options(ap)
    ap.add_argument("--force", action="store_true", help="apply even a calibration whose status is 'diverged'")
    ap.set_defaults(func=cmd_apply)
    ex = sub.add_parser("export", help="write a calibration for Kalibr or imucal",
                        description="Write a calibration JSON in another tool's format (Kalibr imu.yaml, imucal JSON): "
                                    "the values calib apply applies (its applied block: what the session determined, "
                                    "the prior's for the rest).")
    ex.add_argument("calibration", help="calibration JSON written by calib run --json")
    ex.add_argument(
        "--format",
        required=True,
        choices=("kalibr", "imucal"),
        help="kalibr: imu.yaml noise densities and random walks (continuous time); imucal: its Ferraris JSON",
    )
    ex.add_argument("--out", required=True, help="output file")
    ex.add_argument("--rate", type=number(0, 1e6, lo_open=True, unit="Hz"), default=None,
                    help="IMU rate for Kalibr's update_rate, Hz, in (0, 1e6] (default: the session's)")
    ex.add_argument("--rostopic", default="/imu0", help="Kalibr rostopic (default /imu0)")
    ex.add_argument("--gyro-random-walk", type=number(0, None, unit="rad/s²/√Hz"), default=None,
                    help="gyro bias random walk, rad/s²/√Hz (Kalibr needs it; a calibration session cannot measure it: "
                         "calib allan on a long static recording, or the datasheet)")
    ex.add_argument("--acc-random-walk", type=number(0, None, unit="m/s³/√Hz"), default=None,
                    help="accelerometer bias random walk, m/s³/√Hz, ≥ 0")
    ex.add_argument("--noise", help="the noise calib allan --json measured on a long static recording of this IMU: "
                                    "both triads' white noise and random walk (the two options above win over it)")
    ex.set_defaults(func=cmd_export)
    i = sub.add_parser("inspect", help="what a recording holds, what a method would refuse",
                       description="Summarise a recording: format, length, rate, channels, truth, what the input "
                                   "boundary did to it and what a method would refuse.")
    i.add_argument("recording", help=RECORDING_HELP)
    input_options(i)
    i.set_defaults(func=cmd_inspect)


def _add_demo(sub) -> None:
    d = sub.add_parser("demo", help="the whole loop on a simulated session, with a report",
                       description="The main job: simulate the hand-held session, calibrate it, write the "
                                   "recording, a report and a rerun recording.")
    d.add_argument("--out", default="out", help="output folder (default ./out)")
    d.add_argument("--schedule", default="zhou2020", help="built-in schedule or TOML path (default zhou2020)")
    d.add_argument("--hand", default="typical", help="hand preset or TOML path (default typical)")
    d.add_argument("--sensor", default="zhou2020_sim", help="sensor preset or TOML (default: Zhou 2020 Table 7)")
    d.add_argument("--rate", type=number(20, 1000, unit="Hz"), default=100.0,
                   help="sample rate, Hz, in [20, 1000] (what the filter supports; default 100)")
    d.add_argument("--seed", type=integer(0, 2**32 - 1001), default=1,
                   help="seed, 0 … 2³²−1001 (the validation session uses seed + 1000; default 1)")
    d.add_argument("--accelerometer", default=None, choices=("estimate", "calibrated"),
                   help="estimate the accelerometer with the gyro (default) or assume it calibrated (Zhou §3.3.2)")
    d.add_argument("--method", default=None, type=_method_name, metavar="NAME",
                   help="the method, as calib run --method (default calib run's, kf_hand_joint; kf_joint is the "
                   "demo's former hand-blind filter)")
    d.set_defaults(func=cmd_demo)


def add_parsers(sub) -> None:
    """``run``, ``apply``, ``export``, ``inspect``, ``demo`` on the command line's subparsers ``sub``."""
    _add_run(sub)
    _add_apply_export_inspect(sub)
    _add_demo(sub)
