"""A small IMU data generator that does NOT import gyrosim (nor calib): data from outside our
simulator for the calibrator.  Kinematic, numpy only, written independently:

* body frame right-forward-up, navigation east-north-up, quaternion (w, x, y, z) body→nav;
* a rotation schedule of (kind, axis, angle, duration) steps with a raised-cosine rate profile
  ω(t) = (A/T)(1 − cos 2πt/T) — a different profile from gyrosim's quintic, on purpose;
* attitude in closed form: each step turns about one fixed body axis by
  θ(t) = (A/T)(t − (T/2π) sin 2πt/T), so q(t) = q_start ⊗ (cos θ/2, sin θ/2 · axis);
* gyro = (I + S + N(G) − [α×]) ω + b + white noise (α: the gyro triad's rotation against the
  accelerometer's, zero unless given);
  accelerometer = (I + S_a + N(G_a)) Cᵀ (0, 0, g) + b_a + white noise (a raw accelerometer when
  S_a, G_a, b_a are given; N(G) = [[0, Gz, Gy], [Gz, 0, Gx], [Gy, Gx, 0]] for both triads);
* noise-free when both noise levels are 0 (the CSV then carries 9 significant digits);
* optionally an imperfect hand: a lever arm from the rotation centre (closed-form ω̇) and tremor / sway
  as band-limited sums of sines in nav (an imperfect hand);
* CSV in deg/s and g with the header t,gyro_x,gyro_y,gyro_z,acc_x,acc_y,acc_z.

Schedules: ``STEPS`` (Zhou 2020 Table 6-like: vertical and horizontal turns, two rest poses) and
``MULTIPOSE_STEPS`` (the same turns plus rests at the six faces and six 45° poses, as a Ferraris /
Tedaldi multi-position session would hold).
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

_Q = math.pi / 2
# the turns of STEPS, then 3-s rests in turn at: x down, z up, x down, z down, x up, z up, y up, y down,
# z up, y and z up at 45°, x and z up at 45°, x and y at 45°, back level
MULTIPOSE_STEPS = STEPS[:-1] + [
    ("rest", None, 0.0, 3.0),                                   # z horizontal (x down) after the last tip
    ("rot", 1, -_Q, 5.0), ("rest", None, 0.0, 3.0),             # level: z up
    ("rot", 1, _Q, 5.0), ("rest", None, 0.0, 3.0),              # x down
    ("rot", 1, _Q, 5.0), ("rest", None, 0.0, 3.0),              # z down
    ("rot", 1, _Q, 5.0), ("rest", None, 0.0, 3.0),              # x up
    ("rot", 1, _Q, 5.0), ("rest", None, 0.0, 3.0),              # z up
    ("rot", 0, _Q, 5.0), ("rest", None, 0.0, 3.0),              # y up
    ("rot", 0, 2 * _Q, 6.0), ("rest", None, 0.0, 3.0),          # y down
    ("rot", 0, _Q, 5.0), ("rest", None, 0.0, 3.0),              # z up
    ("rot", 0, _Q / 2, 4.0), ("rest", None, 0.0, 3.0),          # y and z up at 45°
    ("rot", 0, -_Q / 2, 4.0), ("rot", 1, -_Q / 2, 4.0), ("rest", None, 0.0, 3.0),  # x and z up at 45°
    ("rot", 1, -_Q / 2, 4.0), ("rot", 2, _Q / 2, 4.0), ("rest", None, 0.0, 3.0),   # x and y at 45° (z level)
    ("rot", 2, -_Q / 2, 4.0), ("rot", 1, _Q, 5.0),
    ("rest", None, 0.0, 8.0),                                   # level again
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


def _m(scale, nonortho):
    gx, gy, gz = nonortho
    return np.eye(3) + np.diag(scale) + np.array([[0, gz, gy], [gz, 0, gx], [gy, gx, 0]])


def kinematics(rate_hz: float = 100.0, steps=STEPS, q0=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t (N,), body rate (N, 3) rad/s, quaternion body→nav (N, 4)) of a schedule, closed form;
    ``q0`` the starting attitude (default level, heading east)."""
    w_list, q_list = [], []
    q_start = np.array([1.0, 0.0, 0.0, 0.0]) if q0 is None else np.asarray(q0, float) / np.linalg.norm(q0)
    for kind, axis, angle, dur in steps:
        t = np.arange(int(round(dur * rate_hz))) / rate_hz
        w = np.zeros((t.size, 3))
        q = np.tile(q_start, (t.size, 1))
        if kind == "rot":
            w[:, axis] = angle / dur * (1 - np.cos(2 * np.pi * t / dur))
            theta = angle / dur * (t - dur / (2 * np.pi) * np.sin(2 * np.pi * t / dur))
            half = np.zeros((t.size, 4))
            half[:, 0] = np.cos(theta / 2)
            half[:, 1 + axis] = np.sin(theta / 2)
            q = np.stack([_qmul(q_start, h) for h in half])
            end = np.zeros(4)
            end[0], end[1 + axis] = math.cos(angle / 2), math.sin(angle / 2)
            q_start = _qmul(q_start, end)
        w_list.append(w)
        q_list.append(q)
    omega, quat = np.concatenate(w_list), np.concatenate(q_list)
    return np.arange(omega.shape[0]) / rate_hz, omega, quat


def held_rate(rate_hz: float = 100.0, steps=STEPS) -> np.ndarray:
    """(N, 3) rad/s: each sample the mean body rate over its own step [t_k, t_k + Δt] — what a gyro that integrates
    over the sample interval outputs (an angle increment divided by Δt), so that holding sample k constant over
    the step turns the attitude exactly to sample k + 1's.  Closed form: each schedule step turns about one fixed
    body axis, so the mean rate is (θ(t + Δt) − θ(t))/Δt with θ of :func:`kinematics`.  It represents the rate at
    t_k + Δt/2: against accelerometer samples taken at t_k the gyro leads by half a sample."""
    out = []
    dt = 1.0 / rate_hz
    for kind, axis, angle, dur in steps:
        t = np.arange(int(round(dur * rate_hz))) / rate_hz
        w = np.zeros((t.size, 3))
        if kind == "rot":
            def theta(x):
                return angle / dur * (x - dur / (2 * np.pi) * np.sin(2 * np.pi * x / dur))
            w[:, axis] = (theta(np.minimum(t + dt, dur)) - theta(t)) / dt
        out.append(w)
    return np.concatenate(out)


def angular_acceleration(rate_hz: float = 100.0, steps=STEPS) -> np.ndarray:
    """ω̇ (N, 3) rad/s² of a schedule in closed form: d/dt of (A/T)(1 − cos 2πt/T) = (2πA/T²) sin 2πt/T."""
    out = []
    for kind, axis, angle, dur in steps:
        t = np.arange(int(round(dur * rate_hz))) / rate_hz
        a = np.zeros((t.size, 3))
        if kind == "rot":
            a[:, axis] = 2 * np.pi * angle / dur**2 * np.sin(2 * np.pi * t / dur)
        out.append(a)
    return np.concatenate(out)


def sum_of_sines(rng: np.random.Generator, t: np.ndarray, band_hz: tuple[float, float], rms: float,
                 components: int = 40) -> np.ndarray:
    """(N, 3) random acceleration with E|a|² = rms² over ``band_hz``: per axis a sum of ``components``
    sinusoids of uniform random frequency in the band and random phase, each of amplitude
    √(2 rms² / (3 J)) (J sinusoids of amplitude A have variance J A²/2).  Not gyrosim's frequency-domain
    synthesis: a different construction of band-limited motion, on purpose."""
    amp = math.sqrt(2.0 * rms**2 / (3.0 * components))
    out = np.zeros((t.size, 3))
    for i in range(3):
        f = rng.uniform(band_hz[0], band_hz[1], components)
        ph = rng.uniform(0.0, 2 * np.pi, components)
        out[:, i] = amp * np.sin(2 * np.pi * np.outer(t, f) + ph).sum(axis=1)
    return out


def attitude_wobble(
    rng: np.random.Generator, t: np.ndarray, bands, components: int = 30
) -> tuple[np.ndarray, np.ndarray]:
    """A hand's rotational tremor / sway as a small body-frame rotation vector φ(t) (N, 3) rad and its
    derivative φ̇ (closed form): per (f_lo, f_hi, rms_rad) band and axis a sum of ``components`` sines of
    uniform random frequency and phase with E|φ|² = rms² (as :func:`sum_of_sines`, in angle)."""
    phi, dphi = np.zeros((t.size, 3)), np.zeros((t.size, 3))
    for lo, hi, rms in bands:
        amp = math.sqrt(2.0 * rms**2 / (3.0 * components))
        for i in range(3):
            f = rng.uniform(lo, hi, components)
            ph = rng.uniform(0.0, 2 * np.pi, components)
            arg = 2 * np.pi * np.outer(t, f) + ph
            phi[:, i] += amp * np.sin(arg).sum(axis=1)
            dphi[:, i] += amp * (2 * np.pi * f * np.cos(arg)).sum(axis=1)
    return phi, dphi


def generate_arrays(
    *,
    rate_hz: float = 100.0,
    seed: int = 0,
    steps=STEPS,
    bias_deg_s=(1.5, -1.0, 0.8),
    scale=(0.03, -0.02, 0.04),
    nonortho=(0.015, -0.01, 0.02),
    gyro_noise_deg_s=0.05,
    acc_noise_g=0.001,
    acc_bias_g=(0.0, 0.0, 0.0),
    acc_scale=(0.0, 0.0, 0.0),
    acc_nonortho=(0.0, 0.0, 0.0),
    kin=None,
    g_sensitivity=None,
    delay_s: float = 0.0,
    field_enu_ut=None,
    mag_noise_ut: float = 0.0,
    lever_arm_m=None,
    tremor_acc_rms_m_s2: float = 0.0,
    tremor_band_hz=(8.0, 12.0),
    sway_acc_rms_m_s2: float = 0.0,
    sway_band_hz=(0.2, 1.0),
    bias_walk_rad_s_sqrt_s: float = 0.0,
    bias_ramp_rad_s2=(0.0, 0.0, 0.0),
    bias_flicker_rad_s: float = 0.0,
    scale_nonlinearity_per_rad_s=(0.0, 0.0, 0.0),
    temperature_c=None,
    scale_per_c=(0.0, 0.0, 0.0),
    acc_bias_per_c=(0.0, 0.0, 0.0),
    gyro_bias_per_c=(0.0, 0.0, 0.0),
    wobble_bands=(),
    output_lowpass_hz: float | None = None,
    output_lowpass_order: int = 2,
    gyro_rotation_rad=(0.0, 0.0, 0.0),
    gyro_held: bool = False,
) -> dict:
    """Samples (SI) and the true parameters; ``kin`` = a precomputed :func:`kinematics` (reused across seeds).

    ``g_sensitivity``: 3×3 (rad/s)/(m/s²), gyro += K f with f the true specific force (gravity);
    ``delay_s``: the gyro output at t is its noise-free value at t − d (linear interpolation; the
    first samples hold the first value);
    ``field_enu_ut``: a constant field (µT, ENU) seen by an ideal magnetometer, m = Cᵀ B + noise
    (``mag_ut`` in the result).

    An imperfect hand, its own way: ``lever_arm_m`` r (body, m, from the rotation centre to
    the accelerometer) adds ω̇ × r + ω × (ω × r) with the closed-form ω̇ of :func:`angular_acceleration`;
    ``tremor_acc_rms_m_s2`` / ``sway_acc_rms_m_s2`` add a translation of the hand in nav, band-limited
    sums of sines (:func:`sum_of_sines`), seen in the body as Cᵀ a.

    A drifting gyro bias (a consumer gyro warming up): ``bias_ramp_rad_s2`` adds a linear trend per axis
    and ``bias_walk_rad_s_sqrt_s`` K a random walk (Euler sum of N(0, K² Δt) steps per sample, its own
    random stream); ``bias_flicker_rad_s`` B a bias-instability (1/f) floor, two-sided PSD B²/(2πf) (IEEE Std 952's
    convention; Kasdin–Walter, :func:`independent_noise.flicker`, its own stream), as a warmed-up MEMS gyro drifts;
    ``bias_rad_s`` in the result stays the bias at t = 0, ``bias_path_rad_s`` the whole path.

    A gyro whose scale is not linear: ``scale_nonlinearity_per_rad_s`` k (3,) adds k_i ω_i|ω_i| per axis to the
    true rate's response (odd-symmetric; ``scale_factor`` in the result stays the slope at 0 rad/s).

    A warming sensor: ``temperature_c`` (N,) the sensor temperature (°C, recorded in ``temp_c``) and
    ``scale_per_c`` (3,) the scale factor's temperature coefficient (1/°C): the gyro's scale is
    S + scale_per_c (T − T[0]) sample by sample (``scale_factor`` in the result is S at T[0]), applied as
    ω_i (1 + ΔS_i(t)) on top of M ω; ``acc_bias_per_c`` (3,) the accelerometer bias's temperature coefficient
    (m/s²/°C): the accelerometer reads its bias plus acc_bias_per_c (T − T[0]) added after M_a, sample by sample
    (``acc_bias_m_s2`` in the result is the bias at T[0]); ``gyro_bias_per_c`` (3,) the gyro bias's temperature
    coefficient (rad/s/°C): the gyro reads gyro_bias_per_c (T − T[0]) more, sample by sample (a warming board's bias
    ramp in the temperature's own shape; ``bias_rad_s`` stays the bias at T[0]).

    A hand that turns a little (tremor, sway — real rotation, which the gyro sees and the accelerometer's tilt
    follows): ``wobble_bands`` ((f_lo, f_hi, rms_rad), ...) makes the attitude q ⊗ exp(φ) with φ(t) from
    :func:`attitude_wobble`, and the body rate exp(φ)ᵀ ω + J_r(φ) φ̇ with J_r ≈ I − ½[φ]× (error O(|φ|² |φ̇|));
    ``omega_rad_s`` and ``quat_nb`` in the result are the total.

    A sensor with an output low-pass (a MEMS DLPF, an AHRS's decimation filter): ``output_lowpass_hz`` f_c filters
    both triads' outputs, noise included, with a causal digital Butterworth low-pass of ``output_lowpass_order``
    poles (scipy's bilinear design; gain 1 at 0 Hz, its state started at the first sample) — white noise then keeps
    its density only below f_c.  The true parameters are unchanged (the filter is linear with unit DC gain).

    The gyro triad turned against the accelerometer's: ``gyro_rotation_rad`` α (3,) adds ω × α = −[α×] ω to the
    gyro (the linear term of its axes' rotation; ``gyro_rotation_rad`` in the result).

    A gyro that integrates over its sample interval: ``gyro_held`` replaces the rate the gyro measures by
    :func:`held_rate` (each sample the mean rate over its own step, the value a consumer holds over that step) —
    the gyro then leads the accelerometer by half a sample (+Δt/2 in the accelerometer-delay convention
    f̃(t) = f(t − δ), 5 ms at 100 Hz).  A schedule's closed form only: not with ``wobble_bands``."""
    rng = np.random.default_rng(seed)
    t, omega, quat = kin if kin is not None else kinematics(rate_hz, steps)
    n = omega.shape[0]
    if gyro_held and wobble_bands:
        raise ValueError("gyro_held needs the schedule's closed form: not with wobble_bands")
    bias = np.radians(np.asarray(bias_deg_s, float))
    if wobble_bands:
        phi, dphi = attitude_wobble(np.random.default_rng([seed, 23]), t, wobble_bands)
        rot = np.stack([_rotation(p) for p in phi])
        omega = np.einsum("nji,nj->ni", rot, omega) + dphi - 0.5 * np.cross(phi, dphi)
        ang = np.linalg.norm(phi, axis=1)
        half = np.where(ang > 0, np.sin(ang / 2) / np.where(ang > 0, ang, 1.0), 0.5)
        dq = np.concatenate([np.cos(ang / 2)[:, None], phi * half[:, None]], axis=1)
        quat = np.stack([_qmul(q, d) for q, d in zip(quat, dq)])
    dcm = np.stack([_dcm(q) for q in quat])
    gravity_body = np.einsum("nji,j->ni", dcm, np.array([0.0, 0.0, G]))
    hand_rng = np.random.default_rng([seed, 13])   # its own stream: the sensor noise stays that of `seed`
    f_hand = np.zeros((n, 3))
    if lever_arm_m is not None:
        r = np.asarray(lever_arm_m, float)
        wdot = angular_acceleration(rate_hz, steps)
        f_hand += np.cross(wdot, r) + np.cross(omega, np.cross(omega, r))
    a_nav = np.zeros((n, 3))
    if tremor_acc_rms_m_s2 > 0:
        a_nav += sum_of_sines(hand_rng, t, tremor_band_hz, tremor_acc_rms_m_s2)
    if sway_acc_rms_m_s2 > 0:
        a_nav += sum_of_sines(hand_rng, t, sway_band_hz, sway_acc_rms_m_s2)
    f_hand += np.einsum("nji,nj->ni", dcm, a_nav)
    bias_path = np.tile(bias, (n, 1)) + np.outer(t, np.asarray(bias_ramp_rad_s2, float))
    if bias_walk_rad_s_sqrt_s > 0:
        steps_rw = np.random.default_rng([seed, 19]).normal(size=(n, 3)) * bias_walk_rad_s_sqrt_s / math.sqrt(rate_hz)
        steps_rw[0] = 0.0
        bias_path = bias_path + np.cumsum(steps_rw, axis=0)
    if bias_flicker_rad_s > 0:
        from independent_noise import flicker
        fl = flicker(n, bias_flicker_rad_s, np.random.default_rng([seed, 29]))
        bias_path = bias_path + fl - fl[0]
    sensed = held_rate(rate_hz, steps) if gyro_held else omega   # what the gyro's samples stand for
    alpha = np.asarray(gyro_rotation_rad, float)
    m_gyro = _m(scale, nonortho) - np.array([[0.0, -alpha[2], alpha[1]], [alpha[2], 0.0, -alpha[0]],
                                             [-alpha[1], alpha[0], 0.0]])
    clean = (
        sensed @ m_gyro.T
        + bias_path
        + np.asarray(scale_nonlinearity_per_rad_s, float) * sensed * np.abs(sensed)
    )
    temp = None
    if temperature_c is not None:
        temp = np.asarray(temperature_c, float)
        clean = clean + sensed * (temp - temp[0])[:, None] * np.asarray(scale_per_c, float)[None, :]
        clean = clean + np.multiply.outer(temp - temp[0], np.asarray(gyro_bias_per_c, float))
    if g_sensitivity is not None:
        clean = clean + gravity_body @ np.asarray(g_sensitivity, float).T
    if delay_s:
        clean = np.stack([np.interp(t - delay_s, t, clean[:, i]) for i in range(3)], axis=1)
    gyro = clean + rng.normal(size=(n, 3)) * math.radians(gyro_noise_deg_s)
    acc_bias = np.asarray(acc_bias_g, float) * G
    acc = (gravity_body + f_hand) @ _m(acc_scale, acc_nonortho).T + acc_bias + rng.normal(size=(n, 3)) * acc_noise_g * G
    if temp is not None and np.any(np.asarray(acc_bias_per_c, float) != 0.0):
        acc = acc + np.multiply.outer(temp - temp[0], np.asarray(acc_bias_per_c, float))
    if output_lowpass_hz is not None:
        from scipy import signal
        b, a = signal.butter(output_lowpass_order, output_lowpass_hz, fs=rate_hz)
        zi = signal.lfilter_zi(b, a)[:, None]
        gyro = signal.lfilter(b, a, gyro, axis=0, zi=zi * gyro[:1])[0]
        acc = signal.lfilter(b, a, acc, axis=0, zi=zi * acc[:1])[0]
    mag = None
    if field_enu_ut is not None:
        mag = np.einsum("nji,j->ni", dcm, np.asarray(field_enu_ut, float))
        mag = mag + rng.normal(size=(n, 3)) * mag_noise_ut
    return {
        "t_s": t,
        "gyro_rad_s": gyro,
        "acc_m_s2": acc,
        "mag_ut": mag,
        "omega_rad_s": omega,
        "quat_nb": quat,
        "bias_rad_s": bias,
        "bias_path_rad_s": bias_path,
        "scale_factor": np.asarray(scale, float),
        "nonorthogonality": np.asarray(nonortho, float),
        "gyro_rotation_rad": alpha,
        "acc_bias_m_s2": acc_bias,
        "acc_scale_factor": np.asarray(acc_scale, float),
        "acc_nonorthogonality": np.asarray(acc_nonortho, float),
        "gyro_noise_rad_s": math.radians(gyro_noise_deg_s),
        "acc_noise_m_s2": acc_noise_g * G,
        "temp_c": temp,
    }


def write_csv(path: Path, data: dict) -> Path:
    """The CSV layout (deg/s, g, 9 significant digits)."""
    t, gyro, acc = data["t_s"], np.degrees(data["gyro_rad_s"]), data["acc_m_s2"] / G
    with Path(path).open("w", newline="") as fh:
        wr = csv.writer(fh)
        wr.writerow(["t", "gyro_x", "gyro_y", "gyro_z", "acc_x", "acc_y", "acc_z"])
        for k in range(t.size):
            wr.writerow([f"{t[k]:.6f}", *(f"{v:.9g}" for v in gyro[k]), *(f"{v:.9g}" for v in acc[k])])
    return Path(path)


def generate(path: Path, **kwargs) -> dict:
    """Write a CSV (see :func:`generate_arrays` for the keywords) and return the true parameters."""
    data = generate_arrays(**kwargs)
    write_csv(path, data)
    return {
        k: v for k, v in data.items() if k not in ("t_s", "gyro_rad_s", "acc_m_s2", "mag_ut", "omega_rad_s", "quat_nb")
    }


def _rotation(rotvec) -> np.ndarray:
    """exp([θ]×) by Rodrigues' formula (written here, not imported)."""
    th = np.asarray(rotvec, float)
    a = float(np.linalg.norm(th))
    if a == 0.0:
        return np.eye(3)
    k = np.array([[0.0, -th[2], th[1]], [th[2], 0.0, -th[0]], [-th[1], th[0], 0.0]]) / a
    return np.eye(3) + math.sin(a) * k + (1 - math.cos(a)) * (k @ k)


def magnetometer_arrays(
    quat_nb: np.ndarray,
    *,
    field_enu_ut=(1.5, 20.0, -44.0),
    hard_iron_ut=(0.0, 0.0, 0.0),
    soft_iron=None,
    rotation_rad=(0.0, 0.0, 0.0),
    noise_ut: float = 0.6,
    seed: int = 0,
) -> np.ndarray:
    """Magnetometer samples (N, 3) µT of a board with attitude ``quat_nb`` (body→ENU) in a uniform
    field: m = A R(θ)ᵀ Cᵀ B + h + noise (A soft iron 3×3, R(θ) the axes' rotation against the body
    frame, h hard iron; AN4246's m = A B + h with the axes rotated first)."""
    rng = np.random.default_rng(seed)
    a = np.eye(3) if soft_iron is None else np.asarray(soft_iron, float)
    body = np.einsum("nji,j->ni", np.stack([_dcm(q) for q in quat_nb]), np.asarray(field_enu_ut, float))
    m = body @ (a @ _rotation(rotation_rad).T).T + np.asarray(hard_iron_ut, float)
    return m + rng.normal(size=m.shape) * noise_ut
