"""``python -m mbn``: the same as the ``mbn`` command."""

import sys

from mbn.cli import main

sys.exit(main())
