"""Output files: atomic writes (a reader sees the old file or the new one, never half of one) and
the one rule every command's ``--out`` follows (:func:`new_outputs`)."""

from __future__ import annotations

import contextlib
import os
import shutil
from collections.abc import Iterable, Iterator
from pathlib import Path

__all__ = ["new_outputs", "write_atomic"]


def write_atomic(path: str | Path, data: str | bytes) -> None:
    """Write ``data`` to a hidden temporary file next to ``path``, then rename it over ``path``."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp")
    if isinstance(data, bytes):
        tmp.write_bytes(data)
    else:
        tmp.write_text(data)
    os.replace(tmp, path)


@contextlib.contextmanager
def new_outputs(folder: str | Path, names: Iterable[str], *, force: bool = False, flag: str = "--out") -> Iterator[Path]:
    """The one rule of every command's ``--out``: a context manager around writing ``names`` in ``folder``.

    * ``folder`` is created (with its parents) if it is missing;
    * a file of ``names`` that already exists is refused (FileExistsError naming it and ``--force``)
      unless ``force``, which lets the command replace it;
    * if the block raises, everything the command made is removed again: the files of ``names``
      that did not exist before, and the folders it created — a failed command leaves nothing.

    Yields the folder as a Path.
    """
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise FileExistsError(f"{flag} {str(folder)!r} is a file; expected a folder")
    names = list(names)
    existing = [n for n in names if (folder / n).exists()]
    if existing and not force:
        shown = ", ".join(repr(str(folder / n)) for n in existing[:3]) + (" ..." if len(existing) > 3 else "")
        raise FileExistsError(f"{flag}: {shown} already exist{'s' if len(existing) == 1 else ''}; pass --force to "
                              f"replace, or choose another {flag}")
    created = []  # folders made here, outermost first
    probe = folder
    while not probe.exists():
        created.insert(0, probe)
        probe = probe.parent
    folder.mkdir(parents=True, exist_ok=True)
    try:
        yield folder
    except BaseException:
        for n in names:
            if n not in existing:
                (folder / n).unlink(missing_ok=True)
        if created:
            shutil.rmtree(created[0], ignore_errors=True)
        raise
