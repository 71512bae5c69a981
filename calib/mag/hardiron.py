"""Hard iron alone, when the attitude coverage cannot carry the 9 soft-iron parameters.

* **Sphere** (the field seen from a spread of directions, not enough for an ellipsoid):
  |m − h| = F, 4 parameters (:func:`calib.mag.ellipsoid.fit_sphere`).
* **Circle** (the board turned about one axis n only, e.g. flat on a table: the samples lie in a
  plane): the circle's centre gives the hard iron in that plane; along n every sample has the same
  component c_n = h·n + B·n, so h·n is unknown unless the field magnitude F and inclination I are:
  then B·n = ±√(F² − r²) (r the circle's radius), the sign the one that makes B·up = −F sin I on
  the quasi-static samples.  Otherwise each body component of h that the unknown moves by more than
  5 µT (|n_k| · 70 µT, the strongest field a sensor could see: an axis tilted > 4° from it) is
  refused by name; the others get that ambiguity in their σ (uniform, /√3).
"""

from __future__ import annotations

import math

import numpy as np

from calib.mag.ellipsoid import fit_sphere
from calib.mag.gravity import GravityReference
from calib.mag.lsq import levenberg_marquardt, sandwich_covariance

__all__ = ["sphere_hard_iron", "circle_hard_iron"]

MAX_FIELD_UT = 70.0  # the strongest Earth field (67 µT at the magnetic poles), rounded up
REFUSE_UT = 5.0  # a component the unknown along-axis value can move by more than this is refused
SCALE_UNCERTAINTY = 0.02  # the sensor scale a hard-iron-only fit assumes to be 1 (AK8963 after its ASA: ~1.5 %)


def sphere_hard_iron(m: np.ndarray, blocks: np.ndarray) -> tuple[np.ndarray, np.ndarray, float, float, np.ndarray]:
    """(h, σ_h, F, σ_F, residual µT) of |m − h| = F."""
    h, f, cov, res = fit_sphere(m, blocks)
    sd = np.sqrt(np.clip(np.diag(cov), 0, None))
    return h, sd[:3], f, float(sd[3]), res


def circle_hard_iron(m: np.ndarray, blocks: np.ndarray, axis: np.ndarray, field_ut: float | None,
                     inclination_deg: float | None, gravity: GravityReference | None, used: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray, float, list[str], list[str]]:
    """(h, σ_h, circle radius r, refused names, notes) for samples in a plane normal to ``axis``."""
    x = m[used]
    n = axis / np.linalg.norm(axis)
    e1 = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    p = np.column_stack([x @ e1, x @ e2])
    c_n = float(np.mean(x @ n))

    def fun(theta):
        d = p - theta[:2]
        nd = np.linalg.norm(d, axis=1)
        return nd - theta[2], np.column_stack([-d / nd[:, None], -np.ones_like(nd)])

    a = np.column_stack([2 * p, np.ones(p.shape[0])])
    sol, *_ = np.linalg.lstsq(a, np.sum(p * p, axis=1), rcond=None)
    r0 = math.sqrt(max(sol[2] + sol[:2] @ sol[:2], 1e-12))
    res = levenberg_marquardt(fun, np.array([sol[0], sol[1], r0]))
    cov, _ = sandwich_covariance(res.jacobian, res.residual, blocks[used])
    cx, cy, radius = (float(v) for v in res.theta)
    refused: list[str] = []
    notes: list[str] = []
    along = float("nan")
    var_t = 0.0
    if field_ut and inclination_deg is not None and gravity is not None and field_ut > radius:
        b_n = math.sqrt(field_ut**2 - radius**2)
        st = gravity.quasi_static[used]
        if st.sum() >= 10:
            best = None
            for sign in (1.0, -1.0):
                h_try = cx * e1 + cy * e2 + (c_n - sign * b_n) * n
                b_up = float(np.mean(np.sum((x[st] - h_try) * gravity.up_body[used][st], axis=1)))
                err = abs(b_up + field_ut * math.sin(math.radians(inclination_deg)))
                if best is None or err < best[0]:
                    best = (err, c_n - sign * b_n)
            along = best[1]
            # σ of B·n = √(F² − r²): the sensor's own scale is unknown here (A = I assumed), so F and r
            # disagree by up to the soft iron's few %: σ_F ≈ SCALE_UNCERTAINTY · F, and dB_n = (F dF − r dr)/B_n
            var_t = ((field_ut * SCALE_UNCERTAINTY * field_ut) ** 2 + (radius * math.sqrt(cov[2, 2])) ** 2) / b_n**2
            notes.append(f"hard iron along the rotation axis from the given field {field_ut:g} µT and inclination "
                         f"{inclination_deg:g}° (σ includes a {100 * SCALE_UNCERTAINTY:g} % unknown sensor scale)")
    basis = np.column_stack([e1, e2])
    cov_h = basis @ cov[:2, :2] @ basis.T + (var_t * np.outer(n, n) if math.isfinite(along) else 0.0)
    sig = np.sqrt(np.clip(np.diag(cov_h), 0, None))
    if math.isfinite(along):
        h = cx * e1 + cy * e2 + along * n
        return h, sig, radius, refused, notes
    h = cx * e1 + cy * e2  # the in-plane part; the along-axis part is unknown
    t_max = math.sqrt(max(MAX_FIELD_UT**2 - radius**2, 0.0))
    for k, ax in enumerate("xyz"):
        if abs(n[k]) * t_max > REFUSE_UT:
            h[k] = np.nan
            sig[k] = np.nan
            refused.append(f"hard_iron_uT[{k}] (body {ax}: along the rotation axis {np.round(n, 2).tolist()})")
        else:
            sig[k] = math.sqrt(sig[k] ** 2 + (abs(n[k]) * t_max) ** 2 / 3)
    return h, sig, radius, refused, notes
