"""imucal 2.6.0's FerrarisCalibration of its own example session in our frame, shared by the tests that compare with
it: the symmetric part of its gyro matrix (docs/real_imu.md, computed by benchmarks/real_imu.py)."""

import numpy as np

#: S_x, S_y, S_z, G_x, G_y, G_z
IMUCAL_SG = np.array([0.02785, -0.01765, -0.00172, 0.00244, 0.00166, -0.00006])
