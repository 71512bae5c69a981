"""ROS 1 and ROS 2 bags read directly: bags written here with rosbags' own writers from 400 samples of a
simulated session (sensor_msgs/Imu, stamps from a Unix origin) and read back through the input
boundary — values, time base, units, topic choice and the refusals.

The values are float64 in the message, so they come back exactly; the stamps are whole ns, so the
times agree to float64 rounding of (stamp − first stamp)·1e-9 s (< 1e-15 s on 4 s).
"""

from __future__ import annotations

import builtins

import numpy as np
import pytest
from conftest import session

from gyrosim.recording import Recording

from calib.inputs import FormatError, TimeBaseError, UnitError, open_recording, read_recording

rosbags = pytest.importorskip("rosbags", reason="the optional extra ros (pip install gyrosim-calib[ros])")
from rosbags.typesys import Stores, get_typestore  # noqa: E402

T0_NS = 1_700_000_000_123_000_000
IMU = "sensor_msgs/msg/Imu"


@pytest.fixture(scope="module")
def rec() -> Recording:
    s = session("typical")
    k = slice(1000, 1400)
    return Recording(s.t_s[k] - s.t_s[1000], s.gyro_rad_s[k], s.acc_m_s2[k])


def _imu(ts, ros1: bool, t_ns: int, g, a, frame="imu_link", no_gyro=False):
    T = ts.types
    stamp = T["builtin_interfaces/msg/Time"](sec=t_ns // 10**9, nanosec=t_ns % 10**9)
    header = T["std_msgs/msg/Header"](seq=0, stamp=stamp, frame_id=frame) if ros1 else \
        T["std_msgs/msg/Header"](stamp=stamp, frame_id=frame)
    v3, q = T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/Quaternion"]
    cov = np.zeros(9)
    return T[IMU](header=header, orientation=q(x=0.0, y=0.0, z=0.0, w=1.0), orientation_covariance=-np.ones(9),
                  angular_velocity=v3(x=g[0], y=g[1], z=g[2]),
                  angular_velocity_covariance=-np.ones(9) if no_gyro else cov,
                  linear_acceleration=v3(x=a[0], y=a[1], z=a[2]), linear_acceleration_covariance=cov)


def _stamps(rec: Recording) -> np.ndarray:
    return T0_NS + np.round(rec.t_s * 1e9).astype(np.int64)


def write_bag(path, rec: Recording, kind: str, topics=("/imu/data",), extra_string_topic=False, **imu_kw):
    """A bag at ``path``: kind "ros1" (.bag), "ros2" (a folder, sqlite3) or "mcap" (a folder, mcap)."""
    ros1 = kind == "ros1"
    ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    if ros1:
        from rosbags.rosbag1 import Writer
        writer = Writer(path)
    else:
        from rosbags.rosbag2 import StoragePlugin, Writer
        writer = Writer(path, version=9, storage_plugin=StoragePlugin.MCAP if kind == "mcap" else
                        StoragePlugin.SQLITE3)
    ser = ts.serialize_ros1 if ros1 else ts.serialize_cdr
    with writer:
        conns = [writer.add_connection(t, IMU, typestore=ts) for t in topics]
        if extra_string_topic:
            sconn = writer.add_connection("/chatter", "std_msgs/msg/String", typestore=ts)
            writer.write(sconn, T0_NS, ser(ts.types["std_msgs/msg/String"](data="hi"), "std_msgs/msg/String"))
        for i, t_ns in enumerate(_stamps(rec)):
            msg = _imu(ts, ros1, int(t_ns), rec.gyro_rad_s[i], rec.acc_m_s2[i], **imu_kw)
            for c in conns:
                writer.write(c, int(t_ns) + 1_500_000, ser(msg, IMU))   # received 1.5 ms after the stamp
    return path


@pytest.mark.parametrize("kind, name", [("ros1", "s.bag"), ("ros2", "s_ros2"), ("mcap", "s_mcap")])
def test_a_bag_reads_back_values_time_base_and_frame(rec, tmp_path, kind, name):
    path = write_bag(tmp_path / name, rec, kind)
    loaded = open_recording(path)
    got = loaded.recording
    assert np.array_equal(got.gyro_rad_s, rec.gyro_rad_s) and np.array_equal(got.acc_m_s2, rec.acc_m_s2)
    np.testing.assert_allclose(got.t_s, (_stamps(rec) - T0_NS) * 1e-9, rtol=0, atol=1e-15)  # header stamps
    assert got.meta["time_origin_unix_s"] == pytest.approx(T0_NS / 1e9, abs=1e-6)
    assert got.meta["ros_topic"] == "/imu/data" and got.meta["ros_frame_id"] == "imu_link"
    assert loaded.report.rate_hz == pytest.approx(100.0, rel=1e-6)
    assert any("frame imu_link" in w and "right-handed" in w for w in loaded.report.warnings)


def test_a_ros2_storage_file_alone_reads_too(rec, tmp_path):
    folder = write_bag(tmp_path / "b", rec, "mcap")
    (mcap,) = folder.glob("*.mcap")
    got, info = read_recording(mcap)
    assert np.array_equal(got.gyro_rad_s, rec.gyro_rad_s) and info.format.startswith("MCAP")


def test_the_topic_is_chosen_or_asked_for(rec, tmp_path):
    path = write_bag(tmp_path / "two.bag", rec, "ros1", topics=("/imu/data", "/imu/data_raw"))
    with pytest.raises(FormatError, match=r"2 sensor_msgs/Imu topics: /imu/data \(400 messages\), /imu/data_raw "
                                          r"\(400 messages\); choose one with --topic"):
        read_recording(path)
    got, _ = read_recording(path, topic="/imu/data_raw")
    assert got.meta["ros_topic"] == "/imu/data_raw" and got.n == rec.n
    with pytest.raises(FormatError, match=r"no topic '/imu' in this bag; its IMU topics: /imu/data"):
        read_recording(path, topic="/imu")


def test_a_bag_without_an_imu_topic_or_without_gyro_data_is_refused(rec, tmp_path):
    ts = get_typestore(Stores.ROS1_NOETIC)
    from rosbags.rosbag1 import Writer
    path = tmp_path / "chatter.bag"
    with Writer(path) as w:
        c = w.add_connection("/chatter", "std_msgs/msg/String", typestore=ts)
        w.write(c, T0_NS, ts.serialize_ros1(ts.types["std_msgs/msg/String"](data="x"), "std_msgs/msg/String"))
    with pytest.raises(FormatError, match=r"no sensor_msgs/Imu topic in this bag \(it has /chatter "
                                          r"\(std_msgs/msg/String\)\)"):
        read_recording(path)
    bad = write_bag(tmp_path / "nogyro.bag", rec, "ros1", no_gyro=True)
    with pytest.raises(FormatError, match=r"carries no angular velocity \(covariance element 0 is -1"):
        read_recording(bad)
    with pytest.raises(FormatError, match=r"topic /chatter holds std_msgs/msg/String, not sensor_msgs/Imu"):
        read_recording(write_bag(tmp_path / "mixed.bag", rec, "ros1", extra_string_topic=True), topic="/chatter")


def test_stamps_that_go_back_are_refused_and_a_unit_option_against_rep145_too(rec, tmp_path):
    from rosbags.rosbag1 import Writer
    path = tmp_path / "back.bag"
    ts = get_typestore(Stores.ROS1_NOETIC)
    stamps = _stamps(rec)
    stamps[200:] -= 1_000_000_000          # the sensor clock jumps back 1 s at message 201
    with Writer(path) as w:
        c = w.add_connection("/imu", IMU, typestore=ts)
        for i, s in enumerate(stamps):
            w.write(c, T0_NS + i, ts.serialize_ros1(_imu(ts, True, int(s), rec.gyro_rad_s[i], rec.acc_m_s2[i]), IMU))
    with pytest.raises(TimeBaseError, match=r"on /imu, message 201's stamp is before message 200's"):
        read_recording(path)
    ok = write_bag(tmp_path / "ok.bag", rec, "ros1")
    with pytest.raises(UnitError, match=r"sensor_msgs/Imu holds rad/s \(REP 145\) but --gyro-unit says deg/s"):
        read_recording(ok, gyro_unit="deg/s")


def test_without_rosbags_the_error_names_the_extra(rec, tmp_path, monkeypatch):
    path = write_bag(tmp_path / "x.bag", rec, "ros1")
    real_import = builtins.__import__

    def no_rosbags(name, *args, **kw):
        if name.startswith("rosbags"):
            raise ImportError(name)
        return real_import(name, *args, **kw)

    monkeypatch.setattr(builtins, "__import__", no_rosbags)
    with pytest.raises(FormatError, match=r"is a ROS 1 bag; reading ROS bags needs the rosbags library: "
                                          r"pip install gyrosim-calib\[ros\]"):
        read_recording(path)
