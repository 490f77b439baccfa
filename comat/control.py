"""The control pipeline of every tick: nominal velocities → safety filter → unicycle → physics.

``SafeTeams`` composes a world (single-team :class:`~comat.sim.World` or batched
:class:`~comat.sim.BatchWorld`) with one :class:`~comat.safety.SafetyFilter` over all its teams,
so a tick is one physics call per team size and one QP. ``go_to_goal`` is the proportional
waypoint controller of the projected points (Robotarium ``si_position_controller``).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from comat._validate import as_float_array
from comat.config import SafetyConfig, SimConfig
from comat.safety import SafetyFilter, SafetyInfo
from comat.sim import BatchWorld, World
from comat.sim.kinematics import projected_points, si_to_uni
from comat.sim.violations import TickEvents

__all__ = ["SafeTeams", "TickTiming", "go_to_goal"]


def go_to_goal(points: np.ndarray, goals: np.ndarray, gain: float = 1.0, max_speed: float = 0.2) -> np.ndarray:
    """Velocities (R, 2) driving points (R, 2) toward goals (R, 2), norm-clipped to ``max_speed``."""
    dxi = gain * (goals - points)
    norm = np.linalg.norm(dxi, axis=-1, keepdims=True)
    return dxi * np.minimum(1.0, max_speed / np.maximum(norm, 1e-12))


@dataclass
class TickTiming:
    """Wall-clock split of the last tick (s): MuJoCo stepping, OSQP's solve, everything else."""

    total: float = 0.0
    physics: float = 0.0
    solver: float = 0.0

    @property
    def rest(self) -> float:
        return self.total - self.physics - self.solver


class SafeTeams:
    """Teams of robots whose every command passes the barrier filter before the wheels.

    Args:
        team_sizes: robots per team.
        sim: world settings (tier, substeps, profile).
        safety: barrier settings.
        batched: use :class:`BatchWorld` (default) or, for a single team, :class:`World`.
    """

    def __init__(
        self,
        team_sizes: Sequence[int],
        sim: SimConfig | None = None,
        safety: SafetyConfig | None = None,
        batched: bool = True,
    ) -> None:
        sizes = tuple(team_sizes)
        self.sim_config = sim or SimConfig()
        self.safety_config = safety or SafetyConfig()
        if batched:
            self.world: World | BatchWorld = BatchWorld(sizes, self.sim_config)
        else:
            if len(sizes) != 1:
                raise ValueError(f"batched=False takes exactly one team, got team_sizes={sizes}")
            self.world = World(sizes[0], self.sim_config)
        self.filter = SafetyFilter(sizes, self.safety_config, self.world.profile)
        self.timing = TickTiming()
        self.interventions = np.zeros(len(sizes), np.int64)
        self.fallbacks = np.zeros(len(sizes), np.int64)

    @property
    def poses(self) -> np.ndarray:
        """(R, 3) current poses."""
        return self.world.poses

    @property
    def points(self) -> np.ndarray:
        """(R, 2) current projected points (what the barrier keeps apart)."""
        return projected_points(self.world.poses, self.safety_config.projection_distance_m)

    def reset(self, poses: np.ndarray) -> None:
        """Place all robots at poses (R, 3) and zero the counters."""
        self.world.reset(poses)
        self.interventions[:] = 0
        self.fallbacks[:] = 0

    def tick(self, dxi: np.ndarray) -> tuple[TickEvents, SafetyInfo]:
        """One control tick with nominal projected-point velocities (R, 2)."""
        t0 = time.perf_counter()
        dxi = as_float_array("dxi", dxi, (self.world.layout.n_robots, 2))
        poses = self.world._poses  # read-only here; our own arrays skip the public checks
        safe, info = self.filter._filter(poses, dxi)
        events = self.world._step(si_to_uni(safe, poses, self.safety_config.projection_distance_m))
        self.interventions += info.intervention > 1e-9
        self.fallbacks += info.fallback
        self.timing.total = time.perf_counter() - t0
        self.timing.physics = self.world.last_physics_s
        self.timing.solver = self.filter.last_solver_s
        return events, info
