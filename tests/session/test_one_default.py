"""One default method (calib.session.defaults): ``calib run``, ``calib demo`` and ``calibrate()`` run the same
registered name when none is named — they ran three (kf_hand_joint, kf_joint, kf_joint).  The former default stays
reachable by naming it; a ``calibrate()`` call that sets an option only the hand-blind filter has keeps running it,
with a DeprecationWarning saying to name it.
"""

from __future__ import annotations

import inspect
import warnings

import independent_generator as ig
import pytest

from gyrosim.recording import Recording

from calib import calibrate
from calib.app.demo import run_demo
from calib.session.defaults import DEFAULT_METHOD, HAND_AWARE_METHODS, default_method
from calib.session.run import SESSION_METHODS, RunOptions, resolve_run_method


def test_the_three_entry_points_share_one_default():
    assert DEFAULT_METHOD == "kf_hand_joint" and DEFAULT_METHOD in SESSION_METHODS
    assert resolve_run_method(RunOptions())[0] == DEFAULT_METHOD == default_method()
    assert resolve_run_method(RunOptions(accelerometer="calibrated"))[0] == default_method("calibrated") == "kf_hand"
    assert resolve_run_method(RunOptions(external_acc_allowance_m_s2=0.1))[0] == default_method(None, 0.1) == "kf_joint"
    assert default_method("calibrated", 0.1) == "kf_session_r"
    assert inspect.signature(run_demo).parameters["method"].default is None        # → default_method(accelerometer)
    assert inspect.signature(calibrate).parameters["method"].default is None
    assert set(HAND_AWARE_METHODS) == {n for n, (alg, _) in SESSION_METHODS.items() if alg == "hand"}


@pytest.fixture(scope="module")
def session() -> Recording:
    """A short clean-ish session of the independent generator (consumer noise, no hand): every filter runs on it."""
    d = ig.generate_arrays(rate_hz=100.0, kin=ig.kinematics(100.0), seed=0, gyro_noise_deg_s=0.05, acc_noise_g=0.001,
                           lever_arm_m=(0.0, 0.0, 0.0), tremor_acc_rms_m_s2=0.0, sway_acc_rms_m_s2=0.0)
    return Recording(d["t_s"], d["gyro_rad_s"], d["acc_m_s2"], meta={"rate_hz": 100.0})


def test_calibrate_runs_the_default_and_the_former_one_by_name(session):
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)      # neither call warns
        default = calibrate(session, keep_history=False)
        former = calibrate(session, "kf_joint", keep_history=False)
    assert default.method == DEFAULT_METHOD and former.method == "kf_joint"
    # a hand-blind option without a method: the former default, and a note saying the default changed
    with pytest.warns(DeprecationWarning, match="now runs kf_hand_joint; iterations is an option of the hand-blind"):
        kept = calibrate(session, iterations=1, keep_history=False)
    assert kept.method == "kf_joint"
    with pytest.raises(ValueError, match="engine: option"):
        calibrate(session, "kf_hand_joint", engine="filterpy")
    with pytest.raises(ValueError, match="use 'kf_hand_joint'"):
        calibrate(session, "kf_hand", accelerometer="estimate")
