"""The calibration of one stretch of one hard iron (the whole session when nothing changed).

1. checks (:mod:`calib.mag.checks`): saturation, unit (the median |m|, then a sphere's radius),
   attitude coverage (:func:`calib.mag.gravity.direction_coverage`);
2. the gravity reference from the gyro and accelerometer (:mod:`calib.mag.gravity`);
3. a robust start: the sphere |m − h| = F, whose residual finds the local disturbances first
   (:mod:`calib.mag.disturbance`) — a full ellipsoid fitted through a disturbance bends towards
   it and then hides it;
4. the method's fit (:data:`calib.mag.methods.METHODS`: ``ellipsoid`` — the field magnitude only;
   ``aided`` — also the inclination against gravity, which makes the misalignment observable) on
   the undisturbed samples, detection again on its residual, refit, until the disturbed set stops
   changing; disturbances are reported, never absorbed;
5. the soft iron is **refused by name** (the hard iron alone is fitted, :mod:`calib.mag.hardiron`)
   when the coverage is below ``min_coverage``, when the data leave some soft-iron entry to the
   prior (posterior σ above half the prior's), or when the fitted A is no magnetometer's
   (axes more than 1.5 : 1); the warning says which rotations to add;
6. self-consistency: when the fit's residual is well above the sensor's own white noise (the model
   leaves structure: a field that varies with position, an effect it lacks), the delete-one-
   cluster jackknife over 10 s stretches widens σ by its median variance ratio to the 1 s-block
   sandwich; a parameter still off by more than 10× in variance → status ``inconsistent``.

:func:`prepare` reads and checks the recording once (:class:`MagSetup`); :func:`fit_samples`
calibrates the samples a mask selects, so that :mod:`calib.mag.calibrate` can calibrate each
hard-iron regime of a session on its own.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from gyrosim.errors import RecordingError
from gyrosim.recording import Recording

from calib.mag.checks import MagInput, check_unit, prepare_magnetometer, rotations_to_add, unit_from_median
from calib.mag.disturbance import find_disturbances
from calib.mag.ellipsoid import white_noise_variance
from calib.mag.gravity import GravityReference, direction_coverage, gravity_reference
from calib.mag.hardiron import circle_hard_iron, sphere_hard_iron
from calib.mag.lsq import block_index, cluster_jackknife
from calib.mag.methods import METHODS, CoreFit, MagMethod, MisalignmentUnobservable, propagate
from calib.mag.result import Disturbance, MagCalibration

__all__ = ["MagSetup", "prepare", "fit_samples", "NotCalibratable", "SOFT_IRON_NAMES", "MIN_COVERAGE"]

SOFT_IRON_NAMES = tuple(f"soft_iron[{i}][{j}]" for i in range(3) for j in range(3))
MIN_COVERAGE = 0.1  # direction_coverage below which the soft iron is refused
MIN_SAMPLES = 50  # fewer samples than this cannot carry a fit
MIN_SPREAD_UT = 2.0  # samples spread less than this in their second direction: the board did not turn
MAX_AXIS_RATIO = 1.5  # a soft iron beyond 50 % is no magnetometer's: a disturbance the detector missed
JACKKNIFE_S = 10.0  # cluster length of the jackknife consistency check (s)
INCONSISTENT_RATIO = 10.0  # jackknife / (widened) sandwich variance beyond which σ is not honest
STRUCTURE_RATIO = 1.5  # residual RMS / white noise above which the residual is said to have structure
# the ellipsoid fit's frame may be turned against the IMU's by an unseen misalignment: a separate
# magnetometer die or chip is aligned to ~1° (AK8963 in the MPU-9250: not specified; engineering value)
MISALIGNMENT_PRIOR_DEG = 1.0


class NotCalibratable(RecordingError):
    """The selected samples cannot carry a calibration: too few, or the board did not turn."""


@dataclass(frozen=True)
class MagSetup:
    """What every fit of one recording shares: the recording, the method, the unit the user declared,
    the checked magnetometer channel, the gravity reference (or None), 1 s blocks, the user's
    references and switches, and the warnings and notes the checks left."""

    rec: Recording
    method: str
    mag_unit: str
    inp: MagInput
    gravity: GravityReference | None
    blocks: np.ndarray
    field_ut: float | None
    inclination_deg: float | None
    min_coverage: float
    detect_disturbances: bool
    consistency_check: bool
    position_nav_m: np.ndarray | None
    warnings: tuple[str, ...]
    notes: tuple[str, ...]


def prepare(rec: Recording, method: str, *, mag_unit: str, field_ut: float | None, inclination_deg: float | None,
            range_ut: float | None, min_coverage: float, time_range_s: tuple[float, float] | None,
            detect_disturbances: bool, consistency_check: bool, position_nav_m: np.ndarray | None) -> MagSetup:
    """Check the arguments and the recording once (module docstring, steps 1–2); raises
    :class:`RecordingError` naming what is wrong."""
    if method not in METHODS:
        raise RecordingError(f"unknown magnetometer method {method!r}; use one of {', '.join(METHODS)}")
    inp = prepare_magnetometer(rec, unit=mag_unit, range_ut=range_ut)
    if position_nav_m is not None:
        position_nav_m = np.asarray(position_nav_m, dtype=float)
        if position_nav_m.shape != (rec.n, 3):
            raise RecordingError(f"position_nav_m has shape {position_nav_m.shape}; the recording has {rec.n} samples: "
                                 f"expected ({rec.n}, 3)")
    if time_range_s is not None:
        inside = (rec.t_s >= time_range_s[0]) & (rec.t_s <= time_range_s[1])
        if inside.sum() < MIN_SAMPLES:
            raise RecordingError(f"only {int(inside.sum())} samples between t = {time_range_s[0]:g} and "
                                 f"{time_range_s[1]:g} s: too few to calibrate")
        inp = replace(inp, valid=inp.valid & inside)
    warnings = list(inp.warnings)
    notes: list[str] = []
    try:
        gravity: GravityReference | None = gravity_reference(rec)
        notes += list(gravity.notes)
    except RecordingError as exc:
        if METHODS[method].needs_gravity:
            raise
        gravity = None
        warnings.append(f"no gravity reference ({exc}): inclination not estimated")
    unit_from_median(inp.mag_ut[inp.valid], mag_unit)
    return MagSetup(rec, method, mag_unit, inp, gravity, block_index(rec.n, max(1, int(round(rec.rate_hz)))), field_ut,
                    inclination_deg, min_coverage, detect_disturbances, consistency_check, position_nav_m,
                    tuple(warnings), tuple(notes))


def _inclination_series(m: np.ndarray, l: np.ndarray, h: np.ndarray, gravity: GravityReference | None) -> np.ndarray:
    """Per-sample inclination (°) of the calibrated field, NaN where not quasi-static."""
    if gravity is None:
        return np.full(m.shape[0], np.nan)
    b = (m - h) @ l.T
    bn = b / np.linalg.norm(b, axis=1, keepdims=True)
    incl = np.degrees(np.arcsin(np.clip(-np.sum(bn * gravity.up_body, axis=1), -1, 1)))
    return np.where(gravity.quasi_static, incl, np.nan)


def _mean_with_std(x: np.ndarray, blocks: np.ndarray) -> tuple[float, float]:
    """Mean of the finite x and its standard error from block sums (cluster-robust)."""
    ok = np.isfinite(x)
    if ok.sum() < 2:
        return float("nan"), float("nan")
    xv, bv = x[ok], blocks[ok]
    mean = float(np.mean(xv))
    starts = np.flatnonzero(np.r_[True, bv[1:] != bv[:-1]])
    sums = np.add.reduceat(xv - mean, starts)
    nb = sums.size
    return mean, math.sqrt(float(np.sum(sums**2)) / xv.size**2 * nb / max(nb - 1, 1))


def _disturbance_loop(residual_of, setup: MagSetup, inp: MagInput, refit, used0: np.ndarray, rounds: int
                      ) -> tuple[np.ndarray, tuple[Disturbance, ...], np.ndarray]:
    """Detect on the residual of the current fit, exclude, refit; until the set stops changing.
    ``residual_of()`` → (|B| − F in µT, inclination − I in ° or None) for every sample;
    ``refit(used)`` refits on the samples ``used``."""
    disturbed = np.zeros_like(used0)
    found: tuple[Disturbance, ...] = ()
    used = used0.copy()
    for _ in range(rounds):
        dev_field, dev_incl = residual_of()
        mask, new = find_disturbances(setup.rec.t_s, dev_field, dev_incl, inp.valid,
                                      position_nav_m=setup.position_nav_m)
        if np.array_equal(mask, disturbed):
            break
        disturbed, found = mask, new
        used = used0 & ~disturbed
        if used.sum() < MIN_SAMPLES:
            break
        refit(used)
    return used, found, disturbed


def _jackknife_check(core: CoreFit, rate_hz: float, structured: bool) -> tuple[CoreFit, dict]:
    """Step 6 of the module docstring."""
    if core.jacobian is None:
        return core, {"test": "jackknife", "skipped": "no Jacobian"}
    clusters = (core.row_sample // max(1, int(round(JACKKNIFE_S * rate_hz)))).astype(int)
    g = int(clusters.max()) + 1
    if g < 8:
        return core, {"test": "jackknife", "skipped": f"{g} clusters of {JACKKNIFE_S:g} s (needs ≥ 8)"}
    jk = cluster_jackknife(core.jacobian, core.residual, clusters)
    d_s, d_j = np.diag(core.cov), np.diag(jk)
    ok = d_s > 0
    ratio = d_j[ok] / d_s[ok]
    inflate = max(1.0, float(np.median(ratio))) if structured else 1.0
    out = {
        "test": "jackknife",
        "clusters": g,
        "cluster_s": JACKKNIFE_S,
        "median_variance_ratio": float(np.median(ratio)),
        "max_variance_ratio": float(np.max(ratio)),
        "residual_structured": structured,
        "inflation": inflate,
    }
    return replace(core, cov=core.cov * inflate), out


def _hard_iron_only_result(setup: MagSetup, inp: MagInput, reason: str, used: np.ndarray, weak: np.ndarray,
                           planar: bool, warnings: list[str], coverage: dict, diagnostics: dict,
                           disturbances: tuple[Disturbance, ...] = (), disturbed: np.ndarray | None = None
                           ) -> MagCalibration:
    m, blocks, field_ut = inp.mag_ut, setup.blocks, setup.field_ut
    notes = diagnostics.setdefault("notes", [])
    if planar:
        h, sig_h, radius, ref_h, hn = circle_hard_iron(m, blocks, weak, field_ut, setup.inclination_deg,
                                                        setup.gravity, used)
        notes += hn
        f_val, f_sd = (float(field_ut), 0.0) if field_ut else (float("nan"), float("nan"))
        diagnostics["circle_radius_uT"] = radius
    else:
        h, sig_h, f_est, f_sd, res = sphere_hard_iron(m[used], blocks[used])
        ref_h = []
        f_val = float(field_ut) if field_ut else f_est
        f_sd = 0.0 if field_ut else f_sd
        diagnostics["residual_field_rms_uT"] = float(np.sqrt(np.mean(res**2)))
    warnings.append(f"{reason}: the soft iron ({', '.join(SOFT_IRON_NAMES)}) is refused and the hard iron alone is "
                    "fitted (A = I); " + rotations_to_add(weak))
    samples = {"total": setup.rec.n, "saturated": inp.saturated_samples, "used": int(used.sum()),
               "disturbed": int(disturbed.sum()) if disturbed is not None else 0}
    return MagCalibration(
        method=setup.method, status="hard_iron_only", hard_iron_ut=h, soft_iron=np.full((3, 3), np.nan),
        field_ut=f_val, inclination_deg=float("nan"), misalignment_deg=None, hard_iron_std_ut=sig_h,
        soft_iron_std=np.full((3, 3), np.nan), field_std_ut=f_sd, inclination_std_deg=float("nan"),
        misalignment_std_deg=None, field_reference="hard iron only (|m − h| = F)", warnings=tuple(warnings),
        refused=tuple(list(SOFT_IRON_NAMES) + ref_h), disturbances=disturbances, samples=samples, coverage=coverage,
        diagnostics=diagnostics)


def _coverage(inp: MagInput, min_coverage: float) -> tuple[float, np.ndarray, dict]:
    """(coverage, weakest body direction, its JSON) of the valid samples; refuses a board that did not
    turn: the samples spread over ≥ 2 µT in two directions (a turn of α spreads the Earth's ≥ 22 µT
    by ~F α/2; a static board spreads only by its noise, < 1 µT)."""
    m = inp.mag_ut[inp.valid]
    if m.shape[0] < MIN_SAMPLES:
        raise NotCalibratable(f"only {m.shape[0]} samples: too few to calibrate")
    cover, weak = direction_coverage(m)
    d = m - m.mean(axis=0)
    ev = np.linalg.eigvalsh(d.T @ d / d.shape[0])
    if math.sqrt(max(ev[1], 0.0)) < MIN_SPREAD_UT:
        raise NotCalibratable(
            "the board did not rotate (the magnetometer samples lie along a line or at one point): neither hard nor "
            "soft iron can be separated from the Earth's field; turn the board about at least one axis, better "
            "about all three")
    return cover, weak, {"value": cover, "minimum": min_coverage, "weakest_direction_body": weak.tolist()}


@dataclass
class _Fits:
    """The state of steps 3–4: the sphere (h, F), the method and its current fit."""

    meth: MagMethod
    h: np.ndarray | None = None
    f: float | None = None
    core: CoreFit | None = None
    refused_misalignment: bool = False


def _robust_fit(setup: MagSetup, inp: MagInput, warnings: list[str], notes: list[str]
                ) -> tuple[_Fits, np.ndarray, tuple[Disturbance, ...], np.ndarray]:
    """Steps 3–4: the sphere start and its disturbances, then the method's fit and its own
    disturbances; (fits, used, disturbances, disturbed mask)."""
    m, blocks, gravity = inp.mag_ut, setup.blocks, setup.gravity
    st = _Fits(METHODS[setup.method]())

    def refit_sphere(used):
        st.h, _, st.f, _, _ = sphere_hard_iron(m[used], blocks[used])

    def sphere_residual():
        return np.linalg.norm(m - st.h, axis=1) - st.f, None

    refit_sphere(inp.valid)
    check_unit(m[inp.valid], st.f, setup.mag_unit)
    rounds = 4 if setup.detect_disturbances else 0
    used, found, disturbed = _disturbance_loop(sphere_residual, setup, inp, refit_sphere, inp.valid, rounds)
    start = (np.eye(3) / st.f, st.h)

    def refit_method(u):
        prev = st.core
        first = start if prev is None else prev.unpack(prev.theta)[:2]
        st.core = st.meth.fit(m, blocks, gravity, u, start=first)

    def method_residual():
        l, h, _ = st.core.unpack(st.core.theta)
        f_est = abs(np.linalg.det(np.linalg.inv(l))) ** (1 / 3)
        dev_field = (np.linalg.norm((m - h) @ l.T, axis=1) - 1.0) * f_est
        incl = _inclination_series(m, l, h, gravity)
        ok = np.isfinite(incl) & used
        return dev_field, (incl - np.median(incl[ok])) if ok.sum() > 10 else None

    try:
        refit_method(used)
    except MisalignmentUnobservable as exc:
        if not st.meth.sees_misalignment:
            raise
        warnings.append(f"misalignment refused (misalignment_deg[0..2]): {exc}; hard and soft iron from the "
                        "ellipsoid fit instead")
        notes.append("attitude-aided fit fell back to the ellipsoid fit")
        st.refused_misalignment = True
        st.meth = METHODS["ellipsoid"]()
        refit_method(used)
    used2, found2, disturbed2 = _disturbance_loop(method_residual, setup, inp, refit_method, inp.valid, rounds)
    if disturbed2.sum() >= disturbed.sum():
        used, found, disturbed = used2, found2, disturbed2
    else:  # the method's fit hid part of a disturbance the sphere saw: keep the sphere's verdict
        refit_method(used)
    return st, used, found, disturbed


def _soft_iron_refusal(core: CoreFit) -> str | None:
    """Step 5: why the soft iron is refused, or None."""
    l, _, _ = core.unpack(core.theta)
    axes = np.linalg.svd(np.linalg.inv(l), compute_uv=False)
    if core.weak_soft_iron:
        return "the data leave part of the soft iron to the prior (posterior σ above half the prior's)"
    if axes.max() > MAX_AXIS_RATIO * axes.min():
        return (f"the fitted ellipsoid's axes are {axes.max() / axes.min():.2f} : 1, no magnetometer's (≤ "
                f"{MAX_AXIS_RATIO}): the field is not uniform over the session (a disturbance spread over it?)")
    return None


def _consistency(setup: MagSetup, core: CoreFit, m_used: np.ndarray, warnings: list[str]
                 ) -> tuple[CoreFit, str, dict, float, float]:
    """Step 6: (core with σ widened, status, consistency JSON, residual RMS µT, white noise µT)."""
    status = "ok"
    consistency: dict = {}
    l, _, _ = core.unpack(core.theta)
    noise = math.sqrt(white_noise_variance(m_used))
    f_est = abs(np.linalg.det(np.linalg.inv(l))) ** (1 / 3)
    resid_rms = float(np.sqrt(np.mean(core.residual_field**2))) * f_est
    structured = resid_rms > STRUCTURE_RATIO * noise
    if setup.consistency_check:
        core, consistency = _jackknife_check(core, setup.rec.rate_hz, structured)
        consistency.update(residual_rms_uT=resid_rms, white_noise_uT=noise)
        # (with a white residual the model fits and the sandwich is right; the jackknife's leverage bias
        # — deleting 10 s of a session removes whole poses — reads up to ~20× then, measured)
        if (
            structured
            and consistency.get("max_variance_ratio", 0.0) / consistency.get("inflation", 1.0) > INCONSISTENT_RATIO
        ):
            status = "inconsistent"
            warnings.append(
                f"inconsistent: a parameter's error over {JACKKNIFE_S:g} s stretches is "
                f"{math.sqrt(consistency['max_variance_ratio'] / consistency['inflation']):.1f}× its σ; the residual "
                f"({resid_rms:.2f} µT RMS against {noise:.2f} µT of sensor noise) has structure the model lacks "
                "(a field that varies with position, a time-varying hard iron): σ is not honest")
    return core, status, consistency, resid_rms, noise


def _inclination(setup: MagSetup, fits: _Fits, y: np.ndarray, sd: np.ndarray, used: np.ndarray, notes: list[str]
                 ) -> tuple[float, float, np.ndarray | None, np.ndarray | None]:
    """(inclination °, σ, misalignment ° or None, σ or None) of the fitted model."""
    if fits.meth.sees_misalignment:
        return float(y[13]), float(sd[13]), y[14:17], sd[14:17]
    # post-hoc inclination: mean over the quasi-static samples, σ from 10 s clusters (the unmodelled
    # misalignment tilts the symmetric frame: an error per pose, not per sample) and the prior of
    # that misalignment, which the fit cannot see
    rec = setup.rec
    l, h, _ = fits.core.unpack(fits.core.theta)
    long_blocks = block_index(rec.n, max(1, int(round(10 * rec.rate_hz))), min_blocks=8)
    incl, incl_sd = _mean_with_std(_inclination_series(setup.inp.mag_ut, l, h, setup.gravity)[used], long_blocks[used])
    notes.append("misalignment to the IMU frame not observable from the field magnitude (use method 'aided'); "
                 f"the inclination assumes none, its σ includes a {MISALIGNMENT_PRIOR_DEG:g}° misalignment prior")
    return incl, math.hypot(incl_sd, MISALIGNMENT_PRIOR_DEG), None, None


def fit_samples(setup: MagSetup, valid: np.ndarray | None = None) -> MagCalibration:
    """The calibration (module docstring) of the samples ``valid`` (default: every usable sample);
    raises :class:`NotCalibratable` when they are too few or the board did not turn."""
    inp = setup.inp if valid is None else replace(setup.inp, valid=setup.inp.valid & valid)
    warnings = list(setup.warnings)
    diagnostics: dict = {"notes": list(setup.notes)}
    notes = diagnostics["notes"]
    cover, weak, coverage = _coverage(inp, setup.min_coverage)
    # below the soft-iron coverage the samples are near a plane: the circle's hard iron, with the
    # component along the weak axis refused unless the field and inclination are given (hardiron.py);
    # a sphere through them would trade that component against the radius (BROAD 16: F = 56 µT)
    if cover < setup.min_coverage:
        return _hard_iron_only_result(setup, inp, f"coverage {cover:.3f} < {setup.min_coverage}", inp.valid.copy(),
                                      weak, True, warnings, coverage, diagnostics)
    fits, used, found, disturbed = _robust_fit(setup, inp, warnings, notes)
    if found:
        frac = disturbed.sum() / max(inp.valid.sum(), 1)
        warnings.append(f"local magnetic disturbance: {len(found)} stretch(es), {int(disturbed.sum())} samples "
                        f"({100 * frac:.1f} %), up to {max(x.max_field_deviation_ut for x in found):.2f} µT off the "
                        "field magnitude; excluded from the fit, not absorbed")
    reason = _soft_iron_refusal(fits.core)
    if reason:
        return _hard_iron_only_result(setup, inp, reason, used, weak, False, warnings, coverage, diagnostics, found,
                                      disturbed)
    core, status, consistency, resid_rms, noise = _consistency(setup, fits.core, inp.mag_ut[used], warnings)
    if found and disturbed.sum() > 0.5 * inp.valid.sum():
        status = "disturbed"
        warnings.append(
            "more than half of the session is magnetically disturbed: the calibration rests on the minority"
        )
    fits.core = core
    y, cy = propagate(core, setup.field_ut)
    sd = np.sqrt(np.clip(np.diag(cy), 0, None))
    incl, incl_sd, mis, mis_sd = _inclination(setup, fits, y, sd, used, notes)
    l, _, _ = core.unpack(core.theta)
    f_est = abs(np.linalg.det(np.linalg.inv(l))) ** (1 / 3)
    if setup.field_ut:
        ref = f"given |B| = {setup.field_ut:g} µT (A absolute; the fit's own scale reads {f_est:.3f} µT)"
        f_val, f_sd = float(setup.field_ut), 0.0
    else:
        ref = "det A = 1 (field_uT in the sensor's own average scale)"
        f_val, f_sd = float(y[12]), float(sd[12])
    diagnostics.update(residual_field_rms_uT=resid_rms, white_noise_uT=noise,
                       sigma_correlation_ratio=core.correlation_ratio, sphere_radius_uT=fits.f,
                       field_estimated_uT=f_est)
    if math.isfinite(core.sigma_inclination):
        diagnostics["residual_inclination_rms_uT"] = core.sigma_inclination * f_est
    samples = {"total": setup.rec.n, "saturated": inp.saturated_samples, "used": int(used.sum()),
               "disturbed": int(disturbed.sum())}
    return MagCalibration(
        method=setup.method, status=status, hard_iron_ut=y[:3], soft_iron=y[3:12].reshape(3, 3), field_ut=f_val,
        inclination_deg=incl, misalignment_deg=mis, hard_iron_std_ut=sd[:3], soft_iron_std=sd[3:12].reshape(3, 3),
        field_std_ut=f_sd, inclination_std_deg=incl_sd, misalignment_std_deg=mis_sd, field_reference=ref,
        warnings=tuple(warnings),
        refused=tuple(f"misalignment_deg[{i}]" for i in range(3)) if fits.refused_misalignment else (),
        disturbances=found, samples=samples, coverage=coverage, consistency=consistency, diagnostics=diagnostics)
