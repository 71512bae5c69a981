"""The magnetometer calibration methods (each defined once, discovered through :data:`METHODS`)
and the map from a method's fitted parameters to what the result reports.

Every method fits |L (m − h)| = 1 in its own parameters θ and says how θ gives (L, h, sin I).
:func:`derived` turns that into (h, A, F, I, misalignment) with A = L⁻¹/F, F = |det L|^(−1/3)
(det A = 1) or a given field magnitude, I = asin(sin I) and the misalignment θ of the right polar
decomposition A = P·R(θ)ᵀ; :func:`propagate` carries the covariance through its numerical
Jacobian (first order).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, ClassVar

import numpy as np

from gyrosim.errors import RecordingError

from calib.mag.aided import fit_aided
from calib.mag.ellipsoid import SYM_IDX, fit_ellipsoid, sym
from calib.mag.gravity import GravityReference

__all__ = ["CoreFit", "MagMethod", "EllipsoidMethod", "AidedMethod", "METHODS", "derived", "propagate",
           "polar_rotation_deg", "DERIVED_NAMES", "MisalignmentUnobservable"]

DERIVED_NAMES = (["hard_iron_uT[0]", "hard_iron_uT[1]", "hard_iron_uT[2]"]
                 + [f"soft_iron[{i}][{j}]" for i in range(3) for j in range(3)]
                 + ["field_uT", "inclination_deg", "misalignment_deg[0]", "misalignment_deg[1]", "misalignment_deg[2]"])


@dataclass(frozen=True)
class CoreFit:
    """A method's fit in its own parameters θ with covariance, and the map θ → (L, h, sin I)."""

    theta: np.ndarray
    cov: np.ndarray
    unpack: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray, float]]
    residual_field: np.ndarray  # |L(m − h)| − 1 per used sample (dimensionless)
    correlation_ratio: float
    sigma_inclination: float = float("nan")
    jacobian: np.ndarray | None = None  # weighted data rows at θ
    residual: np.ndarray | None = None  # weighted data rows at θ
    row_sample: np.ndarray | None = None  # index (into the used samples) of each data row
    weak_soft_iron: bool = False  # the data did not decide some L entry (posterior σ > ½ prior σ)


def polar_rotation_deg(a: np.ndarray) -> np.ndarray:
    """θ (°) with A = P·R(θ)ᵀ, P symmetric positive definite (right polar decomposition)."""
    u, _, vt = np.linalg.svd(a)
    rt = (u @ vt).T  # the orthogonal polar factor is R(θ)ᵀ = U Vᵀ
    ang = math.acos(max(-1.0, min(1.0, (np.trace(rt) - 1) / 2)))
    if ang < 1e-12:
        return np.zeros(3)
    axis = np.array([rt[2, 1] - rt[1, 2], rt[0, 2] - rt[2, 0], rt[1, 0] - rt[0, 1]]) / (2 * math.sin(ang))
    return np.degrees(axis * ang)


def derived(l: np.ndarray, h: np.ndarray, s: float, field_ut: float | None) -> np.ndarray:
    """(h, A row-major, F, I °, misalignment °) from (L, h, sin I) (module docstring)."""
    linv = np.linalg.inv(l)
    f_est = abs(np.linalg.det(linv)) ** (1 / 3)
    a = linv / (field_ut if field_ut else f_est)
    incl = math.degrees(math.asin(max(-1.0, min(1.0, s)))) if math.isfinite(s) else float("nan")
    return np.concatenate([h, a.ravel(), [field_ut or f_est, incl], polar_rotation_deg(a)])


def propagate(core: CoreFit, field_ut: float | None) -> tuple[np.ndarray, np.ndarray]:
    """Values and covariance of :data:`DERIVED_NAMES` (central differences of :func:`derived`)."""
    th = core.theta

    def g(theta):
        return derived(*core.unpack(theta), field_ut)

    y0 = g(th)
    jac = np.zeros((y0.size, th.size))
    scale = max(float(np.max(np.abs(th))), 1e-9)
    for j in range(th.size):
        step = 1e-6 * max(abs(th[j]), 1e-3 * scale)
        tp, tm = th.copy(), th.copy()
        tp[j] += step
        tm[j] -= step
        jac[:, j] = (g(tp) - g(tm)) / (2 * step)
    return y0, jac @ core.cov @ jac.T


MIN_POSE_SPREAD = 0.02  # second eigenvalue of Σuuᵀ/N of the quasi-static up directions (≈ 8° of spread)


class MisalignmentUnobservable(RecordingError):
    """The attitude-aided fit cannot see the misalignment in this recording (gravity in one pose)."""


class MagMethod:
    """A magnetometer calibration method: ``fit`` the used samples into a :class:`CoreFit`."""

    name: ClassVar[str] = ""
    description: ClassVar[str] = ""
    needs_gravity: ClassVar[bool] = False
    sees_misalignment: ClassVar[bool] = False

    def fit(self, m: np.ndarray, blocks: np.ndarray, gravity: GravityReference | None, used: np.ndarray,
            start: tuple[np.ndarray, np.ndarray] | None = None) -> CoreFit:
        raise NotImplementedError


def _sym_unpack(theta):
    return sym(theta[:6]), theta[6:9], float("nan")


class EllipsoidMethod(MagMethod):
    """The ellipsoid fit (:mod:`calib.mag.ellipsoid`): hard iron and a symmetric soft iron from the field
    magnitude alone; blind to the misalignment."""

    name = "ellipsoid"
    description = ("Li & Griffiths' ellipsoid-specific algebraic fit (constraint 4J − I² = 1), refined geometrically: "
                   "|A⁻¹(m − h)| = F, A symmetric, det A = 1 (calib.mag.ellipsoid)")

    def fit(self, m, blocks, gravity, used, start=None):
        st = None if start is None else (0.5 * (start[0] + start[0].T), start[1])
        f = fit_ellipsoid(m[used], blocks[used], start=st)
        return CoreFit(f.theta, f.cov, _sym_unpack, f.residual, f.correlation_ratio, jacobian=f.jacobian,
                       residual=f.residual, row_sample=np.arange(int(used.sum())), weak_soft_iron=bool(f.weak))


class AidedMethod(MagMethod):
    """The attitude-aided fit (:mod:`calib.mag.aided`): the ellipsoid fit's start refined with the
    inclination against the gravity reference, so the misalignment is estimated too; raises
    :class:`MisalignmentUnobservable` when the recording holds still too briefly or in one pose only."""

    name = "aided"
    description = ("attitude-aided: |A⁻¹(m − h)| = F and the inclination against the gravity reference "
                   "(gyro + accelerometer) constant; A general, so the misalignment is estimated (calib.mag.aided)")
    needs_gravity = True
    sees_misalignment = True

    def fit(self, m, blocks, gravity, used, start=None):
        e = fit_ellipsoid(
            m[used], blocks[used], start=None if start is None else (0.5 * (start[0] + start[0].T), start[1])
        )
        static = gravity.quasi_static[used]
        if static.sum() < 50:
            raise MisalignmentUnobservable(
                f"only {int(static.sum())} quasi-static samples: the attitude-aided fit needs the board to hold still "
                "or turn slowly for a few seconds in several orientations")
        u = gravity.up_body[used][static]
        spread = np.linalg.eigvalsh(u.T @ u / u.shape[0])
        if spread[1] < MIN_POSE_SPREAD:
            raise MisalignmentUnobservable(
                f"gravity was seen in one pose only (the quasi-static 'up' directions span {spread[1]:.3f} beyond one "
                f"direction; needs ≥ {MIN_POSE_SPREAD}): a rotation about that vertical leaves the inclination "
                "unchanged. "
                "Hold the board still for a few seconds in ≥ 3 different orientations (e.g. flat, on its side, on its "
                "end)"
            )
        a = fit_aided(m[used], gravity.up_body[used], static, blocks[used], e.l_matrix, e.centre)

        def unpack(theta):
            return theta[:9].reshape(3, 3), theta[9:12], float(theta[12])

        rows = np.concatenate([np.arange(int(used.sum())), np.flatnonzero(static)])
        return CoreFit(a.theta, a.cov, unpack, a.residual_magnitude, a.correlation_ratio, a.sigma_inclination,
                       jacobian=a.jacobian, residual=a.residual, row_sample=rows,
                       weak_soft_iron=bool(e.weak) or bool(a.weak))


METHODS: dict[str, type[MagMethod]] = {cls.name: cls for cls in (EllipsoidMethod, AidedMethod)}

_ = SYM_IDX  # (the symmetric parameter order of the ellipsoid method, re-exported for readers)
