"""The measured-data harness's result types and what every recording shares (for :mod:`calib.scoring.measured`).

Variants of a recording, each scored the same way (a figure maps variant → value):

* ``raw``: the recording as loaded;
* ``bias_only``: the raw gyro less the gyro bias ``calib run`` reported (nothing else of its result);
* ``full``: the file ``calib apply`` wrote (every parameter of the calibration applied);
* ``plain_reference``: the calibration anyone can do without calib — S = G = 0 and the gyro bias the
  mean over the recording's first static interval (:mod:`calib.scoring.measured_statics`);
* peers where there are some (``imu_tk``, ``imucal``) and, for the magnetometer, ``mag_calibrated``
  (``calib mag``'s result applied to the raw recording) and ``full_mag_calibrated`` (to the ``full`` one).

A figure that cannot be computed (no calibration was written, the peer is not installed) is NaN, and
the recording's notes say why.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gyrosim.recording import Recording, load_hdf5

from calib.scoring.measured_runs import CliRun, apply_calibration, run_calibration

__all__ = ["VARIANTS", "FIGURES", "RecordingResult", "MeasuredValidation", "CalibratedVariants", "calibrate_variants",
           "broad_medians", "finite_or_nan"]

VARIANTS = ("raw", "bias_only", "full", "plain_reference")
VARIANT_LABELS = {"raw": "raw", "bias_only": "bias only", "full": "full", "plain_reference": "plain ref.",
                  "imu_tk": "imu_tk", "imucal": "imucal", "mag_calibrated": "calib mag",
                  "full_mag_calibrated": "full + calib mag"}
# figure key → label (units in the label); the keys are the JSON's
FIGURES = {
    "vqf_9d.total_rmse_deg": "VQF 9D total RMSE (°)",
    "vqf_9d.heading_rmse_deg": "VQF 9D heading RMSE (°)",
    "vqf_6d.inclination_rmse_deg": "VQF 6D inclination RMSE (°)",
    "madgwick_c2011_9d.total_rmse_deg": "Madgwick (C form) total RMSE (°)",
    "madgwick_c2011_9d.heading_rmse_deg": "Madgwick (C form) heading RMSE (°)",
    "madgwick_c2011_9d.inclination_rmse_deg": "Madgwick (C form) inclination RMSE (°)",
    "mahony_9d.total_rmse_deg": "Mahony total RMSE (°)",
    "mahony_9d.heading_rmse_deg": "Mahony heading RMSE (°)",
    "mahony_9d.inclination_rmse_deg": "Mahony inclination RMSE (°)",
    "vqf_9d_mag.heading_rmse_deg": "VQF 9D heading RMSE, magnetometer (°)",
    "rest_norm_rms_m_s2": "|f| − g at rest, RMS (m/s²)",
    "carried_gravity_rms_deg": "gravity carried across moves, RMS (°)",
    "turn_error_rms_deg": "360° turns, RMS error (°)",
}


def finite_or_nan(x: Any) -> float:
    """``x`` as a float, NaN for None."""
    return math.nan if x is None else float(x)


def _clean(x: Any) -> Any:
    """JSON-able: NaN → None, numpy → lists and floats."""
    if isinstance(x, dict):
        return {k: _clean(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_clean(v) for v in x]
    if isinstance(x, np.ndarray):
        return _clean(x.tolist())
    if isinstance(x, (float, np.floating)):
        return None if not math.isfinite(float(x)) else float(x)
    if isinstance(x, np.integer):
        return int(x)
    return x


@dataclass(frozen=True)
class RecordingResult:
    """One recording's block: the ``calib`` commands run (``runs``), the calibration applied (``calibration``:
    method, status, gyro bias rad/s, S, G with σ, the accelerometer's when estimated, the status's reasons),
    the plain reference (``plain_reference``: gyro bias rad/s and the rest it came from, s), the figures
    (figure key of :data:`FIGURES` → variant → value), details (counts, published values, peers) and notes
    (what could not be computed, and why)."""

    name: str
    kind: str
    reference: str
    samples: int
    duration_s: float
    runs: tuple[CliRun, ...] = ()
    calibration: dict[str, Any] = field(default_factory=dict)
    plain_reference: dict[str, Any] = field(default_factory=dict)
    figures: dict[str, dict[str, float]] = field(default_factory=dict)
    details: dict[str, Any] = field(default_factory=dict)
    notes: tuple[str, ...] = ()
    seconds: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        return _clean({"name": self.name, "kind": self.kind, "reference": self.reference, "samples": self.samples,
                       "duration_s": self.duration_s, "runs": [r.to_dict() for r in self.runs],
                       "calibration": self.calibration, "plain_reference": self.plain_reference,
                       "figures": self.figures, "details": self.details, "notes": list(self.notes),
                       "seconds": self.seconds})

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "RecordingResult":
        figures = {k: {v: finite_or_nan(x) for v, x in vs.items()} for k, vs in d.get("figures", {}).items()}
        return cls(d["name"], d["kind"], d.get("reference", ""), int(d["samples"]), float(d["duration_s"]),
                   tuple(CliRun.from_dict(r) for r in d.get("runs", [])), dict(d.get("calibration", {})),
                   dict(d.get("plain_reference", {})), figures, dict(d.get("details", {})),
                   tuple(d.get("notes", [])), float(d.get("seconds", 0.0)))


@dataclass(frozen=True)
class MeasuredValidation:
    """Every recording with a reference in a data folder, judged by what the user does next
    (:func:`calib.scoring.measured.validate`): per recording a :class:`RecordingResult`; over the BROAD
    trials the medians (:func:`broad_medians`); wall and CPU time (s, the CPU time of this process and
    of the ``calib`` commands it ran); the calib version that ran."""

    recordings: tuple[RecordingResult, ...]
    medians: dict[str, dict[str, float]]
    seconds: float
    cpu_seconds: float
    calib_version: str
    failed: tuple[str, ...] = ()

    @property
    def ok(self) -> bool:
        """Every recording found was scored (whatever calib's statuses were: those are the measurement)."""
        return not self.failed

    def to_dict(self) -> dict[str, Any]:
        return _clean({"format": "calib.measured_validation/1", "calib_version": self.calib_version,
                       "seconds": self.seconds, "cpu_seconds": self.cpu_seconds, "failed": list(self.failed),
                       "recordings": [r.to_dict() for r in self.recordings], "medians_over_broad": self.medians})

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "MeasuredValidation":
        medians = {k: {m: finite_or_nan(x) for m, x in v.items()} for k, v in d.get("medians_over_broad", {}).items()}
        return cls(tuple(RecordingResult.from_dict(r) for r in d["recordings"]), medians, float(d["seconds"]),
                   float(d["cpu_seconds"]), d.get("calib_version", ""), tuple(d.get("failed", [])))


def _summary(cal_json: Path) -> dict[str, Any]:
    """The parameters a calibration file states (its promised keys), with the warnings behind its status."""
    d = json.loads(cal_json.read_text())
    gyro = d.get("gyro", {})
    applied = d.get("applied")   # what calib apply applies (absent in a file written before the block existed)
    shown = applied if isinstance(applied, dict) else d   # the values calib apply uses
    out: dict[str, Any] = {"method": d.get("method"), "status": d.get("status")}
    for prefix, block in (("", gyro), ("applied_", shown.get("gyro", {}))):   # the estimate; what calib apply uses
        for key in ("bias_rad_s", "scale_factor", "nonorthogonality", "misalignment_rad"):
            out[f"{prefix}gyro_{key}"] = block.get(key)
            out[f"{prefix}gyro_{key}_std"] = block.get("std", {}).get(key)
    acc = d.get("accelerometer")
    applied_acc = shown.get("accelerometer") if isinstance(applied, dict) else None
    prior_acc = bool(applied_acc) and any(v for key in ("bias_m_s2", "scale_factor", "nonorthogonality")
                                          for v in applied_acc.get(key) or ())
    out["accelerometer"] = "estimated" if acc else ("from the prior" if prior_acc else "assumed calibrated")
    if acc or prior_acc:
        for key in ("bias_m_s2", "scale_factor", "nonorthogonality"):
            out[f"acc_{key}"] = (applied_acc or acc).get(key)
    out["gravity_m_s2"] = d.get("noise", {}).get("gravity_m_s2")
    if isinstance(applied, dict):
        out["applied"] = applied.get("summary")
        out["gyro_sg_applied"] = [bool(v) for key in ("scale_factor", "nonorthogonality")
                                  for v in (applied.get("gyro", {}).get("from_session", {}).get(key) or [])]
        out["gyro_sg_determined"] = [bool(v) for key in ("scale_factor", "nonorthogonality")
                                     for v in (gyro.get("determined", {}).get(key) or [])]
        out["motion"] = (d.get("motion") or {}).get("kind")
    out["status_reasons"] = [w for w in d.get("warnings", []) if w.startswith(("inconsistent", "diverged"))]
    return out


@dataclass(frozen=True)
class CalibratedVariants:
    """What ``calib run`` + ``calib apply`` gave for one recording: the runs, the calibration's summary
    ({} when none was written), and the recordings of :data:`VARIANTS` (``full`` and ``bias_only`` absent
    when there is no calibration or no applied file)."""

    runs: tuple[CliRun, ...]
    calibration: dict[str, Any]
    recordings: dict[str, Recording]
    plain_reference: dict[str, Any]
    notes: tuple[str, ...]


def calibrate_variants(raw: Recording, source: str, shown: str, data_dir: Path, workdir: Path,
                       first_rest: tuple[int, int] | None, extra: tuple[str, ...] = ()) -> CalibratedVariants:
    """Run ``calib run`` (and its retry; ``extra``: its further options) and ``calib apply`` on ``source``; build the
    variants from ``raw`` (the same recording as loaded here) and ``first_rest`` (sample range of the plain
    reference's bias)."""
    runs, cal = run_calibration(source, shown, data_dir, workdir, extra)
    recs: dict[str, Recording] = {"raw": raw}
    notes: list[str] = []
    summary: dict[str, Any] = {}
    if cal is None:
        notes.append(f"calib run wrote no calibration (exit {runs[-1].exit_code}): no bias-only or full variant")
    else:
        summary = _summary(cal)
        bias = np.array([finite_or_nan(x) for x in summary.get("gyro_bias_rad_s") or [None] * 3])
        if np.isfinite(bias).all():
            recs["bias_only"] = raw.with_signals(gyro_rad_s=raw.gyro_rad_s - bias)
        else:
            notes.append("the calibration states no finite gyro bias: no bias-only variant")
        run, comp = apply_calibration(cal, source, shown, data_dir, workdir)
        runs = runs + (run,)
        if comp is None:
            notes.append(f"calib apply wrote no file (exit {run.exit_code}): no full variant")
        else:
            full = load_hdf5(comp)
            if full.n != raw.n or not np.allclose(full.t_s, raw.t_s, rtol=0, atol=1e-9):
                notes.append(f"calib apply changed the samples ({raw.n} → {full.n}): the full variant is not scored")
            else:
                recs["full"] = full
    plain: dict[str, Any] = {}
    if first_rest is None:
        notes.append("no static interval found: no plain reference")
    else:
        s, e = first_rest
        b = raw.gyro_rad_s[s:e + 1].mean(axis=0)
        recs["plain_reference"] = raw.with_signals(gyro_rad_s=raw.gyro_rad_s - b)
        plain = {"gyro_bias_rad_s": b.tolist(), "rest_s": [float(raw.t_s[s]), float(raw.t_s[e])]}
    return CalibratedVariants(runs, summary, recs, plain, tuple(notes))


def broad_medians(recordings: tuple[RecordingResult, ...] | list[RecordingResult]) -> dict[str, dict[str, float]]:
    """Per BROAD figure, over the trials where both variants exist: the median change (%) of bias-only and
    full against raw and of full against bias-only, and on how many trials full is worse than raw."""
    out: dict[str, dict[str, float]] = {}
    broad = [r for r in recordings if r.kind == "broad"]
    for key in FIGURES:
        rows = [r.figures[key] for r in broad if key in r.figures]
        if not rows:
            continue
        entry: dict[str, float] = {}
        for label, new, old in (("bias_only_vs_raw_pct", "bias_only", "raw"), ("full_vs_raw_pct", "full", "raw"),
                                ("full_vs_bias_only_pct", "full", "bias_only"),
                                ("mag_calibrated_vs_raw_pct", "mag_calibrated", "raw")):
            pairs = [(f.get(new, math.nan), f.get(old, math.nan)) for f in rows]
            pct = [100.0 * (a - b) / b for a, b in pairs if math.isfinite(a) and math.isfinite(b) and b > 0]
            if pct:
                entry[label] = float(np.median(pct))
                if label in ("full_vs_raw_pct", "mag_calibrated_vs_raw_pct"):
                    entry[label.replace("_vs_raw_pct", "_worse_than_raw")] = float(sum(p > 0 for p in pct))
                    entry[label.replace("_vs_raw_pct", "_trials")] = float(len(pct))
        out[key] = entry
    return out
