"""The bad inputs of the input-boundary tests, derived from one simulated session with numpy/h5py.

Base: ``gyrosim simulate --schedule zhou2020 --hand typical --sensor zhou2020_sim_consumer --rate 100
--seed 1`` (171 s, 17 101 samples), written as HDF5 and as CSV (``%.17g``: the CSV holds exactly the
HDF5's numbers).  Every derived file is built on first use and cached for the session; the inputs
are read-only afterwards (the table test checks their bytes).
"""

from __future__ import annotations

import math
import shutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import h5py
import numpy as np

from gyrosim.recording import Recording, load_hdf5, save_hdf5

HEADER = "t,gyro_x,gyro_y,gyro_z,acc_x,acc_y,acc_z"


def csv_text(t, g, a, *, header=HEADER, sep=",", extra=None, fmt="%.17g", newline="\n") -> str:
    cols = [np.asarray(t)[:, None], np.asarray(g), np.asarray(a)] + ([np.asarray(extra)] if extra is not None else [])
    data = np.hstack([c if c.ndim == 2 else c[:, None] for c in cols])
    lines = [header.replace(",", sep)] + [sep.join(fmt % v for v in row) for row in data]
    return newline.join(lines) + newline


@dataclass
class Base:
    """The simulated session and the folder the derived inputs go to."""

    folder: Path
    rec: Recording
    h5: Path
    csv: Path
    cache: dict[str, Path] = field(default_factory=dict)

    @property
    def t(self):
        return np.asarray(self.rec.t_s)

    @property
    def g(self):
        return np.asarray(self.rec.gyro_rad_s)

    @property
    def a(self):
        return np.asarray(self.rec.acc_m_s2)

    def text(self, name: str, text: str, encoding: str = "utf-8") -> Path:
        p = self.folder / name
        p.write_bytes(text.encode(encoding))
        return p

    def write_csv(self, name: str, t=None, g=None, a=None, **kw) -> Path:
        return self.text(name, csv_text(self.t if t is None else t, self.g if g is None else g,
                                        self.a if a is None else a, **kw))

    def write_h5(self, name: str, **datasets) -> Path:
        p = self.folder / name
        with h5py.File(p, "w") as f:
            for k, v in datasets.items():
                f.create_dataset(k, data=v)
            f.attrs["rate_hz"] = 100.0
        return p

    def rows(self) -> list[str]:
        return self.csv.read_text().splitlines()


def make_base(folder: Path) -> Base:
    from gyrosim.simulate import simulate

    folder.mkdir(parents=True, exist_ok=True)
    rec = simulate("zhou2020", "typical", "zhou2020_sim_consumer", 100.0, seed=1)
    h5 = save_hdf5(rec, folder / "base.h5")
    rec = load_hdf5(h5)
    csv = folder / "base.csv"
    csv.write_text(csv_text(rec.t_s, rec.gyro_rad_s, rec.acc_m_s2))
    return Base(folder, rec, h5, csv)


# ------------------------------------------------------------------ derivations: name -> builder
def _rows_op(name: str, fn: Callable[[list[str]], list[str]], trailing_newline: bool = True) -> Callable[[Base], Path]:
    def build(b: Base) -> Path:
        lines = fn(b.rows())
        return b.text(name, "\n".join(lines) + ("\n" if trailing_newline else ""))
    return build


def _drop_every(k: int, n_gaps: int, missing: int):
    def fn(lines):
        head, body = lines[0], lines[1:]
        drop = set()
        for i in range(n_gaps):
            start = 1500 + i * k
            drop.update(range(start, start + missing))
        return [head] + [l for j, l in enumerate(body) if j not in drop]
    return fn


def _slow(b: Base, degrees: bool, remove_bias: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The session stretched to 30 s per turn (zhou2020 turns in 9 s): t × 30/9, ω × 9/30 — the
    integrated rotation and the gravity sequence are unchanged; optionally without the 2 °/s bias."""
    k = 30.0 / 9.0
    g = b.g.copy()
    if remove_bias:
        g -= g[:800].mean(axis=0)
    g = g / k
    return b.t * k, np.degrees(g) if degrees else g, b.a


def _h5_from_base(name: str, **changes) -> Callable[[Base], Path]:
    def build(b: Base) -> Path:
        p = b.folder / name
        shutil.copyfile(b.h5, p)
        with h5py.File(p, "r+") as f:
            for key, fn in changes.items():
                v = fn(f[key][()]) if callable(fn) else fn
                del f[key]
                if v is not None:
                    f.create_dataset(key, data=v)
        return p
    return build


def _static_10h(b: Base) -> Path:
    """A 10-hour static record at 10 Hz (the issue's closeloop hang): bias + white noise + a slow
    bias random walk, gravity on z."""
    rng = np.random.default_rng(7)
    n = 360_000
    t = np.arange(n) / 10.0
    g = np.radians([0.5, -0.3, 0.2]) + np.cumsum(rng.normal(0, np.radians(0.0005), (n, 3)), axis=0) \
        + rng.normal(0, np.radians(0.05), (n, 3))
    a = np.array([0.0, 0.0, 9.80665]) + rng.normal(0, 0.01, (n, 3))
    p = b.folder / "static_10h.h5"
    save_hdf5(Recording(t, g, a, meta={"rate_hz": 10.0}), p)
    return p


def _khz10_head(b: Base) -> Path:
    """The first 20 s at 10 kHz (linear interpolation of the base): the rate case without 450 MB."""
    t = np.arange(0, 20.0, 1e-4)
    g = np.stack([np.interp(t, b.t, b.g[:, i]) for i in range(3)], axis=1)
    a = np.stack([np.interp(t, b.t, b.a[:, i]) for i in range(3)], axis=1)
    p = b.folder / "khz10_head.h5"
    save_hdf5(Recording(t, g, a, meta={"rate_hz": 10000.0}), p)
    return p


def _spikes(b: Base, name: str, channel: str, idx, value) -> Path:
    g, a = b.g.copy(), b.a.copy()
    arr = g if channel == "gyro" else a
    arr[idx, 1] = value
    return b.write_csv(name, g=g, a=a)


def _static(b: Base, name: str, gyro_spike=None, acc_spike=None, gyro_scale=1.0, acc_scale=1.0, gyro_const=None,
            t_scale=None) -> Path:
    m = b.t >= 146.0
    t, g, a = b.t[m] - 146.0, b.g[m] * gyro_scale, b.a[m] * acc_scale
    if t_scale is not None:
        t = np.round(t * t_scale)
    if gyro_spike is not None:
        g[1000, 1] = gyro_spike
    if acc_spike is not None:
        a[1200, 0] = acc_spike
    if gyro_const is not None:
        g = np.full_like(g, gyro_const)
    return b.write_csv(name, t=t, g=g, a=a)


def _jitter(b: Base) -> Path:
    rng = np.random.default_rng(3)
    t = b.t + rng.uniform(-0.004, 0.004, b.t.size)
    return b.write_csv("jitter_4ms.csv", t=t)


DERIVED: dict[str, Callable[[Base], Path]] = {
    # ---- time column
    # a logger's counters are whole numbers: ms, µs, ns since start
    "t_ms": lambda b: b.write_csv("t_ms.csv", t=np.round(b.t * 1e3)),
    "t_us": lambda b: b.write_csv("t_us.csv", t=np.round(b.t * 1e6)),
    "t_ns": lambda b: b.write_csv("t_ns.csv", t=np.round(b.t * 1e9)),
    "t_ms_float": lambda b: b.write_csv("t_ms_float.csv", t=b.t * 1e3 + 0.25),
    "epoch_s": lambda b: b.write_csv("epoch_s.csv", t=b.t + 1.7e9),
    "epoch_ms": lambda b: b.write_csv("epoch_ms.csv", t=np.round(b.t * 1e3) + 1.7e12),
    "epoch_us": lambda b: b.write_csv("epoch_us.csv", t=np.round(b.t * 1e6) + 1.7e15),
    "h5_t_ms": _h5_from_base("h5_t_ms.h5", t=lambda t: t * 1e3),
    "header_t_ms": lambda b: b.write_csv(
        "header_t_ms.csv", t=np.round(b.t * 1e3), header=HEADER.replace("t,", "t_ms,", 1)
    ),
    "jitter_4ms": _jitter,
    "gaps_2": _rows_op("gaps_2.csv", _drop_every(1000, 10, 2)),
    "gap_200": _rows_op("gap_200.csv", _drop_every(1, 1, 200)),
    "backwards": _rows_op("backwards.csv", lambda l: l[:100] + [l[101], l[100]] + l[102:]),
    "duplicate_row": _rows_op("duplicate_row.csv", lambda l: l[:100] + [l[100]] + l[100:]),
    "duplicate_time": _rows_op(
        "duplicate_time.csv", lambda l: l[:101] + [l[100].split(",")[0] + ",0,0,0,0,0,9.8"] + l[101:]
    ),
    "every_100th": lambda b: b.write_csv("every_100th.csv", t=b.t[::100], g=b.g[::100], a=b.a[::100]),
    "every_10th": lambda b: b.write_csv("every_10th.csv", t=b.t[::10], g=b.g[::10], a=b.a[::10]),
    "khz10": _khz10_head,
    "two_rows": _rows_op("two_rows.csv", lambda l: l[:3]),
    "ten_rows": _rows_op("ten_rows.csv", lambda l: l[:11]),
    "rest_only": _rows_op("rest_only.csv", lambda l: l[:801]),
    "static_10h": _static_10h,
    # ---- format
    "header_only": _rows_op("header_only.csv", lambda l: l[:1]),
    "empty": lambda b: b.text("empty.csv", ""),
    "binary_junk": lambda b: (b.folder / "junk.csv").write_bytes(b"\x80" * 1280) and b.folder / "junk.csv",
    "csv_named_h5": lambda b: Path(shutil.copyfile(b.csv, b.folder / "csv_named.h5")),
    "h5_named_csv": lambda b: Path(shutil.copyfile(b.h5, b.folder / "h5_named.csv")),
    "empty_h5": lambda b: b.write_h5("empty.h5"),
    "truncated_h5": lambda b: (
        (b.folder / "truncated.h5").write_bytes(b.h5.read_bytes()[: b.h5.stat().st_size // 2])
        and b.folder / "truncated.h5"
    ),
    "h5_missing_acc": _h5_from_base("h5_missing_acc.h5", acc=None),
    "h5_gyro_2_columns": _h5_from_base("h5_gyro_2.h5", gyro=lambda g: g[:, :2]),
    "h5_gyro_text": _h5_from_base("h5_gyro_text.h5", gyro=lambda g: np.array([b"x"] * g.shape[0])),
    "h5_int_counts": _h5_from_base("h5_int_counts.h5", gyro=lambda g: np.round(np.degrees(g) * 131).astype(np.int16)),
    "h5_nan": _h5_from_base("h5_nan.h5", gyro=lambda g: np.where(np.arange(g.shape[0])[:, None] == 500, np.nan, g)),
    "truncated_csv": _rows_op(
        "truncated_csv.csv", lambda l: l[:-1] + [l[-1][: len(l[-1]) // 2]], trailing_newline=False
    ),
    "extra_field": _rows_op("extra_field.csv", lambda l: l[:523] + [l[523] + ",1.0"] + l[524:]),
    "missing_field": _rows_op("missing_field.csv", lambda l: l[:523] + [l[523].rsplit(",", 1)[0]] + l[524:]),
    "non_numeric": _rows_op(
        "non_numeric.csv", lambda l: l[:17] + [l[17].replace(l[17].split(",")[2], "abc", 1)] + l[18:]
    ),
    "empty_cell": _rows_op(
        "empty_cell.csv", lambda l: l[:17] + [",".join(l[17].split(",")[:2] + [""] + l[17].split(",")[3:])] + l[18:]
    ),
    "nan_value": _rows_op(
        "nan_value.csv", lambda l: l[:51] + [",".join(l[51].split(",")[:1] + ["nan"] + l[51].split(",")[2:])] + l[52:]
    ),
    "inf_value": _rows_op(
        "inf_value.csv", lambda l: l[:51] + [",".join(l[51].split(",")[:5] + ["inf"] + l[51].split(",")[6:])] + l[52:]
    ),
    "bom": lambda b: b.text("bom.csv", "\ufeff" + b.csv.read_text()),
    "semicolon": lambda b: b.write_csv("semicolon.csv", sep=";"),
    "tab": lambda b: b.write_csv("tab.csv", sep="\t"),
    "semicolon_decimal_comma": lambda b: b.text(
        "decimal_comma.csv", csv_text(b.t, b.g, b.a, sep=";").replace(".", ",")
    ),
    "spaces": lambda b: b.write_csv("spaces.csv", sep=" "),
    "crlf": lambda b: b.write_csv("crlf.csv", newline="\r\n"),
    "header_case": lambda b: b.write_csv("header_case.csv", header=' T , Gyro_X ,"GYRO_Y",gyro_z,ACC_X,acc_y, acc_z '),
    "reordered": lambda b: b.write_csv(
        "reordered.csv",
        t=b.a[:, 2],
        g=b.g[:, [2, 1, 0]],
        a=np.column_stack([b.a[:, :2], b.t]),
        header="acc_z,gyro_z,gyro_y,gyro_x,acc_x,acc_y,t",
    ),
    "missing_column": lambda b: b.text(
        "missing_column.csv", "\n".join(",".join(l.split(",")[:6]) for l in b.rows()) + "\n"
    ),
    "unknown_column": lambda b: b.write_csv("unknown_column.csv", header=HEADER + ",quality", extra=np.ones(b.t.size)),
    "mag_columns": lambda b: b.write_csv(
        "mag.csv", header=HEADER + ",mag_x,mag_y,mag_z", extra=np.tile([20.0, 5.0, -40.0], (b.t.size, 1))
    ),
    "no_header": lambda b: b.text("no_header.csv", "\n".join(b.rows()[1:]) + "\n"),
    "comments": lambda b: b.text("comments.csv", "# logged by a test\n# units: s, rad/s, m/s^2\n" + b.csv.read_text()),
    "utf16": lambda b: b.text("utf16.csv", b.csv.read_text(), encoding="utf-16"),
    "latin1_comment": lambda b: b.text(
        "latin1.csv", "# gyro in rad/s, 25 \xb0C\n" + b.csv.read_text(), encoding="latin-1"
    ),
    "directory": lambda b: (b.folder / "a_folder").mkdir(exist_ok=True) or b.folder / "a_folder",
    "nonexistent": lambda b: b.folder / "no_such_file.csv",
    # ---- values
    "acc_1e30": lambda b: _spikes(b, "acc_1e30.csv", "acc", [5000], 1e30),
    "gyro_1e30": lambda b: _spikes(b, "gyro_1e30.csv", "gyro", [5000], 1e30),
    "gyro_spike_50": lambda b: _spikes(b, "gyro_spike_50.csv", "gyro", [7000], 50.0),
    "spike_stretch": lambda b: _spikes(b, "spike_stretch.csv", "acc", list(range(5000, 5020)), 1e30),
    "many_spikes": lambda b: _spikes(b, "many_spikes.csv", "gyro", list(range(100, 17000, 40)), 1e6),
    "gyro_zero": lambda b: b.write_csv("gyro_zero.csv", g=b.g * 0),
    "dead_axis": lambda b: b.write_csv("dead_axis.csv", g=np.column_stack([np.zeros(b.t.size), b.g[:, 1:]])),
    "constant_acc": lambda b: b.write_csv("constant_acc.csv", a=np.tile([0.0, 0.0, 9.81], (b.t.size, 1))),
    "gyro_counts": lambda b: b.write_csv("gyro_counts.csv", g=np.round(np.degrees(b.g) * 131)),
    "acc_counts": lambda b: b.write_csv("acc_counts.csv", a=np.round(b.a / 9.80665 * 16384)),
    "gyro_deg": lambda b: b.write_csv("gyro_deg.csv", g=np.degrees(b.g)),
    "gyro_deg_slow": lambda b: b.write_csv("gyro_deg_slow.csv", *_slow(b, True, False)),
    "gyro_deg_slow_no_bias": lambda b: b.write_csv("gyro_deg_slow_nb.csv", *_slow(b, True, True)),
    "slow_rad": lambda b: b.write_csv("slow_rad.csv", *_slow(b, False, False)),
    "acc_g": lambda b: b.write_csv("acc_g.csv", a=b.a / 9.80665),
    "acc_mg": lambda b: b.write_csv("acc_mg.csv", a=b.a / 9.80665 * 1e3),
    # ---- static records (the session's final rest, t ≥ 146 s) for calib allan
    "static_part": lambda b: _static(b, "static_part.csv"),
    "static_gyro_spike": lambda b: _static(b, "static_gyro_spike.csv", gyro_spike=1e30),
    "static_t_ms": lambda b: _static(b, "static_t_ms.csv", t_scale=1e3),
    "static_acc_spike": lambda b: _static(b, "static_acc_spike.csv", acc_spike=1e30),
    "static_zero": lambda b: _static(b, "static_zero.csv", gyro_scale=0.0),
    "static_constant_gyro": lambda b: _static(b, "static_constant_gyro.csv", gyro_const=0.01),
    "static_gyro_deg": lambda b: _static(b, "static_gyro_deg.csv", gyro_scale=180 / math.pi),
    "static_acc_g": lambda b: _static(b, "static_acc_g.csv", acc_scale=1 / 9.80665),
    "base_csv": lambda b: b.csv,
    "base_h5": lambda b: b.h5,
}


def derived(b: Base, name: str) -> Path:
    if name not in b.cache:
        b.cache[name] = Path(DERIVED[name](b))
    return b.cache[name]


def math_ok(x) -> bool:
    return all(math.isfinite(v) for v in np.ravel(x))
