"""The README's main job writes its recording, report and rerun file."""

from __future__ import annotations

import json

import rerun as rr

from calib.app.cli import main as calib_main


def test_demo_writes_recording_report_and_rrd(tmp_path, capsys):
    # vertical_only never tips the board: only a calibrated accelerometer makes sense there
    assert calib_main(["demo", "--out", str(tmp_path), "--schedule", "vertical_only", "--hand", "steady",
                       "--accelerometer", "calibrated"]) == 0
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


def test_allan_command_and_library_example(tmp_path, capsys):
    import subprocess
    import sys
    from pathlib import Path

    from gyrosim.cli import main as gyrosim_main

    rec = tmp_path / "static.h5"
    assert gyrosim_main(["simulate", "--schedule", "static", "--hand", "ideal", "--sensor", "mpu9250",
                         "--seed", "2", "--out", str(rec), "--quiet"]) == 0
    assert calib_main(["allan", str(rec), "--png", str(tmp_path / "a.png")]) == 0
    out = capsys.readouterr().out
    # 60 s at 100 Hz: N is resolved (preset 0.6 °/√h, ±1 % at this length), K is not (said so, with a bound)
    n = float(out.split("N = ")[1].split()[0])
    assert abs(n / 0.6 - 1) < 0.1
    assert (tmp_path / "a.png").stat().st_size > 10_000
    example = Path(__file__).resolve().parents[2] / "examples" / "calibrate_your_imu.py"
    run = subprocess.run([sys.executable, str(example)], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    assert "error vs truth" in run.stdout
