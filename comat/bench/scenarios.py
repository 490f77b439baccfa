"""Randomized safety scenarios (many episodes at once) for tests, the demo and benchmarks.

Each scenario draws ``episodes`` independent teams, all simulated as one batch: start poses
(R, 3), goals for the projected points (R, 2), and a tick budget. The nominal controller is
:func:`comat.control.go_to_goal` (``bangbang``: full speed in random directions that switch
every 0.5–1.5 s); every command passes the barrier filter. Adversarial ones (issue 29): a ring
of 20 driven through its centre, bang-bang in a packed arena, a robot pinned in a corner with
three driven at it, and (:data:`UNSAFE_STARTS`) two robots started inside the safety distance.
With ``reality=`` the controller reads measured points and the outcome is judged on true ones.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from comat import constants as C
from comat.bench.liveness import LivenessTracker, live_goals
from comat.config import SafetyConfig, SimConfig
from comat.control import SafeTeams, go_to_goal
from comat.reality import RealityConfig, resolve_reality
from comat.sim.kinematics import si_to_uni

__all__ = [
    "CROSSINGS",
    "FAULTS",
    "SCENARIOS",
    "UNSAFE_STARTS",
    "Scenario",
    "ScenarioResult",
    "make_scenario",
    "run_scenario",
    "swap_scenario",
]

_X0, _X1, _Y0, _Y1 = C.ARENA_BOUNDS_M


@dataclass
class Scenario:
    """Episodes of one kind: teams, start poses (R, 3), goals (R, 2), ticks to run."""

    name: str
    team_sizes: tuple[int, ...]
    poses: np.ndarray
    goals: np.ndarray
    ticks: int
    bangbang: bool = False
    """Full-speed random directions instead of go-to-goal (``goals`` unused)."""
    reality: dict = dataclasses.field(default_factory=dict)
    """Reality fields set on top of the level the scenario runs at (:data:`FAULTS`)."""

    @property
    def live(self) -> bool:
        """Every team's goals can be held at once, so liveness is measured
        (:func:`comat.bench.liveness.live_goals`; never for bang-bang)."""
        return not self.bangbang and live_goals(self.goals, self.team_sizes)


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


def _ellipse(n: int, a: float, b: float, ticks: int):
    """n robots equally spaced along an ellipse (semi-axes a × b m), each driven through the
    centre to the opposite point (an antipodal swap)."""
    t = np.linspace(0, 2 * np.pi, 4001)
    arc = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(a * np.cos(t)), np.diff(b * np.sin(t))))])

    def make(rng, episodes):
        poses, goals = [], []
        for _ in range(episodes):
            at = np.interp((rng.uniform(0, 1) + np.arange(n) / n) % 1.0 * arc[-1], arc, t)
            pts = np.stack([a * np.cos(at), b * np.sin(at)], 1) + rng.uniform(-0.01, 0.01, (n, 2))
            poses.append(np.column_stack([pts, np.arctan2(-pts[:, 1], -pts[:, 0]) + rng.uniform(-0.3, 0.3, n)]))
            goals.append(-pts)
        return (n,) * episodes, poses, goals, ticks

    return make


_ring20 = _ellipse(20, 1.38, 0.8, 500)
"""20 robots along an ellipse filling the arena (semi-axes 1.38 × 0.8 m, ≈ 0.35 m apart)."""


def _lanes(rng, episodes):
    """12 robots in 6 horizontal lanes 0.33 m apart, one at each end of every lane (x = ±1.15 m),
    each driven to the other end: six head-on pairs side by side."""
    poses, goals = [], []
    y = (np.arange(6) - 2.5) * 0.33
    for _ in range(episodes):
        ys = np.concatenate([y, y]) + rng.uniform(-0.005, 0.005, 12)
        xs = np.repeat([-1.15, 1.15], 6) + rng.uniform(-0.03, 0.03, 12)
        heading = np.where(xs < 0, 0.0, np.pi) + rng.uniform(-0.3, 0.3, 12)
        poses.append(np.column_stack([xs, ys, heading]))
        goals.append(np.column_stack([-xs, ys]))
    return (12,) * episodes, poses, goals, 1200


def _pinch(rng, episodes):
    """A doorway: 4 robots parked across the arena's middle (goal = start) at y = ±0.35 and ±0.72 m
    leave one gap of 0.7 m between points (about 0.26 m free at ``nominal``'s safety distance, 0.1 m
    at ``stress``'s); the arena's edge closes the wall's ends (0.18 m from the outer robots' points
    to ``off``'s boundary margin, under the safety distance). 4 robots on each side (x = ±1.1 m,
    0.4 m apart) are driven through the gap to their mirror points on the other side."""
    poses, goals = [], []
    for _ in range(episodes):
        wall = np.column_stack([rng.uniform(-0.05, 0.05, 4), [-0.72, -0.35, 0.35, 0.72]])
        side_y = np.array([-0.6, -0.2, 0.2, 0.6])
        left = np.column_stack([-1.1 + rng.uniform(-0.03, 0.03, 4), side_y + rng.uniform(-0.015, 0.015, 4)])
        right = np.column_stack([1.1 + rng.uniform(-0.03, 0.03, 4), side_y + rng.uniform(-0.015, 0.015, 4)])
        start = np.vstack([wall, left, right])
        goal = np.vstack([wall, left * [-1, 1], right * [-1, 1]])
        heading = np.concatenate([np.full(4, np.pi / 2), np.zeros(4), np.full(4, np.pi)])
        poses.append(np.column_stack([start, heading + rng.uniform(-0.3, 0.3, 12)]))
        goals.append(goal)
    return (12,) * episodes, poses, goals, 1200


def _packed(rng, episodes):
    """16 robots 0.3 m apart across the arena, for bang-bang commands (goals unused)."""
    poses = [
        np.column_stack([_spread(rng, 16, 0.3, margin=0.2), rng.uniform(-np.pi, np.pi, 16)]) for _ in range(episodes)
    ]
    return (16,) * episodes, poses, [np.zeros((16, 2))] * episodes, 300


def _corner(rng, episodes):
    """One robot in a random corner, driven into it; three more driven at the corner."""
    poses, goals = [], []
    for _ in range(episodes):
        sx, sy = rng.choice([-1.0, 1.0], 2)
        corner = np.array([sx * _X1, sy * _Y1])
        pinned = corner - np.array([sx, sy]) * 0.25
        others = pinned - np.array([sx, sy]) * rng.uniform(0.5, 0.9, (3, 1)) * np.array(
            [[1.0, 0.2], [0.6, 0.6], [0.2, 1.0]]
        )
        start = np.vstack([pinned, others])
        poses.append(np.column_stack([start, rng.uniform(-np.pi, np.pi, 4)]))
        goals.append(np.repeat(corner[None], 4, axis=0))
    return (4,) * episodes, poses, goals, 300


def _inside(rng, episodes):
    """Two robots 0.15 m apart (inside the 0.2 m safety distance), driven at each other."""
    poses, goals = [], []
    for _ in range(episodes):
        c = rng.uniform([-0.8, -0.5], [0.8, 0.5])
        a = rng.uniform(0, 2 * np.pi)
        u = np.array([np.cos(a), np.sin(a)])
        start = np.stack([c - 0.075 * u, c + 0.075 * u])
        poses.append(np.column_stack([start - 0.025 * np.stack([u, -u]), [a, a + np.pi]]))
        goals.append(start[::-1].copy())
    return (2,) * episodes, poses, goals, 200


SCENARIOS: dict[str, Callable] = {
    "head_on": _head_on,
    "swap4": _swap(4, 0.45),
    "swap8": _swap(8, 0.75),
    "converge16": _converge(16),
    "converge32": _converge(32),
    "walls": _walls,
    "ring20": _ring20,
    "bangbang16": _packed,
    "corner": _corner,
}
"""Scenarios that start inside the safe set (every pair and wall margin respected)."""
CROSSINGS: dict[str, Callable] = {
    "antipodal16": _ellipse(16, 1.3, 0.75, 1800),
    "antipodal20": _ellipse(20, 1.4, 0.8, 1800),
    "lanes12": _lanes,
    "pinch12": _pinch,
}
"""Dense crossings for liveness (issue 66), safe starts whose goals can all be held at once:
antipodal swaps of 16 (ellipse 1.3 × 0.75 m, ≈ 0.41 m apart) and 20 robots (1.4 × 0.8 m,
≈ 0.35 m), six head-on pairs in lanes, and a doorway; horizons of 36–60 s, at least twice the
time the same teams need at ``off`` (:mod:`comat.bench.liveness`)."""
UNSAFE_STARTS: dict[str, Callable] = {"inside": _inside}
"""Scenarios that start outside it: the filter must recover, not keep a promise it cannot."""

_STOP = {"fault_prob": 1.0, "fault_speed_fraction": 0.0, "fault_start_min_s": 0.5, "fault_start_max_s": 4.0}
FAULTS: dict[str, tuple[str, dict]] = {
    "stop_swap4": ("swap4", _STOP),
    "stop_converge16": ("converge16", _STOP),
    "dropout_swap4": ("swap4", {"command_loss_prob": 0.004, "command_loss_mean_ticks": 45.0}),
    "frozen_stop_swap4": ("swap4", {**_STOP, "pose_freeze_prob": 0.02, "pose_freeze_mean_ticks": 15.0}),
    "exact_swap4": ("swap4", {"pose_noise_xy_m": 0.0, "pose_noise_theta_rad": 0.0, "pose_bias_xy_m": 0.0}),
    "exact_bangbang16": ("bangbang16", {"pose_noise_xy_m": 0.0, "pose_noise_theta_rad": 0.0, "pose_bias_xy_m": 0.0}),
    "stall_converge16": ("converge16", {"script_stall_prob": 0.01, "script_stall_mean_ticks": 8.0}),
    "stall_bangbang16": ("bangbang16", {"script_stall_prob": 0.01, "script_stall_mean_ticks": 8.0}),
}
"""Faults the filters must survive (issue 45), each a safe-start scenario with reality fields set
on top of the battery's level: a robot whose motors stop while it is commanded to move (a dead
robot: ``stop_*``, from 0.5–4 s on); Wi-Fi dropouts of 1.5 s on average, so that the robot brakes
after 0.5 s (``dropout_*``); a stopped robot whose pose also freezes (``frozen_stop_*``: its
commands are not executed and what the script sees of it is stale); repeated poses with no noise
(``exact_*``: an exact tracker, where a repeat cannot be told from a robot standing still); team-wide
stalls of the script, 8 ticks (0.26 s) on average, 1 % of ticks (``stall_*``: every robot keeps its
last command, those past 0.5 s brake). A robot that does not respond is an obstacle to the others,
whatever it was told."""


def swap_scenario(robots: int, episodes: int, seed: int, ticks: int = 300, radius: float = 0.75) -> Scenario:
    """``episodes`` teams of ``robots`` on a jittered ring, each robot driven to the opposite side."""
    sizes, poses, goals, _ = _swap(robots, radius)(np.random.default_rng(seed), episodes)
    return Scenario(f"swap{robots}", tuple(sizes), np.concatenate(poses), np.concatenate(goals), ticks)


def make_scenario(name: str, episodes: int, seed: int) -> Scenario:
    """Draw ``episodes`` random episodes of scenario ``name`` (one of :data:`SCENARIOS`,
    :data:`UNSAFE_STARTS` or :data:`FAULTS`: a fault scenario draws its base scenario's episodes
    and carries its reality fields in :attr:`Scenario.reality`)."""
    makers = {**SCENARIOS, **CROSSINGS, **UNSAFE_STARTS}
    if name in FAULTS:
        base, fields = FAULTS[name]
        return dataclasses.replace(make_scenario(base, episodes, seed), name=name, reality=dict(fields))
    if name not in makers:
        raise ValueError(f"scenario must be one of {sorted(makers) + sorted(FAULTS)}, got {name!r}")
    sizes, poses, goals, ticks = makers[name](np.random.default_rng(seed), episodes)
    return Scenario(
        name, tuple(sizes), np.concatenate(poses), np.concatenate(goals), ticks, bangbang=name.startswith("bangbang")
    )


@dataclass
class ScenarioResult:
    """Outcome per episode (B,) after running a scenario."""

    min_centre_distance: np.ndarray
    min_point_distance: np.ndarray
    """(B,) closest true projected points (what the barrier keeps d_s apart)."""
    safe_start: np.ndarray
    """(B,) the team really started inside the filter's safe set: true projected points at
    least the filter's safety distance apart and inside its boundary margin (with a reality
    layer, the start error can put a team outside it although its requested poses were in it)."""
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
    first_collision: list = dataclasses.field(default_factory=list)
    """Per episode, its first Robotarium collision on true poses: None or (tick, robot i, robot j),
    robots numbered within the team."""
    arrival: np.ndarray | None = None
    """(R,) first tick each robot's true point was at its goal, −1 never (:mod:`comat.bench.liveness`)."""
    movers: np.ndarray | None = None
    """(R,) robots that started away from their goals."""
    freezes: np.ndarray | None = None
    """(B,) team-freeze onsets (:mod:`comat.bench.liveness`)."""
    frozen_ticks: np.ndarray | None = None
    """(B,) ticks each team spent frozen."""


def _bangbang(rng: np.random.Generator, n: int):
    """Nominal commands (n, 2) at full point speed in random directions, each robot switching
    after its own 15-45 ticks."""
    left = np.zeros(n, np.int64)
    u = np.zeros((n, 2))

    def step() -> np.ndarray:
        switch = left <= 0
        if switch.any():
            a = rng.uniform(0, 2 * np.pi, int(switch.sum()))
            u[switch] = 0.2 * np.stack([np.cos(a), np.sin(a)], 1)
            left[switch] = rng.integers(15, 46, int(switch.sum()))
        left[:] -= 1
        return u

    return step


def _drive_wrong_way(teams: SafeTeams, from_tick: int) -> None:
    """Each team's first robot executes its forward speed negated from ``from_tick`` on (the
    layer's motors see −v): a fault the script's commands do not reveal by distance alone."""
    if teams.reality.is_off:
        raise ValueError("wrong_way_tick needs a reality layer (a level other than off)")
    layer, first = teams.reality, teams.world.layout.offsets[:-1]
    actuate, ticks = layer.actuate, [0]

    def wrong_way(dxu: np.ndarray) -> np.ndarray:
        if ticks[0] >= from_tick:
            dxu = dxu.copy()
            dxu[first, 0] *= -1.0
        ticks[0] += 1
        return actuate(dxu)

    layer.actuate = wrong_way


def _in_safe_set(teams: SafeTeams) -> np.ndarray:
    """(B,) every true projected point of the team inside the filter's safe set (the deployed
    loop's: the Robotarium barrier's own)."""
    lay = teams.world.layout
    if teams.deployed is not None:
        true = teams.poses
        return np.array(
            [
                loop.barrier.in_safe_set(true[lay.offsets[b] : lay.offsets[b + 1]].T)
                for b, loop in enumerate(teams.deployed)
            ]
        )
    cfg, q = teams.filter_config, teams.points
    close = np.linalg.norm(q[lay.pair_i] - q[lay.pair_j], axis=1) < cfg.safety_distance_m
    m = cfg.boundary_margin_m
    out = (q[:, 0] < _X0 + m) | (q[:, 0] > _X1 - m) | (q[:, 1] < _Y0 + m) | (q[:, 1] > _Y1 - m)
    bad = np.bincount(lay.pair_team, weights=close, minlength=lay.n_teams)
    bad += np.bincount(lay.robot_team, weights=out, minlength=lay.n_teams)
    return bad == 0


def run_scenario(
    scn: Scenario,
    sim: SimConfig,
    safety: SafetyConfig | None = None,
    filtered: bool = True,
    reality: RealityConfig | str | None = None,
    seed: int = 0,
    filter_reality: RealityConfig | str | None = None,
    wrong_way_tick: int | None = None,
) -> ScenarioResult:
    # long: one batch: the tick loop's safety and liveness records share its arrays, then one result
    """Run every episode of ``scn`` as one batch for ``scn.ticks`` ticks.

    With ``filtered=False`` the nominal commands go to the wheels unfiltered (only clipped to
    the wheel limits), to show what the barrier prevents. ``reality`` (a level or config) puts
    the reality layer between the world and the controller, its draws keyed by ``seed``; a fault
    scenario's fields (:attr:`Scenario.reality`) are set on top. ``safety.loop`` other than
    ``"comat"`` runs the exported script's loop (:meth:`SafeTeams.tick_deployed`) instead.

    A mismatch ("built for X, run in Y"): ``filter_reality`` makes the filter for another reality
    than the world's; ``wrong_way_tick`` negates what each team's first robot executes of its
    forward speed from that tick on (a tracker heading off by π, swapped motor leads).
    """
    config = resolve_reality(reality)
    if scn.reality:
        config = dataclasses.replace(config, **scn.reality)
    design = resolve_reality(filter_reality) if filter_reality is not None else None
    teams = SafeTeams(scn.team_sizes, sim, safety, reality=config, reality_seed=seed, filter_reality=design)
    teams.reset(scn.poses)
    if wrong_way_tick is not None:
        _drive_wrong_way(teams, wrong_way_tick)
    lay = teams.world.layout
    safe_start = _in_safe_set(teams)
    min_d = np.full(lay.n_teams, np.inf)
    min_p = np.full(lay.n_teams, np.inf)
    d_proj = teams.safety_config.projection_distance_m
    bang = _bangbang(np.random.default_rng(seed), lay.n_robots) if scn.bangbang else None
    first: list = [None] * lay.n_teams
    live = LivenessTracker(scn.goals, lay.robot_team, lay.n_teams, teams.points)
    for tick in range(scn.ticks):
        nominal = bang() if bang is not None else go_to_goal(teams.measured_points, scn.goals)
        if filtered and teams.deployed is not None:
            teams.tick_deployed(nominal)
        elif filtered:
            teams.tick(nominal)
        else:
            teams.world.step(si_to_uni(nominal, teams.poses, d_proj))
        p = teams.poses[:, :2]
        d = np.linalg.norm(p[lay.pair_i] - p[lay.pair_j], axis=1)
        np.minimum.at(min_d, lay.pair_team, d)
        q = teams.points
        live.update(q)
        np.minimum.at(min_p, lay.pair_team, np.linalg.norm(q[lay.pair_i] - q[lay.pair_j], axis=1))
        true = teams.poses
        c = true[:, :2] + C.COLLISION_OFFSET_M * np.column_stack([np.cos(true[:, 2]), np.sin(true[:, 2])])
        hit = np.linalg.norm(c[lay.pair_i] - c[lay.pair_j], axis=1) <= C.COLLISION_DIAMETER_M
        for k in np.flatnonzero(hit):
            b = int(lay.pair_team[k])
            if first[b] is None:
                first[b] = (tick, int(lay.pair_i[k] - lay.offsets[b]), int(lay.pair_j[k] - lay.offsets[b]))
    v = teams.world.violations
    err = np.linalg.norm(teams.points - scn.goals, axis=1)
    return ScenarioResult(
        min_centre_distance=min_d,
        min_point_distance=min_p,
        safe_start=safe_start,
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
        first_collision=first,
        arrival=live.arrival,
        movers=live.movers,
        freezes=live.freezes,
        frozen_ticks=live.frozen_ticks,
    )
