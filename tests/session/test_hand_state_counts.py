"""kf_hand's state counts as its docstrings and ``calib bench`` state them, against
:func:`calib.session.hand.params.hand_layout` (they said "24 states" after the temperature block made it 27 on a warming
sensor; the accelerometer's delay δ adds three more)."""

from __future__ import annotations

import re

from calib.scoring import speed as bench
from calib.session.hand.filter import hand_layout, kf_hand
from calib.session.model import HAND_JOINT


def test_state_counts_in_the_docstrings_are_the_layouts():
    n = {(t, g): hand_layout(t, g).n for t in (False, True) for g in (False, True)}
    assert n == {(False, False): 27, (True, False): 33, (False, True): 30, (True, True): 36}
    assert {t: hand_layout(t, delay=False).n for t in (False, True)} == {False: 24, True: 30}
    assert HAND_JOINT.n == 33
    doc = " ".join(kf_hand.__doc__.split())
    assert "27 states, 33 when the recording's temperature moved (c_b, s_T), 36 with the opt-in" in doc
    assert "36 states" in doc
    # calib bench times kf_hand on a warming MPU-9250 session: the c_b and s_T blocks are on, g-sensitivity off
    src = open(bench.__file__, encoding="utf-8").read()
    (label,) = re.findall(r'"kf_hand \((\d+) states', src)
    assert int(label) == n[(True, False)]


def test_kf_hand_joint_state_counts_are_its_layouts():
    """kf_hand_joint: 36 states, 42 when the recording's temperature moved (s_T and the accelerometer bias's c_a:
    :func:`calib.session.hand.params.joint_layout`; both with the accelerometer's delay δ); calib bench's session is a
    warming MPU-9250, so its label says 45 with the gyro's misalignment α that its motion determines (48 with the
    opt-in c_b)."""
    from calib.session.hand.filter import joint_layout

    assert (
        joint_layout(False).n == 36 and joint_layout(True).n == 42 and joint_layout(True, gyro_temp_bias=True).n == 45
    )
    assert joint_layout(False, delay=False).n == 33
    doc = " ".join(kf_hand.__doc__.split())
    assert "36 states, 42 when the recording's temperature moved" in doc
    src = open(bench.__file__, encoding="utf-8").read()
    (label,) = re.findall(r'"kf_hand_joint \((\d+) states', src)
    assert int(label) == joint_layout(True, misalignment=True).n   # + the gyro's misalignment α (the motion sees it)
