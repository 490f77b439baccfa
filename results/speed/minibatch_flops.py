"""Floating-point operations of one PPO minibatch's forward and backward (torch's FlopCounterMode:
matrix products only, exact whatever the machine's load), per learner and task: the arithmetic a
learner's update cannot avoid, against which its seconds can be read.

    python results/speed/minibatch_flops.py TASKS ALGOS > out.jsonl

The minibatch is the first quarter of a rollout (the paper preset's 4 minibatches) collected by
the learner itself (unicycle tier, one env worker, seed 0).
"""

import json
import sys

import torch
from torch.utils.flop_counter import FlopCounterMode

from comat.rl import Dims, load_preset, make_learner, make_run_env, resolve


def minibatch_flops(algo: str, task: str) -> dict:
    config = resolve(load_preset("paper"), algo, task, seed=0, tier="unicycle", env_workers=1)
    torch.manual_seed(0)
    env = make_run_env(config, config.trainer.num_envs, 0)
    try:
        env.reset()
        trainer = make_learner(config, env, Dims.of(env)).trainer
        rollout = trainer.collect()
    finally:
        env.close()
    T, B, N, D = rollout.obs.shape
    teams = T * B // config.trainer.minibatches
    obs, mask = rollout.obs.reshape(T * B, N, D)[:teams], rollout.mask.reshape(T * B, N)[:teams]
    actions = rollout.actions.reshape(T * B, N)[:teams]
    state = None if rollout.state is None else rollout.state.reshape(T * B, -1)[:teams]
    with FlopCounterMode(display=False) as counter:
        logp, entropy, values = trainer.learner.evaluate_actions(obs, mask, actions, state)
        (logp.sum() + entropy.sum() + (values**2).sum()).backward()
    by_op = {str(op): n for op, n in counter.get_flop_counts()["Global"].items()}
    return {
        "algo": algo,
        "task": task,
        "teams": teams,
        "robots": int(mask.sum()),
        "gflop": counter.get_total_flops() / 1e9,
        "gflop_by_op": {k: v / 1e9 for k, v in by_op.items()},
    }


if __name__ == "__main__":
    for task in sys.argv[1].split(","):
        for algo in sys.argv[2].split(","):
            print(json.dumps(minibatch_flops(algo, task)), flush=True)
