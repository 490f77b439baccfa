"""Evaluation episodes: given teams, run each for one episode with a policy, collect metrics.

A policy here is any callable ``act(obs (B, N, D), mask (B, N), state (B, S) or None) ->
actions (B, N)`` on numpy arrays — a trained model (``comat.rl.policy.load_policy``), the
scripted heuristic, or random actions.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from comat.envs.core import COORDINATION, EPISODE_METRICS
from comat.envs.vector import VectorEnv
from comat.measure.metrics import curve_endpoints
from comat.team import TeamSpec

__all__ = ["CURVE_DECIMALS", "SUMMED", "Policy", "robot_rows", "run_episodes", "summarize"]

Policy = Callable[[np.ndarray, np.ndarray, "np.ndarray | None"], np.ndarray]

CURVE_DECIMALS = 4
"""Rows store the progress curve rounded to 1e-4 (0.01 points), which keeps evaluation files
small; the endpoints (``progress_auc``, ``time_to_90``) are computed before rounding."""

SUMMED = ("delivered", "sensed", "captured")
"""Per-robot counts whose per-type sums (``<name>_sum``) ``by_type`` also gives: units of work
that add up over a type's robots."""


def _short(x: float) -> float:
    """x to 6 decimals: sums of payloads carry float noise (58.308173999999994) that only lengthens files."""
    return round(float(x), 6)


def robot_rows(team: TeamSpec, counts: dict[str, np.ndarray]) -> tuple[list[dict], dict[str, dict]]:
    """The ``robots`` (one dict per robot, team order: ``type`` and every count) and ``by_type``
    (per type present: ``robots``, the per-robot mean of each count, and ``<name>_sum`` for
    :data:`SUMMED` counts) entries of an episode row, from counts name -> (n,)."""
    types = [r.type for r in team.robots]
    robots = [{"type": t, **{name: _short(v[i]) for name, v in counts.items()}} for i, t in enumerate(types)]
    by_type = {}
    for t in dict.fromkeys(types):
        sel = np.array([x == t for x in types])
        entry = {"robots": int(sel.sum())}
        for name, v in counts.items():
            entry[name] = _short(v[sel].mean())
            if name in SUMMED:
                entry[f"{name}_sum"] = _short(v[sel].sum())
        by_type[t] = entry
    return robots, by_type


def _row(info: dict, b: int, team: TeamSpec, horizon: int) -> dict:
    """Episode row of env b's episode that ended in this step (see :func:`run_episodes`)."""
    row = {name: float(info["episode"][name][b]) for name in EPISODE_METRICS}
    if COORDINATION in info["episode"]:  # a task with a coordination metric: its mean over the steps
        row[COORDINATION] = float(info["episode"][COORDINATION][b])
    row["team_size"] = team.size
    curve = info["episode_curve"][b, : int(row["steps"])]
    row.update(curve_endpoints(curve, horizon))
    row["progress_curve"] = [round(float(x), CURVE_DECIMALS) for x in curve]
    row.update({name: float(v[b]) for name, v in info["episode_end"].items()})
    row["robots"], row["by_type"] = robot_rows(team, {k: v[b, : team.size] for k, v in info["episode_robots"].items()})
    return row


def run_episodes(
    env: VectorEnv,
    act: Policy,
    teams: list[TeamSpec],
    seed: int,
    use_state: bool = False,
    n_coalitions: int | None = None,
) -> list[dict]:
    """One episode per entry of ``teams``, ``env.num_envs`` at a time; returns their rows, in the
    order of ``teams``.

    A row holds ``EPISODE_METRICS``, ``coordination`` (the task's coordination metric, mean over the
    episode's env steps; only for a task that has one), ``team_size``; ``coalition`` (i % n_coalitions) and
    ``episode_in_coalition`` (i // n_coalitions) for ``teams`` = n_coalitions coalitions
    repeated K times (None: every team its own coalition); ``progress_curve`` (progress after
    each env step, :data:`CURVE_DECIMALS`) with its endpoints ``progress_auc``, ``time_to_90``,
    ``reached_90`` (:func:`comat.measure.metrics.curve_endpoints`); the task's end counts (its
    ``end_count_names``: e.g. HMT ``on_board_end``, PCP ``sensed_not_captured``); ``robots`` and ``by_type``
    (:func:`robot_rows`; the counts are the task's ``robot_count_names``).

    Chunk k is reset with seed ``seed + k``, so the result depends only on the policy, the
    teams and the seed. A short last chunk is filled with repeats that are not reported.
    """
    n = len(teams) if n_coalitions is None else n_coalitions
    if isinstance(n, bool) or not isinstance(n, int) or n < 1 or len(teams) % n:
        raise ValueError(
            f"n_coalitions must be a positive integer dividing the {len(teams)} teams, got {n_coalitions!r}"
        )
    if any(t != teams[i % n] for i, t in enumerate(teams)):
        raise ValueError(f"teams must be {n} coalitions repeated {len(teams) // n} times (team i = coalition i % {n})")
    B, horizon = env.num_envs, env.task.horizon
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
                    found[b] = _row(info, b, chunk[b], horizon)
            mask = info["agent_mask"]
        for i, row in enumerate(found[:n_real]):
            results.append({**row, "coalition": (start + i) % n, "episode_in_coalition": (start + i) // n})
    env.release_solvers()  # the environment may wait long for its next batch: hold no OSQP problems
    return results


def summarize(episodes: list[dict]) -> dict[str, float]:
    """Mean over the episodes of every scalar metric (the curve, the per-robot lists and the
    coalition indices are left out)."""
    if not episodes:
        raise ValueError("summarize needs at least one episode")
    skip = ("coalition", "episode_in_coalition")
    return {
        name: float(np.mean([e[name] for e in episodes]))
        for name, v in episodes[0].items()
        if name not in skip and isinstance(v, (int, float))
    }
