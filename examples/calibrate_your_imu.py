"""Use calib as a library: calibrate your own recording (gyro and accelerometer), check the verdict,
apply the result, save it.

    python examples/calibrate_your_imu.py imu.csv --gyro-unit deg/s --acc-unit g

The CSV needs a header t,gyro_x,gyro_y,gyro_z,acc_x,acc_y,acc_z (README, "your own CSV"). Without an
argument, the script simulates a zhou2020 session with an MPU-9250-class device (datasheet noise,
a raw accelerometer: preset ``mpu9250_linear``) and calibrates that.
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from gyrosim.calibration import truth_calibration
from gyrosim.simulate import simulate

from calib import Calibration
from calib.inputs import load_recording
from calib.session.paper import calibrate


def main() -> None:
    """Calibrate the CSV given on the command line (or a simulated session), print the verdict and the
    scale factors with their σ, compensate the recording, and save and reload the calibration."""
    ap = argparse.ArgumentParser()
    ap.add_argument("recording", nargs="?")
    ap.add_argument("--gyro-unit", default="rad/s")
    ap.add_argument("--acc-unit", default="m/s^2")
    args = ap.parse_args()
    if args.recording:
        rec = load_recording(args.recording, args.gyro_unit, args.acc_unit)
    else:
        rec = simulate("zhou2020", "steady", "mpu9250_linear", 100.0, seed=3)

    result = calibrate(rec)  # gyro and accelerometer: bias, scale factor, non-orthogonality, covariance
    print(f"status {result.status}: " + ("; ".join(result.warnings) or "no warnings"))
    if result.status != "ok":
        print("the result failed its own consistency check: its σ does not describe its error")
    for triad in ("gyro", "accelerometer"):
        print(triad, "S", np.round(result.value(triad, "scale_factor"), 5),
              "±", np.round(result.std(triad, "scale_factor"), 5))

    # apply it: ω = (I + S_g + N(G_g))⁻¹ (ω̃ − b_g), f likewise (body frame RFU)
    comp = result.compensate(rec)
    print(f"compensated {comp.n} samples; peak |ω| = {math.degrees(np.abs(comp.gyro_rad_s).max()):.1f} °/s")

    # it saves and loads itself (versioned JSON; calib apply / calib export read the same file)
    again = Calibration.from_json(result.to_json())
    assert np.array_equal(again.parameters(), result.parameters())

    truth = truth_calibration(rec)  # only simulated recordings know the truth
    if truth is not None:
        print("error vs truth: S", np.round(result.scale_factor - truth.scale_factor, 6),
              "G", np.round(result.nonorthogonality - truth.nonorthogonality, 6))


if __name__ == "__main__":
    main()
