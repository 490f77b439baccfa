"""The control pipeline of every tick: nominal velocities → safety filter → unicycle → physics.

``SafeTeams`` composes a world (single-team :class:`~comat.sim.World` or batched
:class:`~comat.sim.BatchWorld`) with one :class:`~comat.safety.SafetyFilter` over all its teams,
so a tick is one physics call per team size and one QP. With a reality layer
(:mod:`comat.reality`), the filter and :attr:`SafeTeams.measured_poses` read measured poses and
the commands pass the layer's command path and motors before the physics; contacts, Robotarium
checks and :attr:`SafeTeams.poses` stay true. ``go_to_goal`` is the proportional
waypoint controller of the projected points (Robotarium ``si_position_controller``).
"""

from __future__ import annotations

import time
from collections import OrderedDict
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from comat import constants as C
from comat import kernels
from comat._validate import as_float_array
from comat.config import LOOPS, SafetyConfig, SimConfig
from comat.reality import IdentityReality, RealityConfig, RealityLayer
from comat.reality.margin import response_lag_ticks, robust_safety
from comat.safety import SafetyFilter, SafetyInfo
from comat.safety.deployed import (
    ARENA,
    DeadlockTieBreak,
    DeployedLoop,
    PortableBarrier,
    RobotWatch,
    ShippedFilter,
    cvxopt_qp,
    keep_right,
    robotarium_loop,
    uni_to_si,
)
from comat.safety.kernels import portable_problem, watch_judgement
from comat.safety.probation import REFERENCE, SUBSET, TEAM, probation_pass
from comat.safety.qp import dense_qp
from comat.sim import BatchWorld, World, points_to_wheels
from comat.sim.kinematics import (
    WHEEL_LIMIT_TOLERANCE,
    limit_to_wheels,
    projected_points,
    threshold_wheels,
    wheel_rhombus,
)
from comat.sim.violations import TickEvents

__all__ = ["DeployedInfo", "SafeTeams", "TickTiming", "go_to_goal", "portable_settings", "waypoint_controller"]


def go_to_goal(points: np.ndarray, goals: np.ndarray, gain: float = 1.0, max_speed: float = 0.2) -> np.ndarray:
    """Velocities (R, 2) driving points (R, 2) toward goals (R, 2), norm-clipped to ``max_speed``."""
    dxi = gain * (goals - points)
    norm = np.linalg.norm(dxi, axis=-1, keepdims=True)
    return dxi * np.minimum(1.0, max_speed / np.maximum(norm, 1e-12))


def waypoint_controller(
    points: np.ndarray | None,
    goals: np.ndarray,
    poses: np.ndarray,
    gain: float = 4.0,
    projection_distance: float = 0.025,
    cos_sin: tuple[np.ndarray, np.ndarray] | None = None,
    max_speed: float = 0.2,
) -> np.ndarray:
    """The envs' nominal controller: :func:`go_to_goal` saturated to what the wheels can do.

    Saturating here (closed form, per robot) means the safety filter only changes commands for
    safety: its intervention count measures the barrier, not the motors. ``points`` None: the
    projected points of ``poses``; ``cos_sin`` may pass the headings' cosines and sines.
    """
    c, s = cos_sin if cos_sin is not None else (np.cos(poses[..., 2]), np.sin(poses[..., 2]))
    if kernels.enabled() and poses.ndim == 2:
        k, v = wheel_rhombus(projection_distance)
        out = np.empty((poses.shape[0], 2))
        kernels.waypoint_nominal(points, poses, c, s, goals, gain, projection_distance, max_speed, k, v, out)
        return out
    if points is None:
        points = projected_points(poses, projection_distance)
    dxi = go_to_goal(points, goals, gain, max_speed)
    return limit_to_wheels(dxi, poses, projection_distance, cos_sin=(c, s))


def _portable_qp(vhat: np.ndarray, A: np.ndarray, b: np.ndarray, weights: np.ndarray | None = None):
    """:func:`~comat.safety.qp.dense_qp` (DAQP), and where it stops without an answer that is not
    a proof of infeasibility, the export's interior-point :func:`~comat.safety.deployed.cvxopt_qp`
    (with OSQP here before DAQP, the iteration limit on a softened problem, weights 1 and 1e4, in
    the crowds of ``stress`` braked a team: antipodal16 at ``stress``, 63 team-ticks in 4 × 900,
    each solved optimally by cvxopt)."""
    x, status = dense_qp(vhat, A, b, weights)
    if x is None and status != "primal infeasible":
        return cvxopt_qp(vhat, A, b, weights)
    return x, status


def _resolve_subset(solve, A: np.ndarray, b: np.ndarray, u: np.ndarray, u_nom: np.ndarray, broken, tol: float):
    """Re-solve only the robots that appear in the ``broken`` rows of ``A u <= b`` (u (2N,) a
    team's command, stacked per robot), the others fixed at ``u``: min ‖v − v̂‖² over those robots
    under every row that involves them (a row with fixed robots in it bounds the free ones by what
    the fixed ones do). Returns the team's command (2N,) if the sub-problem is solved and the
    result meets every row within ``tol``, else None."""
    cols = np.flatnonzero(np.abs(A[broken]).sum(axis=0) > 0)
    free = np.zeros(u.size, dtype=bool)
    free[np.concatenate([2 * (cols // 2), 2 * (cols // 2) + 1])] = True
    involved = np.abs(A[:, free]).sum(axis=1) > 0
    A_free = A[involved][:, free]
    b_free = b[involved] - A[involved][:, ~free] @ u[~free]
    x, _ = solve(u_nom[free], A_free, b_free)
    if x is None:
        return None
    out = u.copy()
    out[free] = x
    return out if np.all(A @ out <= b + tol) else None


def _probation_teams(portable, teams, offsets, probation, poses, extra, dxi, safe, info, tol: float) -> int:
    """:meth:`SafeTeams._watch_teams`' steps for the ``teams`` (k,) given, in numpy (the reference
    of :func:`comat.safety.probation.probation_pass`): ``portable`` a
    :class:`~comat.safety.deployed.PortableBarrier`, ``offsets`` (B + 1,), ``probation`` (R,),
    poses (R, 3) and extra radii (R,) from :meth:`RobotWatch.obstacles`, nominal ``dxi`` and the
    fast answer ``safe`` (R, 2) (changed in place), ``info`` the tick's
    :class:`~comat.safety.SafetyInfo` (intervention, fallback, recovery set for these teams).
    Returns how many teams were re-solved as a subset."""
    subsets = 0
    for b in teams:
        rows = slice(offsets[b], offsets[b + 1])
        A, bound = portable.problem(poses[rows], probation[rows], extra[rows])
        u = safe[rows].ravel()
        broken = A @ u > bound + tol
        if not broken.any():
            continue
        sub = _resolve_subset(portable.solve, A, bound, u, dxi[rows].ravel(), broken, tol)
        if sub is not None:
            safe[rows] = sub.reshape(-1, 2)
            info.intervention[b] = np.linalg.norm(safe[rows] - dxi[rows])
            subsets += 1
            continue
        failures, recoveries = portable.failures, portable.recoveries
        safe[rows] = portable(poses[rows], dxi[rows], probation[rows], extra[rows])
        info.fallback[b] |= portable.failures > failures
        info.recovery[b] |= portable.recoveries > recoveries
        info.intervention[b] = np.linalg.norm(safe[rows] - dxi[rows])
    return subsets


class CompiledRobotWatch(RobotWatch):
    """:class:`RobotWatch` with its judgement compiled (``comat.safety.kernels.watch_judgement``,
    the same bits); the deployed script keeps the numpy original. That judgement took 0.37 of the
    watch's 0.52 ms a tick for 64 teams of 8 robots at ``nominal``; with the twin the whole tick
    went from 5.60 to 5.30 ms (docs/speed.md). ``old`` is recomputed inside from ``_born``."""

    def _judge(self, old: np.ndarray, stale: np.ndarray, k: int) -> None:
        watch_judgement(
            self._ask, self._points, self.tick, self._born, self.window, self.lag, k, stale,
            self.min_path, self.ratio, self.release_ratio, self.unresponsive,
        )  # fmt: skip


class CompiledPortableBarrier(PortableBarrier):
    """:class:`PortableBarrier` with its rows built by a compiled twin
    (``comat.safety.kernels.portable_problem``, the same bits; tests/test_kernels.py); the export
    keeps the numpy original. Building the rows was 1.1 ms of a team's 1.6 ms on probation at
    ``stress`` (16 robots) once DAQP solved the re-solves in 0.06 ms."""

    def __init__(self, settings: dict, solve=cvxopt_qp) -> None:
        super().__init__(settings, solve)
        s = self.s
        self.constants = (  # read from the settings once, not on every team-tick
            float(s["projection_distance_m"]), float(s["safety_distance_m"]), float(s["boundary_margin_m"]),
            float(s["barrier_gain"]), float(s["boundary_gain"]),
            s["axle_m"] / (2 * s["projection_distance_m"]), s["wheel_radius_m"] * s["wheel_limit_radps"],
            *ARENA,
        )  # fmt: skip
        """The compiled rows' scalar arguments (``portable_problem``'s after the arrays), also
        :func:`comat.safety.probation.probation_pass`'s."""

    def problem(
        self, poses: np.ndarray, probation: np.ndarray | None = None, extra: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        n = poses.shape[0]
        return portable_problem(
            np.ascontiguousarray(poses, dtype=float),
            np.zeros(n, dtype=bool) if probation is None else np.ascontiguousarray(probation, dtype=bool),
            np.zeros(n) if extra is None else np.ascontiguousarray(extra, dtype=float),
            *self.constants,
        )


@dataclass
class TickTiming:
    """Wall-clock split of the last tick (s): MuJoCo stepping, OSQP's solve, everything else."""

    total: float = 0.0
    physics: float = 0.0
    solver: float = 0.0

    @property
    def rest(self) -> float:
        return self.total - self.physics - self.solver


def portable_settings(filter_config: SafetyConfig, profile: C.RobotProfile) -> dict:
    """A filter's settings as :class:`~comat.safety.deployed.PortableBarrier` (and an export's
    config) take them."""
    cfg, p = filter_config, profile
    return {
        "safety_distance_m": cfg.safety_distance_m,
        "projection_distance_m": cfg.projection_distance_m,
        "boundary_margin_m": cfg.boundary_margin_m,
        "barrier_gain": cfg.barrier_gain,
        "boundary_gain": cfg.boundary_gain,
        "axle_m": p.base_length_m,
        "wheel_radius_m": p.wheel_radius_m,
        "wheel_limit_radps": p.max_wheel_velocity_radps * cfg.wheel_speed_fraction,
    }


@dataclass
class DeployedInfo:
    """What the deployed loop's barrier did in one tick (the fields of :class:`SafetyInfo` that
    counters and recorders read)."""

    intervention: np.ndarray
    """(B,) ‖u − û‖ of the projected points' velocities per team (m/s)."""
    robot_intervened: np.ndarray
    """(R,) bool, the barrier changed the robot's command."""
    fallback: np.ndarray
    """(B,) bool, the barrier's QP failed this tick (V2 and comat's shipped filter then command
    zeros to the team)."""
    recovery: np.ndarray
    """(B,) bool, comat's shipped filter took its softened problem's answer (the Robotarium's
    barrier has no recovery mode)."""
    status: str = "deployed"
    solve_time_s: float = 0.0


class SafeTeams:
    """Teams of robots whose every command passes the barrier filter before the wheels.

    Args:
        team_sizes: robots per team.
        sim: world settings (tier, substeps, profile).
        safety: barrier settings.
        batched: use :class:`BatchWorld` (default) or, for a single team, :class:`World`.
        reality: the reality layer's settings (None or a config that ``is_off``: the ideal world,
            bit for bit, through :class:`~comat.reality.IdentityReality`).
        reality_seed: keys of episodes reset without ``reality_keys`` (see :meth:`reset`).
        filter_reality: the reality the filter is made for, if not the world's (``reality``).
    """

    def __init__(
        self,
        team_sizes: Sequence[int],
        sim: SimConfig | None = None,
        safety: SafetyConfig | None = None,
        batched: bool = True,
        reality: RealityConfig | None = None,
        reality_seed: int = 0,
        filter_reality: RealityConfig | None = None,
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
        self._qp_cache: OrderedDict = OrderedDict()
        self.reality: RealityLayer | IdentityReality = IdentityReality(self.world)
        """The reality layer between the world and the decisions (at ``off`` the identity: every
        tick takes the same path through it)."""
        self.filter_config = self.safety_config
        """The filter's settings: ``safety`` made robust to the reality layer's bounds
        (:func:`comat.reality.margin.robust_safety`; ``safety`` itself without a layer)."""
        self.design_reality = filter_reality if filter_reality is not None else reality
        """The reality the filter is made for (margins, gain, the watch's lag): ``filter_reality``,
        else the world's own (a mismatch battery builds it for one level and runs another)."""
        if reality is not None and not reality.is_off:
            self.reality = RealityLayer(reality, self.world.profile, self.world.layout, reality_seed)
            self.filter_config = robust_safety(self.safety_config, self.design_reality, self.world.profile)
        self.filter = SafetyFilter(sizes, self.filter_config, self.world.profile, self._qp_cache)
        self.watch: RobotWatch | None = self._new_watch()
        """What the script tells of each robot under a reality layer (comat's robust filter only):
        a team with a robot on probation (one that does not respond) is filtered by
        :class:`~comat.safety.deployed.PortableBarrier`, which treats it as an obstacle."""
        self.keep_right = not self.reality.is_off and self.safety_config.robust
        """Turn nominal commands right near robots ahead (:func:`~comat.safety.deployed.keep_right`)
        under a reality layer; without one (``off``) the loop is as before, bit for bit."""
        portable = CompiledPortableBarrier if kernels.enabled() else PortableBarrier
        self._portable = portable(portable_settings(self.filter_config, self.world.profile), _portable_qp)
        self.deployed: list[DeployedLoop] | None = self._deployed_loops(sizes)
        """Per team, the exported script's loop (``safety.loop`` not ``"comat"``; else None):
        :meth:`tick_deployed` runs it."""
        self.timing = TickTiming()
        self.interventions = np.zeros(len(sizes), np.int64)
        self.fallbacks = np.zeros(len(sizes), np.int64)
        self.recoveries = np.zeros(len(sizes), np.int64)
        """Per team: ticks the filter changed a command, braked, recovered from outside the safe set."""
        self.subset_solves = 0
        """Team-ticks a robot on probation was handled by re-solving only the robots whose rows the
        fast answer broke (:meth:`_watch_teams`)."""
        self.tie_break = DeadlockTieBreak(sum(sizes))
        """Per robot: the deadlock tie-break (keep right after 1 s held still)."""
        self.tick_observers: list[Callable[[np.ndarray, np.ndarray, TickEvents, SafetyInfo], None]] = []
        """Called after every tick with (nominal (R, 2), filtered (R, 2), events, info); e.g. a
        :mod:`comat.viz` recorder. Empty by default (nothing to pay when not recording)."""

    def _new_watch(self) -> RobotWatch | None:
        if self.reality.is_off or not self.safety_config.robust or self.safety_config.loop != "comat":
            return None
        return (CompiledRobotWatch if kernels.enabled() else RobotWatch)(
            self.world.layout.n_robots,
            self.safety_config.projection_distance_m,
            response_lag_ticks(self.design_reality, self.world.profile),
        )

    def _deployed_loops(self, sizes: Sequence[int]) -> list[DeployedLoop] | None:
        """One deployed loop per team of ``sizes`` (None for comat's own filter)."""
        loop = self.safety_config.loop
        if loop == "comat":
            return None
        kind, generation = loop.split("_")
        d = self.safety_config.projection_distance_m
        if kind == "robotarium":
            return [robotarium_loop(generation, projection=d) for _ in sizes]
        reality = self.reality.config if self.reality.is_off else self.design_reality
        lag = response_lag_ticks(reality, self.world.profile)
        settings = portable_settings(self.filter_config, self.world.profile)
        right = self.keep_right
        return [
            robotarium_loop(generation, projection=d, barrier=ShippedFilter(n, settings, lag, keep_right=right))
            for n in sizes
        ]

    @property
    def poses(self) -> np.ndarray:
        """(R, 3) current true poses."""
        return self.world.poses

    @property
    def points(self) -> np.ndarray:
        """(R, 2) current true projected points (what the barrier keeps apart)."""
        return projected_points(self.world.poses, self.safety_config.projection_distance_m)

    @property
    def measured_poses(self) -> np.ndarray:
        """(R, 3) the poses the robots' script sees now (a copy; the true ones without a layer)."""
        return self.reality.measured.copy()

    @property
    def measured_points(self) -> np.ndarray:
        """(R, 2) projected points of :attr:`measured_poses`."""
        return projected_points(self.measured_poses, self.safety_config.projection_distance_m)

    def decision_poses(self) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray]]:
        """The (R, 3) poses that controllers and the filter read this tick, with their headings'
        cosines and sines (read-only views: measured, the true ones at ``off``)."""
        return self.reality.measured, self.reality.cos_sin()

    def filter_poses(self) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray]]:
        """The (R, 3) poses the filter and the wheel conversion read, with cosines and sines:
        :meth:`decision_poses`, with repeated measurements dead-reckoned under a layer
        (:class:`comat.reality.margin.StalePoses`)."""
        return self.reality.estimated, self.reality.estimated_cos_sin()

    def reset(
        self, poses: np.ndarray, teams: Sequence[int] | None = None, reality_keys: Sequence[int] | None = None
    ) -> None:
        """Place robots at poses (R, 3) and zero their counters; only ``teams`` if given.

        With a reality layer the robots start at the requested poses plus the start error, and
        ``reality_keys`` (one 64-bit key per reset team, e.g. :func:`comat.reality.episode_key`
        of each env's generator) seed their episodes; None: keys from ``reality_seed``."""
        layer = self.reality
        team_ids = np.arange(self.world.layout.n_teams) if teams is None else np.asarray(teams, dtype=np.int64)
        poses = layer.start(as_float_array("poses", poses, (self.world.layout.n_robots, 3)), team_ids, reality_keys)
        if layer.physics_on and self.sim_config.tier == "wheels":
            if isinstance(self.world, BatchWorld):
                self.world.set_robot_physics(*layer.physics(), teams=team_ids)
            else:
                self.world.set_robot_physics(*layer.physics())
        self.world.reset(poses, teams) if teams is not None else self.world.reset(poses)
        layer.begin_measuring(self.world.pose_view, team_ids)
        if self.watch is not None:
            self.watch.restart(np.flatnonzero(np.isin(self.world.layout.robot_team, team_ids)))
        sel = slice(None) if teams is None else np.asarray(teams, dtype=np.int64)
        self.interventions[sel] = 0
        self.fallbacks[sel] = 0
        self.recoveries[sel] = 0
        robots = slice(None) if teams is None else np.isin(self.world.layout.robot_team, sel)
        self.tie_break.restart(robots)

    def forget_solver_state(self) -> None:
        """Drop the OSQP problems (their adapted step sizes) and the filter's warm-start duals.

        After this the next ticks depend only on poses and commands, not on earlier ticks:
        environments call it when every team is reset, so a run resumed from a checkpoint
        takes exactly the steps of the run that was not interrupted.
        """
        self._qp_cache.clear()
        self.filter = SafetyFilter(self.filter.team_sizes, self.filter_config, self.world.profile, self._qp_cache)

    def set_team_sizes(self, team_sizes: Sequence[int]) -> None:
        """New team sizes (batched world only): teams whose size changed must be reset next.

        The filter is rebuilt for the new layout; OSQP problems already set up are reused.
        """
        if not isinstance(self.world, BatchWorld):
            raise TypeError("set_team_sizes needs the batched world (SafeTeams(..., batched=True))")
        sizes = tuple(int(n) for n in team_sizes)
        if sizes == self.world.team_sizes:
            return
        self.world.set_team_sizes(sizes)
        self.filter = SafetyFilter(sizes, self.filter_config, self.world.profile, self._qp_cache)
        self.deployed = self._deployed_loops(sizes)
        self.reality.relayout(self.world.layout)
        self.watch = self._new_watch()  # teams whose size changed start afresh; the others lose a window
        self.interventions = np.zeros(len(sizes), np.int64)
        self.fallbacks = np.zeros(len(sizes), np.int64)
        self.recoveries = np.zeros(len(sizes), np.int64)
        self.tie_break = DeadlockTieBreak(sum(sizes))

    def tick(self, dxi: np.ndarray) -> tuple[TickEvents, SafetyInfo]:
        """One control tick with nominal projected-point velocities (R, 2).

        A robot's command beyond what its wheels can do is first saturated to the closest one
        they can (as the envs' waypoint controller does): the filter then changes commands only
        for safety, and a huge command (1e150 m/s) is as well-posed as a full-speed one.
        Commands within the wheel limits pass on exactly as given."""
        dxi = as_float_array("dxi", dxi, (self.world.layout.n_robots, 2))
        poses, (c, s) = self.filter_poses()
        d = self.safety_config.projection_distance_m
        k, v = wheel_rhombus(d, self.world.profile)
        along, across = c * dxi[:, 0] + s * dxi[:, 1], c * dxi[:, 1] - s * dxi[:, 0]
        over = np.abs(along) + k * np.abs(across) > v * WHEEL_LIMIT_TOLERANCE
        if over.any():
            dxi = dxi.copy()
            # Beyond 1e6·v a command is scaled down to 1e6·v first, so the closed-form
            # projection (which subtracts terms of the command's size) keeps its precision.
            big = np.maximum(np.abs(dxi[over]).max(1, keepdims=True) / (1e6 * v), 1.0)
            dxi[over] = limit_to_wheels(dxi[over] / big, poses[over], d, self.world.profile, cos_sin=(c[over], s[over]))
        return self._tick(dxi)

    def _tick(self, dxi: np.ndarray) -> tuple[TickEvents, SafetyInfo]:
        """:meth:`tick` without input checks, for velocities made inside comat (float64, (R, 2))."""
        t0 = time.perf_counter()
        poses, cos_sin = self.filter_poses()  # read-only here; our own arrays skip the public checks
        nominal = dxi
        dxi = self.tie_break.steer(nominal)
        if self.keep_right:
            lay, c, s = self.world.layout, cos_sin[0], cos_sin[1]
            d = self.safety_config.projection_distance_m
            points = np.column_stack([poses[:, 0] + d * c, poses[:, 1] + d * s])
            dxi = keep_right(points, dxi, lay.pair_i, lay.pair_j)
        safe, info = self.filter._filter(poses, dxi, cos_sin)
        if self.watch is not None:
            self._watch_teams(dxi, safe, info)
        self.tie_break.update(nominal, safe)
        # The script converts the filtered point velocities to unicycle commands on the headings
        # it reads and clips the wheels (an actuator error is judged on this request).
        d = self.safety_config.projection_distance_m
        events = self.execute(*points_to_wheels(safe, poses, cos_sin, d, self.world.profile))
        if self.watch is not None:
            self.watch.sent(self.reality._sent)
        self._account(t0, self.filter.last_solver_s, nominal, safe, events, info)
        return events, info

    def _watch_teams(self, dxi: np.ndarray, safe: np.ndarray, info: SafetyInfo) -> None:
        """Teams with a robot on probation (:class:`RobotWatch`) must meet the portable filter's
        rows, which treat that robot as an obstacle (``safe`` (R, 2), the fast filter's answer,
        is changed in place where it does not). Cheapest first (issue 66: a false alarm must not
        cost a whole team its fast path):

        1. the fast answer meets every row: kept (no QP);
        2. else only the robots in the rows it breaks are re-solved, the rest of the team kept at
           its fast answer (their rows with the re-solved robots become bounds on those alone);
           taken if the result meets every row of the team;
        3. else the whole team through the portable filter (its softened problem, its brake).

        Every command returned meets the same rows, so the promise is the portable filter's. With
        the kernels on, steps 1-3 run compiled for every team at once
        (:func:`comat.safety.probation.probation_pass`, equal to this loop to 1e-9 m/s), and the
        loop (:func:`_probation_teams`, the reference) takes the teams whose hard rows no command
        meets."""
        watch, lay = self.watch, self.world.layout
        watch.observe(self.reality.measured)
        if not watch.probation.any():
            return
        poses, extra = watch.obstacles()
        tol = self.filter_config.feasibility_tol
        if not isinstance(self._portable, CompiledPortableBarrier):
            teams = np.unique(lay.robot_team[watch.probation])
        else:
            # Steps 1-3 for every team in one compiled call (comat.safety.probation: ~36 teams a
            # tick at 8 x 64 stress, ~80 us each in the loop); the loop takes the teams it leaves.
            verdict, change = np.empty(lay.n_teams, np.int8), np.empty(lay.n_teams)
            probation_pass(
                poses, watch.probation, extra, lay.offsets, safe, dxi, tol, self._portable.constants, verdict, change
            )
            solved = (verdict == SUBSET) | (verdict == TEAM)
            info.intervention[solved] = change[solved]
            self.subset_solves += int((verdict == SUBSET).sum())
            teams = np.flatnonzero(verdict == REFERENCE)
        if teams.size:
            self.subset_solves += _probation_teams(
                self._portable, teams, lay.offsets, watch.probation, poses, extra, dxi, safe, info, tol
            )

    def tick_deployed(self, dxi: np.ndarray) -> tuple[TickEvents, DeployedInfo]:
        """One tick of the exported script's loop (``safety.loop`` not ``"comat"``).

        ``dxi`` (R, 2): the waypoint controller's velocities of the measured projected points
        (main.py's: gain·(waypoint − point), norm-clipped to 0.2 m/s). Per team, on the measured
        poses (what ``get_poses`` returns: no dead reckoning), :class:`DeployedLoop` maps them to
        unicycle commands, scales the wheels, runs the Robotarium's barrier and scales again;
        the commands then pass the reality layer (if any) into the world, as ``set_velocities``
        does on the testbed. Judging (contacts, Robotarium checks) stays on true poses."""
        if self.deployed is None:
            raise RuntimeError(
                f"tick_deployed needs a deployed SafetyConfig.loop (one of {list(LOOPS[1:])}), "
                f"got {self.safety_config.loop!r}"
            )
        t0 = time.perf_counter()
        dxi = as_float_array("dxi", dxi, (self.world.layout.n_robots, 2))
        lay, d = self.world.layout, self.safety_config.projection_distance_m
        x = self.measured_poses
        sent = np.empty((lay.n_robots, 2))
        nominal = np.empty((lay.n_robots, 2))
        fallback = np.zeros(lay.n_teams, dtype=bool)
        recovery = np.zeros(lay.n_teams, dtype=bool)
        for b, loop in enumerate(self.deployed):
            rows = slice(lay.offsets[b], lay.offsets[b + 1])
            failures, recoveries = loop.barrier.failures, getattr(loop.barrier, "recoveries", 0)
            nom, out = loop.commands(x[rows].T, dxi[rows].T)
            nominal[rows], sent[rows] = nom.T, out.T
            fallback[b] = loop.barrier.failures > failures
            recovery[b] = getattr(loop.barrier, "recoveries", 0) > recoveries
        events = self.execute(*threshold_wheels(sent, self.world.profile))
        u_nom, u = uni_to_si(nominal.T, x.T, d).T, uni_to_si(sent.T, x.T, d).T
        change = np.linalg.norm(u - u_nom, axis=1)
        info = DeployedInfo(
            intervention=np.sqrt(np.bincount(lay.robot_team, weights=change**2, minlength=lay.n_teams)),
            robot_intervened=change > 1e-9,
            fallback=fallback,
            recovery=recovery,
        )
        self._account(t0, 0.0, u_nom, u, events, info)
        return events, info

    def execute(self, clipped: np.ndarray, overrun: np.ndarray) -> TickEvents:
        """The world's edge, shared by both loops (and open-loop experiments, which skip the filter:
        :mod:`comat.calibration.experiments`): the wheel-realizable commands the script sent
        (R, 2) [v m/s, ω rad/s] pass the reality layer's command path and motors, the world steps
        (``overrun`` (R,): requests the wheel limit clipped), and the layer measures the true poses.
        At ``off`` (:class:`~comat.reality.IdentityReality`) this is the bare world's tick, bit for bit."""
        events = self.world.advance(self.reality.actuate(clipped), overrun)
        self.reality.observe(self.world.pose_view)
        return events

    def _account(
        self, t0: float, solver_s: float, nominal: np.ndarray, sent: np.ndarray, events: TickEvents, info
    ) -> None:
        """A tick's bookkeeping, shared by both loops: the per-team counters from ``info``
        (:class:`~comat.safety.SafetyInfo` or :class:`DeployedInfo`), the timing (``t0`` from
        ``time.perf_counter()`` at the tick's start, ``solver_s`` its QP time) and the observers,
        which get the point velocities before (R, 2) and after (R, 2) the filter."""
        self.interventions += info.intervention > 1e-9
        self.fallbacks += info.fallback
        self.recoveries += info.recovery
        self.timing.total = time.perf_counter() - t0
        self.timing.physics = self.world.last_physics_s
        self.timing.solver = solver_s
        for observe in self.tick_observers:
            observe(nominal, sent, events, info)
