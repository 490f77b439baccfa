"""Randomized safety scenarios (many episodes at once) for tests, the demo and benchmarks.

Each scenario draws ``episodes`` independent teams, all simulated as one batch: start poses
(R, 3), goals for the projected points (R, 2), and a tick budget. The nominal controller is
:func:`comat.control.go_to_goal`; every command passes the barrier filter.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from comat import constants as C
from comat.config import SafetyConfig, SimConfig
from comat.control import SafeTeams, go_to_goal
from comat.sim.kinematics import si_to_uni

__all__ = ["SCENARIOS", "Scenario", "ScenarioResult", "make_scenario", "run_scenario", "swap_scenario"]

_X0, _X1, _Y0, _Y1 = C.ARENA_BOUNDS_M


@dataclass
class Scenario:
    """Episodes of one kind: teams, start poses (R, 3), goals (R, 2), ticks to run."""

    name: str
    team_sizes: tuple[int, ...]
    poses: np.ndarray
    goals: np.ndarray
    ticks: int


def _spread(rng: np.random.Generator, n: int, spacing: float, margin: float = 0.25) -> np.ndarray:
    """n points (n, 2) uniform in the arena, pairwise >= spacing apart (rejection sampling)."""
    pts: list[np.ndarray] = []
    while len(pts) < n:
        p = rng.uniform([_X0 + margin, _Y0 + margin], [_X1 - margin, _Y1 - margin])
        if all(np.hypot(*(p - q)) >= spacing for q in pts):
            pts.append(p)
    return np.array(pts)


def _ring(rng: np.random.Generator, n: int, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """n robots on a jittered ring around a random centre, goals diametrically opposite."""
    centre = rng.uniform([-0.3, -0.1], [0.3, 0.1])
    ang = rng.uniform(0, 2 * np.pi) + np.linspace(0, 2 * np.pi, n, endpoint=False) + rng.uniform(-0.1, 0.1, n)
    r = radius + rng.uniform(-0.03, 0.03, n)
    start = centre + r[:, None] * np.stack([np.cos(ang), np.sin(ang)], 1)
    goal = centre - r[:, None] * np.stack([np.cos(ang), np.sin(ang)], 1)
    return start, goal


def _head_on(rng, episodes):
    poses, goals = [], []
    for _ in range(episodes):
        start, goal = _ring(rng, 2, rng.uniform(0.3, 0.7))
        heading = np.arctan2(*(goal - start)[:, ::-1].T) + rng.uniform(-0.3, 0.3, 2)
        poses.append(np.column_stack([start, heading]))
        goals.append(goal)
    return (2,) * episodes, poses, goals, 200


def _swap(n: int, radius: float):
    def make(rng, episodes):
        poses, goals = [], []
        for _ in range(episodes):
            start, goal = _ring(rng, n, radius)
            poses.append(np.column_stack([start, rng.uniform(-np.pi, np.pi, n)]))
            goals.append(goal)
        return (n,) * episodes, poses, goals, 300

    return make


def _converge(n: int):
    def make(rng, episodes):
        poses, goals = [], []
        for _ in range(episodes):
            start = _spread(rng, n, 0.3)
            poses.append(np.column_stack([start, rng.uniform(-np.pi, np.pi, n)]))
            goals.append(np.repeat(rng.uniform([-0.5, -0.3], [0.5, 0.3])[None], n, axis=0))
        return (n,) * episodes, poses, goals, 300

    return make


def _walls(rng, episodes):
    """4 robots near the walls, each driven at a point 0.5 m beyond its nearest wall."""
    poses, goals = [], []
    for _ in range(episodes):
        start = _spread(rng, 4, 0.35, margin=0.12)
        goal = start.copy()
        for k, (x, y) in enumerate(start):
            dists = [x - _X0, _X1 - x, y - _Y0, _Y1 - y]
            side = int(np.argmin(dists))
            goal[k] = [(_X0 - 0.5, y), (_X1 + 0.5, y), (x, _Y0 - 0.5), (x, _Y1 + 0.5)][side]
        poses.append(np.column_stack([start, rng.uniform(-np.pi, np.pi, 4)]))
        goals.append(goal)
    return (4,) * episodes, poses, goals, 150


SCENARIOS: dict[str, Callable] = {
    "head_on": _head_on,
    "swap4": _swap(4, 0.45),
    "swap8": _swap(8, 0.75),
    "converge16": _converge(16),
    "converge32": _converge(32),
    "walls": _walls,
}


def swap_scenario(robots: int, episodes: int, seed: int, ticks: int = 300, radius: float = 0.75) -> Scenario:
    """``episodes`` teams of ``robots`` on a jittered ring, each robot driven to the opposite side."""
    sizes, poses, goals, _ = _swap(robots, radius)(np.random.default_rng(seed), episodes)
    return Scenario(f"swap{robots}", tuple(sizes), np.concatenate(poses), np.concatenate(goals), ticks)


def make_scenario(name: str, episodes: int, seed: int) -> Scenario:
    """Draw ``episodes`` random episodes of scenario ``name`` (one of :data:`SCENARIOS`)."""
    if name not in SCENARIOS:
        raise ValueError(f"scenario must be one of {sorted(SCENARIOS)}, got {name!r}")
    sizes, poses, goals, ticks = SCENARIOS[name](np.random.default_rng(seed), episodes)
    return Scenario(name, tuple(sizes), np.concatenate(poses), np.concatenate(goals), ticks)


@dataclass
class ScenarioResult:
    """Outcome per episode (B,) after running a scenario."""

    min_centre_distance: np.ndarray
    robot_contacts: np.ndarray
    wall_contacts: np.ndarray
    robotarium_collisions: np.ndarray
    boundary_exits: np.ndarray
    actuator_errors: np.ndarray
    interventions: np.ndarray
    fallbacks: np.ndarray
    recoveries: np.ndarray
    goal_error: np.ndarray
    goal_error_robot: np.ndarray


def run_scenario(
    scn: Scenario, sim: SimConfig, safety: SafetyConfig | None = None, filtered: bool = True
) -> ScenarioResult:
    """Run every episode of ``scn`` as one batch for ``scn.ticks`` ticks.

    With ``filtered=False`` the nominal commands go to the wheels unfiltered (only clipped to
    the wheel limits), to show what the barrier prevents.
    """
    teams = SafeTeams(scn.team_sizes, sim, safety)
    teams.reset(scn.poses)
    lay = teams.world.layout
    min_d = np.full(lay.n_teams, np.inf)
    d_proj = teams.safety_config.projection_distance_m
    for _ in range(scn.ticks):
        nominal = go_to_goal(teams.points, scn.goals)
        if filtered:
            teams.tick(nominal)
        else:
            teams.world.step(si_to_uni(nominal, teams.poses, d_proj))
        p = teams.poses[:, :2]
        d = np.linalg.norm(p[lay.pair_i] - p[lay.pair_j], axis=1)
        np.minimum.at(min_d, lay.pair_team, d)
    v = teams.world.violations
    err = np.linalg.norm(teams.points - scn.goals, axis=1)
    return ScenarioResult(
        min_centre_distance=min_d,
        robot_contacts=v.per_team("contact_ticks"),
        wall_contacts=v.per_team("wall_ticks"),
        robotarium_collisions=v.per_team("collision_pairs"),
        boundary_exits=v.per_team("boundary_ticks"),
        actuator_errors=v.per_team("actuator_ticks"),
        interventions=teams.interventions.copy(),
        fallbacks=teams.fallbacks.copy(),
        recoveries=teams.recoveries.copy(),
        goal_error=np.bincount(lay.robot_team, weights=err) / np.array(lay.team_sizes),
        goal_error_robot=err,
    )
