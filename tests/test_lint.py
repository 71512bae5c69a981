"""The linter CI runs: ruff over the whole tree (the rules are pyproject.toml's: pyflakes, import order with
gyrosim before calib, numpy-style docstrings on public names, 120 columns)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_ruff_is_clean_on_the_whole_tree():
    run = subprocess.run([sys.executable, "-m", "ruff", "check", "--no-cache", "."], cwd=ROOT, capture_output=True,
                         text=True, timeout=300)
    assert run.returncode == 0, f"ruff check found problems (run `ruff check .`):\n{run.stdout}{run.stderr}"


def test_ruff_would_catch_a_violation(tmp_path):
    # the same configuration on a file that breaks two rules: the check above cannot pass vacuously
    bad = tmp_path / "bad.py"
    bad.write_text("import os\nx = 1\n" + "y = '" + "a" * 130 + "'\n")
    run = subprocess.run([sys.executable, "-m", "ruff", "check", "--no-cache", "--config",
                          str(ROOT / "pyproject.toml"), str(bad)], capture_output=True, text=True, timeout=120)
    assert run.returncode == 1 and "F401" in run.stdout and "E501" in run.stdout, run.stdout
