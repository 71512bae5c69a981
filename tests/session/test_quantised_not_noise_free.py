"""A coarsely quantised *real* sensor is not noise-free (calib.session.noiselevels: ``at_floor`` vs ``noise_free``).

calib run's filter and the paper's ``kf`` exempted every recording whose rest noise sat below its floor
(``at_floor``) from the σ-inflation rule (σ grown > ×1.5 ⇒ inconsistent) and from the hand cross-check — an
exemption meant for noise-free simulated input, whose residual is the integration's own discretisation error.
A real sensor with ~1 LSB of noise is also ``at_floor`` (imucal's NilsPod with the accelerometer calibrated:
1.50e-2 measured against a 1.51e-2 floor), so a disturbance that makes the same session ``inconsistent``
with a fine LSB was let through as ``ok`` with a coarse one.  Now the exemption needs ``noise_free`` (rest
noise below half the floor), as kf_hand's.

Data: the independent generator (tests/independent_generator.py), no tremor or sway, a 2.2-cm lever arm
(the disturbance), the consumer noise (1 mg), the accelerometer rounded to a 0.04 m/s² LSB (4 mg: a 12-bit
±8 g part) — its rest noise 0.0096 m/s² sits below the LSB floor 0.0115 m/s² (at_floor) but above half of it.
Measured (seeds 0–3): σ inflated ×3.5–3.6 from the innovations, status ``ok`` before, ``inconsistent`` now; the
unquantised session: inflated ×4.4, ``inconsistent`` both before and now.
"""

from __future__ import annotations

import warnings

import independent_generator as ig
import numpy as np

from gyrosim.recording import Recording

from calib import calibrate
from calib.session.consistency import INFLATION_INCONSISTENT_SIGMA
from calib.session.paper import prepare

LSB_M_S2 = 0.04


def _session(lsb_m_s2: float | None) -> Recording:
    d = ig.generate_arrays(rate_hz=100.0, kin=ig.kinematics(100.0), seed=0, gyro_noise_deg_s=0.05, acc_noise_g=0.001,
                           lever_arm_m=(0.01, 0.0, 0.02), tremor_acc_rms_m_s2=0.0, sway_acc_rms_m_s2=0.0)
    acc = d["acc_m_s2"] if lsb_m_s2 is None else np.round(d["acc_m_s2"] / lsb_m_s2) * lsb_m_s2
    return Recording(d["t_s"], d["gyro_rad_s"], acc, meta={"rate_hz": 100.0})


def test_a_coarse_lsb_does_not_exempt_a_real_sensor_from_the_inflation_rule():
    rec = _session(LSB_M_S2)
    noise = prepare(rec, accelerometer="calibrated").noise
    assert noise.at_floor and not noise.noise_free          # the case: real noise at about one LSB
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        coarse = calibrate(rec, "kf_session", accelerometer="calibrated")
        fine = calibrate(_session(None), "kf_session", accelerometer="calibrated")
    infl = coarse.diagnostics["consistency"]["sigma_inflation"]
    # the lever arm's low-frequency residual: σ grows ×3.5 (κ̂ ≈ 12.8), far above the rule's ×1.5
    assert np.sqrt(infl["covariance_factor"]) > 2 * INFLATION_INCONSISTENT_SIGMA
    assert fine.status == "inconsistent"
    assert coarse.status == "inconsistent", coarse.warnings          # "ok" before: the LSB bought an exemption
