"""MuJoCo worlds: :class:`World` for one team (reference path) and the shared tick logic.

One control tick (0.033 s) of ``step(dxu)``:

1. validate the unicycle commands (R, 2) [v, ω]; flag Robotarium actuator errors;
2. clip each wheel to ±12.5 rad/s, as the current Robotarium does;
3. write actuator targets and run ``substeps`` physics steps (contacts read at every substep);
4. read poses (R, 3), run the Robotarium-style checks and update the counters.

:class:`World` steps one ``MjData`` substep by substep in Python: simple and easy to trust, it is
the reference that :class:`comat.sim.BatchWorld` (one C call per tick for many teams) is tested
against.
"""

from __future__ import annotations

import copy
import time

import mujoco
import numpy as np

from comat import constants as C
from comat import kernels
from comat._validate import as_float_array, check_positive_int
from comat.config import SimConfig
from comat.mjcf.scene import compiled_scene
from comat.sim.binding import Binding
from comat.sim.kinematics import WHEEL_LIMIT_TOLERANCE, si_to_uni, threshold_wheels
from comat.sim.layout import TeamLayout, team_layout
from comat.sim.violations import TickEvents, Violations, check_tick

__all__ = ["World", "points_to_wheels", "validate_start_poses"]


def points_to_wheels(
    dxi: np.ndarray,
    poses: np.ndarray,
    cos_sin: tuple[np.ndarray, np.ndarray],
    distance: float,
    profile: C.RobotProfile,
) -> tuple[np.ndarray, np.ndarray]:
    """Velocities (R, 2) of the points ``distance`` ahead of the axles of robots at ``poses`` (R, 3),
    whose headings' cosines and sines are ``cos_sin``, as the unicycle commands the wheels can do.

    :func:`~comat.sim.kinematics.si_to_uni` then :func:`~comat.sim.kinematics.threshold_wheels`
    (one fused call when the kernels are on). Returns the clipped commands (R, 2) [v m/s, ω rad/s]
    and ``overrun`` (R,) bool, where a requested wheel speed was over the limit."""
    if not kernels.enabled():
        return threshold_wheels(si_to_uni(dxi, poses, distance, cos_sin), profile)
    R = dxi.shape[0]
    dxu, clipped, overrun = np.empty((R, 2)), np.empty((R, 2)), np.empty(R, dtype=bool)
    length = profile.base_length_m
    kernels.si_to_wheels(
        dxi, cos_sin[0], cos_sin[1], distance, profile.wheel_radius_m, length / 2.0, length,
        profile.max_wheel_velocity_radps, WHEEL_LIMIT_TOLERANCE, dxu, clipped, overrun,
    )  # fmt: skip
    return clipped, overrun


def validate_start_poses(poses: np.ndarray, layout: TeamLayout, radius: float) -> None:
    """Raise ValueError if a robot starts outside the arena (body crossing a wall) or two robots of
    one team overlap (centres closer than a diameter)."""
    x0, x1, y0, y1 = C.ARENA_BOUNDS_M
    x, y = poses[:, 0], poses[:, 1]
    outside = (x < x0 + radius) | (x > x1 - radius) | (y < y0 + radius) | (y > y1 - radius)
    if outside.any():
        r = int(np.flatnonzero(outside)[0])
        raise ValueError(
            f"poses: robot {r} at ({x[r]:.3f}, {y[r]:.3f}) is outside the arena; centres must lie in "
            f"x in [{x0 + radius:.3f}, {x1 - radius:.3f}], y in [{y0 + radius:.3f}, {y1 - radius:.3f}] m"
        )
    d = poses[layout.pair_i, :2] - poses[layout.pair_j, :2]
    dist = np.sqrt(np.einsum("pk,pk->p", d, d))
    overlap = dist < 2 * radius
    if overlap.any():
        k = int(np.flatnonzero(overlap)[0])
        i, j = int(layout.pair_i[k]), int(layout.pair_j[k])
        raise ValueError(
            f"poses: robots {i} and {j} overlap (centres {dist[k]:.3f} m apart, need >= {2 * radius:.3f} m)"
        )


class _TickMixin:
    """The per-tick pipeline shared by the single and the batched world."""

    layout: TeamLayout
    binding: Binding
    profile: C.RobotProfile
    violations: Violations
    _poses: np.ndarray
    _cos_sin: tuple[np.ndarray, np.ndarray] | None = None
    last_physics_s: float = 0.0
    """Wall time of the last tick's MuJoCo stepping calls alone (no Python around them)."""

    def _run_physics(self, dxu_clipped: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        raise NotImplementedError

    def step(self, dxu: np.ndarray) -> TickEvents:
        """Advance one control tick with unicycle commands (R, 2) [v m/s, ω rad/s].

        Returns the tick's :class:`TickEvents`; :attr:`poses` then holds the new poses.
        """
        return self._step(as_float_array("dxu", dxu, (self.layout.n_robots, 2)))

    def _step(self, dxu: np.ndarray) -> TickEvents:
        """:meth:`step` without input checks, for commands made inside comat (the filter's)."""
        return self.advance(*threshold_wheels(dxu, self.profile))

    def step_points(self, dxi: np.ndarray, distance: float) -> TickEvents:
        """A tick for velocities (R, 2) of the points ``distance`` ahead of the axles, made inside
        comat (float64, no input checks: the filter's): :func:`points_to_wheels` on the current
        poses, then :meth:`advance`."""
        return self.advance(*points_to_wheels(dxi, self._poses, self.cos_sin(), distance, self.profile))

    def advance(self, clipped: np.ndarray, overrun: np.ndarray) -> TickEvents:
        """Physics, poses, checks and counters of a tick with wheel-realizable unicycle commands
        (R, 2) [v m/s, ω rad/s] (no input checks: commands made inside comat, e.g. a reality
        layer's executed ones) and ``overrun`` (R,) bool, the robots whose request was clipped."""
        poses, robot_contact, wall_contact = self._run_physics(clipped)
        self._set_poses(poses)
        t = self.layout
        if kernels.enabled():
            ev = self.violations.check_and_add(
                poses, t.pair_i, t.pair_j, t.pair_team, overrun, robot_contact, wall_contact, self.cos_sin()
            )
        else:
            ev = check_tick(
                poses, t.pair_i, t.pair_j, t.pair_team, t.n_teams, overrun, robot_contact, wall_contact, self.cos_sin()
            )
            self.violations.add(ev)
        self.ticks += 1
        return ev

    @property
    def poses(self) -> np.ndarray:
        """(R, 3) current poses [x, y, θ] (a copy)."""
        return self._poses.copy()

    @property
    def pose_view(self) -> np.ndarray:
        """(R, 3) current poses [x, y, θ] without a copy, read-only: valid until the next tick or
        reset replaces them (the per-tick readers' seam: the filter, the reality layer, the envs)."""
        view = self._poses.view()
        view.flags.writeable = False
        return view

    def _set_poses(self, poses: np.ndarray) -> None:
        """Replace (or, with ``poses=self._poses``, mark as rewritten) the current poses."""
        self._poses = poses
        self._cos_sin = None

    def cos_sin(self) -> tuple[np.ndarray, np.ndarray]:
        """(R,) cosines and sines of the current headings, computed once per tick (read-only)."""
        if self._cos_sin is None:
            th = self._poses[:, 2]
            self._cos_sin = (np.cos(th), np.sin(th))
        return self._cos_sin


class World(_TickMixin):
    """One team of ``n_robots`` robots in the arena, simulated by MuJoCo.

    Args:
        n_robots: team size (no maximum).
        config: tier, substeps and robot profile.

    Attributes:
        model, data: the MuJoCo model (shared per team size, read-only) and this world's data.
        violations: running Robotarium-style and contact counts since the last reset.
        ticks: control ticks since the last reset.
    """

    def __init__(self, n_robots: int, config: SimConfig | None = None) -> None:
        n = check_positive_int("n_robots", n_robots)
        self.config = config or SimConfig()
        self.profile = C.PROFILES[self.config.profile]
        self.substeps = self.config.resolved_substeps
        self.model = compiled_scene(n, self.config.tier, self.config.profile, self.substeps)
        self.data = mujoco.MjData(self.model)
        self.binding = Binding(self.model, n, self.config.tier, self.profile)
        self.layout = team_layout((n,))
        self.violations = Violations(self.layout.robot_team, 1)
        self.ticks = 0
        self._set_poses(np.zeros((n, 3)))

    @property
    def n_robots(self) -> int:
        return self.layout.n_robots

    @property
    def time(self) -> float:
        """Simulated time since the last reset (s)."""
        return float(self.data.time)

    def reset(self, poses: np.ndarray) -> None:
        """Place the robots at rest at poses (N, 3) [x, y, θ]; zero the counters.

        Raises:
            ValueError: wrong shape, non-finite values, a robot outside the arena, or two
                robots overlapping.
        """
        poses = as_float_array("poses", poses, (self.n_robots, 3))
        validate_start_poses(poses, self.layout, self.profile.radius_m)
        mujoco.mj_resetData(self.model, self.data)
        self.binding.write_poses(self.data.qpos, poses)
        mujoco.mj_forward(self.model, self.data)
        self._set_poses(self.binding.poses(self.data.qpos))
        self.violations.reset()
        self.ticks = 0

    def set_robot_physics(self, friction: np.ndarray, mass_scale: np.ndarray, com_xy: np.ndarray) -> None:
        """Wheels tier: each robot's floor friction (N,), chassis mass scale (N,) and centre-of-mass
        offset (N, 2) m (:meth:`Binding.physics_fields`); this world gets its own model copy first
        (the compiled one is shared). Call before :meth:`reset`."""
        if self.config.tier != "wheels":
            return
        base = compiled_scene(self.n_robots, self.config.tier, self.config.profile, self.substeps)
        if self.model is base:
            self.model = copy.copy(base)
        for name, (index, values) in self.binding.physics_fields(friction, mass_scale, com_xy, base).items():
            field = getattr(self.model, name)
            if name == "geom_friction":
                field[index, 0] = values
            else:
                field[index] = values
        mujoco.mj_setConst(self.model, self.data)

    def _run_physics(self, dxu_clipped: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        m, d, b = self.model, self.data, self.binding
        d.ctrl[:] = b.ctrl(dxu_clipped)
        robot = np.zeros(self.n_robots, dtype=bool)
        wall = np.zeros(self.n_robots, dtype=bool)
        self.last_physics_s = 0.0
        for _ in range(self.substeps):
            t0 = time.perf_counter()
            mujoco.mj_step(m, d)
            self.last_physics_s += time.perf_counter() - t0
            r, w = b.contacts(d.sensordata)
            robot |= r
            wall |= w
        return b.poses(d.qpos), robot, wall
