"""imucal's Ferraris calibration of its own example session, in our parameters (for :mod:`calib.scoring.measured`).

imucal (Küderle et al., mad-lab-fau/imucal; MIT) ships a NilsPod session recorded with the Ferraris protocol
(six static poses, three 360° turns) and its section list.  ``FerrarisCalibration(grav=9.80665)`` on that
file gives, per triad, a general 3×3 matrix K R and a bias; ours is symmetric in the accelerometer's frame
(I + diag(S) + N(G)), so imucal's accelerometer matrix is split A = P U (polar decomposition): P is
comparable with our accelerometer matrix, U turns imucal's frame into ours, and imucal's gyro matrix in
our frame, K_g R_g Uᵀ, has a symmetric part (comparable with ours) and an antisymmetric part — a rotation
of the gyro triad against the accelerometer's, which our model does not have (reported, not compared).
imucal's g-sensitivity K_ga is not compared.  imucal is the optional ``peers`` extra; without it the
comparison is reported as not run.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy.linalg import polar

from gyrosim.units import G0  # the gravity imucal is given (and calib run assumes by default), m/s²

__all__ = ["ImucalResult", "imucal_ferraris"]

RATE_HZ = 102.4    # the NilsPod session's rate (imucal's example)


@dataclass(frozen=True)
class ImucalResult:
    """imucal's calibration in our parameters (rad/s, m/s², fractions; body frame RFU of the accelerometer),
    the gyro triad's rotation against the accelerometer's (° about x, y, z) and the session's signals as
    imucal calibrates them (``gyro_rad_s``, ``acc_m_s2``, in imucal's frame: the figures scored on them —
    magnitudes, angles — do not depend on the frame)."""

    version: str
    parameters: dict[str, list[float]]
    gyro_rotation_deg: list[float]
    gyro_rad_s: np.ndarray
    acc_m_s2: np.ndarray

    def to_dict(self) -> dict[str, Any]:
        return {"version": self.version, "parameters": self.parameters, "gyro_rotation_deg": self.gyro_rotation_deg}


def _sym_parts(m: np.ndarray) -> tuple[list[float], list[float]]:
    """S (diagonal − 1) and G (N(G)'s off-diagonals: [1,2], [0,2], [0,1]) of a symmetric matrix."""
    return (np.diag(m) - 1.0).tolist(), [float(m[1, 2]), float(m[0, 2]), float(m[0, 1])]


def imucal_ferraris(folder: Path) -> ImucalResult | str:
    """imucal's ``FerrarisCalibration`` of the session in ``folder`` (the section list beside it); a sentence
    saying why not when imucal (the ``peers`` extra) is not installed."""
    try:
        import pandas as pd
        from imucal import FerrarisCalibration, ferraris_regions_from_section_list
        from imucal import __version__ as version
    except ImportError:
        return "imucal is not installed (pip install 'gyrosim-calib[peers]'): its result is not shown"
    df = pd.read_csv(folder / "example_ferraris_session.csv")
    sections = pd.DataFrame(json.loads((folder / "example_ferraris_session_list.json").read_text())).T
    info = FerrarisCalibration(grav=G0).compute(ferraris_regions_from_section_list(df, sections), RATE_HZ,
                                                     "m/s^2", "deg/s")
    u, p = polar(info.K_a @ info.R_a, side="left")  # A = P U (scipy returns the rotation first, whatever the side)
    g_ours = info.K_g @ info.R_g @ u.T
    sym, anti = 0.5 * (g_ours + g_ours.T), 0.5 * (g_ours - g_ours.T)
    gs, gg = _sym_parts(sym)
    acs, acg = _sym_parts(p)
    params = {"gyro_bias_rad_s": np.radians(np.asarray(info.b_g, float)).tolist(), "gyro_scale_factor": gs,
              "gyro_nonorthogonality": gg, "acc_bias_m_s2": np.asarray(info.b_a, float).tolist(),
              "acc_scale_factor": acs, "acc_nonorthogonality": acg}
    rot = [math.degrees(anti[2, 1]), math.degrees(anti[0, 2]), math.degrees(anti[1, 0])]
    acc, gyr = info.calibrate(acc=df[["acc_x", "acc_y", "acc_z"]].to_numpy(float),
                              gyr=df[["gyr_x", "gyr_y", "gyr_z"]].to_numpy(float), acc_unit="m/s^2", gyr_unit="deg/s")
    return ImucalResult(str(version), params, rot, np.radians(np.asarray(gyr, float)), np.asarray(acc, float))
