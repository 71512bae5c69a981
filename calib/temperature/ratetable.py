"""Rate-table calibration at temperature points ("Measurement Error and Calibration of FOG IMU": tri-axis ±rate /
one-position).

For each calibration temperature (hold h) and gyro axis i, the faces that put axis i up (s = +1)
and down (s = −1) give steady windows at table rates +Ω, −Ω and 0 (one position).  The mean of
axis i over a window obeys

    m = (1 + S_i(T)) · s·Ω_table + b_i(T) + s·k_i + ε,      k_i = g-sensitivity along the axis × g,

so per (h, i) least squares on the six windows [s·Ω, 1, s] gives 1 + S_i, b_i and k_i, with the
rate from the table's encoder (``truth/table_rate``: the calibration's reference, not the gyro's
truth).  Full turns average out the horizontal Earth rate and any horizontal g-sensitivity; up
and down separate the vertical g-sensitivity from the bias (why the cube has six faces).

σ of each window mean from batch means (20 batches), propagated through the least squares:
what the noise allows.  :func:`piecewise_model` turns the points into the vocabulary's
``temperature_pwl`` (§4 of the same note: piecewise-linear interpolation between calibration points).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gyrosim import effects as E
from gyrosim.errors import RecordingError
from gyrosim.recording import Recording

__all__ = ["PointCalibration", "calibrate_rate_table", "piecewise_model"]

_UP = {"xup": (0, 1), "xdown": (0, -1), "yup": (1, 1), "ydown": (1, -1), "zup": (2, 1), "zdown": (2, -1)}


@dataclass(frozen=True)
class PointCalibration:
    """One calibration temperature: sensor temperature (°C), bias (rad/s), scale error S (1),
    vertical g-sensitivity term (rad/s), each per axis with 1σ."""

    ambient_c: float
    temp_c: np.ndarray
    bias_rad_s: np.ndarray
    bias_sigma: np.ndarray
    scale: np.ndarray
    scale_sigma: np.ndarray
    g_term_rad_s: np.ndarray


def _window_mean(x: np.ndarray) -> tuple[float, float]:
    batches = np.array_split(x, 20)
    means = np.array([b.mean() for b in batches])
    return float(x.mean()), float(means.std(ddof=1) / np.sqrt(len(batches)))


def calibrate_rate_table(rec: Recording) -> list[PointCalibration]:
    """Bias and scale per axis at every calibration temperature of a rate-table recording."""
    segs = rec.meta.get("segments")
    if not segs or rec.truth is None or "table_rate" not in rec.truth.extra:
        raise RecordingError("not a rate-table recording: needs meta['segments'] (face, phase, start, stop) and "
                             "truth/table_rate (gyrosim ratetable)")
    if rec.temp_c is None:
        raise RecordingError("the rate-table recording has no temperature channel")
    table = rec.truth.extra["table_rate"]
    out = []
    for h in sorted({s["hold"] for s in segs}):
        hs = [s for s in segs if s["hold"] == h]
        temps = np.concatenate([rec.temp_c[s["start"] : s["stop"]] for s in hs])
        b, sb, sc, ss, gk = (np.zeros(3) for _ in range(5))
        for i in range(3):
            rows, y, w = [], [], []
            for s in hs:
                axis, sign = _UP[s["face"]]
                if axis != i:
                    continue
                a, z = s["start"], s["stop"]
                m, sm = _window_mean(rec.gyro_rad_s[a:z, i])
                rows.append([sign * float(table[a:z].mean()), 1.0, sign])
                y.append(m)
                w.append(1.0 / sm)
            if len(rows) < 4:
                raise RecordingError(f"hold {h}: axis {'xyz'[i]} has {len(rows)} windows; needs up and down at ±rate")
            a_m = np.array(rows) * np.array(w)[:, None]
            theta, *_ = np.linalg.lstsq(a_m, np.array(y) * np.array(w), rcond=None)
            cov = np.linalg.inv(a_m.T @ a_m)
            sc[i], b[i], gk[i] = theta[0] - 1.0, theta[1], theta[2]
            ss[i], sb[i] = np.sqrt(cov[0, 0]), np.sqrt(cov[1, 1])
        out.append(PointCalibration(float(hs[0]["ambient_c"]), np.full(3, float(temps.mean())), b, sb, sc, ss, gk))
    return out


def piecewise_model(points: list[PointCalibration]) -> E.TemperaturePiecewise:
    """The compensation of ERICCO's *Measurement Error and Calibration of FOG IMU*: bias and scale interpolated
    linearly between the calibration points."""
    if len(points) < 2:
        raise RecordingError("piecewise-linear interpolation needs at least two calibration temperatures")
    order = np.argsort([p.temp_c.mean() for p in points])
    pts = [points[k] for k in order]
    return E.TemperaturePiecewise(points_c=np.array([p.temp_c.mean() for p in pts]),
                                  bias=np.stack([p.bias_rad_s for p in pts], axis=1),
                                  scale=np.stack([p.scale for p in pts], axis=1))
