"""The reality layer of R robots: measured poses out of the world, executed commands into it.

:class:`RealityLayer` composes the pose path, the command path and the motors
(:mod:`comat.reality.paths`, :mod:`comat.reality.motors`) for every robot of a (batched) world.
:class:`comat.control.SafeTeams` calls it at the two boundaries of a tick::

    measured poses ──> waypoint controller, safety filter, (policy)   [decide]
    filtered command ──> si→unicycle on the measured heading ──> wheel limit
      ──> actuate(): command path ──> motors ──> physics ──> true poses   [judge]
      ──> observe(true poses): pose path ──> measured poses

Randomness: each team gets a 64-bit key per episode (:func:`comat.reality.random.episode_key`,
from the env's generator without advancing it), each robot a key derived from it, and every
draw is a pure function of (robot key, robot tick, stream) (:mod:`comat.reality.random`). A
calibrated config (:class:`~comat.reality.randomize.CalibratedReality`) also draws its identified
parameters per episode and team from the team's key (:mod:`comat.reality.randomize`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from comat import constants as C
from comat.reality import random as rr
from comat.reality.config import RealityConfig
from comat.reality.margin import StalePoses
from comat.reality.motors import Motors
from comat.reality.paths import CommandPath, PosePath, run_lengths
from comat.reality.randomize import DRAW_NAMES, EPISODE_STREAM, draw_values
from comat.sim.kinematics import projected_points
from comat.sim.layout import TeamLayout

__all__ = ["IdentityReality", "RealityLayer"]

# Per-tick streams (one draw of 10 streams per robot and tick: 5 uniforms, then 5 normals).
_UNIFORM = slice(0, 5)  # command: loss start, run length; pose: hold, freeze start, freeze length
_CMD = slice(0, 2)
_POSE_U = slice(2, 5)
_NORMAL = slice(5, 10)  # motors: 2 (the wheels' disturbance); pose: 3 (x, y, θ of the next measurement)
_MOTOR = slice(0, 2)
_POSE_N = slice(2, 5)
# Per-episode stream offsets (tick = rr.EPISODE).
_EP_POSE_DELAY, _EP_BIAS, _EP_POSE0, _EP_CMD_DELAY, _EP_MOTOR, _EP_MOTOR_N, _EP_FAULT, _EP_START, _EP_PHYSICS = (
    100,
    200,
    250,
    300,
    400,
    450,
    500,
    600,
    700,
)
# Per-tick team streams, drawn from each team's first robot (its key and its clock): the script's
# timing (missed tick, stall start, stall length) and the pose message's jitter.
_TEAM_STREAM = 20
_T_MISS, _T_STALL, _T_STALL_LEN, _T_HOLD, _T_JITTER = 0, 1, 2, 3, 4
_TEAM_DRAWS = 5


class RealityLayer:
    """Measured poses and executed commands of the robots of ``layout`` under ``config``.

    :class:`IdentityReality` is the layer at ``off``: the same interface, nothing between.

    Args:
        config: the components and their magnitudes (:class:`~comat.control.SafeTeams` builds no
            layer for a config that ``is_off``; a layer built anyway passes everything through).
        profile: the robots' generation (wheel radius, axle, wheel limit).
        layout: the teams' rows (R robots in team order).
        seed: keys of teams reset without one (direct :class:`~comat.control.SafeTeams` users):
            team b's k-th episode gets a key from (seed, b, k).
    """

    def __init__(self, config: RealityConfig, profile: C.RobotProfile, layout: TeamLayout, seed: int = 0) -> None:
        self.config = config
        self.profile = profile
        self.seed = int(seed)
        self.pose_on = any(
            getattr(config, k)
            for k in (
                "pose_delay_ticks",
                "pose_delay_spread_ticks",
                "pose_hold_prob",
                "pose_noise_xy_m",
                "pose_noise_theta_rad",
                "pose_bias_xy_m",
                "pose_freeze_prob",
                "pose_delay_jitter_prob",
            )
        )
        self.command_on = bool(config.command_delay_max_ticks or config.command_loss_prob)
        self.motors_on = bool(
            config.motor_tau_max_s
            or config.motor_accel_limit_radps2
            or config.motor_dead_zone_radps
            or config.wheel_gain_spread
            or config.wheel_gain_mean != 1.0
            or config.top_speed_derate_min < 1
            or config.wheel_disturbance_radps
            or config.fault_prob
        )
        self.is_off = False
        """A layer runs (even one whose every component is zero: each of its paths runs)."""
        self.physics_on = bool(config.floor_friction_max or config.chassis_mass_spread or config.com_offset_m)
        self.script_on = bool(config.script_miss_prob or config.script_stall_prob)
        """The script's own timing: ticks it misses (overruns) and stalls, common to a team."""
        self.team_poses = self.pose_on and not config.pose_per_robot
        """The pose message's delay, jitter and holds are common to each team (one message per tick)."""
        """Per-robot physics to vary (wheels tier; :meth:`physics` gives the values)."""
        self._episodes = np.zeros(0, np.int64)  # per team: episodes begun (for seed-derived keys)
        self.intervals: dict[str, tuple[float, float]] = dict(getattr(config, "intervals", None) or {})
        """Calibrated draws, name -> (lo, hi) (:mod:`comat.reality.randomize`); empty: the config's values."""
        self._build(layout)
        self._u: np.ndarray | None = None

    def _build(self, layout: TeamLayout) -> None:
        R = layout.n_robots
        self.layout = layout
        self.keys = np.zeros(R, np.uint64)
        """(R,) each robot's key for this episode."""
        self.ticks = np.zeros(R, np.int64)
        """(R,) ticks since each robot's episode began."""
        self.pose = PosePath(self.config, R)
        self.command = CommandPath(self.config, R)
        self.motors = Motors(self.config, self.profile, R)
        self._true = np.zeros((R, 3))
        self._cos_sin: tuple[np.ndarray, np.ndarray] | None = None
        self.stale = StalePoses(R, self.pose.noisy)
        """The filter's pose estimate: measured, dead-reckoned while a measurement repeats."""
        self._sent = np.zeros((R, 2))
        self._physics = (np.full(R, C.WHEEL_FRICTION), np.ones(R), np.zeros((R, 2)))
        self._first = layout.offsets[:-1].astype(np.int64)
        """(B,) each team's first robot: its key and clock draw the team's shared randomness."""
        self.stall_left = np.zeros(layout.n_teams, np.int64)
        """(B,) ticks of the team's script stall still to come."""
        self.missed = np.zeros(R, dtype=bool)
        self.drawn = {name: np.zeros(R) for name in self.intervals}
        """Name -> (R,) this episode's calibrated draw of each robot (its team's)."""
        """(R,) robots whose script sent nothing this tick (an overrun or a stall)."""
        self._team_u: np.ndarray | None = None  # this tick's team draws (B, _TEAM_DRAWS)
        self._est_cos_sin: tuple[np.ndarray, np.ndarray] | None = None
        episodes = np.zeros(layout.n_teams, np.int64)
        episodes[: min(layout.n_teams, self._episodes.size)] = self._episodes[: layout.n_teams]
        self._episodes = episodes

    # -- what the robots' script sees -----------------------------------------------------------------
    @property
    def measured(self) -> np.ndarray:
        """(R, 3) the latest measured poses (read-only; the true ones when the pose path is off)."""
        return self.pose.measured if self.pose_on else self._true

    def cos_sin(self) -> tuple[np.ndarray, np.ndarray]:
        """(R,) cosines and sines of the measured headings (computed once per tick)."""
        if self._cos_sin is None:
            th = self.measured[:, 2]
            self._cos_sin = (np.cos(th), np.sin(th))
        return self._cos_sin

    @property
    def estimated(self) -> np.ndarray:
        """(R, 3) the filter's pose estimate (:class:`~comat.reality.margin.StalePoses`; the
        measured poses when repeats cannot be detected)."""
        return self.stale.estimate if self.stale.enabled else self.measured

    def estimated_cos_sin(self) -> tuple[np.ndarray, np.ndarray]:
        """(R,) cosines and sines of the estimated headings (computed once per tick)."""
        if not self.stale.enabled:
            return self.cos_sin()
        if self._est_cos_sin is None:
            th = self.stale.estimate[:, 2]
            self._est_cos_sin = (np.cos(th), np.sin(th))
        return self._est_cos_sin

    def points(self, distance: float) -> np.ndarray:
        """(R, 2) the measured poses' points ``distance`` ahead of the axles."""
        return projected_points(self.measured, distance)

    def physics(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """This episode's wheels-tier physics per robot: floor friction (R,), chassis mass scale
        (R,), centre-of-mass offset (R, 2) m (the model's own values where the component is off)."""
        return self._physics

    @property
    def speed_fraction(self) -> np.ndarray:
        """(R,) each robot's speed factor from its fault now (1: healthy): what a capability
        vector reports when ``config.fault_known``."""
        if self.config.fault_prob <= 0:
            return np.ones(self.layout.n_robots)
        return np.where(self.motors.faulty(self.ticks), self.config.fault_speed_fraction, 1.0)

    # -- episodes -------------------------------------------------------------------------------------
    def start(self, poses: np.ndarray, teams: np.ndarray, keys: Sequence[int] | None) -> np.ndarray:
        """Begin episodes of ``teams`` with their keys (None: from the seed) and return the (R, 3)
        poses they really start at: the requested ones plus the start error, kept inside the
        arena and apart (a robot whose error would overlap a teammate starts where requested)."""
        lay = self.layout
        teams = np.asarray(teams, np.int64)
        if keys is None:
            seed = np.array([self.seed], np.uint64)
            keys = [
                rr._mix(seed ^ rr._mix(np.array([(int(b) << 32) + int(self._episodes[b])], np.uint64)))[0]
                for b in teams
            ]
        self._episodes[teams] += 1
        rows_of = [np.arange(lay.offsets[b], lay.offsets[b + 1]) for b in teams]
        for b, key, rows in zip(teams, keys, rows_of):
            self.keys[rows] = rr.robot_keys(np.uint64(key), rows.size)
        rows = np.concatenate(rows_of) if rows_of else np.zeros(0, np.int64)
        k = self.keys[rows]
        self.ticks[rows] = 0
        c = self.config
        drawn = self._draw(keys, [r.size for r in rows_of], rows) if self.intervals else None
        spread = max(c.pose_delay_spread_ticks, 1)
        delay_u = rr.uniforms(k, rr.EPISODE, spread, _EP_POSE_DELAY)[:, : c.pose_delay_spread_ticks]
        if not c.pose_per_robot and rows.size:  # one message per tick: each team's first robot draws its age
            sizes = [r.size for r in rows_of]
            delay_u = delay_u[np.repeat(np.cumsum([0, *sizes[:-1]]), sizes)]
        self.pose.begin(rows, poses[rows], delay_u, rr.normals(k, rr.EPISODE, 2, _EP_BIAS), drawn)
        self.stall_left[teams] = 0
        spread = max(c.command_delay_spread_ticks, 1)
        self.command.begin(rows, rr.uniforms(k, rr.EPISODE, spread, _EP_CMD_DELAY)[:, : c.command_delay_spread_ticks])
        self.motors.begin(
            rows,
            rr.uniforms(k, rr.EPISODE, 5, _EP_MOTOR),
            rr.normals(k, rr.EPISODE, 2, _EP_MOTOR_N),
            self._fault_ticks(rows_of),
            drawn,
        )
        if self.physics_on:
            u = rr.uniforms(k, rr.EPISODE, 4, _EP_PHYSICS)
            friction, mass, com = self._physics
            if c.floor_friction_max > 0:
                friction[rows] = c.floor_friction_min + (c.floor_friction_max - c.floor_friction_min) * u[:, 0]
            mass[rows] = 1.0 + c.chassis_mass_spread * (2.0 * u[:, 1] - 1.0)
            com[rows] = c.com_offset_m * (2.0 * u[:, 2:4] - 1.0)
        out = poses.copy()
        if c.start_xy_m > 0 or c.start_theta_rad > 0:
            for rows_b in rows_of:
                out[rows_b] = self._start_error(poses[rows_b], self.keys[rows_b])
        return out

    def _draw(self, keys: Sequence[int], sizes: list[int], rows: np.ndarray) -> dict[str, np.ndarray]:
        """The started teams' calibrated draws (one per team from its episode key, ``keys``), spread
        to their robots: stored in :attr:`drawn` and returned for ``rows``, name -> (r,)."""
        team_keys = np.array([np.uint64(key) for key in keys], np.uint64)
        values = draw_values(self.intervals, rr.uniforms(team_keys, rr.EPISODE, len(DRAW_NAMES), EPISODE_STREAM))
        out = {}
        for name, v in values.items():
            out[name] = np.repeat(v, sizes)
            self.drawn[name][rows] = out[name]
        return out

    def _team_value(self, name: str) -> float | np.ndarray:
        """The config's value of ``name``, or (B,) each team's calibrated draw of it (its first robot's)."""
        return self.drawn[name][self._first] if name in self.drawn else getattr(self.config, name)

    def _fault_ticks(self, rows_of: list[np.ndarray]) -> np.ndarray:
        """Per robot of the reset teams: the tick its fault begins (int64 max: none)."""
        c = self.config
        never = np.iinfo(np.int64).max
        out = [np.full(rows.size, never, np.int64) for rows in rows_of]
        if c.fault_prob <= 0:
            return np.concatenate(out) if out else np.zeros(0, np.int64)
        for o, rows in zip(out, rows_of):
            u = rr.uniforms(self.keys[rows[:1]], rr.EPISODE, 3, _EP_FAULT)[0]
            if u[0] < c.fault_prob:
                start_s = c.fault_start_min_s + (c.fault_start_max_s - c.fault_start_min_s) * u[2]
                o[min(int(u[1] * rows.size), rows.size - 1)] = round(start_s / C.CONTROL_DT_S)
        return np.concatenate(out)

    def _start_error(self, poses: np.ndarray, keys: np.ndarray) -> np.ndarray:
        """One team's start poses (n, 3) moved by the start error (uniform in a disc of radius
        ``start_xy_m``: the start-up drive's radial tolerance; heading ±``start_theta_rad``), valid
        for the world."""
        c = self.config
        u = rr.uniforms(keys, rr.EPISODE, 3, _EP_START)
        radius, angle = c.start_xy_m * np.sqrt(u[:, 0]), 2.0 * np.pi * u[:, 1]
        out = poses + np.column_stack(
            [radius * np.cos(angle), radius * np.sin(angle), (2.0 * u[:, 2] - 1.0) * c.start_theta_rad]
        )
        out[:, 2] = np.pi - np.remainder(np.pi - out[:, 2], 2.0 * np.pi)
        r = self.profile.radius_m
        x0, x1, y0, y1 = C.ARENA_BOUNDS_M
        margin = 1e-9  # the world's own check is strict at the wall
        out[:, 0] = np.clip(out[:, 0], x0 + r + margin, x1 - r - margin)
        out[:, 1] = np.clip(out[:, 1], y0 + r + margin, y1 - r - margin)
        n = out.shape[0]
        if n > 1:
            i, j = np.triu_indices(n, 1)
            moved = np.ones(n, dtype=bool)
            while True:  # reset-time only; each pass returns robots to their requested poses
                d = np.hypot(*(out[i, :2] - out[j, :2]).T)
                bad = (d < 2 * r + 1e-9) & (moved[i] | moved[j])
                if not bad.any():
                    break  # (overlaps among requested poses are the world's to reject)
                back = np.unique(np.concatenate([i[bad], j[bad]]))
                out[back] = poses[back]
                moved[back] = False
        return out

    def _script_missed(self, u: np.ndarray) -> np.ndarray:
        """(B,) teams whose script sends nothing this tick: an overrun (``script_miss_prob``) or a
        stall (a run of ticks started with ``script_stall_prob``), from the team draws u (B, 5)."""
        c = self.config
        stalled = self.stall_left > 0
        self.stall_left -= stalled
        start = ~stalled & (u[:, _T_STALL] < c.script_stall_prob)
        if start.any():
            self.stall_left[start] = (
                run_lengths(u[start, _T_STALL_LEN], c.script_stall_mean_ticks, np.iinfo(np.int32).max) - 1
            )
        return stalled | start | (u[:, _T_MISS] < c.script_miss_prob)

    def begin_measuring(self, true: np.ndarray, teams: np.ndarray) -> None:
        """After the world placed the reset teams: their first measurement from true poses (R, 3)."""
        lay = self.layout
        rows = (
            np.concatenate([np.arange(lay.offsets[b], lay.offsets[b + 1]) for b in teams])
            if len(teams)
            else np.zeros(0, np.int64)
        )
        self._true = true
        if self.pose_on and rows.size:
            self.pose.history[rows] = true[rows][:, None, :]
            self.pose.first(rows, true[rows], rr.normals(self.keys[rows], rr.EPISODE, 3, _EP_POSE0))
            self.stale.start(rows, self.pose.measured)
            self._sent[rows] = 0.0
        self._cos_sin = self._est_cos_sin = None

    # -- ticks ----------------------------------------------------------------------------------------
    def actuate(self, dxu: np.ndarray) -> np.ndarray:
        """Unicycle commands (R, 2) the robots execute this tick for those the script sent (R, 2)
        (within the wheel limits)."""
        u, normal = rr.tick_draws(self.keys, self.ticks, _UNIFORM.stop, _NORMAL.stop - _NORMAL.start)
        self._u = (u, normal)
        if self.script_on or self.team_poses:
            self._team_u = rr.uniforms(self.keys[self._first], self.ticks[self._first], _TEAM_DRAWS, _TEAM_STREAM)
        if self.script_on:
            self.missed = self._script_missed(self._team_u)[self.layout.robot_team]
        np.copyto(self._sent, dxu)
        if self.command_on or self.script_on:
            out = self.command.update(dxu, self.ticks, u[:, _CMD], self.missed if self.script_on else None)
        else:
            out = dxu
        if self.motors_on:
            out = self.motors.update_unicycle(out, self.ticks, normal[:, _MOTOR])
        return out

    def observe(self, true: np.ndarray) -> None:
        """After the tick's physics: advance the robots' clocks and measure true poses (R, 3)."""
        self.ticks += 1
        self._true = true
        self._cos_sin = self._est_cos_sin = None
        if not self.pose_on:
            return
        if self._u is None:  # observed without actuate (tests, direct users): the same draws
            self._u = rr.tick_draws(self.keys, self.ticks - 1, _UNIFORM.stop, _NORMAL.stop - _NORMAL.start)
        u, normal = self._u
        self._u = None
        hold, jitter = None, None
        if self.team_poses or self.script_on or "pose_hold_prob" in self.drawn:
            if self._team_u is None and (self.team_poses or self.script_on):  # observed without actuate
                first = self._first
                self._team_u = rr.uniforms(self.keys[first], self.ticks[first] - 1, _TEAM_DRAWS, _TEAM_STREAM)
            c, team, tu = self.config, self.layout.robot_team, self._team_u
            if self.team_poses:  # the message that did not come, or came late, did for every robot
                hold = (tu[:, _T_HOLD] < self._team_value("pose_hold_prob"))[team]
                if c.pose_delay_jitter_prob > 0:
                    jitter = (tu[:, _T_JITTER] < self._team_value("pose_delay_jitter_prob"))[team].astype(np.int64)
            else:
                hold = u[:, _POSE_U][:, 0] < (self.drawn.get("pose_hold_prob", c.pose_hold_prob))
            hold = hold | self.missed  # a script that missed the tick reads a stale message next
        self._team_u = None
        self.pose.update(true, self.ticks, normal[:, _POSE_N] if self.pose.noisy else None, u[:, _POSE_U], hold, jitter)
        self.stale.update(self.pose.measured, self._sent)

    # -- layout ---------------------------------------------------------------------------------------
    def relayout(self, layout: TeamLayout) -> None:
        """New team sizes: teams that kept their size keep their state (as the world keeps their
        poses); the others must be started again."""
        parts = {name: getattr(self, name) for name in ("pose", "command", "motors")}
        old_stale, old_sent, old_physics, old_stall = self.stale, self._sent, self._physics, self.stall_left
        old_drawn = self.drawn
        keys, ticks, true = self.keys, self.ticks, self._true
        old_layout = self.layout
        self._build(layout)
        for b in range(min(layout.n_teams, old_layout.n_teams)):
            if old_layout.team_sizes[b] != layout.team_sizes[b]:
                continue
            new_rows = slice(layout.offsets[b], layout.offsets[b + 1])
            old_rows = slice(old_layout.offsets[b], old_layout.offsets[b + 1])
            self.keys[new_rows], self.ticks[new_rows], self._true[new_rows] = (
                keys[old_rows],
                ticks[old_rows],
                true[old_rows],
            )
            self.stall_left[b] = old_stall[b]
            self.stale.remap(new_rows, old_stale, old_rows)
            self._sent[new_rows] = old_sent[old_rows]
            for new, old in zip(self._physics, old_physics):
                new[new_rows] = old[old_rows]
            for name, old in old_drawn.items():
                self.drawn[name][new_rows] = old[old_rows]
            for name, old_part in parts.items():
                new_part = getattr(self, name)
                for attr in old_part.ROW_STATE:
                    getattr(new_part, attr)[new_rows] = getattr(old_part, attr)[old_rows]


class IdentityReality:
    """The reality layer at ``off``: the world's own poses are the measured ones and commands pass
    unchanged, so a tick through it is the ideal world's tick, bit for bit (tests/test_reality.py).

    The same interface as :class:`RealityLayer`, so the tick pipeline has no second path:
    :attr:`measured` and :attr:`estimated` are the world's current poses (read-only views, no
    copy), :meth:`start` places robots where asked, :meth:`actuate` returns its input, and
    :meth:`begin_measuring`, :meth:`observe` and :meth:`relayout` have nothing to do.

    Args:
        world: the world whose poses are read (:attr:`comat.sim.World.pose_view`,
            :meth:`~comat.sim.World.cos_sin`).
    """

    is_off = True
    physics_on = False

    def __init__(self, world) -> None:
        self.world = world
        self.config = RealityConfig()
        """The ``off`` config (every component zero)."""

    @property
    def layout(self) -> TeamLayout:
        return self.world.layout

    @property
    def measured(self) -> np.ndarray:
        """(R, 3) the true poses (read-only)."""
        return self.world.pose_view

    def cos_sin(self) -> tuple[np.ndarray, np.ndarray]:
        """(R,) cosines and sines of the true headings (the world's, computed once per tick)."""
        return self.world.cos_sin()

    estimated = measured
    estimated_cos_sin = cos_sin

    def points(self, distance: float) -> np.ndarray:
        """(R, 2) the true poses' points ``distance`` ahead of the axles."""
        return projected_points(self.world.pose_view, distance)

    @property
    def speed_fraction(self) -> np.ndarray:
        """(R,) ones: no robot runs slow."""
        return np.ones(self.world.layout.n_robots)

    def start(self, poses: np.ndarray, teams: np.ndarray, keys: Sequence[int] | None) -> np.ndarray:
        """The requested (R, 3) poses: no start error."""
        return poses

    def begin_measuring(self, true: np.ndarray, teams: np.ndarray) -> None:
        """Nothing to measure: :attr:`measured` reads the world."""

    def actuate(self, dxu: np.ndarray) -> np.ndarray:
        """The commands (R, 2) as sent (the same array)."""
        return dxu

    def observe(self, true: np.ndarray) -> None:
        """Nothing to measure: :attr:`measured` reads the world."""

    def relayout(self, layout: TeamLayout) -> None:
        """Nothing kept per robot."""
