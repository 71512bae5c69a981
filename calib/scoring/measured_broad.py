"""A BROAD trial judged by the orientation filters users run after calibrating (for :mod:`calib.scoring.measured`).

BROAD (Laidig, Caruso, Cereatti, Seel, "BROAD — A Benchmark for Robust Inertial Orientation Estimation",
Data 6(7):72, 2021; CC BY 4.0) records a myon aktos-t IMU with optical motion capture.  Every trial file
of its layout (``broad/*.hdf5``) is calibrated with ``calib run`` and ``calib apply``
(:mod:`calib.scoring.measured_runs`), and each variant of :mod:`calib.scoring.measured_result` goes
through four filters:

* VQF 9D (total and heading RMSE) and VQF 6D (inclination RMSE) — ``vqf`` 2.x with its defaults
  (Laidig & Seel, "VQF: Highly Accurate IMU Orientation Estimation with Bias Estimation and Magnetic
  Disturbance Rejection", Information Fusion 91, 2023);
* Madgwick in the form of his 2011 C code (``madgwick_c2011_9d``: the form BROAD's published numbers come
  from) and Mahony, both 9-axis with BROAD's TAGP gains (β = 0.12; k_P = 0.74, k_I = 0.0012;
  :mod:`gyrosim.orientation_broad`) — total, heading and inclination RMSE;

scored with BROAD's own error definitions over its ``movement`` mask
(:func:`gyrosim.attitude_errors.broad_rmse_deg`).  The magnetometer: ``calib mag`` on the trial, its
result applied to the raw and to the applied recording, VQF 9D's heading RMSE for each.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from gyrosim.attitude_errors import broad_rmse_deg
from gyrosim.loaders import load_broad
from gyrosim.orientation import run_orientation
from gyrosim.orientation_broad import PUBLISHED_AS, PUBLISHED_TAGP
from gyrosim.recording import Recording

from calib.mag import MagCalibration
from calib.orientation import builtin
from calib.scoring.measured_result import VARIANTS, RecordingResult, calibrate_variants
from calib.scoring.measured_runs import run_magnetometer
from calib.scoring.measured_statics import StaticDetector, static_intervals

__all__ = ["BROAD_FILTERS", "score_filters", "validate_broad", "shown_path"]

METRICS = ("total_rmse_deg", "heading_rmse_deg", "inclination_rmse_deg")
# (estimator name in calib.orientation, figure prefix, metrics scored): a 6-axis heading is relative, not scored
BROAD_FILTERS = (("vqf_9d", "vqf_9d", ("total_rmse_deg", "heading_rmse_deg")),
                 ("vqf", "vqf_6d", ("inclination_rmse_deg",)),
                 ("madgwick_c2011_9d", "madgwick_c2011_9d", METRICS),
                 ("mahony_9d", "mahony_9d", METRICS))


def score_filters(rec: Recording, quat_ref: np.ndarray, movement: np.ndarray,
                  filters: tuple = BROAD_FILTERS) -> dict[str, float]:
    """BROAD's RMSEs (°) of each filter of ``filters`` on ``rec`` against ``quat_ref`` (body → ENU) over
    ``movement``: figure key → value."""
    out = {}
    for name, prefix, metrics in filters:
        att = run_orientation(builtin(name), rec, name)
        got = broad_rmse_deg(att.quat_nb, quat_ref, movement)
        out.update({f"{prefix}.{m}": got[m] for m in metrics})
    return out


def shown_path(path: Path, data_dir: Path) -> str:
    """``path`` as the report shows it: relative to the data folder (no machine paths in results)."""
    try:
        return path.resolve().relative_to(data_dir.resolve()).as_posix()
    except ValueError:
        return path.name


def _magnetometer(raw: Recording, full: Recording | None, path: Path, shown: str, data_dir: Path, workdir: Path,
                  quat_ref: np.ndarray, movement: np.ndarray, heading_raw: float):
    """``calib mag`` on the trial and VQF 9D's heading RMSE with its result applied: (run, figure, summary)."""
    run, mag_json = run_magnetometer(str(path), shown, data_dir, workdir)
    figure = {"raw": heading_raw, "mag_calibrated": np.nan, "full_mag_calibrated": np.nan}
    if mag_json is None:
        return run, figure, {}
    mag = MagCalibration.load(mag_json)
    vqf9 = (BROAD_FILTERS[0][0], "vqf_9d", ("heading_rmse_deg",))
    for variant, rec in (("mag_calibrated", raw), ("full_mag_calibrated", full)):
        if rec is not None:
            figure[variant] = score_filters(mag.compensate_recording(rec), quat_ref, movement,
                                            (vqf9,))["vqf_9d.heading_rmse_deg"]
    summary = {"status": mag.status, "method": mag.method, "hard_iron_uT": mag.hard_iron_ut.tolist(),
               "field_uT": mag.field_ut, "refused": len(mag.refused)}
    return run, figure, summary


def validate_broad(path: Path, data_dir: Path, workdir: Path) -> RecordingResult:
    """One BROAD trial (module docstring): the runs, the calibration, every variant's filter RMSEs, the
    magnetometer's heading, and BROAD's published raw-data numbers for the trial where there are some."""
    t0 = time.perf_counter()
    raw = load_broad(path)
    movement = raw.truth.extra["movement"].astype(bool)
    quat_ref = raw.truth.quat_nb
    rests = static_intervals(raw.acc_m_s2, StaticDetector.for_rate(raw.rate_hz))
    shown = shown_path(path, data_dir)
    cv = calibrate_variants(raw, str(path), shown, data_dir, workdir, rests[0] if rests else None)
    figures: dict[str, dict[str, float]] = {}
    for variant in VARIANTS:
        rec = cv.recordings.get(variant)
        scores = score_filters(rec, quat_ref, movement) if rec is not None else {}
        for _, prefix, metrics in BROAD_FILTERS:
            for m in metrics:
                figures.setdefault(f"{prefix}.{m}", {})[variant] = scores.get(f"{prefix}.{m}", np.nan)
    mag_run, mag_figure, mag_summary = _magnetometer(raw, cv.recordings.get("full"), path, shown, data_dir, workdir,
                                                     quat_ref, movement, figures["vqf_9d.heading_rmse_deg"]["raw"])
    figures["vqf_9d_mag.heading_rmse_deg"] = mag_figure
    published = {ours: dict(zip(METRICS, PUBLISHED_TAGP[theirs][path.stem]))
                 for ours, theirs in PUBLISHED_AS.items() if path.stem in PUBLISHED_TAGP[theirs]}
    details = {"movement_samples": int(movement.sum()), "static_intervals": len(rests),
               "magnetometer": mag_summary, "published_raw": published}
    notes = cv.notes + (() if mag_summary else (f"calib mag wrote no result (exit {mag_run.exit_code})",))
    return RecordingResult(
        name=shown.removesuffix(".hdf5"), kind="broad", reference="optical orientation (BROAD opt_quat, movement mask)",
        samples=raw.n, duration_s=raw.duration_s, runs=cv.runs + (mag_run,), calibration=cv.calibration,
        plain_reference=cv.plain_reference, figures=figures, details=details, notes=notes,
        seconds=round(time.perf_counter() - t0, 1))
