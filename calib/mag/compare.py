"""The comparison of *Soft Magnetic Error Compensation Method of Electronic Compass*, made measurable: compass
heading before and after compensation — by the calibration (hard and soft iron) and by the note's KF / adaptive KF /
particle filter — against the truth, as RMS heading error and as the Allan deviation of the heading error (the
note's Figs 14–15).

The compass heading of a recording (:func:`compass_heading`): the field compensated with a
calibration (or only its hard iron, or nothing), the gravity reference's tilt
(:mod:`calib.mag.gravity`), the TRIAD attitude (:func:`calib.mag.heading.compass_quaternion`)
and its twist about the vertical.  The gyro's heading increments for the ``gyro`` process model
(:func:`gyro_heading_increments`): Δψ_k = ψ(q_k ⊗ Exp(ω̄_k Δt)) − ψ(q_k), ω̄ the trapezoidal rate.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from gyrosim.recording import Recording
from gyrosim.rotations import quat_from_rotvec, quat_multiply

from calib.mag.filters import HEADING_FILTERS, FilterSettings
from calib.mag.gravity import GravityReference, gravity_reference
from calib.mag.heading import compass_quaternion, twist_heading_rad, wrap_pi
from calib.mag.result import MagCalibration
from calib.noise.allan import allan_deviation

__all__ = ["compass_heading", "gyro_heading_increments", "CompensationRow", "compare_compensation",
           "plot_heading_allan", "comparison_table", "simulated_comparison", "SimulatedComparison"]

ADEV_TAUS_S = (0.1, 1.0, 10.0)


def compass_heading(rec: Recording, calibration: MagCalibration | None, gravity: GravityReference,
                    hard_iron_only: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """(compass attitude (N, 4), heading ψ (N,) rad) of ``rec`` with the given compensation."""
    m = np.asarray(rec.mag_ut, dtype=float)
    if calibration is None:
        b = m
    elif hard_iron_only:
        b = m - np.nan_to_num(calibration.hard_iron_ut)
    else:
        b = calibration.compensate(m)
    q = compass_quaternion(gravity.up_body, b)
    return q, twist_heading_rad(q)


def gyro_heading_increments(q_nb: np.ndarray, gyro_rad_s: np.ndarray, t_s: np.ndarray,
                            bias_rad_s: np.ndarray) -> np.ndarray:
    """Δψ_k (rad): the heading change the gyro's rotation over [t_k, t_{k+1}] gives the attitude q_k."""
    w = np.asarray(gyro_rad_s, dtype=float) - bias_rad_s
    dt = np.diff(t_s)[:, None]
    step = quat_from_rotvec(0.5 * (w[:-1] + w[1:]) * dt)
    q_next = quat_multiply(q_nb[:-1], step)
    return np.append(wrap_pi(twist_heading_rad(q_next) - twist_heading_rad(q_nb[:-1])), 0.0)


@dataclass(frozen=True)
class CompensationRow:
    """One compensation's heading error against the reference (deg) and its Allan deviation."""

    name: str
    rms_deg: float
    p95_deg: float
    adev_tau_s: np.ndarray = field(repr=False)
    adev_deg: np.ndarray = field(repr=False)
    seconds: float = 0.0

    def adev_at(self, tau_s: float) -> float:
        return float(np.interp(math.log(tau_s), np.log(self.adev_tau_s), self.adev_deg))


def _row(name: str, psi: np.ndarray, psi_ref: np.ndarray, valid: np.ndarray, rate_hz: float, seconds: float,
         offset: bool) -> CompensationRow:
    err = wrap_pi(psi - psi_ref)
    if offset:  # a reference whose north is arbitrary (optical): remove the circular mean
        e = err[valid]
        err = wrap_pi(err - math.atan2(float(np.mean(np.sin(e))), float(np.mean(np.cos(e)))))
    e = np.degrees(err)
    e_valid = np.where(valid, e, 0.0)
    curve = allan_deviation(e_valid, rate_hz)
    return CompensationRow(name, float(np.sqrt(np.mean(e[valid] ** 2))), float(np.percentile(np.abs(e[valid]), 95)),
                           curve.tau_s, curve.adev, seconds)


def compare_compensation(rec: Recording, calibration: MagCalibration, psi_ref: np.ndarray, *,
                         valid: np.ndarray | None = None, rng: np.random.Generator | None = None,
                         gyro_arw_rad_s_sqrt_hz: float = math.radians(0.01), offset: bool = False,
                         filters: tuple[str, ...] = tuple(HEADING_FILTERS)) -> list[CompensationRow]:
    """Heading error rows: raw, hard iron only (soft iron left: the note's "before"), the note's
    filters on it in the note's form and with the gyro, the full calibration, and the gyro-aided KF
    on the calibrated heading.  ``psi_ref`` the reference heading (rad, magnetic: e.g. the truth's
    :func:`calib.mag.heading.magnetic_reference`); ``offset`` removes a constant offset first."""
    rng = rng or np.random.default_rng(0)
    grav = gravity_reference(rec)
    valid = np.ones(rec.n, dtype=bool) if valid is None else valid
    rate = rec.rate_hz
    dt = np.diff(rec.t_s)
    rows = []
    q_raw, psi_raw = compass_heading(rec, None, grav)
    rows.append(_row("raw (no calibration)", psi_raw, psi_ref, valid, rate, 0.0, offset))
    q_hi, psi_hi = compass_heading(rec, calibration, grav, hard_iron_only=True)
    rows.append(_row("hard iron only (soft iron left)", psi_hi, psi_ref, valid, rate, 0.0, offset))
    q_cal, psi_cal = compass_heading(rec, calibration, grav)
    # measurement noise of the compass heading: the high-frequency scatter of the calibrated heading
    # (second differences, median-based), which is what a user without a truth can measure
    d2 = np.diff(np.unwrap(psi_cal), n=2)
    r_meas = float((1.4826 * np.median(np.abs(d2 - np.median(d2)))) ** 2 / 6.0)
    for process in ("seed", "gyro"):
        dpsi = (
            gyro_heading_increments(q_hi, rec.gyro_rad_s, rec.t_s, grav.gyro_bias_rad_s) if process == "gyro" else None
        )
        s = FilterSettings(max(r_meas, 1e-8), process, arw_rad_s_sqrt_hz=gyro_arw_rad_s_sqrt_hz)
        for name in filters:
            flt = HEADING_FILTERS[name]()
            t0 = time.perf_counter()
            psi = flt.run(psi_hi, dpsi, dt, s, rng=rng)
            rows.append(_row(f"hard iron only + {name.upper()} ({process})", psi, psi_ref, valid, rate,
                             time.perf_counter() - t0, offset))
    rows.append(
        _row(f"calibrated ({calibration.method}: hard + soft iron)", psi_cal, psi_ref, valid, rate, 0.0, offset)
    )
    dpsi = gyro_heading_increments(q_cal, rec.gyro_rad_s, rec.t_s, grav.gyro_bias_rad_s)
    s = FilterSettings(max(r_meas, 1e-8), "gyro", arw_rad_s_sqrt_hz=gyro_arw_rad_s_sqrt_hz)
    t0 = time.perf_counter()
    psi = HEADING_FILTERS["kf"]().run(psi_cal, dpsi, dt, s)
    rows.append(_row("calibrated + KF (gyro)", psi, psi_ref, valid, rate, time.perf_counter() - t0, offset))
    return rows


def comparison_table(rows: list[CompensationRow]) -> str:
    """Markdown table of the rows (heading error RMS, 95th percentile, ADEV at 0.1/1/10 s, time)."""
    head = ("| compensation | RMS ° | 95 % ° | " + " | ".join(f"ADEV {t:g} s °" for t in ADEV_TAUS_S)
            + " | time s |\n|---|---|---|" + "---|" * len(ADEV_TAUS_S) + "---|\n")
    body = "".join(f"| {r.name} | {r.rms_deg:.2f} | {r.p95_deg:.2f} | "
                   + " | ".join(f"{r.adev_at(t):.3f}" for t in ADEV_TAUS_S) + f" | {r.seconds:.2f} |\n" for r in rows)
    return head + body


def plot_heading_allan(rows: list[CompensationRow], path: str | Path, title: str = "") -> Path:
    """Allan deviation of the heading error of each row ("Soft Magnetic Error Compensation Method of Electronic
    Compass", Figs 14–15, as one plot)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 5.5))
    for r in rows:
        style = "--" if "seed" in r.name else "-"
        ax.loglog(r.adev_tau_s, r.adev_deg, style, label=f"{r.name} (RMS {r.rms_deg:.2f}°)")
    ax.set_xlabel("averaging time τ (s)")
    ax.set_ylabel("Allan deviation of the heading error (°)")
    ax.grid(True, which="both", alpha=0.3)
    ax.set_title(title or "compass heading error: Allan deviation before and after compensation")
    ax.legend(fontsize=7, loc="lower left")
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


@dataclass(frozen=True)
class SimulatedComparison:
    """The simulated comparison: one device calibrated on one session, used on another."""

    sensor: str
    calibration: MagCalibration
    rows: list[CompensationRow]
    rows_true_tilt: list[CompensationRow]
    noise_floor_deg: float


def simulated_comparison(sensor: str = "phone", *, seed: int = 7, hand: str = "typical", method: str = "aided",
                         calibration_schedule: str = "multiposition", use_schedule: str = "compass",
                         rate_hz: float = 100.0) -> SimulatedComparison:
    """Draw one device of ``sensor``, calibrate it on a ``calibration_schedule`` session, then compare
    the compensations on a ``use_schedule`` session of the same device (module docstring); also
    with the true tilt, which isolates the magnetometer from the accelerometer's tilt error.
    Seeding: ``default_rng(seed).spawn(5)`` → (device, two hand sessions, two noise streams); the
    particle filter draws from ``default_rng(seed + 1)``."""
    from gyrosim.sensor_model import load_sensor
    from gyrosim.simulate import EARTH_FIELD_ENU_UT, apply_sensor, simulate_truth

    from calib.mag.calibrate import calibrate_magnetometer
    from calib.mag.heading import heading_noise_floor_rad, magnetic_reference, up_from_quat

    r_dev, r_cal, r_use, n_cal, n_use = np.random.default_rng(seed).spawn(5)
    dev = load_sensor(sensor).realize(r_dev)
    cal_truth = simulate_truth(calibration_schedule, hand, rate_hz, rng=r_cal)
    use_truth = simulate_truth(use_schedule, hand, rate_hz, rng=r_use)
    cal_rec = apply_sensor(cal_truth, dev, n_cal, realize=False)
    use_rec = apply_sensor(use_truth, dev, n_use, realize=False)
    cal = calibrate_magnetometer(cal_rec, method)
    q_ref = magnetic_reference(use_truth.truth.quat_nb, EARTH_FIELD_ENU_UT)
    psi_ref = twist_heading_rad(q_ref)
    rows = compare_compensation(use_rec, cal, psi_ref, rng=np.random.default_rng(seed + 1))
    up_true = up_from_quat(use_truth.truth.quat_nb)
    grav = gravity_reference(use_rec)
    true_tilt = GravityReference(up_true, grav.quasi_static, grav.acc_l, grav.acc_bias_m_s2, grav.gyro_bias_rad_s, ())
    rows_tt = [_row(name, compass_heading(use_rec, c, true_tilt, hi)[1], psi_ref, np.ones(use_rec.n, bool),
                    use_rec.rate_hz, 0.0, False)
               for name, c, hi in (("raw (true tilt)", None, False), ("hard iron only (true tilt)", cal, True),
                                   ("calibrated (true tilt)", cal, False))]
    var = [v for v in (e.sample_noise_variance(use_rec.rate_hz) for e in dev.magnetometer) if v is not None]
    sigma = float(np.sqrt(np.mean(sum(var))))  # white noise N² f_s plus rounding LSB²/12 per sample
    floor = math.degrees(heading_noise_floor_rad(use_truth.truth.extra["mag_field"], up_true, sigma, cal.soft_iron))
    return SimulatedComparison(sensor, cal, rows, rows_tt, floor)
