"""BenchMARL's own MAPPO on a comat task (issue 50's outside reference, results/benchmarl/).

Runs in .venv-benchmarl (``make test-benchmarl``): BenchMARL 1.5.2 pins TorchRL < 0.12, which the
interop extra's TorchRL 0.14.1 excludes, so the main venv skips this module.
"""

from __future__ import annotations

import argparse
import csv
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from comat.team import TASK_TYPES

pytestmark = pytest.mark.benchmarl
pytest.importorskip("benchmarl")

ROOT = Path(__file__).resolve().parents[1]
HERE = ROOT / "results" / "benchmarl"
sys.path.insert(0, str(HERE))

from episodes import comat_env, fixed_team, type_groups
from outside import ComatTask, build_experiment

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


# -- issue 65's matched arm: what BenchMARL's MAPPO does, read off the experiment it builds -------------------
MATCHED = HERE / "matched"


def _matched_args(**changes):
    args = {"task": "hmt", "team": str(MATCHED / "team5.yaml"), "seed": 0, "frames": 2240, "tier": "unicycle",
            "checkpoint_every": 0, "normalize_advantage": False}  # fmt: skip
    return argparse.Namespace(**{**args, **changes})


def test_benchmarls_mappo_makes_the_choices_the_matched_arm_copies(tmp_path):
    """matched.yaml's per_robot GAE (λ 0.95), no advantage normalization, GAE-return targets, squared
    value loss without clipping or normalization, and separate actor and critic optimizers each
    clipped at 10: each is what the experiment ``outside.py`` builds has."""
    from torchrl.objectives.value import GAE

    from comat.rl import load_preset, resolve

    experiment, _ = build_experiment(_matched_args(), tmp_path)
    assert experiment.config.clip_grad_norm and experiment.config.clip_grad_val == 10.0
    for group, loss in experiment.losses.items():
        assert loss.normalize_advantage is False
        assert loss.loss_critic_type == "l2" and loss.clip_value is None
        assert float(loss.critic_coeff) == 1.0 and float(loss.entropy_coeff) == pytest.approx(0.01)
        assert float(loss.clip_epsilon) == pytest.approx(0.2)
        assert isinstance(loss.value_estimator, GAE)
        assert float(loss.value_estimator.lmbda) == pytest.approx(0.95)
        assert float(loss.value_estimator.gamma) == pytest.approx(0.99)
        optimizers = experiment.optimizers[group]
        assert set(optimizers) == {"loss_objective", "loss_critic"}
        actor, critic = ({id(p) for g in optimizers[k].param_groups for p in g["params"]} for k in optimizers)
        assert actor and critic and not actor & critic
    ppo = resolve(load_preset(MATCHED / "matched.yaml"), "mappo", "hmt", seed=0).trainer
    chosen = (ppo.advantage, ppo.normalize_advantage, ppo.value_target, ppo.value_loss, ppo.value_norm, ppo.grad_clip)
    assert chosen == ("per_robot", False, "gae", "mse", False, "separate")
    assert (ppo.gae_lambda, ppo.gamma, ppo.entropy_coef, ppo.clip, ppo.max_grad_norm) == (0.95, 0.99, 0.01, 0.2, 10.0)


def test_comats_per_robot_gae_equals_torchrls():
    """comat's ``advantage: per_robot`` on a rollout with a truncation and terminations equals TorchRL's
    GAE (the estimator of BenchMARL's MAPPO), robot by robot, advantages and value targets."""
    from test_ppo_options import GAMMA, LAM, _stub_trainer
    from torchrl.objectives.value.functional import generalized_advantage_estimate

    trainer, ro = _stub_trainer(advantage="per_robot", normalize_advantage=False, value_norm=False)
    _, _, _, adv, returns = trainer._advantages(ro)

    def agents_time(x):  # (T, B, N) -> TorchRL's (B, N, T, 1)
        return x.permute(1, 2, 0)[..., None]

    expand = ro.values.shape
    theirs, target = generalized_advantage_estimate(
        GAMMA,
        LAM,
        agents_time(ro.values),
        agents_time(ro.next_obs[..., 0]),
        agents_time(ro.rewards[..., None].expand(expand)),
        agents_time(ro.dones[..., None].expand(expand)),
        agents_time(ro.terminated[..., None].expand(expand)),
    )
    real = agents_time(ro.mask)
    torch.testing.assert_close(agents_time(adv)[real], theirs[real])
    torch.testing.assert_close(agents_time(returns)[real], target[real])


def test_kept_checkpoints_play_into_an_evaluation_curve(tmp_path):
    """The pilot's BenchMARL curve: ``train --checkpoint-every`` keeps every checkpoint and
    ``eval-checkpoints`` plays each (``eval_curve.csv``); run.json names the final one."""
    out = tmp_path / "bm"
    _outside("train", "--task", "pcp", "--team", str(TEAM), "--seed", "2", "--frames", "5120", "--episodes", "1",
             "--checkpoint-every", "2560", "--out", str(out))  # fmt: skip
    assert json.loads((out / "run.json").read_text())["checkpoint"].endswith("checkpoints/checkpoint_5120.pt")
    _outside("eval-checkpoints", "--run", str(out), "--episodes", "2")
    with open(out / "eval_curve.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [int(r["env_steps"]) for r in rows] == [2560, 5120]
    assert all(0.0 <= float(r["progress"]) <= 1.0 for r in rows)
