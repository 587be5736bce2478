"""``python -m procmod ...``: the same command line as the ``procmod`` script."""

import sys

from .cli import main

sys.exit(main())
