"""Navigation (``navigation_v0``): every goal must be claimed by one robot before time runs out, and
robots differ in speed — which robot takes which goal decides whether the team makes it.

| | |
|---|---|
| Agents | ``robot_0 … robot_{n-1}``, n = 2…20; types ``fast`` and ``slow``, >= 1 of each; team changes every episode as in every comat task (``possible_agents`` the largest team, ``agents`` this episode's) |
| Capabilities | [speed m]: waypoint step per env step |
| Actions | Discrete(5): 0 stay, 1 +x, 2 −x, 3 +y, 4 −y — a waypoint one speed-step away for the robot's projected point |
| Step | 29 control ticks of 0.033 s (0.96 s): waypoint controller → safety filter → MuJoCo |
| Observation | Box(12,) float64, below |
| State | Box(3K + S·12,): goals (x, y) ×K, claimed ×K over the env's K_max goal slots (one per robot of its largest team; a smaller team's unused slots parked at (2.6, 0), claimed), then the observations of S = ``state_robots`` slots |
| Horizon | 36 steps; ends early when every goal is claimed |
| Goals | one per robot, >= 0.35 m apart in x ∈ [−0.6, 1.45], y ∈ [−0.85, 0.85]. They are drawn robot by robot, each U(0.55, 0.85) × the distance that robot covers in 26 steps from the spawn area's centre, toward +x (±60°), then shuffled; where each robot starts is drawn apart from its goal. A layout is redrawn (up to 50 times) until the scripted plan from the actual starts needs at most 75 % of the horizon: the team can claim every goal in time with the right robot on each, and a fast robot's goal is out of a slow robot's reach |
| Spawn | robots >= 0.3 m apart in x ∈ [−1.45, −0.95], y ∈ [−0.85, 0.85], random headings |

Observation layout (per robot):

| index | feature |
|---|---|
| 0–1 | x, y (m) |
| 2–3 | cos θ, sin θ |
| 4–5 | type one-hot (fast, slow) |
| 6 | speed / 0.2 m |
| 7 | 1 if the robot has claimed a goal (it is done: it holds its place) |
| 8 | team's fraction of goals claimed |
| 9 | steps left / horizon |
| 10–11 | offset (m) to the nearest open goal (0 when none is left) |

Every robot sees the nearest open goal; which robot should take which goal it learns from its
teammates (the model's communication) and their speeds.

Composition sets (``coalitions=``; :mod:`comat.team`; speed, m per step):

* ``train`` (U_train): 3, 5 or 7 robots; fast U(0.14, 0.18), slow U(0.035, 0.05): a fast robot
  covers about four times a slow one's distance.
* ``val``: like U_train from another stream; ``size``: sizes 2…20, U_train's ranges.
* ``test`` (U_test): 2, 4, 6 or 8 robots; fast U(0.12, 0.19), slow U(0.03, 0.06); ``scale``: 10,
  12, 16 or 20 robots with U_test's ranges.
* ``capability`` (U_cap): every speed outside its type's U_train range: fast [0.11, 0.14) ∪
  (0.18, 0.19], slow [0.025, 0.035) ∪ (0.05, 0.06] (0.19 m: 0.2 m/s over one 0.96 s step).

Rule (after every step): a robot that has not claimed a goal, whose centre is within
:attr:`Navigation.goal_radius_m` (0.16 m) of an open goal and which stopped there (it moved less
than half its step in the env step) claims it (the nearest, one per robot and step; robots in
slot order), for good: each robot claims one goal at most, so the team must
share its goals out. A robot that has claimed its goal has done its part (observation 7); the
scripted references keep it there, a parked robot the others steer around.

Reward (shared) = named terms: ``claimed`` +1 per goal claimed, ``time`` −0.05 per step,
``violation`` −5 in a step with any robot–robot contact, Robotarium-style collision or boundary
exit.

References (``results/sets/references.md``): the scripted policy shares the goals out at departure
with the least summed squared travel time (distance from each robot's start over its speed) and
each robot drives to its goal; its capability-blind twin (``blind_scripted_actions``) makes the
same plan by distance alone, as if every robot were equally fast.

Version history: v0 — first version (issue 49; after MARBLER's Simple and JaxRobotarium's
Navigation, with goals shared by the team instead of one fixed goal per robot).
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

# (an export ships this file beside task_logic.py, with this import made local: sim2real/export.py)
from comat.task_logic import Area, Items, Ring, TaskLogic, grid_cells, grow_slots, min_cost_assignment

__all__ = ["NAVIGATION", "Navigation"]


class Navigation(TaskLogic):
    """Team navigation with heterogeneous speeds (module docstring). State per env: goals (B, K, 2),
    claimed (B, K), active (B, K), each robot's claimed flag and goal (B, N)."""

    name = "navigation"
    types = ("fast", "slow")
    capabilities = ("speed_m",)
    capability_scale = np.array([0.2])
    speed_capability = 0
    horizon = 36
    ticks_per_step = 29
    spawn_box = (-1.45, -0.95, -0.85, 0.85)
    goal_box = (-0.6, 1.45, -0.85, 0.85)
    goal_spacing = 0.35
    goal_radius_m = 0.16
    """A robot claims a goal by stopping within this of it (a fast robot's waypoint grid is its step,
    0.19 m at most: its projected point settles within half a step of a goal on each axis)."""
    stop_fraction = 0.5
    """Stopping: the robot's centre moved less than this fraction of its step in the env step (a
    robot driving through a goal toward another does not claim it)."""
    plan_steps = 26
    """Goals are drawn U(0.35, 0.75) × this many of their robot's steps from the spawn area's centre
    (the horizon leaves room for the start's offset, turning, the filter and teammates in the way)."""
    n_task_features = 5
    reward_terms = ("claimed", "time", "violation")
    reward_weights: ClassVar[dict] = {"claimed": 1.0, "time": -0.05, "violation": -5.0}
    parked = (2.6, 0.0)
    reach_fraction = (0.55, 0.85)
    slack = 0.75
    """A layout is kept when the scripted plan needs at most this share of the horizon (the rest:
    turning, the filter, teammates in the way)."""
    reset_uses_starts = True

    capability_limits = ((0.0, 0.19),)
    required = ((0,), (0,))
    capability_bands: ClassVar[dict] = {
        "train": {"fast": (((0.14, 0.18),),), "slow": (((0.035, 0.05),),)},
        "test": {"fast": (((0.12, 0.19),),), "slow": (((0.03, 0.06),),)},
        "capability": {
            "fast": (((0.11, 0.139999), (0.180001, 0.19)),),
            "slow": (((0.025, 0.034999), (0.050001, 0.06)),),
        },
    }
    set_streams = 18
    """The composition sets' random streams are 18… (PCP and HMT 0–11, forage 12–17)."""

    def __init__(self) -> None:
        self.largest_team: int | None = None

    def max_team_size(self) -> int:
        n = self.spawn_capacity()
        return min(n, grid_cells(self.goal_box, self.goal_spacing))

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

    def reset_env(self, state: dict, b: int, rng: np.random.Generator, caps: np.ndarray, starts=None) -> None:
        """One goal per robot of the team (caps (n, 1)): robot i's speed sets how far from the spawn
        area's centre its goal lies (module docstring), redrawn (up to 50 times) until the scripted
        plan from the robots' ``starts`` (n, 3) needs at most :attr:`slack` of the horizon."""
        n, slots = caps.shape[0], state["goals"].shape[1]
        state["start"][b] = 0.0
        if starts is not None:
            state["start"][b, :n] = starts[:, :2]
        state["prev"][b] = state["start"][b]
        state["goals"][b] = self.parked
        state["active"][b] = np.arange(slots) < n
        state["claimed"][b] = ~state["active"][b]
        state["done_robot"][b] = False
        state["steps"][b] = 0
        for _ in range(50):
            state["goals"][b, :n] = self._draw_goals(rng, caps[:, 0])
            if starts is None or self._plan_steps(state, b, caps[:, 0]) <= self.slack * self.horizon:
                break

    def _draw_goals(self, rng: np.random.Generator, speed: np.ndarray) -> np.ndarray:
        """(n, 2) goals, goal i U(reach_fraction) × speed_i × plan_steps from the spawn area's centre."""
        x0, x1, y0, y1 = self.goal_box
        origin = np.array([(self.spawn_box[0] + self.spawn_box[1]) / 2, (self.spawn_box[2] + self.spawn_box[3]) / 2])
        goals = np.zeros((0, 2))
        for v in speed:
            for _ in range(200):
                r = rng.uniform(*self.reach_fraction) * v * self.plan_steps
                a = rng.uniform(-np.pi / 3, np.pi / 3)
                g = origin + r * np.array([np.cos(a), np.sin(a)])
                g = np.array([np.clip(g[0], x0, x1), np.clip(g[1], y0, y1)])
                if goals.shape[0] == 0 or np.min(np.hypot(*(goals - g).T)) >= self.goal_spacing:
                    break
            goals = np.vstack([goals, g])
        return goals[rng.permutation(len(speed))]

    def _plan_steps(self, state: dict, b: int, speed: np.ndarray) -> float:
        """Env steps the slowest robot of env ``b``'s scripted plan needs (Manhattan distance / speed)."""
        n = speed.shape[0]
        one = {k: v[b : b + 1] for k, v in state.items()}
        goals, _ = self._plan(
            one,
            None,
            np.pad(speed, (0, state["start"].shape[1] - n))[None],
            np.arange(state["start"].shape[1])[None] < n,
        )
        return float((np.abs(goals[0, :n] - state["start"][b, :n]).sum(-1) / speed).max())

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
        return state["claimed"].all(axis=1)

    def progress(self, state: dict) -> np.ndarray:
        """Share of the team's goals claimed (B,)."""
        return (state["claimed"] & state["active"]).sum(axis=1) / np.maximum(state["active"].sum(axis=1), 1)

    def task_features(self, state, poses, type_ids, caps, mask) -> np.ndarray:
        B, N = mask.shape
        frac = np.broadcast_to(self.progress(state)[:, None], (B, N))
        left = np.broadcast_to((1.0 - state["steps"] / self.horizon)[:, None], (B, N))
        d = state["goals"][:, None, :, :] - poses[:, :, None, :2]
        dist2 = np.where(~state["claimed"][:, None, :], d[..., 0] ** 2 + d[..., 1] ** 2, np.inf)
        k = np.argmin(dist2, axis=-1)
        ok = np.isfinite(np.take_along_axis(dist2, k[..., None], -1))[..., 0]
        near = np.take_along_axis(d, k[..., None, None], 2)[..., 0, :] * ok[..., None]
        return np.concatenate([np.stack([state["done_robot"].astype(float), frac, left], axis=-1), near], axis=-1)

    def global_features(self, state: dict) -> np.ndarray:
        B = state["goals"].shape[0]
        return np.concatenate([state["goals"].reshape(B, -1), state["claimed"].astype(float)], axis=-1)

    # -- the scripted references ------------------------------------------------------------------
    def _plan(self, state: dict, centres: np.ndarray, speed: np.ndarray, mask: np.ndarray) -> tuple:
        """Each free robot's goal (B, N, 2) and whether it has one: the assignment of free robots to
        open goals with the least summed squared travel time from where they started (distance /
        ``speed`` (B, N)), squared so that no robot is left with a far goal to spare the others a
        little. Planned from the starts, the plan holds over the episode (a goal claimed leaves the
        rest as they were): a plan made at departure, as a dispatcher would."""
        B, N = mask.shape
        # Manhattan: the waypoints move along x or y, one axis a step
        d = np.abs(state["goals"][:, None, :, :] - state["start"][:, :, None, :]).sum(-1)  # (B, N, K)
        t = d / np.maximum(speed, 1e-9)[..., None]
        target = np.zeros((B, N), np.int64)
        has = np.zeros((B, N), bool)
        for b in range(B):
            robots = np.flatnonzero(mask[b] & ~state["done_robot"][b])
            goals = np.flatnonzero(~state["claimed"][b])
            if robots.size and goals.size:
                rows, cols = min_cost_assignment(t[b][np.ix_(robots, goals)] ** 2)
                target[b, robots[rows]], has[b, robots[rows]] = goals[cols], True
        goals_xy = np.take_along_axis(state["goals"], target[..., None].repeat(2, -1), 1)
        return goals_xy, has

    def scripted_actions(self, state, poses, type_ids, caps, mask) -> np.ndarray:
        """The scripted reference (module docstring); a robot that claimed its goal stays."""
        centres = poses[..., :2]
        goals, ok = self._plan(state, centres, caps[..., 0], mask)
        return self.drive(state, poses, caps, mask, goals, ok)

    def blind_scripted_actions(self, state, poses, type_ids, caps, mask) -> np.ndarray:
        """The same plan by distance alone (every robot believed equally fast)."""
        centres = poses[..., :2]
        goals, ok = self._plan(state, centres, np.ones(mask.shape), mask)
        return self.drive(state, poses, caps, mask, goals, ok)

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


NAVIGATION = Navigation
