"""The body-frame magnetic offset per window, from the magnetometer and the gyro together.

In a field that is uniform and constant in the room, the body-frame field is b_k = C_kᵀ W + c:
W the field in a frame fixed to the room, C_k the attitude (body → that frame) and c every field
that turns with the board (hard iron).  The gyro gives C_k to within its bias over a few seconds
(:func:`gyrosim.strapdown.integrate_gyro`), so in each window of ``window_s``

    C_k b_k = W + C_k c                              (6 unknowns, linear)

is a small least-squares problem.  Its information about c, N = Σ (C_k − C̄)ᵀ (C_k − C̄), grows
with how far the board turned: none at rest, none along the axis of a turn about one axis.  The
directions whose information per sample is below ``min_turn`` (≈ a turn of 45° within the window)
are dropped: there a window's c is decided by the gyro's drift and the sensor's scale errors, not by
the data.  What the windows give:

* the offset c (µT) in the directions each window sees, with its information N (per µT²);
* the residual RMS (µT): what a constant body-frame offset leaves.

A magnet attached to the board moves c and leaves W; a magnet in the room moves W (with where the
board is), not c — the test :mod:`calib.mag.regimes` builds on.  Soft iron (A ≠ I, a few %) is
left in b: it adds a slowly varying error of (A − I) B, common to every regime, that the windows'
spread absorbs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gyrosim.rotations import quat_to_matrix
from gyrosim.strapdown import integrate_gyro

__all__ = ["WindowOffsets", "window_offsets", "MIN_TURN"]

MIN_TURN = 0.05  # information per sample (1 − cos-like, dimensionless) below which a direction is not seen


@dataclass(frozen=True)
class WindowOffsets:
    """Per window (W of them): sample range [lo, hi), times (s), valid samples, the information N
    about the offset c restricted to the directions it sees (W, 3, 3), N c (W, 3), the offset c
    (µT; 0 in directions not seen), the number of directions seen, and the residual RMS (µT)."""

    lo: np.ndarray
    hi: np.ndarray
    t_start_s: np.ndarray
    t_end_s: np.ndarray
    n: np.ndarray
    info: np.ndarray
    rhs: np.ndarray
    offset_ut: np.ndarray
    rank: np.ndarray
    rms_ut: np.ndarray
    window_s: float

    @property
    def size(self) -> int:
        return int(self.lo.size)

    @property
    def turning(self) -> np.ndarray:
        """Windows that see the offset in at least two directions (the board turned about two axes or more)."""
        return self.rank >= 2


def _project(nmat: np.ndarray, r: np.ndarray, n: int, min_turn: float) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                                              int]:
    """(N, r, c, rank) restricted to the eigen-directions of N with eigenvalue ≥ min_turn · n."""
    ev, vec = np.linalg.eigh(nmat)
    keep = ev >= min_turn * max(n, 1)
    if not keep.any():
        return np.zeros((3, 3)), np.zeros(3), np.zeros(3), 0
    v = vec[:, keep]
    nk = (v * ev[keep]) @ v.T
    rk = v @ (v.T @ r)
    c = v @ ((v.T @ r) / ev[keep])
    return nk, rk, c, int(keep.sum())


def window_offsets(t_s: np.ndarray, mag_ut: np.ndarray, valid: np.ndarray, gyro_rad_s: np.ndarray,
                   gyro_bias_rad_s: np.ndarray, *, window_s: float = 2.0, min_turn: float = MIN_TURN
                   ) -> WindowOffsets:
    """The offsets of the module docstring over consecutive windows of ``window_s`` (s).

    ``mag_ut`` (N, 3) body frame; ``valid`` (N,) samples that may be used; ``gyro_rad_s`` (N, 3) the
    body rate and ``gyro_bias_rad_s`` (3,) its bias (removed before integrating)."""
    n = t_s.size
    rate = (n - 1) / max(float(t_s[-1] - t_s[0]), 1e-12)
    w = max(8, int(round(window_s * rate)))
    q = integrate_gyro(t_s, np.asarray(gyro_rad_s, float) - np.asarray(gyro_bias_rad_s, float),
                       np.array([1.0, 0.0, 0.0, 0.0]))
    cmat = quat_to_matrix(q)
    y = np.einsum("nij,nj->ni", cmat, mag_ut)
    lo = np.arange(0, n, w)
    hi = np.minimum(lo + w, n)
    if lo.size > 1 and hi[-1] - lo[-1] < w // 2:  # a short tail joins the window before it
        lo, hi = lo[:-1], np.r_[hi[:-2], n]
    nw = lo.size
    out = {k: np.zeros((nw, 3, 3)) if k == "info" else np.zeros((nw, 3)) for k in ("info", "rhs", "offset_ut")}
    cnt, rank, rms = np.zeros(nw, int), np.zeros(nw, int), np.full(nw, np.nan)
    for i in range(nw):
        ok = valid[lo[i]:hi[i]]
        k = int(ok.sum())
        cnt[i] = k
        if k < 8:
            continue
        ck, yk = cmat[lo[i]:hi[i]][ok], y[lo[i]:hi[i]][ok]
        d = ck - ck.mean(axis=0)
        e = yk - yk.mean(axis=0)
        nmat = np.einsum("kji,kjl->il", d, d)
        r = np.einsum("kji,kj->i", d, e)
        nk, rk, c, rank[i] = _project(nmat, r, k, min_turn)
        out["info"][i], out["rhs"][i], out["offset_ut"][i] = nk, rk, c
        res = e - np.einsum("kij,j->ki", d, c)
        rms[i] = float(np.sqrt(np.mean(res**2)))
    return WindowOffsets(lo, hi, t_s[lo], t_s[hi - 1], cnt, out["info"], out["rhs"], out["offset_ut"], rank, rms,
                         float(window_s))
