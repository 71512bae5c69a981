"""What kf_hand's failed innovation tests tell the user (calib.session.consistency, ``hand_aware``).

The hand-blind filters' advice — a larger ``--external-acc``, ``--method iterated_session``, "use kf_hand" —
is no remedy for kf_hand, which already fits the lever arm and the hand's slow acceleration from the data: its
failure means motion outside that model (bursts, taps, a moving pivot) or a sensor effect it lacks, and the
advice must say so.  The other methods' messages stay as they were.
"""

from __future__ import annotations

import re
import warnings

import pytest

from calib.session.consistency import INCONSISTENT_FRACTION, Consistency, Inflation, apply_inflation, verdict
from calib.session.run import FORMER_METHODS, RunOptions, resolve_run_method

HAND_BLIND_ADVICE = ("--external-acc", "iterated_session", "hand-aware method (kf_hand)")


def _consistency(fraction_above: float, nis_mean: float = 2.5) -> Consistency:
    return Consistency(rows=2, nis_mean=nis_mean, windows=180, window_samples=100, band=(0.1, 9.0),
                       fraction_above=fraction_above, fraction_below=0.0)


@pytest.mark.parametrize("fraction", [2 * INCONSISTENT_FRACTION, 0.9])     # inconsistent, diverged
def test_hand_aware_innovation_failure_names_what_its_model_lacks(fraction):
    status, notes = verdict(_consistency(fraction), [], None, "calibrated", hand_aware=True)
    assert status in ("inconsistent", "diverged")
    (w,) = notes
    assert not any(a in w for a in HAND_BLIND_ADVICE), w
    assert "calib run --method kf_hand_joint" in w and "calib closeloop" in w and "pivot" in w
    # the hand-blind filters keep their own remedies
    _, blind = verdict(_consistency(fraction), [], None, "calibrated")
    assert "--external-acc" in blind[0]


def test_hand_aware_inflation_warning_and_status():
    """σ ×2 from the innovations (κ̂ = 4 > ×1.5²): inconsistent either way; kf_hand's text names its model's
    limits, the hand-blind filters' text still points to kf_hand."""
    infl = Inflation(kappa=4.0, dof=40, threshold=1.4, factor=4.0)
    notes: list[str] = []
    assert apply_inflation("ok", notes, infl, hand_aware=True) == "inconsistent"
    assert not any(a in w for w in notes for a in HAND_BLIND_ADVICE), notes
    assert any("kf_hand's model" in w and "calib closeloop" in w for w in notes)
    blind: list[str] = []
    assert apply_inflation("ok", blind, infl) == "inconsistent"
    assert any("kf_hand" in w for w in blind)


def test_kf_hand_on_a_raw_accelerometer_gets_hand_aware_advice():
    """imucal's Ferraris session, raw NilsPod accelerometer: kf_hand's innovations exceed their bound in 20 % of
    the windows; its warnings suggest none of the hand-blind remedies and name the raw accelerometer as a cause."""
    from gyrosim.loaders import available_datasets

    if "imucal_ferraris" not in available_datasets():
        pytest.skip("measured dataset imucal_ferraris not found (set GYROSIM_DATA)")
    from calib import load_recording
    from calib.session.hand.filter import kf_hand

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cal = kf_hand(load_recording("dataset:imucal_ferraris"))
    inn = [w for w in cal.warnings if "innovations" in w]
    assert inn and cal.status != "ok"
    assert not any(a in w for w in inn for a in HAND_BLIND_ADVICE), inn
    assert any("raw accelerometer" in w for w in inn)


RAN = [("kf_hand_joint", "estimate", True), ("kf_hand", "calibrated", True), ("kf_joint", "estimate", False),
       ("kf_session_r", "calibrated", False), ("iterated_joint", "estimate", False),
       ("iterated_session_r", "calibrated", False)]


def _advice_names_what_ran(notes: list[str], method: str, accelerometer: str) -> list[str]:
    """The advice in ``notes`` that names the method (by its registered name or a former spelling, read in the
    accelerometer mode that ran) or the accelerometer mode that ran."""
    bad = []
    for w in notes:
        named = {resolve_run_method(RunOptions(method=m, accelerometer=accelerometer if m in FORMER_METHODS
                                               else None))[0] for m in re.findall(r"--method (\w+)", w)}
        if method in named or f"--accelerometer {accelerometer}" in w:
            bad.append(w)
    return bad


@pytest.mark.parametrize("method, accelerometer, hand_aware", RAN)
def test_advice_never_names_what_ran(method, accelerometer, hand_aware):
    """Every verdict's and the inflation's advice, for each method and accelerometer mode calib run takes: a
    suggested --method / --accelerometer differs from what ran (the README's session was told to use the method
    it had just used)."""
    notes: list[str] = []
    for fraction in (0.0, 2 * INCONSISTENT_FRACTION, 0.9):
        _, n = verdict(_consistency(fraction), [], None, accelerometer, hand_aware=hand_aware, method=method)
        notes += n
    _, n = verdict(_consistency(0.0), ["gyro scale factor is not finite"], None, accelerometer,
                   hand_aware=hand_aware, method=method)
    notes += n
    infl = Inflation(kappa=9.0, dof=80, threshold=1.3, factor=9.0)
    apply_inflation("ok", notes, infl, hand_aware=hand_aware, accelerometer=accelerometer)
    assert len(notes) >= 5
    assert not _advice_names_what_ran(notes, method, accelerometer), _advice_names_what_ran(notes, method,
                                                                                              accelerometer)
