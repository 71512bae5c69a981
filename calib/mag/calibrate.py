"""``calibrate_magnetometer``: hard and soft iron of a recording, end to end.

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
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from threadpoolctl import threadpool_limits

from gyrosim.errors import RecordingError
from gyrosim.recording import Recording
from gyrosim.sensor_model import stored_sensor_model

from calib.mag.checks import MagInput, check_unit, prepare_magnetometer, rotations_to_add, unit_from_median
from calib.mag.disturbance import find_disturbances
from calib.mag.ellipsoid import white_noise_variance
from calib.mag.gravity import GravityReference, direction_coverage, gravity_reference
from calib.mag.hardiron import circle_hard_iron, sphere_hard_iron
from calib.mag.lsq import block_index, cluster_jackknife
from calib.mag.methods import METHODS, CoreFit, MagMethod, MisalignmentUnobservable, polar_rotation_deg, propagate
from calib.mag.result import Disturbance, MagCalibration

__all__ = ["calibrate_magnetometer", "true_magnetometer", "SOFT_IRON_NAMES", "MIN_COVERAGE"]

SOFT_IRON_NAMES = tuple(f"soft_iron[{i}][{j}]" for i in range(3) for j in range(3))
MIN_COVERAGE = 0.1  # direction_coverage below which the soft iron is refused
MIN_SPREAD_UT = 2.0  # samples spread less than this in their second direction: the board did not turn
MAX_AXIS_RATIO = 1.5  # a soft iron beyond 50 % is no magnetometer's: a disturbance the detector missed
JACKKNIFE_S = 10.0  # cluster length of the jackknife consistency check (s)
INCONSISTENT_RATIO = 10.0  # jackknife / (widened) sandwich variance beyond which σ is not honest
STRUCTURE_RATIO = 1.5  # residual RMS / white noise above which the residual is said to have structure
# the ellipsoid fit's frame may be turned against the IMU's by an unseen misalignment: a separate
# magnetometer die or chip is aligned to ~1° (AK8963 in the MPU-9250: not specified; engineering value)
MISALIGNMENT_PRIOR_DEG = 1.0


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


def _disturbance_loop(residual_of, rec: Recording, inp: MagInput, gravity, refit, used0: np.ndarray,
                      rounds: int, position_nav_m: np.ndarray | None = None
                      ) -> tuple[np.ndarray, tuple[Disturbance, ...], np.ndarray]:
    """Detect on the residual of the current fit, exclude, refit; until the set stops changing.
    ``residual_of()`` → (|B| − F in µT, inclination − I in ° or None) for every sample;
    ``refit(used)`` refits on the samples ``used``."""
    disturbed = np.zeros_like(used0)
    found: tuple[Disturbance, ...] = ()
    used = used0.copy()
    for _ in range(rounds):
        dev_field, dev_incl = residual_of()
        mask, new = find_disturbances(rec.t_s, dev_field, dev_incl, inp.valid, position_nav_m=position_nav_m)
        if np.array_equal(mask, disturbed):
            break
        disturbed, found = mask, new
        used = used0 & ~disturbed
        if used.sum() < 50:
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


def _hard_iron_only_result(method: str, reason: str, rec: Recording, inp: MagInput, used: np.ndarray, blocks,
                           cover: float, weak: np.ndarray, planar: bool, field_ut, inclination_deg, gravity,
                           warnings: list[str], coverage: dict, diagnostics: dict,
                           disturbances: tuple[Disturbance, ...] = (), disturbed: np.ndarray | None = None
                           ) -> MagCalibration:
    m = inp.mag_ut
    notes = diagnostics.setdefault("notes", [])
    if planar:
        h, sig_h, radius, ref_h, hn = circle_hard_iron(m, blocks, weak, field_ut, inclination_deg, gravity, used)
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
    samples = {"total": rec.n, "saturated": inp.saturated_samples, "used": int(used.sum()),
               "disturbed": int(disturbed.sum()) if disturbed is not None else 0}
    return MagCalibration(
        method=method, status="hard_iron_only", hard_iron_ut=h, soft_iron=np.full((3, 3), np.nan), field_ut=f_val,
        inclination_deg=float("nan"), misalignment_deg=None, hard_iron_std_ut=sig_h,
        soft_iron_std=np.full((3, 3), np.nan), field_std_ut=f_sd, inclination_std_deg=float("nan"),
        misalignment_std_deg=None, field_reference="hard iron only (|m − h| = F)", warnings=tuple(warnings),
        refused=tuple(list(SOFT_IRON_NAMES) + ref_h), disturbances=disturbances, samples=samples, coverage=coverage,
        diagnostics=diagnostics)


def calibrate_magnetometer(rec: Recording, method: str = "ellipsoid", **kwargs) -> MagCalibration:
    """Hard and soft iron of ``rec``'s magnetometer (module docstring; arguments: :func:`_calibrate`).

    BLAS runs single-threaded inside: the fits multiply N × 9–13 matrices, for which a second
    OpenBLAS thread only adds synchronisation — 4× slower on a loaded 2-core machine (measured)."""
    with threadpool_limits(limits=1, user_api="blas"):
        return _calibrate(rec, method, **kwargs)


def _calibrate(rec: Recording, method: str = "ellipsoid", *, mag_unit: str = "uT",
                           field_ut: float | None = None, inclination_deg: float | None = None,
                           range_ut: float | None = None, min_coverage: float = MIN_COVERAGE,
                           time_range_s: tuple[float, float] | None = None, detect_disturbances: bool = True,
                           consistency_check: bool = True,
                           position_nav_m: np.ndarray | None = None) -> MagCalibration:
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
        position_nav_m: (N, 3) the board's position (ENU, m) from an external reference the user has
            (an optical tracker); only labels where a disturbance was, never enters the fit.

    Reads only the samples, times and rate of ``rec`` (no truth, no stored sensor model): a
    simulated recording and its :func:`gyrosim.estimator.as_user_file` view give the same result.
    """
    if method not in METHODS:
        raise RecordingError(f"unknown magnetometer method {method!r}; use one of {', '.join(METHODS)}")
    meth: MagMethod = METHODS[method]()
    inp = prepare_magnetometer(rec, unit=mag_unit, range_ut=range_ut)
    if position_nav_m is not None:
        position_nav_m = np.asarray(position_nav_m, dtype=float)
        if position_nav_m.shape != (rec.n, 3):
            raise RecordingError(f"position_nav_m has shape {position_nav_m.shape}; the recording has {rec.n} samples: "
                                 f"expected ({rec.n}, 3)")
    if time_range_s is not None:
        inside = (rec.t_s >= time_range_s[0]) & (rec.t_s <= time_range_s[1])
        if inside.sum() < 50:
            raise RecordingError(f"only {int(inside.sum())} samples between t = {time_range_s[0]:g} and "
                                 f"{time_range_s[1]:g} s: too few to calibrate")
        inp = replace(inp, valid=inp.valid & inside)
    warnings = list(inp.warnings)
    diagnostics: dict = {"notes": []}
    m = inp.mag_ut
    blocks = block_index(rec.n, max(1, int(round(rec.rate_hz))))
    try:
        gravity: GravityReference | None = gravity_reference(rec)
        diagnostics["notes"] += list(gravity.notes)
    except RecordingError as exc:
        if meth.needs_gravity:
            raise
        gravity = None
        warnings.append(f"no gravity reference ({exc}): inclination not estimated")

    unit_from_median(m[inp.valid], mag_unit)
    cover, weak = direction_coverage(m[inp.valid])
    d = m[inp.valid] - m[inp.valid].mean(axis=0)
    ev = np.linalg.eigvalsh(d.T @ d / d.shape[0])
    coverage = {"value": cover, "minimum": min_coverage, "weakest_direction_body": weak.tolist()}
    # turned about at least one axis: the samples spread over ≥ 2 µT in two directions (a turn of α
    # spreads the Earth's ≥ 22 µT by ~F α/2; a static board spreads only by its noise, < 1 µT)
    if math.sqrt(max(ev[1], 0.0)) < MIN_SPREAD_UT:
        raise RecordingError(
            "the board did not rotate (the magnetometer samples lie along a line or at one point): neither hard nor "
            "soft iron can be separated from the Earth's field; turn the board about at least one axis, better "
            "about all three")
    # below the soft-iron coverage the samples are near a plane: the circle's hard iron, with the
    # component along the weak axis refused unless the field and inclination are given (hardiron.py);
    # a sphere through them would trade that component against the radius (BROAD 16: F = 56 µT)
    if cover < min_coverage:
        return _hard_iron_only_result(method, f"coverage {cover:.3f} < {min_coverage}", rec, inp, inp.valid.copy(),
                                      blocks, cover, weak, True, field_ut, inclination_deg, gravity, warnings,
                                      coverage, diagnostics)

    # 3. sphere start; its radius checks the unit; its residual finds the disturbances first
    state = {"h": None, "f": None, "core": None}

    def refit_sphere(used):
        h, _, f, _, _ = sphere_hard_iron(m[used], blocks[used])
        state["h"], state["f"] = h, f

    def sphere_residual():
        return np.linalg.norm(m - state["h"], axis=1) - state["f"], None

    refit_sphere(inp.valid)
    check_unit(m[inp.valid], state["f"], mag_unit)
    rounds = 4 if detect_disturbances else 0
    used, found, disturbed = _disturbance_loop(sphere_residual, rec, inp, gravity, refit_sphere, inp.valid, rounds,
                                               position_nav_m)

    # 4. the method, started from the sphere, and detection on its own residual
    start = (np.eye(3) / state["f"], state["h"])
    refused_mis = False

    def refit_method(u):
        prev = state["core"]
        st = start if prev is None else prev.unpack(prev.theta)[:2]
        state["core"] = meth.fit(m, blocks, gravity, u, start=st)

    def method_residual():
        core = state["core"]
        l, h, _ = core.unpack(core.theta)
        f_est = abs(np.linalg.det(np.linalg.inv(l))) ** (1 / 3)
        dev_field = (np.linalg.norm((m - h) @ l.T, axis=1) - 1.0) * f_est
        incl = _inclination_series(m, l, h, gravity)
        ok = np.isfinite(incl) & used
        return dev_field, (incl - np.median(incl[ok])) if ok.sum() > 10 else None

    try:
        refit_method(used)
    except MisalignmentUnobservable as exc:
        if not meth.sees_misalignment:
            raise
        warnings.append(f"misalignment refused (misalignment_deg[0..2]): {exc}; hard and soft iron from the "
                        "ellipsoid fit instead")
        diagnostics["notes"].append("attitude-aided fit fell back to the ellipsoid fit")
        refused_mis = True
        meth = METHODS["ellipsoid"]()
        refit_method(used)
    used2, found2, disturbed2 = _disturbance_loop(method_residual, rec, inp, gravity, refit_method, inp.valid, rounds,
                                                  position_nav_m)
    if disturbed2.sum() >= disturbed.sum():
        used, found, disturbed = used2, found2, disturbed2
    else:  # the method's fit hid part of a disturbance the sphere saw: keep the sphere's verdict
        refit_method(used)
    core: CoreFit = state["core"]
    if found:
        frac = disturbed.sum() / max(inp.valid.sum(), 1)
        warnings.append(f"local magnetic disturbance: {len(found)} stretch(es), {int(disturbed.sum())} samples "
                        f"({100 * frac:.1f} %), up to {max(x.max_field_deviation_ut for x in found):.2f} µT off the "
                        "field magnitude; excluded from the fit, not absorbed")

    # 5. is the soft iron decided by the data, and a magnetometer's?
    l, h, _ = core.unpack(core.theta)
    axes = np.linalg.svd(np.linalg.inv(l), compute_uv=False)
    reason = None
    if core.weak_soft_iron:
        reason = "the data leave part of the soft iron to the prior (posterior σ above half the prior's)"
    elif axes.max() > MAX_AXIS_RATIO * axes.min():
        reason = (f"the fitted ellipsoid's axes are {axes.max() / axes.min():.2f} : 1, no magnetometer's (≤ "
                  f"{MAX_AXIS_RATIO}): the field is not uniform over the session (a disturbance spread over it?)")
    if reason:
        return _hard_iron_only_result(method, reason, rec, inp, used, blocks, cover, weak, False, field_ut,
                                      inclination_deg, gravity, warnings, coverage, diagnostics, found, disturbed)

    # 6. self-consistency
    status = "ok"
    consistency: dict = {}
    noise = math.sqrt(white_noise_variance(m[used]))
    f_est = abs(np.linalg.det(np.linalg.inv(l))) ** (1 / 3)
    resid_rms = float(np.sqrt(np.mean(core.residual_field**2))) * f_est
    structured = resid_rms > STRUCTURE_RATIO * noise
    if consistency_check:
        core, consistency = _jackknife_check(core, rec.rate_hz, structured)
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
    if found and disturbed.sum() > 0.5 * inp.valid.sum():
        status = "disturbed"
        warnings.append(
            "more than half of the session is magnetically disturbed: the calibration rests on the minority"
        )

    y, cy = propagate(core, field_ut)
    sd = np.sqrt(np.clip(np.diag(cy), 0, None))
    l, h, _ = core.unpack(core.theta)
    incl, incl_sd = float(y[13]), float(sd[13])
    notes = diagnostics["notes"]
    if not meth.sees_misalignment:
        # post-hoc inclination: mean over the quasi-static samples, σ from 10 s clusters (the unmodelled
        # misalignment tilts the symmetric frame: an error per pose, not per sample) and the prior of
        # that misalignment, which the fit cannot see
        long_blocks = block_index(rec.n, max(1, int(round(10 * rec.rate_hz))), min_blocks=8)
        incl, incl_sd = _mean_with_std(_inclination_series(m, l, h, gravity)[used], long_blocks[used])
        incl_sd = math.hypot(incl_sd, MISALIGNMENT_PRIOR_DEG)
        mis = mis_sd = None
        notes.append("misalignment to the IMU frame not observable from the field magnitude (use method 'aided'); "
                     f"the inclination assumes none, its σ includes a {MISALIGNMENT_PRIOR_DEG:g}° misalignment prior")
    else:
        mis, mis_sd = y[14:17], sd[14:17]
    if field_ut:
        ref = f"given |B| = {field_ut:g} µT (A absolute; the fit's own scale reads {f_est:.3f} µT)"
        f_val, f_sd = float(field_ut), 0.0
    else:
        ref = "det A = 1 (field_uT in the sensor's own average scale)"
        f_val, f_sd = float(y[12]), float(sd[12])
    diagnostics.update(
        residual_field_rms_uT=resid_rms,
        white_noise_uT=noise,
        sigma_correlation_ratio=core.correlation_ratio,
        sphere_radius_uT=state["f"],
        field_estimated_uT=f_est,
    )
    if math.isfinite(core.sigma_inclination):
        diagnostics["residual_inclination_rms_uT"] = core.sigma_inclination * f_est
    samples = {
        "total": rec.n,
        "saturated": inp.saturated_samples,
        "used": int(used.sum()),
        "disturbed": int(disturbed.sum()),
    }
    return MagCalibration(
        method=method, status=status, hard_iron_ut=y[:3], soft_iron=y[3:12].reshape(3, 3), field_ut=f_val,
        inclination_deg=incl, misalignment_deg=mis, hard_iron_std_ut=sd[:3], soft_iron_std=sd[3:12].reshape(3, 3),
        field_std_ut=f_sd, inclination_std_deg=incl_sd, misalignment_std_deg=mis_sd, field_reference=ref,
        warnings=tuple(warnings),
        refused=tuple(f"misalignment_deg[{i}]" for i in range(3)) if refused_mis else (),
        disturbances=found, samples=samples, coverage=coverage, consistency=consistency, diagnostics=diagnostics)


def true_magnetometer(rec: Recording) -> dict[str, np.ndarray] | None:
    """The oracle: the device's m = A B + h of a simulated recording (from its stored sensor model),
    or None; for scoring a calibration, never for making one.
    A = I + Σ (affine parts of the magnetometer effects), h = Σ constants."""
    model = stored_sensor_model(rec.meta)
    if model is None or not model.magnetometer:
        return None
    a, c = np.eye(3), np.zeros(3)
    for eff in model.magnetometer:
        if eff.stage == "error" and not eff.stochastic:
            ac = eff.affine()
            if ac is not None:
                a = a + ac[0]
                c = c + ac[1]
    return {"hard_iron_uT": c, "soft_iron": a, "misalignment_deg": polar_rotation_deg(a)}
