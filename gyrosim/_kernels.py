"""Single-pass, in-place kernels (numba) behind the hot effects' ``add_delta`` / ``transform``.

Each kernel is the fast form of an equation whose reference is the effect's numpy ``delta`` (see
:mod:`gyrosim.effects`); ``tests/gyrosim/test_effects.py`` holds the two equal.  One loop over the samples
with no temporaries replaces several whole-array numpy passes, which is what made the full
MPU-9250 model 4× slower than a bare bias+scale+noise baseline (the data do not fit in cache).
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = [
    "add_affine", "add_nonlinearity", "add_poly_bias", "add_poly_scale", "add_matvec", "add_scaled",
    "add_upsampled", "lowpass", "quantize", "saturate",
]


@njit(cache=True)
def add_affine(y, x, a, c):  # pragma: no cover - compiled
    """y += x Aᵀ + c."""
    for k in range(y.shape[0]):
        x0, x1, x2 = x[k, 0], x[k, 1], x[k, 2]
        for i in range(3):
            y[k, i] += a[i, 0] * x0 + a[i, 1] * x1 + a[i, 2] * x2 + c[i]


@njit(cache=True)
def add_nonlinearity(y, x, k3):  # pragma: no cover - compiled
    """y += k ⊙ x ⊙ |x|."""
    for k in range(y.shape[0]):
        for i in range(3):
            v = x[k, i]
            y[k, i] += k3[i] * v * abs(v)


@njit(cache=True)
def _poly(coeff, i, d):  # pragma: no cover - compiled
    """Σ_p c_ip d^(p+1)."""
    acc, pw = 0.0, d
    for p in range(coeff.shape[1]):
        acc += coeff[i, p] * pw
        pw *= d
    return acc


@njit(cache=True)
def add_poly_bias(y, dt_c, coeff):  # pragma: no cover - compiled
    """y_i += Σ_p c_ip ΔT^(p+1)."""
    for k in range(y.shape[0]):
        for i in range(3):
            y[k, i] += _poly(coeff, i, dt_c[k])


@njit(cache=True)
def add_poly_scale(y, x, dt_c, coeff):  # pragma: no cover - compiled
    """y_i += x_i Σ_p s_ip ΔT^(p+1)."""
    for k in range(y.shape[0]):
        for i in range(3):
            y[k, i] += x[k, i] * _poly(coeff, i, dt_c[k])


@njit(cache=True)
def add_matvec(y, u, m):  # pragma: no cover - compiled
    """y += u Mᵀ (g-sensitivity K f, magnetic sensitivity K B)."""
    for k in range(y.shape[0]):
        u0, u1, u2 = u[k, 0], u[k, 1], u[k, 2]
        for i in range(3):
            y[k, i] += m[i, 0] * u0 + m[i, 1] * u1 + m[i, 2] * u2


@njit(cache=True)
def add_scaled(y, w, s3):  # pragma: no cover - compiled
    """y += s ⊙ w (white noise from unit normals w)."""
    for k in range(y.shape[0]):
        for i in range(3):
            y[k, i] += s3[i] * w[k, i]


@njit(cache=True)
def add_upsampled(y, coarse, factor):  # pragma: no cover - compiled
    """y += linear interpolation of ``coarse`` (step ``factor`` samples) onto y's samples."""
    inv = 1.0 / factor
    for k in range(y.shape[0]):
        j = k // factor
        f = (k - j * factor) * inv
        for i in range(3):
            y[k, i] += coarse[j, i] + (coarse[j + 1, i] - coarse[j, i]) * f


@njit(cache=True)
def lowpass(y, a):  # pragma: no cover - compiled
    """First-order low-pass, started at steady state: out_k = a out_{k−1} + (1 − a) y_k."""
    out = np.empty_like(y)
    for i in range(3):
        prev = y[0, i]
        for k in range(y.shape[0]):
            prev = a * prev + (1.0 - a) * y[k, i]
            out[k, i] = prev
    return out


@njit(cache=True)
def quantize(y, lsb):  # pragma: no cover - compiled
    """LSB · rint(y · (1/LSB)) (round half to even, as numpy's rint)."""
    out = np.empty_like(y)
    inv = 1.0 / lsb
    for k in range(y.shape[0]):
        for i in range(3):
            out[k, i] = np.rint(y[k, i] * inv[i]) * lsb[i]
    return out


@njit(cache=True)
def saturate(y, rng3):  # pragma: no cover - compiled
    """Clip to ±range."""
    out = np.empty_like(y)
    for k in range(y.shape[0]):
        for i in range(3):
            v = y[k, i]
            r = rng3[i]
            out[k, i] = r if v > r else (-r if v < -r else v)
    return out
