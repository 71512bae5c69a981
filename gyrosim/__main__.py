"""``python -m gyrosim``: the ``gyrosim`` command line (:func:`gyrosim.cli.main`)."""

import sys

from .cli import main

sys.exit(main())
