"""Kept policies of closed studies, out of the tree and back: the results budget's outlet.

    python tools/archive.py archive PATH ...     move every tracked policy.pt under PATHs out of the tree
                                                 (git rm), each recorded in results/archive.json with the
                                                 commit that holds it and its sha256; commit afterwards
    python tools/archive.py restore [PATH ...]   write the archived policies under PATHs (default: all)
                                                 back from git, each checked against its sha256
    python tools/archive.py check                every archived policy is in this clone's history, intact

Why: tracked ``results/`` has a budget (docs/contributing.md, "Budgets": 100 MB), and a study's
policies are most of its weight (a COMAT policy is 0.5 MB; issue 65's table alone keeps 45). A study
whose verdict is written keeps its small files (configs, curves, evaluations) in the tree and its
policies in git's history, where a clone already holds them: ``restore`` brings them back byte for
byte, so every result can still be evaluated again from a clean clone (a full one: a shallow clone
lacks the commits, and ``check`` says so). The pack does not shrink (history keeps every blob); the
tree a newcomer checks out does.

Standard library only; does not import comat. Exit status 0, 1 when ``check`` finds a policy
missing or changed, 2 for bad arguments.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RECORD = "results/archive.json"
"""The archived policies: ``{"policies": [{"path", "commit", "sha256", "bytes"}, ...]}``."""
POLICY_FILE = "policy.pt"


def _git(*args: str, binary: bool = False):
    done = subprocess.run(["git", "-C", str(ROOT), *args], capture_output=True, check=False)
    if done.returncode != 0:
        raise RuntimeError(f"git {' '.join(args)}: {done.stderr.decode().strip() or done.returncode}")
    return done.stdout if binary else done.stdout.decode()


def load_record() -> list[dict]:
    """The archived policies recorded in results/archive.json (none when it does not exist)."""
    path = ROOT / RECORD
    return json.loads(path.read_text())["policies"] if path.exists() else []


def _save_record(entries: list[dict]) -> None:
    path = ROOT / RECORD
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps({"policies": sorted(entries, key=lambda e: e["path"])}, indent=1) + "\n")
    os.replace(tmp, path)


def archive(paths: list[str]) -> int:
    """Record and remove every policy.pt tracked at HEAD under ``paths``."""
    head = _git("rev-parse", "HEAD").strip()
    tracked = [p for p in _git("ls-files", "-z", "--", *paths).split("\0") if p.endswith("/" + POLICY_FILE)]
    dirty = _git("status", "--porcelain", "--", *tracked).strip() if tracked else ""
    if dirty:
        print(f"archive: PATHs must hold only committed policies, got changes:\n{dirty}", file=sys.stderr)
        return 2
    entries = {e["path"]: e for e in load_record()}
    for p in tracked:
        blob = _git("show", f"{head}:{p}", binary=True)
        entries[p] = {"path": p, "commit": head, "sha256": hashlib.sha256(blob).hexdigest(), "bytes": len(blob)}
    if tracked:
        _git("rm", "-q", "--", *tracked)
    _save_record(list(entries.values()))
    freed = sum(entries[p]["bytes"] for p in tracked)
    print(f"archived {len(tracked)} policies ({freed / 1e6:.1f} MB) into {RECORD}; commit both")
    return 0


def restore(paths: list[str]) -> int:
    """Write the archived policies under ``paths`` (all when empty) back, checked."""
    chosen = [e for e in load_record() if not paths or any(e["path"].startswith(p.rstrip("/")) for p in paths)]
    if paths and not chosen:
        print(f"restore: PATH must lie under an archived policy's folder, got {paths}", file=sys.stderr)
        return 2
    for e in chosen:
        blob = _git("show", f"{e['commit']}:{e['path']}", binary=True)
        if hashlib.sha256(blob).hexdigest() != e["sha256"]:
            print(f"restore: {e['path']} at {e['commit'][:10]} does not match its sha256", file=sys.stderr)
            return 1
        out = ROOT / e["path"]
        out.parent.mkdir(parents=True, exist_ok=True)
        tmp = out.with_suffix(".tmp")
        tmp.write_bytes(blob)
        os.replace(tmp, out)
    print(f"restored {len(chosen)} policies")
    return 0


def check() -> int:
    """Every archived policy is in this clone's history with its recorded sha256."""
    bad = []
    for e in load_record():
        try:
            blob = _git("show", f"{e['commit']}:{e['path']}", binary=True)
        except RuntimeError as exc:
            bad.append(f"{e['path']}: not in this clone's history ({exc}; a shallow clone lacks it)")
            continue
        if hashlib.sha256(blob).hexdigest() != e["sha256"]:
            bad.append(f"{e['path']}: changed at {e['commit'][:10]}")
    for line in bad:
        print(f"archive check: {line}", file=sys.stderr)
    print(f"archive check: {len(load_record()) - len(bad)} of {len(load_record())} archived policies intact")
    return 1 if bad else 0


def main(argv: list[str] | None = None) -> int:
    global ROOT
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--root", default=str(ROOT), help="the checkout (default: this one)")
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser("archive", help="move tracked policies out of the tree").add_argument("paths", nargs="+")
    sub.add_parser("restore", help="write archived policies back").add_argument("paths", nargs="*")
    sub.add_parser("check", help="every archived policy is in history, intact")
    args = parser.parse_args(argv)
    ROOT = Path(args.root).resolve()
    if args.command == "archive":
        return archive(args.paths)
    if args.command == "restore":
        return restore(args.paths)
    return check()


if __name__ == "__main__":
    sys.exit(main())
