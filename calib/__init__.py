"""calib — gyroscope calibration from hand rotation (Zhou et al. 2020) on gyrosim Recordings.

Frames: body Right-Forward-Up, navigation East-North-Up; quaternions (w, x, y, z) body→navigation.
"""

__version__ = "0.1.0"
