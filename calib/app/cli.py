"""``calib`` command line: thin wrappers over library calls."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

from gyrosim.cliargs import integer, number, seed
from gyrosim.errors import GyrosimError

from calib import __version__
from calib.app.outputs import atomic_path, check_output_paths, staged_folder, write_json_atomic, write_text_atomic


def _open(args: argparse.Namespace, requirements, path: str | None = None):
    """The input boundary for a command's recording (calib.inputs.open_recording) with its options."""
    from calib.inputs import open_recording

    return open_recording(
        path or args.recording,
        getattr(args, "gyro_unit", "rad/s"),
        getattr(args, "acc_unit", "m/s^2"),
        requirements=requirements,
        time_unit=getattr(args, "time_unit", None),
        decimate=getattr(args, "decimate", None),
    )


def _files(*specs: str | None) -> list[str]:
    """The files behind the inputs a command was given (``dataset:NAME`` → the measured files), so
    that no output can land on one of them."""
    from gyrosim.loaders import data_root

    out: list[str] = []
    for spec in specs:
        if spec is None:
            continue
        if str(spec).startswith("dataset:"):
            name = str(spec)[len("dataset:"):]
            root = data_root()
            where = root / "broad" / f"{name.split('/', 1)[1]}.hdf5" if name.startswith("broad/") else root / name
            out += [str(f) for f in (where.rglob("*") if where.is_dir() else [where]) if f.is_file()][:1000]
        elif Path(spec).is_dir():
            out += [str(f) for f in Path(spec).rglob("*") if f.is_file()][:1000]
        else:
            out.append(str(spec))
    return out


def _print_input_warnings(report) -> None:
    for w in report.warnings:
        print(f"  input: {w}")


def _rms(x: np.ndarray) -> float:
    return math.sqrt(float(np.mean(np.sum(np.asarray(x) ** 2, axis=1))))


def cmd_demo(args: argparse.Namespace) -> int:
    """The main job: simulate the hand-held session, calibrate it, write recording, report and .rrd
    (:func:`calib.app.demo.run_demo`)."""
    from tqdm import tqdm

    from gyrosim.schedule import load_schedule
    from gyrosim.simulate import simulation_grid

    from calib.app.demo import DEMO_FILES, run_demo

    check_output_paths({"--out": args.out}, [args.schedule, args.hand, args.sensor], folders=["--out"],
                       folder_files={"--out": DEMO_FILES})
    grid = simulation_grid(load_schedule(args.schedule).duration_s, args.rate)
    with tqdm(total=grid.t_physics_s.size + 1, unit="step", desc="simulating session", leave=False) as bar:
        def log(msg: str) -> None:
            bar.close()   # the simulation is over once the stages start
            print(msg, flush=True)

        res = run_demo(args.out, schedule=args.schedule, hand=args.hand, sensor=args.sensor, rate_hz=args.rate,
                       seed=args.seed, accelerometer=args.accelerometer, progress=bar.update, log=log)
    print(f"wrote {res.recording}, {res.report}, {res.report_json} and {res.rrd}")
    print(f"open the recording with:  rerun {res.rrd}")
    return 0


# exit code of ``calib run`` by status: 1 = done, but the result failed its own check (the JSON says
# which: inconsistent or diverged); 2 stays "bad input" (gyrosim.cli.run_cli)
EXIT_STATUS = {"ok": 0, "inconsistent": 1, "diverged": 1}


def _print_calibration(cal, truth) -> None:
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
    if ref:   # where S holds (calib.session.hand.filter.scale_reference_rate): the user applies it at other rates
        m = np.degrees(ref["rate_rad_s"])
        top = np.degrees(ref["max_abs_rate_rad_s"])
        print(
            f"  scale factor holds at ±{', '.join(f'{v:.0f}' for v in m)} °/s (x, y, z: the chord over the rates this "
            f"session turned at, up to {', '.join(f'{v:.0f}' for v in top)} °/s); at other rates a gyro's scale "
            "nonlinearity adds to it — calibrate at the rates you will use"
        )
    if truth is not None:
        err_s = cal.scale_factor - truth.value("gyro", "scale_factor")
        err_g = cal.nonorthogonality - truth.value("gyro", "nonorthogonality")
        print(f"  error vs truth: S {np.round(err_s, 5).tolist()}, G {np.round(err_g, 5).tolist()}")
        if cal.has("accelerometer", "bias"):
            print(
                "  accelerometer error vs truth: b "
                f"{np.round(cal.value('accelerometer', 'bias') - truth.value('accelerometer', 'bias'), 4).tolist()} "
                "m/s², "
                f"""S {np.round(
                    cal.value('accelerometer', 'scale_factor') - truth.value('accelerometer', 'scale_factor'), 5
                ).tolist()}"""
            )


def cmd_run(args: argparse.Namespace) -> int:
    """Calibrate a recording; print the result; write JSON and .rrd if asked (the JSON also when the
    result is not ok: the evidence is kept); exit 1 when the calibration failed its own consistency
    check (status inconsistent/diverged), 2 on bad input (calib.inputs: nothing is written)."""
    from gyrosim.calibration import truth_calibration

    from calib.inputs import KF
    from calib.session.paper import DEPRECATED_METHODS, calibrate

    check_output_paths({"--json": args.json, "--rrd": args.rrd}, _files(args.recording))
    if args.method is None:   # the default: the hand-aware filter, unless a hand-blind allowance was given
        args.method = "kf_session" if args.external_acc is not None else "hand"
    method = args.method
    if method in DEPRECATED_METHODS:  # the former spellings: still run, with a note
        method = DEPRECATED_METHODS[method]
        print(f"warning: --method {args.method} is deprecated: use --method {method} (the same filter; 'kf' names "
              "the paper's filter in campaigns and Monte Carlo, which calib run does not run)", file=sys.stderr)
    loaded = _open(args, KF)
    rec = loaded.recording
    if args.method == "hand":   # kf_hand_joint (accelerometer estimated) or kf_hand (--accelerometer calibrated)
        if args.external_acc is not None:
            raise GyrosimError("--external-acc is an allowance of the hand-blind filters (kf_session, "
                               "iterated_session); "
                               "--method hand models the hand's acceleration and estimates its spectrum from the data")
        from calib.session.hand.filter import kf_hand

        result = kf_hand(rec, accelerometer=args.accelerometer, gravity_m_s2=args.gravity,
                         keep_history=args.rrd is not None)
    else:   # the per-step history (√P, θ̂, innovations, NIS: 0.3–0.5 KB a sample) only feeds the .rrd, never the JSON
        result = calibrate(rec, method, accelerometer=args.accelerometer,
                           external_acc_allowance_m_s2=args.external_acc, gravity_m_s2=args.gravity,
                           keep_history=args.rrd is not None)
    d = result.to_dict()
    from calib.session.coach import coach
    from calib.session.paper import prepare

    coaching = coach(rec, result, prepare(rec, accelerometer=args.accelerometer, gravity_m_s2=args.gravity))
    d["coaching"] = coaching.to_dict()
    d["warnings"] = list(loaded.report.warnings) + list(d.get("warnings", []))
    d["input"] = loaded.report.to_dict()
    print(f"{args.recording}: method {result.method}, accelerometer {args.accelerometer}, rest "
          f"{d['rest_segments'][:3]}{' …' if len(d['rest_segments']) > 3 else ''}")
    truth = truth_calibration(rec)
    _print_calibration(result, truth)
    if truth is not None:
        d["truth"] = {"bias_rad_s": truth.value("gyro", "bias").tolist(),
                      "scale_factor": truth.value("gyro", "scale_factor").tolist(),
                      "nonorthogonality": truth.value("gyro", "nonorthogonality").tolist(),
                      "accelerometer": {"bias_m_s2": truth.value("accelerometer", "bias").tolist(),
                                        "scale_factor": truth.value("accelerometer", "scale_factor").tolist(),
                                        "nonorthogonality": truth.value("accelerometer", "nonorthogonality").tolist()}}
    _print_input_warnings(loaded.report)
    for line in coaching.lines():
        print(f"  {line}")
    for w in result.warnings:
        print(f"  warning: {w}")
    print(f"  status: {result.status}")
    if args.json:
        write_json_atomic(args.json, d)
        print(f"wrote {args.json}")
    if args.rrd:
        from calib.app.rerun import save_calibration_rrd

        with atomic_path(args.rrd) as tmp:
            save_calibration_rrd(tmp, rec, result, None if truth is None else _truth_dict(truth))
        print(f"wrote {args.rrd}; open it with:  rerun {args.rrd}")
    if result.status != "ok":
        print(f"calibration {result.status}: see the warnings above for what to try", file=sys.stderr)
    return EXIT_STATUS[result.status]


def _truth_dict(truth) -> dict:
    return {"bias_rad_s": truth.value("gyro", "bias"), "scale_factor": truth.value("gyro", "scale_factor"),
            "nonorthogonality": truth.value("gyro", "nonorthogonality")}


def cmd_apply(args: argparse.Namespace) -> int:
    """Compensate a recording with a calibration file and write the result (HDF5 or CSV by suffix)."""
    from gyrosim.calibration import Calibration
    from gyrosim.recording import save_csv, save_hdf5

    from calib.inputs import GENERIC

    out = Path(args.out)
    if out.suffix.lower() not in (".h5", ".hdf5", ".csv"):
        raise GyrosimError(f"--out {out}: use a .h5/.hdf5 (HDF5, keeps truth and metadata) or .csv (SI units) name")
    check_output_paths({"--out": out}, _files(args.recording, args.calibration))
    cal = Calibration.load(args.calibration)
    if cal.status == "diverged" and not args.force:
        raise GyrosimError(
            f"{args.calibration} has status 'diverged': its numbers are no calibration; re-run calib run "
            "(see its warnings) or pass --force to apply it anyway"
        )
    if cal.status != "ok":
        print(
            f"warning: {args.calibration} has status '{cal.status}': its σ does not describe its error", file=sys.stderr
        )
    loaded = _open(args, GENERIC)
    _print_input_warnings(loaded.report)
    comp = cal.compensate(loaded.recording)
    rec = loaded.recording
    (save_csv if out.suffix.lower() == ".csv" else save_hdf5)(comp, out)
    print(f"wrote {out}: {rec.n} samples, gyro{' and accelerometer' if cal.has('accelerometer', 'bias') else ''} "
          f"compensated with {args.calibration} ({cal.method}, status {cal.status})")
    return 0


def cmd_export(args: argparse.Namespace) -> int:
    """Write a calibration in another tool's format: Kalibr imu.yaml or imucal JSON."""
    from gyrosim.calibration import Calibration
    from gyrosim.exchange import imucal_json, kalibr_imu_yaml

    check_output_paths({"--out": args.out}, [args.calibration])
    cal = Calibration.load(args.calibration)
    if args.format == "kalibr":
        rate = args.rate or cal.diagnostics.get("filter", {}).get("rate_hz")
        if not rate:
            raise GyrosimError("Kalibr's imu.yaml needs the IMU rate: pass --rate HZ")
        text = kalibr_imu_yaml(cal, float(rate), rostopic=args.rostopic, gyro_random_walk=args.gyro_random_walk,
                               acc_random_walk=args.acc_random_walk)
    else:
        text = imucal_json(cal)
    out = Path(args.out)
    write_text_atomic(out, text)
    print(f"wrote {out} ({args.format})")
    return 0


def cmd_montecarlo(args: argparse.Namespace) -> int:
    """Monte Carlo against the Cramér–Rao bound: prints the table, writes JSON if asked."""
    from tqdm import tqdm

    from calib.scoring.montecarlo import monte_carlo

    check_output_paths({"--json": args.json}, [args.schedule, args.hand, args.sensor])
    with tqdm(total=args.seeds, desc="sessions", unit="seed", leave=False) as bar:
        methods = tuple(args.methods.split(",")) if args.methods else None   # None: the library's default
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


def cmd_allan(args: argparse.Namespace) -> int:
    """Allan deviation of a static recording's gyro: fitted N, B, K per IEEE 952, and a plot."""
    from calib.inputs import ALLAN
    from calib.noise.allan import allan_deviation, fit_noise_terms, plot_allan

    check_output_paths({"--png": args.png}, _files(args.recording))
    loaded = _open(args, ALLAN)
    rec = loaded.recording
    curves = [allan_deviation(rec.gyro_rad_s[:, i], rec.rate_hz) for i in range(3)]
    fit = fit_noise_terms(curves)
    deg = 180 / math.pi
    print(f"{args.recording}: {rec.duration_s:.0f} s at {rec.rate_hz:g} Hz, three gyro axes pooled")
    _print_input_warnings(loaded.report)
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
        return _open(args, req), None
    loaded = _open(args, req.with_(motion="any", min_samples=2))
    rec = loaded.recording
    t0 = float(rec.t_s[0])
    if args.span:
        try:
            a, b = (float(v) for v in args.span.split(":"))
        except ValueError:
            raise SystemExit(f"calib noise: error: --span must be START:END in seconds, got {args.span!r}")
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

    check_output_paths({"--json": args.json, "--png": args.png}, _files(args.recording))
    loaded, segments = _noise_recording(args)
    rec = loaded.recording
    n_total = rec.n if segments is None else sum(r.n for r in segments)
    models = None
    if args.model != "auto":
        try:
            kinds = parse_model(args.model)
        except ValueError as exc:
            raise SystemExit(f"calib noise: error: --model: {exc}")
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
    _print_input_warnings(loaded.report)
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
    return 0 if res.status == "ok" else 1


def cmd_plan(args: argparse.Namespace) -> int:
    """How long to record: record length per stochastic parameter for a target
    relative 1σ, and schedule repetitions for a target σ on S and G (CRLB)."""
    from gyrosim.sensor_model import load_sensor

    from calib.noise.plan import record_length, schedule_repetitions

    check_output_paths({"--json": args.json}, _files(args.sensor))
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


def cmd_inspect(args: argparse.Namespace) -> int:
    """Summarise a recording (any file ``calib run`` reads): format, length, rate, channels, truth,
    what the input boundary did to it and what a method would refuse (:mod:`calib.app.inspect`)."""
    from calib.app.inspect import summarise_recording
    from calib.inputs import INSPECT

    loaded = _open(args, INSPECT)
    summary = summarise_recording(args.recording, loaded.recording, loaded.report)
    for line in summary.lines():
        print(line)
    _print_input_warnings(loaded.report)
    for p in loaded.report.problems:
        print(f"  problem: {p}")
    return 0


def cmd_closeloop(args: argparse.Namespace) -> int:
    """Fit the declared model, find what the residual lacks, add it, report before/after."""
    from tqdm import tqdm

    from calib.closeloop import run_closeloop
    from calib.closeloop.report import write_closeloop_report
    from calib.inputs import CLOSELOOP

    check_output_paths({"--out": args.out}, _files(args.recording), folders=["--out"],
                       folder_files={"--out": ("report.json", "report.md", "closeloop.rrd", "residual_time.png")})
    loaded = _open(args, CLOSELOOP.with_(min_duration_s=2 * args.holdout))
    rec = loaded.recording
    declared = tuple(k.strip() for k in args.declared.split(",") if k.strip())
    with tqdm(desc="closeloop", unit="test", leave=False) as bar:
        def progress(msg: str) -> None:
            bar.set_postfix_str(msg, refresh=False)
            bar.update()

        res = run_closeloop(rec, declared, reference=args.reference, holdout_s=args.holdout, progress=progress)
    res.notes[:0] = [f"input: {w}" for w in loaded.report.warnings]
    with staged_folder(args.out) as stage:  # all or nothing: a failed write leaves --out as it was
        staged = write_closeloop_report(stage, rec, res)
    paths = {k: Path(args.out) / p.name for k, p in staged.items()}
    print(f"reference: {res.reference} ({res.reference_description})")
    _print_input_warnings(loaded.report)
    for f in res.found:
        print(f"  found: {f.trace}")
    if not res.found:
        print("  found nothing beyond the declared model")
    print(f"  unexplained: {res.unexplained.get('summary', '')}")
    print(f"  error before: {res.error_before}\n  error after:  {res.error_after}")
    mag = res.magnetometer
    if mag is not None:
        print(f"magnetometer: {mag.reference}")
        for f in mag.found:
            print(f"  found: {f.trace}")
        if not mag.found:
            print("  found nothing beyond the declared magnetometer model")
        print(f"  unexplained: {mag.unexplained.get('summary', '')}")
    print("wrote " + ", ".join(str(p) for p in paths.values()))
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
                       _files(args.recording, args.train, args.ratetable))
    loaded = _open(args, TEMPERATURE)
    rec = loaded.recording
    _print_input_warnings(loaded.report)
    if args.train:
        train, test = [_open(args, TEMPERATURE, args.train).recording], [rec]
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

        rt = _open(args, RATETABLE, args.ratetable).recording
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

    points = calibrate_rate_table(_open(args, RATETABLE).recording)
    print(f"{'T °C':>7} {'axis':>4} {'bias °/s':>10} {'±1σ':>8} {'scale ppm':>10} {'±1σ':>7}")
    for p in points:
        for i, a in enumerate("xyz"):
            print(f"{p.temp_c[i]:7.2f} {a:>4} {math.degrees(p.bias_rad_s[i]):10.4f} "
                  f"{math.degrees(p.bias_sigma[i]):8.4f} "
                  f"{p.scale[i] * 1e6:10.0f} {p.scale_sigma[i] * 1e6:7.0f}")
    return 0


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

    check_output_paths({"--json": args.json}, _files(args.recording))
    loaded = _open(args, NORTHFIND)
    rec = loaded.recording
    _print_input_warnings(loaded.report)
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
    return 0 if res.ok else 1


def cmd_northfind_latitude(args: argparse.Namespace) -> int:
    """The "effect of latitude" (ERICCO, *Effect of latitude on gyroscopic theodolite*): the north-finding limit
    against latitude for sensor presets."""
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
    """The tilt-sensor static test (ERICCO, *Static Capacitance Test of MEMS Tilt Sensor*): per axis sensitivity,
    linearity, cross-axis, zero offset/stability."""
    from calib.inputs import TILT
    from calib.instruments.tilt import plot_tilt, tilt_test

    check_output_paths({"--json": args.json, "--png": args.png}, _files(args.recording, args.holds))
    loaded = _open(args, TILT)
    rec = loaded.recording
    _print_input_warnings(loaded.report)
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
    return 0 if res.ok else 1


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

    check_output_paths({"--json": args.json, "--rrd": args.rrd}, _files(args.recording))
    loaded = _open(args, MAG)
    rec = loaded.recording
    _print_input_warnings(loaded.report)
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
    if not res.ok:
        print(f"status {res.status}: exit code {res.exit_code}", file=sys.stderr)
    return res.exit_code


def cmd_mag_compare(args: argparse.Namespace) -> int:
    """The compass filters of *Soft Magnetic Error Compensation Method of Electronic Compass* (KF / adaptive KF /
    particle filter) against calibration, on a simulated device."""
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


RATE = number(0, 1e6, lo_open=True, unit="Hz")
RECORDING_HELP = (
    "recording: gyrosim .h5, BROAD .hdf5, CSV (t,gyro_x,gyro_y,gyro_z,acc_x,acc_y,acc_z[,temp][,mag_x,mag_y,"
    "mag_z]; separator , ; tab) or dataset:NAME — the format is read from the content"
)


def _decimate_arg(text: str) -> int | str:
    if text.strip().lower() == "auto":
        return "auto"
    return integer(1, 1_000_000)(text)


def _input_options(p: argparse.ArgumentParser, decimate: bool = False) -> None:
    """Options every command reading a recording shares (calib.inputs)."""
    p.add_argument("--gyro-unit", default="rad/s", help="unit of the gyro columns: rad/s (default), deg/s, mdeg/s, "
                                                        "rad/h, deg/h")
    p.add_argument("--acc-unit", default="m/s^2", help="unit of the accelerometer columns: m/s^2 (default), g, mg, ug")
    p.add_argument("--time-unit", default=None, choices=("auto", "s", "ms", "us", "ns"),
                   help="unit of the time column (default auto: seconds unless the step makes that implausible; "
                        "ms, µs, ns and Unix epochs are then converted with a warning)")
    if decimate:
        p.add_argument("--decimate", type=_decimate_arg, default=None, metavar="N|auto",
                       help="average blocks of N samples first (auto: the smallest N that brings the rate within "
                            "what the method supports, 1 kHz for the filter)")


def build_parser() -> argparse.ArgumentParser:
    """The ``calib`` command line's parser: one subcommand per job (``run``, ``demo``, ``closeloop``, ``mag``,
    …), each bound to the ``cmd_*`` function that runs it."""
    p = argparse.ArgumentParser(prog="calib", description="Gyroscope calibration from hand rotation.")
    p.add_argument("--version", action="version", version=f"calib {__version__}")
    sub = p.add_subparsers(dest="command", required=True)
    d = sub.add_parser("demo", help="main job: simulate the hand-held session, write recording, report, .rrd")
    d.add_argument("--out", default="out", help="output folder (default ./out)")
    d.add_argument("--schedule", default="zhou2020", help="built-in schedule or TOML path (default zhou2020)")
    d.add_argument("--hand", default="typical", help="hand preset or TOML path (default typical)")
    d.add_argument("--sensor", default="zhou2020_sim", help="sensor preset or TOML (default: Zhou 2020 Table 7)")
    d.add_argument("--rate", type=number(20, 1000, unit="Hz"), default=100.0,
                   help="sample rate, Hz, in [20, 1000] (what the filter supports; default 100)")
    d.add_argument("--seed", type=integer(0, 2**32 - 1001), default=1,
                   help="seed, 0 … 2³²−1001 (the validation session uses seed + 1000; default 1)")
    d.add_argument("--accelerometer", default="estimate", choices=("estimate", "calibrated"),
                   help="estimate the accelerometer with the gyro (default) or assume it calibrated (Zhou §3.3.2)")
    d.set_defaults(func=cmd_demo)
    r = sub.add_parser(
        "run",
        help="calibrate a recording (HDF5 or CSV): gyro and accelerometer bias, scale factor, "
        "non-orthogonality; exit 1 when the result fails its own check (status inconsistent/diverged)",
    )
    r.add_argument("recording", help=RECORDING_HELP)
    r.add_argument(
        "--method",
        default=None,
        choices=("kf_session", "iterated_session", "hand", "kf", "iterated"),
        help="default: hand (kf_session when --external-acc is given); "
        "kf_session: one filter pass with a session-wide external-acceleration allowance (the result "
        "is labelled kf_joint, or kf_session_r with --accelerometer calibrated: the registered "
        "estimators it equals); iterated_session: re-linearised passes (Gauss–Newton on the batch "
        "posterior; iterated_joint / iterated_session_r); hand: the hand's lever arm and coloured external "
        "acceleration in the model (labelled kf_hand_joint, or kf_hand with --accelerometer calibrated; "
        "docs/hand.md); "
        "kf, iterated: former spellings of kf_session, iterated_session (deprecated)",
    )
    r.add_argument(
        "--accelerometer",
        default="estimate",
        choices=("estimate", "calibrated"),
        help="estimate: the accelerometer's bias, scale factor and non-orthogonality with the gyro's (default); "
        "calibrated: assume it calibrated (Zhou 2020 §3.3.2, the paper's 9-state filter)",
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
    _input_options(r, decimate=True)
    r.add_argument(
        "--external-acc",
        type=number(0, 100, unit="m/s²"),
        default=None,
        help="allowance for the hand's external acceleration, m/s² RMS, in [0, 100] (default: from the rest data)",
    )
    r.set_defaults(func=cmd_run)
    ap = sub.add_parser("apply", help="compensate a recording with a calibration JSON (from calib run --json)")
    ap.add_argument("calibration", help="calibration JSON written by calib run --json")
    ap.add_argument("recording", help="recording to compensate (HDF5, CSV, dataset:NAME)")
    ap.add_argument("--out", required=True, help="output: .h5/.hdf5 (keeps truth, metadata) or .csv (SI units)")
    _input_options(ap)
    ap.add_argument("--force", action="store_true", help="apply even a calibration whose status is 'diverged'")
    ap.set_defaults(func=cmd_apply)
    ex = sub.add_parser("export", help="write a calibration JSON in another tool's format (Kalibr imu.yaml, imucal "
                                       "JSON)")
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
    ex.set_defaults(func=cmd_export)
    mc = sub.add_parser("montecarlo", help="Monte Carlo of the calibration against the Cramér–Rao bound")
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
        help="comma-separated: any registered estimator (kf = the paper's filter, iterated = it in three "
        "passes, kf_hand, kf_session_r, …, or package.module:attribute) and kf_session, "
        "iterated_session (calib run's filter, with the --accelerometer mode asked); default "
        "kf,iterated_session, or kf_session,iterated_session with --accelerometer estimate (the paper's "
        "kf assumes a calibrated accelerometer)",
    )
    mc.add_argument("--calibrated-accelerometer", action="store_true",
                    help="simulate a calibrated accelerometer: keep only its white noise (Zhou §3.3.2's assumption)")
    mc.add_argument("--accelerometer", default="calibrated", choices=("estimate", "calibrated"),
                    help="what the calibration assumes (calib run --accelerometer; default calibrated: the paper)")
    mc.add_argument("--first-seed", type=seed, default=0, help="first seed of the sessions, 0 … 2³²−1")
    mc.add_argument("--json", help="write the table as JSON")
    mc.set_defaults(func=cmd_montecarlo)
    ob = sub.add_parser("observability", help="observability of each schedule segment (Zhou 2020 §4, Tables 5, 10, 11)")
    ob.add_argument("--schedule", default="zhou2020", help="schedule to analyse: built-in name or TOML path (default "
                                                           "zhou2020)")
    ob.add_argument("--rate", type=RATE, default=100.0, help="sample rate, Hz, in (0, 1e6] (default 100)")
    ob.set_defaults(func=cmd_observability)
    be = sub.add_parser("bench", help="calibration speed: calib run (21 states) vs the paper's filterpy kf, same run")
    be.add_argument("--batch", type=integer(1, 10_000), default=50, help="batch size of the kernel-only row, 1 … 10000 "
                                                                         "(default 50)")
    be.add_argument("--repeats", type=integer(1, 1000), default=3,
                    help="interleaved repetitions, 1 … 1000; the best of each is reported (default 3)")
    be.set_defaults(func=cmd_bench)
    al = sub.add_parser("allan", help="Allan deviation of a static recording: ARW, bias instability, rate random walk")
    al.add_argument("recording", help=RECORDING_HELP + "; static (a moving record is refused)")
    al.add_argument("--png", help="write the Allan plot (PNG; never an input file)")
    _input_options(al)
    al.set_defaults(func=cmd_allan)
    no = sub.add_parser(
        "noise",
        help="stochastic model of a static record: wavelet variance, GMWM fit, model chosen by "
        "WIC, 95 %% intervals, every unit, noise-inflation figure",
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
    _input_options(no)
    no.set_defaults(func=cmd_noise)
    pl = sub.add_parser("plan", help="how long to record: record length per noise parameter for a target relative σ, "
                                     "and schedule repetitions for a target σ on S and G (CRLB)")
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
    cl = sub.add_parser("closeloop", help="find the effects the declared model lacks, add them, report before/after")
    cl.add_argument("recording", help=RECORDING_HELP)
    cl.add_argument("--out", required=True,
                    help="output folder: report.json, report.md, plots, closeloop.rrd (written all-or-nothing)")
    cl.add_argument("--declared", default="bias,scale_factor,nonorthogonality",
                    help="effects of the declared model (vocabulary names, comma-separated; magnetometer kinds "
                    "hard_iron, soft_iron, frame_rotation go to the magnetometer's model, which is empty by default)")
    cl.add_argument("--reference", default=None, choices=("truth", "optical", "static", "gravity"),
                    help="force a reference (default: the best the recording has)")
    cl.add_argument("--holdout", type=number(0.01, 3600, unit="s"), default=4.0,
                    help="length of the alternating fit/held-out stretches, s, in [0.01, 3600] (default 4)")
    _input_options(cl, decimate=True)
    cl.set_defaults(func=cmd_closeloop)
    tp = sub.add_parser("temperature", help="temperature models compared on held-out chamber cycles")
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
    _input_options(tp)
    tp.set_defaults(func=cmd_temperature)
    rtc = sub.add_parser("ratetable", help="bias and scale at each temperature point of a rate-table recording")
    rtc.add_argument("recording", help="rate-table recording (gyrosim ratetable)")
    _input_options(rtc)
    rtc.set_defaults(func=cmd_ratetable)
    cb = sub.add_parser("closeloop-bench", help="closeloop wall time vs the Zhou filter on the same ~3-min recordings")
    cb.set_defaults(func=cmd_closeloop_bench)
    cs = sub.add_parser("closeloop-suite", help="undeclared-effect suites over seeds: single effects, pairs, a static "
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
    nf = sub.add_parser("northfind", help="gyrocompassing: true heading from a static 2/4-position record, with σ and "
                                          "its limit")
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
    _input_options(nf)
    nf.set_defaults(func=cmd_northfind)
    nl = sub.add_parser("northfind-latitude", help="north-finding limit against latitude for sensor presets (table, "
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
    nm = sub.add_parser(
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
    tl = sub.add_parser("tilt", help="tilt-sensor static test: sensitivity, linearity, cross-axis, zero offset and "
                                     "stability")
    tl.add_argument("recording", help="gyrosim .h5 (gyrosim tilttable), or a CSV with --holds")
    tl.add_argument("--holds", help="CSV sweep,kind,angle_deg,t_start_s,t_stop_s for a recording without tilt-table "
                                    "metadata")
    tl.add_argument("--json", help="write the figures, tables and excluded holds as JSON")
    tl.add_argument("--png", help="write output against input angle with the residuals")
    _input_options(tl)
    tl.set_defaults(func=cmd_tilt)
    tm = sub.add_parser("tilt-mc", help="each calib tilt figure against the drawn device's value over many devices")
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
    mg = sub.add_parser("mag", help="magnetometer calibration: hard and soft iron, misalignment, local disturbances")
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
    _input_options(mg)
    mg.set_defaults(func=cmd_mag)
    mc2 = sub.add_parser(
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
    mm = sub.add_parser("mag-measured", help="magnetometers of the measured recordings: field spread, heading vs "
                                             "optical")
    mm.add_argument("--method", default="ellipsoid", choices=("ellipsoid", "aided"),
                    help="calibration method, as calib mag --method (default ellipsoid)")
    mm.set_defaults(func=cmd_mag_measured)
    mb = sub.add_parser("mag-bench", help="speed of the ellipsoid and attitude-aided fits on a 3-minute 100 Hz session")
    mb.add_argument("--repeats", type=integer(1, 1000), default=5, help="timing repeats, 1 … 1000 (default 5)")
    mb.set_defaults(func=cmd_mag_bench)
    i = sub.add_parser("inspect", help="summarise a recording")
    i.add_argument("recording", help=RECORDING_HELP)
    _input_options(i)
    i.set_defaults(func=cmd_inspect)
    return p


def main(argv: list[str] | None = None) -> int:
    """Run the ``calib`` command line on ``argv`` (default ``sys.argv[1:]``) and return its exit code
    (:func:`gyrosim.cli.run_cli`)."""
    from gyrosim.cli import run_cli

    return run_cli(build_parser(), argv)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
