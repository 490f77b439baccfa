"""Robotarium export: the folder per task runs under the PyPI rps with zero collision and
boundary errors; only accepted file types; shipped code imports only numpy/scipy/matplotlib/rps
and the standard library; bad input raises clearly and leaves no folder."""

import ast
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from comat.rl.config import resolve
from comat.rl.runner import train
from comat.team import random_team
from sim2real.cli import parse_team
from sim2real.export import (
    ACCEPTED_EXTENSIONS,
    ALLOWED_IMPORTS,
    SHIPPED_FILES,
    check_submission,
    export_submission,
)

pytest.importorskip("rps")

TINY = {"comat": {"embed": 16, "heads": 2, "heat_blocks": 1, "edge_embed": 8}}


def tiny_checkpoint(tmp: Path, task: str) -> Path:
    preset = {"total_env_steps": 12, "eval_every_steps": 10**9, "eval_episodes_per_team": 0,
              "checkpoint_every_steps": 6, "ppo": {"num_envs": 2, "rollout_steps": 3, "epochs": 2, "minibatches": 2},
              "models": TINY}
    train(resolve(preset, "comat", task, seed=3), tmp / f"run_{task}", quiet=True)
    return tmp / f"run_{task}" / "checkpoint.pt"


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    """task -> (checkpoint, folder, check report) for a 4-robot test-set team."""
    tmp = tmp_path_factory.mktemp("export")
    out = {}
    for task in ("pcp", "hmt"):
        ckpt = tiny_checkpoint(tmp, task)
        team = random_team(np.random.default_rng(1), task, "test", 4)
        folder = export_submission(ckpt, task, team, tmp / f"sub_{task}", seed=2)
        out[task] = (ckpt, folder, check_submission(folder, tier="unicycle"))
    return out


@pytest.mark.parametrize("task", ["pcp", "hmt"])
def test_runs_under_rps_without_errors(exported, task):
    report = exported[task][2]
    rps, mj = report["rps"], report["mujoco"]
    assert rps["rps"] == "legacy"
    assert rps["rps_errors"].get("boundary", 0) == 0 and rps["rps_errors"].get("collision", 0) == 0, rps
    assert rps["offset_collision_pair_iterations"] == 0 and rps["boundary_iterations"] == 0
    assert "DEBUG OUTPUT" in rps["stdout"]
    assert 1 <= rps["steps"] <= (80 if task == "pcp" else 70)
    for key in ("return", "completion", "steps"):
        assert np.isfinite(rps[key]) and np.isfinite(mj[key])
    # Same policy, team, start and prey: the episodes stay close (untrained policy, so loosely).
    assert abs(report["gap"]["completion_points"]) <= 10.0 + 1e-9, report["gap"]


@pytest.mark.parametrize("task", ["pcp", "hmt"])
def test_only_accepted_files_and_flat(exported, task):
    folder = exported[task][1]
    entries = sorted(p.name for p in folder.iterdir() if p.name != "__pycache__")
    assert entries == sorted(SHIPPED_FILES)
    for name in entries:
        assert (folder / name).is_file() and Path(name).suffix in ACCEPTED_EXTENSIONS
    record = np.load(folder / "weights.npy", allow_pickle=False)
    assert record.dtype.names == ("manifest", "params")


def _imports(path: Path) -> set[str]:
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            assert node.level == 0, f"{path.name}: relative import"
            names.add(node.module.split(".")[0])
    return names


def test_shipped_code_imports_only_allowed(exported):
    folder = exported["pcp"][1]
    own = {Path(f).stem for f in SHIPPED_FILES if f.endswith(".py")}
    for name in SHIPPED_FILES:
        if name.endswith(".py"):
            bad = _imports(folder / name) - ALLOWED_IMPORTS - set(sys.stdlib_module_names) - own - {"__future__"}
            assert not bad, f"{name} imports {sorted(bad)}"


def test_shipped_files_are_the_sources(exported):
    folder = exported["hmt"][1]
    import comat.task_logic
    import sim2real.runtime

    assert (folder / "task_logic.py").read_bytes() == Path(comat.task_logic.__file__).read_bytes()
    assert (folder / "runtime.py").read_bytes() == Path(sim2real.runtime.__file__).read_bytes()


def _no_leftovers(tmp_path):
    return [p.name for p in tmp_path.iterdir() if p.name.startswith((".sub", "sub"))]


def test_bad_input(exported, tmp_path):
    ckpt = exported["pcp"][0]
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="at most 20 robots"):
        big = random_team(rng, "pcp", "test", 21)
        export_submission(ckpt, "pcp", big, tmp_path / "sub")
    team = random_team(rng, "pcp", "test", 3)
    with pytest.raises(ValueError, match="inside the arena"):
        export_submission(ckpt, "pcp", team, tmp_path / "sub", start_poses=[[1.58, 0, 0.5], [0, 0.5, -0.5], [0, 0, 0]])
    with pytest.raises(ValueError, match="apart"):
        export_submission(ckpt, "pcp", team, tmp_path / "sub", start_poses=[[0, 0.1, 0.5], [0, 0, 0], [0, 0, 0]])
    with pytest.raises(ValueError, match=r"\(3, 3\)"):
        export_submission(ckpt, "pcp", team, tmp_path / "sub", start_poses=np.zeros((3, 2)))
    with pytest.raises(ValueError, match="for task 'pcp', expected 'hmt'"):
        export_submission(ckpt, "hmt", random_team(rng, "hmt", "test", 3), tmp_path / "sub")
    data = torch.load(ckpt, map_location="cpu", weights_only=True)
    data["algo"] = "mat"
    torch.save(data, tmp_path / "mat.pt")
    with pytest.raises(ValueError, match="export supports COMAT"):
        export_submission(tmp_path / "mat.pt", "pcp", team, tmp_path / "sub")
    with pytest.raises(ValueError, match="COMAT policies only"):
        export_submission("heuristic", "pcp", team, tmp_path / "sub")
    with pytest.raises(TypeError, match="COMAT"):
        export_submission(object(), "pcp", team, tmp_path / "sub")
    assert _no_leftovers(tmp_path) == []
    (tmp_path / "sub").mkdir()
    with pytest.raises(FileExistsError):
        export_submission(ckpt, "pcp", team, tmp_path / "sub")


def test_parse_team(tmp_path):
    assert parse_team("test:0", "pcp").task == "pcp"
    with pytest.raises(ValueError, match="index"):
        parse_team("train:99", "hmt")
    with pytest.raises(ValueError, match="JSON file"):
        parse_team(str(tmp_path / "none.json"), "pcp")
