"""A small IMU data generator that does NOT import gyrosim (nor calib): data from outside our
simulator for the calibrator (issue 4).  Kinematic, numpy only, written independently:

* body frame right-forward-up, navigation east-north-up, quaternion (w, x, y, z) body→nav;
* a rotation schedule of (axis, angle, duration) steps with a raised-cosine rate profile
  ω(t) = (A/T)(1 − cos 2πt/T) — a different profile from gyrosim's quintic, on purpose;
* attitude in closed form: each step turns about one fixed body axis by
  θ(t) = (A/T)(t − (T/2π) sin 2πt/T), so q(t) = q_start ⊗ (cos θ/2, sin θ/2 · axis);
* gyro = (I + S + N(G)) ω + b + white noise; accelerometer = Cᵀ (0, 0, g) + white noise;
* CSV in deg/s and g with the header t,gyro_x,gyro_y,gyro_z,acc_x,acc_y,acc_z.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

G = 9.80665

# rest, z vertical ±2π, tip x down, x vertical ±2π, back, y horizontal ±2π, x horizontal ±π, tip, z horizontal
STEPS = [
    ("rest", None, 0.0, 8.0),
    ("rot", 2, 2 * math.pi, 8.0), ("rot", 2, -2 * math.pi, 8.0),
    ("rot", 1, math.pi / 2, 6.0),
    ("rot", 0, 2 * math.pi, 8.0), ("rot", 0, -2 * math.pi, 8.0),
    ("rot", 1, -math.pi / 2, 6.0),
    ("rot", 1, 2 * math.pi, 8.0), ("rot", 1, -2 * math.pi, 8.0),
    ("rot", 0, math.pi, 6.0), ("rot", 0, -math.pi, 6.0),
    ("rot", 1, math.pi / 2, 6.0),
    ("rot", 2, 2 * math.pi, 8.0), ("rot", 2, -2 * math.pi, 8.0),
    ("rest", None, 0.0, 10.0),
]


def _qmul(p, q):
    w1, x1, y1, z1 = p
    w2, x2, y2, z2 = q
    return np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])


def _dcm(q):
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def generate(path: Path, *, rate_hz: float = 100.0, seed: int = 0, bias_deg_s=(1.5, -1.0, 0.8),
             scale=(0.03, -0.02, 0.04), nonortho=(0.015, -0.01, 0.02), gyro_noise_deg_s=0.05,
             acc_noise_g=0.001) -> dict:
    """Write a CSV and return the true parameters (bias in rad/s)."""
    rng = np.random.default_rng(seed)
    w_list, q_list = [], []
    q_start = np.array([1.0, 0.0, 0.0, 0.0])
    for kind, axis, angle, dur in STEPS:
        t = np.arange(int(round(dur * rate_hz))) / rate_hz
        w = np.zeros((t.size, 3))
        q = np.tile(q_start, (t.size, 1))
        if kind == "rot":
            w[:, axis] = angle / dur * (1 - np.cos(2 * np.pi * t / dur))
            theta = angle / dur * (t - dur / (2 * np.pi) * np.sin(2 * np.pi * t / dur))
            for k in range(t.size):
                half = np.zeros(4)
                half[0] = math.cos(theta[k] / 2)
                half[1 + axis] = math.sin(theta[k] / 2)
                q[k] = _qmul(q_start, half)
            end = np.zeros(4)
            end[0], end[1 + axis] = math.cos(angle / 2), math.sin(angle / 2)
            q_start = _qmul(q_start, end)
        w_list.append(w)
        q_list.append(q)
    omega_s, quat_s = np.concatenate(w_list), np.concatenate(q_list)
    n = omega_s.shape[0]
    gx, gy, gz = nonortho
    m = np.eye(3) + np.diag(scale) + np.array([[0, gz, gy], [gz, 0, gx], [gy, gx, 0]])
    bias = np.radians(np.asarray(bias_deg_s))
    gyro = omega_s @ m.T + bias + rng.normal(size=(n, 3)) * math.radians(gyro_noise_deg_s)
    acc = np.stack([_dcm(qq).T @ np.array([0.0, 0.0, G]) for qq in quat_s]) + rng.normal(size=(n, 3)) * acc_noise_g * G
    t = np.arange(n) / rate_hz
    with path.open("w", newline="") as fh:
        wr = csv.writer(fh)
        wr.writerow(["t", "gyro_x", "gyro_y", "gyro_z", "acc_x", "acc_y", "acc_z"])
        for k in range(n):
            wr.writerow([f"{t[k]:.6f}", *(f"{v:.9g}" for v in np.degrees(gyro[k])), *(f"{v:.9g}" for v in acc[k] / G)])
    return {"bias_rad_s": bias, "scale_factor": np.asarray(scale), "nonorthogonality": np.asarray(nonortho),
            "gyro_noise_rad_s": math.radians(gyro_noise_deg_s), "acc_noise_m_s2": acc_noise_g * G}
