"""BenchMARL's own MAPPO on a comat task (issue 50's outside reference, results/benchmarl/).

Runs in .venv-benchmarl (``make test-benchmarl``): BenchMARL 1.5.2 pins TorchRL < 0.12, which the
interop extra's TorchRL 0.14.1 excludes, so the main venv skips this module.
"""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from comat.team import TASK_TYPES

pytestmark = pytest.mark.benchmarl
pytest.importorskip("benchmarl")

ROOT = Path(__file__).resolve().parents[1]
HERE = ROOT / "results" / "benchmarl"
sys.path.insert(0, str(HERE))

from episodes import comat_env, fixed_team, type_groups
from outside import ComatTask

TEAM = HERE / "pcp_team.yaml"


def _outside(*args: str) -> None:
    done = subprocess.run(
        [sys.executable, str(HERE / "outside.py"), *args], check=False, capture_output=True, text=True, cwd=ROOT
    )
    assert done.returncode == 0, done.stderr[-3000:]


def test_the_wrapped_env_groups_the_robots_by_type_and_keeps_comats_spaces():
    team = fixed_team("pcp", str(TEAM))
    horizon = comat_env("pcp", team, "unicycle").task.horizon
    task = ComatTask("PCP", {"task": "pcp", "team": team, "tier": "unicycle", "horizon": horizon})
    env = task.get_env_fun(1, False, 3, "cpu")()
    groups = task.group_map(env)
    assert groups == {"sensing": ["robot_0", "robot_3"], "capture": ["robot_1", "robot_2", "robot_4"]}
    td = env.reset()
    native = comat_env("pcp", team, "unicycle")
    types_of_task = TASK_TYPES["pcp"].types
    for group, agents in groups.items():
        obs = td[group, "observation"].numpy()
        assert obs.shape == (len(agents), native.observation_space(agents[0]).shape[0])
        # Each robot's type one-hot (observation 4 : 4 + types) is its group's type.
        types = np.argmax(obs[:, 4 : 4 + len(types_of_task)], axis=-1)
        assert (types == types_of_task.index(group)).all(), (group, obs[:, :8])
    assert td["state"].shape == native.state_space.shape
    assert env.full_action_spec[("sensing", "action")].space.n == 5


def test_benchmarl_mappo_trains_on_a_fixed_team_and_its_checkpoint_plays_again(tmp_path):
    out = tmp_path / "bm"
    _outside("train", "--task", "pcp", "--team", str(TEAM), "--seed", "1", "--frames", "2560", "--episodes", "2",
             "--out", str(out))  # fmt: skip
    with open(out / "curve.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [int(r["env_steps"]) for r in rows] == [2560]
    assert np.isfinite(float(rows[0]["return"]))  # 32 environments x 80 steps: every episode ended
    run = json.loads((out / "run.json").read_text())
    assert run["frames"] == 2560 and run["team"] == fixed_team("pcp", str(TEAM))
    first = json.loads((out / "eval.json").read_text())
    assert first["episodes"] == 2
    for episode in first["per_episode"]:
        assert 0.0 <= episode["progress"] <= 1.0 and 1 <= episode["steps"] <= 80
    # The checkpoint BenchMARL wrote plays the same deterministic episodes again.
    _outside("eval", "--run", str(out), "--episodes", "2")
    assert json.loads((out / "eval.json").read_text())["per_episode"] == first["per_episode"]


def test_groups_follow_the_team_order_for_any_team():
    team = {"task": "pcp", "robots": [{"type": t, "capabilities": [0.3, 0.0] if t == "sensing" else [0.0, 0.3]}
                                      for t in ("capture", "sensing", "capture")]}  # fmt: skip
    assert type_groups(team) == {"capture": ["robot_0", "robot_2"], "sensing": ["robot_1"]}
