"""Reading a CSV recording (text already decoded by :mod:`calib.inputs.sniff`).

Layout: a header row naming the columns, then one row per sample.  Required columns
``t,gyro_x,gyro_y,gyro_z,acc_x,acc_y,acc_z`` (any order, any case, surrounding spaces and quotes
ignored); known optional columns ``temp`` (°C; empty cells between the readings of a slower
thermometer are interpolated) and ``mag_x,mag_y,mag_z`` (µT, body frame).  Any other column is
listed in a note and ignored.  The time column may carry its unit in its name (``t_ms``,
``time [us]``, ``timestamp_ns``, ...): that unit is then used as declared.  Lines starting with
``#`` are comments.  Separators ``,`` ``;`` tab ``|`` or spaces; with ``;``, tab or spaces, decimal
commas (``0,125``) are read as decimal points.

Every refusal names the line (1-based, as an editor shows it) and the column.
"""

from __future__ import annotations

import csv
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from gyrosim.recording import Recording
from gyrosim.units import to_si

from calib.inputs.errors import FieldError, FormatError, TimeBaseError, TooShortError
from calib.inputs.sniff import SEPARATOR_NAMES, detect_separator

__all__ = ["CSV_COLUMNS", "KNOWN_COLUMNS", "CsvRead", "read_csv_text", "resample_temperature"]

CSV_COLUMNS = ("t", "gyro_x", "gyro_y", "gyro_z", "acc_x", "acc_y", "acc_z")
KNOWN_COLUMNS = {"temp": "°C", "mag_x": "µT", "mag_y": "µT", "mag_z": "µT"}
_TIME_NAMES = {"t": None, "time": None, "timestamp": None}
_TIME_UNITS = {"s": "s", "sec": "s", "ms": "ms", "us": "us", "µs": "us", "μs": "us", "ns": "ns"}
_ALIASES = {"temperature": "temp", "temp_c": "temp", "mag_x_ut": "mag_x", "mag_y_ut": "mag_y", "mag_z_ut": "mag_z"}


@dataclass
class CsvRead:
    """What the reader made of the file: the recording, the declared time unit (from the column
    name, else None) and notes for the report."""

    recording: Recording
    time_unit: str | None
    separator: str
    columns: tuple[str, ...]
    ignored_columns: tuple[str, ...]
    notes: list[str] = field(default_factory=list)


def _norm(name: str) -> str:
    return name.strip().strip("\"'").strip().lower()


def _time_column(name: str) -> tuple[bool, str | None]:
    """(is it the time column, unit named in it)."""
    m = re.fullmatch(r"(t|time|timestamp)(?:[ _]*[\[(]?\s*(s|sec|ms|us|µs|μs|ns)\s*[\])]?)?", name)
    if not m:
        return False, None
    return True, _TIME_UNITS[m.group(2)] if m.group(2) else None


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


def _split_rows(lines: list[tuple[int, str]], sep: str) -> list[list[str]]:
    texts = [s for _, s in lines]
    if sep == " ":
        return [s.split() for s in texts]
    return list(csv.reader(texts, delimiter=sep))


def _cells(line: str, sep: str) -> list[str]:
    return line.split() if sep == " " else next(csv.reader([line], delimiter=sep))


def _fast_float(texts: list[str], sep: str, n_fields: int) -> np.ndarray | None:
    """All rows at once (C parser) when every cell is a plain number; None → the cell-by-cell path,
    which names the first bad cell."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            flat = np.fromstring(sep.join(texts), dtype=float, sep=sep)
        except (ValueError, DeprecationWarning):
            return None
    if flat.size != len(texts) * n_fields:
        return None
    return flat.reshape(len(texts), n_fields)


def _to_float(rows: list[list[str]], lines: list[tuple[int, str]], header: list[str], allow_empty: set[int],
              path: Path) -> np.ndarray:
    """rows → float array; the first bad cell is named with its line and column."""
    try:
        return np.array(rows, dtype=float)
    except ValueError:
        pass
    out = np.empty((len(rows), len(header)))
    for i, r in enumerate(rows):
        for j, v in enumerate(r):
            s = v.strip()
            if not s:
                if j in allow_empty:
                    out[i, j] = np.nan
                    continue
                raise FieldError(f"{path}: line {lines[i][0]}, column {header[j]!r} is empty; every row needs "
                                 "a number in every inertial column: fill or drop that row")
            try:
                out[i, j] = float(s)
            except ValueError:
                raise FieldError(f"{path}: line {lines[i][0]}, column {header[j]!r}: {s[:40]!r} is not a number; "
                                 "only numbers are allowed below the header") from None
    return out


def read_csv_text(text: str, path: Path, gyro_unit: str, acc_unit: str) -> CsvRead:
    """Parse the decoded text of a CSV recording (see the module docstring)."""
    raw_lines = text.splitlines()
    ends_with_newline = text.endswith(("\n", "\r"))
    lines = [
        (i + 1, s)
        for i, s in enumerate(raw_lines)
        if s and s[0] != "#" and not ((s[0] in " \t" or s[-1] in " \t") and (not s.strip() or s.lstrip()[0] == "#"))
    ]
    if not lines:
        raise FormatError(f"{path} holds no rows (only blank or comment lines): not a recording")
    (header_line, header_text), body = lines[0], lines[1:]
    sep = detect_separator(header_text, body[0][1] if body else None)
    header = [_norm(h) for h in (header_text.split() if sep == " " else next(csv.reader([header_text], delimiter=sep)))]
    if not any(re.search(r"[a-z]", h) for h in header):
        raise FormatError(f"{path}: line {header_line} is not a header ({header_text[:60]!r}); the first row must name "
                          f"the columns: {','.join(CSV_COLUMNS)}[,temp][,mag_x,mag_y,mag_z]")
    header = [_ALIASES.get(h, h) for h in header]
    time_unit = None
    for j, h in enumerate(header):
        is_t, unit = _time_column(h)
        if is_t and "t" not in header[:j] + header[j + 1:]:
            header[j], time_unit = "t", unit
            break
    dup = sorted({h for h in header if header.count(h) > 1 and h})
    if dup:
        raise FormatError(f"{path}: column(s) {dup} appear more than once in the header (line {header_line}); "
                          "name each column once")
    missing = [c for c in CSV_COLUMNS if c not in header]
    if missing:
        how = SEPARATOR_NAMES.get(sep, repr(sep))
        raise FormatError(
            f"{path}: missing column(s) {missing} in the header (line {header_line}, read with separator {how}: "
            f"{len(header)} column(s) {header[:8]}{' …' if len(header) > 8 else ''}); the CSV needs a header "
            f"{','.join(CSV_COLUMNS)}[,temp][,mag_x,mag_y,mag_z]")
    notes = []
    if sep != ",":
        notes.append(f"read with separator {SEPARATOR_NAMES.get(sep, repr(sep))}")
    if not body:
        raise FormatError(f"{path} has a header but no data rows: not a recording")
    n_fields = len(header)
    texts = [t for _, t in body]
    simple = sep != " " and not any('"' in t for t in texts[:1000]) and '"' not in "".join(texts[1000:])
    rows = None if simple else _split_rows(body, sep)
    counts = (np.fromiter((t.count(sep) + 1 for t in texts), dtype=np.int64, count=len(texts)) if simple
              else np.fromiter((len(r) for r in rows), dtype=np.int64, count=len(rows)))
    if counts.size and counts[-1] < n_fields and not ends_with_newline and np.all(counts[:-1] == n_fields):
        notes.append(f"the last line ({body[-1][0]}) has {counts[-1]} of {n_fields} fields and no line end: the file "
                     "was cut mid-write; that line is dropped")
        body, counts, texts = body[:-1], counts[:-1], texts[:-1]
        rows = None if rows is None else rows[:-1]
    bad = np.flatnonzero(counts != n_fields)
    if bad.size:
        k = int(bad[0])
        raise FieldError(
            f"{path}: line {body[k][0]} has {counts[k]} field(s) but the header (line {header_line}) has {n_fields} "
            f"(separator {SEPARATOR_NAMES.get(sep, repr(sep))}); {bad.size} row(s) differ: fix or drop them")
    if not body:
        raise FormatError(f"{path} has a header but no complete data rows: not a recording")
    if len(body) < 2:
        raise TooShortError(f"{path} has 1 data row (line {body[0][0]}): a recording needs at least 2 samples")
    if sep in (";", "\t", " ") and "," in texts[0] and "." not in texts[0]:
        texts = [t.replace(",", ".") for t in texts]
        body = [(i, t) for (i, _), t in zip(body, texts)]
        rows = None if rows is None else _split_rows(body, sep)
        notes.append("decimal commas read as decimal points")
    col = {name: j for j, name in enumerate(header)}
    allow_empty = {col["temp"]} if "temp" in col else set()
    data = _fast_float(texts, sep, n_fields) if rows is None else None
    if data is None:
        data = _to_float(rows if rows is not None else _split_rows(body, sep), body, header, allow_empty, path)
    core = [col[c] for c in CSV_COLUMNS]
    nonfinite = ~np.isfinite(data[:, core])
    if nonfinite.any():
        i, j = np.argwhere(nonfinite)[0]
        raise FieldError(
            f"{path}: line {body[i][0]}, column {CSV_COLUMNS[j]!r} is {_cells(body[i][1], sep)[core[j]].strip()!r}: "
            "NaN/inf is not a "
            f"measurement ({int(nonfinite.sum())} such value(s)); drop or interpolate those rows"
        )
    t = data[:, col["t"]]
    dt = np.diff(t)
    if np.any(dt <= 0):
        same = (dt == 0) & np.all(data[1:] == data[:-1], axis=1)
        if same.any():
            keep = np.concatenate([[True], ~same])
            notes.append(f"{int(same.sum())} row(s) repeat the previous row exactly (same time and values): dropped")
            data, body = data[keep], [b for b, k in zip(body, keep) if k]
            t = data[:, col["t"]]
            dt = np.diff(t)
    if np.any(dt <= 0):
        k = int(np.argmax(dt <= 0))
        what = "repeats" if dt[k] == 0 else "is before"
        raise TimeBaseError(
            f"{path}: line {body[k + 1][0]} (t = {float(t[k + 1])!r}) {what} line {body[k][0]} (t = {float(t[k])!r}): "
            "timestamps must "
            f"be strictly increasing ({int(np.sum(dt <= 0))} such step(s)); sort or de-duplicate the rows first"
        )
    unknown = [h for h in header if h not in CSV_COLUMNS and h not in KNOWN_COLUMNS]
    mag_cols = [c for c in ("mag_x", "mag_y", "mag_z") if c in col]
    if mag_cols and len(mag_cols) < 3:
        notes.append(f"magnetometer column(s) {mag_cols} without the other axes: ignored (needs mag_x, mag_y, mag_z)")
        unknown += mag_cols
    if unknown:
        notes.append(f"column(s) {unknown} are not known (t, gyro_*, acc_*, temp, mag_*): ignored")
    g = np.asarray(to_si(1.0, gyro_unit, "rate")) * data[:, [col["gyro_x"], col["gyro_y"], col["gyro_z"]]]
    a = np.asarray(to_si(1.0, acc_unit, "acceleration")) * data[:, [col["acc_x"], col["acc_y"], col["acc_z"]]]
    meta = {"source": str(path), "gyro_unit": gyro_unit, "acc_unit": acc_unit}
    temp = resample_temperature(t, data[:, col["temp"]], meta, str(path)) if "temp" in col else None
    if "temperature_note" in meta:
        notes.append(meta["temperature_note"])
    mag = None
    if len(mag_cols) == 3:
        mag = data[:, [col["mag_x"], col["mag_y"], col["mag_z"]]]
        bad_m = ~np.isfinite(mag).all(axis=1)
        if bad_m.any():
            notes.append(f"the magnetometer has {int(bad_m.sum())} empty/NaN row(s) (first at line "
                         f"{body[int(np.argmax(bad_m))][0]}): "
                         "the mag columns are ignored")
            mag = None
    used = [c for c in header if c not in unknown]
    rec = Recording(t_s=t, gyro_rad_s=g, acc_m_s2=a, temp_c=temp, mag_ut=mag, meta=meta)
    return CsvRead(rec, time_unit, sep, tuple(used), tuple(unknown), notes)
