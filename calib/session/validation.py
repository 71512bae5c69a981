"""Attitude validation (Zhou 2020 §5.2, Table 12): strapdown attitude from a free-style session with
and without the estimated compensation, compared with the truth.

The same device that was calibrated turns freely (schedule ``freestyle``): its drawn sensor
model, stored in the calibration recording, is applied to a new truth session with fresh noise.
The gyro is integrated from the true initial attitude (:func:`gyrosim.strapdown.integrate_gyro`)
twice: bias removed only (the paper's "without compensation") and fully compensated
ω̂ = M̂⁻¹(ω̃ − b̂).  Errors: the attitude difference Ĉ Cᵀ expressed as roll, pitch, heading
(ZYX Euler of the error rotation, degrees); mean and RMS over the session (Table 12's columns).
"""

from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np

from gyrosim.effects import nonortho_matrix
from gyrosim.recording import Recording
from gyrosim.rotations import quat_conjugate, quat_multiply, quat_to_matrix
from gyrosim.sensor_model import SensorModel
from gyrosim.simulate import apply_sensor, simulate_truth
from gyrosim.strapdown import integrate_gyro

__all__ = ["AttitudeErrors", "ValidationSession", "attitude_errors", "validate_attitude", "validation_session",
           "windowed_rotation_error_deg"]


@dataclass(frozen=True)
class AttitudeErrors:
    """Mean and RMS (deg) of roll, pitch, heading error, without and with compensation."""

    without_mean_deg: np.ndarray
    without_rms_deg: np.ndarray
    with_mean_deg: np.ndarray
    with_rms_deg: np.ndarray

    def table(self) -> str:
        rows = ["| | without compensation: mean | RMS | with compensation: mean | RMS |", "|---|---|---|---|---|"]
        for i, name in enumerate(("pitch", "roll", "heading")):
            j = (1, 0, 2)[i]  # Table 12 lists pitch, roll, heading
            rows.append(f"| {name} (°) | {self.without_mean_deg[j]:+.4f} | {self.without_rms_deg[j]:.4f} | "
                        f"{self.with_mean_deg[j]:+.4f} | {self.with_rms_deg[j]:.4f} |")
        return "\n".join(rows)


def attitude_errors(q_est: np.ndarray, q_true: np.ndarray) -> np.ndarray:
    """(N, 3) roll, pitch, heading (deg) of the error rotation q_est ⊗ q_true* (navigation frame)."""
    e = quat_to_matrix(quat_multiply(q_est, quat_conjugate(q_true)))
    roll = np.arctan2(e[:, 2, 1], e[:, 2, 2])
    pitch = -np.arcsin(np.clip(e[:, 2, 0], -1.0, 1.0))
    heading = np.arctan2(e[:, 1, 0], e[:, 0, 0])
    return np.degrees(np.stack([roll, pitch, heading], axis=1))


def windowed_rotation_error_deg(t_s: np.ndarray, gyro_rad_s: np.ndarray, quat_ref_nb: np.ndarray, rate_hz: float,
                                window_s: float = 5.0, step_s: float = 0.5) -> float:
    """RMS (°) over windows [t, t + window_s] (every ``step_s``) of the angle between the rotation the gyro
    (body RFU, rad/s) integrates and the reference's (``quat_ref_nb``, body → nav, e.g. BROAD's optical
    ``opt_quat``): the angle of (q_ref,i⁻¹ q_ref,j)⁻¹ (q_i⁻¹ q_j).  Windows with a non-finite (occluded)
    end are skipped.  Relative rotations need no heading or frame alignment, and a scale or axis error
    shows in proportion to the angle turned in the window."""
    q = integrate_gyro(t_s, gyro_rad_s, np.array([1.0, 0.0, 0.0, 0.0]))
    k, s = int(round(window_s * rate_hz)), int(round(step_s * rate_hz))
    i = np.arange(0, t_s.size - k, s)
    j = i + k
    ok = np.isfinite(quat_ref_nb[i]).all(axis=1) & np.isfinite(quat_ref_nb[j]).all(axis=1)
    i, j = i[ok], j[ok]
    d = quat_multiply(quat_conjugate(quat_multiply(quat_conjugate(quat_ref_nb[i]), quat_ref_nb[j])),
                      quat_multiply(quat_conjugate(q[i]), q[j]))
    ang = 2.0 * np.degrees(np.arccos(np.clip(np.abs(d[:, 0]), 0.0, 1.0)))
    return float(np.sqrt(np.mean(ang**2)))


@dataclass(frozen=True)
class ValidationSession:
    """The free-style session of the calibrated device: its truth and what the device measured."""

    truth: Recording
    measured: Recording


def validation_session(calibration_recording: Recording, *, schedule: str = "freestyle", hand: str = "typical",
                       seed: int = 1000) -> ValidationSession:
    """The device of ``calibration_recording`` (its stored sensor model) on a new ``schedule`` session, fresh noise
    (seed ``seed``): needs no calibration, so it can be simulated while the filter is still compiling."""
    raw = calibration_recording.meta.get("sensor_model")
    if not raw:
        raise ValueError("attitude validation needs a simulated recording that stores its sensor model")
    device = SensorModel.from_dict(raw if isinstance(raw, dict) else json.loads(raw))
    truth = simulate_truth(schedule, hand, calibration_recording.rate_hz, seed=seed)
    return ValidationSession(truth, apply_sensor(truth, device, np.random.default_rng(seed), realize=False))


def validate_attitude(calibration_recording: Recording, result, *, schedule: str = "freestyle",
                      hand: str = "typical", seed: int = 1000, session: ValidationSession | None = None
                      ) -> AttitudeErrors:
    """Table 12 for the device in ``calibration_recording`` calibrated as ``result``; ``session``: the free-style
    session already simulated (:func:`validation_session` with the same arguments), else simulated here."""
    if session is None:
        session = validation_session(calibration_recording, schedule=schedule, hand=hand, seed=seed)
    truth, rec = session.truth, session.measured
    q0 = truth.truth.quat_nb[0]
    w_bias = rec.gyro_rad_s - result.bias_rad_s
    m = np.eye(3) + np.diag(result.scale_factor) + nonortho_matrix(result.nonorthogonality)
    w_comp = np.linalg.solve(m, w_bias.T).T
    e_without = attitude_errors(integrate_gyro(rec.t_s, w_bias, q0), truth.truth.quat_nb)
    e_with = attitude_errors(integrate_gyro(rec.t_s, w_comp, q0), truth.truth.quat_nb)
    rms = lambda e: np.sqrt(np.mean(e**2, axis=0))  # noqa: E731
    return AttitudeErrors(e_without.mean(axis=0), rms(e_without), e_with.mean(axis=0), rms(e_with))
