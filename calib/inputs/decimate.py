"""Decimation by block means: N consecutive samples → one, for a method that supports a lower rate.

For a rate gyro the block mean is the angle turned in the block divided by its duration, so the
integrated attitude is kept (to second order in the rotation within a block); for the
accelerometer it is the mean specific force; both are a boxcar anti-alias filter (first null at the
new rate).  The time of a block is the mean of its sample times; a trailing partial block is
dropped.  Truth channels are averaged the same way (quaternions: normalised mean, adequate for the
small rotation within a block).  A block holding an excluded sample (saturated, spike, inserted)
is excluded as a whole.
"""

from __future__ import annotations

import math

import numpy as np

from gyrosim.recording import Recording, Truth

__all__ = ["decimate", "decimation_factor"]


def decimation_factor(rate_hz: float, max_rate_hz: float) -> int:
    """Smallest N with rate/N ≤ max_rate."""
    return max(1, int(math.ceil(rate_hz / max_rate_hz - 1e-9)))


def _blocks(x: np.ndarray | None, n: int, m: int) -> np.ndarray | None:
    if x is None:
        return None
    x = np.asarray(x, dtype=float)[:m]
    return x.reshape((m // n, n) + x.shape[1:]).mean(axis=1)


def decimate(rec: Recording, n: int, excluded: np.ndarray | None = None) -> tuple[Recording, np.ndarray | None]:
    """Block means of ``n`` samples (module docstring); returns the recording and the block mask."""
    if n <= 1:
        return rec, excluded
    m = (rec.n // n) * n
    truth = None
    if rec.truth is not None:
        ch = {k: _blocks(v, n, m) for k, v in rec.truth.channels().items()}
        if "quat" in ch:
            q = ch["quat"]
            ch["quat"] = q / np.linalg.norm(q, axis=1, keepdims=True)
        core = {"omega": "omega_body_rad_s", "specific_force": "specific_force_body_m_s2", "quat": "quat_nb",
                "position": "position_nav_m"}
        truth = Truth(**{attr: ch.pop(h5) for h5, attr in core.items() if h5 in ch}, extra=ch)
    meta = dict(rec.meta)
    if "rate_hz" in meta:
        meta["rate_hz"] = float(meta["rate_hz"]) / n
    meta["decimated_by"] = n
    out = Recording(
        t_s=_blocks(rec.t_s, n, m),
        gyro_rad_s=_blocks(rec.gyro_rad_s, n, m),
        acc_m_s2=_blocks(rec.acc_m_s2, n, m),
        temp_c=_blocks(rec.temp_c, n, m),
        mag_ut=_blocks(rec.mag_ut, n, m),
        truth=truth,
        meta=meta,
    )
    mask = None if excluded is None else np.asarray(excluded, bool)[:m].reshape(-1, n).any(axis=1)
    return out, mask
