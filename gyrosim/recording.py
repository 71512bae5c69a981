"""One ``Recording`` type for simulated and measured IMU data, and its HDF5 file format.

HDF5 layout (all arrays float64, one row per sample; see docs/recording-format.md):

    /t                      (N,)   s, strictly increasing
    /gyro                   (N,3)  rad/s, body frame (RFU)
    /acc                    (N,3)  m/s², specific force, body frame (RFU)
    /temp                   (N,)   °C                      optional
    /mag                    (N,3)  µT, body frame          optional
    /truth/omega            (N,3)  rad/s, body            true angular rate (gyro site)
    /truth/specific_force   (N,3)  m/s², body            true specific force (accelerometer site)
    /truth/quat             (N,4)  (w,x,y,z) body→navigation (ENU)
    /truth/position         (N,3)  m, navigation (ENU), accelerometer site
    /truth/<other>          extra truth channels (e.g. external_acc, omega_schedule, wrist_position)
    root attributes: rate_hz, frames ("body RFU, navigation ENU"), schedule, hand, sensor_model
                     (JSON strings), seed, version, and any other metadata (JSON-encoded if not a
                     number or string).

Files are written to a temporary name in the target folder and renamed into place, so a failed
write leaves nothing half-written, with the mode the user's umask gives a new file (0644 under the
usual 022); the same content always gives the same bytes (no timestamps).
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from .errors import RecordingError
from .outputs import atomic_path

__all__ = ["Truth", "Recording", "save_hdf5", "load_hdf5", "save_csv", "FRAMES", "CSV_HEADER_UNITS"]

FRAMES = "body RFU, navigation ENU"

_TRUTH_CORE = {
    "omega": "omega_body_rad_s",
    "specific_force": "specific_force_body_m_s2",
    "quat": "quat_nb",
    "position": "position_nav_m",
}


def _readonly(a: np.ndarray | None) -> np.ndarray | None:
    if a is None:
        return None
    a = np.array(a, dtype=float, copy=True)
    a.setflags(write=False)
    return a


def vector_rms(x: np.ndarray | None) -> float:
    """√(mean_k |x_k|²) of an (N, 3) series (NaN for None): the RMS of a vector's magnitude."""
    if x is None:
        return float("nan")
    return math.sqrt(float(np.mean(np.sum(np.asarray(x) ** 2, axis=1))))


@dataclass(frozen=True)
class Truth:
    """Ground truth of a recording. Frames and units are in the field names.

    ``extra`` holds further named truth channels of the same length (e.g. ``external_acc``:
    non-gravity acceleration at the accelerometer site in the body frame, m/s²;
    ``omega_schedule``: the schedule's commanded body rate, rad/s).
    """

    omega_body_rad_s: np.ndarray | None = None
    specific_force_body_m_s2: np.ndarray | None = None
    quat_nb: np.ndarray | None = None
    position_nav_m: np.ndarray | None = None
    extra: dict[str, np.ndarray] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for name in _TRUTH_CORE.values():
            object.__setattr__(self, name, _readonly(getattr(self, name)))
        object.__setattr__(self, "extra", {k: _readonly(v) for k, v in self.extra.items()})

    @property
    def external_acc_m_s2(self) -> np.ndarray | None:
        """Non-gravity acceleration at the accelerometer site, body frame (m/s²), a_e = f − g_b: what the
        hand adds to gravity (``extra['external_acc']``, written by the simulator); None when absent."""
        return self.extra.get("external_acc")

    @property
    def rate_disturbance_rad_s(self) -> np.ndarray | None:
        """True body rate minus the schedule's commanded rate, body frame (rad/s): the hand's rotational
        disturbance ω − ω_schedule (wobble, tremor); None without ``extra['omega_schedule']``."""
        if self.omega_body_rad_s is None or "omega_schedule" not in self.extra:
            return None
        return self.omega_body_rad_s - self.extra["omega_schedule"]

    def disturbance_rms(self) -> tuple[float, float]:
        """(RMS of |a_e| in m/s², RMS of |ω − ω_schedule| in rad/s) over the session, NaN where absent:
        √(mean_k |x_k|²), the severity axes of the campaigns."""
        return vector_rms(self.external_acc_m_s2), vector_rms(self.rate_disturbance_rad_s)

    def channels(self) -> dict[str, np.ndarray]:
        """All present truth channels by their HDF5 name (``omega``, ``quat``, ..., extras)."""
        out = {h5: getattr(self, attr) for h5, attr in _TRUTH_CORE.items() if getattr(self, attr) is not None}
        out.update(self.extra)
        return out


@dataclass(frozen=True)
class Recording:
    """IMU samples with optional truth and metadata. Arrays are copied and made read-only.

    Attributes
    ----------
        t_s: sample times (s), strictly increasing.
        gyro_rad_s: angular rate (rad/s), body frame RFU, shape (N, 3).
        acc_m_s2: specific force (m/s²), body frame RFU, shape (N, 3).
        temp_c: sensor temperature (°C), shape (N,), optional.
        mag_ut: magnetic field (µT), body frame, shape (N, 3), optional.
        truth: :class:`Truth` or None.
        meta: metadata (rate_hz, frames, schedule, hand, sensor_model, seed, version, source, licence ...).
    """

    t_s: np.ndarray
    gyro_rad_s: np.ndarray
    acc_m_s2: np.ndarray
    temp_c: np.ndarray | None = None
    mag_ut: np.ndarray | None = None
    truth: Truth | None = None
    meta: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for name in ("t_s", "gyro_rad_s", "acc_m_s2", "temp_c", "mag_ut"):
            object.__setattr__(self, name, _readonly(getattr(self, name)))
        object.__setattr__(self, "meta", dict(self.meta))
        n = self.t_s.shape[0] if self.t_s.ndim == 1 else -1
        if n < 2:
            raise RecordingError(f"t must be a 1-D array of at least 2 times, got shape {self.t_s.shape}")
        self._check("gyro", self.gyro_rad_s, (n, 3))
        self._check("acc", self.acc_m_s2, (n, 3))
        if self.temp_c is not None:
            self._check("temp", self.temp_c, (n,))
        if self.mag_ut is not None:
            self._check("mag", self.mag_ut, (n, 3))
        bad_t = ~np.isfinite(self.t_s)
        if bad_t.any():
            raise RecordingError(f"t has {bad_t.sum()} non-finite value(s), first at sample {np.argmax(bad_t)}")
        dt = np.diff(self.t_s)
        if np.any(dt <= 0):
            k = int(np.argmax(dt <= 0))
            raise RecordingError(
                f"timestamps are not strictly increasing: t[{k}] = {float(self.t_s[k])!r} s, "
                f"t[{k + 1}] = {float(self.t_s[k + 1])!r} s; sort or de-duplicate the samples first"
            )
        if self.truth is not None:
            for key, arr in self.truth.channels().items():
                if arr.shape[0] != n:
                    raise RecordingError(f"truth/{key} has {arr.shape[0]} rows but t has {n}")

    @staticmethod
    def _check(name: str, arr: np.ndarray, shape: tuple[int, ...]) -> None:
        if arr.shape != shape:
            raise RecordingError(f"{name} has shape {arr.shape}, expected {shape}")
        bad = ~np.isfinite(arr)
        if bad.any():
            row = int(np.argmax(bad.reshape(shape[0], -1).any(axis=1)))
            raise RecordingError(
                f"{name} has {int(bad.sum())} NaN/inf value(s), first at sample {row}; "
                "drop or interpolate those samples before use"
            )

    @property
    def n(self) -> int:
        return int(self.t_s.shape[0])

    @property
    def rate_hz(self) -> float:
        """Nominal sample rate: meta['rate_hz'] if present, else 1/median(Δt)."""
        if "rate_hz" in self.meta:
            return float(self.meta["rate_hz"])
        return float(1.0 / np.median(np.diff(self.t_s)))

    @property
    def duration_s(self) -> float:
        return float(self.t_s[-1] - self.t_s[0])

    def with_signals(self, **changes: Any) -> "Recording":
        """A copy with some fields replaced (e.g. corrupted gyro); the original is untouched."""
        return replace(self, **changes)


def _attr_value(v: Any) -> Any:
    if isinstance(v, (str, int, float, np.integer, np.floating)) and not isinstance(v, bool):
        return v
    return json.dumps(v, sort_keys=True)


def _writable_folder(path: Path) -> None:
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise RecordingError(f"cannot write {path}: folder {folder} does not exist; create it first")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise RecordingError(f"cannot write {path}: folder {folder} is not writable; choose a writable folder")


def save_hdf5(rec: Recording, path: str | os.PathLike[str]) -> Path:
    """Write ``rec`` to ``path`` atomically (temp file in the same folder, then rename), with the mode
    a new file gets under the user's umask (0644 under the usual 022).

    Raises :class:`RecordingError` if the folder does not exist or is not writable; an existing
    file at ``path`` is replaced only once the new one is complete.
    """
    path = Path(path)
    _writable_folder(path)
    try:
        with atomic_path(path) as tmp, h5py.File(tmp, "w", track_order=False) as f:
            def put(name: str, arr: np.ndarray) -> None:
                f.create_dataset(name, data=np.asarray(arr, dtype=np.float64), track_times=False)

            put("t", rec.t_s)
            put("gyro", rec.gyro_rad_s)
            put("acc", rec.acc_m_s2)
            if rec.temp_c is not None:
                put("temp", rec.temp_c)
            if rec.mag_ut is not None:
                put("mag", rec.mag_ut)
            if rec.truth is not None:
                f.create_group("truth", track_order=False)
                for key, arr in sorted(rec.truth.channels().items()):
                    put(f"truth/{key}", arr)
            meta = {"frames": FRAMES, **rec.meta}
            for key in sorted(meta):
                f.attrs[key] = _attr_value(meta[key])
    except PermissionError as exc:
        raise RecordingError(f"cannot write {path}: {exc.strerror}; choose a writable folder") from exc
    return path


CSV_HEADER_UNITS = {"t": "t_s", "gyro": ("gyro_x_rad_s", "gyro_y_rad_s", "gyro_z_rad_s"),
                    "acc": ("acc_x_m_s2", "acc_y_m_s2", "acc_z_m_s2"), "temp": "temp_c",
                    "mag": ("mag_x_ut", "mag_y_ut", "mag_z_ut")}


def save_csv(rec: Recording, path: str | os.PathLike[str]) -> Path:
    """Write ``rec``'s samples as CSV with the unit in every column name: ``t_s,gyro_x_rad_s,gyro_y_rad_s,
    gyro_z_rad_s,acc_x_m_s2,acc_y_m_s2,acc_z_m_s2[,temp_c][,mag_x_ut,mag_y_ut,mag_z_ut]`` — s, rad/s, m/s²,
    °C, µT, body frame RFU (calib reads these names, and the plain ``t,gyro_x,…`` of older files, back).
    17 significant digits (float64 round-trips exactly).  Truth and metadata are not written (use HDF5
    for those).  Atomic like :func:`save_hdf5`, with the same file mode."""
    path = Path(path)
    _writable_folder(path)
    cols = [rec.t_s[:, None], rec.gyro_rad_s, rec.acc_m_s2]
    h = CSV_HEADER_UNITS
    header = [h["t"], *h["gyro"], *h["acc"]]
    if rec.temp_c is not None:
        cols.append(rec.temp_c[:, None])
        header.append(h["temp"])
    if rec.mag_ut is not None:
        cols.append(rec.mag_ut)
        header += list(h["mag"])
    data = np.hstack(cols)
    with atomic_path(path) as tmp:
        np.savetxt(tmp, data, delimiter=",", header=",".join(header), comments="", fmt="%.17g")
    return path


def _decode(v: Any) -> Any:
    if isinstance(v, bytes):
        v = v.decode()
    if isinstance(v, np.generic):
        v = v.item()
    if isinstance(v, str) and v[:1] in "{[":
        try:
            return json.loads(v)
        except json.JSONDecodeError:
            return v
    return v


def load_hdf5(path: str | os.PathLike[str]) -> Recording:
    """Read a gyrosim HDF5 recording (layout in the module docstring). The file is opened read-only."""
    path = Path(path)
    if not path.is_file():
        raise RecordingError(f"no such recording: {path}")
    with h5py.File(path, "r") as f:
        missing = [k for k in ("t", "gyro", "acc") if k not in f]
        if missing:
            raise RecordingError(
                f"{path} lacks dataset(s) {missing}: not a gyrosim recording "
                "(for BROAD or CSV files use gyrosim.loaders)"
            )
        truth = None
        if "truth" in f:
            chans = {k: f["truth"][k][()] for k in f["truth"]}
            core = {attr: chans.pop(h5) for h5, attr in _TRUTH_CORE.items() if h5 in chans}
            truth = Truth(**core, extra=chans)
        meta = {k: _decode(v) for k, v in f.attrs.items()}
        return Recording(
            t_s=f["t"][()],
            gyro_rad_s=f["gyro"][()],
            acc_m_s2=f["acc"][()],
            temp_c=f["temp"][()] if "temp" in f else None,
            mag_ut=f["mag"][()] if "mag" in f else None,
            truth=truth,
            meta=meta,
        )
