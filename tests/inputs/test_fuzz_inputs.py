"""Property-based fuzzing of the loaders and the command lines (hypothesis).

Random CSV and HDF5 recordings — shapes, dtypes, time units and epochs, rates, separators,
encodings, header variants, NaN/inf/spike/constant placement, gaps, disorder, truncation, junk —
go through ``calib run`` / ``allan`` / ``inspect`` / ``closeloop`` in-process.  For every one:

* no traceback and no internal error (exit code 0, 1 or 2 only);
* bounded work: each command returns within ``BOUND_S`` (the files hold ≤ 400 samples, so any
  second beyond that is a runaway loop: the µs-timestamp hang took hours);
* the input file's bytes are unchanged;
* exit 2 comes with a one-line ``error:`` message; an accepted ``run`` writes valid JSON (no bare
  NaN: ``json.loads`` is made to refuse it) with a ``status``, and exit 1 only with a status that
  is not "ok".

``test_fuzz_sample`` (default suite) draws 500 cases; ``test_fuzz_large`` (``-m slow``) 10 000.
Both are derandomized (reproducible); a failure prints the drawn spec.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import math
import tempfile
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from calib.app.cli import main as calib_main

BOUND_S = 20.0
COLUMNS = ["t", "gyro_x", "gyro_y", "gyro_z", "acc_x", "acc_y", "acc_z"]


# ------------------------------------------------------------------ the recording before corruption
def _motion(n: int, rate: float, rest_s: float, turn_deg_s: float, axis: int, seed: int) -> tuple[np.ndarray, ...]:
    """Rest, then a turn about a body axis at a smooth rate; gravity follows (kinematic, no gyrosim)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / rate
    w = np.zeros((n, 3))
    moving = t >= rest_s
    tau = t[moving] - rest_s
    w[moving, axis] = math.radians(turn_deg_s) * np.sin(0.5 * tau) ** 2
    angle = np.concatenate([[0.0], np.cumsum(0.5 * (w[1:, axis] + w[:-1, axis]) / rate)])
    g = np.zeros((n, 3))
    c, s = np.cos(angle), np.sin(angle)
    up = np.array([0.0, 0.0, 9.80665])
    if axis == 0:
        g[:, 1], g[:, 2] = s * up[2], c * up[2]
    elif axis == 1:
        g[:, 0], g[:, 2] = -s * up[2], c * up[2]
    else:
        g[:, 2] = up[2]
    gyro = w + np.radians([0.5, -0.3, 0.2]) + rng.normal(0, 0.002, (n, 3))
    acc = g + rng.normal(0, 0.01, (n, 3))
    return t, gyro, acc


CORRUPTIONS = (
    "nan",
    "inf",
    "spike",
    "huge",
    "dead",
    "gap",
    "short_gap",
    "disorder",
    "duplicate",
    "deg",
    "g",
    "ms_float",
    "broken_row",
    "truncate",
    "missing_column",
    "wrong_shape",
    "int_dtype",
    "bad_rate_attr",
    "bom_latin",
)


@st.composite
def recordings(draw):
    """(spec, file suffix, bytes): a clean recording (35 %), with one corruption (45 %), several (15 %),
    or random bytes (5 %); every benign variation (format, separator, encoding, header layout, time unit
    and epoch, rate, length, motion) is drawn in all modes."""
    mode = draw(st.sampled_from(["clean"] * 7 + ["one"] * 9 + ["many"] * 3 + ["junk"]))
    if mode == "junk":
        return {"mode": mode}, draw(st.sampled_from([".csv", ".h5", ".txt"])), draw(st.binary(min_size=0, max_size=300))
    bad = set() if mode == "clean" else (
        {draw(st.sampled_from(CORRUPTIONS))} if mode == "one" else set(draw(st.lists(st.sampled_from(CORRUPTIONS),
                                                                                      min_size=2, max_size=4))))
    n = draw(st.sampled_from([0, 1, 2, 10, 60, 250, 400, 600, 1200, 1200]))
    rate = draw(st.sampled_from([1.0, 10.0, 20.0, 50.0, 50.0, 100.0, 285.7, 1000.0, 10000.0]))
    spec = {"mode": mode, "bad": sorted(bad), "n": n, "rate": rate}
    t, g, a = _motion(
        max(n, 1),
        rate,
        draw(st.sampled_from([0.0, 3.0, 3.0])),
        draw(st.sampled_from([0.0, 30.0, 200.0])),
        draw(st.integers(0, 2)),
        draw(st.integers(0, 3)),
    )
    t, g, a = t[:n], g[:n], a[:n]
    t_unit = draw(st.sampled_from([1.0, 1.0, 1e3, 1e6, 1e9]))
    epoch = draw(st.sampled_from([0.0, 0.0, 1.7e9]))
    t = (t + epoch) * t_unit
    if t_unit > 1 and "ms_float" not in bad:
        t = np.round(t)  # a logger's counter
    if "deg" in bad:
        g = np.degrees(g)
    if "g" in bad:
        a = a / 9.80665
    spec.update(t_unit=t_unit, epoch=epoch)
    data = np.column_stack([t, g, a]) if n else np.zeros((0, 7))
    if n:
        for kind, values in (("nan", [np.nan]), ("inf", [np.inf, -np.inf]), ("spike", [1e30, -1e308, 1e6]),
                             ("huge", [1e30])):
            if kind in bad:
                rows = draw(st.lists(st.integers(0, n - 1), min_size=1, max_size=3 if kind != "huge" else 1))
                col = draw(st.integers(0 if kind in ("nan", "inf") else 1, 6))
                for i in rows:
                    data[i if kind != "huge" else slice(i, i + 8), col] = draw(st.sampled_from(values))
        if "dead" in bad:
            data[:, draw(st.integers(1, 6))] = draw(st.sampled_from([0.0, 1.0]))
    if n > 3:
        if "gap" in bad or "short_gap" in bad:
            s0 = draw(st.integers(1, n - 2))
            width = draw(st.integers(1, 3)) if "short_gap" in bad else draw(st.integers(4, 60))
            data = np.delete(data, range(s0, min(n - 1, s0 + width)), axis=0)
        if "disorder" in bad:
            i = draw(st.integers(0, data.shape[0] - 2))
            data[[i, i + 1]] = data[[i + 1, i]]
        if "duplicate" in bad:
            i = draw(st.integers(0, data.shape[0] - 1))
            data = np.insert(data, i, data[i], axis=0)
    fmt_kind = draw(st.sampled_from(["csv", "csv", "csv", "hdf5"]))
    spec["format"] = fmt_kind
    if fmt_kind == "csv":
        layout = draw(st.sampled_from(["plain", "plain", "reorder", "extra", "mag", "case", "t_ms_name"]))
        order = list(draw(st.permutations(range(7)))) if layout == "reorder" else list(range(7))
        header = [COLUMNS[i] for i in order]
        body = data[:, order]
        if "missing_column" in bad:
            header, body = header[:-1], body[:, :-1]
        if layout == "extra":
            header, body = header + ["quality"], np.column_stack([body, np.ones(body.shape[0])])
        elif layout == "mag":
            header, body = (
                header + ["mag_x", "mag_y", "mag_z"],
                np.column_stack([body, np.full((body.shape[0], 3), 30.0)]),
            )
        elif layout == "case":
            header = [f" {h.upper()} " for h in header]
        elif layout == "t_ms_name" and t_unit == 1e3 and epoch == 0:
            header = ["t_ms" if h == "t" else h for h in header]
        sep = draw(st.sampled_from([",", ",", ";", "\t", " ", "|"]))
        fmt = draw(st.sampled_from(["%.17g", "%.17g", "%.9g", "%.4f"]))
        lines = [sep.join(header)] + [sep.join(fmt % v for v in row) for row in body]
        if "broken_row" in bad and len(lines) > 1:
            i = draw(st.integers(1, len(lines) - 1))
            lines[i] = draw(
                st.sampled_from(
                    [
                        lines[i] + sep + "1",
                        sep.join(lines[i].split(sep)[:-1]),
                        "abc" + sep + sep.join(lines[i].split(sep)[1:]),
                        lines[i].replace(sep, sep + sep, 1),
                        "",
                    ]
                )
            )
        newline = draw(st.sampled_from(["\n", "\n", "\r\n"]))
        text = newline.join(lines) + (newline if draw(st.integers(0, 4)) else "")
        if sep in (";", "\t") and draw(st.integers(0, 3)) == 0:
            text = text.replace(".", ",")
        enc = (
            draw(st.sampled_from(["utf-8", "utf-8", "utf-8", "utf-8-sig", "utf-16"]))
            if "bom_latin" not in bad
            else "latin-1"
        )
        raw = ("# °C comment\n" + text if enc == "latin-1" else text).encode(enc)
        spec.update(layout=layout, sep=sep, fmt=fmt, enc=enc)
        suffix = ".h5" if draw(st.integers(0, 9)) == 0 else ".csv"
    else:
        dtype = "i2" if "int_dtype" in bad else draw(st.sampled_from(["f8", "f8", "f4"]))
        bio = io.BytesIO()
        with h5py.File(bio, "w") as f:
            for name, arr in (("t", data[:, 0]), ("gyro", data[:, 1:4]), ("acc", data[:, 4:7])):
                if "missing_column" in bad and name == "acc":
                    continue
                if "wrong_shape" in bad and name == "gyro":
                    arr = arr[:, :2]
                with np.errstate(invalid="ignore", over="ignore"):
                    arr = np.clip(np.nan_to_num(arr), -3e4, 3e4).astype(dtype) if dtype[0] == "i" else arr.astype(dtype)
                f.create_dataset(name, data=arr)
            if "bad_rate_attr" in bad:
                f.attrs["rate_hz"] = draw(st.sampled_from([100.0, -1.0, float("nan"), 0.0]))
            elif draw(st.booleans()):
                f.attrs["rate_hz"] = rate
        raw = bio.getvalue()
        spec.update(dtype=dtype)
        suffix = ".csv" if draw(st.integers(0, 9)) == 0 else ".h5"
    if "truncate" in bad:
        raw = raw[: draw(st.integers(0, len(raw)))]
    return spec, suffix, raw


COMMANDS = st.sampled_from(["run", "run", "run", "inspect", "allan", "closeloop"])


def _run(argv: list[str]) -> tuple[int, str, str, float]:
    out, err = io.StringIO(), io.StringIO()
    t0 = time.perf_counter()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = calib_main(argv)
    return rc, out.getvalue(), err.getvalue(), time.perf_counter() - t0


def _no_nan(token: str):
    raise ValueError(f"invalid JSON constant {token}")


def _check_one(case, command: str) -> None:
    spec, suffix, raw = case
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / f"rec{suffix}"
        path.write_bytes(raw)
        digest = hashlib.sha256(raw).hexdigest()
        out_json = Path(d) / "out.json"
        argv = {
            "run": ["run", str(path), "--json", str(out_json)],
            "inspect": ["inspect", str(path)],
            "allan": ["allan", str(path)],
            "closeloop": ["closeloop", str(path), "--out", str(Path(d) / "cl")],
        }[command]
        rc, out, err, dt = _run(argv)
        info = f"{command} {spec} → exit {rc} in {dt:.2f} s\nstderr: {err[-1500:]}"
        assert "Traceback" not in out + err and "internal error" not in err, info
        assert rc in (0, 1, 2), info
        assert dt < BOUND_S, info
        assert hashlib.sha256(path.read_bytes()).hexdigest() == digest, info
        if rc == 2:
            assert "error: " in err and err.strip(), info
            assert not out_json.exists(), info
        elif command == "run":
            d_ = json.loads(out_json.read_text(), parse_constant=_no_nan)
            assert d_["status"] in ("ok", "inconsistent", "diverged") and (rc == 0) == (d_["status"] == "ok"), info
        else:
            assert rc == 0 and out.strip(), info


_SETTINGS = dict(deadline=None, derandomize=True, database=None, print_blob=True,
                 suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.filter_too_much])


@settings(max_examples=500, **_SETTINGS)
@given(recordings(), COMMANDS)
def test_fuzz_sample(case, command):
    _check_one(case, command)


@pytest.mark.slow
@settings(max_examples=10_000, **_SETTINGS)
@given(recordings(), COMMANDS)
def test_fuzz_large(case, command):
    _check_one(case, command)
