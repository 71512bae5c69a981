"""kf_hand's experiments are parameters (calib.session.hand.params.HandParams), not module edits: the defaults are the
validated method, each switch changes what it names and nothing is read from a module global any more.

One warming hand-held session of the independent generator (a bias ramp with the temperature channel that explains
it, a 6-cm lever arm and a sway), run a few times with single fields changed; ~1 s a run.
"""

from __future__ import annotations

import independent_generator as ig
import numpy as np
import pytest

from gyrosim.recording import Recording

from calib.session.hand.filter import kf_hand
from calib.session.hand.params import HandParams

RATE = 50.0


@pytest.fixture(scope="module")
def rec():
    kin = ig.kinematics(RATE)
    n = kin[0].size
    d = ig.generate_arrays(rate_hz=RATE, seed=2, kin=kin, gyro_noise_deg_s=0.05, acc_noise_g=0.001,
                           lever_arm_m=(0.01, 0.06, 0.02), sway_acc_rms_m_s2=0.05,
                           temperature_c=25.0 + 1.5 * np.linspace(0.0, 1.0, n),
                           bias_ramp_rad_s2=(2e-5, -1e-5, 1.5e-5))
    return Recording(d["t_s"], d["gyro_rad_s"], d["acc_m_s2"], meta={"rate_hz": RATE}, temp_c=d["temp_c"])


@pytest.fixture(scope="module")
def default(rec):
    return kf_hand(rec)


def test_the_defaults_are_the_method(rec, default):
    same = kf_hand(rec, params=HandParams())
    assert np.array_equal(same.parameters(), default.parameters())
    assert np.array_equal(same.covariance, default.covariance)
    states = default.diagnostics["filter"]["states"]
    assert {"cb_x", "sT_x", "dt_x"} <= set(states) and "kg_x" not in states   # c_b, s_T, δ on; g-sensitivity off
    assert default.diagnostics["consistency"]["spectral_covariance"] is not None
    assert default.diagnostics["filter"]["passes"] == 3
    assert default.diagnostics["gyro_bias_drift"]["random_walk_factor_used"] in HandParams().qb_ladder


def test_each_switch_changes_what_it_names(rec, default):
    no_cb = kf_hand(rec, params=HandParams(gyro_temp_bias=False))
    assert "cb_x" not in no_cb.diagnostics["filter"]["states"] and "sT_x" in no_cb.diagnostics["filter"]["states"]
    model_sigma = kf_hand(rec, params=HandParams(spectral_sigma=False))
    assert model_sigma.diagnostics["consistency"]["spectral_covariance"] is None
    assert np.array_equal(model_sigma.parameters(), default.parameters())   # σ only: the estimate is the filter's
    assert not np.array_equal(model_sigma.covariance, default.covariance)
    ladder = kf_hand(rec, params=HandParams(qb_ladder=(1.0,), passes=2))
    assert ladder.diagnostics["gyro_bias_drift"]["random_walk_factor_used"] == 1.0
    assert ladder.diagnostics["filter"]["passes"] == 2
    cut = kf_hand(rec, params=HandParams(cutoff_hz=3.0))
    psd, psd0 = cut.diagnostics["hand"]["external_acc_psd"], default.diagnostics["hand"]["external_acc_psd"]
    assert psd["lowpass_hz"] == 3.0 and psd["update_every_samples"] > psd0["update_every_samples"]


def test_a_bad_parameter_is_refused_and_the_old_globals_say_where_they_went():
    with pytest.raises(ValueError, match="sway must be one of"):
        HandParams(sway="lorentz")
    import calib.session.hand.filter as hk

    with pytest.raises(AttributeError, match=r"HandParams\.qb_ladder.*params="):
        hk.QB_LADDER   # the former module switch: reading it says where it went
