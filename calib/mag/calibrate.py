"""``calibrate_magnetometer``: hard and soft iron of a recording, end to end, one calibration per
hard-iron regime.

1. checks and the gravity reference (:func:`calib.mag.fit.prepare`);
2. hard-iron regimes (:mod:`calib.mag.regimes`): where the field that turns with the board changed
   — a magnet attached to it or taken off — found with the gyro's help, with each change's time,
   σ and test;
3. one regime (nothing changed): the session's calibration (:func:`calib.mag.fit.fit_samples`:
   sphere start, local disturbances reported and excluded, the method's fit, the soft iron refused
   by name when the data cannot carry it, the self-consistency check), as always;
4. several: the regimes that share one hard iron (a magnet taken off returns the first) are
   calibrated together on their samples, the transitions excluded; a group that is too short or
   turned too little is ``not_calibratable`` — nothing is fitted to it, the reason is given.  The
   top-level keys are the group with the most samples (``reference``); the others are ``attached``
   disturbances, calibrated; the status is ``partial`` when a regime could not be calibrated to ok;
5. every local disturbance says what it is: ``world-fixed`` when the body-frame offset did not
   move while the board turned through it (a field tied to the room), ``attached`` when it did
   (a field that turned with the board), ``undetermined`` when the board did not turn there.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from threadpoolctl import threadpool_limits

from gyrosim.errors import RecordingError
from gyrosim.recording import Recording
from gyrosim.sensor_model import stored_sensor_model

from calib.mag.fit import MIN_COVERAGE, SOFT_IRON_NAMES, MagSetup, NotCalibratable, fit_samples, prepare
from calib.mag.methods import polar_rotation_deg
from calib.mag.regimes import (
    RegimeSettings,
    RegimeSplit,
    detect_regimes,
    merge_hypotheses,
    offset_change_test,
    stretch_offset_test,
)
from calib.mag.result import Disturbance, MagCalibration, Regime

__all__ = ["calibrate_magnetometer", "true_magnetometer", "SOFT_IRON_NAMES", "MIN_COVERAGE"]

DEFAULT_REGIMES = RegimeSettings()


def calibrate_magnetometer(rec: Recording, method: str = "ellipsoid", **kwargs) -> MagCalibration:
    """Hard and soft iron of ``rec``'s magnetometer (module docstring; arguments: :func:`_calibrate`).

    BLAS runs single-threaded inside: the fits multiply N × 9–13 matrices, for which a second
    OpenBLAS thread only adds synchronisation — 4× slower on a loaded 2-core machine (measured)."""
    with threadpool_limits(limits=1, user_api="blas"):
        return _calibrate(rec, method, **kwargs)


def _calibrate(rec: Recording, method: str = "ellipsoid", *, mag_unit: str = "uT", field_ut: float | None = None,
               inclination_deg: float | None = None, range_ut: float | None = None,
               min_coverage: float = MIN_COVERAGE, time_range_s: tuple[float, float] | None = None,
               detect_disturbances: bool = True, consistency_check: bool = True,
               position_nav_m: np.ndarray | None = None,
               regimes: RegimeSettings | None = DEFAULT_REGIMES) -> MagCalibration:
    """Hard and soft iron of ``rec``'s magnetometer (module docstring).

    Args:
        method: a key of :data:`calib.mag.methods.METHODS` (``ellipsoid`` or ``aided``).
        mag_unit: the unit of ``rec.mag_ut`` if it is not µT (``gauss``, ``mgauss``, ``nT``).
        field_ut: the true field magnitude (e.g. from the World Magnetic Model); fixes the scale of
            A absolutely (else det A = 1 and ``field_ut`` is estimated).
        inclination_deg: the true inclination; resolves the hard iron along the rotation axis of a
            session that turned about one axis only.
        range_ut: the magnetometer's range, if the recording does not declare one.
        min_coverage: below this :func:`direction_coverage` the soft iron is refused.
        time_range_s: calibrate only the samples with t in [t0, t1] (s).
        detect_disturbances: find, report and exclude local disturbances (default True).
        consistency_check: the jackknife check of σ (default True).
        position_nav_m: (N, 3) the board's position (ENU, m) from an external reference the user has
            (an optical tracker); only labels where a disturbance was, never enters the fit.
        regimes: the hard-iron regime detector's settings (:class:`calib.mag.regimes.RegimeSettings`);
            None calibrates the session as one regime.

    Reads only the samples, times and rate of ``rec`` (no truth, no stored sensor model): a
    simulated recording and its :func:`gyrosim.estimator.as_user_file` view give the same result.
    """
    setup = prepare(rec, method, mag_unit=mag_unit, field_ut=field_ut, inclination_deg=inclination_deg,
                    range_ut=range_ut, min_coverage=min_coverage, time_range_s=time_range_s,
                    detect_disturbances=detect_disturbances, consistency_check=consistency_check,
                    position_nav_m=position_nav_m)
    if regimes is None:
        return _one_regime(setup, fit_samples(setup), None, DEFAULT_REGIMES)
    split = _detect(setup, regimes)
    if not split.single:
        # the device's own soft iron biases each window's offset by how it turned (a phone's 8 %: a
        # few µT): look again with it removed
        soft = _reference_soft_iron(setup, split)
        again = _detect(setup, regimes, soft) if soft is not None else split
        # (the longest regime's soft iron may be a magnet's, which biases the others: the look with
        # fewer hard irons wins)
        if len(again.hypotheses) <= len(split.hypotheses):
            split = again
    if split.single:
        return _one_regime(setup, fit_samples(setup), split, regimes)
    return _several_regimes(setup, split, regimes)


def _detect(setup: MagSetup, st: RegimeSettings, soft_iron: np.ndarray | None = None) -> RegimeSplit:
    """Step 2 on the samples with ``soft_iron`` (A, det 1) removed, b = A⁻¹ m (default A = I)."""
    rec, g = setup.rec, setup.gravity
    m = setup.inp.mag_ut if soft_iron is None else setup.inp.mag_ut @ np.linalg.inv(soft_iron).T
    split = detect_regimes(rec.t_s, m, setup.inp.valid, rec.gyro_rad_s,
                           g.gyro_bias_rad_s if g is not None else np.zeros(3),
                           up_body=None if g is None else g.up_body, quasi_static=None if g is None else g.quasi_static,
                           settings=st)
    if soft_iron is not None:
        split = replace(split, notes={**split.notes, "soft_iron_removed": np.round(soft_iron, 4).tolist()})
    return split


def _reference_soft_iron(setup: MagSetup, split: RegimeSplit) -> np.ndarray | None:
    """A soft iron (A, det 1) to look again with: that of the hypothesis labelling the most samples,
    else the whole session's calibration's (its disturbance detector excludes a magnet's stretch, as
    it did before regimes were sought); None when neither carries a soft iron."""
    quick = replace(setup, consistency_check=False)
    j = int(np.argmax([(split.labels == k).sum() for k in range(len(split.hypotheses))]))
    for mask in (split.labels == j, None):
        try:
            a = fit_samples(quick, mask).soft_iron
        except RecordingError:  # (the whole session around two hard irons far apart is no sphere at all)
            continue
        if np.all(np.isfinite(a)):
            return a / np.cbrt(np.linalg.det(a))
    return None


# ---------------------------------------------------------------------------------------- disturbances
def _classify(setup: MagSetup, d: Disturbance, split: RegimeSplit | None, hypothesis: int, st: RegimeSettings
              ) -> Disturbance:
    """Module docstring, step 5 (:func:`calib.mag.regimes.stretch_offset_test`)."""
    if split is None:  # no test was made
        return replace(d, kind="undetermined", evidence=None)
    ev = stretch_offset_test(split, setup.rec.t_s, setup.inp.mag_ut, d.t_start_s, d.t_end_s, hypothesis, st)
    kind = ev.pop("verdict")
    return replace(d, kind=kind, evidence=ev or None)


def _field_deviation(ref: MagCalibration, m: np.ndarray) -> float:
    """The largest | |B| − F | (µT) the reference calibration leaves on the samples ``m``."""
    if m.shape[0] == 0:
        return float("nan")
    return float(np.max(np.abs(np.linalg.norm(ref.compensate(m), axis=1) - ref.field_ut)))


# ---------------------------------------------------------------------------------------- regimes
def _regime(index: int, start: float, end: float, group: int, kind: str, res: MagCalibration | None, reason: str,
            samples: dict, change: dict | None, setup: MagSetup) -> Regime:
    """One :class:`Regime` from its group's calibration (None: not calibratable, ``reason`` says why)."""
    nan3, nan33 = np.full(3, np.nan), np.full((3, 3), np.nan)
    if res is None:
        return Regime(index, start, end, group, kind, "not_calibratable", reason, nan3, nan33, float("nan"), nan3,
                      nan33, float("nan"), samples, change, ())
    own = tuple(w for w in res.warnings if w not in setup.warnings)
    why = "" if res.status == "ok" else (own[-1] if own else res.status)
    return Regime(index, start, end, group, kind, res.status, why, res.hard_iron_ut, res.soft_iron, res.field_ut,
                  res.hard_iron_std_ut, res.soft_iron_std, res.field_std_ut, samples, change, own)


def _one_regime(setup: MagSetup, res: MagCalibration, split: RegimeSplit | None, st: RegimeSettings
                ) -> MagCalibration:
    """Step 3: the session's calibration, listed as its only regime, its disturbances classified."""
    t = setup.rec.t_s[setup.inp.valid]
    samples = {"total": int(setup.inp.valid.sum())}
    reg = _regime(0, float(t[0]), float(t[-1]), 0, "reference", res, "", samples, None, setup)
    diagnostics = dict(res.diagnostics)
    if split is not None:
        diagnostics["regimes"] = dict(split.notes)
    return replace(res, regimes=(reg,), disturbances=tuple(_classify(setup, d, split, 0, st) for d in res.disturbances),
                   diagnostics=diagnostics)


def _fit_groups(setup: MagSetup, split: RegimeSplit) -> tuple[list[MagCalibration | None], list[str]]:
    """Step 4: every hypothesis' samples calibrated on their own; (results or None, reasons)."""
    fits: list[MagCalibration | None] = []
    reasons: list[str] = []
    for j in range(len(split.hypotheses)):
        try:
            fits.append(fit_samples(setup, split.labels == j))
            reasons.append("")
        except NotCalibratable as exc:
            fits.append(None)
            reasons.append(str(exc).split(":")[0])
    return fits, reasons


UNION_SPREAD_RATIO = 1.2  # one calibration of two stretches explains them when its |B| spread is ≤ this × theirs


def _spread(res: MagCalibration, m: np.ndarray) -> float:
    """Standard deviation (µT) of the calibrated field magnitude over the samples ``m``."""
    return float(np.std(np.linalg.norm(res.compensate(m), axis=1)))


def _one_calibration_explains(setup: MagSetup, split: RegimeSplit, i: int, j: int,
                              fits: list[MagCalibration | None]) -> bool:
    """Does one calibration (hard and soft iron) of hypotheses i and j together, every sample kept,
    leave on each of them no more |B| spread than its own calibration (``UNION_SPREAD_RATIO``)?
    Then their offsets differed by how the board turned under a strong soft iron, not by a change."""
    if fits[i] is None or fits[j] is None:
        return False
    m = setup.inp.mag_ut
    masks = [setup.inp.valid & (split.labels == k) for k in (i, j)]
    try:
        union = fit_samples(replace(setup, detect_disturbances=False, consistency_check=False), masks[0] | masks[1])
    except RecordingError:  # too few samples, no turn, or one sphere far from the Earth's field: not one
        return False
    return union.status == "ok" and all(_spread(union, m[k]) <= UNION_SPREAD_RATIO * _spread(own, m[k])
                                        for k, own in zip(masks, (fits[i], fits[j])))


def _merge_explained(setup: MagSetup, split: RegimeSplit, st: RegimeSettings
                     ) -> tuple[RegimeSplit, list[MagCalibration | None], list[str]]:
    """Step 4's guard: neighbouring regimes that one calibration explains become one."""
    fits, reasons = _fit_groups(setup, split)
    tried: set[tuple[int, int]] = set()
    while not split.single:
        pair = next(((min(c.before, c.after), max(c.before, c.after)) for c in split.changes
                     if (min(c.before, c.after), max(c.before, c.after)) not in tried), None)
        if pair is None:
            break
        tried.add(pair)
        if _one_calibration_explains(setup, split, *pair, fits):
            split = merge_hypotheses(split, setup.rec.t_s, pair[0], pair[1], st)
            split = replace(split, notes={**split.notes, "merged": split.notes.get("merged", 0) + 1})
            fits, reasons = _fit_groups(setup, split)
            tried = set()
    return split, fits, reasons


def _in_scale_of(res: MagCalibration, ref: MagCalibration) -> MagCalibration:
    """``res`` with A scaled so that its field is the reference's: the Earth's field is the same in
    every regime, and det A = 1 would otherwise put each regime's |B| in its own scale (a magnet's
    soft iron changes the sensor's average gain).  The same model m = A B + h, B in one scale."""
    if not (np.all(np.isfinite(res.soft_iron)) and np.isfinite(res.field_ut) and np.isfinite(ref.field_ut)):
        return res
    k = res.field_ut / ref.field_ut
    return replace(res, soft_iron=res.soft_iron * k, soft_iron_std=res.soft_iron_std * k, field_ut=ref.field_ut,
                   field_std_ut=ref.field_std_ut,
                   field_reference=f"the reference regime's field ({ref.field_ut:.3f} µT; A scaled by {k:.4f})")


def _spans(setup: MagSetup, split: RegimeSplit) -> list[tuple[int, float, float, dict | None]]:
    """(hypothesis, start s, end s, the change that starts it) of every regime in time order."""
    t = setup.rec.t_s[setup.inp.valid]
    seq = [split.changes[0].before] + [c.after for c in split.changes]
    bounds = [float(t[0])] + [c.time_s for c in split.changes] + [float(t[-1])]
    changes: list[dict | None] = [None] + [c.to_dict() for c in split.changes]
    return [(seq[i], bounds[i], bounds[i + 1], changes[i]) for i in range(len(seq))]


def _several_regimes(setup: MagSetup, split: RegimeSplit, st: RegimeSettings) -> MagCalibration:
    """Step 4 of the module docstring."""
    rec, inp = setup.rec, setup.inp
    split, fits, reasons = _merge_explained(setup, split, st)
    if split.single:
        return _one_regime(setup, fit_samples(setup), split, st)
    spans = _spans(setup, split)
    order = list(dict.fromkeys(h for h, *_ in spans))  # groups numbered by first appearance
    done = [j for j in order if fits[j] is not None]
    if not done:
        raise NotCalibratable(f"the hard iron changed {len(split.changes)} time(s) and no stretch of one hard iron can "
                              f"be calibrated on its own ({'; '.join(dict.fromkeys(r for r in reasons if r))})")
    main = max(done, key=lambda j: fits[j].samples.get("used", 0))
    ref = fits[main]
    if setup.field_ut is None:
        fits = [f if f is None or j == main else _in_scale_of(f, ref) for j, f in enumerate(fits)]
    regimes, attached = [], []
    for i, (h, t0, t1, change) in enumerate(spans):
        inside = inp.valid & (rec.t_s >= t0) & (rec.t_s <= t1)
        samples = {"total": int(inside.sum()), "transition": int((inside & (split.labels < 0)).sum())}
        kind = "reference" if h == main else "attached"
        regimes.append(_regime(i, t0, t1, order.index(h), kind, fits[h], reasons[h], samples, change, setup))
        if h != main:
            hm, hj = split.hypotheses[main], split.hypotheses[h]
            d, sd, chi2, dof, p = offset_change_test(hm.offset_ut, hm.cov, hj.offset_ut, hj.cov)
            ev = {"offset_change_uT": d.tolist(), "offset_change_std_uT": sd.tolist(), "chi2": chi2, "dof": dof,
                  "p_value": p}
            attached.append(Disturbance(t0, t1, int(inside.sum()), _field_deviation(ref, inp.mag_ut[inside]),
                                        float("nan"), None, "attached", i, ev))
    found = [_classify(setup, d, split, j, st) for j in done for d in fits[j].disturbances]
    disturbances = tuple(sorted(found + attached, key=lambda d: d.t_start_s))
    return _assemble(setup, split, ref, regimes, disturbances)


def _assemble(setup: MagSetup, split: RegimeSplit, ref: MagCalibration, regimes: list[Regime],
              disturbances: tuple[Disturbance, ...]) -> MagCalibration:
    """The top-level result of several regimes: the reference group's calibration, the combined
    status and short warnings (what changed, what it does to the result, what to do)."""
    times = ", ".join(f"{c.time_s:.1f}" for c in split.changes)
    warnings = list(ref.warnings)
    warnings.append(f"hard iron changed {len(split.changes)} time(s), at t = {times} s (a magnet attached to the "
                    "board, or taken off): each stretch is calibrated with its own hard iron (see regimes)")
    bad = [r for r in regimes if r.status != "ok"]
    for r in bad:
        where = f"regime t = {r.start_s:.1f}–{r.end_s:.1f} s"
        if r.status == "not_calibratable":
            warnings.append(f"{where} not calibrated ({r.reason}): its samples keep the reference calibration; "
                            "turn the board about two axes or more while it is there")
        else:
            warnings.append(f"{where}: {r.status} (its warnings say why)")
    status = ref.status if ref.status != "ok" or not bad else "partial"
    diagnostics = {**ref.diagnostics, "regimes": dict(split.notes)}
    samples = {**ref.samples, "total": setup.rec.n, "transition": int((setup.inp.valid & (split.labels < 0)).sum())}
    return replace(ref, status=status, warnings=tuple(warnings), disturbances=disturbances, regimes=tuple(regimes),
                   samples=samples, diagnostics=diagnostics)


def true_magnetometer(rec: Recording, at_s: float | None = None) -> dict[str, np.ndarray] | None:
    """The oracle: the device's m = A B + h of a simulated recording (from its stored sensor model),
    or None; for scoring a calibration, never for making one.
    A = I + Σ (affine parts of the magnetometer effects), h = Σ constants; at the time ``at_s`` (s)
    effects that switch (a magnet attached part of the session) add what they are then."""
    model = stored_sensor_model(rec.meta)
    if model is None or not model.magnetometer:
        return None
    a, c = np.eye(3), np.zeros(3)
    for eff in model.magnetometer:
        if eff.stage == "error" and not eff.stochastic:
            at = getattr(eff, "affine_at", None)
            ac = at(at_s) if (at is not None and at_s is not None) else eff.affine()
            if ac is not None:
                a = a + ac[0]
                c = c + ac[1]
    return {"hard_iron_uT": c, "soft_iron": a, "misalignment_deg": polar_rotation_deg(a)}
