"""The reference the magnetometer part of the loop fits against, and its held-out split.

* ``attitude`` — the recording carries a reference attitude q_nb (a simulation's truth, BROAD's
  optical orientation): the field is constant in the navigation frame (ENU), so each sample has a
  vector residual r_k = m_k − m̂_k with m̂_k = A R(θ)ᵀ C_k B_n + h (C_k = C(q_k)ᵀ, body←ENU; B_n
  estimated).  Hard iron, soft iron and the magnetometer-to-IMU misalignment are all visible.
* ``magnitude`` — no attitude reference: only the field magnitude is constant,
  r_k = |A⁻¹(m_k − h)| − F (the ellipsoid fit's residual, :mod:`calib.mag.ellipsoid`).  The
  misalignment is invisible there (|m| does not change when the axes rotate).

The magnetometer channel is checked by :func:`calib.mag.checks.prepare_magnetometer` (unit
refused with the unit to pass; saturated samples excluded and counted).  Held-out split: the time
axis cut into stretches of ``holdout_s`` (4 s, as the gyro loop), even stretches fitted, odd ones
held out.  σ_w, the white-noise level of one field component, comes from second differences
(:func:`calib.mag.ellipsoid.white_noise_variance`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gyrosim.recording import Recording
from gyrosim.rotations import quat_to_matrix

from calib.mag.checks import prepare_magnetometer
from calib.mag.ellipsoid import white_noise_variance

__all__ = ["MagReference", "build_mag_reference"]


@dataclass(frozen=True, eq=False)
class MagReference:
    """What the magnetometer loop fits against: the measured field (µT, body frame), the reference
    attitude C_k (body←ENU) when there is one, the usable samples, the held-out stretches and the
    white-noise level σ_w (module docstring)."""

    kind: str                           # "attitude" or "magnitude"
    source: str                         # where the attitude comes from ("truth", "optical", "none")
    description: str
    t_s: np.ndarray
    mag_ut: np.ndarray                  # (N, 3) measured, body frame
    c_bn: np.ndarray | None             # (N, 3, 3) body←ENU (NaN where the reference has no attitude)
    valid: np.ndarray                   # (N,) usable: finite, unsaturated, with an attitude where needed
    groups: np.ndarray                  # (N,) held-out stretch index
    noise_ut: float                     # σ_w per component (µT)
    position_nav_m: np.ndarray | None
    saturated: int
    warnings: tuple[str, ...]

    @property
    def has_attitude(self) -> bool:
        return self.kind == "attitude"

    def rows(self, held: bool, exclude: np.ndarray | None = None) -> np.ndarray:
        """Samples of the fit (``held`` False) or held-out stretches, minus ``exclude``."""
        sel = self.valid & ((self.groups % 2 == 1) if held else (self.groups % 2 == 0))
        return sel if exclude is None else sel & ~exclude

    @property
    def up_body(self) -> np.ndarray | None:
        """(N, 3) the ENU up direction in the body frame."""
        return None if self.c_bn is None else self.c_bn[:, :, 2]


def build_mag_reference(rec: Recording, holdout_s: float = 4.0, prefer: str | None = None) -> MagReference:
    """The magnetometer reference of ``rec`` (attitude when it has one, else magnitude); raises
    :class:`gyrosim.errors.RecordingError` for a channel in the wrong unit or with too few samples."""
    inp = prepare_magnetometer(rec)
    m = inp.mag_ut
    t = np.asarray(rec.t_s, float)
    tr = rec.truth
    c_bn = None
    source = "none"
    valid = inp.valid & np.all(np.isfinite(m), axis=1)
    if tr is not None and tr.quat_nb is not None and prefer != "magnitude":
        q = np.asarray(tr.quat_nb, float)
        ok = np.all(np.isfinite(q), axis=1)
        if ok.sum() >= 0.5 * t.size:
            c = np.full((t.size, 3, 3), np.nan)
            c[ok] = np.swapaxes(quat_to_matrix(q[ok] / np.linalg.norm(q[ok], axis=1, keepdims=True)), -1, -2)
            c_bn = c
            valid = valid & ok
            source = "truth" if tr.omega_body_rad_s is not None else "optical"
    if prefer == "attitude" and c_bn is None:
        from gyrosim.errors import RecordingError
        raise RecordingError("--mag-reference attitude: the recording has no reference attitude (truth/optical quat)")
    groups = np.floor((t - t[0]) / holdout_s).astype(int)
    noise = math.sqrt(max(white_noise_variance(m[valid]), 1e-12))
    pos = None if tr is None or tr.position_nav_m is None else np.asarray(tr.position_nav_m, float)
    if c_bn is not None:
        desc = (f"the {source} attitude: the field is constant in ENU (B_n estimated), so every sample's field vector "
                f"is predicted: residual m − A R(θ)ᵀ C B_n − h (µT), {int(valid.sum())} samples")
        kind = "attitude"
    else:
        desc = (f"no attitude reference: the field magnitude is constant, residual |A⁻¹(m − h)| − F (µT), "
                f"{int(valid.sum())} samples; the magnetometer-to-IMU misalignment cannot be seen")
        kind = "magnitude"
    return MagReference(kind, source, desc, t, m, c_bn, valid, groups, noise, pos, inp.saturated_samples,
                        inp.warnings)
