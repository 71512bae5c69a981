"""kf_hand's state counts as its docstrings and ``calib bench`` state them, against :func:`calib.handkf.hand_layout`
(they said "24 states" after the temperature block made it 27 on a warming sensor)."""

from __future__ import annotations

import re

from calib import bench
from calib.handkf import hand_layout, kf_hand
from calib.kalman import HAND_JOINT


def test_state_counts_in_the_docstrings_are_the_layouts():
    n = {(t, g): hand_layout(t, g).n for t in (False, True) for g in (False, True)}
    assert n == {(False, False): 24, (True, False): 27, (False, True): 27, (True, True): 30}
    assert HAND_JOINT.n == 33
    doc = " ".join(kf_hand.__doc__.split())
    assert "24 states, 27 when the recording's temperature moved (s_T), 30 with the opt-in" in doc
    assert "33 states" in doc
    # calib bench times kf_hand on a warming MPU-9250 session: the s_T block is on, g-sensitivity off
    src = open(bench.__file__, encoding="utf-8").read()
    (label,) = re.findall(r'"kf_hand \((\d+) states', src)
    assert int(label) == n[(True, False)]


def test_kf_hand_joint_state_counts_are_its_layouts():
    """kf_hand_joint: 33 states, 39 when the recording's temperature moved (s_T and the accelerometer bias's c_a:
    :func:`calib.handkf.joint_layout`); calib bench's session is a warming MPU-9250, so its label says 39."""
    from calib.handkf import joint_layout

    assert joint_layout(False).n == 33 and joint_layout(True).n == 39
    doc = " ".join(kf_hand.__doc__.split())
    assert "33 states, 39 when the recording's temperature moved" in doc
    src = open(bench.__file__, encoding="utf-8").read()
    (label,) = re.findall(r'"kf_hand_joint \((\d+) states', src)
    assert int(label) == joint_layout(True).n
