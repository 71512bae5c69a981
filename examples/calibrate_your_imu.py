"""Use calib as a library: calibrate your own recording, compensate the gyro, check the result.

    python examples/calibrate_your_imu.py imu.csv --gyro-unit deg/s --acc-unit g

The CSV needs a header t,gyro_x,gyro_y,gyro_z,acc_x,acc_y,acc_z (see README). Without an
argument, the script simulates a zhou2020 session with the MPU-9150-class sensor of Zhou 2020
Table 7 (reading B) and calibrates that.
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from calib.calibrate import calibrate, true_gyro_parameters
from calib.inputs import load_recording
from gyrosim.effects import NonOrthogonality
from gyrosim.simulate import simulate


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("recording", nargs="?")
    ap.add_argument("--gyro-unit", default="rad/s")
    ap.add_argument("--acc-unit", default="m/s^2")
    args = ap.parse_args()
    if args.recording:
        rec = load_recording(args.recording, args.gyro_unit, args.acc_unit)
    else:
        rec = simulate("zhou2020", "steady", "zhou2020_sim_consumer", 100.0, seed=3)

    result = calibrate(rec, method="iterated")  # bias, scale factor, non-orthogonality with 1σ
    print(result.to_json())

    # compensate the gyro yourself: ω = (I + S + N(G))⁻¹ (ω̃ − b)   (body frame RFU, rad/s)
    m = np.eye(3) + np.diag(result.scale_factor) + NonOrthogonality(value=result.nonorthogonality).affine()[0]
    omega = np.linalg.solve(m, (rec.gyro_rad_s - result.bias_rad_s).T).T
    print(f"compensated {omega.shape[0]} samples; peak |ω| = {math.degrees(np.abs(omega).max()):.1f} °/s")

    truth = true_gyro_parameters(rec)  # only simulated recordings know the truth
    if truth is not None:
        print("error vs truth: S", np.round(result.scale_factor - truth["scale_factor"], 6),
              "G", np.round(result.nonorthogonality - truth["nonorthogonality"], 6))


if __name__ == "__main__":
    main()
