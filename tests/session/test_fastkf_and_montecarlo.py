"""The compiled fast path equals the filterpy filter; the Monte Carlo reaches the Cramér–Rao bound
with consistent covariances."""

from __future__ import annotations

import numpy as np
from independent_generator import generate
from scipy import stats

from calib.inputs import load_recording
from calib.scoring.montecarlo import monte_carlo
from calib.session.kernel import run_batch
from calib.session.paper import calibrate, prepare


def test_fast_path_equals_filterpy_to_1e_9(tmp_path):
    """The compiled kernel and the filterpy reference run the same arithmetic (kalman docstring): the
    whole calibration agrees to 1e-9 for the paper's 9 states and the 21 joint states, and every member
    of a batch equals the single run."""
    path = tmp_path / "imu.csv"
    generate(path, seed=5, acc_bias_g=(0.05, -0.04, 0.06), acc_scale=(0.02, -0.01, 0.015))
    rec = load_recording(path, "deg/s", "g")
    for mode in ("calibrated", "estimate"):
        ref = calibrate(rec, "kf_session", accelerometer=mode, engine="filterpy")
        fast = calibrate(rec, "kf_session", accelerometer=mode)
        assert np.abs(fast.parameters() - ref.parameters()).max() < 1e-9, mode
        assert np.abs(fast.covariance - ref.covariance).max() < 1e-9 * np.abs(ref.covariance).max(), mode
        np.testing.assert_allclose(fast.history.nis, ref.history.nis, rtol=1e-6, atol=1e-9)
    prep = prepare(rec, accelerometer="calibrated")
    a = prep.start
    g = (rec.gyro_rad_s - prep.bias.value_rad_s)[None, a:]
    out = run_batch(np.repeat(g, 3, 0), np.repeat(rec.acc_m_s2[None, a:], 3, 0), rec.t_s[a:],
                    np.repeat(prep.quat0_nb[None], 3, 0), prep.config, rec.rate_hz)
    for b in range(1, 3):  # every member of the batch
        assert np.abs(out.scale[b] - out.scale[0]).max() == 0.0
        assert np.abs(out.p[b] - out.p[0]).max() == 0.0


def test_monte_carlo_reaches_the_bound_and_is_consistent():
    """12 seeds of zhou2020 / ideal hand / Table 7 reading A.

    RMSE from R = 12 runs scatters by ≈ 1/√(2R) = 20 % (1σ), so for a method at the bound
    (efficiency 1; the 50-seed table in docs/calibration.md gives 0.90-1.11) every efficiency must stay
    below 1 + 3 × 0.2 = 1.6.  NEES: the mean over R runs of 6-dof χ² is inside its 99.9 % band.
    """
    r = monte_carlo("zhou2020", "ideal", "zhou2020_sim", seeds=12)
    for method, st in r.methods.items():
        assert np.all(st.efficiency < 1.6), (method, st.efficiency)
        lo, hi = stats.chi2.ppf([0.0005, 0.9995], 6 * r.seeds) / r.seeds
        assert lo < st.nees_mean < hi, (method, st.nees_mean)
    # the bound is informative: √CRLB of S is a few 1e-3 (reading A), far below the 0.05 prior
    assert np.all(r.sqrt_crlb[3:9] < 0.006)


def test_monte_carlo_refuses_a_gyro_only_method_when_scoring_the_accelerometer():
    # the paper's kf assumes a calibrated accelerometer and reports no σ for its parameters: scoring them
    # used to die inside a matrix inverse (exit 3); now the first session names the method and the fix
    import pytest

    from gyrosim.errors import GyrosimError

    with pytest.raises(GyrosimError, match=r"'kf' does not estimate them.*kf_session"):
        monte_carlo(sensor="mpu9250_linear", seeds=2, methods=("kf",), accelerometer="estimate")


def test_monte_carlo_refuses_a_declared_gyro_only_method_before_simulating(monkeypatch):
    # kf, kf_hand, ... declare estimates = ("gyro",): the refusal comes before the first seed is simulated
    # (it used to come after one MuJoCo session); a joint method declares both triads and is not refused
    import pytest

    from gyrosim.errors import GyrosimError
    from gyrosim.estimator import estimated_triads, load_estimator

    import calib.scoring.montecarlo as mc

    def no_simulation(*a, **k):
        raise AssertionError("simulated before refusing")

    monkeypatch.setattr(mc, "simulate_truth", no_simulation)
    for m in ("kf", "kf_hand", "kf_session_r"):
        with pytest.raises(GyrosimError, match=rf"'{m}' does not estimate them"):
            mc.monte_carlo(sensor="mpu9250_linear", seeds=2, methods=("kf_session", m), accelerometer="estimate")
    assert estimated_triads(load_estimator("kf_joint")) == ("gyro", "accelerometer")
    assert estimated_triads(mc._estimator("kf_session", "estimate")) == ("gyro", "accelerometer")
    assert estimated_triads(mc._estimator("kf_session", "calibrated")) == ("gyro",)
