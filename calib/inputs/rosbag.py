"""Reading ``sensor_msgs/Imu`` from a ROS bag: ROS 1 (``.bag``) and ROS 2 (a bag folder with
``metadata.yaml``, or one ``.db3`` / ``.mcap`` storage file), with the pure-Python ``rosbags`` library
(the optional extra ``ros``: ``pip install gyrosim-calib[ros]``).

The topic: the one given (``topic=``, the command lines' ``--topic``), else the bag's only
``sensor_msgs/Imu`` topic; a bag with several is refused with their names and message counts, one
with none with the topics it has.

What is read (REP 145, "Conventions for IMU Sensor Drivers"): ``angular_velocity`` in rad/s and
``linear_acceleration`` in m/s² *with* gravity (the specific force), in the message's
``header.frame_id`` — the sensor frame as the driver publishes it.  calib takes that frame as the
body frame and assumes it right-handed (RFU-like); a driver that publishes another convention must
be rotated first.  Times are the messages' ``header.stamp`` (the sensor's clock), shifted to start at
0 s with the Unix origin kept in ``meta['time_origin_unix_s']``; a topic whose stamps are all zero
falls back to the bag's receive times (noted: they carry the transport's jitter).  A message whose
covariance element 0 is −1 says it carries no such data (REP 145): a topic without angular velocity
or acceleration is refused.  Other topics (``sensor_msgs/MagneticField``, ``Temperature``) are not read.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from gyrosim.recording import Recording

from calib.inputs.errors import FormatError, TimeBaseError

__all__ = ["IMU_TYPE", "is_bag_folder", "read_rosbag"]

IMU_TYPE = "sensor_msgs/msg/Imu"
INSTALL = "reading ROS bags needs the rosbags library: pip install gyrosim-calib[ros]"


def is_bag_folder(path: Path) -> bool:
    """A ROS 2 bag folder: ``metadata.yaml`` beside ``.db3`` or ``.mcap`` storage files."""
    return path.is_dir() and (path / "metadata.yaml").is_file() and any(
        p.suffix in (".db3", ".mcap") for p in path.iterdir())


def _open(path: Path, storage: str):
    """The rosbags reader for ``path`` (a context manager), or a clear error without the library."""
    try:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        raise FormatError(f"{path} is a {storage}; {INSTALL}") from None
    if path.is_file() and storage.startswith("SQLite") and path.suffix != ".db3":
        raise FormatError(f"{path} is an SQLite database: if it is a ROS 2 bag, name it .db3 (or give its folder)")
    if path.is_file() and storage.startswith("MCAP") and path.suffix != ".mcap":
        raise FormatError(f"{path} is an MCAP file: name it .mcap (or give its folder)")
    if path.is_file() and storage.startswith("ROS 1") and path.suffix != ".bag":
        raise FormatError(f"{path} is a ROS 1 bag: name it .bag")
    # ROS 2 storage without message definitions (before Iron) is read with the standard ones
    return AnyReader([path], default_typestore=get_typestore(Stores.ROS2_HUMBLE))


def _choose_topic(path: Path, topics: dict, topic: str | None) -> str:
    imu = {name: info.msgcount for name, info in topics.items() if info.msgtype == IMU_TYPE}
    listing = ", ".join(f"{n} ({c} messages)" for n, c in sorted(imu.items()))
    if topic is None:
        if len(imu) == 1:
            return next(iter(imu))
        if not imu:
            others = ", ".join(f"{n} ({info.msgtype})" for n, info in sorted(topics.items())[:8]) or "no topics"
            raise FormatError(f"{path}: no sensor_msgs/Imu topic in this bag (it has {others}); record the IMU "
                              "driver's topic")
        raise FormatError(f"{path}: {len(imu)} sensor_msgs/Imu topics: {listing}; choose one with --topic")
    if topic not in topics:
        raise FormatError(f"{path}: no topic {topic!r} in this bag; its IMU topics: {listing or 'none'}")
    if topics[topic].msgtype != IMU_TYPE:
        raise FormatError(f"{path}: topic {topic} holds {topics[topic].msgtype}, not sensor_msgs/Imu; its IMU topics: "
                          f"{listing or 'none'}")
    return topic


def _messages(reader, topic: str, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, str, list[int]]:
    """(header stamps ns, receive times ns, gyro (N,3), acc (N,3), first frame id, messages without gyro/acc)."""
    stamp, recv = np.zeros(n, np.int64), np.zeros(n, np.int64)
    gyro, acc = np.zeros((n, 3)), np.zeros((n, 3))
    frame, missing = "", [0, 0]
    conns = [c for c in reader.connections if c.topic == topic]
    i = 0
    for conn, t_ns, raw in reader.messages(connections=conns):
        if i == n:
            break
        m = reader.deserialize(raw, conn.msgtype)
        stamp[i] = int(m.header.stamp.sec) * 1_000_000_000 + int(m.header.stamp.nanosec)
        recv[i] = t_ns
        w, f = m.angular_velocity, m.linear_acceleration
        gyro[i] = (w.x, w.y, w.z)
        acc[i] = (f.x, f.y, f.z)
        missing[0] += m.angular_velocity_covariance[0] == -1
        missing[1] += m.linear_acceleration_covariance[0] == -1
        frame = frame or m.header.frame_id
        i += 1
    return stamp[:i], recv[:i], gyro[:i], acc[:i], frame, missing


def _times(path: Path, topic: str, stamp: np.ndarray, recv: np.ndarray, gyro: np.ndarray, acc: np.ndarray,
           notes: list[str]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Times in ns (header stamps, or receive times when the stamps are empty); exact repeats dropped,
    any other step that is not forward refused."""
    t = stamp
    if not stamp.any():
        t = recv
        notes.append(f"{topic}: the header stamps are all zero: the bag's receive times are used (they carry the "
                     "transport's jitter)")
    dt = np.diff(t)
    same = (dt == 0) & np.all(gyro[1:] == gyro[:-1], axis=1) & np.all(acc[1:] == acc[:-1], axis=1)
    if same.any():
        keep = np.concatenate([[True], ~same])
        t, gyro, acc = t[keep], gyro[keep], acc[keep]
        notes.append(f"{topic}: {int(same.sum())} message(s) repeat the previous one exactly: dropped")
        dt = np.diff(t)
    if np.any(dt <= 0):
        k = int(np.argmax(dt <= 0))
        what = "repeats" if dt[k] == 0 else "is before"
        raise TimeBaseError(f"{path}: on {topic}, message {k + 2}'s stamp {what} message {k + 1}'s "
                            f"({int(np.sum(dt <= 0))} such step(s)): the stamps must increase; re-record or re-stamp")
    return t, gyro, acc


def read_rosbag(path: Path, storage: str, topic: str | None = None) -> tuple[Recording, list[str], str]:
    """Read one ``sensor_msgs/Imu`` topic of the bag at ``path`` (module docstring).  Returns the
    recording (SI, t from 0 s), notes, and the topic read."""
    notes: list[str] = []
    try:
        with _open(path, storage) as reader:
            topic = _choose_topic(path, reader.topics, topic)
            n = reader.topics[topic].msgcount
            stamp, recv, gyro, acc, frame, missing = _messages(reader, topic, n)
    except FormatError:
        raise
    except Exception as exc:  # rosbags' own errors: a truncated or unreadable bag
        raise FormatError(f"{path}: the {storage} cannot be read ({type(exc).__name__}: {exc}); re-record or "
                          "re-copy it") from exc
    if len(stamp) < 2:
        raise FormatError(f"{path}: topic {topic} holds {len(stamp)} message(s): a recording needs at least 2")
    for k, what in ((0, "angular velocity"), (1, "linear acceleration")):
        if missing[k] == len(stamp):
            raise FormatError(f"{path}: topic {topic} carries no {what} (covariance element 0 is -1 in every "
                              "message, REP 145): record the IMU's raw topic")
    t_ns, gyro, acc = _times(path, topic, stamp, recv, gyro, acc, notes)
    t0 = int(t_ns[0])
    meta = {"source": f"{path} {topic}", "gyro_unit": "rad/s", "acc_unit": "m/s^2", "ros_topic": topic,
            "ros_frame_id": frame, "column_layout": "ROS sensor_msgs/Imu"}
    if 946684800 <= t0 / 1e9 <= 4102444800:
        meta["time_origin_unix_s"] = t0 / 1e9
    notes.insert(0, f"ROS bag topic {topic} ({len(t_ns)} messages, frame {frame or 'unnamed'}): rad/s and m/s² as "
                    "REP 145 says; the sensor frame is taken as the body frame, assumed right-handed")
    rec = Recording(t_s=(t_ns - t0) * 1e-9, gyro_rad_s=gyro, acc_m_s2=acc, meta=meta)
    return rec, notes, topic
