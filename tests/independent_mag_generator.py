"""A 9-axis IMU data generator that imports nothing from gyrosim or calib: data from
outside our simulator for the magnetometer calibration.  numpy and h5py only, written
independently of gyrosim's scene, effects and writer:

* frames: body right-forward-up, navigation east-north-up; quaternions (w, x, y, z) body→nav;
* motion: a random tour of rests and turns — each turn about a random body axis by a random angle
  with a half-sine rate profile ω(t) = (πA/2T) sin(πt/T) (a different profile from gyrosim's
  quintic and from tests/independent_generator.py's raised cosine), rests of 1.5 s between;
  attitude integrated exactly per sample (the axis is fixed within a turn, so the increment is a
  rotation by the integrated angle);
* field: F (cos I sin D, cos I cos D, −sin I) in ENU; magnetometer m = S Rᵀ B_b + h + noise,
  S symmetric (soft iron), R the rotation of the sensor's axes (misalignment) — a product, not
  gyrosim's sum of effect terms;
* accelerometer Cᵀ(0, 0, g) + noise, gyro the exact body rate + noise (the attitude is smooth);
* written to HDF5 with h5py in the documented layout (/t, /gyro, /acc, /mag; attribute rate_hz).
"""

from __future__ import annotations

import math
from pathlib import Path

import h5py
import numpy as np

G = 9.80665


def _qmul(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    w1, x1, y1, z1 = p
    w2, x2, y2, z2 = q
    return np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])


def _dcm(q: np.ndarray) -> np.ndarray:
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def _rot(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rotation matrix about a unit axis (Rodrigues)."""
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k


def generate(path: Path, *, seed: int = 0, rate_hz: float = 100.0, turns: int = 24, field_ut: float = 50.0,
             inclination_deg: float = 60.0, declination_deg: float = 3.0, noise_ut: float = 0.4,
             acc_noise_m_s2: float = 0.02, gyro_noise_rad_s: float = 0.003) -> dict:
    """Write one session and return the truth: hard iron h (µT), A = S Rᵀ, misalignment θ (°,
    sensor axes = IMU axes rotated by θ), field and inclination."""
    rng = np.random.default_rng(seed)
    dt = 1.0 / rate_hz
    q = np.array([1.0, 0.0, 0.0, 0.0])
    quats, rates = [], []
    for _ in range(turns):
        for _ in range(int(1.5 * rate_hz)):  # rest
            quats.append(q.copy())
            rates.append(np.zeros(3))
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        ang = rng.uniform(0.6, 2.4) * rng.choice([-1.0, 1.0])
        dur = 1.0 + abs(ang)
        n = int(round(dur * rate_hz))
        for k in range(n):
            t = k * dt
            theta = ang / 2 * (1 - math.cos(math.pi * t / dur))  # ∫ (πA/2T) sin(πt/T) dt
            quats.append(_qmul(q, np.concatenate([[math.cos(theta / 2)], math.sin(theta / 2) * axis])))
            rates.append(axis * ang * math.pi / (2 * dur) * math.sin(math.pi * t / dur))
        q = _qmul(q, np.concatenate([[math.cos(ang / 2)], math.sin(ang / 2) * axis]))
    for _ in range(int(1.5 * rate_hz)):
        quats.append(q.copy())
        rates.append(np.zeros(3))
    quats, rates = np.array(quats), np.array(rates)
    nsamp = quats.shape[0]
    inc, dec = math.radians(inclination_deg), math.radians(declination_deg)
    b_n = field_ut * np.array([math.cos(inc) * math.sin(dec), math.cos(inc) * math.cos(dec), -math.sin(inc)])
    c = np.array([_dcm(qq) for qq in quats])  # body→nav
    b_b = np.einsum("nji,j->ni", c, b_n)  # Cᵀ B_n
    up_b = c[:, 2, :]  # Cᵀ (0, 0, 1)
    s = np.eye(3) + np.diag(rng.uniform(-0.04, 0.04, 3))
    off = rng.uniform(-0.02, 0.02, 3)
    s[0, 1] = s[1, 0] = off[0]
    s[0, 2] = s[2, 0] = off[1]
    s[1, 2] = s[2, 1] = off[2]
    mis_axis = rng.normal(size=3)
    mis_axis /= np.linalg.norm(mis_axis)
    mis_angle = math.radians(rng.uniform(0.5, 2.0))
    r = _rot(mis_axis, mis_angle)
    a = s @ r.T
    h = rng.uniform(-80, 80, 3)
    mag = b_b @ a.T + h + rng.normal(size=(nsamp, 3)) * noise_ut
    acc = G * up_b + rng.normal(size=(nsamp, 3)) * acc_noise_m_s2
    gyro = rates + rng.normal(size=(nsamp, 3)) * gyro_noise_rad_s
    t = np.arange(nsamp) * dt
    with h5py.File(path, "w") as f:
        f["t"] = t
        f["gyro"] = gyro
        f["acc"] = acc
        f["mag"] = mag
        f.attrs["rate_hz"] = rate_hz
        f.attrs["source"] = "tests/independent_mag_generator.py"
    return {"hard_iron_uT": h, "soft_iron": a, "misalignment_deg": np.degrees(mis_axis * mis_angle),
            "field_uT": field_ut, "inclination_deg": inclination_deg, "noise_uT": noise_ut}
