"""What every task's logic shares, in plain numpy: the arena, the discrete waypoint actions, the
:class:`TaskLogic` base class (spawn, observations, the scripted policy's shape) and the marks a
task draws (:class:`Marks`: its areas, items, capability rings and bars, counters and legend).

Each task's own logic is a module of :mod:`comat.tasks` (``comat/tasks/pcp.py``, ``hmt.py``, …)
built on this one. Both import numpy only, on purpose: the MuJoCo environments (``comat.envs``)
and the exported Robotarium script (``sim2real``) run these same files, so the two cannot drift.
Arrays are batched over B environments with robots padded to N slots: ``mask`` (B, N) marks real
robots; poses (B, N, 3); capabilities (B, N, C); type ids (B, N).
"""

from __future__ import annotations

from abc import ABCMeta, abstractmethod
from dataclasses import dataclass, field
from typing import ClassVar, Tuple  # noqa: UP035 (the Robotarium imports this file on Python 3.8)

import numpy as np

__all__ = [
    "ACTIONS",
    "ACTION_NAMES",
    "ARENA",
    "REQUIRED_HOOKS",
    "Area",
    "Bar",
    "Items",
    "Marks",
    "Ring",
    "TaskLogic",
    "grid_cells",
    "grow_slots",
    "heading_features",
    "min_cost_assignment",
    "nearest",
    "spread_points",
    "toward",
    "waypoint_goals",
]

RGB = Tuple[int, int, int]  # noqa: UP006 (tuple[int, int, int] run at import fails on Python 3.8, where exports run)

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


def nearest(points: np.ndarray, candidates: np.ndarray, allowed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For points (B, N, 2), the nearest allowed candidate (B, K, 2) / allowed (B, N, K), and
    whether there was one (B, N)."""
    d = candidates[:, None, :, :] - points[:, :, None, :]
    dist = np.where(allowed, d[..., 0] ** 2 + d[..., 1] ** 2, np.inf)
    k = np.argmin(dist, axis=-1)
    target = np.take_along_axis(candidates[:, None, :, :].repeat(points.shape[1], 1), k[..., None, None], 2)[..., 0, :]
    return target, np.isfinite(np.take_along_axis(dist, k[..., None], -1))[..., 0]


def min_cost_assignment(cost: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows and columns of a least-cost assignment of the smaller side of ``cost`` (R, C) (the
    Hungarian method, O(n³), numpy over one axis: numpy only, so the export runs it too)."""
    flip = cost.shape[0] > cost.shape[1]
    a = cost.T if flip else cost
    n, m = a.shape
    u, v = np.zeros(n + 1), np.zeros(m + 1)
    p = np.zeros(m + 1, np.int64)  # p[j]: the row (1-based) matched to column j; 0: none
    way = np.zeros(m + 1, np.int64)
    for i in range(1, n + 1):
        p[0], j0 = i, 0
        minv = np.full(m + 1, np.inf)
        used = np.zeros(m + 1, bool)
        while True:
            used[j0] = True
            i0 = p[j0]
            cur = a[i0 - 1] - u[i0] - v[1:]
            free = ~used[1:]
            better = free & (cur < minv[1:])
            minv[1:][better] = cur[better]
            way[1:][better] = j0
            masked = np.where(free, minv[1:], np.inf)
            j1 = int(np.argmin(masked)) + 1
            delta = masked[j1 - 1]
            u[p[used]] += delta
            v[used] -= delta
            minv[1:][free] -= delta
            j0 = j1
            if p[j0] == 0:
                break
        while j0:
            j1 = way[j0]
            p[j0] = p[j1]
            j0 = j1
    cols = np.flatnonzero(p[1:])
    rows = p[1:][cols] - 1
    return (cols, rows) if flip else (rows, cols)


def grow_slots(state: dict, extra: int, fills: dict) -> None:
    """Append ``extra`` slots along axis 1 to each array ``state[key]`` (B, K, ...), filled with
    ``fills[key]`` (a scalar or a trailing-shape value, e.g. a parked position): how a task's
    per-env object slots grow for a larger team (``reserve``)."""
    for key, value in fills.items():
        old = state[key]
        new = np.broadcast_to(np.asarray(value, dtype=old.dtype), (old.shape[0], extra, *old.shape[2:]))
        state[key] = np.concatenate([old, new], axis=1)


def heading_features(poses: np.ndarray) -> np.ndarray:
    """(..., 4) pose features [x, y, cos θ, sin θ]."""
    return np.concatenate([poses[..., :2], np.cos(poses[..., 2:3]), np.sin(poses[..., 2:3])], axis=-1)


def grid_cells(box: tuple[float, float, float, float], spacing: float) -> int:
    """Points a box holds ``spacing`` apart on a grid (what :func:`spread_points` can always place)."""
    x0, x1, y0, y1 = box
    return int(np.floor((x1 - x0) / spacing) + 1) * int(np.floor((y1 - y0) / spacing) + 1)


def spread_points(
    rng: np.random.Generator, n: int, box: tuple[float, float, float, float], spacing: float, what: str, noun: str
) -> np.ndarray:
    """n points (n, 2) uniform in box, pairwise >= spacing apart (bounded rejection sampling)."""
    x0, x1, y0, y1 = box
    cells = grid_cells(box, spacing)
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


# -- what a task draws: one description for frames, Rerun recordings and the Robotarium figure --
@dataclass(frozen=True)
class Area:
    """A fixed region of a task (a zone, a spawn area), drawn under the robots.

    ``shape`` "box": ``geometry`` (x0, x1, y0, y1) m; "circle": (cx, cy, r) m. ``name`` is its
    entity (``world/zones/<name>``); ``label`` its text (:meth:`TaskLogic.area_labels` may
    replace it step by step, e.g. with what is left in it)."""

    name: str
    shape: str
    geometry: tuple[float, ...]
    color: RGB
    label: str


@dataclass(frozen=True)
class Items:
    """A task's objects now (prey, food, targets): positions (K, 2) m, a state index per item (K,)
    into ``states`` (its names) and ``colors``, a disc radius, optional per-item text."""

    name: str
    xy: np.ndarray
    status: np.ndarray
    states: tuple[str, ...]
    colors: tuple[RGB, ...]
    radius_m: float
    labels: tuple[str, ...] | None = None


@dataclass(frozen=True)
class Ring:
    """A circle of ``radius_m`` (n,) around the ``members`` (n,) robots: a capability's reach
    (PCP's sensing radius, a sensor's range); ``dotted`` for a reach rather than an area."""

    name: str
    members: np.ndarray
    radius_m: np.ndarray
    color: RGB
    label: str
    dotted: bool = False


@dataclass(frozen=True)
class Bar:
    """A bar above every robot, ``width_m`` (n,) wide and filled to ``fraction`` (n,) (HMT: the
    payload, filled to the load); entities ``capabilities/<name>`` and ``…/<fill_name>``."""

    name: str
    fill_name: str
    width_m: np.ndarray
    fraction: np.ndarray
    label: str


BAR_OFFSET_M = 0.1
"""A bar floats this far above the robot's centre."""
BAR_HEIGHT_M = 0.025
BAR_FILL: RGB = (230, 170, 20)
"""Colour of a bar's filled part."""


@dataclass(frozen=True)
class Marks:
    """Everything a task draws of one environment now (:meth:`TaskLogic.marks`)."""

    areas: tuple[Area, ...]
    area_labels: dict[str, str]
    items: Items | None
    rings: tuple[Ring, ...]
    bar: Bar | None
    counters: dict[str, float]
    status: str
    legend: tuple[tuple[str, RGB], ...] = field(default=())


REQUIRED_HOOKS = (
    "new_state",
    "reset_env",
    "update",
    "done",
    "progress",
    "step_lengths",
    "task_features",
    "global_features",
    "scripted_actions or scripted_targets",
    "blind_scripted_actions",
)
"""What every task implements (:meth:`TaskLogic.missing_hooks`; registration refuses a class that
lacks one). The scripted planner is either hook: the base's ``scripted_actions`` drives every robot
to the target ``scripted_targets`` gives it. Every other hook has a default."""


class TaskLogic(metaclass=ABCMeta):
    """The base of every task's logic (``comat/tasks/*.py``): class attributes say what the task is
    (``name``, ``types``, ``capabilities``, ``horizon``, ``ticks_per_step``, ``spawn_box``,
    ``reward_terms`` / ``reward_weights``, ``type_colors``); a task implements the hooks of
    :data:`REQUIRED_HOOKS` (``new_state``, ``reset_env``, ``update``, ``done``, ``progress``,
    ``step_lengths``, ``task_features``, ``global_features``, the scripted planner
    ``scripted_actions`` or ``scripted_targets``, and its blind twin ``blind_scripted_actions``),
    and draws itself through the hooks ``areas``, ``items``, ``rings``, ``bar``, ``counters`` (all
    optional). ``layout`` / ``set_layout`` carry what a reset drew at random into an export.
    :func:`comat.tasks.check_task` runs a class through this contract."""

    name = ""
    version = 0
    """The rules' version: the env id is ``<name>_v<version>``; a change of rules (what is observed,
    rewarded or counted, the ground, the sets' ranges) is a new version."""
    title = ""
    """For people: "Predator Capture Prey" (default: the class name)."""
    meant_for: tuple[str, ...] = ()
    """The questions the task is designed to ask (its spec sheet says why): ``"capability"`` (do
    capabilities beyond the type decide?) and/or ``"size"`` (unseen team sizes); ``comat validity``
    measures which it can (:mod:`comat.eval.validity`)."""
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

    @classmethod
    def missing_hooks(cls) -> list[str]:
        """The required hooks (:data:`REQUIRED_HOOKS`) this class does not implement, in that order."""
        abstract = getattr(cls, "__abstractmethods__", frozenset())
        no_planner = (
            cls.scripted_actions is TaskLogic.scripted_actions and cls.scripted_targets is TaskLogic.scripted_targets
        )
        return [
            hook
            for hook in REQUIRED_HOOKS
            if hook in abstract or (hook == "scripted_actions or scripted_targets" and no_planner)
        ]

    # -- the required hooks: state, dynamics, observations (arrays batched over B envs, N slots) --
    @abstractmethod
    def new_state(self, B: int, N: int) -> dict:
        """The task state of B environments with N robot slots each: a dict of arrays (B, ...)."""

    @abstractmethod
    def reset_env(self, state: dict, b: int, rng: np.random.Generator, caps: np.ndarray) -> None:
        """Start env ``b``'s episode in ``state`` for its team's capabilities (n, C), drawing only from
        ``rng`` (with ``reset_uses_starts``, a fifth argument: the team's start poses (n, 3))."""

    @abstractmethod
    def update(self, state: dict, poses: np.ndarray, type_ids: np.ndarray, caps: np.ndarray, mask: np.ndarray) -> dict:
        """One env step of the task's rules at the robots' true poses (B, N, 3): the raw value (B,) of
        every reward term but ``time`` and ``violation`` (the env counts those), by name."""

    @abstractmethod
    def done(self, state: dict) -> np.ndarray:
        """(B,) bool: the task is finished in each env."""

    @abstractmethod
    def progress(self, state: dict) -> np.ndarray:
        """(B,) the share of the task done in each env, in [0, 1]."""

    @abstractmethod
    def step_lengths(self, caps: np.ndarray) -> np.ndarray:
        """(B, N) each robot's waypoint step, m, from its capabilities (B, N, C)."""

    @abstractmethod
    def task_features(self, state, poses, type_ids, caps, mask) -> np.ndarray:
        """(B, N, n_task_features) what each robot observes of the task (the tail of :meth:`observe`)."""

    @abstractmethod
    def global_features(self, state: dict) -> np.ndarray:
        """(B, G) the task's part of the centralized state (critics that read the state)."""

    @abstractmethod
    def blind_scripted_actions(
        self, state: dict, poses: np.ndarray, type_ids: np.ndarray, caps: np.ndarray, mask: np.ndarray
    ) -> np.ndarray:
        """Actions (B, N) of the ladder's blind rung: the scripted plan made without the robots'
        types and capabilities (each task says how its plan reads without them; their motion, the
        waypoint step, stays theirs)."""

    def obs_size(self) -> int:
        return 4 + len(self.types) + len(self.capabilities) + self.n_task_features

    def spawn_capacity(self) -> int:
        """The most robots the spawn area holds :attr:`spawn_spacing` apart, widened as far as
        :meth:`spawn` widens it (to :data:`SPAWN_X_LIMIT`)."""
        x0, x1, y0, y1 = self.spawn_box
        s = self.spawn_spacing
        while x1 + s <= SPAWN_X_LIMIT:
            x1 += s
        return grid_cells((x0, x1, y0, y1), s)

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
        pts = spread_points(rng, n, (x0, x1, y0, y1), s, f"{self.name} spawn area", "robots")
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

    def step_lengths_at(self, caps: np.ndarray, poses: np.ndarray, state: dict) -> np.ndarray:
        """Waypoint step (B, N), m, of robots at ``poses`` (B, N, 3) now: :meth:`step_lengths`, unless a
        task's ground changes how far a robot gets (Arctic transport's ice and water)."""
        return self.step_lengths(caps)

    def scripted_targets(self, state: dict, centres: np.ndarray, type_ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The scripted policy's target per robot (B, N, 2) and whether it has one (B, N); a task whose
        planner overrides :meth:`scripted_actions` instead need not have it."""
        raise NotImplementedError(f"{type(self).__name__} has no scripted_targets (its scripted_actions plans)")

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
        return self.drive(state, poses, caps, mask, target, ok)

    def drive(self, state: dict, poses: np.ndarray, caps: np.ndarray, mask: np.ndarray, target, ok) -> np.ndarray:
        """Actions (B, N) taking each robot toward its ``target`` (B, N, 2) where ``ok`` (B, N), one
        waypoint step at a time (:func:`toward`); padded slots and robots without a target stay."""
        return np.where(mask, toward(poses[..., :2], target, self.step_lengths_at(caps, poses, state), ok), 0)

    best_constant_action = 1
    """The action every robot always takes in the "constant" reference row (measured for each task:
    comat.envs.heuristics.BEST_CONSTANT_ACTION; +x, toward the work, unless a task says otherwise)."""
    reset_uses_starts = False
    """True: ``reset_env`` takes the team's start poses (n, 3) as a fifth argument (navigation: goals
    within each robot's reach of its start)."""

    # -- drawing (optional hooks; every drawing backend reads them through marks()) ---------------
    type_colors: ClassVar[dict[str, RGB]] = {}
    """Robot colour per type (RGB); unknown types are grey."""
    counters_name = "task"
    """Name of the counters' series in a recording (``E/task/<counters_name>``)."""

    def areas(self, state: dict | None = None, b: int = 0) -> tuple[Area, ...]:
        """The task's regions (fixed, or drawn per episode from env ``b``'s ``state``: Arctic's ground)."""
        return ()

    def area_labels(self, state: dict, b: int) -> dict[str, str]:
        """Area name -> its label now, where it changes during an episode."""
        return {}

    def items(self, state: dict, b: int) -> Items | None:
        """Env ``b``'s objects now (copies), or None for a task without any."""
        return None

    def rings(self, caps: np.ndarray, type_ids: np.ndarray) -> tuple[Ring, ...]:
        """Capability circles of a team: caps (n, C), type ids (n,)."""
        return ()

    def bar(self, state: dict, b: int, caps: np.ndarray) -> Bar | None:
        """A bar per robot of env ``b`` (caps (n, C)), or None."""
        return None

    def counters(self, state: dict, b: int, n: int) -> dict[str, float]:
        """Named counts of env ``b`` now (its team has n robots): the status line and a series."""
        return {"progress": float(self.progress(state)[b])}

    def status_text(self, state: dict, b: int, counters: dict[str, float]) -> str:
        """One line of env ``b``'s counters for a frame's header."""
        return ", ".join(f"{k} {v:g}" for k, v in counters.items())

    def marks(self, state: dict, b: int, caps: np.ndarray, type_ids: np.ndarray) -> Marks:
        """What env ``b`` (its team's caps (n, C) and type ids (n,)) draws now."""
        n = caps.shape[0]
        items, rings, bar = self.items(state, b), self.rings(caps, type_ids), self.bar(state, b, caps)
        counters = self.counters(state, b, n)
        legend = [] if items is None else [(f"{items.name} {s}", c) for s, c in zip(items.states, items.colors)]
        legend += [(r.label, r.color) for r in rings] + ([(bar.label, BAR_FILL)] if bar is not None else [])
        return Marks(
            self.areas(state, b),
            self.area_labels(state, b),
            items,
            rings,
            bar,
            counters,
            self.status_text(state, b, counters),
            tuple(dict.fromkeys(legend)),
        )

    # -- diagnostics: what each robot did (comat.envs.diagnostics) -------------------------------
    robot_count_names: tuple[str, ...] = ("still_held", "still_idle")
    """Per-robot counters, in row order; ``still_held`` and ``still_idle`` are counted for every task."""
    end_count_names: tuple[str, ...] = ()

    def count_before(self, state: dict) -> dict:
        """What :meth:`count_robots` needs of the state before a step's update (copies)."""
        return {}

    def count_robots(self, before, raw, state, poses, type_ids, caps, mask) -> dict[str, np.ndarray]:
        """The task's own per-robot counts (B, N) of one env step."""
        return {}

    def end_counts(self, state: dict) -> dict[str, np.ndarray]:
        """Episode-level counts (B,) read from the state when an episode ends."""
        return {}

    # -- coordination: how well the team shares its work out (beside progress in eval and Rerun) --
    coordination_name = ""
    """The task's coordination metric in a few words for tables and recordings (e.g. "goals open,
    robots idle"); "" for a task without one."""
    coordination_doc = ""
    """One sentence for eval's footer: what :meth:`coordination` measures, its unit, which way is better."""

    def coordination(
        self, state: dict, poses: np.ndarray, type_ids: np.ndarray, caps: np.ndarray, mask: np.ndarray
    ) -> np.ndarray | None:
        """(B,) the coordination metric of every env now, after a step's update (true poses
        (B, N, 3)); None for a task without one. An episode's ``coordination`` is its mean over the
        episode's env steps."""
        return None

    # -- export: what a reset drew at random (PCP: the prey), so the Robotarium runs the same episode --
    def layout(self, state: dict, b: int) -> dict[str, list]:
        """Env ``b``'s random layout as plain lists (JSON); {} for a task whose reset draws nothing."""
        return {}

    def set_layout(self, state: dict, b: int, layout: dict[str, list]) -> None:
        """Put a :meth:`layout` back into env ``b`` (after its ``reset_env``)."""

    def set_starts(self, state: dict, b: int, starts: np.ndarray) -> None:
        """Tell env ``b``'s state where its robots start (n, 3), where an export or a twin places them
        elsewhere than the env's spawn; for a task whose state keeps them (``reset_uses_starts``)."""

    @classmethod
    def layout_options(cls, layout: dict[str, list]) -> dict:
        """The task options an export builds the task with to hold ``layout`` (PCP: ``n_prey``)."""
        return {}
