"""The house's budgets: what `make lint` checks beside ruff and the import contracts.

    python tools/budgets.py [--root DIR]                  check every budget of DIR/tools/budgets.toml
    python tools/budgets.py pack-growth [--base REV] [PATH ...]
                                                          what committing PATHs (default results/) and
                                                          the commits since REV would add to the git pack

The budgets (numbers in ``tools/budgets.toml``, reasons in docs/contributing.md, "Budgets"):

=================  ==========================================================================
results            the files under ``results/`` git tracks or would add weigh <= ``results_mb``
large files        no such file anywhere weighs > ``file_mb`` unless ``[large_files]`` names it
checkpoints        no comat ``checkpoint.pt`` under ``results/``: a kept run keeps its ``policy.pt``
long functions     no function in ``comat/`` or ``sim2real/`` over ``function_lines`` lines
                   without a ``# long: <reason>`` comment on its def line or before its body
duplicates         the ``duplicates`` tool lists <= ``duplicate_pairs`` pairs in ``comat/``
                   (skipped, said in one line, where the tool is not on PATH: it is in the
                   developers' library, not a package)
=================  ==========================================================================

"The files git tracks or would add": in a git checkout, ``git ls-files`` plus the untracked files
git does not ignore (so a result file made but not yet added counts, as it will once committed);
elsewhere (a copy), every file below the root. Sizes are the working tree's, in MB of 10^6 bytes.

Exit status 0 when every budget holds, 1 when one is broken (each broken budget is one line
saying what, where, and the number against its budget), 2 for bad arguments. Standard library
only, and it does not import comat: it reads the code as text.
"""

from __future__ import annotations

import argparse
import ast
import json
import os
import re
import shutil
import subprocess
import sys
import tomllib
import zlib
from pathlib import Path

MB = 1_000_000
"""Bytes in the MB the budgets speak of."""
CODE_DIRS = ("comat", "sim2real")
"""Where the function-length budget holds."""
LONG_MARK = re.compile(r"#\s*long:\s*\S")
"""The comment that lets a function be longer than the budget: ``# long: <reason>``."""
CHECKPOINT_FILE = "checkpoint.pt"
"""A comat run's checkpoint: never kept under results/ (its ``policy.pt`` is what acting needs)."""
DUPLICATES_SECONDS = 120
"""How long the duplicates tool may take over comat/ (it takes about 2 s on 2 shared cores)."""


def _git(root: Path, *args: str, stdin: bytes | None = None) -> bytes | None:
    """The output of ``git -C root args``, or None outside a git checkout (or without git)."""
    if shutil.which("git") is None:
        return None
    done = subprocess.run(["git", "-C", str(root), *args], input=stdin, capture_output=True, check=False)
    return done.stdout if done.returncode == 0 else None


def tree_files(root: Path, under: str | None = None) -> list[str]:
    """Paths (relative, ``/``-separated) of the files git tracks or would add below ``root/under``;
    outside a git checkout, every file there. Files tracked but deleted in the working tree are left out."""
    inside = _git(root, "rev-parse", "--show-prefix")
    if inside is not None and inside.strip() == b"":  # root is a checkout's top folder
        spec = [under] if under else []
        out = _git(root, "ls-files", "-z", "--cached", "--others", "--exclude-standard", "--", *spec) or b""
        names = sorted({n for n in out.decode().split("\0") if n} - _archived(root))
        return [n for n in names if (root / n).is_file()]
    base = root / under if under else root
    return sorted(p.relative_to(root).as_posix() for p in base.rglob("*") if p.is_file() and ".git" not in p.parts)


def _archived(root: Path) -> set[str]:
    """Policies ``tools/archive.py`` moved out of the tree (results/archive.json): a copy restored
    from history to evaluate it again is untracked and does not count against the budget."""
    record = root / "results" / "archive.json"
    return {e["path"] for e in json.loads(record.read_text())["policies"]} if record.is_file() else set()


def load_budgets(root: Path) -> dict:
    """``root/tools/budgets.toml`` as a dict, with its keys checked."""
    path = root / "tools" / "budgets.toml"
    data = tomllib.loads(path.read_text())
    for key in ("results_mb", "file_mb", "function_lines", "duplicate_pairs"):
        if not isinstance(data.get(key), int | float):
            raise TypeError(f"{path}: {key} must be a number, got {data.get(key)!r}")
    data.setdefault("large_files", {})
    return data


def check_sizes(root: Path, budgets: dict) -> list[str]:
    """Broken size budgets: results/ over ``results_mb``, files over ``file_mb`` not allowed by name."""
    problems = []
    files = tree_files(root)
    sizes = {name: (root / name).stat().st_size for name in files}
    results = sum(size for name, size in sizes.items() if name.startswith("results/"))
    print(f"budgets: results/ {results / MB:.1f} MB of {budgets['results_mb']} MB")
    if results > budgets["results_mb"] * MB:
        problems.append(
            f"results/ weighs {results / MB:.1f} MB, over its budget of {budgets['results_mb']} MB "
            "(docs/contributing.md, Budgets: keep only what a write-up reads; policies in float16)"
        )
    allowed = budgets["large_files"]
    for name, size in sorted(sizes.items(), key=lambda item: -item[1]):
        if size > budgets["file_mb"] * MB and name not in allowed:
            problems.append(
                f"{name} weighs {size / MB:.1f} MB, over the {budgets['file_mb']} MB a file may weigh "
                "(shrink it, or name it with a reason under [large_files] in tools/budgets.toml)"
            )
    for name in sizes:
        if name.startswith("results/") and name.rsplit("/", 1)[-1] == CHECKPOINT_FILE:
            problems.append(
                f"{name} is a run's checkpoint (optimizer, critic, buffers: 4 to 26 times its policy): keep the run's "
                "policy.pt instead (`comat policy RUN` makes it)"
            )
    for name in allowed:
        if name not in sizes:
            problems.append(f"tools/budgets.toml [large_files] names {name}, which is not in the tree: remove it")
    return problems


def long_functions(root: Path, limit: int) -> list[tuple[str, int, str, int, bool]]:
    """Functions over ``limit`` lines in comat/ and sim2real/: ``(path, line, name, lines, marked)``,
    longest first; ``marked`` when a ``# long:`` comment stands on the def line or before the body."""
    rows = []
    for folder in CODE_DIRS:
        for name in tree_files(root, folder):
            if not name.endswith(".py"):
                continue
            text = (root / name).read_text()
            lines = text.splitlines()
            for node in ast.walk(ast.parse(text, filename=name)):
                if not isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                    continue
                length = node.end_lineno - node.lineno + 1
                if length <= limit:
                    continue
                header = lines[node.lineno - 1 : node.body[0].lineno]  # def line .. the first statement's line
                marked = any(LONG_MARK.search(line) for line in header)
                rows.append((name, node.lineno, node.name, length, marked))
    return sorted(rows, key=lambda row: (-row[3], row[0], row[1]))


def check_functions(root: Path, budgets: dict) -> list[str]:
    """Broken function-length budgets: one line per long function without a ``# long:`` reason."""
    limit = budgets["function_lines"]
    rows = long_functions(root, limit)
    marked = sum(row[4] for row in rows)
    where = " + ".join(CODE_DIRS)
    print(f"budgets: functions over {limit} lines in {where}: {len(rows)}, {marked} with a # long: reason")
    return [
        f"{path}:{line} {name} has {length} lines, over {limit}: split it where a name explains the part, "
        f"or say why it is one piece in a '# long: <reason>' comment on its def line"
        for path, line, name, length, ok in rows
        if not ok
    ]


def count_duplicates(folder: Path) -> tuple[int | None, str]:
    """The pairs the ``duplicates`` tool lists in ``folder`` and its first line; ``(None, why)`` when
    the tool is absent or its count could not be read."""
    tool = shutil.which("duplicates")
    if tool is None:
        return None, "the `duplicates` tool is not on PATH (it is in the developers' library, not installed by make)"
    done = subprocess.run(
        [tool, "--repo", str(folder), "--most", "1", "--seconds", str(DUPLICATES_SECONDS)],
        capture_output=True,
        text=True,
        check=False,
    )
    lines = done.stdout.splitlines()
    first = lines[0] if lines else done.stderr.strip()
    incomplete = [line for line in lines if line.startswith("incomplete:")]
    if incomplete:
        return None, f"duplicates did not finish: {incomplete[0]}"
    if first.startswith("no duplicates"):
        return 0, first
    match = re.match(r"(\d+) pairs? of places", first)
    if match is None:
        return None, f"cannot read the duplicates tool's count from {first!r}"
    return int(match.group(1)), first


def check_duplicates(root: Path, budgets: dict) -> list[str]:
    """A broken duplicates budget: more pairs in comat/ than ``duplicate_pairs``."""
    budget = budgets["duplicate_pairs"]
    count, line = count_duplicates(root / "comat")
    if count is None:
        print(f"budgets: duplicates in comat/ not checked: {line}")
        return []
    print(f"budgets: duplicates in comat/: {count} pairs of {budget}")
    if count > budget:
        return [
            (
                f"comat/ has {count} duplicate pairs, over its budget of {budget}: run `duplicates --change` "
                "and merge what your change wrote again"
            )
        ]
    if count < budget:
        print(f"budgets: comat/ is {budget - count} below its duplicates budget: lower duplicate_pairs to {count}")
    return []


def check(root: Path) -> int:
    """Every budget of ``root``; prints a line per budget and one per breach; 0 if all hold, else 1."""
    budgets = load_budgets(root)
    problems = check_sizes(root, budgets) + check_functions(root, budgets) + check_duplicates(root, budgets)
    for problem in problems:
        print(f"budgets: FAIL {problem}")
    return 1 if problems else 0


def _upstream(root: Path) -> str | None:
    out = _git(root, "rev-parse", "--abbrev-ref", "--symbolic-full-name", "@{upstream}")
    return out.decode().strip() if out else None


def pack_growth(root: Path, base: str | None, paths: list[str], top: int = 10) -> int:
    """Print what the git pack would grow by: the commits since ``base`` (default: the upstream
    branch; none if there is none) as git would send them (a thin pack), and the changed or new
    files under ``paths`` as zlib-compressed blobs (an upper bound: git may store a text file as a
    delta against its previous version; binaries and gzip files rarely delta). Returns 0, 2 on bad input."""
    if _git(root, "rev-parse", "--git-dir") is None:
        print(f"pack-growth: {root} is not a git checkout", file=sys.stderr)
        return 2
    base = base or _upstream(root)
    committed = 0
    if base is None:
        print("commits: no --base given and no upstream branch: commits not counted (pass --base REV)")
    elif _git(root, "rev-parse", "--verify", "--quiet", f"{base}^{{commit}}") is None:
        print(f"pack-growth: --base must name a commit, got {base!r}", file=sys.stderr)
        return 2
    else:
        pack = _git(root, "pack-objects", "--revs", "--thin", "--stdout", "-q", stdin=f"HEAD\n^{base}\n".encode())
        committed = len(pack or b"")
        count = (_git(root, "rev-list", "--count", f"{base}..HEAD") or b"0").decode().strip()
        print(f"commits since {base}: {count}, {committed / MB:.2f} MB as a thin pack")
    out = _git(root, "ls-files", "-z", "--modified", "--others", "--exclude-standard", "--", *paths) or b""
    names = sorted({n for n in out.decode().split("\0") if n and (root / n).is_file()})
    blobs = (_git(root, "hash-object", "--stdin-paths", stdin="\n".join(names).encode()) or b"").decode().split()
    known = set()
    if names:
        listing = _git(root, "cat-file", "--batch-check", stdin="\n".join(blobs).encode()) or b""
        known = {line.split()[0] for line in listing.decode().splitlines() if not line.endswith("missing")}
    rows = []
    for name, blob in zip(names, blobs, strict=True):
        data = (root / name).read_bytes()
        rows.append((0 if blob in known else len(zlib.compress(data, 6)), len(data), name))
    rows.sort(reverse=True)
    packed = sum(row[0] for row in rows)
    raw = sum(row[1] for row in rows)
    where = " ".join(paths) if paths else "the tree"
    print(f"uncommitted under {where}: {len(rows)} files, {raw / MB:.2f} MB, at most {packed / MB:.2f} MB packed")
    for size, length, name in rows[:top]:
        print(f"  {size / MB:8.3f} MB packed  {length / MB:8.3f} MB  {name}")
    if len(rows) > top:
        print(f"  (+{len(rows) - top} more files)")
    pack_line = (_git(root, "count-objects", "-v") or b"").decode()
    size_pack = re.search(r"size-pack: (\d+)", pack_line)
    if size_pack:
        now = int(size_pack.group(1)) * 1024
        print(f"the pack: {now / 2**20:.1f} MiB now, about {(now + committed + packed) / 2**20:.1f} MiB with these")
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="tools/budgets.py", description=__doc__.split("\n\n")[0])
    parser.add_argument("--root", default=Path(__file__).resolve().parent.parent, type=Path, help="the tree")
    sub = parser.add_subparsers(dest="command")
    growth = sub.add_parser("pack-growth", help="what committing results (and unpushed commits) adds to the pack")
    growth.add_argument("--base", help="count the commits since this one (default: the upstream branch)")
    growth.add_argument("--top", type=int, default=10, help="files to list, largest first (default 10)")
    growth.add_argument("paths", nargs="*", default=["results"], help="where to look for changes (default results)")
    args = parser.parse_args(argv)
    root = args.root.resolve()
    if not root.is_dir():
        parser.error(f"--root must be a folder, got {str(args.root)!r}")
    if args.command == "pack-growth":
        return pack_growth(root, args.base, args.paths, args.top)
    return check(root)


if __name__ == "__main__":
    os.environ.setdefault("GIT_OPTIONAL_LOCKS", "0")  # read-only git calls must not take the index lock
    sys.exit(main())
