"""Task logic of PCP and HMT in plain numpy: waypoints, task state, rewards, observations, and
the scripted reference policy (``scripted_actions``).

This module imports numpy only, on purpose: the MuJoCo environments (``comat.envs``) and the
exported Robotarium script (``sim2real``) run this same file, so the two cannot drift. Arrays
are batched over B environments with robots padded to N slots: ``mask`` (B, N) marks real
robots; poses (B, N, 3); capabilities (B, N, 2); type ids (B, N).
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

__all__ = [
    "ACTIONS",
    "ARENA",
    "HMT",
    "PCP",
    "heading_features",
    "toward",
    "waypoint_goals",
]

ARENA = (-1.6, 1.6, -1.0, 1.0)
"""Robotarium arena (x_min, x_max, y_min, y_max), m; equal to comat.constants.ARENA_BOUNDS_M."""
WAYPOINT_LIMITS = (-1.45, 1.45, -0.85, 0.85)
"""Waypoints are clipped to this box (the barrier keeps robots 0.1 m inside the arena anyway)."""
SPAWN_X_LIMIT = 1.45
"""Spawn areas of very large teams grow to the right up to this x (m)."""

ACTIONS = np.array([[0.0, 0.0], [1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]])
"""Discrete actions: 0 stay, 1 +x, 2 -x, 3 +y, 4 -y (unit directions of the waypoint step)."""
ACTION_NAMES = ("stay", "+x", "-x", "+y", "-y")


def waypoint_goals(points: np.ndarray, actions: np.ndarray, step: np.ndarray) -> np.ndarray:
    """Goals (..., 2) for the robots' projected points: one ``step`` (...,) m along the action.

    ``stay`` holds the current point. Goals are clipped to :data:`WAYPOINT_LIMITS`.
    """
    goals = points + ACTIONS[actions] * step[..., None]
    x0, x1, y0, y1 = WAYPOINT_LIMITS
    return np.stack([np.clip(goals[..., 0], x0, x1), np.clip(goals[..., 1], y0, y1)], axis=-1)


def toward(points: np.ndarray, targets: np.ndarray, step: np.ndarray, has_target: np.ndarray) -> np.ndarray:
    """Actions (B, N) moving points (B, N, 2) toward targets along the larger axis; stay when
    within half a step on both axes or without a target."""
    d = targets - points
    ax = np.abs(d)
    along_x = ax[..., 0] >= ax[..., 1]
    act = np.where(along_x, np.where(d[..., 0] > 0, 1, 2), np.where(d[..., 1] > 0, 3, 4))
    close = np.maximum(ax[..., 0], ax[..., 1]) < 0.5 * step
    return np.where(has_target & ~close, act, 0)


def _nearest(points: np.ndarray, candidates: np.ndarray, allowed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For points (B, N, 2), the nearest allowed candidate (B, K, 2) / allowed (B, N, K), and
    whether there was one (B, N)."""
    d = candidates[:, None, :, :] - points[:, :, None, :]
    dist = np.where(allowed, d[..., 0] ** 2 + d[..., 1] ** 2, np.inf)
    k = np.argmin(dist, axis=-1)
    target = np.take_along_axis(candidates[:, None, :, :].repeat(points.shape[1], 1), k[..., None, None], 2)[..., 0, :]
    return target, np.isfinite(np.take_along_axis(dist, k[..., None], -1))[..., 0]


def heading_features(poses: np.ndarray) -> np.ndarray:
    """(..., 4) pose features [x, y, cos θ, sin θ]."""
    return np.concatenate([poses[..., :2], np.cos(poses[..., 2:3]), np.sin(poses[..., 2:3])], axis=-1)


def _cells(box: tuple[float, float, float, float], spacing: float) -> int:
    """Points a box holds ``spacing`` apart on a grid (what :func:`_spread` can always place)."""
    x0, x1, y0, y1 = box
    return int(np.floor((x1 - x0) / spacing) + 1) * int(np.floor((y1 - y0) / spacing) + 1)


def _spread(
    rng: np.random.Generator, n: int, box: tuple[float, float, float, float], spacing: float, what: str, noun: str
) -> np.ndarray:
    """n points (n, 2) uniform in box, pairwise >= spacing apart (bounded rejection sampling)."""
    x0, x1, y0, y1 = box
    cells = _cells(box, spacing)
    if n > cells:
        raise ValueError(
            f"{what}: {n} {noun} do not fit {spacing} m apart in x [{x0}, {x1}], y [{y0}, {y1}] (at most {cells})"
        )
    for _ in range(5):  # random sequential addition; dense teams rarely fit this way
        pts = np.zeros((0, 2))
        for _ in range(30 * n):
            p = rng.uniform((x0, y0), (x1, y1))
            if pts.shape[0] == 0 or np.min(np.hypot(*(pts - p).T)) >= spacing:
                pts = np.vstack([pts, p])
                if pts.shape[0] == n:
                    return pts
    # Dense teams: random cells of a grid of that spacing, which always fits.
    nx = int(np.floor((x1 - x0) / spacing) + 1)
    ny = cells // nx
    grid = np.stack(np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij"), -1).reshape(-1, 2)
    return np.array([x0, y0]) + grid[rng.permutation(grid.shape[0])[:n]] * spacing


class _Task:
    """Shared shape of both tasks (see PCP and HMT)."""

    name = ""
    types: tuple[str, ...] = ()
    capabilities: tuple[str, ...] = ()
    capability_scale = np.ones(2)
    speed_capability: int | None = None
    """Index of the capability a motor fault scales (a known fault reports it), None: no speed
    capability (PCP's are radii: a fault changes nothing a capability vector says)."""
    horizon = 0
    ticks_per_step = 0
    spawn_box = (0.0, 0.0, 0.0, 0.0)
    spawn_spacing = 0.3
    n_task_features = 0
    reward_terms: tuple[str, ...] = ()

    def obs_size(self) -> int:
        return 4 + len(self.types) + len(self.capabilities) + self.n_task_features

    def spawn_capacity(self) -> int:
        """The most robots the spawn area holds :attr:`spawn_spacing` apart, widened as far as
        :meth:`spawn` widens it (to :data:`SPAWN_X_LIMIT`)."""
        x0, x1, y0, y1 = self.spawn_box
        s = self.spawn_spacing
        while x1 + s <= SPAWN_X_LIMIT:
            x1 += s
        return _cells((x0, x1, y0, y1), s)

    def max_team_size(self) -> int:
        """The largest team this task takes (its robots must fit the spawn area)."""
        return self.spawn_capacity()

    def check_team_size(self, n_robots: int) -> None:
        """ValueError saying the largest team this task takes, why, and how to change it."""
        if n_robots > self.max_team_size():
            raise ValueError(self._too_large(int(n_robots)))

    def _too_large(self, n: int) -> str:
        return (
            f"{self.name} takes teams of at most {self.max_team_size()} robots, got {n}: robots start "
            f"{self.spawn_spacing} m apart in the spawn area (x from {self.spawn_box[0]} m, widened up to "
            f"{SPAWN_X_LIMIT} m; y [{self.spawn_box[2]}, {self.spawn_box[3]}] m), which holds "
            f"{self.spawn_capacity()}; a bigger team needs a smaller spawn_spacing (class {type(self).__name__})"
        )

    def spawn(self, rng: np.random.Generator, n: int, spacing: float | None = None) -> np.ndarray:
        """Start poses (n, 3): spread in the spawn area, random headings, centres at least
        ``spacing`` apart (default ``spawn_spacing``).

        A team too large for the spawn area (beyond the Robotarium's 20 robots) gets the area
        widened to the right, one spacing at a time, up to the far side of the arena.
        """
        x0, x1, y0, y1 = self.spawn_box
        s = self.spawn_spacing if spacing is None else spacing
        rows = int(np.floor((y1 - y0) / s) + 1)
        while int(np.floor((x1 - x0) / s) + 1) * rows < n and x1 + s <= SPAWN_X_LIMIT:
            x1 += s
        pts = _spread(rng, n, (x0, x1, y0, y1), s, f"{self.name} spawn area", "robots")
        return np.column_stack([pts, rng.uniform(-np.pi, np.pi, n)])

    def observe(
        self, state: dict, poses: np.ndarray, type_ids: np.ndarray, caps: np.ndarray, mask: np.ndarray
    ) -> np.ndarray:
        """Per-robot observations (B, N, D); padded slots are zeros.

        Layout: [x, y, cos θ, sin θ | type one-hot | capabilities / scale | task features].
        """
        onehot = np.eye(len(self.types))[type_ids]
        obs = np.concatenate(
            [
                heading_features(poses),
                onehot,
                caps / self.capability_scale,
                self.task_features(state, poses, type_ids, caps, mask),
            ],
            axis=-1,
        )
        return obs * mask[..., None]

    def task_features(self, state, poses, type_ids, caps, mask) -> np.ndarray:
        raise NotImplementedError

    def scripted_targets(self, state: dict, centres: np.ndarray, type_ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The scripted policy's target per robot (B, N, 2) and whether it has one (B, N)."""
        raise NotImplementedError

    def scripted_actions(
        self, state: dict, poses: np.ndarray, type_ids: np.ndarray, caps: np.ndarray, mask: np.ndarray
    ) -> np.ndarray:
        """Actions (B, N) of the scripted reference policy (padded slots: stay).

        It reads the full task state (prey positions, material left), which the learners do not
        get: a reference showing the task is solvable, and a policy for checking a Robotarium
        deployment end to end.
        """
        centres = poses[..., :2]
        target, ok = self.scripted_targets(state, centres, type_ids)
        return np.where(mask, toward(centres, target, self.step_lengths(caps), ok), 0)


class PredatorCapturePrey(_Task):
    """PCP: sensing robots find static prey, capture robots capture the sensed ones.

    State per env: prey positions (B, K, 2), sensed (B, K), captured (B, K), active (B, K). A
    prey becomes sensed (for good) when a sensing robot is within its sensing radius; a sensed
    prey is captured when a capture robot is within its capture radius.

    Prey per team (:meth:`prey_for`): K(N) = 6 for N <= 8 robots (the paper's 6: every U_train and
    U_test team), round(1.2 N) above (12 at 10 robots, 24 at 20), so prey per robot do not fall
    as teams grow; ``n_prey=K`` instead gives every team K prey (before the rule every team had
    6). Teams of one batch may differ in K: the arrays hold K_max prey slots (the count
    of the largest team the environment may get, :meth:`fit_teams`), and a slot past a team's K
    is *inactive*: ``active`` False, sensed and captured from the start, parked outside the arena
    (:attr:`parked`). Rewards, observations, the scripted policy, ``done`` and ``progress`` see
    active prey only; :meth:`global_features` keeps all K_max slots (a fixed length).
    """

    name = "pcp"
    types = ("sensing", "capture")
    capabilities = ("sensing_radius_m", "capture_radius_m")
    capability_scale = np.array([0.5, 0.5])
    horizon = 80
    ticks_per_step = 29
    step_m = 0.2
    spawn_box = (-1.4, -0.5, -0.85, 0.85)
    prey_box = (0.5, 1.4, -0.85, 0.85)
    prey_spacing = 0.2
    n_task_features = 5
    reward_terms = ("sensed", "captured", "time", "violation")
    reward_weights: ClassVar[dict] = {"sensed": 1.0, "captured": 5.0, "time": -0.05, "violation": -5.0}

    base_prey = 6
    """Prey of every team of up to :attr:`base_team` robots (the paper's 6)."""
    base_team = 8
    """The largest team the rule leaves at :attr:`base_prey` prey: U_test's (and the paper's) largest."""
    prey_per_robot = 1.2
    """Prey per robot above :attr:`base_team` (1.2 × 5 = the paper's 6 for its 5-robot teams)."""
    parked = (2.6, 0.0)
    """Where inactive prey slots sit, m: 1 m outside the arena, where no robot can be."""

    def __init__(self, n_prey: int | None = None):
        bad = isinstance(n_prey, bool) or not isinstance(n_prey, (int, np.integer)) or n_prey < 1
        if n_prey is not None and bad:
            raise ValueError(
                f"n_prey must be a positive integer (that many prey for every team) or None "
                f"(the rule K(N) of PredatorCapturePrey.prey_for), got {n_prey!r}"
            )
        self.n_prey = None if n_prey is None else int(n_prey)
        if self.n_prey is not None and self.n_prey > self.prey_capacity():
            raise ValueError(
                f"n_prey must be at most {self.prey_capacity()} (the prey that fit {self.prey_spacing} m "
                f"apart in the prey area {self.prey_box} m), got {n_prey!r}"
            )
        self.largest_team: int | None = None

    @classmethod
    def prey_for(cls, n_robots: int) -> int:
        """K(N): prey of a team of ``n_robots`` under the rule (:attr:`base_prey` up to
        :attr:`base_team` robots, else round(:attr:`prey_per_robot` · N))."""
        if n_robots <= cls.base_team:
            return cls.base_prey
        # 1.2 N in integers: 12 N is even, so 12 N / 10 is never halfway and +5 // 10 rounds it.
        return (round(10 * cls.prey_per_robot) * int(n_robots) + 5) // 10

    def prey_capacity(self) -> int:
        """The most prey the prey area holds :attr:`prey_spacing` apart."""
        return _cells(self.prey_box, self.prey_spacing)

    def max_team_size(self) -> int:
        """The largest team PCP takes: its robots fit the spawn area and its prey K(N) the prey area."""
        n = self.spawn_capacity()
        while n > 0 and self.team_prey(n) > self.prey_capacity():
            n -= 1
        return n

    def _too_large(self, n: int) -> str:
        if self.team_prey(n) <= self.prey_capacity():
            return super()._too_large(n)
        x0, x1, y0, y1 = self.prey_box
        rule = (
            f"every team has n_prey={self.n_prey}"
            if self.n_prey is not None
            else f"prey grow with the team, K(N) = round({self.prey_per_robot}·N) above {self.base_team} robots"
        )
        return (
            f"pcp takes teams of at most {self.max_team_size()} robots, got {n}: {rule}, so {self.team_prey(n)} "
            f"prey for {n}, and at most {self.prey_capacity()} fit {self.prey_spacing} m apart in the prey area "
            f"x [{x0}, {x1}] m, y [{y0}, {y1}] m; for a bigger team give every team fewer prey "
            f"(make_env(..., n_prey=K) with K <= {self.prey_capacity()}) or lower "
            f"PredatorCapturePrey.prey_per_robot"
        )

    def team_prey(self, n_robots: int) -> int:
        """Prey of a team of ``n_robots`` in this task: ``n_prey`` if fixed, else :meth:`prey_for`."""
        return self.n_prey if self.n_prey is not None else self.prey_for(n_robots)

    def fit_teams(self, largest: int) -> None:
        """Size the prey slots of later :meth:`new_state` calls for teams of up to ``largest`` robots
        (the environment's largest coalition; without it, the robot slots N of ``new_state``)."""
        self.largest_team = int(largest)

    def step_lengths(self, caps: np.ndarray) -> np.ndarray:
        """Waypoint step (B, N), m: fixed 0.2 m in PCP."""
        return np.full(caps.shape[:-1], self.step_m)

    def new_state(self, B: int, N: int) -> dict:
        """Task state of B environments with N robot slots: K_max prey slots each."""
        K = self.team_prey(self.largest_team if self.largest_team is not None else N)
        return {
            "prey": np.zeros((B, K, 2)),
            "sensed": np.zeros((B, K), bool),
            "captured": np.zeros((B, K), bool),
            "active": np.ones((B, K), bool),
        }

    def reserve(self, state: dict, n_robots: int) -> None:
        """Grow every environment's prey slots, in place in ``state``, to fit a team of
        ``n_robots`` (a team larger than the environment's largest coalition, passed to a reset);
        the added slots are inactive. The global state grows with them: a learner that reads it
        never meets such a team in training (its slots come from its training coalitions)."""
        k, slots = self.team_prey(n_robots), state["prey"].shape[1]
        if k <= slots:
            return
        B, extra = state["prey"].shape[0], k - slots
        state["prey"] = np.concatenate([state["prey"], np.broadcast_to(self.parked, (B, extra, 2))], axis=1)
        for key, value in (("sensed", True), ("captured", True), ("active", False)):
            state[key] = np.concatenate([state[key], np.full((B, extra), value)], axis=1)

    def reset_env(self, state: dict, b: int, rng: np.random.Generator, caps: np.ndarray) -> None:
        """Place env b's prey for its team (capabilities ``caps`` (n, 2): only n is used): K(n)
        active prey, the remaining slots inactive."""
        k, slots = self.team_prey(caps.shape[0]), state["prey"].shape[1]
        assert k <= slots, "reserve() the prey slots before resetting a larger team"
        inactive = np.arange(slots) >= k
        state["prey"][b, :k] = _spread(rng, k, self.prey_box, self.prey_spacing, "pcp prey area", "prey")
        state["prey"][b, k:] = self.parked
        state["active"][b] = ~inactive
        state["sensed"][b] = inactive
        state["captured"][b] = inactive

    def _within(self, state: dict, poses: np.ndarray, radius: np.ndarray, mask: np.ndarray) -> np.ndarray:
        """(B, N, K) robot i within radius_i of prey k (and a real robot)."""
        d = poses[:, :, None, :2] - state["prey"][:, None, :, :]
        return (d[..., 0] ** 2 + d[..., 1] ** 2 <= radius[..., None] ** 2) & mask[..., None]

    def update(self, state: dict, poses: np.ndarray, type_ids: np.ndarray, caps: np.ndarray, mask: np.ndarray) -> dict:
        """Advance the task state after a step; returns the raw (unweighted) reward counts (B,)."""
        sensing = self._within(state, poses, caps[..., 0], mask & (type_ids == 0)).any(axis=1)
        new_sensed = sensing & ~state["sensed"] & ~state["captured"]
        state["sensed"] |= sensing
        capture = self._within(state, poses, caps[..., 1], mask & (type_ids == 1)).any(axis=1)
        new_captured = capture & state["sensed"] & ~state["captured"]
        state["captured"] |= new_captured
        return {"sensed": new_sensed.sum(axis=1).astype(float), "captured": new_captured.sum(axis=1).astype(float)}

    def done(self, state: dict) -> np.ndarray:
        return state["captured"].all(axis=1)

    def progress(self, state: dict) -> np.ndarray:
        """Fraction of the active prey captured (B,)."""
        return self._fraction(state["captured"], state)

    @staticmethod
    def _fraction(flags: np.ndarray, state: dict) -> np.ndarray:
        """(B,) share of the active prey whose flag (B, K) is set."""
        return (flags & state["active"]).sum(axis=1) / state["active"].sum(axis=1)

    def task_features(self, state, poses, type_ids, caps, mask) -> np.ndarray:
        """[seen, dx, dy] to the nearest uncaptured prey inside the robot's own sensing radius
        (only sensing robots see prey), then the team's fractions of its (active) prey sensed and
        captured. Inactive slots count as captured, so no robot ever sees one."""
        d = state["prey"][:, None, :, :] - poses[:, :, None, :2]  # (B, N, K, 2)
        dist2 = d[..., 0] ** 2 + d[..., 1] ** 2
        visible = (dist2 <= caps[..., 0:1] ** 2) & ~state["captured"][:, None, :] & (type_ids == 0)[..., None]
        dist2 = np.where(visible, dist2, np.inf)
        k = np.argmin(dist2, axis=-1)
        seen = np.isfinite(np.take_along_axis(dist2, k[..., None], -1))[..., 0]
        near = np.take_along_axis(d, k[..., None, None], 2)[..., 0, :] * seen[..., None]
        _B, N = mask.shape
        progress = np.stack([self._fraction(state["sensed"], state), self._fraction(state["captured"], state)], -1)[
            :, None, :
        ].repeat(N, 1)
        return np.concatenate([seen[..., None].astype(float), near, progress], axis=-1)

    def scripted_targets(self, state: dict, centres: np.ndarray, type_ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Sensing robots: the nearest prey nobody has sensed yet; capture robots: the nearest
        sensed, uncaptured prey; either, when it has none: the nearest uncaptured prey (to be
        close when it is sensed). Inactive slots are captured: never a target."""
        B, N = type_ids.shape
        K = state["prey"].shape[1]
        open_prey = ~state["captured"]
        sensing = (type_ids == 0)[..., None]
        t_sense, ok_sense = _nearest(
            centres, state["prey"], np.broadcast_to((~state["sensed"] & open_prey)[:, None], (B, N, K))
        )
        t_capture, ok_capture = _nearest(
            centres, state["prey"], np.broadcast_to((state["sensed"] & open_prey)[:, None], (B, N, K))
        )
        t_any, ok_any = _nearest(centres, state["prey"], np.broadcast_to(open_prey[:, None], (B, N, K)))
        target = np.where(
            sensing, np.where(ok_sense[..., None], t_sense, t_any), np.where(ok_capture[..., None], t_capture, t_any)
        )
        ok = np.where(sensing[..., 0], ok_sense | ok_any, ok_capture | ok_any)
        return target, ok

    def global_features(self, state: dict) -> np.ndarray:
        """(B, 4 K_max) prey positions, sensed and captured flags of every slot (inactive slots:
        parked, sensed and captured; K_max = 6 for teams of up to 8 robots, as before the rule)."""
        return np.concatenate(
            [
                state["prey"].reshape(state["prey"].shape[0], -1),
                state["sensed"].astype(float),
                state["captured"].astype(float),
            ],
            axis=-1,
        )


ZONE1_CENTRE = (0.0, 0.0)
ZONE1_RADIUS = 0.35
ZONE2_X = 1.0
"""HMT material zone 2 is x > ZONE2_X; the drop-off is x < -ZONE2_X (MARBLER layout)."""


class MaterialTransport(_Task):
    """HMT: fast and slow robots carry material from two zones to the drop-off.

    State per env: material left in zone 1 (circle r = 0.35 m at the centre) and zone 2
    (x > 1.0 m), (B, 2), the initial amounts, and each robot's load (B, N). Amounts scale with
    the team: zone 1 holds 1.5x and zone 2 0.5x the team's total payload (two full team loads).
    An empty robot inside a zone with material loads min(payload, what is left) (zone 2 first);
    a loaded robot inside the drop-off (x < -1.0 m) unloads everything.
    """

    name = "hmt"
    types = ("fast", "slow")
    capabilities = ("speed_m", "payload")
    capability_scale = np.array([0.5, 20.0])
    speed_capability = 0
    horizon = 70
    ticks_per_step = 74
    spawn_box = (-1.45, -0.75, -0.85, 0.85)
    zone_factors = (1.5, 0.5)
    n_task_features = 7
    reward_terms = ("loaded", "unloaded", "time", "violation")
    reward_weights: ClassVar[dict] = {"loaded": 0.025, "unloaded": 0.075, "time": -0.1, "violation": -6.0}

    def step_lengths(self, caps: np.ndarray) -> np.ndarray:
        """Waypoint step (B, N), m: the robot's speed capability."""
        return caps[..., 0]

    def new_state(self, B: int, N: int) -> dict:
        return {
            "left": np.zeros((B, 2)),
            "initial": np.ones((B, 2)),
            "load": np.zeros((B, N)),
            "delivered": np.zeros(B),
        }

    def reset_env(self, state: dict, b: int, rng: np.random.Generator, caps: np.ndarray) -> None:
        total = float(caps[:, 1].sum())
        state["initial"][b] = np.array(self.zone_factors) * total
        state["left"][b] = state["initial"][b]
        state["load"][b] = 0.0
        state["delivered"][b] = 0.0

    @staticmethod
    def zones(poses: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(B, N) robot centre in zone 1, zone 2, drop-off."""
        x, y = poses[..., 0], poses[..., 1]
        z1 = (x - ZONE1_CENTRE[0]) ** 2 + (y - ZONE1_CENTRE[1]) ** 2 <= ZONE1_RADIUS**2
        return z1, x >= ZONE2_X, x <= -ZONE2_X

    def update(self, state: dict, poses: np.ndarray, type_ids: np.ndarray, caps: np.ndarray, mask: np.ndarray) -> dict:
        z1, z2, drop = self.zones(poses)
        load, left = state["load"], state["left"]
        unload = np.where(drop & mask & (load > 0), load, 0.0)
        load -= unload
        state["delivered"] += unload.sum(axis=1)
        loaded = np.zeros_like(load)
        # Robots load one after another (robot order), zone 2 checked first, as in MARBLER.
        for i in range(load.shape[1]):
            empty = mask[:, i] & (load[:, i] <= 0)
            for z, inside in ((1, z2[:, i]), (0, z1[:, i])):
                take = np.where(empty & inside & (left[:, z] > 0), np.minimum(caps[:, i, 1], left[:, z]), 0.0)
                left[:, z] -= take
                loaded[:, i] += take
                empty &= take <= 0
        load += loaded
        # unloaded_by_robot (B, N): who delivered what (per-robot diagnostics; not a reward term)
        return {"loaded": loaded.sum(axis=1), "unloaded": unload.sum(axis=1), "unloaded_by_robot": unload}

    def done(self, state: dict) -> np.ndarray:
        return state["delivered"] >= state["initial"].sum(axis=1) * (1.0 - 1e-12)

    def progress(self, state: dict) -> np.ndarray:
        """Fraction of the material delivered (B,)."""
        return state["delivered"] / state["initial"].sum(axis=1)

    def task_features(self, state, poses, type_ids, caps, mask) -> np.ndarray:
        """[own load / payload, zone 1 and zone 2 fraction left, vector to zone 1's centre (2),
        x-distance to zone 2's edge, x-distance to the drop-off's edge]."""
        B, N = mask.shape
        frac = state["left"] / np.maximum(state["initial"], 1e-9)
        load = state["load"] / np.maximum(caps[..., 1], 1e-9)
        x, y = poses[..., 0], poses[..., 1]
        return np.stack(
            [
                load,
                *np.broadcast_to(frac[:, None, :], (B, N, 2)).transpose(2, 0, 1),
                ZONE1_CENTRE[0] - x,
                ZONE1_CENTRE[1] - y,
                ZONE2_X - x,
                -ZONE2_X - x,
            ],
            axis=-1,
        )

    def scripted_targets(self, state: dict, centres: np.ndarray, type_ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """A loaded robot: the drop-off; an empty one: a zone with material, fast robots
        preferring zone 2 (far, smaller) and slow robots zone 1 (near, larger)."""
        left = state["left"]  # (B, 2)
        loaded = state["load"] > 0
        y = np.clip(centres[..., 1], -0.8, 0.8)
        drop = np.stack([np.full_like(y, -ZONE2_X - 0.25), y], -1)
        zone1 = np.broadcast_to(np.array(ZONE1_CENTRE), centres.shape)
        zone2 = np.stack([np.full_like(y, ZONE2_X + 0.25), y], -1)
        has1, has2 = (left[:, 0] > 0)[:, None], (left[:, 1] > 0)[:, None]
        prefer2 = np.where(type_ids == 0, has2, has2 & ~has1)
        empty_target = np.where((prefer2 | (has2 & ~has1))[..., None], zone2, zone1)
        return np.where(loaded[..., None], drop, empty_target), loaded | has1 | has2

    state_amount_scale = 160.0
    """Material units per 1.0 in :meth:`global_features`: eight robots' loads at the payload
    scale (8 × 20). Raw amounts reach ~155; centralized critics and QMIX's mixer take the state
    unnormalized, and MAPPO's critic diverged on raw amounts (results/README.md)."""

    def global_features(self, state: dict) -> np.ndarray:
        """(B, 4) material left and initial per zone, in units of :attr:`state_amount_scale`."""
        return np.concatenate([state["left"], state["initial"]], axis=-1) / self.state_amount_scale


PCP = PredatorCapturePrey
HMT = MaterialTransport
