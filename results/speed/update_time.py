"""Seconds of one PPO update (``trainer.update``) alone, on one fixed rollout, from the same learner
and optimizer state each time: what a change to a learner's update costs, without the
environments (paper preset, unicycle tier, one env worker for the rollout, seed 0; the first
iteration's update is part of the warm-up).

    python results/speed/update_time.py LABEL TASKS ALGOS THREADS REPEATS > out.jsonl

Before/after: run it from a worktree of the earlier commit with ``PYTHONPATH`` set to that
worktree, then from this checkout, alternating (results/speed/README.md).
"""

import copy
import json
import sys
import time

import numpy as np
import torch

from comat.rl import Dims, load_preset, make_learner, make_run_env, resolve


def update_seconds(algo: str, task: str, threads: int, repeats: int) -> list[float]:
    config = resolve(load_preset("paper"), algo, task, seed=0, tier="unicycle", env_workers=1)
    torch.set_num_threads(threads)
    torch.manual_seed(0)
    env = make_run_env(config, config.trainer.num_envs, 0)
    try:
        env.reset()
        learner = make_learner(config, env, Dims.of(env))
        learner.iterate()
        rollout = learner.trainer.collect()
    finally:
        env.close()
    trainer = learner.trainer
    weights = copy.deepcopy(trainer.learner.state_dict())
    optimizer = copy.deepcopy(trainer.optimizer.state_dict())
    return [timed_update(trainer, weights, optimizer, rollout) for _ in range(repeats)]


def timed_update(trainer, weights: dict, optimizer: dict, rollout) -> float:
    """Seconds of one ``trainer.update(rollout)`` from the given learner weights and optimizer
    state, with the same minibatch order every time."""
    trainer.learner.load_state_dict(weights)
    trainer.policy.load_state_dict(weights)
    trainer.optimizer.load_state_dict(copy.deepcopy(optimizer))
    trainer.rng = np.random.default_rng(0)
    start = time.perf_counter()
    trainer.update(rollout)
    return time.perf_counter() - start


if __name__ == "__main__":
    label, tasks, algos, threads, repeats = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4]), int(sys.argv[5])
    for task in tasks.split(","):
        for algo in algos.split(","):
            s = update_seconds(algo, task, threads, repeats)
            row = {"label": label, "algo": algo, "task": task, "threads": threads, "update_s": s}
            print(json.dumps({**row, "median_s": float(np.median(s))}), flush=True)
