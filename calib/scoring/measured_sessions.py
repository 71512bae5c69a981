"""Recordings without an orientation reference, judged at their rests (for :mod:`calib.scoring.measured`).

* **imu_tk's Xsens session** (``dataset:imu_tk_xsens``, raw counts): imu_tk's two figures
  (:mod:`calib.scoring.measured_statics`) for every variant, beside imu_tk's own result on the session.
* **imucal's Ferraris session** (``dataset:imucal_ferraris``): the same two figures at the rests the
  detector finds, the error of the protocol's three 360° turns (Σ ω Δt about the turn's axis, imucal's
  measure), and our parameters beside imucal's (:mod:`calib.scoring.measured_imucal`).
* **x-io sessions** (``dataset:xio_fusion``, ``dataset:xio_ximu_thermometer``): the held-out check — the
  gravity direction at each rest predicted by carrying the previous rest's through the gyro (imu_tk's gyro
  figure) — and |f| − g at the rests.  The x-IMU's own quaternion is not used as a reference: it is the
  output of the x-IMU's AHRS (Mahony-type, k_P = 0.5, with the magnetometer; its register file) computed
  from the same factory-calibrated signals, so agreeing with it measures closeness to the factory
  calibration, not correctness, and on this hand-held session its accelerometer correction is driven by
  accelerations of up to 13 m/s².

The detector's threshold comes from the first ``init`` samples, which must be a rest: imu_tk's 50 s on its
session; 2 s on the others (each starts still — on the x-IMU session held in the hand, so its "rests" are
hand-held and the figures include the hand's small motion during them).
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from gyrosim.loaders import load_dataset
from gyrosim.recording import Recording
from gyrosim.units import G0

from calib.scoring.measured_imucal import ImucalResult, imucal_ferraris
from calib.scoring.measured_result import VARIANTS, RecordingResult, calibrate_variants
from calib.scoring.measured_statics import (
    StaticDetector,
    carried_gravity_errors_deg,
    rest_norm_rms,
    static_intervals,
)

__all__ = ["IMU_TK_PUBLISHED", "validate_imu_tk", "validate_ferraris", "validate_xio", "static_figures"]

# imu_tk's own result on its Xsens session (test_imu_calib, github.com/Kyle-ak/imu_tk @ 7780270f, built and run
# on this session by the project, its calibrated output scored with the two figures as computed here): the
# accelerometer figure against its g = 9.81744 m/s², the gyro figure over the same 37 moves
IMU_TK_PUBLISHED = {"rest_norm_rms_m_s2": 0.00795, "carried_gravity_rms_deg": 0.517}
IMU_TK_GRAVITY_M_S2 = 9.81744  # test_imu_calib's setGravityMagnitude
TURNS = ("x_rot", "y_rot", "z_rot")
FERRARIS_RUN = ("--protocol", "ferraris")   # what a user of imucal's session knows and tells calib run


def static_figures(rec: Recording, intervals: list[tuple[int, int]], first_n: int, gravity_m_s2: float) -> dict:
    """imu_tk's two figures of ``rec`` on ``intervals``: |f| − g RMS (m/s²) over the first ``first_n``
    samples of each, and the RMS (°) of the gravity direction carried across the moves between them."""
    err = carried_gravity_errors_deg(rec.acc_m_s2, rec.gyro_rad_s, rec.t_s, intervals)
    return {"rest_norm_rms_m_s2": rest_norm_rms(rec.acc_m_s2, intervals, first_n, gravity_m_s2),
            "carried_gravity_rms_deg": float(np.sqrt(np.mean(err**2))) if err.size else math.nan}


def _gravity(variant: str, calibration: dict) -> float:
    """The g a variant's accelerometer is judged against: the calibration's for the applied file, else the
    loaders' nominal g₀ (each loader scales its accelerometer to standard g units)."""
    g = calibration.get("gravity_m_s2") if variant == "full" else None
    return float(g) if g else G0


def _session(name: str, data_dir: Path, workdir: Path, detector_for, extra: tuple[str, ...] = ()) -> tuple:
    raw = load_dataset(name, data_dir)
    detector = detector_for(raw)
    intervals = static_intervals(raw.acc_m_s2, detector)
    cv = calibrate_variants(raw, f"dataset:{name}", f"dataset:{name}", data_dir, workdir,
                            intervals[0] if intervals else None, extra)
    figures: dict[str, dict[str, float]] = {}
    for variant in VARIANTS:
        rec = cv.recordings.get(variant)
        got = static_figures(rec, intervals, detector.min_samples, _gravity(variant, cv.calibration)) if rec else {}
        for key in ("rest_norm_rms_m_s2", "carried_gravity_rms_deg"):
            figures.setdefault(key, {})[variant] = got.get(key, math.nan)
    details = {"static_intervals": len(intervals), "moves": max(len(intervals) - 1, 0),
               "rest_samples": len(intervals) * detector.min_samples,
               "detector": {"window": detector.window, "multiplier": detector.multiplier, "init": detector.init,
                            "min_samples": detector.min_samples}}
    return raw, intervals, detector, cv, figures, details


def validate_imu_tk(data_dir: Path, workdir: Path) -> RecordingResult:
    """imu_tk's Xsens session: imu_tk's two figures for every variant beside imu_tk's own."""
    t0 = time.perf_counter()
    raw, intervals, _, cv, figures, details = _session("imu_tk_xsens", data_dir, workdir,
                                                       lambda rec: StaticDetector.imu_tk())
    for key, value in IMU_TK_PUBLISHED.items():
        figures[key]["imu_tk"] = value
    details["imu_tk_gravity_m_s2"] = IMU_TK_GRAVITY_M_S2
    notes = cv.notes + ("imu_tk: its own calibration of this session (its test program, built and run by the project), "
                        f"scored the same way; its |f| − g against its g = {IMU_TK_GRAVITY_M_S2} m/s²",)
    return RecordingResult("imu_tk_xsens", "imu_tk", "static poses (imu_tk's two figures)", raw.n, raw.duration_s,
                           cv.runs, cv.calibration, cv.plain_reference, figures, details, notes,
                           round(time.perf_counter() - t0, 1))


def _turn_errors_deg(gyro_rad_s: np.ndarray, t_s: np.ndarray, segments: dict) -> list[float]:
    """|Σ ω Δt about the turn's axis| − 360° for each of the protocol's turns (x, y, z)."""
    out = []
    for axis, key in enumerate(TURNS):
        s, e = int(segments[key]["start"]), int(segments[key]["end"])
        dt = np.diff(t_s[s:e + 1])
        angle = math.degrees(float(np.sum(0.5 * (gyro_rad_s[s:e, axis] + gyro_rad_s[s + 1:e + 1, axis]) * dt)))
        out.append(abs(angle) - 360.0)
    return out


def _ferraris_extra(raw: Recording, intervals, detector, cv, figures, details, data_dir: Path) -> list[str]:
    segments = raw.meta["segments"]
    figures["turn_error_rms_deg"] = {}
    for variant in VARIANTS:
        rec = cv.recordings.get(variant)
        figures["turn_error_rms_deg"][variant] = (float(np.sqrt(np.mean(np.square(
            _turn_errors_deg(rec.gyro_rad_s, rec.t_s, segments))))) if rec else math.nan)
    peer = imucal_ferraris(data_dir / "imucal_ferraris")
    if isinstance(peer, str):
        return [peer]
    assert isinstance(peer, ImucalResult)
    rec = raw.with_signals(gyro_rad_s=peer.gyro_rad_s, acc_m_s2=peer.acc_m_s2)
    for key, value in static_figures(rec, intervals, detector.min_samples, G0).items():
        figures[key]["imucal"] = value
    figures["turn_error_rms_deg"]["imucal"] = float(np.sqrt(np.mean(np.square(
        _turn_errors_deg(rec.gyro_rad_s, rec.t_s, segments)))))
    details["imucal"] = peer.to_dict()
    return ["imucal fits its gyro to these three turns: its turn figure is in-sample"]


def validate_ferraris(data_dir: Path, workdir: Path) -> RecordingResult:
    """imucal's Ferraris session: the rest figures and the 360° turns for every variant and imucal's result."""
    t0 = time.perf_counter()
    raw, intervals, detector, cv, figures, details = _session(
        "imucal_ferraris", data_dir, workdir, lambda rec: StaticDetector.for_rate(rec.rate_hz), FERRARIS_RUN)
    notes = _ferraris_extra(raw, intervals, detector, cv, figures, details, data_dir)
    notes.append(f"calib run was told the protocol ({' '.join(FERRARIS_RUN)}): the three turns enter it as "
                 "known angles, so its turn figure is in-sample too; the six box-face poses give its accelerometer")
    return RecordingResult("imucal_ferraris", "imucal", "Ferraris protocol (rests, 360° turns)", raw.n,
                           raw.duration_s, cv.runs, cv.calibration, cv.plain_reference, figures, details,
                           cv.notes + tuple(notes), round(time.perf_counter() - t0, 1))


def validate_xio(name: str, data_dir: Path, workdir: Path) -> RecordingResult:
    """An x-io session: the held-out gravity check and |f| − g at the rests for every variant."""
    t0 = time.perf_counter()
    raw, _, _, cv, figures, details = _session(name, data_dir, workdir,
                                               lambda rec: StaticDetector.for_rate(rec.rate_hz))
    notes = cv.notes
    if details["moves"] < 1:
        notes += ("fewer than two rests: no held-out check",)
    if name == "xio_ximu_thermometer":
        notes += ("the x-IMU's own quaternion is not a reference (its AHRS on the same factory-calibrated signals); "
                  "its rests are hand-held",)
    return RecordingResult(name, "xio", "held out: gravity carried from rest to rest", raw.n, raw.duration_s,
                           cv.runs, cv.calibration, cv.plain_reference, figures, details, notes,
                           round(time.perf_counter() - t0, 1))
