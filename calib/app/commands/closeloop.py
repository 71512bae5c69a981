"""``calib closeloop``: fit the declared model, find what the residual lacks, add it, report before/after
(:func:`calib.closeloop.run_closeloop`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from gyrosim.cliargs import number

from calib.app.commands.common import RECORDING_HELP, input_files, input_options, open_input, print_input_warnings
from calib.app.outputs import check_output_paths, staged_folder

__all__ = ["add_parsers", "cmd_closeloop"]


def cmd_closeloop(args: argparse.Namespace) -> int:
    """Fit the declared model, find what the residual lacks, add it, report before/after."""
    from calib.inputs import CLOSELOOP

    check_output_paths({"--out": args.out}, input_files(args.recording), folders=["--out"],
                       folder_files={"--out": ("report.json", "report.md", "closeloop.rrd", "residual_time.png")})
    loaded = open_input(args, CLOSELOOP.with_(min_duration_s=2 * args.holdout))
    # a bad file is refused above, before the loop's libraries (MuJoCo, scipy) are imported
    from tqdm import tqdm

    from calib.closeloop import run_closeloop
    from calib.closeloop.report import write_closeloop_report

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
    print_input_warnings(loaded.report)
    for f in res.found:
        print(f"  found: {f.trace}")
    if not res.found:
        print("  found nothing beyond the declared model")
    ranked = res.ranked_by_size()
    if len(ranked) > 1:
        print("  largest first, each judged with the others in (held-out G): "
              + ", ".join(f"{kind} {gain:.0f}" for kind, gain in ranked))
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


def add_parsers(sub) -> None:
    """``closeloop`` on the command line's subparsers ``sub``."""
    cl = sub.add_parser("closeloop", help="find the effects a model lacks, add them, re-fit",
                        description="Fit the declared model, find the effects its residual says it lacks, add them, "
                                    "report before/after.")
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
    input_options(cl, decimate=True)
    cl.set_defaults(func=cmd_closeloop)
