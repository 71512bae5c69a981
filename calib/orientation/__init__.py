"""Orientation estimators under test (VQF, Madgwick, Mahony, Fusion) behind gyrosim's orientation interface.

:mod:`.estimators` holds the adapters and the names gyrosim finds them by; :mod:`.kernels` the compiled
Madgwick and Mahony filters.  The adapters' names are re-exported here (``calib.orientation.vqf``), as
they were when this package was one module.
"""

from calib.orientation.estimators import *  # noqa: F401,F403  (the former module's public names)
from calib.orientation.estimators import __all__  # noqa: F401
