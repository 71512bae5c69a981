"""Magnetometer calibration: hard and soft iron, misalignment, local disturbances.

``calibrate_magnetometer(rec, method)`` → :class:`MagCalibration` (m = A·B + h).  Methods
(:data:`METHODS`): ``ellipsoid`` (field magnitude only) and ``aided`` (also the inclination
against the gyro/accelerometer's gravity; sees the misalignment).  The in-motion heading compensation of *Soft
Magnetic Error Compensation Method of Electronic Compass* (KF, Sage–Husa adaptive KF, particle filter) lives in
:mod:`calib.mag.filters`, their comparison in :mod:`calib.mag.compare`.
"""

from calib.mag.calibrate import calibrate_magnetometer, true_magnetometer
from calib.mag.methods import METHODS
from calib.mag.result import Disturbance, MagCalibration

__all__ = ["calibrate_magnetometer", "true_magnetometer", "METHODS", "MagCalibration", "Disturbance"]
