"""Which column of a CSV holds which channel, and in which unit: calib's own header, the headers of
common loggers, and the user's own mapping.

The channels are ``t, gyro_x..z, acc_x..z`` (required) and ``temp, mag_x..z`` (optional).  A column
is recognised by its name, in this order:

1. the user's mapping (:func:`parse_columns` reads ``t=timestamp_ms,gyro_x=gx_dps,…``; the Python API
   takes the same as a dict); channels it does not name are recognised as below among the other columns;
2. a logger whose header needs more than a name lookup (:data:`LAYOUTS`): a ROS ``sensor_msgs/Imu``
   CSV export, where ``linear_acceleration`` *is* the specific force, and the Physics Toolbox multi
   record, where ``ax`` is the acceleration *without* gravity and ``gFx`` the one to use;
3. the channel's own name (``gyro_x``) and then its aliases (``gx``, ``Gyroscope X``, ``imu.gyro.x``,
   ``angular_velocity.x``…): names are compared lower-case with every run of spaces, dots, dashes and
   slashes read as ``_``.  Two aliases for one channel, with the channel's own name absent, are
   refused as ambiguous: the mapping says which.

Units in names: a bracketed unit (``Gyroscope X (deg/s)``, ``acc_x [m/s^2]``) or a unit suffix
(``gx_dps``, ``ax_g``, ``timestamp_ms``, ``t_s``, ``gyro_x_rad_s``, ``acc_x_m_s2``, ``mag_x_ut``,
``temp_c``).  The three axes of a sensor must agree.  A unit the user gives (``gyro_unit=``,
``acc_unit=``) is used where the header says none, and refused where it says another: the file and
the option cannot both be right.  Without either, the units are calib's: s (or found from the
steps, :mod:`calib.inputs.timebase`), rad/s, m/s², °C, µT.

The loggers recognised without a mapping, each checked by a test on a file of its shape:

* calib's own CSV, with or without units in the names (``t_s,gyro_x_rad_s,…,acc_x_m_s2,…,temp_c,
  mag_x_ut,…``, what ``calib apply`` writes);
* tofupilot-style dotted names: ``timestamp,imu.gyro.x,…,imu.accel.x,…`` (SI units unless named);
* x-io x-IMU3 GUI export ``Inertial.csv``: ``Timestamp (us),Gyroscope X (deg/s),…,Accelerometer X (g),…``
  (and x-io Fusion's example ``Time (s),…,Magnetometer X (uT),…``);
* the older x-IMU GUI export ``CalInertialAndMag.csv`` (``Packet number,Gyroscope X (deg/s),…,
  Magnetometer X (G),…``): no time column; the sample rate is read from the ``*_Registers.csv``
  beside it (register ``InertialAndMagneticDataRate``: code k is 2^(k−1) Hz);
* ROS ``sensor_msgs/Imu`` exported to CSV: ``rostopic echo -p`` (``%time,field.header.stamp,…,
  field.angular_velocity.x,…,field.linear_acceleration.x,…``, stamps in ns) and ROS 2 / PlotJuggler
  style names ending in ``angular_velocity.x`` (a ``header.stamp.sec`` + ``header.stamp.nanosec``
  pair is added up).  REP 145: rad/s and m/s² with gravity, in the sensor's own frame as the driver
  publishes it; calib takes that frame as the body frame and assumes it right-handed (RFU-like);
* phone loggers: Physics Toolbox Sensor Suite's multi record (Vieyra Software; ``time,gFx,gFy,gFz,
  ax,ay,az,wx,wy,wz,Bx,By,Bz,…``: g-force in g, rad/s, µT; ``ax..az`` is the linear acceleration
  without gravity and is not used) and AndroSensor (Fiv Asim; ``ACCELEROMETER X (m/s²);…;GYROSCOPE X
  (rad/s);…;MAGNETIC FIELD X (μT);…;Time since start in ms``; its LINEAR ACCELERATION and GRAVITY
  columns are not used).  Sensor Logger (Kelvin Choi) and phyphox write one file per sensor: map the
  columns of a merged file, or export from an app that logs all sensors in one file.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

from calib.inputs.errors import FormatError, UnitError

__all__ = ["CHANNELS", "REQUIRED", "ColumnMap", "parse_columns", "resolve_columns", "split_name", "unit_of"]

REQUIRED = ("t", "gyro_x", "gyro_y", "gyro_z", "acc_x", "acc_y", "acc_z")
CHANNELS = REQUIRED + ("temp", "mag_x", "mag_y", "mag_z")
SENSORS = ("t", "gyro", "acc", "temp", "mag")
_OPTION = {"t": "--time-unit", "gyro": "--gyro-unit", "acc": "--acc-unit"}
_WHAT = {"t": "time", "gyro": "gyro", "acc": "accelerometer", "temp": "temperature", "mag": "magnetometer"}


def sensor_of(channel: str) -> str:
    """``gyro_x`` → ``gyro``, ``t`` → ``t``."""
    return channel.split("_")[0]


# unit spellings (lower case, spaces removed) → the spelling gyrosim.units / calib.inputs.timebase take
_UNITS: dict[str, dict[str, str]] = {
    "t": {**dict.fromkeys(("s", "sec", "secs", "second", "seconds"), "s"),
          **dict.fromkeys(("ms", "msec", "millisecond", "milliseconds"), "ms"),
          **dict.fromkeys(("us", "µs", "μs", "usec", "microsecond", "microseconds"), "us"),
          **dict.fromkeys(("ns", "nsec", "nanosecond", "nanoseconds"), "ns")},
    "gyro": {**dict.fromkeys(("rad/s", "rad_s", "rads", "rad/sec", "rad·s⁻¹", "rad.s-1"), "rad/s"),
             **dict.fromkeys(("deg/s", "deg_s", "degs", "dps", "°/s", "º/s", "degrees/s", "deg/sec", "degree/s"),
                             "deg/s"),
             **dict.fromkeys(("mdeg/s", "mdps"), "mdeg/s"), "deg/h": "deg/h", "rad/h": "rad/h"},
    "acc": {**dict.fromkeys(("m/s^2", "m/s²", "m/s2", "m_s2", "m_s_2", "ms2", "mps2", "m/s/s", "ms^-2", "ms-2",
                             "m·s⁻²", "m.s-2"), "m/s^2"),
            "g": "g", "mg": "mg", "ug": "ug", "µg": "ug", "μg": "ug"},
    "temp": dict.fromkeys(("c", "°c", "ºc", "degc", "deg_c", "degreesc", "degreec", "celsius", "℃"), "degC"),
    "mag": {**dict.fromkeys(("ut", "µt", "μt", "microtesla"), "uT"), **dict.fromkeys(("g", "gauss", "ga"), "gauss"),
            **dict.fromkeys(("mg", "mgauss", "milligauss"), "mgauss"), "nt": "nT"},
}
_SI = {"gyro": "rad/s", "acc": "m/s^2", "temp": "degC", "mag": "uT"}
# unit suffixes a name may end with (after its separators became "_"), longest first
_SUFFIXES = sorted({k for units in _UNITS.values() for k in units if re.fullmatch(r"[a-zµμ0-9_]+", k)},
                   key=len, reverse=True)
_BRACKET = re.compile(r"^(.*?)\s*[\[(]\s*([^\[\]()]*?)\s*[\])]\s*$")


def _key(text: str) -> str:
    return re.sub(r"[^0-9a-zµμ°]+", "_", text.lower()).strip("_")


def split_name(name: str) -> tuple[str, str | None]:
    """A column name → (key, unit text or None): ``"Gyroscope X (deg/s)"`` → ``("gyroscope_x", "deg/s")``,
    ``"gx_dps"`` → ``("gx", "dps")``, ``"imu.gyro.x"`` → ``("imu_gyro_x", None)``.  The suffix is only
    split off when what remains is a channel name (so ``"mag_x"`` stays whole)."""
    s = name.strip().strip("\"'").strip()
    m = _BRACKET.match(s)
    if m and m.group(1).strip():
        return _key(m.group(1)), m.group(2).strip()
    key = _key(s)
    for suf in _SUFFIXES:
        if key.endswith("_" + suf) and len(key) > len(suf) + 1:
            base = key[: -len(suf) - 1]
            if _channel_of(base) is not None:
                return base, suf
    return key, None


def unit_of(sensor: str, text: str) -> str | None:
    """The unit a name's unit text means for ``sensor`` (``"dps"`` → ``"deg/s"``), None if not one of its units."""
    return _UNITS[sensor].get(text.strip().lower().replace(" ", ""))


def _aliases() -> dict[str, str]:
    """key → channel, for every accepted alias of every channel (the generic lookup, step 3)."""
    out: dict[str, str] = {}
    stems = {
        "gyro": ("gyro", "gyr", "g", "gyroscope", "imu_gyro", "imu_gyr", "angular_velocity", "angular_rate",
                 "omega", "w", "rotation_rate", "rotationrate", "rot_rate"),
        "acc": ("acc", "a", "accel", "acceleration", "accelerometer", "imu_acc", "imu_accel", "imu_acceleration",
                "specific_force"),
        "mag": ("mag", "m", "b", "magn", "magnetometer", "magnetic_field", "imu_mag", "imu_magnetometer"),
    }
    for sensor, names in stems.items():
        for stem in names:
            for ax in "xyz":
                out[f"{stem}_{ax}"] = out[f"{stem}{ax}"] = f"{sensor}_{ax}"
    for k in ("time", "timestamp", "time_stamp", "stamp", "seconds_elapsed", "elapsed", "elapsed_time",
              "time_since_start_in", "time_since_start", "sample_time", "imu_time", "imu_timestamp"):
        out[k] = "t"
    for k in ("temperature", "thermometer", "imu_temp", "imu_temperature", "sensor_temperature", "temp_c", "tmp"):
        out[k] = "temp"
    for c in CHANNELS:
        out[c] = c
    return out


_ALIASES = _aliases()


def _channel_of(key: str) -> str | None:
    return _ALIASES.get(key)


@dataclass(frozen=True)
class Layout:
    """A logger whose header the alias lookup alone would misread: candidate keys per channel (a key
    ending with the given text, most preferred first) and the units the format fixes."""

    name: str
    signature: tuple[str, ...]                 # endings that must all be present
    channels: dict[str, tuple[str, ...]]
    units: dict[str, str]
    note: str = ""


def _axes(channel_stem: str, endings: tuple[str, ...]) -> dict[str, tuple[str, ...]]:
    """``gyro_x: (angular_velocity_x, angular_velocityx)``…: both spellings of each ending, per axis."""
    return {f"{channel_stem}_{ax}": tuple(f for e in endings for f in (f"{e}_{ax}", f"{e}{ax}")) for ax in "xyz"}


LAYOUTS = (
    Layout("ROS sensor_msgs/Imu", ("angular_velocity_x", "linear_acceleration_x"),
           {"t": ("field_header_stamp", "header_stamp", "time"), **_axes("gyro", ("angular_velocity",)),
            **_axes("acc", ("linear_acceleration",))},
           {"gyro": "rad/s", "acc": "m/s^2"},
           "the sensor frame as published (REP 145) is taken as the body frame, assumed right-handed"),
    Layout("Physics Toolbox Sensor Suite", ("gfx", "wx"),
           {"t": ("time",), **_axes("acc", ("gf",)), **_axes("gyro", ("w",)), **_axes("mag", ("b",))},
           {"acc": "g", "gyro": "rad/s", "mag": "uT"},
           "g-force gFx..gFz used as the accelerometer (ax..az there is the acceleration without gravity)"),
)
_SIGNATURES = (  # recognised by the alias lookup; named in the note only
    ("AndroSensor", ("accelerometer_x", "gyroscope_x", "time_since_start_in")),
    ("x-IMU3 (x-io)", ("gyroscope_x", "accelerometer_x")),
    ("tofupilot", ("imu_gyro_x",)),
)


@dataclass(frozen=True)
class ColumnMap:
    """Where each channel is (column index in the header) and in which unit.

    ``units`` maps a sensor (``t``, ``gyro``, ``acc``, ``temp``, ``mag``) to its unit (``t`` may be
    absent: found from the steps); ``declared`` says for each where the unit came from (the column name,
    the logger's format, the user); ``t_nanosec``: a second time column added as nanoseconds (ROS 2's
    ``header.stamp.sec`` + ``header.stamp.nanosec``)."""

    index: dict[str, int]
    units: dict[str, str]
    declared: dict[str, str]
    layout: str
    ignored: tuple[str, ...]
    t_nanosec: int | None = None
    notes: tuple[str, ...] = field(default=())


def parse_columns(text: str) -> dict[str, str]:
    """The ``--columns`` option: ``t=timestamp_ms,gyro_x=gx_dps,…`` → ``{"t": "timestamp_ms", …}``.

    Keys are the channels ``t, gyro_x..z, acc_x..z, temp, mag_x..z``; values are column names as the
    header spells them (case and surrounding spaces do not matter).  Raises :class:`FormatError` naming
    the bad item."""
    pairs: list[tuple[str, str]] = []
    for item in text.split(","):
        if not item.strip():
            raise FormatError(f"--columns {text!r}: an empty item; write channel=column pairs separated by commas, "
                              "e.g. t=timestamp_ms,gyro_x=gx_dps")
        if "=" not in item:
            raise FormatError(f"--columns: {item.strip()!r} is not channel=column (e.g. gyro_x=gx_dps)")
        key, col = (s.strip() for s in item.split("=", 1))
        pairs.append((key, col))
    return check_mapping(pairs, f"--columns {text!r}")


def check_mapping(mapping: dict[str, str] | list[tuple[str, str]], where: str = "columns") -> dict[str, str]:
    """A mapping channel → column name, checked: known channels, each once, non-empty names, no column twice."""
    out: dict[str, str] = {}
    for key, col in (mapping.items() if isinstance(mapping, dict) else mapping):
        k = str(key).strip().lower()
        if k not in CHANNELS:
            raise FormatError(f"{where}: {key!r} is not a channel; use {', '.join(CHANNELS)}")
        if k in out:
            raise FormatError(f"{where}: {k} is given twice; give each channel once")
        if not str(col).strip():
            raise FormatError(f"{where}: {k}= names no column")
        out[k] = str(col).strip()
    lower = [c.lower() for c in out.values()]
    twice = sorted({c for c in out.values() if lower.count(c.lower()) > 1})
    if twice:
        raise FormatError(f"{where}: column {twice[0]!r} is given to several channels; give each its own column")
    return out


def _clean(name: str) -> str:
    return name.strip().strip("\"'").strip()


def _find_mapped(col: str, raw: list[str], keys: list[str], channel: str, where: str) -> int:
    """The header column the user named for ``channel``: the same text (any case), else the one column
    whose name without its unit is that text."""
    hits = [j for j, r in enumerate(raw) if r.lower() == col.lower()]
    if not hits:
        hits = [j for j, k in enumerate(keys) if k == split_name(col)[0]]
    if len(hits) != 1:
        shown = ", ".join(repr(r) for r in raw[:12]) + (" …" if len(raw) > 12 else "")
        what = "no" if not hits else f"{len(hits)} columns like"
        raise FormatError(f"{where}: the mapping {channel}={col} names {what} column {col!r}; the header has "
                          f"{shown}: name one of those")
    return hits[0]


def _ambiguous(channel: str, names: list[str], where: str) -> FormatError:
    if len({n.lower() for n in names}) == 1:
        return FormatError(f"{where}: column {names[0]!r} appears {len(names)} times in the header: name each column "
                           "once")
    return FormatError(f"{where}: columns {', '.join(repr(n) for n in names)} all look like {channel}: say which "
                       f"with a column mapping (--columns {channel}={names[0]})")


def _match_layout(layout: Layout, keys: list[str], index: dict[str, int], raw: list[str], where: str) -> None:
    taken = set(index.values())
    for ch, endings in layout.channels.items():
        if ch in index:
            continue
        for e in endings:
            hits = [j for j, k in enumerate(keys) if j not in taken and (k == e or k.endswith("_" + e))]
            if len(hits) > 1:
                raise _ambiguous(ch, [raw[j] for j in hits], where)
            if hits:
                index[ch] = hits[0]
                taken.add(hits[0])
                break


def _match_names(keys: list[str], index: dict[str, int], raw: list[str], where: str) -> None:
    """Step 3: the channel's own name first, then its aliases; two candidates of one rank are ambiguous."""
    taken = set(index.values())
    for ch in CHANNELS:
        if ch in index:
            continue
        cand = [j for j, k in enumerate(keys) if j not in taken and _ALIASES.get(k) == ch]
        own = [j for j in cand if keys[j] == ch]
        pick = own or cand
        if len(pick) > 1:
            raise _ambiguous(ch, [raw[j] for j in pick], where)
        if pick:
            index[ch] = pick[0]
            taken.add(pick[0])


def _ros2_stamp(keys: list[str], index: dict[str, int]) -> int | None:
    """ROS 2 exports split the stamp into ``header.stamp.sec`` and ``.nanosec``: t = sec (+ nanosec column)."""
    if "t" in index:
        return None
    sec = [j for j, k in enumerate(keys) if k.endswith("header_stamp_sec")]
    nsec = [j for j, k in enumerate(keys) if k.endswith("header_stamp_nanosec")]
    if len(sec) == 1 and len(nsec) == 1:
        index["t"] = sec[0]
        return nsec[0]
    return None


def _declared_units(index: dict[str, int], parsed: list[tuple[str, str | None]], raw: list[str], where: str,
                    notes: list[str]) -> dict[str, tuple[str, str]]:
    """sensor → (unit, column that says it), from the column names; the axes of a sensor must agree.
    An unknown unit refuses the file for t, gyro and acc, and drops temp and mag with a note."""
    out: dict[str, tuple[str, str]] = {}
    for sensor in SENSORS:
        cols = [index[c] for c in CHANNELS if sensor_of(c) == sensor and c in index]
        found: dict[str, str] = {}
        for j in cols:
            text = parsed[j][1]
            if text is None:
                continue
            unit = unit_of(sensor, text)
            if unit is None:
                accepted = ", ".join(sorted(set(_UNITS[sensor].values())))
                msg = (f"column {raw[j]!r}: {text!r} is not a {_WHAT[sensor]} unit ({accepted})")
                if sensor in ("temp", "mag"):
                    notes.append(f"{msg}: the {_WHAT[sensor]} columns are ignored")
                    for c in [c for c in CHANNELS if sensor_of(c) == sensor]:
                        index.pop(c, None)
                    break
                raise FormatError(f"{where}: {msg}; rename the column, or map it and give {_OPTION[sensor]}")
            found.setdefault(unit, raw[j])
        else:
            if len(found) > 1:
                raise FormatError(f"{where}: the {_WHAT[sensor]} columns name different units "
                                  f"({', '.join(f'{c!r}: {u}' for u, c in found.items())}); one sensor has one unit")
            if found:
                unit, col = next(iter(found.items()))
                out[sensor] = (unit, f"column {col!r}")
    return out


def _final_units(declared: dict[str, tuple[str, str]], layout: Layout | None, given: dict[str, str | None],
                 where: str) -> tuple[dict[str, str], dict[str, str]]:
    """The unit of each sensor: the user's where the file says none, the file's (name, then logger format)
    where the user says none, refused where both say and differ; calib's SI units otherwise."""
    from gyrosim.units import to_si

    units, how = {}, {}
    for sensor in SENSORS:
        file_unit, source = declared.get(sensor, (None, ""))
        if file_unit is None and layout is not None and sensor in layout.units:
            file_unit, source = layout.units[sensor], f"the {layout.name} format"
        user = given.get(sensor)
        if user is not None and file_unit is not None:
            q = {"gyro": "rate", "acc": "acceleration"}[sensor]
            if float(to_si(1.0, user, q)) != float(to_si(1.0, file_unit, q)):
                raise UnitError(f"{where}: {source} says {file_unit} but {_OPTION[sensor]} says {user}: drop "
                                f"{_OPTION[sensor]} (the file's unit is used) or fix the column name")
        if user is not None:
            units[sensor], how[sensor] = user, _OPTION[sensor]
        elif file_unit is not None:
            units[sensor], how[sensor] = file_unit, source
        elif sensor in _SI:
            units[sensor], how[sensor] = _SI[sensor], "default"
    return units, how


def resolve_columns(header: list[str], columns: dict[str, str] | None = None, gyro_unit: str | None = None,
                    acc_unit: str | None = None, *, where: str = "") -> ColumnMap:
    """Find every channel's column and unit in ``header`` (module docstring).  Required channels that
    are not found are simply absent from ``index`` (the caller names them); an ambiguous header, a
    mapping naming a missing column, an unknown unit or a unit conflict raise."""
    raw = [_clean(h) for h in header]
    parsed = [split_name(h) for h in raw]
    keys = [k for k, _ in parsed]
    index: dict[str, int] = {}
    for ch, col in check_mapping(columns or {}).items():
        index[ch] = _find_mapped(col, raw, keys, ch, where)
    layout = next((lay for lay in LAYOUTS if all(any(k == s or k.endswith("_" + s) for k in keys)
                                                 for s in lay.signature)), None)
    if layout is not None:
        _match_layout(layout, keys, index, raw, where)
    t_nanosec = _ros2_stamp(keys, index)
    _match_names(keys, index, raw, where)
    notes: list[str] = []
    declared = _declared_units(index, parsed, raw, where, notes)
    if layout is not None and layout.name.startswith("ROS") and "t" in index and "t" not in declared:
        if keys[index["t"]] == "field_header_stamp" or raw[index["t"]] == "%time":
            declared["t"] = ("ns", "rostopic echo -p (stamps in ns)")
        elif t_nanosec is not None:
            declared["t"] = ("s", "header.stamp.sec")
    units, how = _final_units(declared, layout, {"gyro": gyro_unit, "acc": acc_unit}, where)
    if "t" in declared:
        units["t"], how["t"] = declared["t"][0], declared["t"][1]
    name = "column mapping" if columns else (layout.name if layout else next(
        (n for n, sig in _SIGNATURES if all(any(k == s or k.endswith("_" + s) for k in keys) for s in sig)),
        "calib"))
    if layout is not None and layout.note:
        notes.append(layout.note)
    used = set(index.values()) | ({t_nanosec} if t_nanosec is not None else set())
    ignored = tuple(raw[j] for j in range(len(raw)) if j not in used)
    return ColumnMap(index, units, how, name, ignored, t_nanosec, tuple(notes))


_SHOW = {"m/s^2": "m/s²", "uT": "µT", "degC": "°C"}


def describe_units(cmap: ColumnMap) -> str | None:
    """One line for the report when the header chose a logger's layout or units other than calib's SI
    defaults; None when there is nothing to say (calib's plain header, units given by option only)."""
    from_file = {s: u for s, u in cmap.units.items() if s in ("gyro", "acc", "mag", "temp")
                 and cmap.declared.get(s, "default").startswith(("column", "the"))}
    if cmap.layout in ("calib", "column mapping"):
        shown = {s: u for s, u in from_file.items() if u != _SI[s]}
        if not shown and not cmap.notes:
            return None
        text = "units from the column names: " + ", ".join(f"{_WHAT[s]} {_SHOW.get(u, u)}" for s, u in shown.items())
        return "; ".join([text, *cmap.notes])
    text = f"read as the {cmap.layout} layout"
    if from_file:
        text += ": " + ", ".join(f"{_WHAT[s]} {_SHOW.get(u, u)}" for s, u in from_file.items())
    assumed = [s for s in ("gyro", "acc") if cmap.declared.get(s) == "default"]
    if assumed:
        text += (f"; {' and '.join(_SHOW.get(_SI[s], _SI[s]) for s in assumed)} assumed (the header names no unit; "
                 f"{' or '.join(_OPTION[s] for s in assumed)} says another)")
    return "; ".join([text, *cmap.notes])
