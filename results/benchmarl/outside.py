"""An outside reference for comat's MAPPO (issue 50): BenchMARL's own MAPPO trains on a comat task.

BenchMARL (Meta's TorchRL-based MARL benchmarking library) and TorchRL's ``PettingZooWrapper`` are
code that someone else wrote; comat only supplies the environment: ``comat.make_env`` with one
fixed team (a coalition set of one), wrapped by TorchRL as any PettingZoo parallel env is. The
robots are grouped by type, and BenchMARL shares parameters within a group, so its actors are
shared within a type as comat's MAPPO's are; its critic is centralized on the env's global state.

Hyperparameters follow comat's ``paper`` preset wherever BenchMARL has the same knob (32
environments, a batch of one horizon per environment, 5 epochs of 4 minibatches, lr 5e-4, Adam eps
1e-5, clip 0.2, entropy 0.01, value weight 1, gradient-norm clip 10, γ 0.99, λ 0.95, hidden width
128). What BenchMARL does its own way is listed in ``README.md`` beside this file.

Runs in the BenchMARL environment (``make benchmarl-venv``: BenchMARL 1.5.2 pins TorchRL < 0.12,
which cannot share a venv with the interop extra's TorchRL 0.14.1)::

    .venv-benchmarl/bin/python results/benchmarl/outside.py train --task pcp --team results/benchmarl/pcp_team.yaml \
        --seed 0 --frames 300000 --out runs/benchmarl/bm_pcp_s0
    .venv-benchmarl/bin/python results/benchmarl/outside.py eval --run runs/benchmarl/bm_pcp_s0 --episodes 20

``train`` writes BenchMARL's own folder (its CSV logs and final checkpoint, without the buffer),
``curve.csv`` (env steps, mean return of the training episodes that ended in each batch),
``run.json`` and ``eval.json``: the actors played deterministically in comat's own PettingZoo env
(no TorchRL wrapper) on fixed episode seeds, as ``compare.py`` plays comat's MAPPO. ``eval``
plays a run's checkpoint again. ``train --checkpoint-every FRAMES`` keeps a checkpoint every so many
frames, and ``eval-checkpoints`` plays each of them (``eval_curve.csv``: the deterministic progress
curve of issue 65's pilot, ``matched/``).
"""

from __future__ import annotations

import argparse
import csv
import itertools
import json
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch
from benchmarl.algorithms import MappoConfig
from benchmarl.environments.pettingzoo.common import PettingZooClass
from benchmarl.experiment import Callback, Experiment, ExperimentConfig
from benchmarl.models.mlp import MlpConfig
from episodes import comat_env, fixed_team, play, type_groups, write_eval
from tensordict import TensorDict
from torchrl.envs import DoubleToFloat, ExplorationType, set_exploration_type
from torchrl.envs.libs.pettingzoo import PettingZooWrapper


class ComatTask(PettingZooClass):
    """A comat task with one fixed team, as a BenchMARL task (discrete actions, global state)."""

    distinct_seeds = False
    """BenchMARL builds every environment with the run's seed, so its 32 environments start each
    batch's episodes from one state (outside_env/README.md, difference 7). True (``--distinct-seeds``;
    the matched arm's setting, not BenchMARL's behaviour) seeds the k-th environment built with
    seed + k, as comat's vector env seeds each of its environments on its own."""

    def get_env_fun(self, num_envs, continuous_actions, seed, device):
        cfg = dict(self.config)
        built = itertools.count()

        def make():
            k = next(built) if self.distinct_seeds and seed is not None else 0
            return PettingZooWrapper(
                comat_env(cfg["task"], cfg["team"], cfg["tier"]),
                group_map=type_groups(cfg["team"]),
                categorical_actions=True,
                return_state=True,
                seed=None if seed is None else seed + k,
                device=device,
            )

        return make

    def get_env_transforms(self, env):
        return [DoubleToFloat()]  # comat's observations and state are float64; BenchMARL's networks float32

    def supports_continuous_actions(self) -> bool:
        return False

    def supports_discrete_actions(self) -> bool:
        return True

    def has_state(self) -> bool:
        return True

    def has_render(self, env) -> bool:
        return False

    def max_steps(self, env) -> int:
        return int(self.config["horizon"])

    def group_map(self, env):
        return type_groups(self.config["team"])

    @staticmethod
    def env_name() -> str:
        return "comat"


class Curve(Callback):
    """Each collected batch: env steps so far and the mean return of the episodes that ended in it
    (TorchRL's wrapper keeps no info key that is absent at reset, so progress is measured by
    ``eval``; the return is the same reward in both learners' logs)."""

    def __init__(self, path: Path, group: str) -> None:
        super().__init__()
        self.path, self.group, self.rows = path, group, []

    def on_batch_collected(self, batch):
        done = batch["next", "done"].squeeze(-1)  # (envs, T): the whole team ends together
        ret = batch["next", self.group, "episode_reward"][..., 0, 0][done]
        steps = self.experiment.total_frames
        self.rows.append((steps, float(ret.mean()) if ret.numel() else ""))
        tmp = self.path.with_suffix(".tmp")
        with open(tmp, "w", newline="") as f:
            csv.writer(f).writerows([("env_steps", "return"), *self.rows])
        os.replace(tmp, self.path)


def experiment_config(frames: int, horizon: int, out: Path, checkpoint_every: int = 0) -> ExperimentConfig:
    """BenchMARL's experiment settings matched to comat's ``paper`` preset (module docstring);
    ``checkpoint_every``: keep a checkpoint every so many frames (0: the final one only)."""
    cfg = ExperimentConfig.get_from_yaml()
    batch = 32 * horizon
    cfg.sampling_device = cfg.train_device = cfg.buffer_device = "cpu"
    cfg.share_policy_params = True  # within a group, i.e. within a robot type
    cfg.prefer_continuous_actions = False
    cfg.gamma, cfg.lr, cfg.adam_eps = 0.99, 5e-4, 1e-5
    cfg.clip_grad_norm, cfg.clip_grad_val = True, 10.0
    cfg.max_n_frames = frames
    cfg.on_policy_collected_frames_per_batch = batch
    cfg.on_policy_n_envs_per_worker = 32
    cfg.on_policy_n_minibatch_iters = 5  # epochs: each pass is batch // minibatch_size minibatches
    cfg.on_policy_minibatch_size = batch // 4
    cfg.evaluation = False  # eval.json is played in comat's own env afterwards, the same for both
    cfg.render = False
    cfg.loggers = ["csv"]
    cfg.create_json = False
    cfg.save_folder = str(out)
    cfg.checkpoint_at_end = True
    cfg.checkpoint_interval = checkpoint_every
    if checkpoint_every:
        cfg.keep_checkpoints_num = None  # all of them
    cfg.exclude_buffer_from_checkpoint = True  # the networks and optimizers only: small enough to commit
    return cfg


def build_experiment(args, out: Path) -> tuple[Experiment, dict]:
    """BenchMARL's MAPPO experiment on the fixed team of ``args`` (not yet run) and the team."""
    team = fixed_team(args.task, args.team)
    horizon = comat_env(args.task, team, args.tier).task.horizon
    task = ComatTask(args.task.upper(), {"task": args.task, "team": team, "tier": args.tier, "horizon": horizon})
    task.distinct_seeds = bool(getattr(args, "distinct_seeds", False))
    algo = MappoConfig.get_from_yaml()
    algo.clip_epsilon, algo.entropy_coef, algo.critic_coef, algo.lmbda = 0.2, 0.01, 1.0, 0.95
    actor = MlpConfig(num_cells=[128], activation_class=torch.nn.ReLU, layer_class=torch.nn.Linear)
    critic = MlpConfig(num_cells=[128, 128], activation_class=torch.nn.ReLU, layer_class=torch.nn.Linear)
    torch.set_num_threads(1)
    groups = list(type_groups(team))
    experiment = Experiment(
        task=task,
        algorithm_config=algo,
        model_config=actor,
        critic_model_config=critic,
        seed=args.seed,
        config=experiment_config(args.frames, horizon, out, args.checkpoint_every),
        callbacks=[Curve(out / "curve.csv", groups[0])],
    )
    if args.normalize_advantage:  # a diagnostic, not BenchMARL's MAPPO: README.md, "Why HMT differs"
        for loss in experiment.losses.values():
            loss.normalize_advantage = True
    return experiment, team


def train(args) -> None:
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    experiment, team = build_experiment(args, out)
    started = time.perf_counter()
    experiment.run()
    wall = time.perf_counter() - started
    checkpoint = Path(experiment.folder_name, "checkpoints", f"checkpoint_{experiment.total_frames}.pt")
    meta = {
        "task": args.task,
        "team": team,
        "tier": args.tier,
        "seed": args.seed,
        "frames": experiment.total_frames,
        "wall_s": wall,
        "checkpoint": str(checkpoint.relative_to(out)),
        "normalize_advantage": bool(args.normalize_advantage),
        "distinct_seeds": bool(args.distinct_seeds),
    }
    (out / "run.json").write_text(json.dumps(meta, indent=1))
    print(f"BenchMARL MAPPO on {args.task}: {experiment.total_frames} env steps in {wall / 60:.1f} min -> {out}")
    evaluate_policy(out, experiment.policy, meta, args.episodes)


def benchmarl_actor(policy, team: dict) -> Callable[[dict], dict]:
    """BenchMARL's actors (a TensorDict module over the type groups) as observation dict -> actions,
    deterministic (each categorical's mode)."""
    groups = type_groups(team)

    def act(obs: dict) -> dict:
        td = TensorDict(
            {
                g: TensorDict(
                    {"observation": torch.as_tensor(np.stack([obs[a] for a in agents]), dtype=torch.float32)},
                    [len(agents)],
                )
                for g, agents in groups.items()
            },
            [],
        )
        with torch.no_grad(), set_exploration_type(ExplorationType.DETERMINISTIC):
            td = policy(td)
        return {a: int(td[g, "action"][i]) for g, agents in groups.items() for i, a in enumerate(agents)}

    return act


def evaluate_policy(out: Path, policy, meta: dict, episodes: int) -> None:
    rows = play(benchmarl_actor(policy, meta["team"]), meta["task"], meta["team"], meta["tier"], episodes)
    mean = write_eval(out, rows)
    print(f"eval ({episodes} episodes): " + ", ".join(f"{k} {v:.3f}" for k, v in mean.items()))


def evaluate(args) -> None:
    """Play a finished run's policy again from its BenchMARL checkpoint (the run folder's run.json)."""
    out = Path(args.run)
    meta = json.loads((out / "run.json").read_text())
    experiment = Experiment.reload_from_file(str(out / meta["checkpoint"]))
    evaluate_policy(out, experiment.policy, meta, args.episodes)


def evaluate_checkpoints(args) -> None:
    """Play every checkpoint a run kept (``train --checkpoint-every``): ``eval_curve.csv`` with the
    frames and the mean return, progress and finished share of ``--episodes`` deterministic episodes."""
    out = Path(args.run)
    meta = json.loads((out / "run.json").read_text())
    found = sorted((int(p.stem.rpartition("_")[2]), p) for p in out.glob("*/checkpoints/checkpoint_*.pt"))
    rows = [("env_steps", "return", "progress", "finished")]
    for frames, path in found:
        policy = Experiment.reload_from_file(str(path)).policy
        episodes = play(benchmarl_actor(policy, meta["team"]), meta["task"], meta["team"], meta["tier"], args.episodes)
        rows.append((frames, *(float(np.mean([e[k] for e in episodes])) for k in ("return", "progress", "finished"))))
        print(f"{frames}: " + ", ".join(f"{k} {v:.3f}" for k, v in zip(rows[0][1:], rows[-1][1:])))
    with open(out / "eval_curve.csv", "w", newline="") as f:
        csv.writer(f).writerows(rows)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    t = sub.add_parser("train", help="train BenchMARL's MAPPO on one fixed comat team")
    t.add_argument("--task", default="pcp")
    t.add_argument("--team", required=True, help="a comat team file (YAML/JSON) or a one-team coalition file")
    t.add_argument("--seed", type=int, default=0)
    t.add_argument("--frames", type=int, default=300_000, help="env steps (frames) to train for")
    t.add_argument("--tier", default="unicycle")
    t.add_argument("--out", required=True)
    t.add_argument("--episodes", type=int, default=20, help="deterministic evaluation episodes after training")
    t.add_argument("--checkpoint-every", type=int, default=0, help="keep a checkpoint every so many frames")
    t.add_argument(
        "--normalize-advantage",
        action="store_true",
        help="standardize each group's advantages per minibatch (BenchMARL's MAPPO does not; a diagnostic)",
    )
    t.add_argument(
        "--distinct-seeds",
        action="store_true",
        help="seed each environment on its own (BenchMARL seeds them all alike; the matched arm's setting)",
    )
    e = sub.add_parser("eval", help="play a trained run's policy again in comat's env")
    e.add_argument("--run", required=True, help="the run folder that train wrote")
    e.add_argument("--episodes", type=int, default=20)
    c = sub.add_parser("eval-checkpoints", help="play every checkpoint a run kept: eval_curve.csv")
    c.add_argument("--run", required=True, help="the run folder that train --checkpoint-every wrote")
    c.add_argument("--episodes", type=int, default=20)
    args = parser.parse_args(argv)
    {"train": train, "eval": evaluate, "eval-checkpoints": evaluate_checkpoints}[args.command](args)


if __name__ == "__main__":
    sys.exit(main())
