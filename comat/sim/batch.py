"""Many teams advanced together: one ``mujoco.batch.Batch`` call per tick and team size.

Teams of equal size share one compiled model and one Batch (``rollout`` of ``substeps``
substeps, recording the contact sensors at every substep); teams of different sizes run as a
few such groups. Arrays are the teams' robots concatenated row-wise, (R, ·), in team order
(see :class:`comat.sim.layout.TeamLayout`). Results equal :class:`comat.sim.World` run on each
team alone (``tests/test_batch.py``).
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import mujoco
import mujoco.batch
import numpy as np

from comat import constants as C
from comat._validate import as_float_array
from comat.config import SimConfig
from comat.mjcf.scene import compiled_scene
from comat.sim.binding import Binding
from comat.sim.layout import team_layout
from comat.sim.violations import Violations
from comat.sim.world import _TickMixin, validate_start_poses

__all__ = ["BatchWorld"]


class _Group:
    """All teams of one size: a Batch over their shared model."""

    def __init__(self, teams: np.ndarray, rows: np.ndarray, n: int, config: SimConfig, substeps: int, nthread: int):
        self.teams = teams  # (S,) team indices
        self.rows = rows  # (S, n) robot rows in the flat arrays
        model = compiled_scene(n, config.tier, config.profile, substeps)
        self.binding = Binding(model, n, config.tier, C.PROFILES[config.profile])
        self.batch = mujoco.batch.Batch(model, nsim=len(teams), nthread=nthread)
        self.qpos = self.batch.bind("qpos")
        self.qvel = self.batch.bind("qvel")
        self.ctrl = self.batch.bind("ctrl")
        self.substeps = substeps
        self._record = {"sensordata": np.empty((len(teams), substeps, model.nsensordata))}


class BatchWorld(_TickMixin):
    """B teams (sizes may differ) simulated together; the batched counterpart of ``World``.

    Args:
        team_sizes: robots per team.
        config: tier, substeps and profile, shared by all teams.
        nthread: threads for MuJoCo's batch (1 = the calling thread only; 0 = all cores).
    """

    def __init__(self, team_sizes: Sequence[int], config: SimConfig | None = None, nthread: int = 1) -> None:
        if isinstance(team_sizes, (int, np.integer)) or not all(
            isinstance(n, (int, np.integer)) and not isinstance(n, bool) and n >= 1 for n in team_sizes
        ) or len(team_sizes) == 0:
            raise ValueError(f"team_sizes must be a non-empty sequence of positive integers, got {team_sizes!r}")
        self.config = config or SimConfig()
        self.profile = C.PROFILES[self.config.profile]
        self.substeps = self.config.resolved_substeps
        self.layout = team_layout(tuple(int(n) for n in team_sizes))
        sizes = np.array(self.layout.team_sizes)
        self.groups: list[_Group] = []
        for n in np.unique(sizes):
            teams = np.flatnonzero(sizes == n)
            rows = self.layout.offsets[teams][:, None] + np.arange(n)
            self.groups.append(_Group(teams, rows, int(n), self.config, self.substeps, nthread))
        self.violations = Violations(self.layout.robot_team, self.layout.n_teams)
        self.ticks = 0
        self._poses = np.zeros((self.layout.n_robots, 3))

    @property
    def team_sizes(self) -> tuple[int, ...]:
        return self.layout.team_sizes

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
            g.batch.reset(sel, stage=mujoco.mjtStage.mjSTAGE_NONE)
            q = g.qpos[sel].copy()
            g.binding.write_poses(q, poses[g.rows[sel]])
            g.qpos[sel] = q
            g.batch.forward(sel)
            self._poses[g.rows[sel].ravel()] = g.binding.poses(g.qpos[sel]).reshape(-1, 3)
        self.violations.reset(team_ids)
        if teams is None:
            self.ticks = 0

    def _run_physics(self, dxu_clipped: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        self.last_physics_s = 0.0
        if len(self.groups) == 1:  # all teams of one size, rows in order: no gathers/scatters
            g = self.groups[0]
            poses, robot, wall = self._group_step(g, dxu_clipped.reshape(*g.rows.shape, 2))
            return poses.reshape(-1, 3), robot.ravel(), wall.ravel()
        R = self.layout.n_robots
        poses = np.empty((R, 3))
        robot = np.empty(R, dtype=bool)
        wall = np.empty(R, dtype=bool)
        for g in self.groups:
            p, r, w = self._group_step(g, np.take(dxu_clipped, g.rows, axis=0))
            idx = g.rows.ravel()
            poses[idx] = p.reshape(-1, 3)
            robot[idx] = r.ravel()
            wall[idx] = w.ravel()
        return poses, robot, wall

    def _group_step(self, g: _Group, dxu: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One tick of one group: commands (S, n, 2) in; poses (S, n, 3) and contact flags out."""
        g.ctrl[:] = g.binding.ctrl(dxu)
        t0 = time.perf_counter()
        rec = g.batch.rollout(g.substeps, record=("sensordata",), out=g._record)["sensordata"]
        self.last_physics_s += time.perf_counter() - t0
        robot, wall = g.binding.contacts_any(rec)
        return g.binding.poses(g.qpos), robot, wall
