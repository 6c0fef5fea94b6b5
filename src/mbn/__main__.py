"""``python -m mbn``: the same as the ``mbn`` command."""

import sys

from mbn.cli.main import main

sys.exit(main())
