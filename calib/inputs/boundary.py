"""The input boundary: one entry for every command, in a fixed order.

:func:`open_recording` (a path) = :func:`read_recording` (format by content) + :func:`prepare_recording`
(a Recording), which runs, in order:

1. time base — unit of the time column (:mod:`~calib.inputs.timebase`), stated rate consistency;
2. degenerate data — dead axes, constant sensors, raw counts (:mod:`~calib.inputs.degenerate`);
3. spikes — isolated corrupt samples excluded and counted, corrupt stretches refused (:mod:`~calib.inputs.spikes`);
4. gaps — a few missing samples bridged, longer gaps refused or listed (:mod:`~calib.inputs.gaps`);
5. rate — decimation if asked, then the method's rate range (:mod:`~calib.inputs.decimate`);
6. length — the method's minimum samples and duration;
7. units — accelerometer magnitude, gyro peak, rest level and gravity consistency (:mod:`~calib.inputs.plausibility`);
8. motion — a moving record where the method needs one, a still one for Allan (:mod:`~calib.inputs.motion`).

:func:`check_recording` is the cheap re-check every method runs on the Recording it is given
(library callers included): it refuses what the boundary would have repaired or refused, and
returns the saturation and exclusion masks.  The Recording's ``meta['input_repairs']`` holds the
samples the boundary inserted or repaired (as [start, stop) ranges) so that the method makes no
measurement update there.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from gyrosim.errors import GyrosimError, RecordingError
from gyrosim.recording import Recording
from gyrosim.units import to_si

from calib.inputs.csvfile import read_csv_text
from calib.inputs.decimate import decimate as _decimate
from calib.inputs.decimate import decimation_factor
from calib.inputs.degenerate import degenerate_problems
from calib.inputs.errors import (
    DegenerateError,
    FormatError,
    GapError,
    InputError,
    MotionError,
    RateError,
    SpikeError,
    TimeBaseError,
    TooShortError,
    UnitError,
)
from calib.inputs.gaps import Gaps, bridge_gaps, find_gaps, gaps_warning
from calib.inputs.hdf5file import read_hdf5
from calib.inputs.motion import rotation_consistency, summarise_motion
from calib.inputs.plausibility import acc_unit_problem, gyro_unit_problem
from calib.inputs.report import InputCheck, InputReport, Loaded
from calib.inputs.requirements import GENERIC, Requirements
from calib.inputs.saturation import saturated_samples
from calib.inputs.sniff import SEPARATOR_NAMES, sniff
from calib.inputs.spikes import find_spikes, repair_spikes
from calib.inputs.timebase import (
    AmbiguousTimeUnit,
    TimeBase,
    detect_time_unit,
    normalise_time_unit,
    time_base,
    to_seconds,
)

__all__ = ["read_recording", "prepare_recording", "open_recording", "load_recording", "check_recording",
           "ReadInfo", "repaired_mask", "MAX_INSERTED_FRACTION"]

MAX_INSERTED_FRACTION = 0.10   # more bridged samples than this: a lossy link, not a few dropped packets
STATIC_MOVING_FRACTION = 0.01  # Allan: at most 1 % of 1-s windows may move


@dataclass
class ReadInfo:
    """What the reader found out about the file."""

    source: str
    format: str
    encoding: str | None = None
    separator: str | None = None
    columns: tuple[str, ...] = ()
    ignored_columns: tuple[str, ...] = ()
    time_unit: str | None = None
    notes: list[str] = field(default_factory=list)


def _convert_units(rec: Recording, gyro_unit: str | None, acc_unit: str | None) -> Recording:
    gyro_unit, acc_unit = gyro_unit or "rad/s", acc_unit or "m/s^2"
    f_g = float(to_si(1.0, gyro_unit, "rate"))
    f_a = float(to_si(1.0, acc_unit, "acceleration"))
    meta = {**rec.meta, "gyro_unit": gyro_unit, "acc_unit": acc_unit}
    if f_g == 1.0 and f_a == 1.0:
        return Recording(rec.t_s, rec.gyro_rad_s, rec.acc_m_s2, rec.temp_c, rec.mag_ut, rec.truth, meta)
    return Recording(rec.t_s, rec.gyro_rad_s * f_g, rec.acc_m_s2 * f_a, rec.temp_c, rec.mag_ut, rec.truth, meta)


def _read_dataset(name: str, gyro_unit: str | None, acc_unit: str | None) -> tuple[Recording, ReadInfo]:
    from gyrosim import loaders

    try:
        rec = loaders.load_dataset(name)
    except RecordingError as err:  # a name that is not there: the message names the folder and what is
        raise FormatError(str(err)) from err
    given = gyro_unit not in (None, "rad/s") or acc_unit not in (None, "m/s^2", "m/s²")
    info = ReadInfo(f"dataset:{name}", "measured dataset", notes=[] if not given else
                    [f"--gyro-unit/--acc-unit ignored: dataset {name} is converted to SI by its loader"])
    return rec, info


def _refuse_options(p: Path, what: str, columns: dict[str, str] | None, topic: str | None) -> None:
    """A column mapping is for CSV files and a topic for ROS bags: given for another input, it is a mistake."""
    if columns and what != "CSV":
        raise FormatError(f"{p} is {what}, not a CSV: a column mapping (--columns) applies to CSV files only")
    if topic is not None and what != "ROS bag":
        raise FormatError(f"{p} is {what}, not a ROS bag: --topic applies to ROS bags only")


def read_recording(path: str | Path, gyro_unit: str | None = None, acc_unit: str | None = None, *,
                   columns: dict[str, str] | None = None, topic: str | None = None) -> tuple[Recording, ReadInfo]:
    """Read a file (format by content), a measured-data folder, a ROS 2 bag folder, or ``dataset:NAME``;
    no checks beyond what reading needs.  Files are only read, never modified.

    ``gyro_unit``/``acc_unit``: the user's units (None: the file's, else rad/s and m/s²; a CSV header
    that says another unit is refused); ``columns``: a CSV column mapping channel → column name
    (:func:`calib.inputs.columns.parse_columns`); ``topic``: the ``sensor_msgs/Imu`` topic of a ROS bag
    (:mod:`calib.inputs.rosbag`)."""
    from gyrosim import loaders

    from calib.inputs.rosbag import is_bag_folder, read_rosbag

    for unit, q in ((gyro_unit, "rate"), (acc_unit, "acceleration")):
        if unit is not None:
            to_si(1.0, unit, q)  # an unknown unit is refused before anything is read
    if str(path).startswith("dataset:"):
        _refuse_options(Path(str(path)), "a measured dataset", columns, topic)
        return _read_dataset(str(path)[len("dataset:"):], gyro_unit, acc_unit)
    p = Path(path)
    if is_bag_folder(p):
        _refuse_options(p, "ROS bag", columns, None)
        rec, notes, _ = read_rosbag(p, "ROS 2 bag folder", topic)
        return _bag_units(rec, gyro_unit, acc_unit, p), ReadInfo(str(p), "ROS 2 bag", notes=notes, time_unit="s")
    if p.is_dir():
        _refuse_options(p, "a folder", columns, topic)
        for name in loaders.available_datasets(p.parent):
            if name == p.name:
                return loaders.load_dataset(name, p.parent), ReadInfo(str(p), "measured dataset")
        raise FormatError(f"{p} is a folder but not a known measured dataset "
                          f"({', '.join(loaders.available_datasets(p.parent)) or 'none'}) nor a ROS 2 bag; give a file")
    if not p.exists():
        raise FormatError(f"no such recording: {p}")
    if not p.is_file():
        raise FormatError(f"{p} is not a regular file")
    try:
        s = sniff(p)
    except PermissionError as exc:
        raise FormatError(f"cannot read {p}: {exc.strerror}") from exc
    if s.kind == "rosbag":
        _refuse_options(p, "ROS bag", columns, None)
        rec, notes, _ = read_rosbag(p, s.encoding, topic)
        return _bag_units(rec, gyro_unit, acc_unit, p), ReadInfo(str(p), s.encoding, notes=notes, time_unit="s")
    if s.kind == "hdf5":
        _refuse_options(p, "HDF5", columns, topic)
        rec, notes = read_hdf5(p)
        info = ReadInfo(str(p), "HDF5 (BROAD)" if notes else "HDF5 (gyrosim)", notes=list(notes))
        if notes:  # BROAD: SI as published
            return rec, info
        return _convert_units(rec, gyro_unit, acc_unit), info
    _refuse_options(p, "CSV", columns, topic)
    r = read_csv_text(s.text, p, gyro_unit, acc_unit, columns)
    info = ReadInfo(str(p), "CSV", s.encoding, r.separator, r.columns, r.ignored_columns, r.time_unit,
                    list(s.notes) + r.notes)
    return r.recording, info


def _bag_units(rec: Recording, gyro_unit: str | None, acc_unit: str | None, p: Path) -> Recording:
    """sensor_msgs/Imu is rad/s and m/s² by definition: a unit option that says otherwise is refused."""
    for unit, si, q, opt in ((gyro_unit, "rad/s", "rate", "--gyro-unit"),
                             (acc_unit, "m/s^2", "acceleration", "--acc-unit")):
        if unit is not None and float(to_si(1.0, unit, q)) != 1.0:
            raise UnitError(f"{p}: sensor_msgs/Imu holds {si} (REP 145) but {opt} says {unit}: drop {opt}")
    return rec


def _ranges(mask: np.ndarray) -> list[list[int]]:
    edges = np.diff(np.concatenate([[0], np.asarray(mask, bool).astype(np.int8), [0]]))
    return [[int(a), int(b)] for a, b in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1))]


def repaired_mask(rec: Recording) -> np.ndarray:
    """Samples the boundary inserted or repaired (``meta['input_repairs']``), as a (N,) mask."""
    out = np.zeros(rec.n, bool)
    rep = rec.meta.get("input_repairs")
    if isinstance(rep, dict):
        for ranges in rep.values():
            for a, b in ranges if isinstance(ranges, list) else []:
                out[max(0, int(a)):min(rec.n, int(b))] = True
    return out


def _time_unit_from_motion(rec: Recording, candidates: tuple[str, ...]):
    """The one candidate time unit under which the gyro and the gravity direction agree, else None."""
    agree = []
    for u in candidates:
        tb = time_base(rec.t_s, u, "from motion")
        trial = Recording(to_seconds(rec.t_s, tb), rec.gyro_rad_s, rec.acc_m_s2)
        c = rotation_consistency(trial, summarise_motion(trial).rest_level_rad_s, factors=(1.0, 1e-3, 1e3))
        if c.pairs >= 5 and c.verdict() is None and c.errors_deg[1.0] < 10.0:
            agree.append((u, tb, c))
    if len(agree) != 1:
        return None
    u, tb, c = agree[0]
    others = ", ".join(x for x in candidates if x != u)
    note = (f"time unit {u} chosen from the motion: the time column counts whole units and {others} would also give a "
            f"plausible rate, but only in {u} does the gyro's rotation agree with the gravity direction the "
            f"accelerometer sees (median {c.errors_deg[1.0]:.1f}° over {c.pairs} moves); pass --time-unit to override")
    return TimeBase(tb.unit, tb.how, tb.origin, tb.origin_unix_s, f"{note}; {tb.warning}" if tb.warning else note)


def _digest(rec: Recording) -> str:
    """A fingerprint of the checked signals: per channel the plain and the index-weighted sum (any change
    of a sample moves one of them), hashed with the shapes.  Not a cryptographic hash; it guards against
    signals edited after the check (``with_signals``), at 1/50 the cost of hashing every byte."""
    h = hashlib.blake2b(digest_size=16)
    for x in (rec.t_s, rec.gyro_rad_s, rec.acc_m_s2, rec.mag_ut):
        if x is not None:
            xt = np.ascontiguousarray(np.asarray(x, dtype=float).reshape(x.shape[0], -1).T)  # channel-major
            w = np.arange(1, xt.shape[1] + 1, dtype=float)
            weighted = (xt * w).sum(axis=1)  # not x @ w: BLAS threads spin on a loaded machine
            h.update(np.array(xt.shape, dtype=np.int64).tobytes() + xt.sum(axis=1).tobytes() + weighted.tobytes())
    return h.hexdigest()


def _describe_spikes(spk, t: np.ndarray) -> str:
    per = ", ".join(f"{k}: {v}" for k, v in spk.per_channel().items())
    first = int(np.argmax(spk.any_sample))
    return f"{spk.count} isolated corrupt sample(s) (spikes; {per}; first at t = {t[first]:.4f} s)"


@dataclass
class _Pass:
    """One recording on its way through :func:`prepare_recording`'s steps: the recording as repaired so far, which
    samples were repaired, what was said and what was found wrong (raised at once when ``strict``)."""

    rec: Recording
    req: Requirements
    where: str
    warnings: list[str]
    repaired: np.ndarray
    problems: list[str] = field(default_factory=list)

    def fail(self, err: InputError) -> None:
        """Raise ``err`` (strict requirements) or keep it as a problem."""
        if self.req.strict:
            raise err
        self.problems.append(f"{err.kind}: {err}")

    def replace(self, **fields) -> None:
        """The recording with ``fields`` replaced (t_s, meta, …)."""
        r = self.rec
        args = dict(t_s=r.t_s, gyro_rad_s=r.gyro_rad_s, acc_m_s2=r.acc_m_s2, temp_c=r.temp_c, mag_ut=r.mag_ut,
                    truth=r.truth, meta=r.meta)
        args.update(fields)
        self.rec = Recording(**args)


def prepare_recording(rec: Recording, requirements: Requirements = GENERIC, *, time_unit: str | None = None,
                      decimate: int | str | None = None, info: ReadInfo | None = None) -> Loaded:
    """Run the boundary's checks and repairs on ``rec`` for a method (module docstring).

    Returns the recording to use (possibly converted, bridged, repaired, decimated; ``rec`` itself
    is not modified) and the :class:`InputReport`.  Raises an :class:`InputError` subclass on what
    the method cannot use, unless ``requirements.strict`` is False (then it is in ``problems``)."""
    info = info or ReadInfo(str(rec.meta.get("source", rec.meta.get("dataset", "recording"))), "Recording")
    ps = _Pass(rec, requirements, info.source, list(info.notes), repaired_mask(rec))
    tb = _time_base(ps, time_unit or info.time_unit)                       # 1. time base
    measured_rate = _stated_rate(ps)
    # 2. degenerate data (before spikes: robust statistics of a constant channel are meaningless)
    degenerate = degenerate_problems(ps.rec, ps.req.sensors)
    if degenerate:
        ps.fail(DegenerateError(f"{ps.where}: " + "; ".join(degenerate)))
    spikes_found = {} if degenerate else _spikes(ps)                     # 3. spikes
    bridged, inserted_n = _gaps(ps)                                      # 4. gaps
    n_dec, rate = _rate(ps, decimate, measured_rate, tb)                 # 5. rate
    _length(ps)                                                          # 6. length
    if not degenerate:                                                   # 7. units, 8. motion
        _units_and_motion(ps)
    _stamp(ps)
    rec = ps.rec
    sat = int((saturated_samples(rec.gyro_rad_s) | saturated_samples(rec.acc_m_s2)).sum()) if not degenerate else 0
    report = InputReport(
        source=ps.where, format=info.format, encoding=info.encoding,
        separator=SEPARATOR_NAMES.get(info.separator, info.separator) if info.separator else None,
        columns=info.columns, ignored_columns=info.ignored_columns, time_unit=tb.unit if tb else "s",
        time_unit_how=tb.how if tb else "unknown", time_origin_unix_s=tb.origin_unix_s if tb else None,
        samples=rec.n, duration_s=float(rec.t_s[-1] - rec.t_s[0]), rate_hz=rate, bridged_gaps=bridged,
        inserted_samples=inserted_n, spikes=spikes_found, saturated_samples=sat, decimated_by=n_dec,
        warnings=tuple(ps.warnings), problems=tuple(ps.problems))
    return Loaded(rec, report)


def _time_base(ps: _Pass, time_unit: str | None):
    """Step 1: the time column's unit and origin, converted to seconds from the start."""
    rec, tb = ps.rec, None
    try:
        tb = detect_time_unit(rec.t_s, ps.req, time_unit, rec.meta.get("rate_hz") if
                              isinstance(rec.meta.get("rate_hz"), (int, float)) else None, ps.where)
    except AmbiguousTimeUnit as err:
        tb = _time_unit_from_motion(rec, err.candidates)
        if tb is None:
            ps.fail(err)
    except TimeBaseError as err:
        ps.fail(err)
    meta = dict(rec.meta)
    if tb is not None and (tb.factor != 1.0 or tb.origin != 0.0):
        t_new = to_seconds(rec.t_s, tb)
        if np.any(np.diff(t_new) <= 0):  # pragma: no cover - float rounding of huge epochs
            ps.fail(TimeBaseError(f"{ps.where}: the time column does not increase after conversion to s"))
        else:
            if tb.origin_unix_s is not None:
                meta["time_origin_unix_s"] = tb.origin_unix_s
            ps.replace(t_s=t_new, meta=meta)
    if tb is not None and tb.warning:
        ps.warnings.append(tb.warning)
    return tb


def _stated_rate(ps: _Pass) -> float:
    """The rate the timestamps step at (Hz); a stated ``rate_hz`` that disagrees is replaced, with a warning."""
    measured_rate = 1.0 / float(np.median(np.diff(ps.rec.t_s)))
    meta = dict(ps.rec.meta)
    stated = meta.get("rate_hz")
    if isinstance(stated, (int, float)) and not isinstance(stated, bool):
        if not (math.isfinite(stated) and stated > 0 and abs(measured_rate / stated - 1) < 0.02):
            ps.warnings.append(f"the file states rate_hz = {stated:g} but the timestamps step at {measured_rate:.6g} "
                               "Hz: the timestamps are used")
            meta["rate_hz"] = measured_rate
            ps.replace(meta=meta)
    return measured_rate


def _spikes(ps: _Pass) -> dict[str, int]:
    """Step 3: isolated spikes repaired (interpolated, no measurement update); corrupt stretches refused."""
    rec, req, where = ps.rec, ps.req, ps.where
    spk = find_spikes(rec)
    if spk.stretches:
        ch, a, b = spk.stretches[0]
        ps.fail(
            SpikeError(
                f"{where}: {ch} holds a corrupt stretch of {b - a + 1} samples (t = "
                f"{rec.t_s[a]:.4f}–{rec.t_s[b]:.4f} s) "
                "far outside the rest of its "
                f"data{f' and {len(spk.stretches) - 1} more' if len(spk.stretches) > 1 else ''}; "
                "too long to be excluded as spikes: cut that part of the recording"
            )
        )
    elif spk.count > max(1, req.max_spike_fraction * rec.n):
        ps.fail(
            SpikeError(
                f"{where}: {_describe_spikes(spk, rec.t_s)} — more than {req.max_spike_fraction:.0%} of the "
                "samples: the data are corrupt, not occasionally glitched; fix the logger or the export"
            )
        )
    elif spk.count:
        ps.rec = repair_spikes(rec, spk)
        ps.repaired |= spk.any_sample
        ps.warnings.append(f"{_describe_spikes(spk, ps.rec.t_s)} excluded: replaced by interpolation between their "
                           "neighbours and given no measurement update")
        return spk.per_channel()
    return {}


def _gaps(ps: _Pass) -> tuple[int, int]:
    """Step 4: short gaps bridged (linear interpolation, no measurement update); longer ones allowed or refused as
    the method requires.  Returns (gaps bridged, samples inserted)."""
    req, where = ps.req, ps.where
    gaps = find_gaps(ps.rec.t_s)
    bridged, inserted_n = 0, 0
    if not gaps.count:
        return bridged, inserted_n
    small = gaps.missing <= req.max_bridged_gap_samples
    if small.any() and gaps.missing[small].sum() <= MAX_INSERTED_FRACTION * ps.rec.n:
        sub = Gaps(gaps.index[small], gaps.missing[small], gaps.step_s, gaps.jitter_s, gaps.bound_s)
        old_n = ps.rec.n
        ps.rec, inserted = bridge_gaps(ps.rec, sub)
        new_repaired = np.zeros(ps.rec.n, bool)
        new_repaired[~inserted] = ps.repaired[:old_n]
        ps.repaired = new_repaired | inserted
        bridged, inserted_n = sub.count, int(inserted.sum())
        ps.warnings.append(
            f"bridged {bridged} gap(s) of {int(sub.missing.min())}–{int(sub.missing.max())} missing sample(s) "
            f"({inserted_n} sample(s) interpolated linearly, no measurement update there; first at t = "
            f"{ps.rec.t_s[int(np.argmax(inserted))]:.4f} s)")
        gaps = find_gaps(ps.rec.t_s)
    elif small.any():
        ps.fail(GapError(f"{where}: {int(gaps.missing[small].sum())} samples are missing in {int(small.sum())} short "
                         "gaps "
                         f"(more than {MAX_INSERTED_FRACTION:.0%} of the record): a lossy link, not a few dropped "
                         "packets; fix the logging"))
    if gaps.count:
        if req.gaps == "allow":
            ps.warnings.append(gaps_warning(gaps, ps.rec.t_s))
        else:
            ps.fail(
                GapError(
                    f"{where}: {gaps.describe(ps.rec.t_s)}; gaps of up to {req.max_bridged_gap_samples} missing "
                    "samples are bridged, this one is longer: the strapdown integration cannot cross it; split "
                    "the recording or fill it"
                )
            )
    return bridged, inserted_n


def _rate(ps: _Pass, decimate: int | str | None, measured_rate: float, tb) -> tuple[int, float]:
    """Step 5: decimated when asked; a rate outside the method's range refused.  Returns (factor, rate in Hz)."""
    req, where = ps.req, ps.where
    n_dec = 1
    if decimate not in (None, 1, "1", "none"):
        if decimate == "auto":
            n_dec = decimation_factor(measured_rate, req.rate_hz[1]) if req.rate_hz else 1
        else:
            n_dec = int(decimate)
        if n_dec > 1:
            if ps.rec.n // n_dec < 2:
                ps.fail(TooShortError(f"{where}: decimating {ps.rec.n} samples by {n_dec} leaves fewer than 2"))
            else:
                ps.rec, ps.repaired = _decimate(ps.rec, n_dec, ps.repaired)
                ps.warnings.append(f"decimated by {n_dec} (block means): {measured_rate:.6g} Hz → "
                                   f"{measured_rate / n_dec:.6g} Hz")
    rate = 1.0 / float(np.median(np.diff(ps.rec.t_s)))
    if req.rate_hz is not None:
        lo, hi = req.rate_hz
        if rate > hi * 1.02:
            n = decimation_factor(rate, hi)
            ps.fail(RateError(
                f"{where}: {rate:.6g} Hz is above the {hi:g} Hz that {req.name} supports"
                + (f" ({req.why_max_rate})" if req.why_max_rate else "")
                + f"; pass {req.decimate_option} {n} (or auto) to average blocks of {n} samples → {rate / n:.6g} Hz"))
        elif rate < lo * 0.98:
            ps.fail(
                RateError(
                    f"{where}: {rate:.4g} Hz is below the {lo:g} Hz that {req.name} supports (the strapdown "
                    "integration between samples aliases the hand's motion); record at a higher rate"
                    + ("; if the time column is not in seconds, pass --time-unit" if tb and tb.unit == "s" else "")
                )
            )
    return n_dec, rate


def _length(ps: _Pass) -> None:
    """Step 6: enough samples and seconds for the method."""
    rec, req = ps.rec, ps.req
    duration = float(rec.t_s[-1] - rec.t_s[0])
    if rec.n < req.min_samples or duration < req.min_duration_s:
        need = " and ".join(
            [f"{req.min_samples} samples"] + ([f"{req.min_duration_s:g} s"] if req.min_duration_s else [])
        )
        ps.fail(TooShortError(f"{ps.where}: {rec.n} samples over {duration:.4g} s; {req.name} needs at least {need}"))


def _units_and_motion(ps: _Pass) -> None:
    """Steps 7 and 8: units plausible for the motion; the motion the method needs (static, or turning)."""
    rec, req, where = ps.rec, ps.req, ps.where
    motion = summarise_motion(rec)
    consistency = None
    if req.motion != "static" and motion.moving_fraction > 0:
        consistency = rotation_consistency(rec, motion.rest_level_rad_s)
    msgs = [m for m in (gyro_unit_problem(rec, motion, consistency), acc_unit_problem(rec)) if m]
    if msgs:
        ps.fail(UnitError(f"{where}: " + "; and ".join(msgs)))
    if req.motion == "static" and motion.moving_fraction > STATIC_MOVING_FRACTION:
        still = motion.longest_still()
        hint = (f"; its longest still stretch is t = {still[0]:.1f}–{still[1]:.1f} s: cut that out"
                if still and still[1] - still[0] >= 10 * motion.window_s else "")
        ps.fail(
            MotionError(
                f"{where}: the board moves in {motion.moving_fraction:.0%} of its 1-s windows (gravity turns by up "
                f"to {motion.gravity_swing_deg:.0f}°, the rate departs from its level by up to "
                f"{motion.peak_rate_rad_s:.2f} "
                f"rad/s; first at t = {motion.first_motion_s():.1f} s): {req.name} needs a static recording{hint}"
            )
        )
    if req.motion == "required" and motion.gravity_swing_deg < 10.0 and motion.peak_rate_rad_s < 0.2:
        ps.fail(
            MotionError(
                f"{where}: the board never turns (gravity stays within {motion.gravity_swing_deg:.1f}° "
                "and the rate within "
                f"{motion.peak_rate_rad_s:.3f} rad/s of its level): {req.name} estimates scale factors and "
                "non-orthogonality from rotations; for the noise of a static record use calib allan"
            )
        )


def _stamp(ps: _Pass) -> None:
    """The repairs and, when every check passed, the digest that lets the method's re-check skip the expensive ones."""
    meta = dict(ps.rec.meta)
    if ps.repaired.any():
        meta["input_repairs"] = {"excluded": _ranges(ps.repaired)}
    else:
        meta.pop("input_repairs", None)
    meta.pop("input_checked", None)
    if not ps.problems:  # every check passed: the method's re-check may skip the expensive ones for these bytes
        meta["input_checked"] = {"by": ps.req.name, "digest": _digest(ps.rec)}
    ps.replace(meta=meta)


def open_recording(path: str | Path, gyro_unit: str | None = None, acc_unit: str | None = None, *,
                   requirements: Requirements = GENERIC, time_unit: str | None = None,
                   decimate: int | str | None = None, columns: dict[str, str] | None = None,
                   topic: str | None = None) -> Loaded:
    """Read ``path`` (:func:`read_recording`: units, column mapping, ROS topic) and pass it through the
    boundary for ``requirements`` (module docstring)."""
    normalise_time_unit(time_unit)
    try:
        rec, info = read_recording(path, gyro_unit, acc_unit, columns=columns, topic=topic)
    except InputError:
        raise
    except RecordingError as err:  # the Recording's own checks (NaN, shapes, order) on an HDF5/dataset
        raise FormatError(f"{path}: {err}") from err
    except GyrosimError:
        raise
    return prepare_recording(rec, requirements, time_unit=time_unit, decimate=decimate, info=info)


def load_recording(path: str | Path, gyro_unit: str | None = None, acc_unit: str | None = None, *,
                   requirements: Requirements = GENERIC, time_unit: str | None = None,
                   decimate: int | str | None = None, columns: dict[str, str] | None = None,
                   topic: str | None = None) -> Recording:
    """Load a recording through the input boundary; files are only read, never modified.

    Accepts a gyrosim HDF5, a BROAD trial (HDF5 as published), a CSV (``t,gyro_x,gyro_y,gyro_z,
    acc_x,acc_y,acc_z[,temp][,mag_x,mag_y,mag_z]``, common loggers' headers, units in column names;
    see :mod:`calib.inputs.columns`), a ROS 1 or ROS 2 bag (``topic``: its ``sensor_msgs/Imu`` topic,
    needed when it has several), a measured-data folder known to :mod:`gyrosim.loaders`, or
    ``dataset:NAME`` resolved under ``$GYROSIM_DATA``.  The format is found from the content, not the
    name.  ``columns``: channel → CSV column name, e.g. ``{"t": "timestamp_ms", "gyro_x": "gx_dps", …}``;
    ``gyro_unit``/``acc_unit``: the units when the file does not say them (None: rad/s, m/s²).  Use
    :func:`open_recording` for the :class:`InputReport` (warnings) too."""
    return open_recording(path, gyro_unit, acc_unit, requirements=requirements, time_unit=time_unit,
                          decimate=decimate, columns=columns, topic=topic).recording


def check_recording(
    rec: Recording, *, allow_gaps: bool = False, requirements: Requirements | None = None
) -> InputCheck:
    """The check each method runs on the Recording it is given (library calls included).

    Refuses (raises an :class:`InputError` subclass): gaps (unless ``allow_gaps``: listed as a warning), degenerate
    channels, unrepaired spikes, accelerometer and gyro unit mistakes (peak and rest level), and — with ``requirements``
    — too short records, the wrong rate, or a stated ``rate_hz`` that the timestamps contradict.  A recording that
    passed :func:`prepare_recording` without a problem carries a fingerprint of its signals (``meta['input_checked']``);
    while the signals still match it, the degenerate, spike and unit checks are not repeated.  Returns the warnings, the
    saturation mask and the exclusion mask (saturated or repaired samples: no measurement update there)."""
    warnings: list[str] = []
    gaps = find_gaps(rec.t_s)
    if gaps.count and allow_gaps:
        warnings.append(gaps_warning(gaps, rec.t_s))
    elif gaps.count:
        raise GapError(
            f"{gaps.describe(rec.t_s)}; the strapdown integration cannot cross a gap: split the recording or "
            "fill it (calib.inputs.open_recording bridges gaps of a few samples)"
        )
    checked = rec.meta.get("input_checked")
    if not (isinstance(checked, dict) and checked.get("digest") == _digest(rec)):  # else: passed the boundary as is
        degenerate = degenerate_problems(rec)
        if degenerate:
            raise DegenerateError("; ".join(degenerate))
        spk = find_spikes(rec)
        if spk.count or spk.stretches:
            raise SpikeError(
                f"{_describe_spikes(spk, rec.t_s) if spk.count else 'a corrupt stretch'} in the recording: "
                "load it through calib.inputs.open_recording / prepare_recording, which excludes isolated "
                "spikes, or remove them"
            )
        msgs = [m for m in (gyro_unit_problem(rec, summarise_motion(rec)), acc_unit_problem(rec)) if m]
        if msgs:
            raise UnitError("; and ".join(msgs))
    rate = 1.0 / float(np.median(np.diff(rec.t_s)))
    stated = rec.meta.get("rate_hz")
    if isinstance(stated, (int, float)) and not isinstance(stated, bool) and not abs(rate / stated - 1) < 0.02:
        raise TimeBaseError(f"meta rate_hz = {stated:g} but the timestamps step at {rate:.6g} Hz: fix one of them "
                            "(calib.inputs.prepare_recording trusts the timestamps)")
    if requirements is not None:
        req = requirements
        duration = float(rec.t_s[-1] - rec.t_s[0])
        if rec.n < req.min_samples or duration < req.min_duration_s:
            raise TooShortError(f"{rec.n} samples over {duration:.4g} s; {req.name} needs at least {req.min_samples} "
                                f"samples and {req.min_duration_s:g} s")
        if req.rate_hz is not None and not (req.rate_hz[0] * 0.98 <= rate <= req.rate_hz[1] * 1.02):
            lo, hi = req.rate_hz
            raise RateError(f"{rate:.6g} Hz is outside the {lo:g}–{hi:g} Hz that {req.name} supports"
                            + ("; decimate it first (calib.inputs.prepare_recording(rec, decimate='auto'))"
                               if rate > hi else "; if the time is not in seconds, convert it"))
    sat = saturated_samples(rec.gyro_rad_s) | saturated_samples(rec.acc_m_s2)
    if sat.any():
        warnings.append(f"saturated: {int(sat.sum())} sample(s) sit at a rail (runs of equal extreme values); they are "
                        "excluded from the filter's measurement updates")
    return InputCheck(tuple(warnings), sat, sat | repaired_mask(rec))
