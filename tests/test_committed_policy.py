"""A policy committed under ``results/policies/`` evaluates from a fresh clone with one command
(issue 28): ``comat eval --policy <its folder> --teams capability``. CI runs the suite on a fresh
clone, so the file read here is the one git holds, not one a training run left behind."""

import shutil
import subprocess
from pathlib import Path

import pytest

from comat.cli import main
from comat.measure.metrics import read_results

ROOT = Path(__file__).resolve().parents[1]
KEPT = ROOT / "results" / "policies" / "comat_pcp_s0"
MAX_POLICY_BYTES = 1_000_000
"""What a kept policy may weigh to be committed with every run (COMAT's is 527 KB)."""


@pytest.mark.skipif(shutil.which("git") is None or not (ROOT / ".git").exists(), reason="not a git checkout")
def test_the_kept_policy_is_committed_and_small():
    tracked = subprocess.run(
        ["git", "-C", str(ROOT), "ls-files", str(KEPT.relative_to(ROOT))], capture_output=True, text=True, check=True
    ).stdout.split()
    names = {Path(p).name for p in tracked}
    assert {"policy.pt", "config.yaml", "evaluation_unicycle.json"} <= names, names
    assert "checkpoint.pt" not in names  # optimizer state is not what a reader needs
    assert (KEPT / "policy.pt").stat().st_size < MAX_POLICY_BYTES


def test_a_committed_policy_evaluates_on_the_capability_set_with_one_command(tmp_path, capsys):
    out = tmp_path / "cap"
    assert (
        main(
            [
                "eval",
                "--policy",
                str(KEPT),
                "--teams",
                "capability",
                "--episodes",
                "1",
                "--no-references",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    result = read_results(out / "evaluation_unicycle.json")
    (row,) = result["rows"]
    assert (row["policy"], row["task"], row["set"], row["episodes"]) == ("comat", "pcp", "capability", 20)
    assert [e["coalition"] for e in row["per_episode"]] == list(range(20))
    assert all(e["robots"] and e["by_type"] for e in row["per_episode"])
    # The policy does the task on robots it never saw: its committed 5-episode evaluation captured
    # 99 % of the prey on U_cap; a random policy captures under 10 % (results/sets/validity.md).
    # Not an exact match: another CPU may order the network's sums differently (README).
    assert row["metrics"]["progress"]["mean"] > 0.8
    assert "comat" in capsys.readouterr().out
