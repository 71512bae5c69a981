import math

import numpy as np
import pytest

from gyrosim.errors import ScheduleError
from gyrosim.rotations import quat_angle_between, quat_from_rotvec, quat_multiply, quat_rotate
from gyrosim.schedule import load_schedule, minimum_jerk


def test_zhou2020_matches_table6_times_and_axes():
    s = load_schedule("zhou2020")
    # Table 6 boundaries (s), with the misprinted last row read as 126-135, 135-144, rest to 171
    expected = [0, 9, 18, 27, 36, 45, 54, 63, 72, 81, 90, 99, 108, 117, 126, 135, 144, 171]
    assert list(s.boundaries_s) == expected
    kinds = [seg.kind for seg in s.segments]
    assert kinds.count("switch") == 3 and kinds[0] == "rest" and kinds[-1] == "rest"
    t = np.array([9.0 + 4.5, 36 + 4.5, 63 + 4.5, 81 + 4.5, 126 + 4.5])
    kin = s.kinematics(t)
    # mid-segment the body rate is along the segment's body axis: z, x, y, x, z
    axes = np.argmax(np.abs(kin.omega_body_rad_s), axis=1)
    assert list(axes) == [2, 0, 1, 0, 2]
    # and the axis is vertical (z-vertical, x-vertical) or horizontal as Table 6 says
    up = quat_rotate(kin.quat_nb, np.eye(3)[axes])[:, 2]
    np.testing.assert_allclose(np.abs(up), [1, 1, 0, 0, 0], atol=1e-12)


def test_profile_is_smooth_and_integrates_to_the_angle():
    s = load_schedule("zhou2020")
    t = np.arange(0, s.duration_s, 1e-3)
    kin = s.kinematics(t)
    w = kin.omega_body_rad_s
    # continuous rate and acceleration: the largest 1 ms change of the rate is bounded by
    # max|ω̇|·Δt = 5.77·A/T²·1e-3 = 2.5e-3 rad/s for A = 2π, T = 9 s (no steps at boundaries)
    assert np.abs(np.diff(w, axis=0)).max() < 2.5e-3
    assert np.abs(np.diff(kin.omega_dot_body_rad_s2, axis=0)).max() < 60 * 2 * math.pi / 9**3 * 1e-3 * 1.01
    # integrating the rate over each rotation gives the commanded angle (trapezoid, O(Δt²))
    for i, seg in enumerate(s.segments):
        sel = (t >= s.boundaries_s[i]) & (t <= s.boundaries_s[i + 1])
        if seg.axis_body is not None:
            ang = np.trapezoid(w[sel] @ np.asarray(seg.axis_body), t[sel])
            assert abs(ang - seg.angle_rad) < 1e-5


def test_closed_form_attitude_composes_segment_rotations():
    s = load_schedule("zhou2020")
    q = np.array([1.0, 0, 0, 0])
    for i, seg in enumerate(s.segments):
        if seg.axis_body is not None:
            q = quat_multiply(q, quat_from_rotvec(np.asarray(seg.axis_body) * seg.angle_rad))
        end = s.kinematics(np.array([s.boundaries_s[i + 1] - 1e-12])).quat_nb[0]
        assert quat_angle_between(q, end) < 1e-9


def test_minimum_jerk_endpoints():
    s, ds, dds = minimum_jerk(np.array([0.0, 0.5, 1.0]))
    np.testing.assert_allclose(s, [0, 0.5, 1])
    np.testing.assert_allclose(ds, [0, 1.875, 0])
    np.testing.assert_allclose(dds, [0, 0, 0], atol=1e-12)


def test_user_toml_schedule(tmp_path):
    p = tmp_path / "mine.toml"
    p.write_text(
        'name = "mine"\n[[segments]]\nkind = "rest"\nduration_s = 2\n'
        '[[segments]]\nkind = "rotate"\naxis = [0, 0, 1]\nangle_deg = 90\nduration_s = 3\n'
    )
    s = load_schedule(p)
    assert s.name == "mine" and s.duration_s == 5
    end = s.kinematics(np.array([5.0])).quat_nb[0]
    assert quat_angle_between(end, quat_from_rotvec(np.array([0, 0, math.pi / 2]))) < 1e-12


@pytest.mark.parametrize(
    "body, message",
    [
        ('[[segments]]\nkind = "spin"\nduration_s = 1\n', "unknown segment kind"),
        ('[[segments]]\nkind = "rest"\nduration_s = -1\n', "duration_s"),
        ('[[segments]]\nkind = "rotate"\naxis = "w"\nangle_deg = 9\nduration_s = 1\n', "axis"),
        ('[[segments]]\nkind = "rest"\nduration_s = 1\nspeed = 3\n', "unknown key"),
        ('colour = "red"\n[[segments]]\nkind = "rest"\nduration_s = 1\n', "unknown schedule key"),
    ],
)
def test_bad_schedules_are_rejected_with_a_reason(tmp_path, body, message):
    p = tmp_path / "bad.toml"
    p.write_text(body)
    with pytest.raises(ScheduleError, match=message):
        load_schedule(p)


def test_unknown_schedule_name():
    with pytest.raises(ScheduleError, match="zhou2020"):
        load_schedule("zhou2021")
