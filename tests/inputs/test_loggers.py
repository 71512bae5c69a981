"""The user's files read as they are: the headers of common loggers, units in column names, a column
mapping, and what is refused (an ambiguous header, a mapping naming a missing column, a unit conflict).

Every fixture is written here from 400 rows (4 s at 100 Hz, while the hand turns) of a simulated
zhou2020 session, in the logger's own units and layout, and read back: the test checks the values,
not only that the file parses.  Tolerances follow from how the fixture is written: ``%.9g`` keeps 9
significant digits, so a value converted back to SI differs from the simulated one by at most
5e-9 of itself (relative) — rtol 1e-8; a unit conversion adds float rounding (≈1e-16) only.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import session

from gyrosim.loaders import available_datasets, data_root, load_xio_fusion, load_xio_thermometer
from gyrosim.recording import Recording, save_csv
from gyrosim.units import DEG, G0

from calib.inputs import FormatError, UnitError, open_recording, read_recording
from calib.inputs.columns import parse_columns, resolve_columns, split_name

RTOL = 1e-8  # %.9g: 9 significant digits


@pytest.fixture(scope="module")
def rec() -> Recording:
    s = session("typical")
    k = slice(1000, 1400)
    return Recording(s.t_s[k] - s.t_s[1000], s.gyro_rad_s[k], s.acc_m_s2[k], mag_ut=s.mag_ut[k])


def _write(path, header: list[str], cols: list[np.ndarray], sep: str = ",", fmt: str = "%.9g",
           text_cols: dict[int, str] | None = None) -> None:
    data = np.column_stack(cols)
    rows = []
    for r in data:
        cells = [fmt % v for v in r]
        for j, txt in sorted((text_cols or {}).items()):
            cells.insert(j, txt)
        rows.append(sep.join(cells))
    path.write_text(sep.join(header) + "\n" + "\n".join(rows) + "\n")


def _same(got: Recording, want: Recording, mag: bool = True) -> None:
    np.testing.assert_allclose(got.gyro_rad_s, want.gyro_rad_s, rtol=RTOL, atol=1e-12)
    np.testing.assert_allclose(got.acc_m_s2, want.acc_m_s2, rtol=RTOL, atol=1e-12)
    if mag:
        np.testing.assert_allclose(got.mag_ut, want.mag_ut, rtol=RTOL, atol=1e-12)


# ------------------------------------------------------------------ names and units
@pytest.mark.parametrize("name, key, unit", [
    ("Gyroscope X (deg/s)", "gyroscope_x", "deg/s"), ("gx_dps", "gx", "dps"), ("imu.gyro.x", "imu_gyro_x", None),
    ("timestamp_ms", "timestamp", "ms"), ("acc_x [m/s^2]", "acc_x", "m/s^2"), ("mag_x_uT", "mag_x", "ut"),
    ("%time", "time", None), ("field.angular_velocity.x", "field_angular_velocity_x", None),
    ("Time since start in ms ", "time_since_start_in", "ms"), ("mag_x", "mag_x", None), ("t_s", "t", "s"),
])
def test_a_column_name_splits_into_its_channel_key_and_unit(name, key, unit):
    assert split_name(name) == (key, unit)


def test_the_columns_option_parses_and_refuses_what_it_cannot_use():
    assert parse_columns("t=timestamp_ms, gyro_x=gx_dps,acc_z=Az (g)") == {
        "t": "timestamp_ms", "gyro_x": "gx_dps", "acc_z": "Az (g)"}
    for bad, msg in (("gyro_x", r"not channel=column"), ("gyro_w=gw", r"'gyro_w' is not a channel"),
                     ("t=a,t=b", r"t is given twice"), ("t=a,,gyro_x=b", r"an empty item"),
                     ("t=a,gyro_x=A", r"column 'A' is given to several channels"), ("t=", r"t= names no column")):
        with pytest.raises(FormatError, match=msg):
            parse_columns(bad)


# ------------------------------------------------------------------ calib's own CSV, with and without units
def test_calib_apply_csv_has_units_in_its_header_and_reads_back_exactly(rec, tmp_path):
    with_temp = rec.with_signals(temp_c=np.linspace(20.0, 21.0, rec.n))
    p = save_csv(with_temp, tmp_path / "out.csv")
    assert p.read_text().splitlines()[0] == ("t_s,gyro_x_rad_s,gyro_y_rad_s,gyro_z_rad_s,acc_x_m_s2,acc_y_m_s2,"
                                             "acc_z_m_s2,temp_c,mag_x_ut,mag_y_ut,mag_z_ut")
    got, info = read_recording(p)
    for a, b in ((got.t_s, rec.t_s), (got.gyro_rad_s, rec.gyro_rad_s), (got.acc_m_s2, rec.acc_m_s2),
                 (got.mag_ut, rec.mag_ut), (got.temp_c, with_temp.temp_c)):
        assert np.array_equal(a, b)          # %.17g: float64 round-trips exactly
    assert info.time_unit == "s" and not info.ignored_columns
    assert not any("units from the header" in n for n in info.notes)  # SI as calib's default: nothing to say


def test_the_old_plain_header_still_reads(rec, tmp_path):
    p = tmp_path / "old.csv"
    _write(p, ["t", "gyro_x", "gyro_y", "gyro_z", "acc_x", "acc_y", "acc_z"], [rec.t_s, rec.gyro_rad_s, rec.acc_m_s2])
    got, info = read_recording(p)
    _same(got, rec, mag=False)
    assert info.time_unit is None and info.columns == ("t", "gyro_x", "gyro_y", "gyro_z", "acc_x", "acc_y", "acc_z")


# ------------------------------------------------------------------ loggers recognised without options
def test_tofupilot_dotted_names(rec, tmp_path):
    p = tmp_path / "tofupilot.csv"
    names = [f"imu.{s}.{a}" for s in ("gyro", "accel", "mag") for a in "xyz"]
    _write(p, ["timestamp", *names], [rec.t_s, rec.gyro_rad_s, rec.acc_m_s2, rec.mag_ut])
    got, info = read_recording(p)
    _same(got, rec)
    assert "tofupilot" in info.notes[0] and "rad/s and m/s² assumed (the header names no unit" in info.notes[0]


def test_xio_ximu3_inertial_csv_in_microseconds_degrees_and_g(rec, tmp_path):
    p = tmp_path / "Inertial.csv"
    t_us = 123_456_789 + np.round(rec.t_s * 1e6)   # the device's clock since power-on, whole µs
    header = ["Timestamp (us)"] + [f"Gyroscope {a} (deg/s)" for a in "XYZ"] + [f"Accelerometer {a} (g)" for a in "XYZ"]
    _write(p, header, [t_us, rec.gyro_rad_s / DEG, rec.acc_m_s2 / G0])
    loaded = open_recording(p)
    got = loaded.recording
    _same(got, rec, mag=False)
    np.testing.assert_allclose(got.t_s - got.t_s[0], rec.t_s, atol=1.1e-6)   # whole µs: ≤ 0.5 µs rounding each
    assert got.t_s[0] == pytest.approx(123.456789)      # not a Unix epoch: the device's clock is kept
    assert loaded.report.time_unit == "us" and loaded.report.time_unit_how == "declared"
    assert any("x-IMU3" in w and "gyro deg/s" in w and "accelerometer g" in w for w in loaded.report.warnings)


def test_ros_rostopic_echo_csv_with_text_and_covariance_columns(rec, tmp_path):
    p = tmp_path / "imu.csv"
    t0 = 1_700_000_000_000_000_000
    stamp = t0 + np.round(rec.t_s * 1e9)
    header = ["%time", "field.header.seq", "field.header.stamp", "field.header.frame_id"]
    header += [f"field.orientation.{a}" for a in "xyzw"] + [f"field.orientation_covariance{i}" for i in range(9)]
    header += [f"field.angular_velocity.{a}" for a in "xyz"] + [f"field.angular_velocity_covariance{i}"
                                                                 for i in range(9)]
    header += [f"field.linear_acceleration.{a}" for a in "xyz"] + [f"field.linear_acceleration_covariance{i}"
                                                                    for i in range(9)]
    n = rec.n
    cols = [stamp + 2_000_000, np.arange(n), stamp, np.zeros((n, 4)), np.zeros((n, 9)), rec.gyro_rad_s,
            np.zeros((n, 9)), rec.acc_m_s2, np.zeros((n, 9))]
    _write(p, header, cols, fmt="%.19g", text_cols={3: "imu_link"})
    loaded = open_recording(p)
    _same(loaded.recording, rec, mag=False)
    # float64 holds a 1.7e18 ns stamp to 256 ns: the times agree to 0.3 µs on a 10 ms step
    np.testing.assert_allclose(loaded.recording.t_s, rec.t_s, atol=3e-7)
    assert loaded.report.time_origin_unix_s == pytest.approx(1.7e9)
    assert any("ROS sensor_msgs/Imu" in w and "right-handed" in w for w in loaded.report.warnings)


def test_ros2_csv_with_a_stamp_split_in_sec_and_nanosec(rec, tmp_path):
    p = tmp_path / "imu2.csv"
    ns = 1_700_000_000_000_000_000 + np.round(rec.t_s * 1e9).astype(np.int64)
    header = ["header.stamp.sec", "header.stamp.nanosec", "header.frame_id"] + [
        f"angular_velocity.{a}" for a in "xyz"] + [f"linear_acceleration.{a}" for a in "xyz"]
    _write(p, header, [ns // 10**9, ns % 10**9, rec.gyro_rad_s, rec.acc_m_s2], fmt="%.17g", text_cols={2: "imu"})
    got = open_recording(p).recording
    _same(got, rec, mag=False)
    np.testing.assert_allclose(got.t_s, rec.t_s, atol=1e-6)   # sec + 1e-9 nanosec in float64: 0.24 µs at 1.7e9 s


def test_physics_toolbox_multi_record_uses_g_force_not_linear_acceleration(rec, tmp_path):
    p = tmp_path / "physics_toolbox.csv"
    linear = rec.acc_m_s2 - np.array([0.0, 0.0, G0])     # what its ax..az hold: the acceleration without gravity
    header = ["time", "gFx", "gFy", "gFz", "ax", "ay", "az", "wx", "wy", "wz", "Bx", "By", "Bz", "Azimuth"]
    _write(p, header, [rec.t_s, rec.acc_m_s2 / G0, linear, rec.gyro_rad_s, rec.mag_ut, np.zeros(rec.n)])
    got, info = read_recording(p)
    _same(got, rec)
    assert {"ax", "ay", "az", "Azimuth"} <= set(info.ignored_columns)
    assert "Physics Toolbox" in info.notes[0] and "accelerometer g" in info.notes[0]


def test_androsensor_semicolons_text_date_and_gravity_columns(rec, tmp_path):
    p = tmp_path / "Sensor_record.csv"
    header = [f"ACCELEROMETER {a} (m/s²)" for a in "XYZ"] + [f"GRAVITY {a} (m/s²)" for a in "XYZ"] + [
        f"LINEAR ACCELERATION {a} (m/s²)" for a in "XYZ"] + [f"GYROSCOPE {a} (rad/s)" for a in "XYZ"] + [
        f"MAGNETIC FIELD {a} (μT)" for a in "XYZ"] + ["Time since start in ms ", "YYYY-MO-DD HH-MI-SS_SSS"]
    grav = np.tile([0.0, 0.0, G0], (rec.n, 1))
    _write(p, header, [rec.acc_m_s2, grav, rec.acc_m_s2 - grav, rec.gyro_rad_s, rec.mag_ut, np.round(rec.t_s * 1e3)],
           sep=";", text_cols={16: "2024-05-01 12-00-00_000"})
    loaded = open_recording(p)
    _same(loaded.recording, rec)
    assert loaded.report.time_unit == "ms"
    assert "YYYY-MO-DD HH-MI-SS_SSS" in loaded.report.ignored_columns
    assert any("AndroSensor" in w for w in loaded.report.warnings)


def test_units_in_short_names_of_a_phone_logger(rec, tmp_path):
    p = tmp_path / "phone.csv"
    header = ["timestamp_ms", "gx_dps", "gy_dps", "gz_dps", "ax_g", "ay_g", "az_g"]
    _write(p, header, [np.round(rec.t_s * 1e3), rec.gyro_rad_s / DEG, rec.acc_m_s2 / G0])
    loaded = open_recording(p)
    _same(loaded.recording, rec, mag=False)
    assert loaded.report.time_unit == "ms"
    assert any("gyro deg/s" in w and "accelerometer g" in w for w in loaded.report.warnings)


# ------------------------------------------------------------------ measured files as published
@pytest.mark.skipif("xio_fusion" not in available_datasets(), reason="measured data folder ($GYROSIM_DATA) absent")
def test_the_xio_fusion_example_file_reads_as_its_loader_reads_it():
    path = data_root() / "xio_fusion" / "sensor_data.csv"
    got, ref = read_recording(path)[0], load_xio_fusion(path)
    np.testing.assert_allclose(got.t_s, ref.t_s, atol=1e-12)
    for a, b in ((got.gyro_rad_s, ref.gyro_rad_s), (got.acc_m_s2, ref.acc_m_s2), (got.mag_ut, ref.mag_ut)):
        np.testing.assert_allclose(a, b, rtol=1e-15, atol=1e-15)


@pytest.mark.skipif("xio_ximu_thermometer" not in available_datasets(), reason="measured data folder absent")
def test_the_old_ximu_export_takes_its_rate_from_the_registers_file_beside_it():
    folder = data_root() / "xio_ximu_thermometer"
    got, info = read_recording(folder / "00033_CalInertialAndMag.csv")
    ref = load_xio_thermometer(folder)
    np.testing.assert_allclose(got.t_s, ref.t_s, atol=1e-12)   # 256 Hz from InertialAndMagneticDataRate = 9
    for a, b in ((got.gyro_rad_s, ref.gyro_rad_s), (got.acc_m_s2, ref.acc_m_s2), (got.mag_ut, ref.mag_ut)):
        np.testing.assert_allclose(a, b, rtol=1e-15, atol=1e-15)
    assert any("256 Hz" in n for n in info.notes)


def test_an_ximu_export_without_its_registers_file_is_refused_with_what_to_copy(rec, tmp_path):
    p = tmp_path / "00001_CalInertialAndMag.csv"
    header = ["Packet number"] + [f"Gyroscope {a} (deg/s)" for a in "XYZ"] + [
        f"Accelerometer {a} (g)" for a in "XYZ"] + [f"Magnetometer {a} (G)" for a in "XYZ"]
    _write(p, header, [np.arange(rec.n) * 2, rec.gyro_rad_s / DEG, rec.acc_m_s2 / G0, rec.mag_ut / 100.0])
    with pytest.raises(FormatError, match=r"x-IMU export .*no \*_Registers\.csv beside it.*copy that file"):
        read_recording(p)
    (tmp_path / "00001_Registers.csv").write_text("Packet number,Address,Value,Fixed-point value,Name\n"
                                                  "70,69,8,NaN,InertialAndMagneticDataRate\n")
    got, _ = read_recording(p)
    assert got.rate_hz == pytest.approx(128.0)          # code 8 → 2^7 Hz
    np.testing.assert_allclose(got.mag_ut, rec.mag_ut, rtol=RTOL)   # gauss → µT


# ------------------------------------------------------------------ the user's mapping and units
def test_a_column_mapping_reads_any_header(rec, tmp_path):
    p = tmp_path / "zeit.csv"
    header = ["Zeit", "DrehX", "DrehY", "DrehZ", "BeschlX", "BeschlY", "BeschlZ", "Kommentar"]
    _write(p, header, [rec.t_s, rec.gyro_rad_s / DEG, rec.acc_m_s2], text_cols={7: "ok"})
    with pytest.raises(FormatError, match=r"missing column\(s\).*--columns t="):
        read_recording(p)
    mapping = parse_columns("t=Zeit,gyro_x=DrehX,gyro_y=DrehY,gyro_z=drehz,acc_x=BeschlX,acc_y=BeschlY,acc_z=BeschlZ")
    got, info = read_recording(p, gyro_unit="deg/s", columns=mapping)
    _same(got, rec, mag=False)
    assert info.ignored_columns == ("Kommentar",)


def test_a_partial_mapping_leaves_the_rest_to_the_names(rec, tmp_path):
    p = tmp_path / "part.csv"
    _write(p, ["Zeit", "gyro_x", "gyro_y", "gyro_z", "acc_x", "acc_y", "acc_z"],
           [rec.t_s, rec.gyro_rad_s, rec.acc_m_s2])
    got, _ = read_recording(p, columns={"t": "Zeit"})
    _same(got, rec, mag=False)


def test_a_unit_the_header_does_not_say_is_the_users(rec, tmp_path):
    p = tmp_path / "plain_deg.csv"
    _write(p, ["t", "gyro_x", "gyro_y", "gyro_z", "acc_x", "acc_y", "acc_z"], [rec.t_s, rec.gyro_rad_s / DEG,
                                                                                rec.acc_m_s2 / G0])
    got, _ = read_recording(p, gyro_unit="deg/s", acc_unit="g")
    _same(got, rec, mag=False)


def test_refusals_name_the_problem(rec, tmp_path):
    p = tmp_path / "phone.csv"
    _write(p, ["timestamp_ms", "gx_dps", "gy_dps", "gz_dps", "ax", "ay", "az"],
           [np.round(rec.t_s * 1e3), rec.gyro_rad_s / DEG, rec.acc_m_s2])
    with pytest.raises(UnitError, match=r"column 'gx_dps' says deg/s but --gyro-unit says rad/s: drop --gyro-unit"):
        read_recording(p, gyro_unit="rad/s")
    assert read_recording(p, gyro_unit="dps")[0].gyro_rad_s[0, 0] == pytest.approx(rec.gyro_rad_s[0, 0], rel=RTOL)
    with pytest.raises(FormatError, match=r"mapping gyro_x=gyro_X names no column 'gyro_X'; the header has "
                                          r"'timestamp_ms', 'gx_dps'"):
        read_recording(p, columns={"gyro_x": "gyro_X"})
    amb = tmp_path / "amb.csv"
    _write(amb, ["time", "timestamp", "gx", "gy", "gz", "ax", "ay", "az"], [rec.t_s, rec.t_s, rec.gyro_rad_s,
                                                                            rec.acc_m_s2])
    with pytest.raises(FormatError, match=r"columns 'time', 'timestamp' all look like t: say which .*--columns t=time"):
        read_recording(amb)
    mixed = tmp_path / "mixed.csv"
    _write(mixed, ["t", "gx_dps", "gy_rad_s", "gz", "ax", "ay", "az"], [rec.t_s, rec.gyro_rad_s, rec.acc_m_s2])
    with pytest.raises(FormatError, match=r"the gyro columns name different units"):
        read_recording(mixed)
    odd = tmp_path / "odd.csv"
    _write(odd, ["t", "gyro_x (furlong/fortnight)", "gyro_y", "gyro_z", "ax", "ay", "az"],
           [rec.t_s, rec.gyro_rad_s, rec.acc_m_s2])
    with pytest.raises(FormatError, match=r"'furlong/fortnight' is not a gyro unit"):
        read_recording(odd)


def test_a_mapping_or_topic_given_for_the_wrong_kind_of_file_is_refused(rec, tmp_path):
    p = save_csv(rec, tmp_path / "r.csv")
    with pytest.raises(FormatError, match=r"--topic applies to ROS bags only"):
        read_recording(p, topic="/imu")
    from gyrosim.recording import save_hdf5
    h = save_hdf5(rec, tmp_path / "r.h5")
    with pytest.raises(FormatError, match=r"a column mapping \(--columns\) applies to CSV files only"):
        read_recording(h, columns={"t": "t"})


def test_resolve_columns_reports_where_each_unit_came_from():
    cmap = resolve_columns(["Timestamp (us)", "Gyroscope X (deg/s)", "Gyroscope Y (deg/s)", "Gyroscope Z (deg/s)",
                            "Accelerometer X (g)", "Accelerometer Y (g)", "Accelerometer Z (g)"])
    assert cmap.units == {"t": "us", "gyro": "deg/s", "acc": "g", "temp": "degC", "mag": "uT"}
    assert cmap.declared["gyro"] == "column 'Gyroscope X (deg/s)'" and cmap.layout == "x-IMU3 (x-io)"
