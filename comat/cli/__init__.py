"""The ``comat`` command layer: ``comat <command> --help`` documents each command.

One module per command family, each with the ``add_*_parser`` that declares its flags and the
function that runs it; :mod:`comat.cli.main` assembles them. Nothing below this package imports it.
Run it as ``comat``, ``python -m comat`` or ``python -m comat.cli``.
"""

from __future__ import annotations

import sys
import types

__all__ = ["build_parser", "main"]


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``comat`` console script (:func:`comat.cli.main.main`)."""
    from comat.cli.main import main as run

    return run(argv)


def build_parser():
    """The ``comat`` argument parser (:func:`comat.cli.main.build_parser`)."""
    from comat.cli.main import build_parser as build

    return build()


class _Package(types.ModuleType):
    """This package, whose ``main`` stays the function above once the submodule of that name is loaded.

    Importing :mod:`comat.cli.main` binds the submodule on its parent as ``main`` (the import
    system's own setattr), which would turn ``from comat.cli import main`` into the module. The
    submodule is imported here only when a command runs, not when the package loads, so that
    ``python -m comat.cli.main`` finds it unloaded (runpy warns otherwise)."""

    def __setattr__(self, name: str, value) -> None:
        if name == "main" and isinstance(value, types.ModuleType):
            return  # the submodule stays reachable as sys.modules["comat.cli.main"]
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package
