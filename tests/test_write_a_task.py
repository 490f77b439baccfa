"""docs/write-a-task.md, run as written (issue 49): its task module registered through COMAT_TASKS,
listed, trained for a few steps, evaluated, recorded, exported and checked under the PyPI rps."""

import functools
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from test_policy_file import TINY_CLI

from comat.tasks import check_task, load_plugins

PAGE = Path(__file__).resolve().parents[1] / "docs" / "write-a-task.md"
TINY = TINY_CLI  # a 20-step run with a small COMAT (test_policy_file.py)


def _module() -> str:
    """The page's first python block: the task module."""
    blocks = re.findall(r"```python\n(.*?)```", PAGE.read_text(), flags=re.DOTALL)
    assert blocks and blocks[0].startswith("# gather_example.py"), "the page's first python block is the module"
    return blocks[0]


@functools.cache
def page_task() -> type:
    """The page's task class (``Gather``), its module run as ``gather_example``."""
    space = {"__name__": "gather_example"}
    exec(compile(_module(), "gather_example.py", "exec"), space)  # noqa: S102 - the page's own code
    return space["Gather"]


def test_the_page_s_task_keeps_the_contract():
    means = check_task(page_task())
    # a crawler the type's mean speed sends far but too slow for it, or that the blind plan sends far, arrives nowhere
    assert means["heuristic"] > means["type_only"] and means["heuristic"] > means["blind"] > means["random"]


def _comat(args, folder: Path, check=True) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(folder), "COMAT_TASKS": "gather_example:Gather"}
    cmd = [sys.executable, "-m", "comat.cli.main", *args]
    proc = subprocess.run(cmd, cwd=folder, env=env, capture_output=True, text=True, timeout=600, check=False)
    if check:
        assert proc.returncode == 0, f"{' '.join(args)}\n{proc.stdout[-2000:]}\n{proc.stderr[-3000:]}"
    return proc


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    folder = tmp_path_factory.mktemp("gather")
    (folder / "gather_example.py").write_text(_module())
    return folder


@pytest.mark.learning  # it trains (20 env steps, ~25 s with its six subprocesses): the learning tier CI runs
def test_the_page_s_task_is_listed_and_runs_through_every_command(folder):
    out = _comat(["tasks"], folder).stdout
    assert "gather (gather_v0)" in out and "'scout'" in out and "'crawler'" in out
    _comat(["train", "--algo", "comat", "--task", "gather", "--out", "run", "--quiet", *TINY], folder)
    assert (folder / "run" / "policy.pt").is_file()
    evaluation = _comat(["eval", "--policy", "run", "--task", "gather", "--teams", "val", "--out", "eval"], folder)
    assert "heuristic" in evaluation.stdout and "comat" in evaluation.stdout
    _comat(["rollout", "--policy", "run", "--task", "gather", "--team", "test:0", "--out", "ep.rrd"], folder)
    assert (folder / "ep.rrd").stat().st_size > 10_000
    _comat(["export", "--policy", "heuristic", "--task", "gather", "--team", "test:0", "--out", "sub"], folder)
    assert (folder / "sub" / "task_gather.py").is_file()
    check = _comat(["export", "--check", "sub", "--tier", "unicycle"], folder)
    assert "finished" in check.stdout + check.stderr


def test_a_bad_entry_is_named():
    with pytest.raises(
        ValueError, match="^COMAT_TASKS entry 'no_such_module:Task': module 'no_such_module' did not import"
    ):
        load_plugins("no_such_module:Task")
    with pytest.raises(ValueError, match="expected module:Class"):
        load_plugins("just_a_module")
