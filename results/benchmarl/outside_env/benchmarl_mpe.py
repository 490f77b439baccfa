"""BenchMARL's own MAPPO on PettingZoo's simple_spread_v3 (mpe2): the outside run of issue 65's check.

BenchMARL's ``PettingZooTask.SIMPLE_SPREAD`` with its own config file, changed only to
``mpe.SETTINGS`` (max_cycles 25 instead of its 100, the env's own default that comat's adapter uses).
One line departs from BenchMARL's own path: TorchRL 0.11.1's ``PettingZooEnv`` looks MPE up in
PettingZoo, which moved it to the ``mpe2`` package (PettingZoo 1.25+ raises "MPE has been moved into its
own package"), so the task's env function builds ``mpe2.simple_spread_v3.parallel_env`` and wraps it in
TorchRL's ``PettingZooWrapper`` with the arguments BenchMARL's ``PettingZooClass`` passes
(categorical actions, the global state, the seed). Groups (``agent``), state, spaces and rewards are
then BenchMARL's and TorchRL's own.

Hyperparameters as in ``../outside.py`` (matched to comat's where both have the knob): 32 environments,
a batch of one horizon each (800 env steps), 5 epochs of 4 minibatches, lr 5e-4, Adam eps 1e-5, clip
0.2, entropy 0.01, value weight 1, gradient-norm clip 10, γ 0.99, λ 0.95, actor one hidden layer of
128, critic two of 128.

    .venv-benchmarl/bin/python results/benchmarl/outside_env/benchmarl_mpe.py train --seed 0 --frames 300000 \\
        --out runs/benchmarl/outside_env/benchmarl_s0
    .venv-benchmarl/bin/python results/benchmarl/outside_env/benchmarl_mpe.py eval --run runs/benchmarl/outside_env/benchmarl_s0

``train`` writes BenchMARL's own folder (CSV logs, final checkpoint without the buffer), ``curve.csv``
(env steps, mean return of the training episodes that ended in each batch), ``run.json`` and
``eval.json`` (``mpe.play``: the actor, deterministic, in PettingZoo's own env).
"""

from __future__ import annotations

import argparse
import csv
import itertools
import json
import os
import sys
import time
from pathlib import Path

import numpy as np
import torch
from benchmarl.algorithms import MappoConfig
from benchmarl.environments import PettingZooTask
from benchmarl.environments.pettingzoo.common import PettingZooClass
from benchmarl.experiment import Callback, Experiment, ExperimentConfig
from benchmarl.models.mlp import MlpConfig
from mpe import SETTINGS, play, write_eval
from tensordict import TensorDict
from torchrl.envs import ExplorationType, set_exploration_type
from torchrl.envs.libs.pettingzoo import PettingZooWrapper

GROUP = "agent"
"""TorchRL's group of simple_spread's agents (agent_0 ... agent_2): one group, parameters shared."""


class Mpe2Spread(PettingZooClass):
    """BenchMARL's SIMPLE_SPREAD task, its env built from mpe2 (module docstring)."""

    distinct_seeds = False
    """BenchMARL builds every environment with the run's seed, so its 32 environments start each batch's
    episodes from one state (README.md, difference 7); True (``--distinct-seeds``, a diagnostic, not
    BenchMARL's behaviour) seeds the k-th environment built with seed + k."""

    def get_env_fun(self, num_envs, continuous_actions, seed, device):
        config = {k: v for k, v in self.config.items() if k != "task"}
        config["continuous_actions"] = continuous_actions
        built = itertools.count()

        def make():
            k = next(built) if self.distinct_seeds and seed is not None else 0
            return PettingZooWrapper(
                make_env_with(config),
                categorical_actions=True,
                return_state=self.has_state(),
                seed=None if seed is None else seed + k,
                device=device,
            )

        return make


def make_env_with(config: dict):
    from mpe2 import simple_spread_v3

    return simple_spread_v3.parallel_env(**config)


class Curve(Callback):
    """Each collected batch: env steps so far and the mean return (over the agents, then over the
    episodes that ended in the batch) of the training episodes."""

    def __init__(self, path: Path) -> None:
        super().__init__()
        self.path, self.rows = path, []

    def on_batch_collected(self, batch):
        done = batch["next", "done"].squeeze(-1)  # (envs, T): the whole team ends together
        ret = batch["next", GROUP, "episode_reward"].mean(-2)[..., 0][done]
        self.rows.append((self.experiment.total_frames, float(ret.mean()) if ret.numel() else ""))
        tmp = self.path.with_suffix(".tmp")
        with open(tmp, "w", newline="") as f:
            csv.writer(f).writerows([("env_steps", "return"), *self.rows])
        os.replace(tmp, self.path)


def experiment_config(frames: int, horizon: int, out: Path) -> ExperimentConfig:
    cfg = ExperimentConfig.get_from_yaml()
    batch = 32 * horizon
    cfg.sampling_device = cfg.train_device = cfg.buffer_device = "cpu"
    cfg.share_policy_params = True
    cfg.prefer_continuous_actions = False
    cfg.gamma, cfg.lr, cfg.adam_eps = 0.99, 5e-4, 1e-5
    cfg.clip_grad_norm, cfg.clip_grad_val = True, 10.0
    cfg.max_n_frames = frames
    cfg.on_policy_collected_frames_per_batch = batch
    cfg.on_policy_n_envs_per_worker = 32
    cfg.on_policy_n_minibatch_iters = 5
    cfg.on_policy_minibatch_size = batch // 4
    cfg.evaluation = False  # eval.json is played in PettingZoo's own env afterwards, the same for both
    cfg.render = False
    cfg.loggers = ["csv"]
    cfg.create_json = False
    cfg.save_folder = str(out)
    cfg.checkpoint_at_end = True
    cfg.exclude_buffer_from_checkpoint = True
    return cfg


def task() -> Mpe2Spread:
    own = PettingZooTask.SIMPLE_SPREAD.get_from_yaml()  # BenchMARL's config file for the task
    config = {**own.config, **{k: v for k, v in SETTINGS.items() if k != "continuous_actions"}}
    return Mpe2Spread(name=own.name, config=config)


def train(args) -> None:
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    algo = MappoConfig.get_from_yaml()
    algo.clip_epsilon, algo.entropy_coef, algo.critic_coef, algo.lmbda = 0.2, 0.01, 1.0, 0.95
    actor = MlpConfig(num_cells=[128], activation_class=torch.nn.ReLU, layer_class=torch.nn.Linear)
    critic = MlpConfig(num_cells=[128, 128], activation_class=torch.nn.ReLU, layer_class=torch.nn.Linear)
    torch.set_num_threads(1)
    spread = task()
    spread.distinct_seeds = args.distinct_seeds
    experiment = Experiment(
        task=spread,
        algorithm_config=algo,
        model_config=actor,
        critic_model_config=critic,
        seed=args.seed,
        config=experiment_config(args.frames, SETTINGS["max_cycles"], out),
        callbacks=[Curve(out / "curve.csv")],
    )
    started = time.perf_counter()
    experiment.run()
    wall = time.perf_counter() - started
    (checkpoint,) = Path(experiment.folder_name, "checkpoints").glob("checkpoint_*.pt")
    meta = {
        "settings": SETTINGS,
        "seed": args.seed,
        "frames": experiment.total_frames,
        "wall_s": wall,
        "checkpoint": str(checkpoint.relative_to(out)),
        "distinct_seeds": bool(args.distinct_seeds),
    }
    (out / "run.json").write_text(json.dumps(meta, indent=1))
    print(f"BenchMARL MAPPO on simple_spread_v3: {experiment.total_frames} env steps in {wall / 60:.1f} min -> {out}")
    evaluate_policy(out, experiment.policy, args.episodes)


def benchmarl_actor(policy):
    """BenchMARL's actor (a TensorDict module over the group) as observation dict -> actions, each
    categorical's mode."""

    def act(obs: dict) -> dict:
        agents = sorted(obs)
        x = torch.as_tensor(np.stack([obs[a] for a in agents]), dtype=torch.float32)
        td = TensorDict({GROUP: TensorDict({"observation": x}, [len(agents)])}, [])
        with torch.no_grad(), set_exploration_type(ExplorationType.DETERMINISTIC):
            td = policy(td)
        return {a: int(td[GROUP, "action"][i]) for i, a in enumerate(agents)}

    return act


def evaluate_policy(out: Path, policy, episodes: int) -> None:
    mean = write_eval(out, play(benchmarl_actor(policy), episodes))
    print(f"eval ({episodes} episodes): " + ", ".join(f"{k} {v:.3f}" for k, v in mean.items()))


def evaluate(args) -> None:
    out = Path(args.run)
    meta = json.loads((out / "run.json").read_text())
    experiment = Experiment.reload_from_file(str(out / meta["checkpoint"]))
    evaluate_policy(out, experiment.policy, args.episodes)


def main(argv=None) -> None:
    from mpe import EPISODES

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    t = sub.add_parser("train", help="train BenchMARL's MAPPO on simple_spread_v3")
    t.add_argument("--seed", type=int, default=0)
    t.add_argument("--frames", type=int, default=300_000, help="env steps (frames) to train for")
    t.add_argument("--out", required=True)
    t.add_argument("--episodes", type=int, default=EPISODES, help="deterministic evaluation episodes after training")
    t.add_argument(
        "--distinct-seeds",
        action="store_true",
        help="seed each environment on its own (BenchMARL seeds them all alike; a diagnostic)",
    )
    e = sub.add_parser("eval", help="play a trained run's actor again")
    e.add_argument("--run", required=True, help="the run folder that train wrote")
    e.add_argument("--episodes", type=int, default=EPISODES)
    args = parser.parse_args(argv)
    (train if args.command == "train" else evaluate)(args)


if __name__ == "__main__":
    sys.exit(main())
