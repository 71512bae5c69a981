"""The 9-axis virtual IMU (simulation side): MuJoCo's magnetometer on the board, the
Earth field from the World Magnetic Model or an ENU vector, dipole anomalies, the magnetometer
effects (a magnet attached to the board part of the session too), and the 6-axis results left as
they were."""

from __future__ import annotations

import math

import h5py
import numpy as np
import pytest
from conftest import session

from gyrosim.cli import main as gyrosim_main
from gyrosim.effects import AttachedMagnet, FrameRotation, HardIron, SoftIron, effect_from_dict
from gyrosim.errors import GyrosimError
from gyrosim.magnetic import Dipole, MagneticEnvironment, attached_magnet_from_text, environment_from_text
from gyrosim.recording import load_hdf5
from gyrosim.rotations import quat_conjugate, quat_rotate
from gyrosim.sensor_model import SensorModel, load_sensor, stored_sensor_model
from gyrosim.simulate import EARTH_FIELD_ENU_UT, apply_sensor, signal_context, simulate_truth, with_attached_magnet


def test_truth_field_is_the_earth_field_in_the_board_frame():
    """MuJoCo's magnetometer = C_bⁿᵀ B_ENU; only T→µT rounding (1e-13 µT) separates them."""
    rec = session("typical")
    expected = quat_rotate(quat_conjugate(rec.truth.quat_nb), EARTH_FIELD_ENU_UT)
    np.testing.assert_allclose(rec.mag_ut, expected, atol=1e-9)
    np.testing.assert_array_equal(rec.truth.extra["mag_field"], rec.mag_ut)


def test_world_magnetic_model_field_and_its_provenance():
    """WMM2025 at Munich, 2025-06-01: |B| ≈ 48.7 µT, inclination ≈ 64.4°, declination ≈ 4.2° (NOAA's
    calculator gives the same to 0.1 µT / 0.1°, the model's own accuracy is ~0.15 µT)."""
    env = MagneticEnvironment.at(48.14, 11.58, 520.0, "2025-06-01")
    assert env.magnitude_ut == pytest.approx(48.75, abs=0.3)
    assert env.inclination_deg == pytest.approx(64.4, abs=0.3)
    assert math.degrees(math.atan2(env.earth_enu_ut[0], env.earth_enu_ut[1])) == pytest.approx(4.2, abs=0.3)
    assert "WMM2025" in env.source
    south = MagneticEnvironment.at(-33.9, 18.4, 0.0, "2022-03-01")  # Cape Town: South Atlantic Anomaly, field up
    assert south.inclination_deg < -50 and south.magnitude_ut < 30 and "WMM2020" in south.source
    with pytest.raises(GyrosimError, match="2010–2030"):
        MagneticEnvironment.at(48.0, 11.0, 0.0, "1999-01-01")


def test_dipole_field_is_the_textbook_field():
    """On the axis B = μ₀/4π · 2m/r³, in the equatorial plane −μ₀/4π · m/r³; divergence-free."""
    d = Dipole([0.0, 0.0, 0.0], [0.0, 0.0, 2.0])
    r = 0.3
    on_axis = d.field_nav_ut(np.array([[0.0, 0.0, r]]))[0]
    side = d.field_nav_ut(np.array([[r, 0.0, 0.0]]))[0]
    np.testing.assert_allclose(on_axis, [0.0, 0.0, 1e-7 * 2 * 2.0 / r**3 * 1e6], rtol=1e-12)
    np.testing.assert_allclose(side, [0.0, 0.0, -1e-7 * 2.0 / r**3 * 1e6], rtol=1e-12, atol=1e-12)
    p, h = np.array([0.11, -0.07, 0.2]), 1e-5
    div = sum((d.field_nav_ut((p + h * e)[None])[0, i] - d.field_nav_ut((p - h * e)[None])[0, i]) / (2 * h)
              for i, e in enumerate(np.eye(3)))
    assert abs(div) < 1e-6 * np.linalg.norm(d.field_nav_ut(p[None])) / 0.2
    sphere = Dipole.ferrous_sphere([0, 0, 0], 0.05, [0.0, 20.0, -44.0])  # m = 4π a³ B₀/μ₀
    np.testing.assert_allclose(sphere.moment_a_m2, 0.05**3 * np.array([0.0, 20.0, -44.0]) * 1e-6 / 1e-7)


def test_a_room_anomaly_makes_the_field_depend_on_where_the_hand_is():
    """A steel sphere 0.12 m from the start point: the truth field is B_E + B_dipole(site) rotated into
    the board frame, and its magnitude changes as the hand moves (≥ 0.5 µT over the session); the
    same session without the anomaly keeps |B| constant to rounding."""
    env = environment_from_text(anomalies=["0.25,0.40,1.10,0.04"])
    rec = simulate_truth("zhou2020", "typical", 50.0, seed=3, magnetic=env)
    plain = simulate_truth("zhou2020", "typical", 50.0, seed=3)
    np.testing.assert_array_equal(rec.gyro_rad_s, plain.gyro_rad_s)  # the field does not push the hand
    q, pos = rec.truth.quat_nb, rec.truth.position_nav_m
    from gyrosim.scene import HandScene

    sc = HandScene()
    site = pos + quat_rotate(q, sc.mag_site_body_m - sc.acc_site_body_m)
    expected = quat_rotate(quat_conjugate(q), env.field_nav_ut(site))
    np.testing.assert_allclose(rec.mag_ut, expected, atol=1e-9)
    mag = np.linalg.norm(rec.mag_ut, axis=1)
    assert np.ptp(mag) > 0.5
    assert np.ptp(np.linalg.norm(plain.mag_ut, axis=1)) < 1e-9


def test_nine_axis_preset_keeps_the_six_axis_results_bit_identical():
    truth = session("typical")
    six = apply_sensor(truth, "mpu9250", np.random.default_rng(11))
    nine = apply_sensor(truth, "mpu9250_9axis", np.random.default_rng(11))
    np.testing.assert_array_equal(six.gyro_rad_s, nine.gyro_rad_s)
    np.testing.assert_array_equal(six.acc_m_s2, nine.acc_m_s2)
    assert six.mag_ut is None and nine.mag_ut is not None  # a 6-axis IMU has no /mag
    assert "magnetometer" not in six.meta["sensor_model"]
    # AK8963 16-bit output: multiples of 0.15 µT
    k = nine.mag_ut / 0.15
    assert np.abs(k - np.round(k)).max() < 1e-9


def test_magnetometer_effects_give_m_equals_A_B_plus_h():
    """Noise-free: m = A B + h with A = S + (Rᵀ − I) (error effects add, gyrosim.effects), which is
    what a calibration of m = A B + h estimates; the frame rotation is the rotation part of A."""
    ctx = signal_context(session("typical"))
    s = np.array([[1.06, 0.02, -0.03], [0.02, 0.95, 0.01], [-0.03, 0.01, 1.03]])
    model = SensorModel("mag", magnetometer=(HardIron(value=[30.0, -12.0, 55.0]), SoftIron(matrix=s),
                                             FrameRotation(angles=np.radians([1.0, -2.0, 0.5]))))
    m = model.apply_magnetometer(ctx, np.random.default_rng(0))
    rot = FrameRotation(angles=np.radians([1.0, -2.0, 0.5])).matrix()
    a = s + rot - np.eye(3)
    np.testing.assert_allclose(m, ctx.mag_body_ut @ a.T + [30.0, -12.0, 55.0], atol=1e-10)
    back = model.compensate_triad("magnetometer", m, ctx)
    np.testing.assert_allclose(back, ctx.mag_body_ut, atol=1e-10)


def test_soft_iron_draws_are_symmetric_and_preset_units_convert():
    dev = load_sensor("phone").realize(np.random.default_rng(4))
    si = next(e for e in dev.magnetometer if e.kind == "soft_iron")
    np.testing.assert_array_equal(si.matrix, si.matrix.T)
    wn = next(e for e in dev.magnetometer if e.kind == "white_noise")
    np.testing.assert_allclose(wn.density, 0.05)
    fr = next(e for e in load_sensor("mpu9250_9axis").magnetometer if e.kind == "frame_rotation")
    np.testing.assert_allclose(fr.angles_sigma, np.radians(0.5))
    with pytest.raises(GyrosimError, match="does not apply to the gyro"):
        SensorModel("bad", gyro=(HardIron(value=[1.0, 0, 0]),))


def test_simulate_cli_with_location_and_anomaly(tmp_path, capsys):
    out = tmp_path / "mag.h5"
    assert gyrosim_main(["simulate", "--schedule", "static", "--hand", "ideal", "--rate", "20", "--sensor",
                         "mpu9250_9axis", "--location", "52.5,13.3,40,2021-05-01", "--anomaly", "0.3,0.3,1.1,0.03",
                         "--out", str(out), "--quiet"]) == 0
    with h5py.File(out) as f:
        assert f["mag"].shape == f["truth/mag_field"].shape == (1201, 3)
        assert "WMM2020" in f.attrs["magnetic_field"]
    rec = load_hdf5(out)
    assert np.linalg.norm(rec.truth.extra["mag_field"], axis=1).mean() == pytest.approx(49.8, abs=1.5)
    assert gyrosim_main(["simulate", "--schedule", "static", "--mag-field", "0.2,0.25,-0.4", "--out",
                         str(tmp_path / "g.h5"), "--quiet"]) == 2
    assert "plausible field in µT" in capsys.readouterr().err


def test_attached_magnet_is_a_hard_and_soft_iron_that_switches_on_and_off():
    """Noise-free: before t_on and from t_off on, m = A B + h (the device alone); in between the
    magnet adds h_m + S_m B (it turns with the board: a body-frame term).  It serialises, undoes
    itself, and appended to a 9-axis preset leaves the device's other draws and noise as they were."""
    ctx = signal_context(session("typical"))
    magnet = AttachedMagnet(value=[8.0, -5.0, 12.0], soft_iron=np.diag([0.02, -0.01, 0.015]), t_on_s=40.0,
                            t_off_s=90.0)
    model = SensorModel("mag", magnetometer=(HardIron(value=[30.0, -12.0, 55.0]), magnet))
    m = model.apply_magnetometer(ctx, np.random.default_rng(0))
    on = (ctx.t_s >= 40.0) & (ctx.t_s < 90.0)
    b = ctx.mag_body_ut
    np.testing.assert_allclose(m[~on], b[~on] + [30.0, -12.0, 55.0], atol=1e-10)
    np.testing.assert_allclose(m[on], b[on] @ (np.eye(3) + magnet.soft_iron).T + [38.0, -17.0, 67.0], atol=1e-10)
    np.testing.assert_allclose(model.compensate_triad("magnetometer", m, ctx), b, atol=1e-10)
    assert effect_from_dict(magnet.to_dict()).to_dict() == magnet.to_dict()
    a, c = magnet.affine_at(50.0)
    np.testing.assert_array_equal(c, [8.0, -5.0, 12.0])
    np.testing.assert_array_equal(a, magnet.soft_iron)
    assert not np.any(magnet.affine_at(95.0)[1]) and magnet.affine() is None  # it changes with time
    truth = session("typical")
    plain = apply_sensor(truth, "mpu9250_9axis", np.random.default_rng(3))
    with_magnet = apply_sensor(truth, with_attached_magnet(load_sensor("mpu9250_9axis"), magnet),
                               np.random.default_rng(3))
    np.testing.assert_array_equal(plain.gyro_rad_s, with_magnet.gyro_rad_s)
    off = (truth.t_s < 40.0) | (truth.t_s >= 90.0)
    np.testing.assert_array_equal(plain.mag_ut[off], with_magnet.mag_ut[off])  # same device, same noise
    assert any(e.kind == "attached_magnet" for e in stored_sensor_model(with_magnet.meta).magnetometer)


def test_attached_magnet_text_and_bad_values():
    m = attached_magnet_from_text("12.5,1,2,3")
    assert m.t_on_s == 12.5 and m.t_off_s is None and m.value.tolist() == [1.0, 2.0, 3.0]
    assert attached_magnet_from_text("1,0,0,5,20").t_off_s == 20.0
    with pytest.raises(GyrosimError, match="T_ON,HX,HY,HZ"):
        attached_magnet_from_text("1,a,2,3")
    with pytest.raises(GyrosimError, match="expected 4 or 5"):
        attached_magnet_from_text("1,2,3")
    with pytest.raises(GyrosimError, match="after t_on_s"):
        AttachedMagnet(value=[1.0, 0, 0], t_on_s=10.0, t_off_s=5.0)
    with pytest.raises(GyrosimError, match="no magnetometer"):
        with_attached_magnet(load_sensor("mpu9250"), m)


def test_simulate_cli_attaches_a_magnet(tmp_path, capsys):
    out = tmp_path / "magnet.h5"
    assert gyrosim_main(["simulate", "--schedule", "static", "--hand", "ideal", "--rate", "20", "--sensor",
                         "mpu9250_9axis", "--attach-magnet", "30,0,0,40", "--seed", "2", "--out", str(out),
                         "--quiet"]) == 0
    rec = load_hdf5(out)
    step = rec.mag_ut[rec.t_s >= 31.0].mean(axis=0) - rec.mag_ut[rec.t_s < 29.0].mean(axis=0)
    np.testing.assert_allclose(step, [0.0, 0.0, 40.0], atol=0.5)  # at rest: the magnet's field, ± noise/√N
    assert gyrosim_main(["simulate", "--schedule", "static", "--attach-magnet", "30,0,0,40", "--out",
                         str(tmp_path / "x.h5"), "--quiet"]) == 2
    assert "needs a sensor with a magnetometer" in capsys.readouterr().err
