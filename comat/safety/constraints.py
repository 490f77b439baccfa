"""Rows of the barrier QP for many teams at once: layout (fixed per team sizes) and values.

Decision variable: the stacked single-integrator velocities u (2R,) of all R robots of all
teams, robot r at entries (2r, 2r+1). Rows, in this order:

* pair rows, one per unordered pair (i, j) of the same team, e = p_i - p_j:
  ``-2eᵀu_i + 2eᵀu_j <= γ·(‖e‖² - d_s²)`` (ḣ >= -γh for h = ‖e‖² - d_s²); a layout may keep
  only some pairs (those closer than :func:`binding_distance`: the others hold for every
  command the wheels allow, so dropping them leaves the QP's answer unchanged);
* boundary rows, two per robot (x and y): ``-γ_b·(p - lo) <= u <= γ_b·(hi - p)`` where
  [lo, hi] is the arena shrunk by the margin;
* wheel rows, two per robot: ``|u·(ê ± k·n̂)| <= r·φ̇_max`` with k = l_axle / (2·projection),
  the exact image of the per-wheel limit |φ̇| <= φ̇_max under the projection map, so any
  feasible u is realizable by the wheels without clipping.

Values are computed for all rows in one vectorized pass (no loops over pairs); the slow
reference :func:`reference_rows` builds the same rows with plain loops, for tests.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from comat import constants as C
from comat import kernels
from comat.safety import kernels as safety_kernels
from comat.sim.kinematics import WHEEL_LIMIT_TOLERANCE, wheel_rhombus
from comat.sim.layout import TeamLayout, team_layout

__all__ = [
    "OSQP_INFINITY",
    "Layout",
    "RowValues",
    "binding_distance",
    "edge_binding_distance",
    "make_layout",
    "point_speed_bound",
    "reference_rows",
    "row_constants",
    "row_values",
]

OSQP_INFINITY = 1e30
"""OSQP's infinity: bounds at or beyond it are treated as absent (pair rows have no lower bound)."""


@dataclass(frozen=True)
class Layout:
    """Sparsity of the block-diagonal QP for a tuple of team sizes.

    Attributes:
        teams: robot offsets and same-team pairs.
        row_team: (n_rows,) team of each row.
        n_rows: total rows = P + 4R.
        rows, cols: (nnz,) coordinates of the nonzeros, in :func:`row_values` data order.
        n_pair_rows: P, the pair rows (one per pair of ``teams``).
    """

    teams: TeamLayout
    row_team: np.ndarray
    n_rows: int
    rows: np.ndarray
    cols: np.ndarray
    n_pair_rows: int


def make_layout(team_sizes: Sequence[int], pairs: tuple[np.ndarray, np.ndarray] | None = None) -> Layout:
    """The QP structure for teams of the given sizes (each >= 1): a row for every same-team pair,
    or only for ``pairs`` = (pair_i, pair_j), (P,) robot rows with i < j in the same team, sorted
    (the pairs that can bind, see :func:`binding_distance`)."""
    if pairs is None:
        t = team_layout(tuple(team_sizes))
    else:
        sizes = tuple(int(n) for n in team_sizes)
        offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
        robot_team = np.repeat(np.arange(len(sizes)), sizes)
        t = TeamLayout(sizes, offsets, robot_team, pairs[0], pairs[1], robot_team[pairs[0]])
    pair_i, pair_j, pair_team = t.pair_i, t.pair_j, t.pair_team
    R, P = t.n_robots, pair_i.size
    # Pair rows: 4 nonzeros each, columns [2i, 2i+1, 2j, 2j+1].
    pr = np.repeat(np.arange(P), 4)
    pc = np.stack([2 * pair_i, 2 * pair_i + 1, 2 * pair_j, 2 * pair_j + 1], axis=1).ravel()
    # Boundary rows: row P + 2r (+1) has one nonzero at column 2r (+1).
    br = P + np.arange(2 * R)
    bc = np.arange(2 * R)
    # Wheel rows: rows P + 2R + 2r (+1), each with nonzeros at columns 2r, 2r+1.
    wr = P + 2 * R + np.repeat(np.arange(2 * R), 2)
    wc = np.stack([2 * np.arange(R), 2 * np.arange(R) + 1], axis=1).repeat(2, axis=0).ravel()
    per_robot = np.repeat(t.robot_team, 2)
    return Layout(
        teams=t,
        row_team=np.concatenate([pair_team, per_robot, per_robot]).astype(np.int64),
        n_rows=P + 4 * R,
        rows=np.concatenate([pr, br, wr]).astype(np.int64),
        cols=np.concatenate([pc, bc, wc]).astype(np.int64),
        n_pair_rows=P,
    )


def point_speed_bound(cfg, profile: C.RobotProfile) -> float:
    """v̄ (m/s): no command the filter accepts moves a projected point faster.

    Accepted commands keep each point inside its wheel rhombus |a| + k·|b| <= v, up to the true
    wheel limit ``v·WHEEL_LIMIT_TOLERANCE / fraction``; the rhombus's farthest points are its
    vertices, so ‖u‖ <= max(v, v/k) (0.2 m/s with the defaults)."""
    k, v = _limits(cfg, profile)
    return max(v, v / k) * WHEEL_LIMIT_TOLERANCE / cfg.wheel_speed_fraction


def binding_distance(cfg, profile: C.RobotProfile) -> float:
    """Projected-point distance (m) beyond which a pair row holds for every command the filter
    can return, so the row cannot bind and may be left out of the QP.

    With ‖u‖ <= v̄ (:func:`point_speed_bound`) the row's left side is at most
    |2eᵀ(u_i - u_j)| <= 4·‖e‖·v̄, and ``4‖e‖v̄ <= γ(‖e‖² - d_s²)`` holds for
    ‖e‖ >= D = (2v̄ + √(4v̄² + γ²d_s²)) / γ. With the defaults (v̄ = 0.2 m/s, γ = 10 /s,
    d_s = 0.2 m) D = 0.244 m: a pair row matters only for robots within about one robot's
    width of the safety distance, so the rows grow with the neighbours, not with N².
    """
    v_bar = point_speed_bound(cfg, profile)
    g, d = cfg.barrier_gain, cfg.safety_distance_m
    return (2.0 * v_bar + math.sqrt(4.0 * v_bar**2 + (g * d) ** 2)) / g


def edge_binding_distance(cfg, profile: C.RobotProfile) -> float:
    """Distance (m) of a projected point from the margin's edge beyond which its boundary rows
    ``-γ_b·(p - lo) <= u <= γ_b·(hi - p)`` hold for every accepted command: v̄ / γ_b (0.02 m)."""
    return point_speed_bound(cfg, profile) / cfg.boundary_gain


@dataclass
class RowValues:
    """The QP's rows for one state, kept in factored form.

    Attributes:
        e: (P, 2) pair differences p_i - p_j.
        cos, sin: (R,) heading of each robot.
        k: wheel-row lateral factor l_axle / (2·projection).
        lower, upper: (n_rows,) row bounds.
    """

    layout: Layout
    e: np.ndarray
    cos: np.ndarray
    sin: np.ndarray
    k: float
    lower: np.ndarray
    upper: np.ndarray

    def products(self, u: np.ndarray) -> np.ndarray:
        """A @ u for stacked velocities u (2R,), without forming A."""
        t = self.layout.teams
        if kernels.enabled():
            out = np.empty(self.layout.n_rows)
            safety_kernels.row_products(self.e, self.cos, self.sin, self.k, t.pair_i, t.pair_j, u, out)
            return out
        U = u.reshape(-1, 2)
        du = np.take(U, t.pair_i, axis=0) - np.take(U, t.pair_j, axis=0)
        pair = -2.0 * (self.e[:, 0] * du[:, 0] + self.e[:, 1] * du[:, 1])
        along = self.cos * U[:, 0] + self.sin * U[:, 1]
        across = -self.sin * U[:, 0] + self.cos * U[:, 1]
        wheel = np.stack([along + self.k * across, along - self.k * across], axis=1).ravel()
        return np.concatenate([pair, u, wheel])

    def data(self) -> np.ndarray:
        """Nonzeros of A in layout order."""
        c, s, k = self.cos, self.sin, self.k
        if kernels.enabled():
            out = np.empty(4 * self.e.shape[0] + 6 * c.size)
            safety_kernels.row_data(self.e, c, s, k, out)
            return out
        pair = np.concatenate([-2.0 * self.e, 2.0 * self.e], axis=1).ravel()
        # ê ± k·n̂ with ê = (c, s), n̂ = (-s, c): rows (2r) for +, (2r+1) for -.
        wheel = np.stack([c - k * s, s + k * c, c + k * s, s - k * c], axis=1).ravel()
        return np.concatenate([pair, np.ones(2 * c.size), wheel])


def _limits(cfg, profile: C.RobotProfile) -> tuple[float, float]:
    return wheel_rhombus(cfg.projection_distance_m, profile, cfg.wheel_speed_fraction)


def row_values(
    layout: Layout,
    points: np.ndarray,
    headings: np.ndarray,
    cfg,
    profile: C.RobotProfile,
    cos_sin: tuple[np.ndarray, np.ndarray] | None = None,
) -> RowValues:
    """Rows for projected points (R, 2) and headings (R,) of all robots (no loops over pairs).

    ``cfg`` is a :class:`comat.config.SafetyConfig`; ``cos_sin`` may pass the headings' cosines
    and sines when the caller has them already.
    """
    t = layout.teams
    c, s = cos_sin if cos_sin is not None else (np.cos(headings), np.sin(headings))
    if kernels.enabled():
        return _row_values_compiled(layout, points, cfg, profile, c, s)
    # np.take: several times faster than fancy indexing for these row gathers.
    e = np.take(points, t.pair_i, axis=0) - np.take(points, t.pair_j, axis=0)  # (P, 2)
    h = e[:, 0] ** 2 + e[:, 1] ** 2 - cfg.safety_distance_m**2
    P, R = t.n_pairs, t.n_robots
    x0, x1, y0, y1 = C.ARENA_BOUNDS_M
    m = cfg.boundary_margin_m
    k, speed = _limits(cfg, profile)
    lower = np.empty(layout.n_rows)
    upper = np.empty(layout.n_rows)
    lower[:P] = -OSQP_INFINITY
    upper[:P] = cfg.barrier_gain * h
    lower[P : P + 2 * R] = (-cfg.boundary_gain * (points - (x0 + m, y0 + m))).ravel()
    upper[P : P + 2 * R] = (cfg.boundary_gain * ((x1 - m, y1 - m) - points)).ravel()
    lower[P + 2 * R :] = -speed
    upper[P + 2 * R :] = speed
    return RowValues(layout, e, c, s, k, lower, upper)


def row_constants(cfg, profile: C.RobotProfile) -> tuple[float, float, np.ndarray, np.ndarray]:
    """What the compiled row kernels take besides the state: wheel rhombus (k, v) and the
    arena shrunk by the margin, lower (2,) and upper (2,) corners."""
    x0, x1, y0, y1 = C.ARENA_BOUNDS_M
    m = cfg.boundary_margin_m
    k, speed = _limits(cfg, profile)
    return k, speed, np.array((x0 + m, y0 + m)), np.array((x1 - m, y1 - m))


def _row_values_compiled(layout: Layout, points: np.ndarray, cfg, profile: C.RobotProfile, c, s) -> RowValues:
    t = layout.teams
    k, speed, lo, hi = row_constants(cfg, profile)
    e = np.empty((t.n_pairs, 2))
    lower, upper = np.empty(layout.n_rows), np.empty(layout.n_rows)
    safety_kernels.row_bounds_into(
        points, t.pair_i, t.pair_j, cfg.safety_distance_m**2, cfg.barrier_gain, -cfg.boundary_gain,
        cfg.boundary_gain, lo, hi, speed, e, lower, upper,
    )  # fmt: skip
    return RowValues(layout, e, c, s, k, lower, upper)


def reference_rows(team_sizes: Sequence[int], points: np.ndarray, headings: np.ndarray, cfg, profile: C.RobotProfile):
    """Slow reference: dense (n_rows, 2R) matrix and bounds built with plain loops (tests only)."""
    R = points.shape[0]
    rows_a, lows, ups = [], [], []
    start = 0
    pair_rows, bound_rows, wheel_rows = [], [], []
    for n in team_sizes:
        for i in range(start, start + n):
            for j in range(i + 1, start + n):
                e = points[i] - points[j]
                a = np.zeros(2 * R)
                a[2 * i : 2 * i + 2] = -2 * e
                a[2 * j : 2 * j + 2] = 2 * e
                pair_rows.append((a, -OSQP_INFINITY, cfg.barrier_gain * (e @ e - cfg.safety_distance_m**2)))
        start += n
    x0, x1, y0, y1 = C.ARENA_BOUNDS_M
    m = cfg.boundary_margin_m
    k, speed = _limits(cfg, profile)
    for r in range(R):
        for axis, (lo, hi) in enumerate(((x0 + m, x1 - m), (y0 + m, y1 - m))):
            a = np.zeros(2 * R)
            a[2 * r + axis] = 1.0
            bound_rows.append(
                (a, -cfg.boundary_gain * (points[r, axis] - lo), cfg.boundary_gain * (hi - points[r, axis]))
            )
    for r in range(R):
        ehat = np.array([np.cos(headings[r]), np.sin(headings[r])])
        nhat = np.array([-np.sin(headings[r]), np.cos(headings[r])])
        for sign in (+1, -1):
            a = np.zeros(2 * R)
            a[2 * r : 2 * r + 2] = ehat + sign * k * nhat
            wheel_rows.append((a, -speed, speed))
    for a, lo, hi in pair_rows + bound_rows + wheel_rows:
        rows_a.append(a)
        lows.append(lo)
        ups.append(hi)
    return np.array(rows_a).reshape(-1, 2 * R), np.array(lows), np.array(ups)
