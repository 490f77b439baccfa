"""Many teams advanced together: one ``mujoco.batch.Batch`` call per tick and team size.

Teams of equal size share one compiled model and one Batch (``rollout`` of ``substeps``
substeps, recording the contact sensors at every substep); teams of different sizes run as a
few such groups. Team sizes may change between episodes (:meth:`BatchWorld.set_team_sizes`):
each size's Batch has room for every team, and a team simply moves to a free simulation of its
new size. Arrays are the teams' robots concatenated row-wise, (R, ·), in team order (see
:class:`comat.sim.layout.TeamLayout`). Results equal :class:`comat.sim.World` run on each team
alone (``tests/test_batch.py``).
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import mujoco
import mujoco.batch
import numpy as np

from comat import constants as C
from comat import kernels
from comat._validate import as_float_array
from comat.config import SimConfig
from comat.mjcf.scene import compiled_scene
from comat.sim.binding import Binding
from comat.sim.layout import TeamLayout, team_layout
from comat.sim.violations import Violations
from comat.sim.world import _TickMixin, validate_start_poses

__all__ = ["BatchWorld"]

# The extension's rollout behind mujoco.batch.Batch.rollout, as mujoco 4.0 calls it.
_DIRECT_ROLLOUT = mujoco.__version__.startswith("4.0.") and hasattr(mujoco.batch.Batch, "_check")


class _Group:
    """Every team of one size: a Batch of ``capacity`` simulations over their shared model."""

    def __init__(self, n: int, capacity: int, config: SimConfig, substeps: int, nthread: int):
        model = compiled_scene(n, config.tier, config.profile, substeps)
        self.n = n
        self.binding = Binding(model, n, config.tier, C.PROFILES[config.profile])
        self.batch = mujoco.batch.Batch(model, nsim=capacity, nthread=nthread)
        self.qpos = self.batch.bind("qpos")
        self.ctrl = self.batch.bind("ctrl")
        self.substeps = substeps
        self.nsensordata = model.nsensordata
        self.owner = np.full(capacity, -1, dtype=np.int64)  # team using each simulation, -1 = free
        # Per layout: active simulations (sorted), their teams and robot rows (S, n).
        self.sims = np.zeros(0, np.int64)
        self.sims32 = np.zeros(0, np.int32)
        self.in_order = False
        self.teams = np.zeros(0, np.int64)
        self.rows = np.zeros((0, n), np.int64)
        self._records: dict[int, dict[str, np.ndarray]] = {}

    def record(self, count: int) -> dict[str, np.ndarray]:
        buf = self._records.get(count)
        if buf is None:
            buf = self._records[count] = {"sensordata": np.empty((count, self.substeps, self.nsensordata))}
        return buf

    def rollout(self) -> np.ndarray:
        """``substeps`` physics steps of this layout's simulations, recording the sensors:
        (S, substeps, nsensordata) in the order of :attr:`sims`.

        With mujoco 4.0 the call goes to the extension directly: the public wrapper re-checks the
        ids and rebuilds its record list on every call (~50 µs, 7 % of an env step with 16
        environments), for ids that :meth:`BatchWorld.set_team_sizes` made valid once. The
        reference path (``comat.kernels.reference_path``) keeps the wrapper; rollouts through
        both are equal bit for bit (tests/test_kernels.py)."""
        buf = self.record(self.sims.size)
        if not _DIRECT_ROLLOUT:
            return self.batch.rollout(
                self.substeps, record=("sensordata",), ids=None if self.in_order else self.sims, out=buf
            )["sensordata"]
        ids = None if self.in_order else self.sims32
        failed = self.batch._b.rollout(
            ids, self.substeps, None, mujoco.mjtState.mjSTATE_CTRL.value, [("sensordata", 0, buf["sensordata"])]
        )
        if failed:
            self.batch._check(ids, failed)  # raises SimulationError, as the wrapper does
        return buf["sensordata"]


class BatchWorld(_TickMixin):
    """B teams (sizes may differ, and change between episodes) simulated together.

    Args:
        team_sizes: robots per team.
        config: tier, substeps and profile, shared by all teams.
        nthread: threads for MuJoCo's batch (1 = the calling thread only; 0 = all cores); None:
            ``config.threads``.
    """

    def __init__(self, team_sizes: Sequence[int], config: SimConfig | None = None, nthread: int | None = None) -> None:
        sizes = self._check_sizes(team_sizes)
        self.config = config or SimConfig()
        nthread = self.config.threads if nthread is None else nthread
        self.profile = C.PROFILES[self.config.profile]
        self.substeps = self.config.resolved_substeps
        self._nthread = nthread
        self._groups: dict[int, _Group] = {}
        self._sim_of = np.full(len(sizes), -1, dtype=np.int64)  # simulation index of each team
        self.layout: TeamLayout = team_layout((1,) * len(sizes))  # replaced below
        self._sizes = np.zeros(len(sizes), np.int64)
        self.set_team_sizes(sizes)

    @staticmethod
    def _check_sizes(team_sizes) -> tuple[int, ...]:
        if (
            isinstance(team_sizes, (int, np.integer))
            or len(team_sizes) == 0
            or not all(isinstance(n, (int, np.integer)) and not isinstance(n, bool) and n >= 1 for n in team_sizes)
        ):
            raise ValueError(f"team_sizes must be a non-empty sequence of positive integers, got {team_sizes!r}")
        return tuple(int(n) for n in team_sizes)

    @property
    def team_sizes(self) -> tuple[int, ...]:
        return self.layout.team_sizes

    @property
    def groups(self) -> list[_Group]:
        """Groups with at least one team, by size (set by :meth:`set_team_sizes`)."""
        return self._active

    def set_team_sizes(self, team_sizes: Sequence[int]) -> None:
        """Change the team sizes (same number of teams).

        Teams whose size is unchanged keep their simulation and state; the others get a fresh
        simulation of their new size and must be :meth:`reset` before the next tick. Counters
        restart (they are per robot, and robots change).
        """
        sizes = self._check_sizes(team_sizes)
        if len(sizes) != self._sizes.size:
            raise ValueError(f"team_sizes must list {self._sizes.size} teams, got {len(sizes)}")
        old_poses = getattr(self, "_poses", None)
        old_layout = self.layout
        B = len(sizes)
        for b, n in enumerate(sizes):
            if self._sizes[b] == n and self._sim_of[b] >= 0:
                continue
            if self._sim_of[b] >= 0:
                self._groups[int(self._sizes[b])].owner[self._sim_of[b]] = -1
            group = self._groups.get(n)
            if group is None:
                group = self._groups[n] = _Group(n, B, self.config, self.substeps, self._nthread)
            free = np.flatnonzero(group.owner < 0)
            sim = int(free[0])
            group.owner[sim] = b
            self._sim_of[b] = sim
            self._sizes[b] = n
        self.layout = team_layout(sizes)
        poses = np.zeros((self.layout.n_robots, 3))
        for n, group in self._groups.items():
            teams = np.flatnonzero(self._sizes == n)
            order = np.argsort(self._sim_of[teams])  # MuJoCo's batch calls take sorted ids
            group.teams = teams[order]
            group.sims = self._sim_of[group.teams]
            group.sims32 = group.sims.astype(np.int32)
            group.rows = self.layout.offsets[group.teams][:, None] + np.arange(n)
            group.in_order = group.teams.size == B and np.array_equal(group.sims, np.arange(B))
        self._active = [g for g in self._groups.values() if g.sims.size]
        if old_poses is not None:
            # Teams that kept their size keep their poses.
            for b in range(B):
                if b < old_layout.n_teams and old_layout.team_sizes[b] == sizes[b]:
                    poses[self.layout.offsets[b] : self.layout.offsets[b + 1]] = old_poses[
                        old_layout.offsets[b] : old_layout.offsets[b + 1]
                    ]
        self._set_poses(poses)
        self.violations = Violations(self.layout.robot_team, self.layout.n_teams)
        self.ticks = 0

    def set_robot_physics(
        self, friction: np.ndarray, mass_scale: np.ndarray, com_xy: np.ndarray, teams: Sequence[int] | None = None
    ) -> None:
        """Wheels tier: per-robot floor friction (R,), chassis mass scale (R,) and centre-of-mass
        offset (R, 2) m of ``teams`` (all if None; rows of the others are ignored), written into
        their simulations' own model fields (``Batch.expand``; the first call makes those fields
        per simulation, which no off run ever does). Call before :meth:`reset`."""
        if self.config.tier != "wheels":
            return
        team_ids = np.arange(self.layout.n_teams) if teams is None else np.asarray(teams, dtype=np.int64)
        for g in self.groups:
            sel = np.flatnonzero(np.isin(g.teams, team_ids))
            if sel.size == 0:
                continue
            sims, rows = g.sims[sel], g.rows[sel]
            base = compiled_scene(g.n, self.config.tier, self.config.profile, g.substeps)
            for s_i, r in zip(sims, rows):
                for name, (index, values) in g.binding.physics_fields(
                    friction[r], mass_scale[r], com_xy[r], base
                ).items():
                    field = g.batch.expand(name)
                    if name == "geom_friction":
                        field[s_i, index, 0] = values
                    else:
                        field[s_i, index] = values
            g.batch.set_const(sims.astype(np.int32))

    def reset(self, poses: np.ndarray, teams: Sequence[int] | None = None) -> None:
        """Place robots at rest and zero their counters.

        Args:
            poses: (R, 3) poses of all robots; with ``teams``, only those teams' rows are used.
            teams: team indices to reset (all if None); the others keep running.
        """
        R = self.layout.n_robots
        poses = as_float_array("poses", poses, (R, 3))
        team_ids = np.arange(self.layout.n_teams) if teams is None else np.asarray(teams, dtype=np.int64)
        if team_ids.size and (team_ids.min() < 0 or team_ids.max() >= self.layout.n_teams):
            raise ValueError(f"teams must be indices in [0, {self.layout.n_teams}), got {team_ids.tolist()}")
        for b in team_ids:
            sl = slice(self.layout.offsets[b], self.layout.offsets[b + 1])
            validate_start_poses(poses[sl], team_layout((self.layout.team_sizes[b],)), self.profile.radius_m)
        for g in self.groups:
            sel = np.flatnonzero(np.isin(g.teams, team_ids))
            if sel.size == 0:
                continue
            sims = g.sims[sel]
            g.batch.reset(sims, stage=mujoco.mjtStage.mjSTAGE_NONE)
            q = g.qpos[sims].copy()
            g.binding.write_poses(q, poses[g.rows[sel]])
            g.qpos[sims] = q
            g.batch.forward(sims)
            self._poses[g.rows[sel].ravel()] = g.binding.poses(g.qpos[sims]).reshape(-1, 3)
        self._set_poses(self._poses)  # rewritten in place
        self.violations.reset(team_ids)
        if teams is None:
            self.ticks = 0

    def _run_physics(self, dxu_clipped: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        self.last_physics_s = 0.0
        if kernels.enabled():
            return self._run_physics_compiled(dxu_clipped)
        groups = self.groups
        if len(groups) == 1 and groups[0].in_order:  # one size, simulations in team order
            g = groups[0]
            poses, robot, wall = self._group_step(g, dxu_clipped.reshape(*g.rows.shape, 2), None)
            return poses.reshape(-1, 3), robot.ravel(), wall.ravel()
        R = self.layout.n_robots
        poses = np.empty((R, 3))
        robot = np.empty(R, dtype=bool)
        wall = np.empty(R, dtype=bool)
        for g in groups:
            p, r, w = self._group_step(g, np.take(dxu_clipped, g.rows, axis=0), g.sims)
            idx = g.rows.ravel()
            poses[idx] = p.reshape(-1, 3)
            robot[idx] = r.ravel()
            wall[idx] = w.ravel()
        return poses, robot, wall

    def _run_physics_compiled(self, dxu: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`_run_physics` with the bindings compiled: per group, one kernel writes the
        actuator targets, MuJoCo steps, one kernel scatters poses and contact flags."""
        R = self.layout.n_robots
        poses = np.empty((R, 3))
        robot = np.empty(R, dtype=bool)
        wall = np.empty(R, dtype=bool)
        for g in self.groups:
            b = g.binding
            unicycle = b.tier == "unicycle"
            kernels.group_ctrl(
                dxu, g.rows, g.sims, unicycle, b.half_timestep, b.lateral_gain, *b.wheel_geometry, g.ctrl
            )
            t0 = time.perf_counter()
            rec = g.rollout()
            self.last_physics_s += time.perf_counter() - t0
            kernels.group_read(
                rec, g.qpos, g.sims, b.qadr, b.sensor_all, b.sensor_wall, g.rows, unicycle, poses, robot, wall
            )
            if not unicycle:  # the yaw from the quaternion: arctan2 stays in numpy
                poses[g.rows.ravel(), 2] = b.poses(g.qpos[g.sims])[..., 2].ravel()
        return poses, robot, wall

    def _group_step(self, g: _Group, dxu: np.ndarray, sims: np.ndarray | None):
        """One tick of one group: commands (S, n, 2) in; poses (S, n, 3) and contact flags out."""
        count = g.batch.nsim if sims is None else sims.size
        if sims is None:
            g.ctrl[:] = g.binding.ctrl(dxu)
        else:
            g.ctrl[sims] = g.binding.ctrl(dxu)
        t0 = time.perf_counter()
        rec = g.batch.rollout(g.substeps, record=("sensordata",), ids=sims, out=g.record(count))["sensordata"]
        self.last_physics_s += time.perf_counter() - t0
        robot, wall = g.binding.contacts_any(rec)
        qpos = g.qpos if sims is None else g.qpos[sims]
        return g.binding.poses(qpos), robot, wall
