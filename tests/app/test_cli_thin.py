"""The thin ``calib`` command line: ``calib run --json`` is ``Calibration.save``'s bytes, ``calib --help`` is short,
former spellings (commands and methods) still run and say the new one, and every command exits by one table.

One simulated session (typical hand, MPU-9250-class sensor, 50 Hz) with a two-sample gap the input boundary
bridges — so the run's JSON carries input warnings, coaching and the simulator's truth — is calibrated a few
times; the 9-state filters (``--accelerometer calibrated``) carry the spelling checks because they are the
cheapest full runs.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json

import numpy as np
import pytest
from conftest import session

from gyrosim.calibration import Calibration, truth_calibration
from gyrosim.cli import EXIT_CODES, EXIT_CODES_HELP
from gyrosim.recording import load_hdf5, save_hdf5
from gyrosim.sensor_model import load_sensor
from gyrosim.simulate import apply_sensor

from calib.app.cli import build_parser
from calib.app.cli import main as calib_main
from calib.app.commands import lab

USER_COMMANDS = ("run", "apply", "export", "inspect", "demo", "allan", "noise", "plan", "temperature", "ratetable",
                 "closeloop", "mag", "northfind", "tilt", "lab")


def _call(argv: list[str]) -> tuple[int, str, str]:
    """``calib ARGV`` in-process: (exit code, stdout, stderr)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = calib_main(argv)
    return rc, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    return tmp_path_factory.mktemp("thin")


@pytest.fixture(scope="module")
def recording(folder):
    """The session as a gyrosim HDF5 file, samples 4000–4001 missing (a gap the boundary bridges and names)."""
    rec = apply_sensor(session("typical", rate_hz=50.0), load_sensor("mpu9250"), np.random.default_rng(1))
    keep = np.ones(rec.n, bool)
    keep[4000:4002] = False
    cut = rec.with_signals(t_s=rec.t_s[keep], gyro_rad_s=rec.gyro_rad_s[keep], acc_m_s2=rec.acc_m_s2[keep],
                           temp_c=None if rec.temp_c is None else rec.temp_c[keep],
                           truth=None)   # the sensor model stays in the metadata: the file still has its truth
    return str(save_hdf5(cut, folder / "rec.h5"))


@pytest.fixture(scope="module")
def default_run(recording, folder):
    """``calib run rec.h5 --json`` with the default method: (exit code, stdout, stderr, JSON path)."""
    path = folder / "default.json"
    return (*_call(["run", recording, "--json", str(path)]), path)


def test_calib_run_json_is_exactly_what_the_library_call_saves(recording, default_run, folder):
    from calib.inputs import KF, open_recording
    from calib.session.run import RunOptions, run_session

    rc, out, err, path = default_run
    cal = run_session(open_recording(recording, requirements=KF), RunOptions())
    cal.save(folder / "library.json")
    assert path.read_bytes() == (folder / "library.json").read_bytes()   # one author for the JSON
    Calibration.load(path).save(folder / "again.json")                    # and it round-trips
    assert (folder / "again.json").read_bytes() == path.read_bytes()
    d = json.loads(path.read_text(encoding="utf-8"))
    assert d["method"] == cal.method == "kf_hand_joint"
    # what calib run added before is in the Calibration now, under the same keys
    # and what decided the applied parameters (the motion, the prior, the held-out check)
    sections = {"coaching", "input", "truth", "motion", "prior", "held_out_check"}
    assert sections <= set(d) and set(cal.report) == sections and "applied" in d
    given = d["input"]["warnings"]
    assert given and any("bridged" in w for w in given), given
    assert d["warnings"][:len(given)] == given and len(d["warnings"]) > len(given)   # the input's first
    device = truth_calibration(load_hdf5(recording))   # the drawn device's own effects, from the file's metadata
    assert d["truth"]["scale_factor"] == device.value("gyro", "scale_factor").tolist()
    assert d["truth"]["accelerometer"]["bias_m_s2"] == device.value("accelerometer", "bias").tolist()
    assert set(d["coaching"]) >= {"external_acc_rms_m_s2", "sigma_over_ideal", "worst_segments"}
    # the console says the same: input warnings as input lines, the method's as warnings, the status
    assert f"  input: {given[0]}" in out and f"  status: {d['status']}" in out
    assert rc == (0 if d["status"] == "ok" else 1)
    assert (rc == 0) == (err == ""), err   # exit 1 is said on stderr, in one line
    if rc:
        assert err.strip() == f"calibration {d['status']}: see the warnings above for what to try"


def test_calib_help_is_short_and_lists_the_users_commands(monkeypatch):
    monkeypatch.setenv("COLUMNS", "80")
    text = build_parser().format_help()
    lines = text.splitlines()
    assert len(lines) <= 25 and max(len(line) for line in lines) <= 80, text
    listed = {line.split()[0] for line in lines if line.startswith("  ") and not line.startswith("   ")}
    assert set(USER_COMMANDS) <= listed, listed
    assert not set(lab.COMMANDS) & listed   # research and benchmark commands live under calib lab
    assert EXIT_CODES_HELP in text and all(f"{code} {what}" in text for code, what in EXIT_CODES.items())
    rc, out, _ = _call(["lab", "--help"])
    assert rc == 0 and all(name in out for name in lab.COMMANDS)


def test_every_lab_command_and_option_has_help_text():
    top = build_parser()
    (sub,) = [a for a in top._actions if isinstance(a, argparse._SubParsersAction)]
    (labsub,) = [a for a in sub.choices["lab"]._actions if isinstance(a, argparse._SubParsersAction)]
    helped = {c.dest: c.help for c in labsub._choices_actions}
    assert set(labsub.choices) == set(lab.COMMANDS) | set(lab.LAB_ONLY)
    missing = [name for name in (*lab.COMMANDS, *lab.LAB_ONLY) if not helped.get(name)]
    n = 0
    for name, parser in labsub.choices.items():
        parser.format_help()
        for action in parser._actions:
            if isinstance(action, argparse._HelpAction):
                continue
            n += 1
            if not (action.help or "").strip() or action.help == argparse.SUPPRESS:
                missing.append(f"calib lab {name} {'/'.join(action.option_strings) or action.dest}")
    assert n > 40 and not missing, missing


@pytest.mark.parametrize("name", lab.COMMANDS)
def test_former_top_level_spellings_still_run_with_a_note(name):
    rc, out, err = _call([name, "--help"])
    assert rc == 0 and out.startswith(f"usage: calib lab {name}")
    assert err.strip() == (f"warning: calib {name} is deprecated: use calib lab {name} (the same command; research "
                           "and benchmark commands live under calib lab)")


def test_a_former_top_level_spelling_runs_the_same_command():
    args = ["--sensors", "mpu9250", "--accuracy-deg", "1"]
    old, new = _call(["northfind-latitude", *args]), _call(["lab", "northfind-latitude", *args])
    assert old[0] == new[0] == 0 and old[1] == new[1] and "deprecated" in old[2] and new[2] == ""


@pytest.mark.parametrize("old, new, note", [
    ("kf", "kf_session_r", "it still runs kf_session_r (calib run's hand-blind filter, as before), not the paper's "
                           "filter that the registered name 'kf' means"),
    ("kf_session", "kf_session_r", "use --method kf_session_r (the same filter, by its registered name)"),
    ("iterated", "iterated_session_r", "it still runs iterated_session_r"),
    ("iterated_session", "iterated_session_r", "use --method iterated_session_r"),
    ("hand", "kf_hand", "use --method kf_hand (the same filter, by its registered name)"),
])
def test_former_method_spellings_still_run_with_a_note(old, new, note, recording, folder):
    rc, _, err = _call(["run", recording, "--method", old, "--accelerometer", "calibrated",
                        "--json", str(folder / f"{old}.json")])
    d = json.loads((folder / f"{old}.json").read_text(encoding="utf-8"))
    assert d["method"] == new and rc == (0 if d["status"] == "ok" else 1)
    first = err.splitlines()[0]
    assert first.startswith(f"warning: --method {old} is deprecated: ") and note in first, err
    if rc:   # done, not ok: said on stderr after the note
        assert err.splitlines()[1:] == [f"calibration {d['status']}: see the warnings above for what to try"], err


def test_a_former_method_spelling_gives_the_registered_methods_bytes(recording, folder):
    """--method kf_session with the accelerometer calibrated is kf_session_r: the same file, byte for byte."""
    if not (folder / "kf_session.json").exists():
        _call(["run", recording, "--method", "kf_session", "--accelerometer", "calibrated",
               "--json", str(folder / "kf_session.json")])
    rc, _, err = _call(["run", recording, "--method", "kf_session_r", "--json", str(folder / "kf_session_r.json")])
    assert "deprecated" not in err
    assert (folder / "kf_session_r.json").read_bytes() == (folder / "kf_session.json").read_bytes()


def test_method_names_resolve_by_registered_name_and_refuse_contradictions():
    from gyrosim.errors import GyrosimError

    from calib.session.paper import resolve_method
    from calib.session.run import RunOptions, resolve_run_method

    assert resolve_run_method(RunOptions()) == ("kf_hand_joint", "estimate", None)
    assert resolve_run_method(RunOptions(accelerometer="calibrated")) == ("kf_hand", "calibrated", None)
    assert resolve_run_method(RunOptions(external_acc_allowance_m_s2=0.1))[:2] == ("kf_joint", "estimate")
    assert resolve_run_method(RunOptions(method="kf_session_r"))[:2] == ("kf_session_r", "calibrated")
    with pytest.raises(GyrosimError, match="use --method kf_hand_joint"):
        resolve_run_method(RunOptions(method="kf_hand", accelerometer="estimate"), flag="--method")
    with pytest.raises(GyrosimError, match="hand-blind filters"):
        resolve_run_method(RunOptions(method="kf_hand_joint", external_acc_allowance_m_s2=0.1))
    with pytest.raises(GyrosimError, match="unknown method 'kf_adaptive'"):
        resolve_run_method(RunOptions(method="kf_adaptive"))
    # calibrate(method=…): the registered names fix the mode; the algorithm's own names warn
    assert resolve_method("kf_joint") == ("kf_session", "estimate")
    assert resolve_method("iterated_session_r") == ("iterated_session", "calibrated")
    with pytest.raises(ValueError, match="use 'kf_joint'"):
        resolve_method("kf_session_r", "estimate")
    with pytest.warns(DeprecationWarning, match="use 'kf_session_r', its registered name"):
        assert resolve_method("kf_session", "calibrated") == ("kf_session", "calibrated")


def test_monte_carlo_takes_a_former_method_spelling_with_a_note(monkeypatch):
    """The note comes before the (long) run, and the library gets the name as asked (its table keeps it)."""
    import calib.scoring.montecarlo as mc

    asked = {}

    def stop(*args, **kwargs):
        asked["methods"] = args[5]
        raise mc.GyrosimError("stopped here by the test")

    monkeypatch.setattr(mc, "monte_carlo", stop)
    rc, _, err = _call(["lab", "montecarlo", "--methods", "kf,kf_session", "--accelerometer", "estimate"])
    assert rc == 2 and asked["methods"] == ("kf", "kf_session")
    assert err.splitlines()[0] == ("warning: --methods kf_session is deprecated: use kf_joint (the same filter with "
                                   "--accelerometer estimate, by its registered name; the table keeps the name asked)")


# ---------------------------------------------------------------- exit codes, one table for every command family

@pytest.fixture(scope="module")
def static_file(folder):
    from gyrosim.simulate import simulate

    return str(save_hdf5(simulate("static", "ideal", "mpu9250", 100.0, seed=2), folder / "static.h5"))


def test_exit_codes_of_the_noise_family(static_file, folder):
    assert _call(["allan", static_file])[0] == 0
    # white noise alone does not describe the MPU-9250 preset's gyro (the automatic choice adds a Gauss–Markov
    # term): status inconsistent, exit 1
    rc, _, err = _call(["noise", static_file, "--model", "white", "--json", str(folder / "noise.json")])
    status = json.loads((folder / "noise.json").read_text(encoding="utf-8"))["status"]
    assert status == "inconsistent" and rc == 1
    assert err.strip() == ("noise model inconsistent: the model does not describe every axis (see the INCONSISTENT "
                           "axes above)")
    assert _call(["noise", static_file, "--span", "1-2"])[0] == 2   # was a bare SystemExit: exit 1
    assert _call(["plan", "--sensor", "no_such_sensor"])[0] == 2   # (a whole plan takes half a minute: not here)


@pytest.mark.parametrize("argv, why", [
    (["run", "{static}", "--method", "no_such_method"], "argument --method: invalid choice: 'no_such_method'"),
    (["run", "{static}"], "never turns"),                                 # a motionless file: nothing to calibrate
    (["apply", "{static}", "{static}", "--out", "x.h5"], "not a calibration"),
    (["temperature", "{static}"], "chamber cycles"),
    (["mag", "{static}"], "magnetometer"),
    (["northfind", "{static}"], ""),
    (["tilt", "{static}"], ""),
    (["closeloop", "{static}"], "--out"),
    (["lab", "montecarlo", "--seeds", "1"], "--seeds"),
])
def test_bad_input_exits_2_with_one_line(argv, why, static_file):
    rc, _, err = _call([a.replace("{static}", static_file) for a in argv])
    assert rc == 2 and why.lower() in err.lower(), err


@pytest.mark.parametrize("argv, target", [
    (["run", "{rec}"], "calib.session.run.run_session"),
    (["allan", "{static}"], "calib.noise.allan_triads.allan_triads"),
    (["mag", "{static}"], "calib.inputs.open_recording"),
    (["northfind", "{static}"], "calib.instruments.northfind.find_north"),
    (["closeloop", "{static}", "--out", "{folder}/cl"], "calib.closeloop.run_closeloop"),
    (["temperature", "{static}"], "calib.inputs.open_recording"),
    (["lab", "northfind-latitude"], "calib.instruments.northfind_plan.latitude_curve"),
])
def test_an_internal_error_exits_3_with_one_line(argv, target, static_file, recording, folder, monkeypatch):
    import importlib
    import re

    module, name = target.rsplit(".", 1)

    def broken(*args, **kwargs):
        raise RuntimeError("a bug")

    monkeypatch.setattr(importlib.import_module(module), name, broken)
    monkeypatch.delenv("GYROSIM_TRACEBACK", raising=False)
    rc, _, err = _call([a.replace("{static}", static_file).replace("{rec}", recording).replace("{folder}", str(folder))
                        for a in argv])
    lines = [line for line in re.split(r"[\r\n]", err) if line.strip()]   # (a progress bar redraws with \r)
    assert rc == 3 and lines[-1].startswith("calib: internal error") and "RuntimeError: a bug" in lines[-1], err
    assert sum("error" in line for line in lines) == 1, err
