"""The measured-data harness: judge a calibration by what the user does next.

On simulated worlds a calibration is scored against the truth; on a real IMU the question is whether the
calibration helps the person who made it.  For every recording with a reference in a data folder, this
harness calibrates as a user does — a subprocess of ``calib run`` with its defaults (again with
``--accelerometer calibrated`` when it refuses because the session cannot separate the accelerometer, as
its message suggests), then ``calib apply`` — and scores the result by what comes next:

* **BROAD** (every ``broad/*.hdf5`` of BROAD's layout: a new trial is a new file, not new code): the
  orientation filters users run — VQF 9D and 6D, Madgwick (BROAD's C form) and Mahony with BROAD's
  gains — against the optical reference, BROAD's RMSE over its ``movement`` mask; and ``calib mag``'s
  effect on VQF 9D's heading (:mod:`calib.scoring.measured_broad`);
* **imu_tk's Xsens session**: imu_tk's two figures beside imu_tk's own result;
  **imucal's Ferraris session**: the rest figures, the 360° turns and our parameters beside imucal's;
  **the x-io sessions**: a held-out check — gravity carried by the gyro from one rest to the next
  (:mod:`calib.scoring.measured_sessions`).

Each recording is scored in four variants (raw, bias only, full, plain reference;
:mod:`calib.scoring.measured_result`), so a figure says both whether the calibration helped and whether
it beat what anyone gets by subtracting the bias of the first rest.  Over the BROAD trials the medians of
the changes summarise it.

Command::

    python -m calib.scoring.measured DATA_DIR [--only NAME] [--json OUT] [--markdown OUT] [--workdir DIR]

prints one block per recording (a progress line per recording on stderr), then the medians.  Exit code 0
when every recording found was scored (whatever calib's own statuses: they are the measurement), 1 when
some could not be, 2 when it cannot start (no such folder, nothing matches ``--only``, the orientation filters
— the ``orientation`` extra — not installed), 3 for an internal error.
"""

from __future__ import annotations

import argparse
import re
import resource
import sys
import tempfile
import time
from datetime import datetime, timezone
from pathlib import Path
from typing import Callable

from gyrosim.errors import GyrosimError
from gyrosim.loaders import available_datasets

import calib
from calib.orientation import builtin
from calib.scoring.measured_broad import BROAD_FILTERS, validate_broad
from calib.scoring.measured_format import markdown, text_block, text_medians
from calib.scoring.measured_result import MeasuredValidation, RecordingResult, broad_medians
from calib.scoring.measured_sessions import validate_ferraris, validate_imu_tk, validate_xio

__all__ = ["validate", "recordings_in", "main", "MeasuredValidation", "RecordingResult"]

SESSIONS: dict[str, Callable[[Path, Path], RecordingResult]] = {
    "imu_tk_xsens": validate_imu_tk,
    "imucal_ferraris": validate_ferraris,
    "xio_fusion": lambda data, work: validate_xio("xio_fusion", data, work),
    "xio_ximu_thermometer": lambda data, work: validate_xio("xio_ximu_thermometer", data, work),
}


def recordings_in(data_dir: Path) -> dict[str, Callable[[Path, Path], RecordingResult]]:
    """Every recording with a reference under ``data_dir``: name → the function that scores it."""
    jobs: dict[str, Callable[[Path, Path], RecordingResult]] = {}
    for path in sorted((data_dir / "broad").glob("*.hdf5")) if (data_dir / "broad").is_dir() else []:
        jobs[f"broad/{path.stem}"] = lambda data, work, path=path: validate_broad(path, data, work)
    for name in available_datasets(data_dir):
        if name in SESSIONS:
            jobs[name] = SESSIONS[name]
    return jobs


def _require_filters() -> None:
    """Refuse before any work when the orientation filters BROAD is scored with are not installed."""
    for name, _, _ in BROAD_FILTERS:
        try:
            builtin(name)
        except ImportError as exc:
            raise GyrosimError(f"scoring the BROAD trials needs the orientation filters: {exc}") from exc


def _cpu_seconds() -> float:
    own, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def _progress_line(i: int, n: int, rec: RecordingResult) -> str:
    runs = [r for r in rec.runs if r.command[1] == "run"]
    codes = ", then ".join(str(r.exit_code) for r in runs)
    status = rec.calibration.get("status", "no calibration")
    return f"[{i}/{n}] {rec.name}: calib run exit {codes} ({status}); {rec.seconds:.0f} s"


def validate(data_dir: str | Path, only: str | None = None, workdir: str | Path | None = None,
             progress: Callable[[str], None] | None = None) -> MeasuredValidation:
    """Score every recording with a reference in ``data_dir`` (module docstring); ``only``: the recordings
    whose name contains it; ``workdir``: keep calib's files there (one folder per recording; default a
    temporary folder); ``progress``: called with a line per recording."""
    data_dir = Path(data_dir).resolve()  # the calib commands run in their own folder
    if not data_dir.is_dir():
        raise GyrosimError(f"no data folder at {data_dir}: give the folder that holds broad/, imu_tk_xsens/, …")
    jobs = recordings_in(data_dir)
    if only:
        jobs = {k: f for k, f in jobs.items() if only in k}
        if not jobs:
            raise GyrosimError(f"no recording matches {only!r}; found: {', '.join(recordings_in(data_dir)) or 'none'}")
    if not jobs:
        raise GyrosimError(f"no recording with a reference under {data_dir} (expected broad/*.hdf5, imu_tk_xsens/, "
                           "imucal_ferraris/, xio_fusion/, xio_ximu_thermometer/)")
    if any(name.startswith("broad/") for name in jobs):
        _require_filters()
    t0, c0 = time.perf_counter(), _cpu_seconds()
    results, failed = [], []
    with tempfile.TemporaryDirectory(prefix="calib-measured-") as tmp:
        root = Path(workdir).resolve() if workdir else Path(tmp)
        for i, (name, job) in enumerate(jobs.items(), 1):
            work = root / re.sub(r"[^A-Za-z0-9_.-]", "_", name)
            work.mkdir(parents=True, exist_ok=True)
            try:
                rec = job(data_dir, work)
            except (GyrosimError, OSError, ValueError) as exc:
                failed.append(f"{name}: {exc}")
                if progress:
                    progress(f"[{i}/{len(jobs)}] {name}: not scored — {exc}")
                continue
            results.append(rec)
            if progress:
                progress(_progress_line(i, len(jobs), rec))
    return MeasuredValidation(tuple(results), broad_medians(results), round(time.perf_counter() - t0, 1),
                              round(_cpu_seconds() - c0, 1), calib.__version__, tuple(failed))


def build_parser() -> argparse.ArgumentParser:
    """The command's arguments (module docstring)."""
    p = argparse.ArgumentParser(prog="python -m calib.scoring.measured",
                                description="judge calib on every measured recording with a reference: calib run and "
                                            "calib apply as a user runs them, then the filters and checks that follow")
    p.add_argument("data_dir", type=Path, help="the measured-data folder (broad/, imu_tk_xsens/, imucal_ferraris/, …)")
    p.add_argument("--only", metavar="NAME", help="only the recordings whose name contains NAME (e.g. broad/16_)")
    p.add_argument("--json", type=Path, metavar="OUT", help="write the result as JSON")
    p.add_argument("--markdown", type=Path, metavar="OUT", help="write the tables as Markdown")
    p.add_argument("--workdir", type=Path, metavar="DIR", help="keep calib's files (cal.json, comp.h5, mag.json) here")
    return p


def main(argv: list[str] | None = None) -> int:
    """The command: blocks and medians on stdout, progress on stderr; the exit code of the module docstring."""
    args = build_parser().parse_args(argv)
    for out in (args.json, args.markdown):
        if out is not None and not out.parent.is_dir():
            print(f"error: the folder of {out} does not exist: create it or choose another output", file=sys.stderr)
            return 2
    try:
        result = validate(args.data_dir, args.only, args.workdir, lambda line: print(line, file=sys.stderr))
    except GyrosimError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    for rec in result.recordings:
        print(text_block(rec) + "\n")
    print(text_medians(result))
    print(f"{len(result.recordings)} recording(s) in {result.seconds:.0f} s wall, {result.cpu_seconds:.0f} s CPU")
    if args.json:
        import json

        args.json.write_text(json.dumps(result.to_dict(), indent=1) + "\n")
        print(f"wrote {args.json}")
    if args.markdown:
        command = " ".join(["python -m calib.scoring.measured", *(sys.argv[1:] if argv is None else argv)])
        stamp = f"calib {result.calib_version}; `{command}`; {datetime.now(timezone.utc):%Y-%m-%d %H:%M} UTC"
        args.markdown.write_text(markdown(result, stamp))
        print(f"wrote {args.markdown}")
    if result.failed:
        print("not scored: " + "; ".join(result.failed), file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except Exception as exc:  # noqa: BLE001 - an internal error: exit 3 with a one-line message
        print(f"internal error: {type(exc).__name__}: {exc}", file=sys.stderr)
        sys.exit(3)
