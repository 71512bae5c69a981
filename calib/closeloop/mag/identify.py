"""Identifiability gate of a magnetometer candidate: would every component of it, at its largest
plausible size, show on this recording against the model already held?

With J = [J_model | J_cand] the Jacobian of the model's residual rows on the fit samples (at the
current fit, the candidate at zero) and J = Q R its QR factorisation, the block R₂₂ is the
triangular factor of the candidate's columns projected orthogonal to the model's.  With D the
diagonal of the candidate's plausible sizes ρ (:mod:`calib.closeloop.mag.terms`) and σ_w the
noise per residual row,

    z = s_min(R₂₂ D) / σ_w,     σ_w = max(σ_white, σ_rich √τ_rich)

is the smallest change of the residual (in σ) that a plausible-size effect along its *least
excited* combination of parameters makes.  σ_white is the magnetometer's white noise
(second differences); σ_rich and τ_rich the held-out residual RMS and integrated autocorrelation
time of the model with every candidate: on a recording whose field samples are interpolated or
whose reference has its own slow errors (BROAD: optical attitude, a magnetometer read slower
than the log) the rows are not independent, and √τ counts that.  The candidate is identifiable when z ≥ 3: every
component must be seen (soft iron and the misalignment are matrices of one physical cause; a
component fitted from nothing would only echo noise or another effect).  Examples: a board turned
about one axis only leaves a soft-iron component in the span of B_n (z ≈ 0: "add rotations
about …", the advice of :func:`calib.mag.checks.rotations_to_add`); a board that does not turn at
all leaves the hard iron in the span of B_n; on a magnitude reference the misalignment has no
column at all (``needs_attitude``).

The excitation must come from the driver (the field direction changing with the attitude), not
from noise: on a magnitude reference the columns depend on the measured field itself, whose noise
alone "excites" them (a board turned about one axis puts the field on a circle, where the
soft iron is degenerate, yet noise across the circle's plane gave z ≈ 9 and a fitted soft iron
of 0.3 that shrank the noise of |m|, measured).  So the Jacobian is taken on the field smoothed
over 0.25 s (a centred moving average: white noise down ~5× at 100 Hz, the attitude's changes
kept), and on a magnitude reference hard and soft iron also need
:func:`calib.mag.gravity.direction_coverage` ≥ :data:`calib.mag.calibrate.MIN_COVERAGE` (the rule
of ``calib mag``): with the field on a circle the hard iron along the turning axis trades with the
field magnitude, and the Jacobian at h = 0 (far from a large hard iron) does not show it.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from scipy import ndimage

from calib.closeloop.identify import Z_DETECT, Excitation
from calib.closeloop.mag.fit import MagFit, model_function, split_theta
from calib.closeloop.mag.reference import MagReference
from calib.closeloop.mag.terms import mag_term
from calib.mag.calibrate import MIN_COVERAGE
from calib.mag.checks import rotations_to_add
from calib.mag.gravity import direction_coverage

__all__ = ["mag_excitation"]


def _weak_components(names: tuple[str, ...], v: np.ndarray) -> str:
    w = np.abs(v) / np.max(np.abs(v))
    return ", ".join(n for n, x in zip(names, w) if x > 0.3)


def _field_body(ref: MagReference, fit: MagFit, rows: np.ndarray) -> np.ndarray:
    base = split_theta(ref, fit.kinds, fit.theta)["base"]
    if ref.has_attitude:
        return np.einsum("kij,j->ki", ref.c_bn[rows], base)
    return ref.mag_ut[rows]


def mag_excitation(ref: MagReference, fit: MagFit, kind: str, rows: np.ndarray, noise_ut: float) -> Excitation:
    """The gate's verdict (module docstring) on adding ``kind`` to the model ``fit`` (fit samples ``rows``)."""
    term = mag_term(kind)
    if term.needs_attitude and not ref.has_attitude:
        return Excitation(kind, term.driver, False, 0, math.nan, 1.0,
                          "needs an attitude reference: the field magnitude does not change when the magnetometer's "
                          "axes rotate (the ellipsoid fit's blind spot); record with an optical/truth attitude")
    idx = np.flatnonzero(rows & ref.valid)
    if not ref.has_attitude and term.coverage_part:
        cov, weak = direction_coverage(ref.mag_ut[idx])
        if cov < MIN_COVERAGE:
            part = term.coverage_part
            return Excitation(kind, term.driver, False, 0, 0.0, 1.0,
                              f"field direction coverage {cov:.2f} < {MIN_COVERAGE:g} (calib mag's rule; 1 = every "
                              f"direction): the magnitude alone cannot separate {part} from the field magnitude — "
                              + rotations_to_add(weak))
    kinds = fit.kinds + (kind,)
    rate = (ref.t_s.size - 1) / max(float(ref.t_s[-1] - ref.t_s[0]), 1e-12)
    smooth = replace(ref, mag_ut=ndimage.uniform_filter1d(ref.mag_ut, max(1, int(round(0.25 * rate))), axis=0,
                                                          mode="nearest"))
    _, jac = model_function(smooth, kinds, idx)(np.concatenate([fit.theta, np.zeros(term.n_params)]))
    p0 = fit.theta.size
    scale = np.linalg.norm(jac, axis=0)
    scale[scale == 0] = 1.0
    r = np.linalg.qr(jac / scale, mode="r")
    r22 = r[p0:, p0:] * (scale[p0:] * term.plausible_max)[None, :]
    _, sv, vt = np.linalg.svd(r22)
    z = float(sv[-1] / noise_ut)
    rank = int(np.sum(sv > 1e-7 * max(float(np.max(np.abs(r[p0:, p0:]))), 1e-300)))
    if z >= Z_DETECT:
        return Excitation(kind, term.driver, True, rank, z, 1.0, "")
    f, unit = term.display
    why = (f"{term.driver}: its least excited combination ({_weak_components(term.param_names, vt[-1])}) at the "
           f"largest plausible size ({term.plausible_max * f:.3g} {unit}) would change the residual by only {z:.2g}σ "
           f"(needs {Z_DETECT:g}σ); what would show it: {term.separated_by}")
    if term.coverage_part:
        cov, weak = direction_coverage(_field_body(ref, fit, idx))
        why += f"; field direction coverage {cov:.2f} (1 = every direction): " + rotations_to_add(weak)
    return Excitation(kind, term.driver, False, rank, z, 1.0, why)
