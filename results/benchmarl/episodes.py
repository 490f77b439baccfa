"""What both sides of the BenchMARL comparison share: the fixed team, the env and the evaluation.

Plain comat and numpy (no BenchMARL): ``outside.py`` runs it in the BenchMARL venv, ``compare.py``
in comat's own. Both learners' policies are played by :func:`play` in comat's PettingZoo env with
the same episode seeds, so their progress is measured the same way.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from pathlib import Path

import numpy as np

import comat
from comat.envs.base import resolve_coalitions
from comat.tasks import env_id

__all__ = ["EVAL_SEED", "comat_env", "fixed_team", "play", "type_groups", "write_eval"]

#: First seed of the evaluation episodes (episode k plays seed EVAL_SEED + k), the same for both.
EVAL_SEED = 10_000
METRICS = ("return", "progress", "finished", "steps", "collisions")


def fixed_team(task: str, path: str) -> dict:
    """The one team of ``path`` (a comat team file or a one-team coalition file) as a mapping."""
    teams = resolve_coalitions(path, task)
    if len(teams) != 1:
        raise ValueError(f"--team {path!r}: expected a file with one team, got {len(teams)} teams")
    return teams[0].to_dict()


def type_groups(team: dict) -> dict[str, list[str]]:
    """The agents of each robot type: BenchMARL's groups (parameters shared within a group)."""
    groups: dict[str, list[str]] = {}
    for i, robot in enumerate(team["robots"]):
        groups.setdefault(robot["type"], []).append(f"robot_{i}")
    return groups


def comat_env(task: str, team: dict, tier: str):
    """comat's PettingZoo env with ``team`` as its only coalition (its robots are robot_0...)."""
    return comat.make_env(env_id(task), coalitions=[team], tier=tier)


def play(act: Callable[[dict], dict], task: str, team: dict, tier: str, episodes: int) -> list[dict]:
    """``episodes`` episodes of ``act`` (observation dict -> action dict), seeds EVAL_SEED + k:
    each episode's return, progress, finished, steps and collisions (read from the true state)."""
    env, rows = comat_env(task, team, tier), []
    for k in range(episodes):
        obs, infos = env.reset(seed=EVAL_SEED + k)
        while env.agents:
            obs, _, _, _, infos = env.step(act(obs))
        rows.append({key: float(infos["robot_0"][f"episode/{key}"]) for key in METRICS})
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
