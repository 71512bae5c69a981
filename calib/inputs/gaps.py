"""Gaps in time (missing samples), told apart from timestamp jitter, and bridged when short.

Nominal step Δ = median Δt; timestamp jitter σ_Δ = 1.4826 · MAD(Δt) (robust: gaps are rare).  A
step is a gap when Δt > max(1.5 Δ, Δ + 6 σ_Δ): without jitter that is today's 1.5 Δ; with jitter
the bound follows it (±4 ms uniform jitter on a 10 ms clock gives steps of 2–18 ms, σ_Δ ≈ 3.5 ms, a
bound of 31 ms: no false gaps, as the differences of jitter stay within ±8 ms).  A gap misses
m = round(Δt/Δ) − 1 samples.

Bridging (``Requirements.max_bridged_gap_samples``, default 5): m samples are inserted at equal
steps and every channel (truth too) is interpolated linearly in time.  The inserted samples are not
measurements: their indices are kept in ``meta['input_repairs']['inserted']`` and the filter makes
no measurement update there (:func:`calib.inputs.check_recording` → ``excluded``).  For the gyro,
linear interpolation of the rate integrates to the trapezoidal rule over the gap, which is what the
strapdown step across it would use anyway.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gyrosim.recording import Recording, Truth

__all__ = ["Gaps", "find_gaps", "bridge_gaps", "gaps_warning"]


@dataclass(frozen=True)
class Gaps:
    """Gaps of a time axis: the step index k (gap between samples k and k+1) and samples missing."""

    index: np.ndarray
    missing: np.ndarray
    step_s: float
    jitter_s: float
    bound_s: float

    @property
    def count(self) -> int:
        return int(self.index.size)

    def describe(self, t: np.ndarray) -> str:
        k = int(self.index[0])
        dt = float(t[k + 1] - t[k])
        return (f"{self.count} gap(s) in time: the first from t = {t[k]:.4f} s to {t[k + 1]:.4f} s "
                f"({dt / self.step_s:.1f} × the {self.step_s * 1e3:.3f} ms step)")


def gaps_warning(gaps: "Gaps", t: np.ndarray) -> str:
    """The warning of a caller that integrates over the actual Δt and keeps the gaps (closeloop)."""
    dt = np.diff(t)
    return (f"{gaps.count} gap(s) in time up to {dt.max() * 1e3:.1f} ms ({dt.max() / gaps.step_s:.1f} × the "
            f"{gaps.step_s * 1e3:.3f} ms step), first at t = {t[int(gaps.index[0])]:.4f} s")


def find_gaps(t_s: np.ndarray) -> Gaps:
    """Gaps of ``t_s`` (strictly increasing), see the module docstring."""
    dt = np.diff(np.asarray(t_s, dtype=float))
    step = float(np.median(dt))
    jitter = 1.4826 * float(np.median(np.abs(dt - step)))
    bound = max(1.5 * step, step + 6.0 * jitter)
    idx = np.flatnonzero(dt > bound)
    missing = np.maximum(np.round(dt[idx] / step).astype(np.int64) - 1, 1)
    return Gaps(idx, missing, step, jitter, bound)


def _interp_rows(t_new: np.ndarray, t: np.ndarray, x: np.ndarray) -> np.ndarray:
    x = np.asarray(x, dtype=float)
    flat = x.reshape(x.shape[0], -1)
    out = np.stack([np.interp(t_new, t, flat[:, j]) for j in range(flat.shape[1])], axis=1)
    return out.reshape((t_new.size,) + x.shape[1:])


def bridge_gaps(rec: Recording, gaps: Gaps) -> tuple[Recording, np.ndarray]:
    """Insert the missing samples of ``gaps`` (linear in time); returns the recording and the
    mask of inserted samples (length of the new recording)."""
    t = np.asarray(rec.t_s)
    inserts = []
    for k, m in zip(gaps.index, gaps.missing):
        inserts.append(t[k] + (t[k + 1] - t[k]) * np.arange(1, m + 1) / (m + 1))
    t_new = np.sort(np.concatenate([t] + inserts))
    inserted = ~np.isin(t_new, t)

    def fill(x):
        return None if x is None else _interp_rows(t_new, t, x)

    truth = None
    if rec.truth is not None:
        ch = {}
        for name, arr in rec.truth.channels().items():
            v = _interp_rows(t_new, t, arr)
            if name == "quat":
                v = v / np.linalg.norm(v, axis=1, keepdims=True)
            ch[name] = v
        core = {"omega": "omega_body_rad_s", "specific_force": "specific_force_body_m_s2", "quat": "quat_nb",
                "position": "position_nav_m"}
        truth = Truth(**{attr: ch.pop(h5) for h5, attr in core.items() if h5 in ch}, extra=ch)
    new = Recording(t_s=t_new, gyro_rad_s=fill(rec.gyro_rad_s), acc_m_s2=fill(rec.acc_m_s2), temp_c=fill(rec.temp_c),
                    mag_ut=fill(rec.mag_ut), truth=truth, meta=rec.meta)
    return new, inserted
