"""The ``comat`` command layer: ``comat <command> --help`` documents each command.

One module per command family, each with the ``add_*_parser`` that declares its flags and the
function that runs it; :mod:`comat.cli.main` assembles them. Nothing below this package imports it.
"""

from __future__ import annotations

from comat.cli.main import build_parser, main

__all__ = ["build_parser", "main"]
