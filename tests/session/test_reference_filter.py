"""The compiled filter (calib.session.kernel.run_filter) against its readable twin (calib.session.reference): the same
runs, state for state, on every layout and option the methods use — the paper's 9 states, the joint 21, the hand's
layouts with the thermal blocks, the g-sensitivity, the accelerometer bias's temperature coefficient, the delay, the
Gauss–Markov and the band-limited sway, update masks, rests, gating, per-sample R, two and three measurement rows,
the lever arm term's Jacobian, batches.  Short recordings (4 s at 50 Hz) of the independent generator, so every
case runs in well under a second in the reference.

Tolerance: the two evaluate the same equations in a different order (the kernel on H's and Φ's non-zero columns,
the reference on dense matrices through filterpy), so they differ by float64 rounding, ε = 2.2e-16 relative per
operation.  A step sums O(n) products per element (n ≤ 45) and the differences accumulate over the N = 200 steps:
N · n · ε ≈ 2e-12 relative to each quantity's own scale (measured: 1e-15 for the paper's and the hand's layouts,
up to 2.4e-12 for P of the joint layouts, whose tilt–accelerometer coupling in P₀ is ill-conditioned).  So: states,
attitude, innovations and P (each element against √(P_ii P_jj)) to 1e-9 — a factor ~400 above that, and six orders
below a modelling difference (a column of H off by 0.1 % moves them by 1e-4 or more: the last test perturbs one
and must fail this comparison).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from independent_generator import generate_arrays, kinematics

from calib.session.hand.filter import hand_layout, joint_layout, lever_jacobian, lever_regressor
from calib.session.kernel import run_filter
from calib.session.model import HAND, JOINT, PAPER, FilterConfig, StateLayout, initial_covariance, m_matrix
from calib.session.reference import run_reference

RATE = 50.0
# rest 1 s, then turns about z, x and y with a tip between: every S, G direction excited within 4 s
STEPS = [("rest", None, 0.0, 1.0), ("rot", 2, math.pi / 2, 1.0), ("rot", 0, math.pi / 3, 1.0),
         ("rot", 1, -math.pi / 3, 1.0)]
RTOL = 1e-9


def _session(hand: bool) -> dict:
    """A 4-s session of the independent generator with a raw accelerometer; ``hand``: a 6-cm lever arm and a sway
    (the hand-blind filters' cases run without them, where their model holds)."""
    kin = kinematics(RATE, STEPS)
    d = generate_arrays(rate_hz=RATE, steps=STEPS, kin=kin, seed=11, gyro_noise_deg_s=0.05, acc_noise_g=0.002,
                        acc_bias_g=(0.02, -0.01, 0.015), acc_scale=(0.01, -0.02, 0.005),
                        lever_arm_m=(0.02, 0.06, 0.01) if hand else None, sway_acc_rms_m_s2=0.05 if hand else 0.0)
    t = d["t_s"]
    n = t.size
    theta0 = np.zeros(18)
    theta0[0:3] = (0.028, -0.018, 0.041)                       # S, G near the truth, not on it
    theta0[3:6] = (0.014, -0.011, 0.019)
    theta0[6:9] = np.radians((1.49, -1.01, 0.81))
    theta0[9:12] = (0.15, -0.1, 0.12)
    theta0[12:15] = (0.008, -0.018, 0.004)
    m = m_matrix(theta0[0:3], theta0[3:6])
    w = (d["gyro_rad_s"] - theta0[6:9]) @ np.linalg.inv(m).T
    upd = np.ones(n, bool)
    upd[1::3] = False                                          # decimated updates, as kf_hand
    upd[57] = False
    return {
        "d": d, "t": t, "n": n, "theta0": theta0,
        "q0": np.array([0.9998, 0.012, -0.015, 0.0]) / np.linalg.norm([0.9998, 0.012, -0.015, 0.0]),
        "lever": lever_regressor(w, t, RATE), "jac": lever_jacobian(w, t, RATE, m),
        "jac_misalign": lever_jacobian(w, t, RATE, m, misalignment=True),
        "temp": np.linspace(-0.4, 0.5, n), "force": d["acc_m_s2"].copy(),
        "acc_rate": np.gradient(d["acc_m_s2"], t, axis=0), "upd": upd,
        "rest": t < 0.9, "r_var": 4e-4 * (1.0 + 0.5 * np.sin(t)),
    }


@pytest.fixture(scope="module")
def sessions():
    return {True: _session(True), False: _session(False)}


def _config(**kw) -> FilterConfig:
    return FilterConfig(arw_rad_s_sqrt_hz=2e-3, vrw_m_s2_sqrt_hz=3e-3, external_acc_allowance_m_s2=0.02, **kw)


def _args(s, layout: StateLayout, cfg: FilterConfig, *, joint_tilt: bool = False, delay_rank_one: bool = True,
          batch: int = 1, **options):
    """run_filter's arguments for one case: P₀ from the layout's priors (with the joint's tilt coupling), a prior mean
    off the nominal, small non-zero nominals of the hand's and the sensor's extra blocks."""
    d = s["d"]
    f0 = d["acc_m_s2"][:10].mean(axis=0)
    p0 = (initial_covariance(layout, cfg, s["q0"], f0, np.eye(3), None, 0.01) if joint_tilt
          else initial_covariance(layout, cfg))
    o = layout.offset("acc_delay")
    if o >= 0 and delay_rank_one:                              # kf_hand's one δ for the triad: a rank-one prior
        v = float(np.mean(np.diag(p0)[o:o + 3]))
        p0[o:o + 3, :] = 0.0
        p0[:, o:o + 3] = 0.0
        p0[o:o + 3, o:o + 3] = v
    x0 = np.zeros(layout.n)
    x0[3:9] = -s["theta0"][0:6]                                # the prior S = G = 0 seen from the nominal
    g = np.repeat(d["gyro_rad_s"][None], batch, 0)
    a = np.repeat(d["acc_m_s2"][None], batch, 0)
    if batch > 1:                                              # the second run differs (batches are per run)
        g[1:] += 1e-4
    kw = dict(x0=x0[None], hand0=np.array([0.01, 0.05, 0.0, 0.01, -0.02, 0.005]),
              sensor0=np.array([1e-4, -1e-4, 2e-4, 3e-4, -2e-4, 1e-4, 0, 0, 0, 1e-3, 0, -1e-3, 1e-3, 1e-3, 1e-3,
                                0.01, -0.006, 0.002]),
              keep_history=True, rest_mask=s["rest"])
    if layout.has("lever_arm"):
        kw.update(lever_regressor=s["lever"],
                  lever_jacobian=s["jac_misalign"] if layout.models_misalignment else s["jac"])
    if layout.models_temperature:
        kw["temperature_rel_c"] = s["temp"]
    if layout.models_g_sensitivity:
        kw["specific_force_m_s2"] = s["force"]
    if layout.models_acc_delay:
        kw["acc_rate_m_s3"] = s["acc_rate"]
    kw.update(options)
    return (g, a, s["t"], np.repeat(s["q0"][None], batch, 0), s["theta0"], p0, layout, cfg, RATE), kw


def _hand_cfg(**kw) -> FilterConfig:
    base = dict(ext_acc_rms_m_s2=0.05, ext_acc_tau_s=0.8, gyro_bias_rw_rad_s_sqrt_s=2e-4,
                prior_gyro_bias_rad_s=(2e-3, 2e-3, 2e-3))
    return _config(**{**base, **kw})


CASES = {
    # the paper's filter: kf, iterated, kf_session_r (x0, rests, saturation mask)
    "paper": lambda s: _args(s, PAPER, _config(), update_mask=s["upd"]),
    # kf_adaptive_gated: R per sample, gating at χ²₂(0.999)
    "paper_adaptive_gated": lambda s: _args(s, PAPER, _config(), r_var_per_sample=s["r_var"], gate_nis=2.0),
    # calib run's joint filter: the tilt's dependence on the accelerometer in P₀
    "joint": lambda s: _args(s, JOINT, _config(), joint_tilt=True, update_mask=s["upd"]),
    # the bounds at the truth: three measurement rows
    "paper_rows3": lambda s: _args(s, PAPER, _config(), rows=3),
    "joint_rows3": lambda s: _args(s, JOINT, _config(), rows=3),
    # the hand-aware bound: HAND (no bias state), the plain Gauss–Markov a_e
    "hand_bound": lambda s: _args(s, HAND, _hand_cfg(gyro_bias_rw_rad_s_sqrt_s=0.0), update_mask=s["upd"],
                                  r_var_per_sample=s["r_var"]),
    # kf_hand on a session whose temperature stayed: bias random walk, δ, second-order high-pass
    "kf_hand": lambda s: _args(s, hand_layout(False), _hand_cfg(ext_acc_highpass_tau_s=3.0, ext_acc_highpass_order=2),
                               update_mask=s["upd"], r_var_per_sample=s["r_var"]),
    # … first-order high-pass, no delay
    "kf_hand_hp1_no_delay": lambda s: _args(s, hand_layout(False, delay=False),
                                            _hand_cfg(ext_acc_highpass_tau_s=5.0, ext_acc_highpass_order=1),
                                            update_mask=s["upd"]),
    # kf_hand on a warming sensor: c_b, s_T (and the g-sensitivity, opt-in)
    "kf_hand_thermal": lambda s: _args(s, hand_layout(True), _hand_cfg(ext_acc_highpass_tau_s=3.0),
                                       update_mask=s["upd"], r_var_per_sample=s["r_var"]),
    "kf_hand_thermal_gsens": lambda s: _args(s, hand_layout(True, True), _hand_cfg(), update_mask=s["upd"]),
    # kf_hand_band: the band-limited sway's general shaping filter
    "kf_hand_band": lambda s: _args(s, hand_layout(False, band=True),
                                    _hand_cfg(ext_acc_band_hz=(0.2, 1.0), ext_acc_band_rms_m_s2=0.04),
                                    update_mask=s["upd"]),
    # kf_hand_joint: the accelerometer's nine states, the vertical row, c_a and s_T on a warming sensor (c_b opt-in)
    "kf_hand_joint": lambda s: _args(s, joint_layout(False), _hand_cfg(ext_acc_highpass_tau_s=3.0,
                                                                        ext_acc_highpass_order=2),
                                     joint_tilt=True, rows=3, update_mask=s["upd"]),
    "kf_hand_joint_thermal": lambda s: _args(s, joint_layout(True), _hand_cfg(), joint_tilt=True, rows=3,
                                             update_mask=s["upd"], r_var_per_sample=s["r_var"]),
    # the gyro's rotation against the accelerometer: on the joint filter (calib run) and on the paper's joint layout
    "kf_hand_joint_misalign": lambda s: _args(s, joint_layout(False, misalignment=True), _hand_cfg(), joint_tilt=True,
                                              rows=3, update_mask=s["upd"]),
    "kf_hand_thermal_misalign": lambda s: _args(s, hand_layout(True, misalignment=True), _hand_cfg(),
                                                update_mask=s["upd"]),
    "joint_misalign": lambda s: _args(s, StateLayout(JOINT.blocks + ("gyro_misalign",)), _config(), joint_tilt=True),
    "kf_hand_joint_thermal_cb": lambda s: _args(s, joint_layout(True, gyro_temp_bias=True), _hand_cfg(),
                                                joint_tilt=True, rows=3, update_mask=s["upd"]),
    # the hand-aware bound's nuisance layouts: s_T, k, δ without the bias state; the band on HAND
    "hand_bound_nuisance": lambda s: _args(s, StateLayout(HAND.blocks + ("gyro_temp_scale", "gyro_g_sens",
                                                                         "acc_delay")),
                                           _hand_cfg(gyro_bias_rw_rad_s_sqrt_s=0.0), update_mask=s["upd"]),
    "hand_bound_band": lambda s: _args(s, StateLayout(HAND.blocks + ("ext_acc_s3", "ext_acc_s4")),
                                       _hand_cfg(ext_acc_band_hz=(0.3, 1.2), ext_acc_band_rms_m_s2=0.03)),
    # the lever arm without its Jacobian (hand_crlb's regressor at the truth), a batch of two runs
    "hand_no_jacobian_batch": lambda s: _args(s, hand_layout(False), _hand_cfg(), lever_jacobian=None, batch=2,
                                              update_mask=s["upd"]),
}
FIELDS = ("theta", "quat", "nis", "innovation", "whitened", "hand", "sensor_extra", "theta_history")


def _compare(fast, ref, case: str) -> None:
    for name in FIELDS:
        a, b = getattr(fast, name), getattr(ref, name)
        assert (a is None) == (b is None), (case, name)
        if a is None:
            continue
        if name in ("innovation", "whitened", "nis"):          # NaN where no update, in both
            assert np.array_equal(np.isnan(a), np.isnan(b)), (case, name)
            a, b = np.nan_to_num(a), np.nan_to_num(b)
        scale = max(float(np.max(np.abs(b))), 1e-12)
        assert np.max(np.abs(a - b)) <= RTOL * scale, (case, name, float(np.max(np.abs(a - b))), scale)
    # P relative to its own diagonal: each element against √(P_ii P_jj)
    sd = np.sqrt(np.einsum("bii->bi", ref.p))
    rel = np.abs(fast.p - ref.p) / np.maximum(sd[:, :, None] * sd[:, None, :], 1e-300)
    assert np.max(rel) <= RTOL, (case, "P", float(np.max(rel)))
    sh_a, sh_b = fast.sd_history, ref.sd_history
    assert np.max(np.abs(sh_a - sh_b) / np.maximum(sh_b, 1e-300)) <= RTOL, (case, "sd_history")


@pytest.mark.parametrize("case", sorted(CASES))
def test_the_kernel_equals_the_reference(sessions, case):
    args, kw = CASES[case](sessions[not case.startswith(("paper", "joint"))])
    fast = run_filter(*args, **kw)
    ref = run_reference(*args, **kw)
    assert np.isfinite(fast.p).all() and np.sum(~np.isnan(fast.nis)) > 50   # a real run: updates happened
    _compare(fast, ref, case)


def test_recording_the_linear_model_does_not_change_the_run(sessions):
    # calib.session.spectral reads the first run's linear error model; asking for it leaves the run as it was
    args, kw = CASES["kf_hand"](sessions[True])
    plain, recorded = run_filter(*args, **kw), run_filter(*args, **kw, record=True)
    assert recorded.record is not None and recorded.record.updated.sum() > 50
    for name in FIELDS + ("p",):
        assert np.array_equal(getattr(plain, name), getattr(recorded, name), equal_nan=True), name


def test_the_comparison_catches_a_wrong_equation(sessions, monkeypatch):
    # the comparison is not vacuous: the reference with one Φ column scaled by 1.001 (the lever arm's H,
    # then the g-sensitivity's E column) fails it
    from calib.session import reference

    args, kw = CASES["kf_hand_thermal_gsens"](sessions[True])
    fast = run_filter(*args, **kw)
    real = reference.ZhouFilter.measurement

    def wrong_h(self, *a, **k):
        z, H = real(self, *a, **k)
        o = self.layout.offset("lever_arm")
        H[:, o:o + 3] *= 1.001
        return z, H

    monkeypatch.setattr(reference.ZhouFilter, "measurement", wrong_h)
    with pytest.raises(AssertionError):
        _compare(fast, run_reference(*args, **kw), "wrong H")
