"""Start-up cost, checked by what is imported (not by a timer, which a loaded CI machine would make flaky):
``calib --help`` / ``--version`` and the refusal of a bad file import none of the heavy libraries a
calibration, a simulation or a view needs (scipy ≈ 1–4 s, numba ≈ 0.7 s, MuJoCo, rerun, matplotlib, Dask).
The measured times are in benchmarks/startup.md (``python benchmarks/startup.py``)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

import calib

REPO = Path(__file__).resolve().parents[2]
HEAVY = ("scipy", "numba", "mujoco", "rerun", "matplotlib", "dask", "distributed", "filterpy", "allantools")
# the commands that read a recording, each with the options it needs besides the recording
READERS = {"run": [], "inspect": [], "allan": [], "noise": [], "temperature": [], "ratetable": [], "mag": [],
           "closeloop": ["--out", "closeloop_out"], "northfind": [], "tilt": []}


def _heavy_after(code: str, cwd: Path) -> dict:
    """Run ``code`` in a fresh interpreter (this checkout first on the path) and return its JSON line."""
    env_code = f"import sys; sys.path.insert(0, {str(REPO)!r})\n" + code
    out = subprocess.run([sys.executable, "-c", env_code], capture_output=True, text=True, cwd=cwd, timeout=300)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_help_and_version_import_no_heavy_library(tmp_path):
    code = f"""
import contextlib, io, json, sys
from calib.app.cli import main
codes = []
for argv in (["--version"], ["--help"], ["run", "--help"]):
    with contextlib.redirect_stdout(io.StringIO()):
        codes.append(main(argv))
print(json.dumps({{"codes": codes, "heavy": sorted({{m.split(".")[0] for m in sys.modules}} & set({HEAVY!r}))}}))
"""
    got = _heavy_after(code, tmp_path)
    assert got["codes"] == [0, 0, 0]
    assert got["heavy"] == []


def test_version_answers_without_numpy(tmp_path):
    code = """
import contextlib, io, json, sys
from calib.app.cli import main
out = io.StringIO()
with contextlib.redirect_stdout(out):
    rc = main(["--version"])
print(json.dumps({"rc": rc, "out": out.getvalue(), "numpy": "numpy" in sys.modules}))
"""
    got = _heavy_after(code, tmp_path)
    assert got == {"rc": 0, "out": f"calib {calib.__version__}\n", "numpy": False}


@pytest.mark.parametrize("command", READERS)
def test_a_bad_file_is_refused_before_any_heavy_import(tmp_path, command):
    (tmp_path / "bad.csv").write_text("t,gyro_x\n0,1\n", encoding="utf-8")
    code = f"""
import contextlib, io, json, sys
from calib.app.cli import main
err = io.StringIO()
with contextlib.redirect_stderr(err):
    rc = main([{command!r}, "bad.csv", *{READERS[command]!r}])
print(json.dumps({{"rc": rc, "err": err.getvalue(),
                  "heavy": sorted({{m.split(".")[0] for m in sys.modules}} & set({HEAVY!r}))}}))
"""
    got = _heavy_after(code, tmp_path)
    assert got["rc"] == 2 and "missing column" in got["err"]
    assert got["heavy"] == [], f"calib {command} imported {got['heavy']} before refusing a bad file"
