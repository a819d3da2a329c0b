"""``python -m predictive_drive.cli``: the ``predictive-drive`` command."""

import sys

from . import main

sys.exit(main())
