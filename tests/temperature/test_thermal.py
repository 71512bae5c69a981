"""Thermal scenarios (chamber profiles, virtual rate table) and temperature compensation.

Tolerances:
* case lag: a first-order case (τ = 300 s) under a ramp of r °C/s lags by r·τ once settled
  (1.5 °C at 18 °C/h); held to 2 % (the exact discrete solution differs by < 0.1 %).
* hysteresis: the device's h·LP(dT/dt) makes heating and cooling biases differ by 2·h·r at the
  same temperature; the measured gap is compared on 10 °C-wide bins where the flicker (10 °/h)
  and white noise average to < 3 % of the 0.1 °/s gap.
* rate table: each point's bias and scale within 4σ of the device's value, σ from the window
  noise (white noise only in that device, so σ is the whole noise; a 4σ miss has p ≈ 6e-5).
* compensation: the best method ≥ 10× better than none on held-out cycles (the issue's bound).
"""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from gyrosim.chamber import load_chamber, simulate_chamber
from gyrosim.errors import PresetError, RecordingError
from gyrosim.ratetable import simulate_rate_table
from gyrosim.sensor_model import SensorModel, load_sensor

from calib.temperature.compensation import compare_methods, fit_compensation, fit_methods, split_cycles
from calib.temperature.ratetable import calibrate_rate_table, piecewise_model

SHORT = """
name = "short"
start_c = 0.0
repeat = 2
[[step]]
hold_s = 600.0
[[step]]
ramp_to_c = 40.0
rate_c_per_h = 60.0
[[step]]
hold_s = 600.0
[[step]]
ramp_to_c = 0.0
rate_c_per_h = 60.0
"""


@pytest.fixture(scope="module")
def chamber():
    return simulate_chamber("tde_cycles_003", "consumer_thermal", 1.0, seed=1)


def test_profiles_follow_their_programme(tmp_path):
    p = load_chamber("tde_cycles_003")
    assert p.duration_s == pytest.approx(5 * (3600 + 2 * 125 / 18 * 3600 + 3600))
    heat = [(a, b) for a, b, lab in p.segments() if lab == "heat"]
    assert len(heat) == 5
    a, b = heat[0]
    assert (p.ambient(b) - p.ambient(a)) / (b - a) * 3600 == pytest.approx(18.0)
    user = tmp_path / "mine.toml"
    user.write_text(SHORT)
    q = load_chamber(user)
    assert q.name == "mine" and len(q.cycle_starts_s) == 2 and q.ambient(600 + 1200) == pytest.approx(20.0)
    user.write_text(SHORT.replace("hold_s = 600.0", "hold_minutes = 10", 1))
    with pytest.raises(PresetError, match="unknown key"):
        load_chamber(user)
    user.write_text(SHORT.replace("rate_c_per_h = 60.0", "", 1))
    with pytest.raises(PresetError, match="rate_c_per_h"):
        load_chamber(user)


def test_chamber_sensor_lags_the_ramp_and_shows_heating_cooling_hysteresis(chamber):
    p = load_chamber("tde_cycles_003")
    dev = SensorModel.from_dict(json.loads(chamber.meta["sensor_model"]))
    tau = dev.thermal.case_tau_s
    rate = 18.0 / 3600.0
    mid = 3600 + 0.5 * 125 / 18 * 3600           # middle of the first heating ramp
    k = int(mid)
    assert p.ambient(chamber.t_s[k]) - chamber.temp_c[k] == pytest.approx(rate * tau, rel=0.02)
    # heating vs cooling at the same temperature: gap 2·h·LP(rate) (LP settled: τ_h ≪ ramp)
    h = next(e for e in dev.gyro if e.kind == "thermal_hysteresis").value
    heating = np.zeros(chamber.n, bool)
    cooling = np.zeros(chamber.n, bool)
    for a, b, lab in p.segments():
        m = (chamber.t_s >= a + 3 * 600) & (chamber.t_s < b)
        if lab == "heat":
            heating |= m
        elif lab == "cool":
            cooling |= m
    band = (chamber.temp_c > 15) & (chamber.temp_c < 25)
    gap = chamber.gyro_rad_s[heating & band].mean(0) - chamber.gyro_rad_s[cooling & band].mean(0)
    np.testing.assert_allclose(gap, 2 * h * rate, rtol=0.05)


def test_best_compensation_is_ten_times_better_on_held_out_cycles(chamber, tmp_path):
    cycles = split_cycles(chamber)
    fitted = fit_methods(cycles[:2])
    listed = compare_methods(cycles[:2], cycles[2:], fitted=fitted)
    rows = {r.method: r for r in listed}
    none = rows["none"]
    best = min(rows.values(), key=lambda r: r.bias_stability_deg_h)
    assert best.method == "polynomial+dT/dt"  # the device has hysteresis: only this method models it
    assert none.bias_stability_deg_h / best.bias_stability_deg_h >= 10
    assert none.held_out_rms_deg_s / best.held_out_rms_deg_s >= 10
    assert rows["polynomial+dT/dt"].held_out_rms_deg_s < 0.5 * rows["polynomial"].held_out_rms_deg_s
    for m in ("polynomial", "piecewise_linear", "rbf"):
        assert rows[m].held_out_rms_deg_s < 0.1 * none.held_out_rms_deg_s
    # the same comparison as a recording (what its viewer opens on): every model's residual in one view per axis on one
    # y range, the whole chamber run on x, the held-out cycles marked, the story names the best model
    from gyrosim.viewer import read_blueprint, read_texts

    from calib.app.rerun_temperature import save_temperature_rrd

    held = [(float(c.t_s[0]), float(c.t_s[-1])) for c in cycles[2:]]
    path = save_temperature_rrd(tmp_path / "t.rrd", chamber, fitted, listed, held, "2 cycles")
    views = {v.origin: v for v in read_blueprint(path)}
    res = [views[f"temperature/residual/{a}"] for a in "xyz"]
    assert res[0].y_range == res[1].y_range == res[2].y_range
    assert all(v.time_ranges["sensor_time"] == (chamber.t_s[0], chamber.t_s[-1]) for v in res)
    assert {views[f"temperature/vs_temp/{a}"].kind for a in "xyz"} == {"BarChart"}
    assert "Best: **polynomial+dT/dt**" in read_texts(path)["story"]


def test_compensated_recording_is_a_new_file_and_flattens_the_bias(chamber, tmp_path):
    from gyrosim.recording import load_hdf5, save_hdf5

    from calib.app.cli import main

    src = save_hdf5(chamber, tmp_path / "ch.h5")
    before = src.read_bytes()
    out = tmp_path / "comp.h5"
    assert main(["temperature", str(src), "--compensate", "polynomial+dT/dt", "--out", str(out)]) == 0
    comp = load_hdf5(out)
    assert src.read_bytes() == before
    assert comp.meta["temperature_compensation"]["method"] == "polynomial+dT/dt"
    held = chamber.t_s >= chamber.meta["chamber"]["cycle_starts_s"][2]
    assert np.std(comp.gyro_rad_s[held], axis=0).max() < 0.1 * np.std(chamber.gyro_rad_s[held], axis=0).min()
    assert main(["temperature", str(src), "--compensate", "rbf", "--out", str(src)]) == 2


def test_rate_table_recovers_bias_and_scale_at_each_point_within_noise():
    base = load_sensor("consumer_thermal")
    white_only = replace(base, gyro=tuple(e for e in base.gyro if e.kind != "bias_instability"))
    rec = simulate_rate_table("points_001", white_only, 100.0, seed=3)
    dev = SensorModel.from_dict(json.loads(rec.meta["sensor_model"]))
    g = {e.kind: e for e in dev.gyro}
    points = calibrate_rate_table(rec)
    assert [round(p.ambient_c) for p in points] == [-10, 5, 20, 30, 40]
    for p in points:
        d = p.temp_c - g["temperature_bias"].t_ref_c
        c = g["temperature_bias"].coefficients
        b_true = g["bias"].value + c[:, 0] * d + c[:, 1] * d**2
        s_true = g["scale_factor"].value + g["temperature_scale"].coefficients[:, 0] * d
        assert np.all(np.abs(p.bias_rad_s - b_true) < 4 * p.bias_sigma), (p.ambient_c, p.bias_rad_s, b_true)
        assert np.all(np.abs(p.scale - s_true) < 4 * p.scale_sigma), (p.ambient_c, p.scale, s_true)
    pwl = piecewise_model(points)
    assert pwl.kind == "temperature_pwl" and pwl.points_c.size == 5


def test_closeloop_names_temperature_on_an_undeclared_thermal_drift(tmp_path):
    from calib.closeloop import run_closeloop
    from calib.closeloop.report import write_closeloop_report

    prof = tmp_path / "short.toml"
    prof.write_text(SHORT)
    rec = simulate_chamber(load_chamber(prof), "consumer_thermal", 1.0, seed=4)
    res = run_closeloop(rec)
    assert res.reference in ("truth", "static")  # the board is fixed: its truth is the zero rate
    assert res.found and res.found[0].effect in ("temperature_bias", "temperature_pwl", "temperature_rbf",
                                                 "thermal_hysteresis")
    assert res.error_after["held_out_residual_rms"] < 0.2 * res.error_before["held_out_residual_rms"]
    write_closeloop_report(tmp_path / "cl", rec, res)
    md = (tmp_path / "cl" / "report.md").read_text()
    assert "## Error on held-out data" in md and "the temperature" in md


def test_bad_temperature_input_gets_a_clear_answer(chamber, tmp_path):
    from calib.inputs import load_recording

    temp = np.array(chamber.temp_c)
    temp[100] = np.nan
    with pytest.raises(RecordingError, match="NaN"):
        fit_compensation(chamber.with_signals(temp_c=temp), "polynomial")
    flat = chamber.with_signals(temp_c=np.full(chamber.n, 25.0))
    with pytest.raises(RecordingError, match="too small"):
        fit_compensation(flat, "rbf")
    with pytest.raises(RecordingError, match="unknown temperature method"):
        fit_compensation(chamber, "spline")
    # a thermometer at 1/10 of the inertial rate: empty cells, resampled with a note
    csv = tmp_path / "slow_temp.csv"
    rows = ["t,gyro_x,gyro_y,gyro_z,acc_x,acc_y,acc_z,temp"]
    for k in range(200):
        rows.append(f"{k * 0.01},0,0,0,0,0,9.81," + (f"{20 + 0.01 * k}" if k % 10 == 0 else ""))
    csv.write_text("\n".join(rows))
    rec = load_recording(csv)
    assert np.all(np.isfinite(rec.temp_c)) and rec.temp_c[5] == pytest.approx(20.05)
    assert "resampled" in rec.meta["temperature_note"]


def test_gyrosim_commands_write_thermal_recordings(tmp_path):
    from gyrosim.cli import main

    prof = tmp_path / "short.toml"
    prof.write_text(SHORT)
    assert main(["chamber", "--profile", str(prof), "--out", str(tmp_path / "c.h5")]) == 0
    assert main(["chamber", "--profile", "nope", "--out", str(tmp_path / "c.h5")]) == 2
