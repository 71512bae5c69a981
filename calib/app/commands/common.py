"""What the ``calib`` commands share: the options of every command that reads a recording, the input
boundary with those options, the files behind an input (so no output lands on one), and the exit code of a
finished command (:func:`gyrosim.cli.status_exit`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from gyrosim.cli import status_exit
from gyrosim.cliargs import integer, number

__all__ = ["RATE", "RECORDING_HELP", "open_input", "input_files", "print_input_warnings", "input_options",
           "status_exit"]

RATE = number(0, 1e6, lo_open=True, unit="Hz")
RECORDING_HELP = (
    "recording: gyrosim .h5, BROAD .hdf5, CSV (t,gyro_x,gyro_y,gyro_z,acc_x,acc_y,acc_z[,temp][,mag_x,mag_y,"
    "mag_z]; separator , ; tab) or dataset:NAME — the format is read from the content"
)


def open_input(args: argparse.Namespace, requirements, path: str | None = None):
    """The input boundary for a command's recording (:func:`calib.inputs.open_recording`) with its options."""
    from calib.inputs import open_recording, parse_columns

    columns = getattr(args, "columns", None)
    return open_recording(
        path or args.recording,
        getattr(args, "gyro_unit", None),
        getattr(args, "acc_unit", None),
        requirements=requirements,
        time_unit=getattr(args, "time_unit", None),
        decimate=getattr(args, "decimate", None),
        columns=parse_columns(columns) if columns else None,
        topic=getattr(args, "topic", None),
    )


def input_files(*specs: str | None) -> list[str]:
    """The files behind the inputs a command was given (``dataset:NAME`` → the measured files), so
    that no output can land on one of them."""
    from gyrosim.loaders import data_root

    out: list[str] = []
    for spec in specs:
        if spec is None:
            continue
        if str(spec).startswith("dataset:"):
            name = str(spec)[len("dataset:"):]
            root = data_root()
            where = root / "broad" / f"{name.split('/', 1)[1]}.hdf5" if name.startswith("broad/") else root / name
            out += [str(f) for f in (where.rglob("*") if where.is_dir() else [where]) if f.is_file()][:1000]
        elif Path(spec).is_dir():
            out += [str(f) for f in Path(spec).rglob("*") if f.is_file()][:1000]
        else:
            out.append(str(spec))
    return out


def print_input_warnings(warnings) -> None:
    """The input boundary's warnings, one ``input:`` line each (an InputReport or its list of warnings)."""
    for w in getattr(warnings, "warnings", warnings):
        print(f"  input: {w}")


def _decimate_arg(text: str) -> int | str:
    if text.strip().lower() == "auto":
        return "auto"
    return integer(1, 1_000_000)(text)


def input_options(p: argparse.ArgumentParser, decimate: bool = False) -> None:
    """Options every command reading a recording shares (calib.inputs)."""
    p.add_argument("--gyro-unit", default=None, help="unit of the gyro columns when the header names none: rad/s "
                                                     "(default), deg/s, mdeg/s, rad/h, deg/h")
    p.add_argument("--acc-unit", default=None, help="unit of the accelerometer columns when the header names none: "
                                                    "m/s^2 (default), g, mg, ug")
    p.add_argument("--columns", default=None, metavar="t=COL,gyro_x=COL,...",
                   help="which file column holds which channel, when the header is not one calib recognises "
                        "(channels: t, gyro_x..z, acc_x..z, temp, mag_x..z; units from the names or the options)")
    p.add_argument("--topic", default=None, help="the sensor_msgs/Imu topic of a ROS bag (needed when it has several)")
    p.add_argument("--time-unit", default=None, choices=("auto", "s", "ms", "us", "ns"),
                   help="unit of the time column (default auto: seconds unless the step makes that implausible; "
                        "ms, µs, ns and Unix epochs are then converted with a warning)")
    if decimate:
        p.add_argument("--decimate", type=_decimate_arg, default=None, metavar="N|auto",
                       help="average blocks of N samples first (auto: the smallest N that brings the rate within "
                            "what the method supports, 1 kHz for the filter)")
