"""Identifiability gate: is a candidate excited, on this recording, by what it claims to depend on?

A candidate may join the model only if all of these hold (the first that fails is its reason in
the report's "Not tested"):

1. **Its driver is measured finely enough** (:meth:`CandidateFamily.measurement_check`): e.g. a
   temperature span ≥ 10× the thermometer's own resolution.
2. **The driver, not a proxy, moves the regressor.**  When the regressor reaches its driver
   through another sensor (the specific force through the accelerometer, the field through the
   magnetometer) or through the model's own terms (a time offset's regressor is the derivative of
   the modelled output, which a thermal bias also moves), the family predicts the same signal from
   the driver alone (specific force from motion and attitude; field from attitude; dω/dt of the
   reference rate) and the driver must explain at least half of the signal's variation:

       share = 1 − Σ_k var(s_k − ŝ_k) / Σ_k var(s_k) ≥ ½,

   s the regressor signal, ŝ its motion-driven prediction.  On a static board in a chamber the
   specific force varies only through the accelerometer's thermal drift: share ≈ 0, and
   g-sensitivity is not identifiable there however well it would "fit".
3. **Its regressor is not spanned by the model** (Δp > 0 columns outside the model's span on the
   fit rows, relative singular-value tolerance 1e-7 on unit-norm columns).
4. **An effect of the largest plausible size would be seen.**  With the design rows projected
   orthogonal to the current model (fit rows), J⊥, the z of a change of one parameter j by its
   largest plausible size ρ_j (:meth:`CandidateFamily.plausible_max`) is

       z_j = ρ_j ‖J⊥_j‖ / σ_w,

   σ_w the white-noise floor of the rows: per axis 1.4826·MAD(Δr)/√2 of the first differences of
   the residual rows of the model *with* the candidate (fit rows), averaged over axes in quadrature.
   The floor, not the residual's RMS, because whatever the model does not hold yet (other effects,
   slow thermal structure) is what the loop is still looking for, not noise that hides an effect;
   differences remove slow structure and keep the white part.  The gravity reference's rows are
   per pose, not a time series: there σ_w is the rest noise (rate σ of a rest mean, tilt σ from the
   accelerometer noise) in the rows' weighted units.
   The candidate is identifiable when max_j z_j ≥ 3 (even the largest plausible effect in its
   best-excited parameter would show at 3σ); e.g. a time offset needs enough dω/dt that an offset of
   50 ms shows.  If not, whatever the candidate would fit on this recording can only be something
   else (and a fit beyond the plausible size is refused for the same reason).

The projection runs in the row space of the chunked-QR factor of [J_model | J_cand]
(:func:`calib.closeloop.fit.reduce_rows`), so its cost is bounded like the fit's.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Sequence

import numpy as np

from calib.closeloop.candidates import Candidate
from calib.closeloop.fit import FitResult, design_rows, reduce_rows
from calib.closeloop.reference import GravityReference, Reference

__all__ = ["Excitation", "excitation", "precheck", "Z_DETECT", "MIN_DRIVER_SHARE"]

Z_DETECT = 3.0
MIN_DRIVER_SHARE = 0.5
RANK_TOL = 1e-7


@dataclass(frozen=True)
class Excitation:
    """The gate's verdict on one candidate (see the module docstring)."""

    effect: str
    driver: str
    identifiable: bool
    added_rank: int
    detectable_z: float        # max_j z_j of the largest plausible effect (NaN: no size stated)
    driver_share: float        # share of the regressor signal's variation the driver explains (1: the driver itself)
    reason: str                # why not identifiable ("" when it is)

    def to_json(self) -> dict:
        return asdict(self)


def _share(cand: Candidate, ref: Reference) -> float:
    d = cand.family.driver_signal(cand, ref)
    if d is None or cand.follows_series is None:
        return 1.0
    s = np.asarray(cand.follows_series, float)
    ok = np.all(np.isfinite(s), axis=1) & np.all(np.isfinite(d), axis=1)
    if ok.sum() < 3:
        return 0.0
    s, d = s[ok], d[ok]
    total = float(np.sum(np.var(s, axis=0)))
    if total <= 0:
        return 1.0  # nothing varies: the rank check says "no excitation"
    return float(max(0.0, 1.0 - np.sum(np.var(s - d, axis=0)) / total))


def _projected(ref: Reference, model: Sequence[Candidate], fit: FitResult, cand: Candidate, gyro: np.ndarray,
               rows: np.ndarray, extended: FitResult) -> tuple[np.ndarray, np.ndarray]:
    """(J⊥ column norms in θ units (P_c,), singular values of J⊥ on unit-norm columns)."""
    p = fit.theta.size + cand.n_params
    pm = p - cand.n_params
    if extended.factor is not None and extended.theta.size == p:   # the extended fit's own reduction
        red, scale = extended.factor[:, :p], extended.scale
    else:
        theta = np.concatenate([fit.theta, np.zeros(cand.n_params)])
        j = design_rows(ref, list(model) + [cand], gyro, theta)[rows]
        scale = np.linalg.norm(j, axis=0)
        scale[scale == 0] = 1.0
        red = reduce_rows(j / scale)                # RᵀR = JᵀJ: project in R's row space
    rm, rc = red[:, :pm], red[:, pm:]
    if pm:
        u, s, _ = np.linalg.svd(rm, full_matrices=False)
        u = u[:, s > (s[0] if s.size else 0.0) * 1e-8]
        rc = rc - u @ (u.T @ rc)
    sv = np.linalg.svd(rc, compute_uv=False)
    return np.linalg.norm(rc, axis=0) * scale[pm:], sv


def noise_floor(ref: Reference, fit: FitResult, rows: np.ndarray) -> float:
    """σ_w of the residual rows (see the module docstring), row units."""
    r = fit.residual
    if isinstance(ref, GravityReference):
        return max(ref.noise_floor(), 1e-300)
    if ref.row_axis.min() < 0:
        return max(fit.sigma, 1e-300)
    per = []
    for a in range(3):
        ra = r[rows & (ref.row_axis == a)]
        if ra.size > 8:
            d = np.diff(ra)
            per.append(1.4826 * float(np.median(np.abs(d - np.median(d)))) / math.sqrt(2.0))
    return max(math.sqrt(float(np.mean(np.square(per)))) if per else fit.sigma, 1e-300)


def precheck(ref: Reference, cand: Candidate) -> Excitation | None:
    """Checks 1–2 (no fit needed): the verdict when the candidate fails them, else None."""
    fam = cand.family
    why = fam.measurement_check(ref.ctx)
    if why:
        return Excitation(cand.kind, fam.driver, False, 0, math.nan, math.nan, why)
    share = _share(cand, ref)
    if share < MIN_DRIVER_SHARE:
        return Excitation(cand.kind, fam.driver, False, 0, math.nan, share, fam.proxy_reason(share, ref))
    return None


def excitation(ref: Reference, model: Sequence[Candidate], fit: FitResult, cand: Candidate, gyro: np.ndarray,
               fit_rows: np.ndarray, extended: FitResult) -> Excitation:
    """Whether ``cand`` is identifiable against the current ``model`` (fitted as ``fit``) on this
    reference; ``extended``: the model with the candidate fitted on the fit rows (its noise level)."""
    fam = cand.family
    kind = cand.kind

    def verdict(ok: bool, rank: int, z: float, share: float, why: str) -> Excitation:
        return Excitation(kind, fam.driver, ok, rank, z, share, "" if ok else why)

    pre = precheck(ref, cand)
    if pre is not None:
        return pre
    share = _share(cand, ref)
    norms, sv = _projected(ref, model, fit, cand, gyro, fit_rows, extended)
    rank = int(np.sum(sv > RANK_TOL))
    res = np.broadcast_to(np.asarray(fam.plausible_max(kind, ref.ctx), float), norms.shape)
    z = float(np.nanmax(res * norms / noise_floor(ref, extended, fit_rows))) if not np.all(np.isnan(res)) else math.nan
    if rank == 0 or z < 1e-6:  # (a column of rounding noise, e.g. dω/dt of a zero rate, is no excitation)
        return verdict(False, 0, 0.0, share, fam.unexcited(kind, ref))
    if math.isnan(z):
        return verdict(True, rank, math.nan, share, "")
    if z < Z_DETECT:
        f, unit = fam.display
        best = float(np.nanmax(res)) * f
        return verdict(False, rank, z, share,
                       f"{fam.driver} barely varies on this recording: even the largest plausible effect ({best:.3g} "
                       f"{unit}) would change the residual by only {z:.1f}σ (needs {Z_DETECT:g}σ)")
    return verdict(True, rank, z, share, "")
