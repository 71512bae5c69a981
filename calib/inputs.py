"""Reading recordings for calibration, and the input checks every method relies on.

Accepted inputs: a gyrosim HDF5 recording, or a CSV with a header row
``t,gyro_x,gyro_y,gyro_z,acc_x,acc_y,acc_z[,temp]`` (s, rad/s, m/s², °C unless ``gyro_unit`` /
``acc_unit`` say otherwise).  Checks (each raises :class:`~gyrosim.errors.RecordingError` with what
is wrong and what to do, or returns a named warning):

* NaN/inf values and non-monotonic time (the ``Recording`` constructor);
* gaps: a step Δt > 1.5 × the median step;
* units: a gyro whose rates reach more than 35 rad/s (2000 °/s, beyond any MEMS range) is almost
  certainly in °/s; an accelerometer whose resting magnitude is ~1 is in g;
* saturation: runs of ≥ 3 equal samples at a channel's extreme value (clipped at the rail), in
  channels where equal consecutive samples are otherwise rare (< 5 % of the other steps): a
  noise-free or coarsely quantized channel repeats values everywhere, and a flat top there says
  nothing.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from gyrosim.errors import RecordingError
from gyrosim.recording import Recording, load_hdf5
from gyrosim.units import to_si

__all__ = ["InputCheck", "load_recording", "check_recording", "CSV_COLUMNS"]

CSV_COLUMNS = ("t", "gyro_x", "gyro_y", "gyro_z", "acc_x", "acc_y", "acc_z")
MAX_PLAUSIBLE_RATE_RAD_S = 35.0  # 2000 °/s: the largest MEMS full scale


@dataclass(frozen=True)
class InputCheck:
    """What the input checks found that is not fatal (``warnings``: named, for the JSON)."""

    warnings: tuple[str, ...]
    saturated: np.ndarray  # per-sample mask: at a rail on any channel

    @property
    def saturated_samples(self) -> int:
        return int(self.saturated.sum())


def _read_csv(path: Path, gyro_unit: str, acc_unit: str) -> Recording:
    with path.open(newline="") as fh:
        reader = csv.reader(fh)
        try:
            header = [h.strip().lower() for h in next(reader)]
        except StopIteration as exc:
            raise RecordingError(f"{path} is empty") from exc
        rows = [r for r in reader if r and any(c.strip() for c in r)]
    missing = [c for c in CSV_COLUMNS if c not in header]
    if missing:
        raise RecordingError(
            f"{path}: missing column(s) {missing}; the CSV needs a header {','.join(CSV_COLUMNS)}[,temp]"
        )
    try:
        data = np.array([[float(v) if v.strip() else np.nan for v in r] for r in rows], dtype=float)
    except ValueError as exc:
        raise RecordingError(f"{path}: non-numeric value ({exc}); only numbers are allowed below the header") from exc
    col = {name: header.index(name) for name in header}
    g = np.asarray(to_si(data[:, [col["gyro_x"], col["gyro_y"], col["gyro_z"]]].ravel().tolist(), gyro_unit, "rate")).reshape(-1, 3)
    a = np.asarray(to_si(data[:, [col["acc_x"], col["acc_y"], col["acc_z"]]].ravel().tolist(), acc_unit, "acceleration")).reshape(-1, 3)
    meta = {"source": str(path), "gyro_unit": gyro_unit, "acc_unit": acc_unit}
    temp = resample_temperature(data[:, col["t"]], data[:, col["temp"]], meta, str(path)) if "temp" in col else None
    return Recording(t_s=data[:, col["t"]], gyro_rad_s=g, acc_m_s2=a, temp_c=temp, meta=meta)


def resample_temperature(t_s: np.ndarray, temp_c: np.ndarray, meta: dict, where: str) -> np.ndarray | None:
    """A temperature column logged at a lower rate than the inertial rows (empty cells between
    readings) is interpolated linearly onto every row, held beyond the first/last reading, and
    ``meta['temperature_note']`` says so.  No reading at all → None with a note; a reading only at
    isolated rows is fine (that is what a slower thermometer looks like)."""
    ok = np.isfinite(temp_c)
    if ok.all():
        return temp_c
    if ok.sum() < 2:
        meta["temperature_note"] = f"{where}: the temp column has {int(ok.sum())} reading(s): ignored"
        return None
    rate = (ok.sum() - 1) / max(t_s[ok][-1] - t_s[ok][0], 1e-12)
    meta["temperature_note"] = (f"{where}: temperature given on {int(ok.sum())} of {ok.size} rows (≈ {rate:.3g} Hz); "
                                "resampled linearly onto the inertial clock")
    return np.interp(t_s, t_s[ok], temp_c[ok])


def load_recording(path: str | Path, gyro_unit: str = "rad/s", acc_unit: str = "m/s^2") -> Recording:
    """Load a recording; files are only read, never modified.

    Accepts a gyrosim HDF5, a BROAD trial (HDF5 as published), a CSV in the layout above, a
    measured-data folder known to :mod:`gyrosim.loaders`, or ``dataset:NAME`` (e.g.
    ``dataset:broad/02_undisturbed_slow_rotation_B``) resolved under ``$GYROSIM_DATA``.
    """
    from gyrosim import loaders

    if str(path).startswith("dataset:"):
        return loaders.load_dataset(str(path)[len("dataset:"):])
    path = Path(path)
    if path.is_dir():
        for name in loaders.available_datasets(path.parent):
            if name == path.name:
                return loaders.load_dataset(name, path.parent)
        raise RecordingError(f"{path} is a folder but not a known measured dataset ({', '.join(loaders.available_datasets(path.parent)) or 'none'})")
    if not path.is_file():
        raise RecordingError(f"no such recording: {path}")
    if path.suffix.lower() in (".h5", ".hdf5"):
        with h5py.File(path, "r") as f:
            is_broad = "imu_gyr" in f and "t" not in f
        if is_broad:
            return loaders.load_broad(path)
        rec = load_hdf5(path)
        if gyro_unit != "rad/s" or acc_unit not in ("m/s^2", "m/s²"):
            f_g = to_si(1.0, gyro_unit, "rate")
            f_a = to_si(1.0, acc_unit, "acceleration")
            rec = rec.with_signals(gyro_rad_s=rec.gyro_rad_s * f_g, acc_m_s2=rec.acc_m_s2 * f_a)
        return rec
    if path.suffix.lower() in (".csv", ".txt"):
        return _read_csv(path, gyro_unit, acc_unit)
    raise RecordingError(f"{path}: unknown file type {path.suffix!r}; use a gyrosim .h5 or a .csv")


def _saturated(x: np.ndarray, run: int = 3) -> np.ndarray:
    """Samples in runs of ≥ ``run`` equal values at the channel's extreme |value| (per sample)."""
    bad = np.zeros(x.shape[0], dtype=bool)
    for i in range(x.shape[1]):
        c = x[:, i]
        peak = float(np.max(np.abs(c)))
        if peak == 0:
            continue
        equal = c[1:] == c[:-1]
        at = np.abs(c) >= peak * (1 - 1e-9)
        pair = at[1:] & at[:-1] & equal  # sample k and k+1 equal and at the rail
        if equal[~pair].mean() > 0.05:
            continue  # repeats are normal away from the extreme too: a flat top is no evidence of a rail
        edges = np.diff(np.concatenate([[0], pair.astype(np.int8), [0]]))
        starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
        for s0, s1 in zip(starts, stops):
            if s1 - s0 + 1 >= run:  # s1 - s0 equal pairs = s1 - s0 + 1 samples
                bad[s0 : s1 + 1] = True
    return bad


def check_recording(rec: Recording, *, allow_gaps: bool = False) -> InputCheck:
    """Gaps, units and saturation checks (see module docstring); raises on what is fatal.

    ``allow_gaps``: a caller that integrates over the actual Δt (``calib closeloop``) gets the gaps
    as a warning instead of an error."""
    dt = np.diff(rec.t_s)
    med = float(np.median(dt))
    gaps = np.flatnonzero(dt > 1.5 * med)
    gap_warning = []
    if gaps.size and allow_gaps:
        gap_warning.append(f"{gaps.size} gap(s) in time up to {dt.max() * 1e3:.1f} ms ({dt.max() / med:.1f} × the "
                           f"{med * 1e3:.3f} ms step), first at t = {rec.t_s[int(gaps[0])]:.4f} s")
    elif gaps.size:
        k = int(gaps[0])
        raise RecordingError(
            f"{gaps.size} gap(s) in time: the first from t = {rec.t_s[k]:.4f} s to {rec.t_s[k + 1]:.4f} s "
            f"({dt[k] / med:.1f} × the {med * 1e3:.3f} ms step); the strapdown integration cannot cross "
            "a gap: split the recording or fill it"
        )
    peak = float(np.max(np.abs(rec.gyro_rad_s)))
    if peak > MAX_PLAUSIBLE_RATE_RAD_S:
        raise RecordingError(
            f"the gyro reaches {peak:.1f} rad/s ({np.degrees(peak):.0f} °/s), beyond any MEMS range: the "
            "rates are probably in deg/s; pass --gyro-unit deg/s (gyro_unit='deg/s')"
        )
    f_med = float(np.median(np.linalg.norm(rec.acc_m_s2, axis=1)))
    if 0.5 < f_med < 2.0:
        raise RecordingError(
            f"the accelerometer's median magnitude is {f_med:.3f}: that is gravity in g, not m/s²; "
            "pass --acc-unit g (acc_unit='g')"
        )
    if not 7.0 < f_med < 13.0:
        raise RecordingError(
            f"the accelerometer's median magnitude is {f_med:.3f} m/s², far from gravity (9.81): check "
            "--acc-unit and that the accelerometer channels are the ones named acc_x, acc_y, acc_z"
        )
    sat = _saturated(rec.gyro_rad_s) | _saturated(rec.acc_m_s2)
    warnings = gap_warning
    if sat.any():
        warnings.append(
            f"saturated: {int(sat.sum())} sample(s) sit at a rail (runs of equal extreme values); they are "
            "excluded from the filter's measurement updates"
        )
    return InputCheck(tuple(warnings), sat)
