"""Run whole episodes of a policy on a vector env and collect their metrics."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from comat.envs.vector import VectorEnv
from comat.team import TeamSpec

__all__ = ["episodes_per_team"]


def episodes_per_team(
    env: VectorEnv, policy: Callable[[VectorEnv], np.ndarray], teams: Sequence[TeamSpec], seed: int | None = None
) -> list[dict[str, float]]:
    """One episode for each team (env b runs ``teams[b]``), with ``policy(env) -> actions (B, N)``.

    Returns the episodes' metrics (:data:`comat.envs.core.EPISODE_METRICS`), in team order.
    """
    if len(teams) != env.num_envs:
        raise ValueError(f"teams must list one team per environment ({env.num_envs}), got {len(teams)}")
    env.fixed_team = None
    draw = env._draw
    env._draw = lambda b: teams[b]
    try:
        env.reset(seed)
        results: dict[int, dict[str, float]] = {}
        while len(results) < env.num_envs:
            _, _, _, _, info = env.step(policy(env))
            if "_episode" in info:
                for b in np.flatnonzero(info["_episode"]):
                    results.setdefault(int(b), {k: float(v[b]) for k, v in info["episode"].items()})
    finally:
        env._draw = draw
    return [results[b] for b in range(env.num_envs)]
