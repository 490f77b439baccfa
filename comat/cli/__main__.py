"""``python -m comat.cli``: the ``comat`` command."""

import sys

from comat.cli.main import main

sys.exit(main())
