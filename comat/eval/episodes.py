"""Evaluation episodes: given teams, run each for one episode with a policy, collect metrics.

A policy here is any callable ``act(obs (B, N, D), mask (B, N), state (B, S) or None) ->
actions (B, N)`` on numpy arrays — a trained model (``comat.rl.runner.load_policy``), the
scripted heuristic, or random actions.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from comat.envs.core import EPISODE_METRICS
from comat.envs.vector import VectorEnv
from comat.team import TeamSpec

__all__ = ["Policy", "run_episodes", "summarize"]

Policy = Callable[[np.ndarray, np.ndarray, "np.ndarray | None"], np.ndarray]


def run_episodes(env: VectorEnv, act: Policy, teams: list[TeamSpec], seed: int, use_state: bool = False) -> list[dict]:
    """One episode per entry of ``teams``, ``env.num_envs`` at a time; returns their metrics
    (``EPISODE_METRICS`` plus ``team_size``), in the order of ``teams``.

    Chunk k is reset with seed ``seed + k``, so the result depends only on the policy, the
    teams and the seed. A short last chunk is filled with repeats that are not reported.
    """
    B = env.num_envs
    results: list[dict] = []
    for k, start in enumerate(range(0, len(teams), B)):
        chunk = list(teams[start : start + B])
        n_real = len(chunk)
        chunk += [chunk[i % n_real] for i in range(B - n_real)]
        obs, info = env.reset(seed=seed + k, teams=chunk)
        mask = info["agent_mask"]
        found: list[dict | None] = [None] * B
        while any(f is None for f in found[:n_real]):
            actions = act(obs, mask, env.state() if use_state else None)
            obs, _, terminated, truncated, info = env.step(np.where(mask, actions, 0))
            for b in np.flatnonzero(terminated | truncated):
                if found[b] is None:
                    found[b] = {name: float(info["episode"][name][b]) for name in EPISODE_METRICS}
                    found[b]["team_size"] = chunk[b].size
            mask = info["agent_mask"]
        results += found[:n_real]
    env.release_solvers()  # the environment may wait long for its next batch: hold no OSQP problems
    return results


def summarize(episodes: list[dict]) -> dict[str, float]:
    """Mean of every metric over the episodes."""
    if not episodes:
        raise ValueError("summarize needs at least one episode")
    return {name: float(np.mean([e[name] for e in episodes])) for name in episodes[0]}
