"""End-to-end training throughput of whichever comat is on the path: ``comat bench learn``'s
training part (collect a rollout + learn from it, the paper preset, unicycle tier, the first
iteration untimed), with a task argument, which the commit before issue 48's work lacks.

    python results/speed/throughput.py LABEL TASKS ALGOS WORKERS ITERATIONS > out.jsonl

Before/after in one sitting: run it from a worktree of the earlier commit with ``PYTHONPATH`` set
to that worktree (its workers inherit it), then from this checkout (results/speed/README.md).
"""

import json
import sys
import time

import torch

from comat.rl import Dims, load_preset, make_learner, make_run_env, resolve


def run(algo, task, workers, iterations):
    config = resolve(load_preset("paper"), algo, task, seed=0, tier="unicycle", env_workers=workers)
    torch.set_num_threads(config.torch_threads)
    torch.manual_seed(0)
    env = make_run_env(config, config.trainer.num_envs, 0)
    try:
        env.reset()
        learner = make_learner(config, env, Dims.of(env))
        clock = {"env": 0.0}

        def timed(call):
            def w(*a, **k):
                t0 = time.perf_counter()
                out = call(*a, **k)
                clock["env"] += time.perf_counter() - t0
                return out

            return w

        for name in ("step", "step_recv"):
            if hasattr(env, name):
                setattr(env, name, timed(getattr(env, name)))
        learner.iterate()
        steps = c = u = e = 0.0
        for _ in range(iterations):
            clock["env"] = 0.0
            t0 = time.perf_counter()
            ro = learner.trainer.collect()
            t1 = time.perf_counter()
            learner.trainer.update(ro)
            t2 = time.perf_counter()
            steps += ro.rewards.numel()
            c += t1 - t0
            u += t2 - t1
            e += clock["env"]
    finally:
        env.close()
    return {
        "label": sys.argv[1],
        "algo": algo,
        "task": task,
        "workers": workers,
        "env_steps_per_s": steps / (c + u),
        "env_s": e,
        "act_s": c - e,
        "learn_s": u,
    }


if __name__ == "__main__":
    for task in sys.argv[2].split(","):
        for algo in sys.argv[3].split(","):
            r = run(algo, task, int(sys.argv[4]), int(sys.argv[5]))
            print(json.dumps(r), flush=True)
