"""Navigation (``navigation_v1``): every goal must be claimed by one robot before time runs out, and
each goal is as far as one robot of the team can just reach at its own speed — which robot takes
which goal is decided by the robots' actual speeds, not by their types.

| | |
|---|---|
| Agents | ``robot_0 … robot_{n-1}``, n = 2…20; types ``fast`` and ``slow``, >= 1 of each; team changes every episode as in every comat task (``possible_agents`` the largest team, ``agents`` this episode's) |
| Capabilities | [speed m]: waypoint step per env step; the two types' ranges overlap and each is wide (below) |
| Actions | Discrete(5): 0 stay, 1 +x, 2 −x, 3 +y, 4 −y — a waypoint one speed-step away for the robot's projected point |
| Step | 29 control ticks of 0.033 s (0.96 s): waypoint controller → safety filter → MuJoCo |
| Observation | Box(25,) float64, below |
| State | Box(3K + S·25,): goals (x, y) ×K, claimed ×K over the env's K_max goal slots (one per robot of its largest team; a smaller team's unused slots parked at (2.6, 0), claimed), then the observations of S = ``state_robots`` slots |
| Horizon | 22 steps; ends early when every goal is claimed |
| Goals | one per robot, drawn against the team's own speeds: goal i lies U(0.9, 1.0) × robot i's reach (Manhattan, plus 0.1 m) from where robot i starts, toward +x (y uniform where the reach allows), inside x ∈ [−1.45, 1.45], y ∈ [−0.85, 0.85], >= 0.35 m from the other goals and >= 0.2 m from every start; then shuffled. A robot's reach is its speed × 18 steps in teams of up to 8 robots, 0.25 step less per robot above (15 at 20: teammates in the way). So a right assignment exists by construction (no layout is redrawn or selected), and a goal asks for a robot at least about 0.8 × as fast as the one it was drawn for: the faster of two robots of one type can matter |
| Spawn | robots >= 0.3 m apart in x ∈ [−1.45, −0.95], y ∈ [−0.85, 0.85] (widened to the right for large teams), random headings |
| Meant for | both families: **capability** (scripted − type_only on U_cap: the type says nothing of a U_cap robot's speed) and **size** (scripted − blind on U_size ∪ U_scale) |

Observation layout (per robot; a goal's *steps to go* is (Manhattan distance − 0.1 m) / the robot's
own speed, / horizon, clipped to 2):

| index | feature |
|---|---|
| 0–1 | x, y (m) |
| 2–3 | cos θ, sin θ |
| 4–5 | type one-hot (fast, slow) |
| 6 | speed / 0.2 m |
| 7 | 1 if the robot has claimed a goal (it is done: it holds its place) |
| 8 | team's fraction of goals claimed |
| 9 | steps left / horizon |
| 10–12 | nearest open goal: offset x, y (m), steps to go |
| 13–15 | second nearest open goal, the same |
| 16–18 | farthest open goal the robot can still reach in the steps left (steps to go <= steps left), the same |
| 19–21 | second farthest it can still reach |
| 22–24 | third farthest it can still reach |

A view with no goal is zeros; views may repeat a goal. What is near tells a robot what is easy; what
it can only just reach is what its speed is for. Together the team's views show nearly every open
goal: a planner that reads only the team's observations (what the model's communication carries)
does better than the blind reference (tests/test_navigation.py). Which robot should take which goal
a learner works out from its teammates' observations (their speeds and views).

Composition sets (``coalitions=``; :mod:`comat.team`; speed, m per step; type means over each set's
bands in brackets, what the ``type_only`` reference believes):

* ``train`` (U_train): 3, 5 or 7 robots; fast U(0.06, 0.17), slow U(0.04, 0.11) [0.115, 0.075]: the
  types overlap over 0.06–0.11, and a fast robot can be almost three times as fast as another.
* ``val``: like U_train from another stream; ``size``: sizes 2…20, U_train's ranges.
* ``test`` (U_test): 2, 4, 6 or 8 robots; fast U(0.05, 0.19), slow U(0.03, 0.13); ``scale``: 10,
  12, 16 or 20 robots with U_test's ranges.
* ``capability`` (U_cap): every speed outside its type's U_train range: fast [0.03, 0.06) ∪ (0.17,
  0.19], slow [0.025, 0.04) ∪ (0.11, 0.14] (0.19 m: 0.2 m/s over one 0.96 s step) [0.099, 0.094]:
  a robot's type mean lies between its two bands, so it is wrong for every robot.

Rule (after every step): a robot that has not claimed a goal, whose centre is within
:attr:`Navigation.goal_radius_m` (0.16 m) of an open goal and which stopped there (it moved less
than half its step in the env step) claims it (the nearest, one per robot and step; robots in
slot order), for good: each robot claims one goal at most, so the team must share its goals out.
A robot that has claimed its goal has done its part (observation 7); the scripted references keep
it there, a parked robot the others steer around.

Reward (shared) = named terms: ``claimed`` +1 per goal claimed, ``time`` −0.05 per step,
``violation`` −5 in a step with any robot–robot contact, Robotarium-style collision or boundary
exit.

Coordination (``coordination``, lower is better): the share of the team's goals *stranded* — open,
and out of reach of every robot still free (Manhattan distance less the claim radius > its speed ×
the steps left). 0 at the start by construction; a goal is stranded once every robot that could
have taken it went elsewhere or claimed another. An episode's value is its mean over its steps.

References (``results/sets/validity.md``): the scripted policy shares the goals out at departure,
reading the speeds from ``caps`` only: the assignment of free robots to open goals (from where they
started) with the least summed squared travel time (steps to go), each travel beyond 15 steps
costing 100 × its excess² more and one beyond the horizon less 3 steps counted as hopeless first;
each robot drives to its goal and stops within 0.1 m. ``type_only`` is the same planner believing
each robot has its type's mean speed; the capability-blind twin (``blind_scripted_actions``) makes
the plan by distance alone, as if every robot were equally fast.

Design measurements (coalition seed 1, episode seed 2,000,003, 20 coalitions × 3 episodes, unicycle
tier; progress %, differences with 95 % t-intervals over coalitions): scripted 98.9 on U_train,
95.5 on U_size ∪ U_scale; scripted − type_only on U_cap +19.4 [13.6, 25.1] (U_train +12.7);
scripted − blind on U_size ∪ U_scale +12.4 [10.0, 14.9] (U_size +11.4, U_scale +13.4). The size gap
rests on planning at departure: re-planned every step from where the robots are, distance alone
reads much of the speeds off how far each robot got (1 episode per coalition: U_size 95.0 against
98.0 with speeds, U_scale 90.3 against 95.7), while on U_cap it does not (86.1 against 98.6).

Version history: v0 — first version (issue 49; after MARBLER's Simple and JaxRobotarium's
Navigation, with goals shared by the team instead of one fixed goal per robot). v1 (issue 64) —
speeds decide, not types. In v0 a planner knowing only each type's mean speed recovered 86–99 % of
the scripted − blind gap (fast U(0.14, 0.18), slow U(0.035, 0.05): disjoint and narrow); layouts were
redrawn until the scripted plan fitted 75 % of the horizon, which favoured the scripted reference;
and each robot saw only its nearest open goal, while the scripted plan read every goal (learners
sat below the blind reference). v1: overlapping, wide speed ranges; each goal drawn within its own
robot's reach from its own start at 0.9–1.0 of it, then shuffled, never redrawn; observations of
the 2 nearest and the 3 farthest reachable open goals with their steps to go; a 22-step horizon
(v0: 36); goals anywhere in the arena (v0: x >= −0.6); the planners stop within 0.1 m of their goal
and weigh lateness; the coordination metric. Designed on coalition seed 1 and episode seed
2,000,003 only.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

# (an export ships this file beside task_logic.py, with this import made local: sim2real/export.py)
from comat.task_logic import WAYPOINT_LIMITS, Area, Items, Ring, TaskLogic, grid_cells, grow_slots, min_cost_assignment

__all__ = ["NAVIGATION", "Navigation"]


class Navigation(TaskLogic):
    """Team navigation with heterogeneous speeds (module docstring). State per env: goals (B, K, 2),
    claimed (B, K), active (B, K), each robot's claimed flag (B, N) and start (B, N, 2)."""

    name = "navigation"
    meant_for = ("capability", "size")
    """Both families (its spec sheet says why; :mod:`comat.eval.validity` measures them)."""
    version = 1
    types = ("fast", "slow")
    capabilities = ("speed_m",)
    capability_scale = np.array([0.2])
    speed_capability = 0
    horizon = 22
    ticks_per_step = 29
    spawn_box = (-1.45, -0.95, -0.85, 0.85)
    goal_box = WAYPOINT_LIMITS
    """Goals lie anywhere a waypoint can (x ∈ [−1.45, 1.45], y ∈ [−0.85, 0.85]): a slow robot's
    goal may be near the spawn area."""
    goal_spacing = 0.35
    start_clearance = 0.2
    """No goal lies within this of any robot's start (m; claim radius 0.16 m + margin): a robot
    turning on the spot at its start claims no goal it did not drive to, and a goal may sit between
    the starts of a large team's spawn block (0.3 m grid: 0.21 m from its corners)."""
    goal_radius_m = 0.16
    """A robot claims a goal by stopping within this of it (a fast robot's waypoint grid is its step,
    0.19 m at most: its projected point settles within half a step of a goal on each axis)."""
    arrive_m = 0.1
    """The travel a goal asks of a robot ends this far (Manhattan) short of it; the scripted robots
    stay once within this of their goal (inside the claim radius)."""
    stop_fraction = 0.5
    """Stopping: the robot's centre moved less than this fraction of its step in the env step (a
    robot driving through a goal toward another does not claim it)."""
    reach_steps = 18
    """A robot's reach in a team of up to 8: its speed × this many steps of Manhattan travel (the
    horizon less room for turning on the spot, stopping and the safety filter)."""
    crowd_steps_per_robot = 0.25
    """Each robot above 8 takes this many steps off the reach (teammates in the way: 15 at 20)."""
    reach_fraction = (0.9, 1.0)
    """Goal i lies U(reach_fraction) × robot i's reach (+ :attr:`arrive_m`) from robot i's own start
    (Manhattan): a robot slower than about 0.8 × robot i rarely makes it in time."""
    plan_budget_steps = 15
    """The travel (steps) the planners believe fits the horizon (the rest: turning, stopping,
    teammates in the way); a longer travel costs them :attr:`late_weight` × its excess², squared."""
    late_weight = 100.0
    plan_margin_steps = 3
    hopeless_cost = 1e6
    """A travel longer than the horizon less :attr:`plan_margin_steps` (turning, stopping) is taken as
    hopeless: it costs this, so the planners first keep as many robots within time as they can."""
    goal_tries = 256
    """Candidate places drawn at once for one goal (a second round if all are refused; see
    :meth:`_draw_goals`)."""
    near_views = 2
    far_views = 3
    """Goals in a robot's observation: its ``near_views`` nearest open goals and the ``far_views``
    farthest it can still reach in the steps left (together they show the team every goal: an
    observation-only planner reaches the scripted one's progress; tests/test_navigation.py)."""
    steps_view_cap = 2.0
    """A goal view's steps to go (/ horizon) is clipped to this (a slow robot, a far goal)."""
    n_task_features = 3 + 3 * (near_views + far_views)
    reward_terms = ("claimed", "time", "violation")
    reward_weights: ClassVar[dict] = {"claimed": 1.0, "time": -0.05, "violation": -5.0}
    parked = (2.6, 0.0)
    reset_uses_starts = True

    capability_limits = ((0.0, 0.19),)
    required = ((0,), (0,))
    capability_bands: ClassVar[dict] = {
        "train": {"fast": (((0.06, 0.17),),), "slow": (((0.04, 0.11),),)},
        "test": {"fast": (((0.05, 0.19),),), "slow": (((0.03, 0.13),),)},
        "capability": {
            "fast": (((0.03, 0.059999), (0.170001, 0.19)),),
            "slow": (((0.025, 0.039999), (0.110001, 0.14)),),
        },
    }
    set_streams = 18
    """The composition sets' random streams are 18… (PCP and HMT 0–11, forage 12–17)."""

    def __init__(self) -> None:
        self.largest_team: int | None = None

    def max_team_size(self) -> int:
        return min(self.spawn_capacity(), grid_cells(self.goal_box, self.goal_spacing))

    def fit_teams(self, largest: int) -> None:
        self.largest_team = int(largest)

    def step_lengths(self, caps: np.ndarray) -> np.ndarray:
        return caps[..., 0]

    def new_state(self, B: int, N: int) -> dict:
        K = max(N, self.largest_team or 0)
        return {
            "goals": np.broadcast_to(self.parked, (B, K, 2)).copy(),
            "claimed": np.ones((B, K), bool),
            "active": np.zeros((B, K), bool),
            "done_robot": np.zeros((B, N), bool),
            "steps": np.zeros(B),
            "start": np.zeros((B, N, 2)),
            "prev": np.zeros((B, N, 2)),
        }

    def reserve(self, state: dict, n_robots: int) -> None:
        """Grow every env's goal slots to fit a team of ``n_robots`` (the added slots inactive)."""
        slots = state["goals"].shape[1]
        if n_robots <= slots:
            return
        grow_slots(state, n_robots - slots, {"goals": self.parked, "claimed": True, "active": False})

    def reach_steps_for(self, n: int) -> float:
        """Steps of travel a goal asks of its robot in a team of ``n``: :attr:`reach_steps` up to 8
        robots, :attr:`crowd_steps_per_robot` fewer for each robot more (teammates in the way)."""
        return self.reach_steps - self.crowd_steps_per_robot * max(0, n - 8)

    def reset_env(self, state: dict, b: int, rng: np.random.Generator, caps: np.ndarray, starts=None) -> None:
        """One goal per robot of the team (caps (n, 1)), each within its own robot's reach of where
        that robot starts (``starts`` (n, 3); None: the spawn area's centre), shuffled (module
        docstring)."""
        n, slots = caps.shape[0], state["goals"].shape[1]
        if starts is None:
            box = self.spawn_box
            starts = np.tile([(box[0] + box[1]) / 2, (box[2] + box[3]) / 2, 0.0], (n, 1))
        self.set_starts(state, b, starts)
        state["goals"][b] = self.parked
        state["active"][b] = np.arange(slots) < n
        state["claimed"][b] = ~state["active"][b]
        state["done_robot"][b] = False
        state["steps"][b] = 0
        state["goals"][b, :n] = self._draw_goals(rng, caps[:, 0], np.asarray(starts, dtype=float)[:, :2])

    def _draw_goals(self, rng: np.random.Generator, speed: np.ndarray, starts: np.ndarray) -> np.ndarray:
        """(n, 2) goals for robots of ``speed`` (n,) starting at ``starts`` (n, 2): goal i
        :attr:`arrive_m` + U(reach_fraction) × robot i's reach (Manhattan) from its start, toward +x
        (y uniform where the reach allows), inside :attr:`goal_box`, >= :attr:`goal_spacing` from the
        goals placed before and >= :attr:`start_clearance` from every start; then shuffled, so a
        goal's slot says nothing of its robot. The robots with the least reach place theirs first
        (they have the least room). Where all :attr:`goal_tries` candidates are refused, a second
        round tries either way along x, anywhere within the reach; where that fails too (about 1 %
        of the goals of teams of 14 or more, none on U_train), the candidate that keeps farthest
        from the others is kept: spacing given up (to about 0.3 m), never the reach. A candidate
        past the box is clipped to it, which only shortens its distance: every goal stays within
        its robot's reach, so a right assignment exists by construction."""
        x0, x1, y0, y1 = self.goal_box
        reach = speed * self.reach_steps_for(speed.shape[0])
        goals = np.zeros((0, 2))
        order = np.argsort(reach, kind="stable")
        for i in order:
            best, best_gap = None, -np.inf
            # first toward +x at U(reach_fraction) of the reach; then either way, anywhere within it
            for lo, hi, both_ways in ((*self.reach_fraction, False), (0.0, 1.0, True)):
                r = self.arrive_m + reach[i] * rng.uniform(lo, hi, self.goal_tries)
                y = rng.uniform(np.maximum(y0, starts[i, 1] - r), np.minimum(y1, starts[i, 1] + r))
                sign = rng.choice([-1.0, 1.0], self.goal_tries) if both_ways else 1.0
                x = starts[i, 0] + sign * (r - np.abs(y - starts[i, 1]))  # |dx| + |dy| = r
                inside = (x >= x0) & (x <= x1)
                cand = np.stack([np.clip(x, x0, x1), y], -1)
                to_starts = np.hypot(*(cand[:, None, :] - starts[None]).transpose(2, 0, 1)).min(1)
                to_goals = (
                    np.hypot(*(cand[:, None, :] - goals[None]).transpose(2, 0, 1)).min(1)
                    if goals.shape[0]
                    else np.full(self.goal_tries, np.inf)
                )
                ok = np.flatnonzero((to_starts >= self.start_clearance) & (to_goals >= self.goal_spacing) & inside)
                if ok.size:
                    best = cand[ok[0]]
                    break
                gap = np.minimum(to_starts / self.start_clearance, to_goals / self.goal_spacing)
                k = int(np.argmax(gap))
                if gap[k] > best_gap:
                    best, best_gap = cand[k], gap[k]
            goals = np.vstack([goals, best])
        placed = np.zeros_like(goals)
        placed[order] = goals
        return placed[rng.permutation(speed.shape[0])]

    def update(self, state: dict, poses: np.ndarray, type_ids: np.ndarray, caps: np.ndarray, mask: np.ndarray) -> dict:
        centres = poses[..., :2]
        stopped = np.hypot(*(centres - state["prev"]).transpose(2, 0, 1)) < self.stop_fraction * caps[..., 0]
        d = centres[:, :, None, :] - state["goals"][:, None, :, :]
        dist2 = np.where(~state["claimed"][:, None, :], d[..., 0] ** 2 + d[..., 1] ** 2, np.inf)  # (B, N, K)
        near = (dist2 <= self.goal_radius_m**2) & (mask & ~state["done_robot"] & stopped)[..., None]
        claimed = np.zeros(state["claimed"].shape[0])
        envs = np.arange(near.shape[0])
        for i in range(near.shape[1]):  # robots in slot order: two robots never claim one goal
            k = np.argmin(dist2[:, i], axis=-1)
            take = near[envs, i, k] & ~state["claimed"][envs, k]
            state["claimed"][take, k[take]] = True
            state["done_robot"][take, i] = True
            claimed += take
        state["prev"] = centres.copy()
        state["steps"] += 1
        return {"claimed": claimed}

    def done(self, state: dict) -> np.ndarray:
        """Every goal of the team claimed (B,)."""
        return state["claimed"].all(axis=1)

    def progress(self, state: dict) -> np.ndarray:
        """Share of the team's goals claimed (B,)."""
        return (state["claimed"] & state["active"]).sum(axis=1) / np.maximum(state["active"].sum(axis=1), 1)

    def _steps_to(self, state: dict, centres: np.ndarray, speed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Offsets (B, N, K, 2) from robots at ``centres`` (B, N, 2) to every goal slot, and the env
        steps (B, N, K) each robot needs at ``speed`` (B, N) to get there (Manhattan: the waypoints
        move along x or y, one axis a step)."""
        d = state["goals"][:, None, :, :] - centres[:, :, None, :]
        travel = np.maximum(np.abs(d).sum(-1) - self.arrive_m, 0.0)
        return d, travel / np.maximum(speed, 1e-9)[..., None]

    def task_features(self, state, poses, type_ids, caps, mask) -> np.ndarray:
        """(B, N, 3 + 3V): claimed flag, team's fraction claimed, steps left / horizon, then V goal
        views (offset x, y m; steps to go / horizon, clipped): the :attr:`near_views` nearest open
        goals and the :attr:`far_views` farthest open goals the robot can still reach in the steps
        left (zeros where there is none)."""
        B, N = mask.shape
        frac = np.broadcast_to(self.progress(state)[:, None], (B, N))
        left = self.horizon - state["steps"]  # (B,)
        d, steps = self._steps_to(state, poses[..., :2], caps[..., 0])
        open_ = np.broadcast_to(~state["claimed"][:, None, :], steps.shape)
        by_distance = np.where(open_, steps, np.inf)  # one robot's speed: steps order = distance order
        reachable = open_ & (steps <= left[:, None, None])
        near, near_ok = _first(by_distance, np.isfinite(by_distance), self.near_views)
        far, far_ok = _first(np.where(reachable, -steps, np.inf), reachable, self.far_views)
        picks, ok = np.concatenate([near, far], -1), np.concatenate([near_ok, far_ok], -1)
        off = np.take_along_axis(d, picks[..., None].repeat(2, -1), 2)
        to_go = np.minimum(np.take_along_axis(steps, picks, -1) / self.horizon, self.steps_view_cap)
        views = np.concatenate([off, to_go[..., None]], axis=-1) * ok[..., None]  # (B, N, V, 3)
        head = np.stack(
            [state["done_robot"].astype(float), frac, np.broadcast_to(left[:, None] / self.horizon, (B, N))], -1
        )
        return np.concatenate([head, views.reshape(B, N, -1)], axis=-1)

    def global_features(self, state: dict) -> np.ndarray:
        B = state["goals"].shape[0]
        return np.concatenate([state["goals"].reshape(B, -1), state["claimed"].astype(float)], axis=-1)

    # -- the scripted references ------------------------------------------------------------------
    def _plan(self, state: dict, speed: np.ndarray, mask: np.ndarray) -> tuple:
        """Each free robot's goal (B, N, 2) and whether it has one: the assignment of free robots to
        open goals with the least summed squared travel time from where they started (steps to go at
        ``speed`` (B, N)), squared so that no robot is left with a far goal to spare the others a
        little; a travel beyond :attr:`plan_budget_steps` costs more, one the horizon cannot hold is
        hopeless. Planned from the starts, the plan holds over the episode (a goal claimed leaves the
        rest as they were): a plan made at departure, as a dispatcher would, by every rung alike (a
        re-planning blind twin would read the robots' speeds off how far they got)."""
        B, N = mask.shape
        _, t = self._steps_to(state, state["start"], speed)  # (B, N, K)
        target = np.zeros((B, N), np.int64)
        has = np.zeros((B, N), bool)
        for b in range(B):
            robots = np.flatnonzero(mask[b] & ~state["done_robot"][b])
            goals = np.flatnonzero(~state["claimed"][b])
            if robots.size and goals.size:
                tb = t[b][np.ix_(robots, goals)]
                late = np.maximum(tb - self.plan_budget_steps, 0.0)
                hopeless = tb > self.horizon - self.plan_margin_steps
                rows, cols = min_cost_assignment(tb**2 + self.late_weight * late**2 + self.hopeless_cost * hopeless)
                target[b, robots[rows]], has[b, robots[rows]] = goals[cols], True
        goals_xy = np.take_along_axis(state["goals"], target[..., None].repeat(2, -1), 1)
        return goals_xy, has

    def drive(self, state, poses, caps, mask, target, ok) -> np.ndarray:
        """:meth:`TaskLogic.drive`, and stay once within :attr:`arrive_m` of the target (inside the
        claim radius: the next step's stop claims it)."""
        gap = poses[..., :2] - target
        there = gap[..., 0] ** 2 + gap[..., 1] ** 2 <= self.arrive_m**2
        return np.where(there, 0, super().drive(state, poses, caps, mask, target, ok))

    def scripted_actions(self, state, poses, type_ids, caps, mask) -> np.ndarray:
        """The scripted reference (module docstring): speeds read from ``caps`` only; a robot that
        claimed its goal stays."""
        goals, ok = self._plan(state, caps[..., 0], mask)
        return self.drive(state, poses, caps, mask, goals, ok)

    def blind_scripted_actions(self, state, poses, type_ids, caps, mask) -> np.ndarray:
        """The same plan by distance alone (every robot believed equally fast)."""
        goals, ok = self._plan(state, np.ones(mask.shape), mask)
        return self.drive(state, poses, caps, mask, goals, ok)

    # -- coordination --------------------------------------------------------------------------------
    coordination_name = "goals stranded"
    coordination_doc = (
        "share of the team's goals that are open and that no robot still free could reach in the steps "
        "left at its speed (Manhattan distance less the claim radius); 0 at the start by construction, "
        "lower is better"
    )

    def coordination(self, state, poses, type_ids, caps, mask) -> np.ndarray:
        """(B,) the share of goals stranded now (:attr:`coordination_doc`): a goal is lost to the team
        once every robot that could have taken it has gone elsewhere or claimed another."""
        left = np.maximum(self.horizon - state["steps"], 0)
        d, _ = self._steps_to(state, poses[..., :2], caps[..., 0])
        gap = np.abs(d).sum(-1) - self.goal_radius_m  # (B, N, K)
        free = mask & ~state["done_robot"]
        can = free[..., None] & (gap <= caps[..., 0][..., None] * left[:, None, None])
        stranded = state["active"] & ~state["claimed"] & ~can.any(axis=1)
        return stranded.sum(axis=1) / np.maximum(state["active"].sum(axis=1), 1)

    # -- diagnostics, drawing and export ------------------------------------------------------------
    end_count_names = ("goals_open",)

    def end_counts(self, state: dict) -> dict[str, np.ndarray]:
        return {"goals_open": (state["active"] & ~state["claimed"]).sum(1).astype(float)}

    type_colors: ClassVar[dict] = {"fast": (15, 157, 88), "slow": (142, 68, 173)}
    counters_name = "goals"

    def areas(self, state: dict | None = None, b: int = 0) -> tuple[Area, ...]:
        return (
            Area("spawn", "box", self.spawn_box, (160, 160, 160), "robot spawn"),
            Area("goal_area", "box", self.goal_box, (66, 133, 244), "goal area"),
        )

    def items(self, state: dict, b: int) -> Items:
        on = state["active"][b]
        status = state["claimed"][b][on].astype(np.int64)
        colors = ((66, 133, 244), (15, 157, 88))
        return Items("goals", state["goals"][b][on].copy(), status, ("open", "claimed"), colors, 0.04)

    def rings(self, caps: np.ndarray, type_ids: np.ndarray) -> tuple[Ring, ...]:
        return (Ring("step", np.ones(caps.shape[0], bool), caps[:, 0], (120, 120, 120), "dotted ring: step", True),)

    def counters(self, state: dict, b: int, n: int) -> dict[str, float]:
        return {"claimed": float((state["claimed"][b] & state["active"][b]).sum())}

    def status_text(self, state: dict, b: int, counters: dict[str, float]) -> str:
        return f"goals claimed {int(counters['claimed'])}/{int(state['active'][b].sum())}"

    def layout(self, state: dict, b: int) -> dict[str, list]:
        return {"goals": state["goals"][b][state["active"][b]].tolist()}

    def set_starts(self, state: dict, b: int, starts: np.ndarray) -> None:
        n = starts.shape[0]
        state["start"][b] = 0.0
        state["start"][b, :n] = np.asarray(starts, dtype=float)[:, :2]
        state["prev"][b] = state["start"][b]

    def set_layout(self, state: dict, b: int, layout: dict[str, list]) -> None:
        goals = np.asarray(layout["goals"], dtype=float).reshape(-1, 2)
        k = goals.shape[0]
        state["goals"][b] = self.parked
        state["goals"][b, :k] = goals
        state["active"][b] = np.arange(state["goals"].shape[1]) < k
        state["claimed"][b] = ~state["active"][b]


def _first(key: np.ndarray, valid: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """The ``k`` slots (B, N, k) of least ``key`` (B, N, K) and whether each is ``valid``; slots past K
    are slot 0, not valid."""
    order = np.argsort(key, axis=-1, kind="stable")[..., :k]
    ok = np.take_along_axis(valid, order, -1)
    short = k - order.shape[-1]
    if short > 0:
        order = np.concatenate([order, np.zeros((*order.shape[:-1], short), np.int64)], -1)
        ok = np.concatenate([ok, np.zeros((*ok.shape[:-1], short), bool)], -1)
    return order, ok


NAVIGATION = Navigation
