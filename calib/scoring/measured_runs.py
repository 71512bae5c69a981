"""The ``calib`` command run as a user runs it, for the measured-data harness (:mod:`calib.scoring.measured`).

Every calibration the harness scores comes from a subprocess of the ``calib`` command — ``calib run``,
``calib apply``, ``calib mag`` — of the interpreter and the code this module was imported from (the
child's ``PYTHONPATH`` starts with the folder holding this ``calib`` package), so what is measured is
what a user gets: the input checks, the default method, the refusals, the exit codes and the files.

``calib run`` is run with its defaults first; when it refuses because the session "cannot separate the
accelerometer" (exit 2), it is run again with ``--accelerometer calibrated``, as its message suggests.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import calib

__all__ = ["ACC_REFUSAL", "CliRun", "calib_command", "run_calibration", "apply_calibration", "run_magnetometer"]

# the words of calib run's refusal that its own message answers with "--accelerometer calibrated"
ACC_REFUSAL = "cannot separate the accelerometer"
MESSAGE_CHARS = 240  # a refusal's message is kept to this length in the result


@dataclass(frozen=True)
class CliRun:
    """One ``calib`` command as the user typed it (``command``: paths shown relative to the data folder or
    as the output file's name), its exit code, wall time (s), the status of the JSON it wrote (``None``
    when it wrote none) and what it said on stderr when it refused or failed (first error line, or '')."""

    command: tuple[str, ...]
    exit_code: int
    seconds: float
    status: str | None = None
    message: str = ""

    @property
    def text(self) -> str:
        """The command line as one string."""
        return " ".join(self.command)

    def to_dict(self) -> dict[str, Any]:
        return {"command": list(self.command), "exit_code": self.exit_code, "seconds": self.seconds,
                "status": self.status, "message": self.message}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "CliRun":
        return cls(tuple(d["command"]), int(d["exit_code"]), float(d["seconds"]), d.get("status"),
                   d.get("message", ""))


def _child_env(data_dir: Path) -> dict[str, str]:
    """The environment of a ``calib`` child: this ``calib`` first on the path, the data folder as
    ``$GYROSIM_DATA`` (so ``dataset:NAME`` means a recording of the folder being validated)."""
    env = dict(os.environ)
    here = str(Path(calib.__file__).resolve().parents[1])
    env["PYTHONPATH"] = os.pathsep.join([here, *([env["PYTHONPATH"]] if env.get("PYTHONPATH") else [])])
    env["GYROSIM_DATA"] = str(data_dir)
    return env


def _message(stderr: str, exit_code: int, folders: tuple[Path, ...]) -> str:
    """The line that says why a command refused or failed, the ``folders`` (data, work) shown relative."""
    if exit_code == 0:
        return ""
    lines = [ln.strip() for ln in stderr.splitlines() if ln.strip()]
    errors = [ln for ln in lines if ln.startswith("calib: error:")]
    text = errors[0] if errors else (lines[-1] if lines else f"exit {exit_code} without a message")
    for folder in folders:
        for spelling in {str(folder), str(folder.resolve())}:
            text = text.replace(spelling.rstrip("/") + "/", "")
    return text if len(text) <= MESSAGE_CHARS else text[:MESSAGE_CHARS - 1] + "…"


def _status(path: Path | None) -> str | None:
    if path is None or not path.is_file():
        return None
    try:
        return json.loads(path.read_text()).get("status")
    except (OSError, ValueError):
        return None


def calib_command(args: list[str], shown: list[str], data_dir: Path, workdir: Path,
                  writes: Path | None = None) -> CliRun:
    """Run ``calib ARGS`` in ``workdir`` (a subprocess of this interpreter's ``calib``; its own files are named
    relative to ``workdir``); ``shown`` is the same command as the result reports it, ``writes`` the JSON
    whose status it reads back."""
    if writes is not None and writes.exists():
        writes.unlink()  # a file of an earlier run must not pass for this one's
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "calib", *args], cwd=workdir, env=_child_env(data_dir),
                          capture_output=True, text=True)
    seconds = time.perf_counter() - t0
    return CliRun(("calib", *shown), proc.returncode, round(seconds, 2), _status(writes),
                  _message(proc.stderr, proc.returncode, (data_dir, workdir)))


def run_calibration(source: str, shown: str, data_dir: Path, workdir: Path, extra: tuple[str, ...] = ()
                    ) -> tuple[tuple[CliRun, ...], Path | None]:
    """``calib run SOURCE --json cal.json`` with the defaults (and ``extra`` options: what a user of that
    recording knows, e.g. its protocol), then, if it refused for the accelerometer, with ``--accelerometer
    calibrated``; the runs and the calibration file (``None`` when none was written)."""
    cal = workdir / "cal.json"
    runs = [calib_command(["run", source, *extra, "--json", cal.name], ["run", shown, *extra, "--json", "cal.json"],
                          data_dir, workdir, cal)]
    if runs[0].exit_code == 2 and ACC_REFUSAL in runs[0].message:
        runs.append(calib_command(["run", source, *extra, "--accelerometer", "calibrated", "--json", cal.name],
                                  ["run", shown, *extra, "--accelerometer", "calibrated", "--json", "cal.json"],
                                  data_dir, workdir, cal))
    return tuple(runs), (cal if cal.is_file() and runs[-1].exit_code in (0, 1) else None)


def apply_calibration(cal: Path, source: str, shown: str, data_dir: Path, workdir: Path) -> tuple[CliRun, Path | None]:
    """``calib apply cal.json SOURCE --out comp.h5`` (no ``--force``: a diverged calibration is refused, as
    for a user); the run and the compensated file (``None`` when none was written)."""
    out = workdir / "comp.h5"
    if out.exists():
        out.unlink()
    run = calib_command(["apply", cal.name, source, "--out", out.name],
                        ["apply", "cal.json", shown, "--out", "comp.h5"], data_dir, workdir)
    return run, (out if out.is_file() and run.exit_code == 0 else None)


def run_magnetometer(source: str, shown: str, data_dir: Path, workdir: Path) -> tuple[CliRun, Path | None]:
    """``calib mag SOURCE --json mag.json``; the run and the file (``None`` when none was written).  Its exit
    code is the magnetometer status's (0 ok, 3 hard iron only, 4 inconsistent, 5 disturbed; 2 refused)."""
    out = workdir / "mag.json"
    run = calib_command(["mag", source, "--json", out.name], ["mag", shown, "--json", "mag.json"], data_dir,
                        workdir, out)
    return run, (out if out.is_file() and run.exit_code != 2 else None)
