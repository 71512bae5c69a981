"""One name per algorithm, and estimators that see only what a user's file carries.

* ``kf`` is the paper's filter everywhere; ``calib run``'s filter (session-wide external-acceleration
  allowance) is ``kf_session`` and labels its result with the registered estimator it equals
  (``kf_joint`` / ``kf_session_r``); ``iterated`` is the three-pass filter, ``smoother`` its
  deprecated alias.
* Every registered estimator and :func:`calib.session.paper.calibrate` give bit-identical results on a
  simulated session and on its user view (:func:`gyrosim.estimator.as_user_file`: samples + rate,
  no truth, no sensor model, no hand): nothing they compute reads the simulator's knowledge.
  Exact equality, not a tolerance: the same arithmetic on the same samples.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from conftest import session

from gyrosim.estimator import as_user_file, load_estimator, registered_estimators
from gyrosim.sensor_model import load_sensor
from gyrosim.simulate import apply_sensor

from calib.session.paper import calibrate


@pytest.fixture(scope="module")
def device_session():
    """The typical hand with the consumer sensor, accelerometer calibrated (a campaign's session)."""
    s = load_sensor("zhou2020_sim_consumer")
    from dataclasses import replace

    s = replace(s, accelerometer=tuple(e for e in s.accelerometer if e.kind == "white_noise"))
    return apply_sensor(session("typical"), s, np.random.default_rng(7))


def _same(a, b) -> None:
    assert a.status == b.status and a.warnings == b.warnings and a.method == b.method
    assert np.array_equal(a.vector("gyro"), b.vector("gyro"))
    assert np.array_equal(np.asarray(a.covariance), np.asarray(b.covariance))


def test_every_registered_estimator_ignores_truth_and_metadata(device_session):
    user = as_user_file(device_session)
    assert user.truth is None and set(user.meta) == {"rate_hz"}
    assert device_session.truth is not None and "sensor_model" in device_session.meta
    # the aliases are tested on their own: smoother below, kf_lever_arm (= kf_hand) in test_honest_sigma.py
    names = [n for n in registered_estimators() if n not in ("smoother", "kf_lever_arm")]
    assert {"kf", "iterated", "kf_hand", "kf_joint", "kf_session_r", "iterated_session_r"} <= set(names)
    for name in names:
        est = load_estimator(name)
        _same(est(device_session), est(user))
    _same(calibrate(device_session, "kf_joint", hand_check=False), calibrate(user, "kf_joint", hand_check=False))


def test_smoother_is_a_warning_alias_of_iterated(device_session):
    user = as_user_file(device_session)
    with pytest.warns(FutureWarning, match="'smoother' is deprecated: use 'iterated'"):   # what a CLI user sees
        smoother = load_estimator("smoother")
    with pytest.warns(DeprecationWarning, match="iterated"):
        old = smoother(user)
    _same(old, load_estimator("iterated")(user))


def test_calib_run_filter_is_registered_under_the_name_it_reports(device_session):
    """calibrate(rec, "kf_session") = kf_session_r with the accelerometer calibrated (same numbers, same label); the
    former spelling "kf" still runs it, with a DeprecationWarning naming the new one."""
    user = as_user_file(device_session)
    new = calibrate(user, "kf_session", accelerometer="calibrated", keep_history=False)
    assert new.method == "kf_session_r"
    _same(new, load_estimator("kf_session_r")(user))
    with pytest.warns(DeprecationWarning, match="kf_session"):
        old = calibrate(user, "kf", accelerometer="calibrated", keep_history=False)
    _same(old, new)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the registered spelling does not warn
        named = calibrate(user, "kf_session_r", accelerometer="calibrated", keep_history=False, hand_check=False)
        assert named.method == "kf_session_r"


@pytest.fixture(scope="module")
def clipped_mag_session():
    """A 9-axis session whose magnetometer clips 25 µT above its largest hard-iron component (seed 4:
    at 221 µT): the stored sensor model declares that rail, a user's file does not."""
    from gyrosim.sensor_model import SensorModel
    from gyrosim.simulate import signal_context

    mag9 = load_sensor("mpu9250_9axis")
    probe = SensorModel("mag", magnetometer=mag9.magnetometer).realize(np.random.default_rng(4))
    rail = float(np.max(np.abs(next(e.value for e in probe.magnetometer if e.kind == "hard_iron")))) + 25.0
    mag = tuple(e if e.kind != "saturation" else type(e)(range=[rail] * 3) for e in mag9.magnetometer)
    dev = SensorModel("clipped", magnetometer=mag).realize(np.random.default_rng(4))
    truth = session("typical")
    m = dev.apply_magnetometer(signal_context(truth), np.random.default_rng(10_004))
    return truth.with_signals(mag_ut=m, meta={**truth.meta, "sensor_model": dev.to_json()}), rail


def test_every_registered_magnetometer_calibrator_ignores_truth_and_metadata(clipped_mag_session):
    """Each calibrator of the ``gyrosim.magnetometer_calibrators`` group (both methods) gives the same
    JSON on the simulated session and on its user view; the rail the stored model declares is not
    used unless passed (range_ut), and then on both alike.  Exact equality: the same arithmetic."""
    import json

    from gyrosim.plugins import load, registered

    rec, rail = clipped_mag_session
    user = as_user_file(rec)
    assert user.truth is None and set(user.meta) == {"rate_hz"} and "sensor_model" in rec.meta
    clipped = int(np.any(np.abs(rec.mag_ut) >= rail * (1 - 1e-9), axis=1).sum())
    assert rail > 200.0 and 100 < clipped < rec.n // 2
    names = tuple(registered("gyrosim.magnetometer_calibrators"))
    assert "ellipsoid" in names

    def js(res):
        return json.dumps(res.to_dict(), sort_keys=True)

    for name in names:
        cal = load("gyrosim.magnetometer_calibrators", name)
        for method in ("ellipsoid", "aided"):
            full, mine = cal(rec, method), cal(user, method)
            assert js(full) == js(mine), (name, method)
            # the rail (221 µT for this device) found from the data alone: its flat tops beyond 200 µT
            assert full.samples["saturated"] == clipped
        passed = cal(user, "ellipsoid", range_ut=rail)   # the user's own datasheet range: the same samples
        assert passed.samples["saturated"] == clipped and js(passed) == js(cal(rec, "ellipsoid", range_ut=rail))
