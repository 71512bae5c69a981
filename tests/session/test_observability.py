"""Observability (Zhou 2020 §4): Table 5's conclusions and Tables 10–11's structure."""

from __future__ import annotations

import numpy as np
import pytest

from gyrosim.schedule import load_schedule

from calib.session.observability import parameter_gram, segment_observability, som, unobservable_parameters

G = 9.80665


@pytest.fixture(scope="module")
def rows():
    return segment_observability(load_schedule("zhou2020"), 100.0, without={
        1: [("G_x", "G_y")], 4: [("G_y", "G_z")], 7: [("S_y", "G_x", "G_z")], 9: [("S_x", "G_y", "G_z")],
        14: [("S_z", "G_x", "G_y")]})


def test_table5_conclusions_per_segment(rows):
    # Zhou 2020 Table 5: which parameters each rotation makes observable
    expected = {1: ("G_x", "G_y"), 4: ("G_y", "G_z"), 7: ("S_y", "G_x", "G_z"), 9: ("S_x", "G_y", "G_z"),
                14: ("S_z", "G_x", "G_y"), 0: (), 16: ()}
    for i, names in expected.items():
        assert set(rows[i].observable) == set(names), (i, rows[i].label, rows[i].observable)


def test_tables_10_11_structure(rows):
    for i in (1, 4, 7, 9, 14):
        sv = rows[i].singular_values
        # two levelling values equal g (the paper's 9.8 rows), exactly
        assert np.sum(np.isclose(sv, G, rtol=1e-12)) >= 2
        (without,) = rows[i].without.values()
        # without the states the rotation observes, only the two levelling values remain
        assert np.allclose(without[without > 1e-9], [G, G], rtol=1e-12)
    # a vertical rotation at RMS rate ω gives two values g·ω_RMS (paper: 8.52, 8.51 at its rate);
    # the minimum-jerk 2π in 9 s has ω_RMS = 1.195 × 2π/9 = 0.834 rad/s → 8.18 m/s²
    omega_rms = np.sqrt(900 * 576 / 362880) * 2 * np.pi / 9
    np.testing.assert_allclose(np.sort(rows[1].singular_values)[-4:-2], [G * omega_rms] * 2, rtol=1e-3)


def test_body_frame_gram_equals_the_som_gram():
    # the attitude cancels in the parameter block: Σ Xᵀ[g_b×]ᵀ[g_b×]X = (SOM parameter columns)ᵀ(…)
    s = load_schedule("zhou2020")
    t = np.arange(63, 81, 0.1)
    kin = s.kinematics(t)
    full = som(kin.omega_body_rad_s, kin.quat_nb)
    from gyrosim.rotations import quat_conjugate, quat_rotate

    g_b = quat_rotate(quat_conjugate(kin.quat_nb), np.array([0.0, 0.0, G]))
    np.testing.assert_allclose(parameter_gram(kin.omega_body_rad_s, g_b), full[:, 3:].T @ full[:, 3:], atol=1e-9)
    # 63–81 s is the y-horizontal rotation: Table 5 says it observes (S_y, G_x, G_z) only
    assert unobservable_parameters(parameter_gram(kin.omega_body_rad_s, g_b)) == ["S_x", "S_z", "G_y"]
