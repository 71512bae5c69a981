"""``kf_hand`` on the measured recordings (docs/real_imu.md, "kf_hand on the measured recordings");
skipped with a reason when a dataset is absent (``GYROSIM_DATA``; the data are never committed).

A method exact on our simulator can be wrong on anyone else's data: these tests hold it to physical facts
of each recording — a truth-based attitude score (BROAD's optical attitude), a peer's calibration of the same
file (imucal's Ferraris session), the hand's plausibility (x-io Fusion, hand-held) — and to an honest status
wherever one of kf_hand's assumptions fails (raw accelerometer, impacts, a far "lever arm").

Fast tests run whole files (kf_hand takes ≤ 0.6 s CPU on each: no segments needed); the BROAD sweep over
all seven trials is under ``slow``.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from imucal_reference import IMUCAL_SG

from gyrosim.errors import RecordingError
from gyrosim.loaders import available_datasets
from gyrosim.units import G0

from calib import load_recording
from calib.inputs.turns import turns_for_protocol
from calib.session.gravityfit import compensate_acc
from calib.session.hand.checks import DISPLACEMENT_MAX_M, LEVER_ARM_MAX_M
from calib.session.hand.filter import kf_hand
from calib.session.hand.params import HandParams
from calib.session.six_poses import six_pose_accelerometer
from calib.session.validation import windowed_rotation_error_deg

AVAILABLE = set(available_datasets())
BROAD = sorted(n for n in AVAILABLE if n.startswith("broad/"))


def needs(name: str):
    return pytest.mark.skipif(name not in AVAILABLE, reason=f"measured dataset {name} not found (set GYROSIM_DATA)")


def _load(name: str):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return load_recording("dataset:" + name)


def _hand(rec):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return kf_hand(rec)


def optical_attitude_error_deg(rec, gyro_rad_s: np.ndarray, window_s: float = 5.0, step_s: float = 0.5) -> float:
    """BROAD's score: :func:`calib.session.validation.windowed_rotation_error_deg` against the optical ``opt_quat``."""
    return windowed_rotation_error_deg(rec.t_s, gyro_rad_s, rec.truth.quat_nb, rec.rate_hz, window_s, step_s)


# The score's noise: ~35 independent 5-s windows per trial (3 min), so the RMS has a relative standard error
# ≈ 1/√(2·35) = 0.12; "no worse within its noise" = after ≤ (1 + 2·0.12) × before.
ATTITUDE_TOLERANCE = 1.25


def _broad_verdict(name: str):
    rec = _load(name)
    cal = _hand(rec)
    before = optical_attitude_error_deg(rec, rec.gyro_rad_s - cal.bias_rad_s)
    after = optical_attitude_error_deg(rec, cal.compensate(rec).gyro_rad_s)
    return cal, before, after


@needs("broad/25_disturbed_tapping_B")
def test_broad_tapping_is_not_ok():
    """The trial that made kf_hand's "ok" untrustworthy: taps (4.8 m/s² RMS above 4 Hz) made it return S_y, G_y
    4.6 σ and 7.8 σ from a maker-calibrated IMU's ≈ 0 with status ok, and the optical attitude error ×5.8
    after the calibration.  Now the tremor-band check says inconsistent."""
    cal, before, after = _broad_verdict("broad/25_disturbed_tapping_B")
    assert after > ATTITUDE_TOLERANCE * before          # the estimate really is bad (truth-based) …
    assert cal.status != "ok"                             # … and the status says so


@needs("broad/02_undisturbed_slow_rotation_B")
def test_broad_slow_rotation_status_matches_truth():
    """ok ⇒ the calibration does not worsen the optical attitude error beyond the score's noise (measured:
    0.62° → 0.80°, ×1.29, and the status is inconsistent); the lever arm of this hand-held trial is a hand's."""
    cal, before, after = _broad_verdict("broad/02_undisturbed_slow_rotation_B")
    assert np.isfinite(before) and np.isfinite(after)
    assert cal.status != "ok" or after <= ATTITUDE_TOLERANCE * before, (cal.status, before, after)
    assert np.linalg.norm(cal.diagnostics["hand"]["lever_arm_m"]) < LEVER_ARM_MAX_M


@pytest.mark.slow
@pytest.mark.skipif(not BROAD, reason="BROAD trials not found (set GYROSIM_DATA)")
@pytest.mark.parametrize("name", BROAD)
def test_broad_every_trial_ok_only_when_truth_agrees(name):
    """Every BROAD trial: an "ok" must not worsen the optical attitude error beyond its noise."""
    cal, before, after = _broad_verdict(name)
    if cal.status == "ok":
        assert after <= ATTITUDE_TOLERANCE * before, (name, before, after)


@needs("xio_fusion")
def test_xio_fusion_hand_held_plausible_and_honest():
    """x-IMU3 hand-held: the lever arm is a hand's (|r| + 3σ below 30 cm), but the slow external acceleration kf_hand
    fits is not: at periods of 5–20 s it implies a displacement of 2.9 m RMS (calib.session.hand.checks check 4; a hand
    turning a device: ≤ 0.30 m), a 5-s burst of 2.3 m/s² mean |f| − g with rotations to 368 °/s — the device travelled
    or an effect the model lacks was fitted as the hand.  The status was "ok" (honest but uninformative: every S, G
    within 2.5 σ of the factory calibration's ≈ 0), then "inconsistent" with the warning that says why; since the
    update's H carries the lever arm term's dependence on S, G, b (docs/hand.md, "The lever arm term's Jacobian") the
    non-hand acceleration, seen through ω² up to 40 rad²/s², also drags S to −40 … −129 %: "diverged" (S beyond any real
    sensor) — never "ok", and the slow-content warning still says why.  Margin: 2.9 m is 10× the bound; gyrosim's hands
    read ≤ 0.010 m."""
    cal = _hand(_load("xio_fusion"))
    h = cal.diagnostics["hand"]
    r, rsd = np.array(h["lever_arm_m"]), np.array(h["lever_arm_std_m"])
    assert np.linalg.norm(r) + 3 * np.linalg.norm(rsd) < LEVER_ARM_MAX_M
    assert cal.diagnostics["assumptions"]["slow_displacement_rms_m"] > 3 * DISPLACEMENT_MAX_M
    assert cal.status in ("inconsistent", "diverged")
    assert any("slow content" in w and "calib closeloop" in w for w in cal.warnings)


@pytest.mark.parametrize("name", ["imucal_ferraris", "imu_tk_xsens"])
def test_raw_accelerometer_is_flagged(name):
    """Raw accelerometers (NilsPod: rest |f| spread 107 mg; Xsens counts: 234 mg) violate kf_hand's
    calibrated-accelerometer assumption: the status is not ok and the warning says why (before: Ferraris's G
    landed 6–10 σ from imucal's, with a warning calling the data "noise-free")."""
    if name not in AVAILABLE:
        pytest.skip(f"measured dataset {name} not found (set GYROSIM_DATA)")
    cal = _hand(_load(name))
    assert cal.status != "ok"
    assert any("accelerometer is not calibrated" in w for w in cal.warnings)
    assert not any(w.startswith("noise-free input") for w in cal.warnings)




def _ferraris_with_six_pose_accelerometer():
    """kf_hand with imucal's six poses calibrating the accelerometer (:mod:`calib.session.six_poses`: the box's faces
    at right angles fix its non-orthogonality, which |f| = g at near-axis poses does not), the gyro's rotation
    against it estimated, and the protocol's three 360° turns as known angles."""
    rec = _load("imucal_ferraris")
    acc = six_pose_accelerometer(rec.acc_m_s2, rec.meta["segments"], G0)
    turns = turns_for_protocol("ferraris", rec.meta, rec.t_s)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return kf_hand(rec.with_signals(acc_m_s2=compensate_acc(rec.acc_m_s2, acc.theta())), turns=turns,
                       params=HandParams(misalignment=True))


def _innovations(cal) -> np.ndarray:
    return np.array([t["normalised_innovation"] for t in cal.diagnostics["known_turns"]["turns"]])


@needs("imucal_ferraris")
def test_ferraris_y_turn_agrees_once_the_accelerometer_is_the_six_poses():
    """The y turn's −10σ innovation under calib run's joint filter is the accelerometer's: a shear of the x–z plane
    (G_y) changes the angle gravity shows over a quarter turn about y by 2 G_y, the same as a gyro S_y error, and
    the hand-held motion put G_y at 0.013 ± 0.0007 (the six poses: 0.003).  With the six poses' accelerometer
    and α, S_x, S_y and G land within max(3σ, 0.005) of imucal's (0.005: a hand-made session's agreement — each
    360° turn is known to ±0.5°, 0.0014 of S, and imucal reads the gyro in the box's frame, 0.6° from the
    accelerometer's; measured: S_x 0.0027 off, the rest ≤ 0.001) and the y turn agrees (measured −1.1σ; was
    −10.4σ)."""
    rec = _load("imucal_ferraris")
    turns = turns_for_protocol("ferraris", rec.meta, rec.t_s)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        joint = kf_hand(rec, "estimate", turns=turns)
    assert _innovations(joint)[1] < -5        # the disagreement this test explains
    cal = _ferraris_with_six_pose_accelerometer()
    sg = np.concatenate([cal.scale_factor, cal.nonorthogonality])
    sd = np.concatenate([cal.scale_factor_std, cal.nonorthogonality_std])
    keep = [0, 1, 3, 4, 5]                    # S_z: the next test
    assert np.all(np.abs(sg - IMUCAL_SG)[keep] <= np.maximum(3 * sd, 0.005)[keep]), (sg - IMUCAL_SG) / sd
    assert abs(_innovations(cal)[1]) < 3


@needs("imucal_ferraris")
def test_calib_run_with_the_protocol_applies_the_six_poses_accelerometer_and_matches_imucal():
    """What ``calib run dataset:imucal_ferraris --protocol ferraris`` does (:func:`calib.session.run.run_session`):
    the protocol's six box-face poses give the accelerometer (the prior it is read through, applied as it is), the
    hand-aware filter runs with it calibrated and the gyro's rotation against it estimated, and what it applies
    matches imucal as the test above does (S_z: the strict xfail below)."""
    from calib.session.run import RunOptions, run_session

    rec = _load("imucal_ferraris")
    turns = turns_for_protocol("ferraris", rec.meta, rec.t_s)
    assert [p[0] for p in turns.poses] == ["x_p", "x_a", "y_p", "y_a", "z_p", "z_a"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cal = run_session(rec, RunOptions(turns=turns))
    a = cal.applied
    poses = six_pose_accelerometer(rec.acc_m_s2, rec.meta["segments"], G0)
    np.testing.assert_allclose(a.vector()[9:18], poses.theta(), atol=1e-3)   # σ-level: 1e-4 to 3e-4 (prior.six_poses)
    assert not a.from_session[9:18].any() and "six box-face poses" in a.prior
    sg, sd = a.vector()[3:9], a.sigma_vector()[3:9]
    keep = [0, 1, 3, 4, 5]
    assert a.from_session[3:9].all() and a.gyro_misalignment_rad is not None
    assert np.all(np.abs(sg - IMUCAL_SG)[keep] <= np.maximum(3 * sd, 0.005)[keep]), (sg - IMUCAL_SG) / sd
    # |f| at two of the 12 rests is 0.8 mg off the six faces' calibration (noise 0.08 mg): the check says so and names
    # what calibrated the accelerometer, instead of telling the user to calibrate it
    acc_check = [w for w in cal.warnings if "|f| at rest differs" in w]
    assert len(acc_check) == 1 and "six box-face poses" in acc_check[0], acc_check
    assert "calibrate it first" not in acc_check[0]


@needs("imucal_ferraris")
@pytest.mark.xfail(strict=True, reason=(
    "the sensor's z scale depends on the sign of the rate (benchmarks/sz_ferraris.py): the moves turning +z carry "
    "gravity best at S_z -0.008 to -0.0095, those turning -z (and imucal's -360 deg z turn) at -0.001 to +0.004; "
    "kf_hand's one symmetric S_z (-0.0080 +- 0.0003) takes the + side, imucal's (-0.0017) the - side"))
def test_ferraris_s_z_agrees_with_imucal():
    """S_z within max(3σ, 0.005) of imucal's (measured: 0.0063 off, 21σ)."""
    cal = _ferraris_with_six_pose_accelerometer()
    assert abs(cal.scale_factor[2] - IMUCAL_SG[2]) <= max(3 * cal.scale_factor_std[2], 0.005)


def _carried_s_z(cal, rec, move: int) -> float:
    """S_z that makes gravity carried across ``move`` (between the detector's rests) land where the next rest
    measures it, the gyro's other parameters at ``cal``'s (one Gauss–Newton step: the error is linear in S_z)."""
    from calib.scoring.measured_statics import StaticDetector, integrate_rk4, static_intervals
    from calib.session.model import gyro_axis_matrix

    (s0, e0), (s1, e1) = static_intervals(rec.acc_m_s2, StaticDetector.for_rate(rec.rate_hz))[move:move + 2]
    g0, g1 = (rec.acc_m_s2[a:b + 1].mean(axis=0) for a, b in ((s0, e0), (s1, e1)))
    alpha = cal.value("gyro", "gyro_acc_misalignment")

    def err(sz):
        m = gyro_axis_matrix(np.r_[cal.scale_factor[:2], sz], cal.nonorthogonality, alpha)
        w = (rec.gyro_rad_s - cal.bias_rad_s) @ np.linalg.inv(m).T
        return np.cross(integrate_rk4(w, rec.t_s, e0, s1 - 1).T @ (g0 / np.linalg.norm(g0)), g1 / np.linalg.norm(g1))

    sz, h = float(cal.scale_factor[2]), 1e-3
    d = (err(sz + h) - err(sz - h)) / (2 * h)
    return sz - float(err(sz) @ d / (d @ d))


@needs("imucal_ferraris")
def test_ferraris_z_flips_disagree_by_the_sign_of_the_rate():
    """Why no symmetric S_z fits this sensor: moves 1 and 3 each flip the box ~180° about z to the opposite face
    (x up → down, then y up → down; peak 786 and 706 °/s), so the accelerometer's linear errors cancel in each
    (a face and its opposite see the same rotation of gravity), yet the gravity they carry wants S_z −0.0095 (+z)
    and −0.0011 (−z).  Noise: each move's S_z has σ ≈ 1e-4 (the rests' mean directions, ~0.01°, and the gyro's
    white noise over 2 s, ~0.02°, against 1.8° per 0.01 of S_z), so 0.004 apart is > 30σ; measured 0.0084."""
    rec = _load("imucal_ferraris")
    acc = six_pose_accelerometer(rec.acc_m_s2, rec.meta["segments"], G0)
    rec = rec.with_signals(acc_m_s2=compensate_acc(rec.acc_m_s2, acc.theta()))
    cal = _ferraris_with_six_pose_accelerometer()
    plus, minus = _carried_s_z(cal, rec, 1), _carried_s_z(cal, rec, 3)
    assert plus - minus < -0.004, (plus, minus)
    assert abs(minus - IMUCAL_SG[2]) < 0.002 and abs(plus - cal.scale_factor[2]) < 0.002, (plus, minus)


@needs("xio_ximu_thermometer")
def test_too_short_rest_is_a_named_error():
    """49 s x-IMU export whose longest rest is 1.86 s: a named RecordingError (calib run: exit 2), no traceback."""
    with pytest.raises(RecordingError, match="rest"):
        _hand(_load("xio_ximu_thermometer"))
