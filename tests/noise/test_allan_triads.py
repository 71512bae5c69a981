"""calib allan on both triads: SI and display units, an undetermined term said so (never ± inf), a temperature
drift flagged; its JSON is what the Kalibr export takes the noise from; calib apply/export read the demo's
report.json."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import yaml

from gyrosim.calibration import Calibration
from gyrosim.effects import Bias, WhiteNoise
from gyrosim.errors import GyrosimError
from gyrosim.exchange import kalibr_imu_yaml
from gyrosim.recording import Recording, save_hdf5

from calib.app.cli import main as calib_main
from calib.noise.allan_triads import TEMPERATURE_DRIFT_C, allan_triads, read_kalibr_noise

RATE = 100.0
N_GYRO, N_ACC = 2e-4, 3e-3  # white noise densities: rad/s/√Hz, m/s²/√Hz


def _static(seconds: float = 600.0, temp_span_c: float = 0.0, tempco_rad_s_c: float = 0.0, seed: int = 3):
    """A static board, white noise only on both triads (per-sample σ = N·√f_s), the temperature a ramp of
    ``temp_span_c`` with the gyro bias following it by ``tempco_rad_s_c`` per °C."""
    rng = np.random.default_rng(seed)
    n = int(seconds * RATE)
    t = np.arange(n) / RATE
    temp = 25.0 + temp_span_c * t / t[-1]
    gyro = rng.normal(0.0, N_GYRO * math.sqrt(RATE), (n, 3)) + tempco_rad_s_c * (temp - 25.0)[:, None]
    acc = rng.normal(0.0, N_ACC * math.sqrt(RATE), (n, 3)) + np.array([0.0, 0.0, 9.81])
    return Recording(t_s=t, gyro_rad_s=gyro, acc_m_s2=acc, temp_c=temp)


def test_both_triads_are_measured_and_a_short_record_does_not_determine_k():
    res = allan_triads(_static())
    d = res.to_dict()
    # 600 s at 100 Hz pooled over 3 axes: N's Allan fit is within a few % (the fit's own 1σ is < 1 %); 10 % is
    # far outside its error and far inside a wrong unit (√2, 60, 2π)
    for triad, n_true in (("gyro", N_GYRO), ("accelerometer", N_ACC)):
        nd = d["triads"][triad]["noise_density"]
        assert nd["determined"] and nd["value"] == pytest.approx(n_true, rel=0.1)
    # white noise alone: K is not there; its bound is finite and said, never a σ of inf
    assert "inf" not in json.dumps(d).lower() and "nan" not in json.dumps(d).lower()
    for triad in ("gyro", "accelerometer"):
        k = d["triads"][triad]["random_walk"]
        if not k["determined"]:
            assert k["value"] is None and math.isfinite(k["upper_2sigma"]) and k["upper_2sigma"] > 0
    assert res.kalibr()["gyroscope_noise_density"] == pytest.approx(N_GYRO, rel=0.1)
    assert res.warnings == ()  # constant temperature: no flag


def test_a_temperature_drift_is_flagged_with_the_bias_it_explains():
    tempco = math.radians(0.02)  # 0.02 °/s per °C, a MEMS gyro's order
    res = allan_triads(_static(temp_span_c=15.0, tempco_rad_s_c=tempco))
    assert res.temperature.flagged and res.temperature.span_c == pytest.approx(15.0 * 0.98, rel=0.01)
    # the bias change the temperature explains: 0.02 °/s/°C × 14.7 °C (1st–99th percentile span); block means of
    # 1200 samples each carry white noise of 0.0011 °/s, far below the 0.29 °/s explained
    assert math.degrees(res.temperature.bias_change["gyro"]) == pytest.approx(0.02 * 15.0 * 0.98, rel=0.02)
    (w,) = res.warnings
    assert "temperature changed by 14.7 °C" in w and "upper bounds" in w and "calib temperature" in w
    assert TEMPERATURE_DRIFT_C < 14.7


def test_calib_allan_prints_both_triads_without_inf_and_writes_the_json(tmp_path, capsys):
    rec = save_hdf5(_static(seconds=300.0, temp_span_c=5.0, tempco_rad_s_c=math.radians(0.01)), tmp_path / "s.h5")
    assert calib_main(["allan", str(rec), "--json", str(tmp_path / "noise.json")]) == 0
    out = capsys.readouterr().out
    assert "gyro:" in out and "accelerometer:" in out and "inf" not in out
    assert "°/√h" in out and "rad/s/sqrt(Hz)" in out and "µg/√Hz" in out and "m/s^2/sqrt(Hz)" in out
    assert "warning: the temperature changed by" in out
    noise = read_kalibr_noise(tmp_path / "noise.json")
    assert set(noise) == {"gyroscope_noise_density", "gyroscope_random_walk", "accelerometer_noise_density",
                          "accelerometer_random_walk"}


def _calibration(random_walk: bool = False) -> Calibration:
    gyro = (Bias(np.array([1e-3, 0.0, 0.0])), WhiteNoise(np.full(3, 1e-4)))
    acc = (Bias(np.zeros(3)), WhiteNoise(np.full(3, 2e-3)))
    return Calibration(gyro=gyro, accelerometer=acc, method="test", diagnostics={"filter": {"rate_hz": 100.0}})


def test_kalibr_export_takes_the_noise_file_and_the_options_win():
    noise = {"gyroscope_noise_density": 1.5e-4, "gyroscope_random_walk": 3e-6, "accelerometer_noise_density": None,
             "accelerometer_random_walk": 4e-5}
    y = yaml.safe_load(kalibr_imu_yaml(_calibration(), 100.0, noise=noise))
    # the noise file's numbers where it has them, the calibration's own white noise where it has none
    assert (y["gyroscope_noise_density"], y["gyroscope_random_walk"]) == (1.5e-4, 3e-6)
    assert (y["accelerometer_noise_density"], y["accelerometer_random_walk"]) == (2e-3, 4e-5)
    y = yaml.safe_load(kalibr_imu_yaml(_calibration(), 100.0, noise=noise, gyro_random_walk=7e-6))
    assert y["gyroscope_random_walk"] == 7e-6
    with pytest.raises(GyrosimError, match=r"accelerometer random walk.*calib allan REC --json"):
        kalibr_imu_yaml(_calibration(), 100.0, noise={**noise, "accelerometer_random_walk": None})


def test_calib_export_reads_calib_allans_json_and_the_demo_report(tmp_path):
    cal = _calibration()
    report = {"recording": "session.h5", "seed": 1, "calibration": cal.to_dict()}  # calib demo's report.json
    (tmp_path / "report.json").write_text(json.dumps(report), encoding="utf-8")
    rec = save_hdf5(_static(seconds=200.0), tmp_path / "s.h5")
    assert calib_main(["allan", str(rec), "--json", str(tmp_path / "noise.json")]) == 0
    noise = json.loads((tmp_path / "noise.json").read_text(encoding="utf-8"))["kalibr"]
    argv = ["export", str(tmp_path / "report.json"), "--format", "kalibr", "--out", str(tmp_path / "imu.yaml"),
            "--noise", str(tmp_path / "noise.json")]
    # the white noise densities come from the noise file, the random walks from the options (which win over it)
    assert calib_main([*argv, "--gyro-random-walk", "1e-5", "--acc-random-walk", "2e-4"]) == 0
    y = yaml.safe_load((tmp_path / "imu.yaml").read_text(encoding="utf-8"))
    assert y["gyroscope_noise_density"] == pytest.approx(noise["gyroscope_noise_density"], rel=1e-6)
    assert y["accelerometer_noise_density"] == pytest.approx(noise["accelerometer_noise_density"], rel=1e-6)
    assert (y["gyroscope_random_walk"], y["accelerometer_random_walk"]) == (1e-5, 2e-4)
    # calib apply takes the demo's report.json as it is
    assert calib_main(["apply", str(tmp_path / "report.json"), str(rec), "--out", str(tmp_path / "c.h5")]) == 0


def test_a_json_that_is_no_calibration_says_what_to_pass(tmp_path):
    p = tmp_path / "x.json"
    for text in ('{"format": "something"}', "[1, 2]"):
        p.write_text(text, encoding="utf-8")
        with pytest.raises(GyrosimError, match="calib run --json"):
            Calibration.load(p)
