"""What both sides of the outside-env comparison share: the task, its settings and the evaluation.

Plain numpy and mpe2 (no BenchMARL, no comat learner): ``benchmarl_mpe.py`` runs it in the BenchMARL
venv, ``compare.py`` in comat's own. Both learners' actors play the same episodes of PettingZoo's own
``simple_spread_v3`` (mpe2), not comat's adapter (:mod:`comat.envs.outside`), so a defect of the adapter
cannot favour one side in the evaluation.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from pathlib import Path

import numpy as np
from mpe2 import simple_spread_v3

__all__ = ["EPISODES", "EVAL_SEED", "SETTINGS", "TASK", "make_env", "play", "write_eval"]

TASK = "outside:mpe2.simple_spread_v3"
"""comat's name for the task (``comat train --task``)."""
SETTINGS = {"N": 3, "local_ratio": 0.5, "max_cycles": 25, "continuous_actions": False}
"""simple_spread_v3's own defaults, which comat's adapter builds it with; BenchMARL's task config
(pettingzoo/simple_spread.yaml: max_cycles 100) is set to them."""
EVAL_SEED = 20_000
"""Episode k of the evaluation is ``reset(seed=EVAL_SEED + k)``, the same for both learners."""
EPISODES = 100
METRICS = ("return", "final_distance", "collisions")


def make_env():
    """PettingZoo's simple_spread_v3 (mpe2) with :data:`SETTINGS`: 3 agents, 3 landmarks, 25 steps."""
    return simple_spread_v3.parallel_env(**SETTINGS)


def _landmark_distance(world) -> float:
    """Sum over landmarks of the distance to the nearest agent (what simple_spread's global reward is
    the negative of)."""
    agents = np.array([a.state.p_pos for a in world.agents])
    marks = np.array([m.state.p_pos for m in world.landmarks])
    return float(np.linalg.norm(marks[:, None] - agents[None], axis=-1).min(1).sum())


def _collisions(world) -> int:
    """Agent pairs in contact now (simple_spread's is_collision: centres closer than the two sizes)."""
    p = np.array([a.state.p_pos for a in world.agents])
    size = np.array([a.size for a in world.agents])
    d = np.linalg.norm(p[:, None] - p[None], axis=-1)
    return int(np.triu(d < size[:, None] + size[None], 1).sum())


def play(act: Callable[[dict], dict], episodes: int = EPISODES) -> list[dict]:
    """``episodes`` episodes of ``act`` (observation dict -> action dict), seeds EVAL_SEED + k: each
    episode's return (the sum over steps of the agents' mean reward, the quantity both learners train
    on and log), the landmarks' summed distance to their nearest agent at the end, and the agent-pair
    collisions summed over the steps."""
    env, rows = make_env(), []
    for k in range(episodes):
        obs, _ = env.reset(seed=EVAL_SEED + k)
        ret, hits = 0.0, 0
        while env.agents:
            obs, rewards, _, _, _ = env.step(act(obs))
            ret += float(np.mean(list(rewards.values())))
            hits += _collisions(env.unwrapped.world)
        rows.append({"return": ret, "final_distance": _landmark_distance(env.unwrapped.world), "collisions": hits})
    env.close()
    return rows


def write_eval(out: Path, rows: list[dict], name: str = "eval.json") -> dict:
    """The episodes and their means, written atomically to ``out/name``; returns the means."""
    mean = {key: float(np.mean([r[key] for r in rows])) for key in METRICS}
    tmp = Path(out, name + ".tmp")
    tmp.write_text(
        json.dumps({"episodes": len(rows), "eval_seed": EVAL_SEED, "mean": mean, "per_episode": rows}, indent=1)
    )
    os.replace(tmp, Path(out, name))
    return mean
