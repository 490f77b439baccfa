"""tools/archive.py: archived policies leave the tree and come back byte for byte; every policy
results/archive.json records is in this clone's history, intact."""

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
TOOL = REPO / "tools" / "archive.py"


def _run(root: Path, *args: str) -> subprocess.CompletedProcess:
    cmd = [sys.executable, str(TOOL), "--root", str(root), *args]
    return subprocess.run(cmd, check=False, capture_output=True, text=True)


def _git(root: Path, *args: str) -> None:
    subprocess.run(["git", "-C", str(root), *args], check=True, capture_output=True)


@pytest.mark.skipif(shutil.which("git") is None, reason="needs git")
def test_archive_and_restore_round_trip(tmp_path):
    _git(tmp_path, "init", "-q")
    _git(tmp_path, "config", "user.email", "t@t")
    _git(tmp_path, "config", "user.name", "t")
    run = tmp_path / "results" / "study" / "runs" / "a_s0"
    run.mkdir(parents=True)
    (run / "policy.pt").write_bytes(b"\x00weights" * 1000)
    (run / "summary.json").write_text("{}")
    _git(tmp_path, "add", ".")
    _git(tmp_path, "commit", "-qm", "a study")
    done = _run(tmp_path, "archive", "results/study")
    assert done.returncode == 0, done.stderr
    assert not (run / "policy.pt").exists() and (run / "summary.json").exists()
    record = json.loads((tmp_path / "results" / "archive.json").read_text())["policies"]
    assert [e["path"] for e in record] == ["results/study/runs/a_s0/policy.pt"]
    _git(tmp_path, "add", "-A")
    _git(tmp_path, "commit", "-qm", "archive")
    assert _run(tmp_path, "check").returncode == 0
    done = _run(tmp_path, "restore", "results/study")
    assert done.returncode == 0, done.stderr
    assert (run / "policy.pt").read_bytes() == b"\x00weights" * 1000
    # A record that points at a blob another commit holds differently fails the check.
    record[0]["sha256"] = "0" * 64
    (tmp_path / "results" / "archive.json").write_text(json.dumps({"policies": record}))
    assert _run(tmp_path, "check").returncode == 1
    assert _run(tmp_path, "restore", "results/nothing").returncode == 2


@pytest.mark.skipif(not (REPO / ".git").exists(), reason="not a git checkout")
def test_every_archived_policy_is_in_history_and_out_of_the_tree():
    record = REPO / "results" / "archive.json"
    if not record.exists():
        pytest.skip("nothing archived")
    git = ["git", "-C", str(REPO)]
    shallow = subprocess.run([*git, "rev-parse", "--is-shallow-repository"], check=False, capture_output=True)
    if shallow.stdout.strip() == b"true":
        pytest.skip("a shallow clone lacks the archived policies' commits")
    done = _run(REPO, "check")
    assert done.returncode == 0, done.stderr
    for entry in json.loads(record.read_text())["policies"]:  # restored copies are untracked, not kept
        tracked = subprocess.run([*git, "ls-files", "--error-unmatch", entry["path"]], check=False, capture_output=True)
        assert tracked.returncode != 0, f"{entry['path']} is archived but tracked"
