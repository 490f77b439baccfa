"""``python -m comat``: the ``comat`` command."""

import sys

from comat.cli import main

sys.exit(main())
