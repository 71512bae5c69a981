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

from gyrosim.errors import RecordingError
from gyrosim.loaders import available_datasets

from calib import calibrate, load_recording
from calib.session.gravityfit import compensate_acc
from calib.session.hand.checks import DISPLACEMENT_MAX_M, LEVER_ARM_MAX_M
from calib.session.hand.filter import kf_hand
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


# imucal 2.6.0's FerrarisCalibration of the same file in our frame (the symmetric part of its gyro matrix,
# docs/real_imu.md, computed by benchmarks/real_imu.py): S_x, S_y, S_z, G_x, G_y, G_z.
IMUCAL_SG = np.array([0.02785, -0.01765, -0.00172, 0.00244, 0.00166, -0.00006])


@needs("imucal_ferraris")
@pytest.mark.xfail(strict=True, reason=(
    "open: with the |f| = g fit weighing each pose by its own scatter, the accelerometer's residual on this session "
    "fell from 10.9 to 0.8 mg, and kf_hand's S_y, S_z now show their own disagreement with imucal's (0.008, 0.005: "
    "5-16 sigma) that the residual used to cover"))
def test_ferraris_with_calibrated_accelerometer_agrees_with_imucal():
    """With the accelerometer calibrated first (our joint estimate's accelerometer part applied), kf_hand's
    S, G agree with imucal's within 3σ + ε, ε the residual accelerometer error kf_hand's own check reports
    (the rests' |f| spread, 10.9 mg: a tilt reference error that biases S, G by ~ε) — measured: |δ| ≤ 0.008,
    up to 3.8 σ alone (S_z), ε = 0.011.  Since ε exceeds σ the status is honestly not ok.  And the raw
    accelerometer puts kf_hand's S, G far further from imucal's (G_y 9.8 σ off)."""
    rec = _load("imucal_ferraris")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        joint = calibrate(rec, "kf_joint")
    th = np.concatenate([joint.value("accelerometer", k) for k in ("bias", "scale_factor", "nonorthogonality")])
    cal = _hand(rec.with_signals(acc_m_s2=compensate_acc(rec.acc_m_s2, th)))
    sg = np.concatenate([cal.scale_factor, cal.nonorthogonality])
    sd = np.concatenate([cal.scale_factor_std, cal.nonorthogonality_std])
    eps = cal.diagnostics["assumptions"]["rest_acc_norm_spread_g"]
    assert np.all(np.abs(sg - IMUCAL_SG) <= 3 * sd + eps), (sg - IMUCAL_SG) / sd
    if eps > np.median(sd):
        assert cal.status != "ok"
    raw = _hand(rec)
    raw_sg = np.concatenate([raw.scale_factor, raw.nonorthogonality])
    assert np.max(np.abs(sg - IMUCAL_SG)) < 0.5 * np.max(np.abs(raw_sg - IMUCAL_SG))


@needs("xio_ximu_thermometer")
def test_too_short_rest_is_a_named_error():
    """49 s x-IMU export whose longest rest is 1.86 s: a named RecordingError (calib run: exit 2), no traceback."""
    with pytest.raises(RecordingError, match="rest"):
        _hand(_load("xio_ximu_thermometer"))
