"""gyrosim — a virtual hand-held IMU in MuJoCo and a sensor error model.

Frames everywhere: body Right-Forward-Up (RFU), navigation East-North-Up (ENU); quaternions
(w, x, y, z) rotate body → navigation.  Units are SI unless a name says otherwise.
"""

__version__ = "0.1.0"
