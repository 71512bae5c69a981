"""``calib demo``: the main job end to end — simulate a hand-held session, calibrate it, validate the
attitude on a second session of the same device, write the recording, the report and the rerun file.

:func:`run_demo` is the library form (the command is a thin layer over it) and returns a
:class:`DemoResult` with the paths it wrote and the calibration.
"""

from __future__ import annotations

from contextlib import nullcontext
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from gyrosim.calibration import Calibration

__all__ = ["DemoResult", "run_demo", "DEMO_FILES"]

DEMO_FILES = ("session.h5", "report.json", "report.md", "convergence.png", "session.rrd")


@dataclass(frozen=True)
class DemoResult:
    """What :func:`run_demo` wrote into its folder, and the calibration it made."""

    recording: Path
    report: Path
    report_json: Path
    rrd: Path
    calibration: Calibration


def run_demo(
    out: str | Path,
    *,
    schedule: str = "zhou2020",
    hand: str = "typical",
    sensor: str = "zhou2020_sim",
    rate_hz: float = 100.0,
    seed: int = 1,
    accelerometer: str = "estimate",
    method: str | None = None,
    progress: Callable[[int], None] | None = None,
    log: Callable[[str], None] = lambda msg: None,
    compile_ahead: bool = True,
) -> DemoResult:
    """Simulate ``schedule`` × ``hand`` × ``sensor`` (seed ``seed``), calibrate it with ``method`` (a registered name;
    None: ``calib run``'s default, :func:`calib.session.defaults.default_method` — the hand-aware ``kf_hand_joint``,
    ``kf_hand`` with ``accelerometer="calibrated"``; the demo ran the hand-blind ``kf_joint`` before, which
    ``method="kf_joint"`` still does: Zhou's Figures 2–3 on the paper's sensor), validate the
    attitude on the free-style session of seed + 1000 (:func:`calib.session.validation.validate_attitude`), and write
    :data:`DEMO_FILES` into ``out`` (created).  ``progress(physics_steps)`` follows the simulation; ``log(text)`` the
    stages.  ``compile_ahead``: compile the filter in a background process while the session is simulated
    (:class:`calib.app.warmup.FilterWarmup`; the first run on a machine is ~20 s shorter, later runs load it from
    numba's cache either way)."""
    from calib.app.warmup import FilterWarmup

    with FilterWarmup() if compile_ahead else nullcontext() as warm:
        return _run_demo(Path(out), schedule, hand, sensor, rate_hz, seed, accelerometer, method, progress, log, warm)


def _run_demo(out: Path, schedule: str, hand: str, sensor: str, rate_hz: float, seed: int, accelerometer: str,
              method: str | None, progress: Callable[[int], None] | None, log: Callable[[str], None],
              warm) -> DemoResult:
    """:func:`run_demo`'s steps; ``warm`` the filter's background compile (or None), waited for before calibrating."""
    from gyrosim.hand import load_hand
    from gyrosim.recording import save_hdf5
    from gyrosim.schedule import load_schedule
    from gyrosim.sensor_model import load_sensor
    from gyrosim.simulate import simulate

    from calib.app.report import import_plotting, write_session_report
    from calib.app.rerun import save_calibration_rrd
    from calib.session.defaults import default_method
    from calib.session.paper import calibrate, true_gyro_parameters
    from calib.session.validation import validate_attitude, validation_session

    out.mkdir(parents=True, exist_ok=True)
    sched, hnd, model = load_schedule(schedule), load_hand(hand), load_sensor(sensor)
    rec = simulate(sched, hnd, model, rate_hz, seed=seed, progress=progress)
    rec_path = save_hdf5(rec, out / "session.h5")
    name = method or default_method(accelerometer)
    log("simulating a free-style session of the same device, to validate the attitude on …")
    free = validation_session(rec, hand=hnd.name, seed=seed + 1000)   # needs no filter: while it compiles
    import_plotting()                                      # the report's first plot imports matplotlib: now too
    if warm is not None:
        warm.wait(log)                                     # the filter compiled in the background: loaded, not rebuilt
    log(f"calibrating {rec.n} samples ({name}) …")
    result = calibrate(rec, name, accelerometer=accelerometer)
    truth = true_gyro_parameters(rec)
    log("validating the attitude on the free-style session …")
    validation = validate_attitude(rec, result, session=free)
    report = write_session_report(out, rec, result, truth, schedule=sched, hand=hnd, sensor=model, seed=seed,
                                  validation=validation)
    rrd = save_calibration_rrd(out / "session.rrd", rec, result, truth)
    return DemoResult(Path(rec_path), Path(report), out / "report.json", Path(rrd), result)
