"""The barrier QP of large teams restricted to what can bind: close pairs and the robots in them.

For a team of N robots the all-pairs QP has N(N-1)/2 pair rows (496 at N = 32) that couple every
robot with every other, although a row can only bind near its limit:

* a pair row, when the two projected points are closer than
  :func:`~comat.safety.constraints.binding_distance` D (0.244 m with the defaults): farther
  pairs meet it for every command the wheels allow;
* a boundary row, when the point is closer than v̄/γ_b (0.02 m) to the margin's edge
  (:func:`~comat.safety.constraints.edge_binding_distance`).

So the reduced problem holds pair rows for close pairs only, and variables only for "coupled"
robots (in a close pair, or near the edge). Every other robot's problem is separate from the
rest (no row couples it) and is ``min ‖u - û‖²`` over its wheel rhombus, whose answer is the
rhombus projection of stage 2 of :mod:`comat.safety.filter`: it keeps that command. Keeping more
rows or robots than these (any superset) changes nothing either, so the optimum is the all-pairs
QP's — the QP is strictly convex — and its size grows with the robots that have close
neighbours, not with N².

A fresh OSQP set-up costs about as much as the solve, so :class:`CouplingPattern` keeps one
pattern over ticks: built with a slack on both distances, it stays a superset until some pair
outside it comes within D or some robot outside it within v̄/γ_b of the edge, and only then is
rebuilt (robots close in at most 2·0.2 m/s, 13 mm per tick).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from comat.sim.layout import TeamLayout

__all__ = ["PATTERN_SLACK_M", "CoupledRows", "CouplingPattern", "coupled_rows"]

PATTERN_SLACK_M = 0.05
"""Extra distance (m) on both binding distances when a pattern is built, so that it lasts several
ticks (a pair closes in by at most 13 mm per tick)."""


@dataclass
class CoupledRows:
    """The reduced problem of some teams, as indices into the full problem.

    Attributes:
        teams: (k,) the teams it covers, ascending.
        sizes: (k,) coupled robots of each team (>= 1).
        pair_i, pair_j: (P_sub,) the kept pairs as rows of the reduced problem's robots (i < j,
            sorted: the order of their rows).
        rows: (n_rows_sub,) full-layout rows: kept pairs, then boundary, then wheel rows.
        cols: (2·R_sub,) full-layout velocity components of the coupled robots.
        nnz: (nnz_sub,) full-layout nonzeros (:meth:`RowValues.data` order).
    """

    teams: np.ndarray
    sizes: np.ndarray
    pair_i: np.ndarray
    pair_j: np.ndarray
    rows: np.ndarray
    cols: np.ndarray
    nnz: np.ndarray


def coupled_rows(t: TeamLayout, teams: np.ndarray, kept_pair: np.ndarray, edge_robot: np.ndarray) -> CoupledRows:
    """The reduced problem of ``teams`` (ascending) with rows for the ``kept_pair`` (P,) pairs and
    variables for their robots and the ``edge_robot`` (R,) ones.

    Args:
        t: the full problem's team layout (B teams, R robots, P pairs).
    """
    P, R = t.n_pairs, t.n_robots
    in_teams = np.zeros(t.n_teams, dtype=bool)
    in_teams[teams] = True
    pairs = np.flatnonzero(kept_pair & in_teams[t.pair_team])
    coupled = edge_robot & in_teams[t.robot_team]
    coupled[t.pair_i[pairs]] = True
    coupled[t.pair_j[pairs]] = True
    # A team without a coupled robot needs no QP; should one be passed anyway, its first robot
    # stands in (alone, it keeps its stage-2 command as its optimum), so no team is empty.
    empty = teams[np.bincount(t.robot_team[coupled], minlength=t.n_teams)[teams] == 0]
    coupled[t.offsets[empty]] = True
    robots = np.flatnonzero(coupled)  # grouped by team, teams ascending
    sizes = np.bincount(t.robot_team[robots], minlength=t.n_teams)[teams]
    # Row of each coupled robot in the reduced problem. It follows robot order, so the pairs,
    # ascending by full id (row-major upper triangle per team), stay sorted there too.
    index = np.zeros(R, np.int64)
    index[robots] = np.arange(robots.size)
    cols = np.stack([2 * robots, 2 * robots + 1], axis=1).ravel()
    rows = np.concatenate([pairs, P + cols, P + 2 * R + cols])
    pair_nnz = (4 * pairs[:, None] + np.arange(4)).ravel()
    wheel_nnz = (4 * P + 2 * R + 2 * cols[:, None] + np.arange(2)).ravel()
    nnz = np.concatenate([pair_nnz, 4 * P + cols, wheel_nnz])
    return CoupledRows(teams, sizes, index[t.pair_i[pairs]], index[t.pair_j[pairs]], rows, cols, nnz)


class CouplingPattern:
    """The reduced problem of a filter's large teams, kept over ticks while it is a superset.

    Args:
        t: the filter's team layout.
        large: (B,) bool, the teams that use reduced problems.
        pair_d, edge_d: binding distances (m) of pair and boundary rows.
        lo, hi: (2,) corners of the arena shrunk by the boundary margin.
    """

    def __init__(
        self, t: TeamLayout, large: np.ndarray, pair_d: float, edge_d: float, lo, hi, slack: float = PATTERN_SLACK_M
    ) -> None:
        self.t, self.large = t, large
        self._large_pair, self._large_robot = large[t.pair_team], large[t.robot_team]
        self._pair_d2, self._pair_wide2 = pair_d**2, (pair_d + slack) ** 2
        self._edge_d, self._edge_wide = edge_d, edge_d + slack
        self._lo, self._hi = np.asarray(lo, float), np.asarray(hi, float)
        self.current: CoupledRows | None = None
        self._in_pairs = np.zeros(t.n_pairs, dtype=bool)
        self._in_robots = np.zeros(t.n_robots, dtype=bool)
        self.rebuilds = 0

    def _edge_gap(self, points: np.ndarray) -> np.ndarray:
        """(R,) distance of each point to the nearest edge of the shrunk arena (< 0 outside it)."""
        return np.minimum(points - self._lo, self._hi - points).min(axis=1)

    def rows(self, e: np.ndarray, points: np.ndarray, teams: np.ndarray) -> CoupledRows:
        """A reduced problem for this tick's pair differences ``e`` (P, 2) and projected points
        (R, 2) that covers ``teams`` (those needing the QP): the kept one if it still holds every
        row that can bind, else a new one."""
        d2 = e[:, 0] ** 2 + e[:, 1] ** 2
        gap = self._edge_gap(points)
        cur = self.current
        if cur is not None:
            missing_pair = (d2 < self._pair_d2) & self._large_pair & ~self._in_pairs
            missing_robot = (gap < self._edge_d) & self._large_robot & ~self._in_robots
            covered = np.zeros(self.t.n_teams, dtype=bool)
            covered[cur.teams] = True
            if not (missing_pair.any() or missing_robot.any() or not covered[teams].all()):
                return cur
        kept = (d2 < self._pair_wide2) & self._large_pair
        edge = (gap < self._edge_wide) & self._large_robot
        t = self.t
        has = np.zeros(t.n_teams, dtype=bool)
        has[t.pair_team[kept]] = True
        has[t.robot_team[edge]] = True
        has[teams] = True
        cur = coupled_rows(t, np.flatnonzero(has & self.large), kept, edge)
        self.current, self.rebuilds = cur, self.rebuilds + 1
        self._in_pairs[:] = kept
        self._in_robots[:] = False
        self._in_robots[cur.cols[0::2] // 2] = True
        return cur

    def subset(self, teams: np.ndarray) -> CoupledRows:
        """The kept pattern's rows and robots of some of its ``teams`` (ascending), to re-solve them."""
        return coupled_rows(self.t, teams, self._in_pairs, self._in_robots)
