"""Index structure of several teams stacked row-wise: robot offsets and same-team pairs."""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ["TeamLayout", "team_layout"]


@dataclass(frozen=True)
class TeamLayout:
    """Teams of ``team_sizes`` robots, concatenated: robot r of team b is row offsets[b] + r.

    Attributes:
        team_sizes: robots per team (B,).
        offsets: (B+1,) first row of each team, then the total R.
        robot_team: (R,) team of each robot.
        pair_i, pair_j: (P,) rows of every unordered same-team pair, i < j.
        pair_team: (P,) team of each pair.
    """

    team_sizes: tuple[int, ...]
    offsets: np.ndarray
    robot_team: np.ndarray
    pair_i: np.ndarray
    pair_j: np.ndarray
    pair_team: np.ndarray

    @property
    def n_teams(self) -> int:
        return len(self.team_sizes)

    @property
    def n_robots(self) -> int:
        return int(self.offsets[-1])

    @property
    def n_pairs(self) -> int:
        return int(self.pair_i.size)


@functools.lru_cache(maxsize=16)
def team_layout(team_sizes: Sequence[int]) -> TeamLayout:
    """Layout for teams of the given sizes (each >= 1); cached, treat as read-only.

    The cache is small on purpose: a vector env's tuple of sizes changes with nearly every reset
    and rarely comes back, and one layout of 32 twenty-robot teams holds ~150 KB of pair indices,
    so 256 entries held ~21 MiB (the U_scale soak grew 10 %) for hardly any hits; what
    repeats (single-team layouts, the current vector's) stays cached."""
    sizes = tuple(int(n) for n in team_sizes)
    if not sizes or min(sizes) < 1:
        raise ValueError(f"team_sizes must be a non-empty sequence of positive integers, got {team_sizes!r}")
    offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    pairs = [np.triu_indices(n, k=1) for n in sizes]
    pair_i = np.concatenate([i + offsets[b] for b, (i, _) in enumerate(pairs)]).astype(np.int64)
    pair_j = np.concatenate([j + offsets[b] for b, (_, j) in enumerate(pairs)]).astype(np.int64)
    pair_team = np.concatenate([np.full(i.size, b) for b, (i, _) in enumerate(pairs)]).astype(np.int64)
    for arr in (offsets, pair_i, pair_j, pair_team):
        arr.flags.writeable = False
    robot_team = np.repeat(np.arange(len(sizes)), sizes)
    robot_team.flags.writeable = False
    return TeamLayout(sizes, offsets, robot_team, pair_i, pair_j, pair_team)
