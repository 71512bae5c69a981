"""The model must load from an installed wheel as well as from the checkout."""

from __future__ import annotations

import os
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def test_model_loads_from_the_checkout():
    from gyrosim.scene import HandScene

    scene = HandScene()
    assert scene.model.nsensor == 5 and scene.model_path.name == "handheld.xml"
    assert {scene.model.site(i).name for i in range(scene.model.nsite)} >= {"imu_gyro", "imu_acc", "imu_mag"}


def test_model_and_data_ship_in_the_wheel_and_load_from_it(tmp_path):
    pytest.importorskip("setuptools")
    wheel_dir = tmp_path / "wheel"
    build = subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "wheel",
            "--no-deps",
            "--no-build-isolation",
            "-q",
            "-w",
            str(wheel_dir),
            str(ROOT),
        ],
        capture_output=True,
        text=True,
    )
    assert build.returncode == 0, build.stderr
    (wheel,) = wheel_dir.glob("*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    for required in ("gyrosim/models/handheld.xml", "gyrosim/schedules/zhou2020.toml",
                     "gyrosim/presets/hands/typical.toml", "calib/app/cli.py"):
        assert required in names, required
    # every source module and data file of the two packages ships (a forgotten subpackage would
    # work in the editable checkout and break in an installed copy)
    for pkg in ("gyrosim", "calib"):
        for f in (ROOT / pkg).rglob("*"):
            if f.suffix in (".py", ".toml") and "__pycache__" not in f.parts:
                assert f.relative_to(ROOT).as_posix() in names, f"{f.relative_to(ROOT)} is not in the wheel"
    for f in (ROOT / "models").glob("*.xml"):
        assert f"gyrosim/models/{f.name}" in names, f.name
    # calib's estimators are registered for gyrosim in the wheel's metadata (gyrosim.plugins)
    (ep_file,) = [n for n in names if n.endswith(".dist-info/entry_points.txt")]
    ep_text = zipfile.ZipFile(wheel).read(ep_file).decode()
    assert "[gyrosim.estimators]" in ep_text and "kf = calib.session.registry:kf" in ep_text
    target = tmp_path / "site"
    inst = subprocess.run(
        [sys.executable, "-m", "pip", "install", "--no-deps", "-q", "--target", str(target), str(wheel)],
        capture_output=True,
        text=True,
    )
    assert inst.returncode == 0, inst.stderr
    # run from an unrelated folder with only the installed copy on the path
    code = ("from gyrosim.scene import HandScene; from gyrosim.simulate import simulate_truth; "
            "s = HandScene(); print(s.model_path); r = simulate_truth('static', 'ideal', 50, scene=s); print(r.n); "
            "from gyrosim.estimator import load_estimator; print(load_estimator('kf').__module__)")
    env = {**os.environ, "PYTHONPATH": str(target)}
    run = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    model_path, n, kf_module = run.stdout.split()
    assert Path(model_path).is_relative_to(target) and int(n) == 3001
    assert kf_module == "calib.session.registry"  # found by entry point from the installed copy (no source tree)
