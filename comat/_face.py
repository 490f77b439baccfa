"""A package's face, loaded on first use (PEP 562): the names it exports and the module each lives in.

``__all__, __getattr__, __dir__ = lazy_face(__name__, {"comat.rl.runner": "saved_config train", ...})`` in a
package's ``__init__`` makes ``from comat.rl import train`` import :mod:`comat.rl.runner` only then.
Why lazy: :mod:`comat.rl`, :mod:`comat.eval`, :mod:`comat.models` and :mod:`comat.bench` each mix
torch-heavy modules with light ones that light callers import (the command line's parser, the
exported ``comat_schema``, the scenario tables), so a face that imported its modules would load torch
for ``comat --help`` and ``import sim2real``. Nothing is cached on the package: every look-up reads the
home module, so a test that patches ``comat.rl.runner.train`` is seen through ``comat.rl.train``.
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable
from typing import Any


def lazy_face(
    package: str, homes: dict[str, str], renamed: dict[str, str] | None = None
) -> tuple[list[str], Callable[[str], Any], Callable[[], list[str]]]:
    """``(__all__, __getattr__, __dir__)`` of ``package`` exporting, per home module, its names
    (separated by white space, as ``collections.namedtuple`` takes field names).

    ``renamed`` maps a face name to the name in its home module, for a name the package cannot
    export as is (one that is also a submodule's name: importing that submodule would overwrite it)."""
    renamed = renamed or {}
    home_of = {name: module for module, names in homes.items() for name in names.split()}
    listed = [name for names in homes.values() for name in names.split()]
    if len(listed) != len(home_of):
        twice = sorted({name for name in listed if listed.count(name) > 1})
        raise ValueError(f"homes: expected each name of {package}'s face once, got {twice} more than once")

    def __getattr__(name: str) -> Any:
        if name not in home_of:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        return getattr(importlib.import_module(home_of[name]), renamed.get(name, name))

    def __dir__() -> list[str]:
        return sorted({*home_of, *vars(sys.modules[package])})

    return sorted(home_of), __getattr__, __dir__
