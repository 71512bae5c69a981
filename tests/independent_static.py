"""Static-test data written without gyrosim or calib (numpy only), for the static instruments (tilt, north-finding):

* a north-finding record: a level board turned about the vertical between P positions, the
  Earth's rotation computed here in ENU, Ω = 7.292115e-5 rad/s, ω_ie = Ω (0, cos L, sin L); the
  turns run at a constant rate (a trapezoid-free profile, unlike gyrosim's servo);
* a tilt-sensor record: a board tilted about its x or y axis in steps, its accelerometer
  a = (I + S + M) f + k f|f| + b + noise, with a hold table as a CSV.

Frames as everywhere: body right-forward-up, navigation east-north-up.  CSV in deg/s and g.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

OMEGA = 7.292115e-5
G = 9.80665


def _rz(a: float) -> np.ndarray:
    """Body → ENU for a level board whose forward axis has azimuth a (clockwise from North)."""
    c, s = math.cos(a), math.sin(a)
    # forward (body y) = (sin a, cos a, 0) in ENU, right (body x) = (cos a, −sin a, 0)
    return np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])


def _rx(t: float) -> np.ndarray:
    c, s = math.cos(t), math.sin(t)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _ry(t: float) -> np.ndarray:
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _write(path: Path, t, gyro_rad_s, acc_m_s2) -> None:
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["t", "gyro_x", "gyro_y", "gyro_z", "acc_x", "acc_y", "acc_z"])
        for k in range(t.size):
            w.writerow(
                [
                    f"{t[k]:.4f}",
                    *(f"{v:.10g}" for v in np.degrees(gyro_rad_s[k])),
                    *(f"{v:.10g}" for v in acc_m_s2[k] / G),
                ]
            )


def northfind_csv(path: Path, *, latitude_deg: float, heading_deg: float, positions: int = 4, hold_s: float = 120.0,
                  turn_s: float = 9.0, rate_hz: float = 10.0, bias_deg_h=(3.0, -2.0, 1.0), arw_deg_rt_h: float = 0.01,
                  seed: int = 0) -> dict:
    """Write the CSV; return the truth (headings of the forward axis per position, °)."""
    rng = np.random.default_rng(seed)
    lat = math.radians(latitude_deg)
    w_n = OMEGA * np.array([0.0, math.cos(lat), math.sin(lat)])
    step = 2 * math.pi / positions
    rows_w, rows_f, heads = [], [], []
    n_hold, n_turn = int(hold_s * rate_hz), int(turn_s * rate_hz)
    for k in range(positions):
        a = math.radians(heading_deg) + k * step
        heads.append(math.degrees(a) % 360)
        c = _rz(a)
        rows_w.append(np.tile(c.T @ w_n, (n_hold, 1)))
        rows_f.append(np.tile(c.T @ np.array([0, 0, G]), (n_hold, 1)))
        if k < positions - 1:
            rate = -step / turn_s          # heading grows: clockwise seen from above = −z body rate
            ang = a + (np.arange(n_turn) + 0.5) / rate_hz * (-rate)
            rows_w.append(np.array([_rz(x).T @ w_n + np.array([0, 0, rate]) for x in ang]))
            rows_f.append(np.tile([0.0, 0.0, G], (n_turn, 1)))
    w = np.concatenate(rows_w)
    f = np.concatenate(rows_f)
    n = w.shape[0]
    sd = math.radians(arw_deg_rt_h) / 60 * math.sqrt(rate_hz)
    gyro = w + np.radians(np.asarray(bias_deg_h)) / 3600 + rng.normal(size=(n, 3)) * sd
    acc = f + np.array([0.003, -0.002, 0.001]) + rng.normal(size=(n, 3)) * 5e-4
    _write(path, np.arange(n) / rate_hz, gyro, acc)
    return {"headings_deg": heads, "arw_rad_rt_s": math.radians(arw_deg_rt_h) / 60}


def tilt_csv(
    path: Path,
    holds_path: Path,
    *,
    angles_deg=tuple(np.arange(-15, 15.01, 2.5)),
    hold_s: float = 20.0,
    rate_hz: float = 10.0,
    scale=(0.004, -0.003, 0.0),
    misalign=((0, 0.01, 0.004), (-0.006, 0, 0.008), (0, 0, 0)),
    bias_g=(0.002, -0.001, 0.0),
    k_per_g: float = 0.03,
    noise_ug_rt_hz: float = 30.0,
    seed: int = 0,
) -> dict:
    """Write the accelerometer CSV (gyro columns 0) and the holds CSV; return the truth."""
    rng = np.random.default_rng(seed)
    m = np.eye(3) + np.diag(scale) + np.asarray(misalign)
    plan = []                                          # (sweep, kind, angle)
    for sweep in ("x", "y"):
        plan += [(sweep, "step", float(a)) for a in angles_deg] + [(sweep, "flip", 180.0)]
    rows, holds, t0 = [], [], 0.0
    n = int(hold_s * rate_hz)
    for sweep, kind, a in plan:
        r = _ry(-math.radians(a)) if sweep == "x" else _rx(math.radians(a))
        f = r.T @ np.array([0, 0, G])
        y = m @ f + (k_per_g / G) * f * np.abs(f) + np.asarray(bias_g) * G
        rows.append(np.tile(y, (n, 1)) + rng.normal(size=(n, 3)) * noise_ug_rt_hz * 1e-6 * G * math.sqrt(rate_hz))
        holds.append((sweep, kind, a, t0 + 1.0, t0 + hold_s - 1.0))   # the operator's log, a second in from each end
        t0 += hold_s
    acc = np.concatenate(rows)
    t = np.arange(acc.shape[0]) / rate_hz
    _write(path, t, np.zeros_like(acc), acc)
    with holds_path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["sweep", "kind", "angle_deg", "t_start_s", "t_stop_s"])
        for h in holds:
            w.writerow(h)
    return {"matrix": m, "bias_g": np.asarray(bias_g), "k_per_g": k_per_g}
