"""calib — gyroscope and accelerometer calibration from hand rotation (Zhou et al. 2020, extended) on
gyrosim Recordings.

``from calib import Calibration``: the result every estimator returns (defined in gyrosim's floor,
:mod:`gyrosim.calibration`, so the testbed can use it without importing calib).

Frames: body Right-Forward-Up, navigation East-North-Up; quaternions (w, x, y, z) body→navigation.
"""

from gyrosim.calibration import Calibration

__all__ = ["Calibration", "__version__"]
__version__ = "0.1.0"
