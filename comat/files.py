"""Output files: atomic writes (a reader sees the old file or the new one, never half of one), the
one rule every command's ``--out`` follows (:func:`new_outputs`), and result documents with their
bulky detail in a gzipped side file (:func:`write_json_detail`, :func:`read_json_detail`).

**Result documents.** An evaluation file (``evaluation_<tier>.json``, a sweep's
``evaluation_<tier>_sweep_<component>.json``) is a small, indented JSON summary: the rows with
their metrics and intervals. What a row holds per episode (the ``per_episode`` lists: endpoints,
progress curves, per-robot tables; 99 % of the bytes) goes to ``<stem>.episodes.json.gz`` next to
it (:data:`DETAIL_SUFFIX`), gzipped JSON that the summary names and checks by hash
(``"detail": {"file", "key", "items", "sha256"}``). :func:`read_json_detail` puts the detail back,
so a reader gets the document as it was written; it reads the plain JSON files written before
(detail inline) and a whole ``.json.gz`` the same way. Paths inside a document are relative to its
folder (:func:`relative_path`)."""

from __future__ import annotations

import contextlib
import csv
import gzip
import hashlib
import io
import json
import os
import shutil
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

__all__ = [
    "DETAIL_KEY",
    "DETAIL_SUFFIX",
    "csv_text",
    "detail_name",
    "encode_json_detail",
    "new_outputs",
    "portable_command",
    "read_json_detail",
    "relative_path",
    "replace_block",
    "write_atomic",
    "write_json_detail",
]

DETAIL_KEY = "per_episode"
"""The key whose values a result document keeps in its detail file."""
DETAIL_SUFFIX = ".episodes.json.gz"
"""``evaluation_unicycle.json``'s detail file: ``evaluation_unicycle.episodes.json.gz``."""


def csv_text(rows: Iterable[dict], fields: list[str]) -> str:
    """``rows`` as CSV text: a header of ``fields``, then a line per row (``\n`` line ends; a
    missing field is empty)."""
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=fields, lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    return buf.getvalue()


def write_atomic(path: str | Path, data: str | bytes) -> None:
    """Write ``data`` to a hidden temporary file next to ``path``, then rename it over ``path``."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp")
    if isinstance(data, bytes):
        tmp.write_bytes(data)
    else:
        tmp.write_text(data)
    os.replace(tmp, path)


def replace_block(path: str | Path, name: str, text: str) -> None:
    """Rewrite, atomically, what stands between ``<!-- NAME:begin -->`` and ``<!-- NAME:end -->`` in
    ``path`` (a generated table in a hand-written README); ValueError if a marker is missing."""
    path = Path(path)
    begin, end = f"<!-- {name}:begin -->", f"<!-- {name}:end -->"
    old = path.read_text()
    if begin not in old or end not in old:
        raise ValueError(f"{path}: expected the markers {begin} and {end}")
    head, rest = old.split(begin, 1)
    tail = rest.split(end, 1)[1]
    write_atomic(path, f"{head}{begin}\n{text}{end}{tail}")


@contextlib.contextmanager
def new_outputs(
    folder: str | Path, names: Iterable[str], *, force: bool = False, flag: str = "--out"
) -> Iterator[Path]:
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
        raise FileExistsError(
            f"{flag}: {shown} already exist{'s' if len(existing) == 1 else ''}; pass --force to "
            f"replace, or choose another {flag}"
        )
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


def detail_name(name: str) -> str:
    """The detail file's name of a summary named ``name`` (``x.json`` → ``x`` + :data:`DETAIL_SUFFIX`)."""
    return name.removesuffix(".json") + DETAIL_SUFFIX


def relative_path(path: str | Path, folder: str | Path) -> str:
    """``path`` relative to ``folder`` (both taken from the current directory when relative), with
    forward slashes: what a result file records instead of a machine's absolute path."""
    return Path(os.path.relpath(os.path.abspath(path), os.path.abspath(folder))).as_posix()


def portable_command(argv: Iterable[str], cwd: str | Path | None = None) -> list[str]:
    """A command line as a run records it, without the machine's folders: the program by its name
    (``/home/me/.venv/bin/comat`` → ``comat``) and every other absolute path (an argument, or the
    value of ``--flag=PATH`` or ``key=PATH``) relative to ``cwd`` (default: the current
    directory), as if typed there: ``--out /home/me/comat/runs/x`` → ``--out runs/x``."""
    cwd = os.path.abspath(cwd or os.getcwd())

    def rel(arg: str) -> str:
        return Path(os.path.relpath(arg, cwd)).as_posix() if os.path.isabs(arg) else arg

    out = []
    for i, arg in enumerate(str(a) for a in argv):
        key, eq, value = arg.partition("=")
        if i == 0:
            out.append(Path(arg).name if os.path.isabs(arg) else arg)
        else:
            out.append(f"{key}={rel(value)}" if eq and not os.path.isabs(arg) else rel(arg))
    return out


def _split(node: Any, key: str, where: list, items: list) -> Any:
    """``node`` without ``key`` at any depth; each value removed appended to ``items`` as
    ``[path, value]`` (the path: the keys and list indices from the root to its dict)."""
    if isinstance(node, dict):
        if key in node:
            items.append([list(where), node[key]])
        return {k: _split(v, key, [*where, k], items) for k, v in node.items() if k != key}
    if isinstance(node, list):
        return [_split(v, key, [*where, i], items) for i, v in enumerate(node)]
    return node


def encode_json_detail(name: str, doc: dict, *, key: str = DETAIL_KEY) -> tuple[str, bytes | None]:
    """What :func:`write_json_detail` writes for a summary named ``name``: its text and the detail
    file's bytes (None where ``doc`` holds no ``key``)."""
    items: list = []
    summary = _split(doc, key, [], items)
    blob = None
    if items:
        if "detail" in summary:
            raise ValueError(f"{name}: a result document with detail cannot hold a key 'detail' of its own")
        raw = json.dumps({"key": key, "items": items}, separators=(",", ":")).encode()
        blob = gzip.compress(raw, compresslevel=9, mtime=0)
        summary["detail"] = {
            "file": detail_name(name),
            "key": key,
            "items": len(items),
            "sha256": hashlib.sha256(raw).hexdigest(),
        }
    return json.dumps(summary, indent=1) + "\n", blob


def write_json_detail(path: str | Path, doc: dict, *, key: str = DETAIL_KEY) -> list[Path]:
    """Write ``doc`` as the summary ``path`` (indented JSON without ``key``) and, where ``doc``
    holds ``key`` anywhere, its values to :func:`detail_name` next to it (gzipped compact JSON,
    the same bytes for the same document); both atomically, the detail first. Returns the paths
    written."""
    path = Path(path)
    text, blob = encode_json_detail(path.name, doc, key=key)
    paths = [path]
    if blob is not None:
        paths.append(path.with_name(detail_name(path.name)))
        write_atomic(paths[1], blob)
    write_atomic(path, text)
    return paths


def _read_json(path: Path) -> tuple[Any, bytes]:
    raw = path.read_bytes()
    if raw[:2] == b"\x1f\x8b":  # gzip, whatever the name
        raw = gzip.decompress(raw)
    return json.loads(raw), raw


def read_json_detail(path: str | Path, *, detail: bool = True) -> Any:
    """A result document as it was written: the summary at ``path`` with its detail file's values
    put back (``detail=False``: the summary alone, the detail left out); a plain JSON file written
    before (detail inline) or a gzipped one as it is. Raises FileNotFoundError where the summary
    names a detail file that is missing, ValueError where that file belongs to another summary."""
    path = Path(path)
    doc, _ = _read_json(path)
    ref = doc.get("detail") if isinstance(doc, dict) else None
    if not (isinstance(ref, dict) and "file" in ref and "key" in ref):
        return doc
    doc = {k: v for k, v in doc.items() if k != "detail"}
    if not detail:
        return doc
    side = path.with_name(ref["file"])
    if not side.is_file():
        raise FileNotFoundError(
            f"{str(path)!r} keeps its {ref['key']} in {ref['file']!r}, which is missing (copy it with the summary)"
        )
    data, raw = _read_json(side)
    if hashlib.sha256(raw).hexdigest() != ref.get("sha256") or len(data["items"]) != ref.get("items"):
        raise ValueError(f"{str(side)!r} does not belong to {str(path)!r} (another evaluation's detail?)")
    for where, value in data["items"]:
        node = doc
        for step in where:
            node = node[step]
        node[data["key"]] = value
    return doc
