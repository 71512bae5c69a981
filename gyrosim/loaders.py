"""Loaders for measured IMU recordings (``../shared/data`` or ``$GYROSIM_DATA``) into ``Recording``.

Measured data are never part of the project: they are read from a folder, by default
``../shared/data`` next to the checkout, or the folder named by the environment variable
``GYROSIM_DATA``.  Every loader keeps the source's attribution (``meta['source']``,
``meta['licence']``) and states its unit conversions in ``meta['conversion']``.

The data sets, by name (loader: units and notes):

``broad/<trial>``
    :func:`load_broad`: rad/s, m/s², µT; truth: optical ``opt_quat`` (ENU), position, ``movement``
    mask.
``imu_tk_xsens``
    :func:`load_imu_tk`: raw 16-bit counts; nominal gyro 1/6258 rad/s per count about 32768; acc
    scaled so the first rest reads g.
``imucal_ferraris``
    :func:`load_ferraris`: °/s, m/s² at 102.4 Hz; protocol segments in ``meta['segments']``.
``xio_fusion``
    :func:`load_xio_fusion`: °/s, g, µT; own timestamps.
``xio_ximu_thermometer``
    :func:`load_xio_thermometer`: °/s, g, G at 256 Hz; 4 Hz thermometer resampled onto the inertial
    clock by packet number.
"""

from __future__ import annotations

import csv
import json
import os
from pathlib import Path

import h5py
import numpy as np

from .errors import RecordingError
from .recording import Recording, Truth
from .units import DEG, G0

__all__ = ["data_root", "available_datasets", "describe_available", "load_dataset", "load_broad", "load_imu_tk",
           "load_ferraris", "load_xio_fusion", "load_xio_thermometer"]



def data_root() -> Path:
    """``$GYROSIM_DATA`` if set, else ``../shared/data`` beside the checkout (or the working folder)."""
    env = os.environ.get("GYROSIM_DATA")
    if env:
        return Path(env)
    here = Path(__file__).resolve().parents[2] / "shared" / "data"
    return here if here.is_dir() else Path.cwd().parent / "shared" / "data"


def _where(root: Path, given: bool) -> str:
    """Where the data were looked for, and why there (for the messages of :func:`load_dataset`)."""
    if given:
        return f"{root}"
    env = os.environ.get("GYROSIM_DATA")
    if env:
        return f"{root} (GYROSIM_DATA)"
    return f"{root} (the default: GYROSIM_DATA is not set)"


def _dataset_missing(name: str, root: Path, given: bool) -> RecordingError:
    """The error for a dataset name that is not there: where it looked, what is there, what to do."""
    where = _where(root, given)
    if not root.is_dir():
        return RecordingError(f"dataset:{name}: no data folder at {where}; set GYROSIM_DATA to the folder that holds "
                              "the measured recordings (broad/, xio_fusion/, ...)")
    return RecordingError(f"dataset:{name} is not in {where}; available: {describe_available(root)}; check the "
                          "name, or set GYROSIM_DATA to the folder that holds it")


def describe_available(root: str | Path | None = None) -> str:
    """The names of :func:`available_datasets` on one line: the BROAD trials by number (``broad/02_…``)."""
    names = available_datasets(root)
    broad = [n for n in names if n.startswith("broad/")]
    out = [n for n in names if not n.startswith("broad/")]
    if broad:
        nums = ", ".join(n.split("/", 1)[1].split("_", 1)[0] for n in broad)
        out.append(f"broad/<trial> for {len(broad)} BROAD trials (numbers {nums}; e.g. {broad[0]})")
    return ", ".join(out) if out else "none"


def _source(folder: Path) -> str:
    p = folder / "SOURCE.txt"
    return p.read_text().strip() if p.is_file() else ""


def _licence(folder: Path) -> str:
    for name in ("LICENSE", "LICENSE.md", "LICENSE.txt"):
        if (folder / name).is_file():
            return (folder / name).read_text().strip().splitlines()[0]
    return "see SOURCE.txt"


def load_broad(path: str | Path) -> Recording:
    """A BROAD trial (Laidig et al., Data 6(7) 2021, CC BY 4.0) as published (HDF5)."""
    path = Path(path)
    with h5py.File(path, "r") as f:
        missing = [k for k in ("imu_gyr", "imu_acc", "opt_quat", "movement") if k not in f]
        if missing:
            raise RecordingError(f"{path}: not a BROAD trial (missing {missing})")
        fs = float(f.attrs["sampling_rate"])
        gyro, acc, mag = f["imu_gyr"][()], f["imu_acc"][()], f["imu_mag"][()] if "imu_mag" in f else None
        quat, pos, movement = f["opt_quat"][()], f["opt_pos"][()] if "opt_pos" in f else None, f["movement"][()]
    n = gyro.shape[0]
    truth = Truth(quat_nb=quat, position_nav_m=pos, extra={"movement": movement.astype(float)})
    return Recording(
        t_s=np.arange(n) / fs,
        gyro_rad_s=gyro,
        acc_m_s2=acc,
        mag_ut=mag,
        truth=truth,
        meta={
            "rate_hz": fs,
            "source": f"BROAD {path.stem}; {_source(path.parent)}",
            "licence": "CC BY 4.0 (Laidig et al., BROAD, Data 6(7):72, 2021)",
            "conversion": "none (rad/s, m/s², µT as published); truth quat = opt_quat (sensor→ENU, w,x,y,z; NaN where "
                          "occluded)",
            "dataset": f"broad/{path.stem}",
        },
    )


def _read_table(path: Path) -> np.ndarray:
    with path.open(newline="") as fh:
        rows = [r for r in csv.reader(fh)]
    return np.array([[float(v) for v in r] for r in rows[1:] if r], dtype=float)


def load_imu_tk(folder: str | Path) -> Recording:
    """The imu_tk Xsens multi-position data (Tedaldi et al., ICRA 2014; BSD).

    Raw counts: gyro ω = (c − 32768)/6258 rad/s (the nominal scale of imu_tk's example); the
    accelerometer has no nominal scale in the source, so a = (c − 32768)·k with k chosen so that
    the first 40 s (the initial rest) reads |a| = g₀: a self-consistent nominal, to be calibrated.
    """
    folder = Path(folder)
    g = np.loadtxt(folder / "xsens_gyro.mat")
    a = np.loadtxt(folder / "xsens_acc.mat")
    if g.shape != a.shape or g.shape[1] != 4:
        raise RecordingError(f"{folder}: expected two t,x,y,z tables of equal length")
    if not np.allclose(g[:, 0], a[:, 0]):
        raise RecordingError(f"{folder}: gyro and accelerometer timestamps differ")
    t = g[:, 0] - g[0, 0]
    gyro = (g[:, 1:] - 32768.0) / 6258.0
    counts = a[:, 1:] - 32768.0
    rest = t < 40.0
    k = G0 / float(np.mean(np.linalg.norm(counts[rest], axis=1)))
    return Recording(
        t_s=t, gyro_rad_s=gyro, acc_m_s2=counts * k,
        meta={"source": _source(folder), "licence": "BSD (imu_tk README)", "dataset": "imu_tk_xsens",
              "conversion": f"gyro (c−32768)/6258 rad/s; acc (c−32768)·{k:.6g} m/s² (|a| = g₀ over the first 40 s)"},
    )


def load_ferraris(folder: str | Path) -> Recording:
    """imucal's Ferraris example session (NilsPod, 102.4 Hz; MIT): segments in ``meta['segments']``."""
    folder = Path(folder)
    data = _read_table(folder / "example_ferraris_session.csv")
    fs = 102.4
    segments = json.loads((folder / "example_ferraris_session_list.json").read_text())
    return Recording(
        t_s=data[:, 0] / fs, gyro_rad_s=data[:, 1:4] * DEG, acc_m_s2=data[:, 4:7],
        meta={"rate_hz": fs, "source": _source(folder), "licence": _licence(folder), "dataset": "imucal_ferraris",
              "segments": segments, "conversion": "gyro °/s → rad/s; t = sample / 102.4 Hz"},
    )


def load_xio_fusion(path: str | Path) -> Recording:
    """x-io Fusion's example hand-held recording (x-IMU3; MIT)."""
    path = Path(path)
    data = _read_table(path)
    return Recording(
        t_s=data[:, 0], gyro_rad_s=data[:, 1:4] * DEG, acc_m_s2=data[:, 4:7] * G0, mag_ut=data[:, 7:10],
        meta={"source": _source(path.parent), "licence": _licence(path.parent), "dataset": "xio_fusion",
              "conversion": "gyro °/s → rad/s; acc g → m/s² (g₀); mag µT"},
    )


def load_xio_thermometer(folder: str | Path) -> Recording:
    """x-IMU export with a thermometer channel (scikit-kinematics test data; BSD-3-Clause).

    Inertial samples at 256 Hz (t = k/256 s); the 4 Hz thermometer is resampled onto them by
    linear interpolation in *packet number*, the logger's common clock for both streams (its
    packets interleave), and held constant beyond the first/last reading.
    """
    folder = Path(folder)
    inert = _read_table(folder / "00033_CalInertialAndMag.csv")
    therm = _read_table(folder / "00033_CalBattAndTherm.csv")
    fs = 256.0
    packet = inert[:, 0]
    if np.any(np.diff(packet) <= 0):
        raise RecordingError(f"{folder}: inertial packet numbers are not increasing")
    temp = np.interp(packet, therm[:, 0], therm[:, 2])
    return Recording(
        t_s=np.arange(packet.size) / fs, gyro_rad_s=inert[:, 1:4] * DEG, acc_m_s2=inert[:, 4:7] * G0,
        temp_c=temp, mag_ut=inert[:, 7:10] * 100.0,
        meta={"rate_hz": fs, "source": _source(folder), "licence": _licence(folder), "dataset": "xio_ximu_thermometer",
              "conversion": "gyro °/s → rad/s; acc g → m/s²; mag G → µT; thermometer (4 Hz) resampled onto the "
                            "256 Hz inertial samples by packet number (linear)"},
    )


def available_datasets(root: str | Path | None = None) -> list[str]:
    """Names of the measured recordings present under ``root`` (default :func:`data_root`)."""
    root = Path(root) if root else data_root()
    out = []
    if (root / "broad").is_dir():
        out += [f"broad/{p.stem}" for p in sorted((root / "broad").glob("*.hdf5"))]
    for name, probe in (("imu_tk_xsens", "xsens_gyro.mat"), ("imucal_ferraris", "example_ferraris_session.csv"),
                        ("xio_fusion", "sensor_data.csv"), ("xio_ximu_thermometer", "00033_CalInertialAndMag.csv")):
        if (root / name / probe).is_file():
            out.append(name)
    return out


def load_dataset(name: str, root: str | Path | None = None) -> Recording:
    """Load a measured recording by its name in :func:`available_datasets`.  A name that is not there
    raises :class:`RecordingError` naming the folder looked in (and ``GYROSIM_DATA``) and the names
    that are."""
    given = root is not None
    root = Path(root) if root else data_root()
    loaders = {"imu_tk_xsens": lambda: load_imu_tk(root / "imu_tk_xsens"),
               "imucal_ferraris": lambda: load_ferraris(root / "imucal_ferraris"),
               "xio_fusion": lambda: load_xio_fusion(root / "xio_fusion" / "sensor_data.csv"),
               "xio_ximu_thermometer": lambda: load_xio_thermometer(root / "xio_ximu_thermometer")}
    if not root.is_dir() or name not in available_datasets(root):
        raise _dataset_missing(name, root, given)
    if name.startswith("broad/"):
        return load_broad(root / "broad" / f"{name.split('/', 1)[1]}.hdf5")
    return loaders[name]()
