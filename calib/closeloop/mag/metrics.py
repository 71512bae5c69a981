"""Held-out error metrics of a magnetometer model, and the local disturbances its residual shows.

Metrics (mean squares per held-out stretch, compared by :func:`calib.closeloop.metrics.compare_metrics`:
Wilcoxon signed rank over the stretches, family-wise 1 %), with m_c = R(θ) A⁻¹ (m − h) the
corrected field (IMU axes) and B_n the fitted ENU field:

``held_out_field_residual_rms`` (µT)
    Reference: the model's residual rows.  Weighs everything the model predicts.
``held_out_field_magnitude_rms`` (µT)
    Reference: |m_c| − |B| (attitude ref.).  Weighs hard and soft iron; blind to the misalignment.
``held_out_heading_rms_deg`` (°)
    Reference: heading of C_kᵀ m_c against that of B_n.  Weighs what a compass shows: hard/soft iron
    and the rotation about up.
``held_out_inclination_rms_deg`` (°)
    Reference: angle of m_c to the reference up against B_n's.  Weighs tilt of the axes:
    misalignment, soft iron.

On a magnitude reference only the first exists (it is the magnitude residual).

Disturbances: :func:`calib.mag.disturbance.find_disturbances` on |m_c| − F and the inclination
deviation (window means and spreads leaving the session's typical values by 6 robust σ): a field
that changes with where the board is, which no sensor term explains.  The loop excludes those
samples from every fit and reports them as unexplained structure (never absorbed).
"""

from __future__ import annotations

import math

import numpy as np

from gyrosim.units import RAD2DEG

from calib.closeloop.mag.fit import MagFit, corrected_field, split_theta
from calib.closeloop.mag.reference import MagReference
from calib.closeloop.metrics import MetricSums
from calib.mag.disturbance import find_disturbances
from calib.mag.result import Disturbance

__all__ = ["field_deviations", "mag_metrics", "detect_disturbances"]


def field_deviations(ref: MagReference, fit: MagFit) -> dict[str, np.ndarray]:
    """Per-sample deviations of the corrected field from the fitted reference field (NaN where not valid)."""
    mc = corrected_field(ref, fit.kinds, fit.theta)
    base = split_theta(ref, fit.kinds, fit.theta)["base"]
    mag = np.linalg.norm(mc, axis=1)
    out = {"residual_sq": np.sum(fit.residual**2, axis=1) / fit.residual.shape[1]}
    if not ref.has_attitude:
        out["field_dev_ut"] = mag - base[0]
        return {k: np.where(ref.valid, v, np.nan) for k, v in out.items()}
    fmag = float(np.linalg.norm(base))
    up = ref.up_body
    incl = np.arcsin(np.clip(np.sum(up * mc, axis=1) / mag, -1, 1))
    incl0 = math.asin(float(np.clip(base[2] / fmag, -1, 1)))
    mn = np.einsum("kji,kj->ki", ref.c_bn, mc)                     # corrected field in ENU
    head = np.arctan2(mn[:, 0], mn[:, 1]) - math.atan2(base[0], base[1])
    out.update(field_dev_ut=mag - fmag, incl_dev_deg=(incl - incl0) * RAD2DEG,
               heading_dev_deg=np.angle(np.exp(1j * head)) * RAD2DEG)
    return {k: np.where(ref.valid, v, np.nan) for k, v in out.items()}


_DEFS = (
    ("held_out_field_residual_rms", "residual_sq", "µT", "the model's residual rows", "everything the model predicts"),
    (
        "held_out_field_magnitude_rms",
        "field_dev_ut",
        "µT",
        "|corrected field| − |B_n|",
        "hard and soft iron; blind to the misalignment",
    ),
    (
        "held_out_heading_rms_deg",
        "heading_dev_deg",
        "°",
        "the reference attitude's heading of the field",
        "what a compass shows: hard/soft iron and the axes' rotation about up",
    ),
    (
        "held_out_inclination_rms_deg",
        "incl_dev_deg",
        "°",
        "the reference attitude's up direction",
        "the tilt of the axes: misalignment and soft iron",
    ),
)


def mag_metrics(ref: MagReference, fit: MagFit, exclude: np.ndarray) -> dict[str, MetricSums]:
    """Every metric of the module docstring on the held-out stretches minus ``exclude`` (the same
    ``exclude`` for two models keeps their stretches paired)."""
    dev = field_deviations(ref, fit)
    keep = ref.rows(held=True, exclude=exclude)
    out = {}
    for name, key, unit, against, weighs in _DEFS:
        if key not in dev or (key == "field_dev_ut" and not ref.has_attitude):
            continue
        v = dev[key]
        sq = v if key == "residual_sq" else v**2
        ok = keep & np.isfinite(sq)
        if ok.sum() == 0:
            continue
        uniq, inv = np.unique(ref.groups[keep], return_inverse=True)
        ss = np.bincount(inv, np.where(ok[keep], sq[keep], 0.0), minlength=uniq.size)
        n = np.bincount(inv, ok[keep].astype(float), minlength=uniq.size)
        out[name] = MetricSums(name, unit, against, weighs, ss, n)
    return out


def detect_disturbances(ref: MagReference, fit: MagFit) -> tuple[np.ndarray, tuple[Disturbance, ...]]:
    """(per-sample mask, disturbances) of the model's residual (module docstring)."""
    dev = field_deviations(ref, fit)
    return find_disturbances(ref.t_s, np.nan_to_num(dev["field_dev_ut"]), dev.get("incl_dev_deg"), ref.valid,
                             position_nav_m=ref.position_nav_m)
