"""The house's budgets (tools/budgets.py, run by ``make lint``): each fails on what it guards
against, planted in a copy, and the tree as it is passes."""

from __future__ import annotations

import importlib.util
import re
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "tools" / "budgets.py"
_spec = importlib.util.spec_from_file_location("budgets", SCRIPT)
budgets = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(budgets)
HAS_DUPLICATES = shutil.which("duplicates") is not None
HAS_GIT = shutil.which("git") is not None


def _run(root: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, str(SCRIPT), "--root", str(root), *args], capture_output=True, text=True, check=False
    )


def _copy(files: list[str], dest: Path) -> None:
    for name in files:
        (dest / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(ROOT / name, dest / name)


@pytest.fixture(scope="module")
def code_copy(tmp_path_factory) -> Path:
    """comat/, sim2real/ and tools/budgets.toml as the checker sees them here (a plain folder, no git)."""
    dest = tmp_path_factory.mktemp("tree")
    _copy([*budgets.tree_files(ROOT, "comat"), *budgets.tree_files(ROOT, "sim2real"), "tools/budgets.toml"], dest)
    (dest / "results").mkdir()
    return dest


def _long_function(name: str, lines: int, mark: str = "") -> str:
    body = "".join(f"    total += {i} * x  # step {i}\n" for i in range(lines - 3))
    return f"def {name}(x):{mark}\n    total = 0\n{body}    return total\n"


def test_the_tree_as_it_is_keeps_every_budget():
    """What `make lint` runs, on this checkout: exit 0, a line per budget."""
    done = _run(ROOT)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "results/" in done.stdout and "functions over 80 lines" in done.stdout
    assert ("duplicates in comat/" in done.stdout) if HAS_DUPLICATES else ("not checked" in done.stdout)


def test_a_3_mb_result_file_fails(code_copy, tmp_path):
    tree = tmp_path / "t"
    shutil.copytree(code_copy / "tools", tree / "tools")
    (tree / "results" / "study").mkdir(parents=True)
    (tree / "results" / "study" / "big.bin").write_bytes(b"\0" * 3_000_000)
    done = _run(tree)
    assert done.returncode == 1
    assert "FAIL results/study/big.bin weighs 3.0 MB, over the 2 MB" in done.stdout
    toml = tree / "tools" / "budgets.toml"  # named with a reason, it passes
    toml.write_text(toml.read_text() + '"results/study/big.bin" = "a test of the allow-list"\n')
    assert _run(tree).returncode == 0


def test_a_run_checkpoint_under_results_fails(code_copy, tmp_path):
    """A kept run keeps its policy.pt; its checkpoint.pt (optimizer, critic, buffers) fails, whatever its size."""
    tree = tmp_path / "t"
    shutil.copytree(code_copy / "tools", tree / "tools")
    run = tree / "results" / "study" / "runs" / "comat_pcp_s0"
    run.mkdir(parents=True)
    (run / "policy.pt").write_bytes(b"\0" * 1000)
    assert _run(tree).returncode == 0
    (run / "checkpoint.pt").write_bytes(b"\0" * 1000)
    done = _run(tree)
    assert done.returncode == 1
    assert "FAIL results/study/runs/comat_pcp_s0/checkpoint.pt is a run's checkpoint" in done.stdout


def test_results_over_100_mb_fail(code_copy, tmp_path):
    """51 files of 1.99 MB each (sparse: no disk used): each under the file budget, together over 100 MB."""
    tree = tmp_path / "t"
    shutil.copytree(code_copy / "tools", tree / "tools")
    (tree / "results").mkdir()
    for i in range(51):
        with open(tree / "results" / f"part{i}.bin", "wb") as fh:
            fh.truncate(1_990_000)
    done = _run(tree)
    assert done.returncode == 1 and "FAIL results/ weighs 101.5 MB, over its budget of 100 MB" in done.stdout
    (tree / "results" / "part50.bin").unlink()
    assert _run(tree).returncode == 0


def test_a_120_line_function_fails_unless_it_says_why(code_copy):
    """Planted in a copy of comat/: a 120-line function fails (exit 1, named), an 80-line one does not;
    a '# long:' reason on the def line lets it pass, one further down the body does not."""
    planted = code_copy / "comat" / "planted_long.py"
    limit = {"function_lines": 80}
    try:
        planted.write_text(_long_function("planted", 120) + "\n\n" + _long_function("short_enough", 80))
        done = _run(code_copy)
        assert done.returncode == 1
        assert "FAIL comat/planted_long.py:1 planted has 120 lines, over 80" in done.stdout
        assert "short_enough" not in done.stdout
        planted.write_text(_long_function("planted", 120, "  # long: a test of the reason"))
        assert not any("planted_long" in p for p in budgets.check_functions(code_copy, limit))
        lines = _long_function("planted", 120).splitlines(keepends=True)
        planted.write_text("".join(lines[:10] + ["    # long: too late\n"] + lines[10:]))
        assert any("planted_long.py:1 planted has 121 lines" in p for p in budgets.check_functions(code_copy, limit))
    finally:
        planted.unlink(missing_ok=True)


@pytest.mark.skipif(not HAS_DUPLICATES, reason="the duplicates tool is not on PATH (developers' library)")
def test_a_planted_duplicate_pair_fails(code_copy):
    """A copy of comat/ within its budget; one more pair (the same seven lines twice) breaks it."""
    count, _ = budgets.count_duplicates(code_copy / "comat")
    assert count is not None and count <= budgets.load_budgets(ROOT)["duplicate_pairs"]
    # The copy's budget at its own count: the main budget may sit a pair or two above the tree's
    # count between a merge and the commit that lowers it, and one planted pair must still break it.
    toml = code_copy / "tools" / "budgets.toml"
    original = toml.read_text()
    toml.write_text(re.sub(r"(?m)^duplicate_pairs = \d+", f"duplicate_pairs = {count}", original))
    body = textwrap.dedent(
        """
        weights = [abs(v) for v in values if v is not None]
        scale = max(weights) if weights else 1.0
        shifted = [w / scale - offset for w in weights]
        kept = [s for s in shifted if s > threshold]
        ranked = sorted(kept, reverse=True)[:limit]
        summary = {"n": len(ranked), "top": ranked[0] if ranked else None}
        return summary, ranked
        """
    )
    block = textwrap.indent(body, "    ")
    planted = code_copy / "comat" / "planted_twice.py"
    try:
        args = "(values, offset, threshold, limit):"
        planted.write_text(f"def first{args}{block}\n\ndef second{args}{block}")
        done = _run(code_copy)
        assert done.returncode == 1, done.stdout
        assert f"FAIL comat/ has {count + 1} duplicate pairs" in done.stdout
    finally:
        planted.unlink()
        toml.write_text(original)


def test_without_the_duplicates_tool_it_says_so_in_one_line(code_copy, monkeypatch):
    monkeypatch.setattr(budgets.shutil, "which", lambda name: None)
    assert budgets.count_duplicates(code_copy / "comat")[0] is None
    assert budgets.check_duplicates(code_copy, {"duplicate_pairs": 0}) == []


@pytest.mark.skipif(not HAS_GIT, reason="git is not installed")
def test_pack_growth_counts_commits_and_new_results(tmp_path):
    """A 200 kB random file committed since the base and a 100 kB one not yet added: about 0.2 MB of
    commits and at most 0.1 MB of files (random bytes do not compress); a file git already holds adds 0."""
    repo = tmp_path / "repo"
    (repo / "results").mkdir(parents=True)
    git = ["git", "-C", str(repo), "-c", "user.name=t", "-c", "user.email=t@t"]
    subprocess.run([*git, "init", "-q"], check=True)
    (repo / "results" / "a.txt").write_text("kept\n")
    subprocess.run([*git, "add", "."], check=True)
    subprocess.run([*git, "commit", "-qm", "base"], check=True)
    rng = __import__("random").Random(0)
    (repo / "results" / "b.bin").write_bytes(rng.randbytes(200_000))
    subprocess.run([*git, "add", "."], check=True)
    subprocess.run([*git, "commit", "-qm", "b"], check=True)
    (repo / "results" / "c.bin").write_bytes(rng.randbytes(100_000))
    (repo / "results" / "copy_of_b.bin").write_bytes((repo / "results" / "b.bin").read_bytes())
    done = _run(repo, "pack-growth", "--base", "HEAD~1")
    assert done.returncode == 0, done.stderr
    assert "commits since HEAD~1: 1, 0.20 MB as a thin pack" in done.stdout
    assert "uncommitted under results: 2 files, 0.30 MB, at most 0.10 MB packed" in done.stdout
    assert _run(repo, "pack-growth", "--base", "nope").returncode == 2
