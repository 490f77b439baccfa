"""The resumable row files of this folder's studies: read what an earlier sitting kept, keep each new
row as it comes (``scale_gap.py``, ``reality_gap.py``)."""

from __future__ import annotations

import csv
from pathlib import Path

from comat.files import write_atomic


def load_rows(path: Path) -> list[dict]:
    """The rows kept in ``path`` (none if it does not exist), ``team`` and ``robots`` as integers."""
    if not path.exists():
        return []
    return [{**r, "team": int(r["team"]), "robots": int(r["robots"])} for r in csv.DictReader(path.open())]


def keep_row(path: Path, rows: list[dict], row: dict, fields: tuple[str, ...]) -> None:
    """Append ``row`` to ``rows``, print it, and rewrite ``path`` atomically with every row so far."""
    rows.append(row)
    print(" ".join(f"{key}={row[key]}" for key in fields), flush=True)
    lines = [",".join(fields)] + [",".join(str(r[key]) for key in fields) for r in rows]
    write_atomic(path, "\n".join(lines) + "\n")
