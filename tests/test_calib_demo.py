"""The README's main job writes its recording, report and rerun file (issue 2 part of the demo)."""

from __future__ import annotations

import json

import rerun as rr

from calib.cli import main as calib_main


def test_demo_writes_recording_report_and_rrd(tmp_path, capsys):
    assert calib_main(["demo", "--out", str(tmp_path), "--schedule", "vertical_only", "--hand", "steady"]) == 0
    assert "rerun " in capsys.readouterr().out  # says how to open the recording
    report = json.loads((tmp_path / "report.json").read_text())
    m, e = report["external_acc_rms_m_s2"]["measured"], report["external_acc_rms_m_s2"]["expected"]
    assert abs(m / e - 1) < 0.2  # same ±20% the physics tests use
    assert set(report["calibration"]["gyro"]) >= {"bias_rad_s", "scale_factor", "nonorthogonality", "std"}
    assert (tmp_path / "convergence.png").stat().st_size > 10_000
    entities = {chunk.entity_path for chunk in rr.chunk.RrdReader(str(tmp_path / "session.rrd")).stream()}
    assert {"/imu/gyro/x", "/imu/acc/z", "/world/board", "/world/arm", "/calib/P/S/x", "/calib/estimate/G/z",
            "/calib/estimate/S/x_true"} <= entities
    assert calib_main(["inspect", str(tmp_path / "session.h5")]) == 0
