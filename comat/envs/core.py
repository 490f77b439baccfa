"""The engine under both env APIs: B environments of one task, stepped together.

Per env step and environment: each robot's discrete action sets a waypoint for its projected
point (:func:`comat.task_logic.waypoint_goals`); then ``ticks_per_step`` control ticks of
waypoint controller → safety filter → physics run for all B teams at once
(:class:`comat.control.SafeTeams`: one physics call per team size and one QP per tick); then
the task logic (:mod:`comat.task_logic`) updates its state and the named reward terms, the
task's coordination metric is read (where the task has one), and the episode record
(:mod:`comat.envs.diagnostics`: progress curve, per-robot counts) moves one step.

With a reality layer (``reality=``, :mod:`comat.reality`) the waypoints, the controller, the
filter and the observations read *measured* poses; the task logic, rewards and metrics read
*true* ones (:meth:`TaskCore.poses`).

Robots are padded to ``N`` slots per environment (``mask`` (B, N)); physics arrays are flat
(R, ·) in team order, and ``_flat`` maps slots to rows. Team sizes change between episodes.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from comat import kernels
from comat.config import SafetyConfig, SimConfig
from comat.control import SafeTeams, go_to_goal, waypoint_controller
from comat.envs.diagnostics import EpisodeRecorder
from comat.envs.options import check_count
from comat.reality import RealityConfig, episode_key, resolve_reality
from comat.task_logic import waypoint_goals
from comat.team import TeamSpec

__all__ = ["COORDINATION", "EPISODE_METRICS", "StepResult", "TaskCore"]

WAYPOINT_GAIN = 4.0
"""Proportional gain (1/s) of the waypoint controller: covers ~90 % of a 0.2 m step in 29 ticks."""

EPISODE_METRICS = (
    "return",
    "steps",
    "progress",
    "finished",
    "collisions",
    "robotarium_collisions",
    "boundary_exits",
    "actuator_errors",
    "interventions",
    "fallbacks",
    "recoveries",
)
"""Per-episode metrics of every task (see :meth:`TaskCore.episode_metrics`)."""
COORDINATION = "coordination"
"""The episode metric of a task's coordination hook (:meth:`comat.task_logic.TaskLogic.coordination`):
the mean over the episode's env steps; left out of the episode's metrics for a task without one."""


@dataclass
class StepResult:
    """One env step of all B environments: rewards (B,), reward terms name -> (B,), flags (B,)."""

    rewards: np.ndarray
    terms: dict[str, np.ndarray]
    terminated: np.ndarray
    truncated: np.ndarray


@dataclass
class _Stats:
    """Running per-environment counters of the current episode (B,)."""

    B: int
    values: dict[str, np.ndarray] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for name in EPISODE_METRICS:
            self.values[name] = np.zeros(self.B)

    def zero(self, envs: np.ndarray) -> None:
        for v in self.values.values():
            v[envs] = 0.0


class TaskCore:
    """B environments of ``task`` (a :mod:`comat.task_logic` task) with up to ``max_robots`` each.

    The env APIs build it from their :class:`comat.envs.options.EnvOptions`
    (:func:`comat.envs.base.build_core`); its arguments are those options resolved: the robot
    slots counted, the physics settings made.

    Args:
        task: task logic instance (``PCP()`` or ``HMT()``).
        num_envs: B.
        max_robots: robot slots per environment (N).
        sim: physics settings.
        safety: barrier filter settings.
        ticks_per_step: control ticks per env step (default: the task's, PCP 29, HMT 74).
        state_robots: robots covered by :meth:`global_state`.
        reality: the reality layer (see :func:`comat.reality.resolve_reality`; default off).
    """

    def __init__(
        self,
        task,
        num_envs: int,
        max_robots: int,
        sim: SimConfig | None = None,
        safety: SafetyConfig | None = None,
        ticks_per_step: int | None = None,
        state_robots: int = 8,
        reality: RealityConfig | str | None = None,
    ) -> None:
        check_count("ticks_per_step", ticks_per_step)
        check_count("state_robots", state_robots)
        self.task = task
        self.state_robots = state_robots
        self.B, self.N = int(num_envs), int(max_robots)
        self.sim_config = sim or SimConfig()
        self.safety_config = safety or SafetyConfig()
        self.reality_config = resolve_reality(reality)
        """The reality layer's settings (``is_off``: the ideal world)."""
        self.ticks_per_step = int(ticks_per_step or task.ticks_per_step)
        self.state = task.new_state(self.B, self.N)
        self.mask = np.zeros((self.B, self.N), dtype=bool)
        self.type_ids = np.zeros((self.B, self.N), dtype=np.int64)
        self.caps = np.zeros((self.B, self.N, len(task.capabilities)))
        self.teams: list[TeamSpec | None] = [None] * self.B
        self.steps = np.zeros(self.B, dtype=np.int64)
        self.stats = _Stats(self.B)
        self.record = EpisodeRecorder(task, self.B, self.N)
        self.coordination_now: np.ndarray | None = None
        """(B,) the task's coordination metric after the last env step (true poses); None before
        the first step and for a task without one (its hook returns None)."""
        self._coordination_sum = np.zeros(self.B)
        self._coordination_steps = np.zeros(self.B, dtype=np.int64)
        self.safe: SafeTeams | None = None
        self._flat = np.zeros((self.B, self.N), dtype=np.int64)

    # -- layout -------------------------------------------------------------------------------------
    def _relayout(self) -> None:
        sizes = [int(m.sum()) for m in self.mask]
        if self.safe is None:
            self.safe = SafeTeams(sizes, self.sim_config, self.safety_config, reality=self.reality_config)
        else:
            self.safe.set_team_sizes(sizes)
        offsets = self.safe.world.layout.offsets
        self._flat = offsets[:-1, None] + np.arange(self.N)[None, :]
        self._flat = np.where(self.mask, self._flat, 0)

    def padded(self, flat: np.ndarray) -> np.ndarray:
        """(B, N, ...) view of flat (R, ...) per-robot values; padded slots are 0."""
        out = flat[self._flat]
        out[~self.mask] = 0
        return out

    def poses(self) -> np.ndarray:
        """(B, N, 3) current true poses (padded slots 0): what the task logic and metrics judge."""
        return self.padded(self.safe.world.pose_view)

    def measured_poses(self) -> np.ndarray:
        """(B, N, 3) the poses the robots' script sees (padded slots 0): what observations are
        made of; the true poses when the reality layer is off."""
        return self.padded(self.safe.decision_poses()[0])

    # -- episodes -----------------------------------------------------------------------------------
    def reset(self, envs: Sequence[int], teams: Sequence[TeamSpec], rngs: Sequence[np.random.Generator]) -> None:
        """Start new episodes in ``envs`` with the given teams and random generators."""
        envs = np.asarray(envs, dtype=np.int64)
        starts = {}
        # The layer's keys come from each env's generator without advancing it: the same teams
        # and starts are drawn at every reality level (paired comparisons).
        keys = None if self.reality_config.is_off else [episode_key(rng) for rng in rngs]
        for team in teams:
            self.task.check_team_size(team.size)
        if hasattr(self.task, "reserve") and len(teams):  # PCP: prey slots for the largest team here
            self.task.reserve(self.state, max(t.size for t in teams))
        for b, team, rng in zip(envs, teams, rngs):
            n = team.size
            if n > self.N:
                raise ValueError(f"team of {n} robots does not fit this environment's {self.N} robot slots")
            self.teams[b] = team
            self.mask[b] = np.arange(self.N) < n
            self.type_ids[b] = 0
            self.type_ids[b, :n] = team.type_ids()
            self.caps[b] = 0.0
            self.caps[b, :n] = team.capability_array()
            starts[int(b)] = self.task.spawn(rng, n)
            if self.task.reset_uses_starts:  # a task whose layout depends on where its robots start
                self.task.reset_env(self.state, b, rng, self.caps[b, :n], starts[int(b)])
            else:
                self.task.reset_env(self.state, b, rng, self.caps[b, :n])
        self._relayout()
        flat = self.safe.world.poses
        for b, p in starts.items():
            flat[self._flat[b, : p.shape[0]]] = p
        self.safe.reset(flat, teams=envs, reality_keys=keys)
        if envs.size == self.B:  # every episode starts afresh: so does the solver (exact resume)
            self.safe.forget_solver_state()
        self.steps[envs] = 0
        self.stats.zero(envs)
        self.record.zero(envs)
        self._coordination_sum[envs] = 0.0
        self._coordination_steps[envs] = 0
        self._last_contact = np.zeros(self.safe.world.layout.n_robots, dtype=bool)

    def step(self, actions: np.ndarray) -> StepResult:
        """Advance every environment one env step with actions (B, N) (padded slots ignored)."""
        task, safe = self.task, self.safe
        lay = safe.world.layout
        flat_actions = actions[self.mask]
        step_len = task.step_lengths_at(
            self.caps, self.poses(), self.state
        )  # (B, N): a terrain task's depends on where
        steps = step_len[self.mask]
        points = safe.points
        goals = waypoint_goals(safe.measured_points, flat_actions, steps)
        starts = lay.offsets[:-1]
        d = self.safety_config.projection_distance_m
        violations = np.zeros(self.B)
        s = self.stats.values
        last = self._last_contact
        for _ in range(self.ticks_per_step):
            if safe.deployed is not None:  # the exported script's loop (SafetyConfig.loop)
                events, info = safe.tick_deployed(
                    go_to_goal(safe.measured_points, goals, WAYPOINT_GAIN, safe.world.profile.max_linear_velocity_mps)
                )
            else:
                seen, cos_sin = safe.decision_poses()  # measured with a reality layer, else true
                events, info = safe._tick(waypoint_controller(None, goals, seen, WAYPOINT_GAIN, d, cos_sin))
            self._count_tick(starts, events, info, last, violations)
            last = events.robot_contact
        self._last_contact = last
        poses = self.poses()
        before = self.record.before(self.state)
        raw = task.update(self.state, poses, self.type_ids, self.caps, self.mask)
        raw["time"] = np.ones(self.B)
        raw["violation"] = (violations > 0).astype(float)
        terms = {name: task.reward_weights[name] * raw[name] for name in task.reward_terms}
        rewards = np.zeros(self.B)
        for name in task.reward_terms:
            rewards = rewards + terms[name]
        self.steps += 1
        terminated = task.done(self.state)
        truncated = (self.steps >= task.horizon) & ~terminated
        s["return"] += rewards
        s["steps"] = self.steps.astype(float)
        s["progress"] = task.progress(self.state)
        s["finished"] = terminated.astype(float)
        self._add_coordination(poses)
        moved = self.padded(np.hypot(*(safe.points - points).T))
        self.record.add(
            before,
            raw,
            self.state,
            actions,
            moved,
            step_len,
            poses,
            self.type_ids,
            self.caps,
            self.mask,
            self.steps,
            s["progress"],
        )
        return StepResult(rewards, terms, terminated, truncated)

    def _add_coordination(self, poses: np.ndarray) -> None:
        """Read the task's coordination metric after this step's update (true ``poses`` (B, N, 3))
        into :attr:`coordination_now` and the episode's running sum; nothing for a task without one."""
        task = self.task
        value = task.coordination(self.state, poses, self.type_ids, self.caps, self.mask)
        if value is None:
            self.coordination_now = None
            return
        value = np.asarray(value, dtype=float)
        if value.shape != (self.B,) or not np.isfinite(value).all():
            raise ValueError(
                f"{type(task).__name__}.coordination must return None or ({self.B},) finite values (one per env), "
                f"got shape {value.shape}: {value.ravel()[:4]}"
            )
        self.coordination_now = value
        self._coordination_sum += value
        self._coordination_steps += 1

    def _count_tick(self, starts: np.ndarray, events, info, last: np.ndarray, violations: np.ndarray) -> None:
        """Add one tick's events to the episode counters and to this env step's violations (B,);
        ``last``: the robots' contact flags of the tick before (onsets are counted)."""
        s = self.stats.values
        if kernels.enabled():
            kernels.episode_stats_add(
                starts, events.robot_contact, last, events.boundary, events.actuator, events.collision_pairs,
                info.intervention, info.fallback, s["collisions"], s["boundary_exits"], s["actuator_errors"],
                s["robotarium_collisions"], s["interventions"], s["fallbacks"], violations,
            )  # fmt: skip
            s["recoveries"] += info.recovery
            return
        per_robot = np.stack([events.robot_contact & ~last, events.boundary, events.actuator], axis=1).astype(np.int64)
        counts = np.add.reduceat(per_robot, starts, axis=0)  # (B, 3)
        s["collisions"] += counts[:, 0]
        s["boundary_exits"] += counts[:, 1]
        s["actuator_errors"] += counts[:, 2] > 0
        s["robotarium_collisions"] += events.collision_pairs
        s["interventions"] += info.intervention > 0
        s["fallbacks"] += info.fallback
        s["recoveries"] += info.recovery
        violations += counts[:, 0] + counts[:, 1] + events.collision_pairs

    def episode_metrics(self, b: int) -> dict[str, float]:
        """The paper's metrics for env b's episode so far.

        return; steps; progress (the task's share of its work done: its ``progress``); finished
        (the task done before the horizon: its ``done``); collisions (MuJoCo robot–robot contact onsets,
        summed over robots); robotarium_collisions (pair-ticks with offset centres <= 0.135 m);
        boundary_exits (robot-ticks outside the arena); actuator_errors (ticks with a wheel
        over 12.5 rad/s requested); interventions (ticks the filter changed a command);
        fallbacks (ticks the filter braked: no trusted command, not even a recovery one);
        recoveries (ticks the team was outside the safe set and the filter's softened problem
        moved it back toward it); and, for a task with a coordination hook, :data:`COORDINATION`
        (its mean over the episode's env steps so far; absent before the first step).
        """
        out = {name: float(v[b]) for name, v in self.stats.values.items()}
        if self._coordination_steps[b] > 0:
            out[COORDINATION] = float(self._coordination_sum[b] / self._coordination_steps[b])
        return out

    def episode_detail(self) -> dict:
        """Copies of every environment's current episode record (:mod:`comat.envs.diagnostics`),
        keyed as the vector env's ``info``: ``episode_curve`` (B, H) progress after each env step
        (valid for the episode's ``steps`` entries), ``episode_robots`` name -> (B, N) per-robot
        counts, ``episode_end`` name -> (B,) episode-level counts."""
        rec = self.record
        return {
            "episode_curve": rec.curve.copy(),
            "episode_robots": {k: v.copy() for k, v in rec.robots.items()},
            "episode_end": rec.end(self.state),
        }

    # -- observations -------------------------------------------------------------------------------
    def observe(self) -> np.ndarray:
        """(B, N, D) observations (padded slots 0), made of the measured poses and the capability
        vectors the robots report (:meth:`reported_caps`)."""
        return self.task.observe(self.state, self.measured_poses(), self.type_ids, self.reported_caps(), self.mask)

    def reported_caps(self) -> np.ndarray:
        """(B, N, C) the capability vectors the policy sees: the team's, except that under the
        reality layer with ``fault_known`` a faulty robot's speed capability (HMT's ``speed_m``)
        is scaled by its fault's fraction from the fault on. Hidden faults (the default) and PCP
        (no speed capability) report the team's vectors unchanged. Task logic and rewards always
        use the team's own vectors."""
        layer, k = self.safe.reality, self.task.speed_capability
        if k is None or not layer.config.fault_known or layer.config.fault_prob <= 0:
            return self.caps
        caps = self.caps.copy()
        caps[..., k] *= np.where(self.mask, self.padded(layer.speed_fraction), 1.0)
        return caps

    def graph(self) -> dict[str, np.ndarray]:
        """Dense team graphs of all environments.

        Returns:
            nodes (B, N, D): observations; node_type (B, N); edge_attr (B, N, N, 5): for the edge
            from j to i, j's position in i's frame (2), distance (1) and relative heading as
            cos, sin (2); edge_type (B, N, N): type_i · n_types + type_j; edge_mask (B, N, N):
            both robots real and i != j; mask (B, N).
        """
        poses = self.measured_poses()
        d = poses[:, None, :, :2] - poses[:, :, None, :2]  # [b, i, j] = p_j - p_i
        c, s = np.cos(poses[..., 2])[..., None], np.sin(poses[..., 2])[..., None]
        local = np.stack([c * d[..., 0] + s * d[..., 1], -s * d[..., 0] + c * d[..., 1]], axis=-1)
        dist = np.sqrt(d[..., 0] ** 2 + d[..., 1] ** 2)[..., None]
        rel = poses[:, None, :, 2] - poses[:, :, None, 2]
        edge_attr = np.concatenate([local, dist, np.cos(rel)[..., None], np.sin(rel)[..., None]], axis=-1)
        edge_mask = self.mask[:, :, None] & self.mask[:, None, :] & ~np.eye(self.N, dtype=bool)
        n_types = len(self.task.types)
        edge_type = self.type_ids[:, :, None] * n_types + self.type_ids[:, None, :]
        return {
            "nodes": self.observe(),
            "node_type": self.type_ids.copy(),
            "edge_attr": edge_attr * edge_mask[..., None],
            "edge_type": np.where(edge_mask, edge_type, 0),
            "edge_mask": edge_mask,
            "mask": self.mask.copy(),
        }

    def state_size(self) -> int:
        """Length of :meth:`global_state` rows."""
        return self.task.global_features(self.state).shape[-1] + self.state_robots * self.task.obs_size()

    def global_state(self) -> np.ndarray:
        """(B, G + state_robots·D) centralized state: task features, then robots' observations."""
        max_robots = self.state_robots
        obs = self.observe()
        if self.N > max_robots and self.mask[:, max_robots:].any():
            raise ValueError(
                f"state() covers {max_robots} robots but a team has {int(self.mask.sum(1).max())}; "
                "create the environment with a larger state_robots"
            )
        pad = np.zeros((self.B, max_robots, obs.shape[-1]))
        n = min(max_robots, self.N)
        pad[:, :n] = obs[:, :n]
        return np.concatenate([self.task.global_features(self.state), pad.reshape(self.B, -1)], axis=-1)
