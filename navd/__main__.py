"""``python -m navd``: the ``navd`` command line."""

import sys

from navd.cli import main

sys.exit(main())
