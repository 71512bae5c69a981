"""Noise of a static recording and how long to record: ``calib allan``, ``calib noise`` (GMWM), ``calib plan``."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from gyrosim.cliargs import number
from gyrosim.errors import GyrosimError

from calib.app.commands.common import (
    RECORDING_HELP,
    input_files,
    input_options,
    open_input,
    print_input_warnings,
    status_exit,
)
from calib.app.outputs import atomic_path, check_output_paths, write_json_atomic

__all__ = ["add_parsers", "cmd_allan", "cmd_noise", "cmd_plan"]


def cmd_allan(args: argparse.Namespace) -> int:
    """Allan deviation of a static recording's gyro: fitted N, B, K per IEEE 952, and a plot."""
    from calib.inputs import ALLAN
    from calib.noise.allan import allan_deviation, fit_noise_terms, plot_allan

    check_output_paths({"--png": args.png}, input_files(args.recording))
    loaded = open_input(args, ALLAN)
    rec = loaded.recording
    curves = [allan_deviation(rec.gyro_rad_s[:, i], rec.rate_hz) for i in range(3)]
    fit = fit_noise_terms(curves)
    deg = 180 / math.pi
    print(f"{args.recording}: {rec.duration_s:.0f} s at {rec.rate_hz:g} Hz, three gyro axes pooled")
    print_input_warnings(loaded.report)
    print(f"  angle random walk   N = {fit.arw * deg * 60:.4f} ± {fit.arw_std * deg * 60:.4f} °/√h")
    print(f"  bias instability    B = {fit.bias_instability * deg * 3600:.3f} ± "
          f"{fit.bias_instability_std * deg * 3600:.3f} °/h")
    print(f"  rate random walk    K = {fit.rate_random_walk * deg * 3600 * 60:.3f} ± "
          f"{fit.rate_random_walk_std * deg * 3600 * 60:.3f} °/h/√h")
    print("  (± is the fit's 1σ from the Allan confidence; the recording must be static)")
    if args.png:
        with atomic_path(args.png) as tmp:
            plot_allan(curves, fit, tmp, unit_scale=deg * 3600, unit="°/h",
                       title=f"Allan deviation: {Path(str(args.recording)).name}")
        print(f"wrote {args.png}")
    return 0


def _noise_recording(args: argparse.Namespace):
    """The static record for ``calib noise``: the whole file (a moving one is refused), the span
    ``--span A:B``, the longest still stretch (``--longest-still``) or every still stretch
    (``--still-segments``) of a file that also moves.  Returns (Loaded, segments or None)."""
    from calib.inputs import NOISE, MotionError, TooShortError, prepare_recording
    from calib.inputs.motion import summarise_motion

    req = NOISE.with_(sensors=(args.triad,))  # the other triad may be absent or constant
    if not (args.span or args.longest_still or args.still_segments):
        return open_input(args, req), None
    loaded = open_input(args, req.with_(motion="any", min_samples=2))
    rec = loaded.recording
    t0 = float(rec.t_s[0])
    if args.span:
        try:
            a, b = (float(v) for v in args.span.split(":"))
        except ValueError:
            raise GyrosimError(f"--span must be START:END in seconds, got {args.span!r}")
        spans = [(a + t0, b + t0)]
    else:
        mot = summarise_motion(rec)
        still = ~mot.moving
        edges = np.diff(np.concatenate([[0], still.astype(np.int8), [0]]))
        starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
        # 1 s margins: a window's edges may hold the start or end of a turn
        spans = sorted(((float(mot.window_t_s[s]) + 1.0, float(mot.window_t_s[e - 1] + mot.window_s) - 1.0)
                        for s, e in zip(starts, ends)), key=lambda ab: ab[0] - ab[1])
        spans = [ab for ab in spans if ab[1] - ab[0] >= 3.0]
        if not spans:
            longest = max(((e - s) * mot.window_s for s, e in zip(starts, ends)), default=0.0)
            raise MotionError(f"{args.recording}: the board moves in {mot.moving_fraction:.0%} of its 1-s windows; its "
                              f"longest still stretch is {longest:.0f} s, and calib noise needs at least 5 s still "
                              "(3 s after 1-s margins at both ends) for white noise alone")
        if args.longest_still:
            spans = spans[:1]
    segs, notes = [], []
    for a, b in spans:
        keep = (rec.t_s >= a) & (rec.t_s <= b)
        if keep.sum() < 2:
            raise TooShortError(f"{args.recording}: t = {a - t0:.1f}–{b - t0:.1f} s holds {int(keep.sum())} samples")
        sub = rec.with_signals(**{k: (None if getattr(rec, k) is None else getattr(rec, k)[keep])
                                  for k in ("t_s", "gyro_rad_s", "acc_m_s2", "temp_c", "mag_ut")}, truth=None)
        segs.append(prepare_recording(sub, req if len(spans) == 1 else req.with_(min_samples=16)))
        notes.append(f"{a - t0:.1f}–{b - t0:.1f} s")
    first = segs[0]
    warn = (
        tuple(loaded.report.warnings)
        + (f"analysed {len(segs)} still span(s) of the file: t = {', '.join(notes)}",)
        + tuple(w for sg in segs for w in sg.report.warnings)
    )
    report = type(first.report)(**{**first.report.__dict__, "warnings": warn})
    if len(segs) == 1:
        return type(first)(first.recording, report), None
    return type(first)(first.recording, report), [sg.recording for sg in segs]


def cmd_noise(args: argparse.Namespace) -> int:
    """Stochastic model of a static record: wavelet variance, GMWM, WIC selection,
    intervals, every unit, the noise-inflation figure; ``--json`` holds a sensor model."""
    from calib.inputs import TemperatureTrendError, TooShortError
    from calib.noise import identify_noise, minimum_samples, model_name, parse_model
    from calib.noise.gmwm import NOISE_TERMS
    from calib.noise.report import plot_noise, summary_lines, temperature_trend_c

    check_output_paths({"--json": args.json, "--png": args.png}, input_files(args.recording))
    loaded, segments = _noise_recording(args)
    rec = loaded.recording
    n_total = rec.n if segments is None else sum(r.n for r in segments)
    models = None
    if args.model != "auto":
        try:
            kinds = parse_model(args.model)
        except ValueError as exc:
            raise GyrosimError(f"--model: {exc}")
        models = [kinds]
        p = sum(len(NOISE_TERMS[k].noise_parameters) for k in kinds)
        need = minimum_samples(p)
        if n_total < need:
            raise TooShortError(f"{args.recording}: {n_total} samples ({n_total / rec.rate_hz:.1f} s); the model "
                                f"{model_name(kinds)} "
                                f"({p} parameters) needs at least {need} samples = {need / rec.rate_hz:.1f} s at "
                                f"{rec.rate_hz:g} Hz (J ≥ p + 2 octave scales with the largest Allan cluster ≤ T/8)")
    sig = "gyro_rad_s" if args.triad == "gyro" else "acc_m_s2"
    x = getattr(rec, sig) if segments is None else [getattr(r, sig) for r in segments]
    warnings = list(loaded.report.warnings)
    trend = temperature_trend_c(rec.t_s, rec.temp_c)
    trend_msg = None
    if trend is not None and abs(trend) >= args.max_temperature_trend:
        trend_msg = (
            f"the temperature changes by {trend:+.2f} °C over the {rec.duration_s:.0f}-s record (straight-line fit): "
            "the bias follows the temperature, so its drift would be read as random walk (or rate ramp) and "
            "that estimate biased high"
        )
        asked_slow = models is not None and any(NOISE_TERMS[k].noise_bias_drift for k in models[0])
        if asked_slow and not args.allow_temperature_trend:
            raise TemperatureTrendError(
                f"{args.recording}: {trend_msg}; record at a stable temperature, compensate the "
                "temperature first (calib temperature), or pass --allow-temperature-trend"
            )
        warnings.append(trend_msg)
    res = identify_noise(x, rec.rate_hz, args.triad, models, tuple(warnings))
    chosen_slow = [a.axis for a in res.axes if any(NOISE_TERMS[k].noise_bias_drift for k in a.selection.chosen.kinds)]
    if trend_msg and chosen_slow and not args.allow_temperature_trend:
        raise TemperatureTrendError(
            f"{args.recording}: axes {', '.join(chosen_slow)} chose a random walk or rate ramp, "
            f"but {trend_msg}; record at a stable temperature, compensate the temperature first "
            "(calib temperature), or pass --allow-temperature-trend"
        )
    print(f"{args.recording}: {n_total} samples, static")
    print_input_warnings(loaded.report)
    for line in summary_lines(res):
        print(line)
    infl = res.inflation["axes"]
    for a in infl:
        hz = a["white_only"]["max_over_horizon"]
        cells = ", ".join(f"{h} s: ×{v['factor']:.2f}" for h, v in hz.items())
        print(f"  noise inflation (axis {a['axis']}, white-only estimator aided every h): {cells}")
    for w in res.warnings:
        if w not in loaded.report.warnings:
            print(f"  warning: {w}")
    if args.json:
        write_json_atomic(args.json, {"recording": str(args.recording), **res.to_dict()})
        print(f"wrote {args.json} (its sensor_model: gyrosim simulate --sensor {args.json})")
    if args.png:
        with atomic_path(args.png) as tmp:
            plot_noise(res, tmp)
        print(f"wrote {args.png}")
    return status_exit(res.status == "ok", f"noise model {res.status}: the model does not describe every axis (see "
                       "the INCONSISTENT axes above)")


def cmd_plan(args: argparse.Namespace) -> int:
    """How long to record: record length per stochastic parameter for a target
    relative 1σ, and schedule repetitions for a target σ on S and G (CRLB)."""
    from gyrosim.sensor_model import load_sensor

    from calib.noise.plan import record_length, schedule_repetitions

    check_output_paths({"--json": args.json}, input_files(args.sensor))
    sensor = load_sensor(args.sensor)
    rows = []
    for triad, effects in (("gyro", sensor.gyro), ("accelerometer", sensor.accelerometer)):
        rows += record_length(tuple(effects), triad, args.rate, args.target)
    print(f"sensor {sensor.name}, static record at {args.rate:g} Hz, target relative 1σ {args.target:g} "
          f"(95 % interval ≈ ±{196 * args.target:.0f} %) per parameter (axis x's values):")
    for r in rows:
        length = ("beyond 10⁶ s" if r.record_length_s is None else
                  "≤ 10 s" if r.record_length_s <= r.curve_t_s[0] else
                  f"{r.record_length_s:,.0f} s ({r.record_length_s / 3600:.2f} h)")
        print(f"  {r.triad:<13} {r.term}.{r.parameter} = {r.value_si:.4g} SI: record {length}")
    out = {"sensor": sensor.name, "rate_hz": args.rate, "target_relative_sigma": args.target,
           "stochastic": [r.to_dict() for r in rows]}
    if args.target_s is not None or args.target_g is not None:
        ts = args.target_s if args.target_s is not None else args.target_g
        tg = args.target_g if args.target_g is not None else args.target_s
        reps = schedule_repetitions(sensor, args.schedule, args.rate, ts, tg)
        print(f"  schedule {args.schedule}: CRLB of one pass σ_S ≤ {max(reps['crlb_one_pass']['S']):.2e}, "
              f"σ_G ≤ {max(reps['crlb_one_pass']['G']):.2e}; {reps['repetitions']} repetition(s) for σ_S ≤ {ts:g}, "
              f"σ_G ≤ {tg:g}")
        out["deterministic"] = reps
    if args.json:
        write_json_atomic(args.json, out)
        print(f"wrote {args.json}")
    return 0


def add_parsers(sub) -> None:
    """``allan``, ``noise``, ``plan`` on the command line's subparsers ``sub``."""
    al = sub.add_parser("allan", help="Allan deviation of a static recording",
                        description="Allan deviation of a static recording: angle random walk, bias instability, "
                                    "rate random walk (IEEE 952), and a plot.")
    al.add_argument("recording", help=RECORDING_HELP + "; static (a moving record is refused)")
    al.add_argument("--png", help="write the Allan plot (PNG; never an input file)")
    input_options(al)
    al.set_defaults(func=cmd_allan)
    no = sub.add_parser(
        "noise", help="stochastic noise model of a static recording",
        description="Stochastic model of a static record: wavelet variance, GMWM fit, model chosen by "
        "WIC, 95 % intervals, every unit, noise-inflation figure; --json holds a sensor model for gyrosim.",
    )
    no.add_argument("recording", help=RECORDING_HELP + "; static (a moving record is refused unless "
                                                       "--span/--longest-still)")
    no.add_argument("--triad", choices=("gyro", "acc"), default="gyro", help="which triad (default gyro)")
    no.add_argument("--model", default="auto",
                    help="auto (default: chosen among 32 candidates by WIC) or a model such as white+rw, "
                         "white+flicker+rw, white+2gm, white+qn+gm+rw+drift")
    no.add_argument("--span", default=None, metavar="START:END", help="analyse only t = START…END s of the file")
    no.add_argument("--longest-still", action="store_true", help="analyse the file's longest still stretch")
    no.add_argument("--still-segments", action="store_true",
                    help="analyse every still stretch of ≥ 5 s, wavelet variances pooled (multi-position sessions)")
    no.add_argument("--max-temperature-trend", type=number(0.0, 1e3), default=0.2, metavar="DEG_C",
                    help="a temperature change over the record above this (°C, default 0.2) is named as a bias source")
    no.add_argument("--allow-temperature-trend", action="store_true",
                    help="identify a random walk / rate ramp despite a temperature trend (warned)")
    no.add_argument("--json", help="write the result (JSON; holds sensor_model for gyrosim simulate --sensor)")
    no.add_argument("--png", help="write the wavelet-variance plot with the chosen model (PNG)")
    input_options(no)
    no.set_defaults(func=cmd_noise)
    pl = sub.add_parser("plan", help="how long to record for a target σ",
                        description="How long to record: record length per noise parameter for a target relative σ, "
                                    "and schedule repetitions for a target σ on S and G (CRLB).")
    pl.add_argument(
        "--sensor", required=True, help="sensor preset name, TOML, Kalibr imu.yaml, or a calib noise --json"
    )
    pl.add_argument("--target", type=number(1e-4, 10.0), default=0.1,
                    help="target relative 1σ of each stochastic parameter (default 0.1 = 10 %%)")
    pl.add_argument("--rate", type=number(1.0, 1e5), default=100.0, help="sample rate (Hz, default 100)")
    pl.add_argument("--target-s", type=number(1e-9, 1.0), default=None, help="target σ on the gyro scale factors S (1)")
    pl.add_argument("--target-g", type=number(1e-9, 1.0), default=None, help="target σ on the gyro non-orthogonality G "
                                                                             "(1)")
    pl.add_argument("--schedule", default="zhou2020", help="schedule for --target-s/-g (default zhou2020)")
    pl.add_argument("--json", help="write the plan (JSON)")
    pl.set_defaults(func=cmd_plan)
