"""The one default method of a hand-held session, by registered estimator name: what ``calib run``, ``calib demo``
and :func:`calib.calibrate` run when no method is named.

``kf_hand_joint`` — the hand-aware filter with the accelerometer estimated (:func:`calib.session.hand.filter.kf_hand`):
a hand-held session has a lever arm and the hand's slow acceleration, which the hand-blind filters read as gravity
(docs/hand.md); ``kf_hand`` with the accelerometer calibrated.  An external-acceleration allowance is an option of the
hand-blind filter only, so giving one selects it (``kf_joint``, ``kf_session_r`` calibrated), as ``calib run
--external-acc`` always has.  Every other method is reached by naming it.

Until this module, :func:`calib.calibrate` and ``calib demo`` defaulted to the hand-blind ``kf_joint`` while
``calib run`` ran ``kf_hand_joint``; ``calibrate(rec, "kf_joint")`` and ``run_demo(..., method="kf_joint")`` are the
former behaviour.
"""

from __future__ import annotations

__all__ = ["DEFAULT_METHOD", "HAND_AWARE_METHODS", "default_method", "method_label"]

DEFAULT_METHOD = "kf_hand_joint"
# the hand-aware methods by registered name → their accelerometer mode
HAND_AWARE_METHODS = {"kf_hand_joint": "estimate", "kf_hand": "calibrated"}
# the hand-blind filter's names by accelerometer mode (selected by an external-acceleration allowance)
_HAND_BLIND = {"estimate": "kf_joint", "calibrated": "kf_session_r"}
_HAND_AWARE = {mode: name for name, mode in HAND_AWARE_METHODS.items()}


def default_method(accelerometer: str | None = None, external_acc_allowance_m_s2: float | None = None) -> str:
    """The registered name run when none is named (module docstring): ``kf_hand_joint`` (``kf_hand`` with
    ``accelerometer="calibrated"``), or the hand-blind ``kf_joint`` / ``kf_session_r`` when an external-acceleration
    allowance (m/s² RMS) is given.  An unknown ``accelerometer`` is left to the caller's check (the default's)."""
    mode = accelerometer or "estimate"
    table = _HAND_BLIND if external_acc_allowance_m_s2 is not None else _HAND_AWARE
    return table.get(mode, table["estimate"])


def method_label(name: str) -> str:
    """What a report calls the filter a registered ``name`` ran: the hand-aware one or Zhou 2020's family."""
    return "hand-aware filter (Zhou 2020's, with the hand in the model)" if name in HAND_AWARE_METHODS else (
        "Zhou 2020 filter")
