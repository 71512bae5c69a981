"""``python -m calib``: the ``calib`` command line (:func:`calib.app.cli.main`)."""

import sys

from calib.app.cli import main

sys.exit(main())
