"""Gyro bias as a function of temperature, fitted only as far as the data support it.

bias_i(T) = Σ_{p=0..d} c_ip (T − T_ref)^p, fitted by least squares to the gyro at rest (where
the true rate is zero, Earth rate aside), with the degree d chosen by cross-validation over
contiguous time blocks (random folds would let neighbouring, correlated samples leak between
training and test).  A degree is accepted only if

* it lowers the cross-validated error against the degree below, and
* its highest coefficient is significant: |c_id| > 3 σ(c_id), with σ from the regression using a
  residual variance inflated for correlation (batch means of 20 blocks), so tremor or flicker
  cannot pass for a temperature effect.

A recording whose temperature span is too small for even a linear term (x-IMU export: 31.0–31.9 °C)
gets degree 0 and a message saying why, never a wild polynomial.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gyrosim.errors import RecordingError
from gyrosim.recording import Recording

from calib.session.rest import detect_rest

__all__ = ["TemperatureFit", "fit_bias_temperature"]


@dataclass(frozen=True)
class TemperatureFit:
    """bias(T) per axis (rad/s): coefficients (3, d+1) in powers of (T − t_ref_c), lowest first."""

    degree: int
    coefficients: np.ndarray
    coefficient_std: np.ndarray
    t_ref_c: float
    span_c: float
    cv_rms_rad_s: tuple[float, ...]
    messages: tuple[str, ...]

    def bias_rad_s(self, temp_c: np.ndarray) -> np.ndarray:
        d = np.asarray(temp_c, float) - self.t_ref_c
        return np.stack([np.polyval(self.coefficients[i, ::-1], d) for i in range(3)], axis=1)


def _design(dT: np.ndarray, degree: int) -> np.ndarray:
    return np.stack([dT**p for p in range(degree + 1)], axis=1)


def _fit(dT: np.ndarray, y: np.ndarray, degree: int) -> tuple[np.ndarray, np.ndarray]:
    """Coefficients (3, d+1) and their σ, with batch-means-inflated residual variance."""
    a = _design(dT, degree)
    coef, *_ = np.linalg.lstsq(a, y, rcond=None)
    resid = y - a @ coef
    white = resid.var(axis=0, ddof=degree + 1)
    means = np.array([b.mean(axis=0) for b in np.array_split(resid, 20)])
    correlated = means.var(axis=0, ddof=1) * (resid.shape[0] / 20)  # variance of the mean × block size
    var = np.maximum(white, correlated)
    cov = np.linalg.inv(a.T @ a)
    return coef.T, np.sqrt(np.outer(var, np.diag(cov)))


def fit_bias_temperature(rec: Recording, *, max_degree: int = 3, folds: int = 5) -> TemperatureFit:
    """Fit bias(T) on the rest samples of ``rec`` (module docstring)."""
    if rec.temp_c is None:
        raise RecordingError("the recording has no temperature channel (/temp, °C); bias(T) cannot be fitted")
    if not np.all(np.isfinite(rec.temp_c)):
        raise RecordingError("the temperature channel has NaN values: interpolate or drop them first")
    rest = detect_rest(rec)
    if not rest.index_ranges:
        raise RecordingError("no rest period: bias(T) is fitted where the true rate is zero")
    idx = np.concatenate([np.arange(a, b) for a, b in rest.index_ranges])
    temp, y = rec.temp_c[idx], rec.gyro_rad_s[idx]
    t_ref = float(np.mean(temp))
    dT = temp - t_ref
    span = float(temp.max() - temp.min())
    blocks = np.array_split(np.arange(idx.size), folds)
    cv = []
    for d in range(max_degree + 1):
        err = []
        for k in range(folds):
            test = blocks[k]
            train = np.concatenate([blocks[j] for j in range(folds) if j != k])
            if np.ptp(dT[train]) == 0 and d > 0:
                err.append(np.inf)
                continue
            c, _ = _fit(dT[train], y[train], d)
            err.append(float(np.mean((y[test] - _design(dT[test], d) @ c.T) ** 2)))
        cv.append(math.sqrt(float(np.mean(err))))
    degree, messages = 0, []
    for d in range(1, max_degree + 1 if span > 0 else 1):
        coef, sd = _fit(dT, y, d)
        significant = np.abs(coef[:, d]) > 3 * sd[:, d]
        if cv[d] < cv[d - 1] and significant.any():
            degree = d
            continue
        slope_unit = "°/s per °C" if d == 1 else f"°/s per °C^{d}"
        messages.append(
            f"degree {d} rejected: the {span:.2f} °C span does not support it (highest coefficient "
            f"{np.degrees(np.abs(coef[:, d])).max():.3g} ± {np.degrees(sd[:, d]).max():.2g} {slope_unit} (1σ); "
            f"cross-validated error {np.degrees(cv[d]):.4f} vs {np.degrees(cv[d - 1]):.4f} °/s)"
        )
        break
    if degree == 0:
        messages.append(
            f"temperature span {span:.2f} °C is too small to fit a temperature dependence: returning the constant "
            "rest bias; record over a wider temperature range (a warm-up or a chamber cycle) to fit bias(T)"
        )
    coef, sd = _fit(dT, y, degree)
    return TemperatureFit(degree, coef, sd, t_ref, span, tuple(cv), tuple(messages))
