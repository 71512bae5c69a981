import sys

from calib.app.cli import main

sys.exit(main())
