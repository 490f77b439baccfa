"""The committed results in issue 46's format: one-off, re-runnable, idempotent (a second run
changes nothing). From the repository root:
    .venv/bin/python results/tools/convert_results.py            # convert every file under results/
    .venv/bin/python results/tools/convert_results.py --check    # say what would change; exit 1 if anything
    .venv/bin/python results/tools/convert_results.py results/grid_v3   # only these folders

What it does, per file:
* an evaluation or sweep file (``evaluation_*.json``, any JSON whose rows carry ``per_episode``):
  rewritten as ``comat eval`` writes it today (:func:`comat.files.write_json_detail`): the
  summary ``<stem>.json`` and the per-episode detail in ``<stem>.episodes.json.gz``. Values are
  kept as they are (metric names too: readers rename old ones); after writing, the file is read back
  and compared with what it held, number for number, and the script stops at the first difference;
* ``"checkpoint"`` in an evaluation or ``probe.json``: the path relative to the file's folder, as
  today's writers record it. The old files hold the absolute path of the machine that wrote them,
  or a path relative to its working directory, which was the checkout's root (``WAS``). The files
  were written in that checkout (``runs/...``) and copied under ``results/`` with the same layout,
  so ``<WAS>/runs/grid_v3/X/checkpoint.pt`` in ``results/grid_v3/runs/X/`` becomes
  ``../../../../runs/grid_v3/X/checkpoint.pt`` (the uncommitted checkpoint the policy came from);
* ``config.yaml``: every recorded command line (``command``, and those of ``earlier_sittings``)
  as ``comat train`` records it today (:func:`comat.files.portable_command`): the program by its
  name, the other paths relative to ``WAS`` (``--out <WAS>/runs/x`` → ``--out runs/x``,
  ``/tmp/x`` → ``../../tmp/x``). The file is rewritten only where ``yaml.safe_dump`` gives back
  its text unchanged (all of them do: ``comat train`` wrote them with it).

* a run's CSV (``eval.csv``, ``progress.csv``, ``evaluation_*.csv``): the metric names of before the
  vocabulary was made one (``completion``, ``success``, ...: :data:`comat.measure.metrics.RETIRED_NAMES`)
  in its header and, in an evaluation's ``metric`` column, as today's (``progress``, ``finished``);
  in these files ``completion`` always meant progress. Report tables (``table1.csv``,
  ``aggregates.csv``, ...) are left as they were written (their README says so).

Any other absolute path left in a JSON or YAML file is listed at the end.
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import os
import sys
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from comat.files import (
    DETAIL_SUFFIX,
    detail_name,
    encode_json_detail,
    portable_command,
    read_json_detail,
    write_atomic,
)
from comat.measure.metrics import RETIRED_NAMES

WAS = str(ROOT)
"""The checkout root of the machine that wrote the files (their working directory): ``--written-in``;
by default this checkout. The committed files of December 2026 were written in a checkout at the
training machine's root folder ``work/main`` and are converted already."""


def machine_path(value: str, file: Path) -> str:
    """A recorded path as the file's folder sees it on the machine that wrote it (module docstring)."""
    where = Path(WAS) / file.parent.resolve().relative_to(ROOT)
    return Path(os.path.relpath(os.path.join(WAS, value), where)).as_posix()  # join: an absolute value wins


def _canonical(doc) -> str:
    return json.dumps(doc, sort_keys=True, allow_nan=True)


def _absolute(node) -> list[str]:
    if isinstance(node, dict):
        return [s for v in node.values() for s in _absolute(v)]
    if isinstance(node, list):
        return [s for v in node for s in _absolute(v)]
    return [node] if isinstance(node, str) and node.startswith("/") else []


def convert_json(path: Path, check: bool) -> tuple[bool, list[str]]:
    """(changed, absolute paths left) for one JSON file."""
    doc = read_json_detail(path)
    if not isinstance(doc, dict):
        return False, _absolute(doc)
    raw = json.loads(path.read_text())
    written_today = "detail" in raw  # this format's summary: its paths are today's
    result = path.name.startswith("evaluation_") or written_today or '"per_episode":' in path.read_text()
    if not (result or path.name == "probe.json"):
        return False, _absolute(doc)  # summary.json and the like: left as they are
    new = dict(doc)
    ckpt = new.get("checkpoint")
    if isinstance(ckpt, str) and not written_today and ckpt.startswith(("/", "runs/", "results/")):
        new["checkpoint"] = machine_path(ckpt, path)
    if path.name == "probe.json":
        text = json.dumps(new, indent=2)
        changed = text != path.read_text()
        if changed and not check:
            write_atomic(path, text)
        return changed, _absolute(new)
    text, blob = encode_json_detail(path.name, new)
    side = path.with_name(detail_name(path.name))
    changed = text != path.read_text() or (blob is not None and (not side.is_file() or side.read_bytes() != blob))
    if changed and not check:
        if blob is not None:
            write_atomic(side, blob)
        write_atomic(path, text)
        if _canonical(read_json_detail(path)) != _canonical(new):
            raise SystemExit(f"{path}: reads back different from what it held; stopped (restore it from git)")
    return changed, _absolute(new)


RUN_CSVS = ("eval.csv", "progress.csv")
"""A run's CSV files by name; evaluation CSVs by their prefix ``evaluation_``."""


def convert_csv(path: Path, check: bool) -> bool:
    """Whether a run's CSV held retired metric names (renamed in place unless ``check``)."""
    with open(path, newline="") as fh:  # keep the file's own line endings (csv writes \r\n)
        text = fh.read()
    newline = "\r\n" if "\r\n" in text else "\n"
    rows = list(csv.reader(io.StringIO(text)))
    if not rows:
        return False
    metric = rows[0].index("metric") if "metric" in rows[0] else None
    renamed = [[RETIRED_NAMES.get(c, c) for c in rows[0]]]
    for row in rows[1:]:
        row = list(row)
        if metric is not None and metric < len(row):
            row[metric] = RETIRED_NAMES.get(row[metric], row[metric])
        renamed.append(row)
    if renamed == rows:
        return False
    if not check:
        out = io.StringIO()
        csv.writer(out, lineterminator=newline).writerows(renamed)
        write_atomic(path, out.getvalue())
    return True


def convert_yaml(path: Path, check: bool) -> tuple[bool, list[str]]:
    text = path.read_text()
    doc = yaml.safe_load(text)
    if not isinstance(doc, dict) or yaml.safe_dump(doc, sort_keys=False) != text:
        return False, _absolute(doc)  # not one comat wrote: left as it is, listed if it holds a path
    for sitting in [doc, *(doc.get("earlier_sittings") or [])]:
        if isinstance(sitting, dict) and isinstance(sitting.get("command"), list):
            sitting["command"] = portable_command(sitting["command"], WAS)
    new = yaml.safe_dump(doc, sort_keys=False)
    if new != text and not check:
        write_atomic(path, new)
    return new != text, _absolute(doc)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("folders", nargs="*", type=Path, default=[ROOT / "results"])
    parser.add_argument("--check", action="store_true", help="change nothing; exit 1 if a file would change")
    parser.add_argument(
        "--written-in",
        default=None,
        metavar="DIR",
        help="the checkout root of the machine that wrote the files (default: this checkout)",
    )
    args = parser.parse_args(argv)
    global WAS
    WAS = args.written_in or WAS
    changed, left, seen = [], [], 0
    for folder in args.folders:
        for path in sorted(Path(folder).resolve().rglob("*")):
            if not path.is_file() or path.name.startswith("."):
                continue
            if path.suffix == ".json" and not path.name.endswith(DETAIL_SUFFIX):
                did, absolute = convert_json(path, args.check)
            elif path.suffix in (".yaml", ".yml"):
                did, absolute = convert_yaml(path, args.check)
            elif path.suffix == ".csv" and (path.name in RUN_CSVS or path.name.startswith("evaluation_")):
                did, absolute = convert_csv(path, args.check), []
            else:
                continue
            seen += 1
            if did:
                changed.append(path)
            left += [(path, s) for s in absolute]
    rel = [str(p.relative_to(ROOT)) for p in changed]
    verb = "would change" if args.check else "changed"
    print(f"{seen} JSON/YAML/CSV files read, {len(changed)} {verb}" + (":" if changed and args.check else ""))
    if args.check:
        for r in rel:
            print(f"  {r}")
    for path, s in left:
        print(f"absolute path left in {path.relative_to(ROOT)}: {s}")
    return 1 if args.check and changed else 0


if __name__ == "__main__":
    sys.exit(main())
