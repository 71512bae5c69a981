"""Reading a CSV recording (text already decoded by :mod:`calib.inputs.sniff`).

Layout: a header row naming the columns, then one row per sample.  Required columns
``t,gyro_x,gyro_y,gyro_z,acc_x,acc_y,acc_z`` (any order, any case, surrounding spaces and quotes
ignored); known optional columns ``temp`` (°C; empty cells between the readings of a slower
thermometer are interpolated) and ``mag_x,mag_y,mag_z`` (µT, body frame).  The headers of common
loggers, units in column names (``gx_dps``, ``Timestamp (us)``) and a user's column mapping are
resolved by :mod:`calib.inputs.columns`.  Any other column is listed in a note and ignored (it may
hold text: a date, a frame id).  The time column's unit, when its name says it (``t_ms``,
``time [us]``, ``timestamp_ns``, ...), is used as declared.  Lines starting with
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

from calib.inputs.columns import REQUIRED, ColumnMap, describe_units, resolve_columns
from calib.inputs.errors import FieldError, FormatError, TimeBaseError, TooShortError
from calib.inputs.sniff import SEPARATOR_NAMES, detect_separator

__all__ = ["CSV_COLUMNS", "KNOWN_COLUMNS", "CsvRead", "read_csv_text", "resample_temperature"]

CSV_COLUMNS = ("t", "gyro_x", "gyro_y", "gyro_z", "acc_x", "acc_y", "acc_z")
KNOWN_COLUMNS = {"temp": "°C", "mag_x": "µT", "mag_y": "µT", "mag_z": "µT"}


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


def _data_lines(text: str, path: Path) -> list[tuple[int, str]]:
    """(line number, text) of every line that is not blank or a comment."""
    lines = [
        (i + 1, s)
        for i, s in enumerate(text.splitlines())
        if s and s[0] != "#" and not ((s[0] in " \t" or s[-1] in " \t") and (not s.strip() or s.lstrip()[0] == "#"))
    ]
    if not lines:
        raise FormatError(f"{path} holds no rows (only blank or comment lines): not a recording")
    return lines


def _clean(name: str) -> str:
    return name.strip().strip("\"'").strip()


def _header(lines: list[tuple[int, str]], path: Path) -> tuple[int, str, list[str]]:
    """(line number, separator, cells) of the header row; refuses a first row that names nothing."""
    header_line, header_text = lines[0]
    sep = detect_separator(header_text, lines[1][1] if len(lines) > 1 else None)
    cells = [_clean(h) for h in _cells(header_text, sep)]
    if not any(re.search(r"[a-z]", h.lower()) for h in cells):
        raise FormatError(f"{path}: line {header_line} is not a header ({header_text[:60]!r}); the first row must name "
                          f"the columns: {','.join(CSV_COLUMNS)}[,temp][,mag_x,mag_y,mag_z]")
    return header_line, sep, cells


def _ximu_rate(path: Path) -> tuple[float, str]:
    """The inertial sample rate of an x-IMU GUI export, from the ``*_Registers.csv`` beside it
    (register InertialAndMagneticDataRate: code k → 2^(k−1) Hz)."""
    found = sorted(path.parent.glob(f"{path.name.split('_')[0]}_Registers.csv")) or sorted(
        path.parent.glob("*Registers.csv"))
    how = ("the x-IMU exports the sample rate in the Registers.csv file written beside it: copy that file next to "
           "this one, or add a time column")
    if len(found) != 1:
        raise FormatError(f"{path}: an x-IMU export ('Packet number', no time column) and "
                          f"{'no' if not found else 'more than one'} *_Registers.csv beside it; {how}")
    for row in csv.reader(found[0].read_text(errors="replace").splitlines()):
        if len(row) >= 5 and row[4].strip() == "InertialAndMagneticDataRate" and row[2].strip().isdigit():
            code = int(row[2])
            if code >= 1:
                return 2.0 ** (code - 1), found[0].name
    raise FormatError(f"{path}: {found[0].name} has no InertialAndMagneticDataRate register (or it is off); {how}")


def _require(cmap: ColumnMap, header: list[str], header_line: int, sep: str, path: Path) -> float | None:
    """Refuse a header without the required channels (naming them); an x-IMU export's missing time column
    is made from its sample rate (returned, else None)."""
    keys = [_clean(h).lower() for h in header]
    rate = None
    if "t" not in cmap.index and "packet number" in keys and all(c in cmap.index for c in REQUIRED[1:]):
        rate, _ = _ximu_rate(path)
        return rate
    missing = [c for c in REQUIRED if c not in cmap.index]
    if missing:
        how = SEPARATOR_NAMES.get(sep, repr(sep))
        raise FormatError(
            f"{path}: missing column(s) {missing} in the header (line {header_line}, read with separator {how}: "
            f"{len(keys)} column(s) {keys[:8]}{' …' if len(keys) > 8 else ''}); the CSV needs a header "
            f"{','.join(CSV_COLUMNS)}[,temp][,mag_x,mag_y,mag_z], or a column mapping (--columns t=…,gyro_x=…)")
    return rate


def _complete_rows(body: list[tuple[int, str]], sep: str, n_fields: int, header_line: int, ends_with_newline: bool,
                   path: Path, notes: list[str]) -> tuple[list[tuple[int, str]], list[str], list[list[str]] | None]:
    """The data rows, each with the header's field count: a last line cut mid-write is dropped (noted),
    any other count mismatch refused; decimal commas become points.  Returns (body, texts, split rows or
    None when the fast parser can take the texts as they are)."""
    if not body:
        raise FormatError(f"{path} has a header but no data rows: not a recording")
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
    return body, texts, rows


def _column(cells: list[str], j: int, name: str, body: list[tuple[int, str]], allow_empty: bool,
            path: Path) -> tuple[np.ndarray, tuple[int, FieldError] | None]:
    """One column's cells → floats, or the first bad cell (row index, its error)."""
    try:
        return np.array(cells, dtype=float), None
    except ValueError:
        pass
    out = np.empty(len(cells))
    for i, v in enumerate(cells):
        s = v.strip()
        if not s and allow_empty:
            out[i] = np.nan
            continue
        if not s:
            return out, (i, FieldError(f"{path}: line {body[i][0]}, column {name!r} is empty; every row needs a number "
                                       "in every inertial column: fill or drop that row"))
        try:
            out[i] = float(s)
        except ValueError:
            return out, (i, FieldError(f"{path}: line {body[i][0]}, column {name!r}: {s[:40]!r} is not a number; "
                                       "only numbers are allowed below the header"))
    return out, None


def _numbers(body: list[tuple[int, str]], texts: list[str], rows: list[list[str]] | None, sep: str,
             header: list[str], used: dict[str, int], path: Path) -> dict[str, np.ndarray]:
    """The used columns as floats (channel → array).  Other columns are not parsed: they may hold text.
    The first bad cell of a used column, in file order, is refused with its line and column."""
    data = _fast_float(texts, sep, len(header)) if rows is None else None
    if data is not None:
        return {ch: data[:, j] for ch, j in used.items()}
    rows = rows if rows is not None else _split_rows(body, sep)
    out, first = {}, None
    for ch, j in sorted(used.items(), key=lambda kv: kv[1]):
        out[ch], bad = _column([r[j] for r in rows], j, header[j], body, ch == "temp", path)
        if bad is not None and (first is None or bad[0] < first[0]):
            first = bad
    if first is not None:
        raise first[1]
    return out


def _increasing_time(cols: dict[str, np.ndarray], body: list[tuple[int, str]], path: Path,
                     notes: list[str]) -> tuple[dict[str, np.ndarray], list[tuple[int, str]]]:
    """Rows that repeat the previous one exactly are dropped (noted); any other step that is not forward
    in time is refused with its lines."""
    t = cols["t"]
    dt = np.diff(t)
    if np.any(dt <= 0):
        same = (dt == 0) & np.all([c[1:] == c[:-1] for c in cols.values()], axis=0)
        if same.any():
            keep = np.concatenate([[True], ~same])
            notes.append(f"{int(same.sum())} row(s) repeat the previous row exactly (same time and values): dropped")
            cols, body = {k: v[keep] for k, v in cols.items()}, [b for b, k in zip(body, keep) if k]
            t = cols["t"]
            dt = np.diff(t)
    if np.any(dt <= 0):
        k = int(np.argmax(dt <= 0))
        what = "repeats" if dt[k] == 0 else "is before"
        raise TimeBaseError(
            f"{path}: line {body[k + 1][0]} (t = {float(t[k + 1])!r}) {what} line {body[k][0]} (t = {float(t[k])!r}): "
            "timestamps must "
            f"be strictly increasing ({int(np.sum(dt <= 0))} such step(s)); sort or de-duplicate the rows first"
        )
    return cols, body


def _finite_core(cols: dict[str, np.ndarray], header: list[str], used: dict[str, int], body: list[tuple[int, str]],
                 sep: str, path: Path) -> None:
    core = [c for c in REQUIRED if c in cols]
    nonfinite = ~np.isfinite(np.column_stack([cols[c] for c in core]))
    if nonfinite.any():
        i, j = np.argwhere(nonfinite)[0]
        col = used[core[j]]
        raise FieldError(
            f"{path}: line {body[i][0]}, column {header[col]!r} is {_cells(body[i][1], sep)[col].strip()!r}: "
            f"NaN/inf is not a measurement ({int(nonfinite.sum())} such value(s)); drop or interpolate those rows")


def _magnetometer(cols: dict[str, np.ndarray], cmap: ColumnMap, body: list[tuple[int, str]],
                  notes: list[str]) -> tuple[np.ndarray | None, list[str]]:
    """The (N, 3) magnetometer in µT, or None (noted) when an axis is missing or a row is empty; and the
    mag channels that were not used."""
    from gyrosim.units import to_si

    mag_cols = [c for c in ("mag_x", "mag_y", "mag_z") if c in cols]
    if mag_cols and len(mag_cols) < 3:
        notes.append(f"magnetometer column(s) {mag_cols} without the other axes: ignored (needs mag_x, mag_y, mag_z)")
        return None, mag_cols
    if not mag_cols:
        return None, []
    mag = np.column_stack([cols[c] for c in mag_cols]) * float(to_si(1.0, cmap.units.get("mag", "uT"),
                                                                        "magnetic_field"))
    bad_m = ~np.isfinite(mag).all(axis=1)
    if bad_m.any():
        notes.append(f"the magnetometer has {int(bad_m.sum())} empty/NaN row(s) (first at line "
                     f"{body[int(np.argmax(bad_m))][0]}): the mag columns are ignored")
        return None, []
    return mag, []


def read_csv_text(text: str, path: Path, gyro_unit: str | None = None, acc_unit: str | None = None,
                  columns: dict[str, str] | None = None) -> CsvRead:
    """Parse the decoded text of a CSV recording (see the module docstring).  ``gyro_unit``/``acc_unit``:
    the user's units (None: the header's, else rad/s and m/s²); ``columns``: the user's mapping
    channel → column name (:func:`calib.inputs.columns.parse_columns`)."""
    lines = _data_lines(text, path)
    header_line, sep, header = _header(lines, path)
    body = lines[1:]
    cmap = resolve_columns(header, columns, gyro_unit, acc_unit, where=str(path))
    rate = _require(cmap, header, header_line, sep, path)
    notes = [f"read with separator {SEPARATOR_NAMES.get(sep, repr(sep))}"] if sep != "," else []
    body, texts, rows = _complete_rows(body, sep, len(header), header_line, text.endswith(("\n", "\r")), path, notes)
    used = dict(cmap.index) | ({"t_nanosec": cmap.t_nanosec} if cmap.t_nanosec is not None else {})
    cols = _numbers(body, texts, rows, sep, header, used, path)
    if rate is not None:
        cols["t"] = np.arange(len(body)) / rate
        notes.append(f"an x-IMU export without times: t = sample index / {rate:g} Hz (the rate in its Registers.csv); "
                     "the packet numbers are not used")
    if "t_nanosec" in cols:
        cols["t"] = cols["t"] + 1e-9 * cols.pop("t_nanosec")
    _finite_core(cols, header, used, body, sep, path)
    cols, body = _increasing_time(cols, body, path, notes)
    return _assemble(cols, cmap, body, header, sep, path, notes, "s" if rate is not None else cmap.units.get("t"))


def _assemble(cols: dict[str, np.ndarray], cmap: ColumnMap, body: list[tuple[int, str]], header: list[str], sep: str,
              path: Path, notes: list[str], time_unit: str | None) -> CsvRead:
    """The Recording in SI units, and what the reader made of the file."""
    t = cols["t"]
    mag, unused_mag = _magnetometer(cols, cmap, body, notes)
    unknown = list(cmap.ignored) + [header[cmap.index[c]] for c in unused_mag]
    if unknown:
        shown = f"{unknown}" if len(unknown) <= 8 else f"{unknown[:6]} and {len(unknown) - 6} more"
        notes.append(f"column(s) {shown} are not known (t, gyro_*, acc_*, temp, mag_*): ignored")
    said = describe_units(cmap)
    if said:
        notes.insert(0, said)
    gu, au = cmap.units["gyro"], cmap.units["acc"]
    g = np.asarray(to_si(1.0, gu, "rate")) * np.column_stack([cols["gyro_x"], cols["gyro_y"], cols["gyro_z"]])
    a = np.asarray(to_si(1.0, au, "acceleration")) * np.column_stack([cols["acc_x"], cols["acc_y"], cols["acc_z"]])
    meta = {"source": str(path), "gyro_unit": gu, "acc_unit": au}
    if cmap.layout != "calib":
        meta["column_layout"] = cmap.layout
    temp = resample_temperature(t, cols["temp"], meta, str(path)) if "temp" in cols else None
    if "temperature_note" in meta:
        notes.append(meta["temperature_note"])
    used = [c for c in sorted(cmap.index, key=cmap.index.get) if c not in unused_mag]
    rec = Recording(t_s=t, gyro_rad_s=g, acc_m_s2=a, temp_c=temp, mag_ut=mag, meta=meta)
    return CsvRead(rec, time_unit, sep, tuple(used), tuple(unknown), notes)
