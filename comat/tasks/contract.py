"""A task is a contract: :func:`check_task` runs a task-logic class through what every command
expects of it, and says in one line what it breaks.

It checks, in this order:

1. the class: every required hook (:data:`comat.task_logic.REQUIRED_HOOKS`), its composition sets
   (as registration checks them), its attributes (a positive horizon and ticks per step, one
   capability scale per capability, a weight for every reward term, a constant action that is one);
2. a batch of B teams, one per size of :data:`CHECK_SIZES` (raised to the types a team needs,
   capped at the largest team the task takes), each drawn from one set's bands
   (:data:`CHECK_SETS` in turn), started in the task's spawn area and reset, then stepped with
   every rung of the reference ladder (:data:`comat.tasks.LADDER`: the scripted planner, it with its
   types' mean capabilities, the blind twin, the constant action, random actions) for the
   task's horizon, an env starting a new episode when its last one ends. At every step: the
   observations are (B, N, ``obs_size()``) and finite; the actions (B, N) whole numbers in 0-4, stay
   in padded slots; the waypoint steps (B, N) finite and >= 0; ``update`` gives a finite (B,) value
   for every task reward term, so that the reward (the sum of the weighted terms, as the env
   reports them) is finite; ``done`` is (B,) bool; ``progress`` (B,) in [0, 1];
   ``global_features`` (B, G) finite with G fixed in the batch; ``coordination`` None or (B,)
   finite; under the scripted planner, what every env draws (``marks``: the drawing hooks) comes out;
3. determinism: every rung run a second time from the same seed gives the same observations,
   actions, reward terms, progress and done flags, bit for bit;
4. the export round trip: each env's ``layout``, through JSON, put back with ``set_layout`` (and
   ``set_starts``) into a fresh task built as an exported script builds it (``layout_options``,
   ``new_state(1, n)``, ``reset_env`` with another generator) gives the same episode under the
   scripted planner: its observations, actions, reward terms, progress and done.

The robots move as an ideal world moves them: each reaches its waypoint (one waypoint step along
its action, :func:`comat.task_logic.waypoint_goals`), facing the way it went. No physics, filter or
contacts (numpy only, a second or so a task): the MuJoCo environments run the same hooks (``comat eval
--policy heuristic --task NAME`` runs the ladder there).
"""

from __future__ import annotations

import copy
import hashlib
import json

import numpy as np

from comat.task_logic import Marks, TaskLogic, waypoint_goals
from comat.tasks import LADDER, entry_of

__all__ = ["CHECK_SETS", "CHECK_SIZES", "TaskCheckError", "check_task"]

CHECK_SIZES = (2, 3, 5, 8)
"""The team sizes of the batch (one team each)."""
CHECK_SETS = ("train", "test", "capability")
"""The sets whose bands the teams' capabilities are drawn from, in turn."""
ENV_TERMS = ("time", "violation")
"""Reward terms the env counts itself (1 per step; 1 in a step with a safety violation: none here)."""
ROUND_TRIP_TOL = 1e-9
"""Absolute and relative tolerance of the export round trip's float comparisons (a batch of B
envs and the exported batch of one may round sums differently)."""


class TaskCheckError(ValueError):
    """What a task breaks of its contract, in one line (:func:`check_task`)."""


def check_task(task, seed: int = 0, steps: int | None = None) -> dict[str, float]:
    """Run ``task`` (a task-logic class, or an instance with options of its own) through its contract
    (module docstring). ``steps``: env steps per rung (default: the horizon). Returns each rung's
    mean progress over the batch's first episodes; raises :class:`TaskCheckError`, one line, at the
    first thing broken."""
    cls = task if isinstance(task, type) else type(task)
    where = f"check_task({getattr(cls, '__name__', cls)!r})"
    try:
        entry = entry_of(cls, getattr(cls, "title", "") or getattr(cls, "__name__", ""))
    except (ValueError, TypeError) as err:
        raise TaskCheckError(f"{where}: {err}") from err

    def make() -> TaskLogic:
        return cls() if isinstance(task, type) else copy.deepcopy(task)

    proto = _call(where, "the class's constructor", make)
    _check_attributes(where, proto)
    teams = _draw_teams(where, proto, entry, seed)
    steps = proto.horizon if steps is None else int(steps)
    means = {}
    for rung in LADDER:
        first = _Run(where, make, entry, teams, seed, rung)
        first.play(steps)
        second = _Run(where, make, entry, teams, seed, rung)
        second.play(steps)
        for k, (a, b) in enumerate(zip(first.digests, second.digests)):
            if a != b:
                raise TaskCheckError(
                    f"{where}: not deterministic: rung {rung!r} run twice from seed {seed} differs at step {k} "
                    f"(randomness only through the rng reset_env is given)"
                )
        means[rung] = float(np.mean(first.first_progress))
    return means


# -- the class ------------------------------------------------------------------------------------
def _check_attributes(where: str, task: TaskLogic) -> None:
    def need(ok: bool, what: str) -> None:
        if not ok:
            raise TaskCheckError(f"{where}: {what}")

    C = len(task.capabilities)
    need(
        isinstance(task.horizon, (int, np.integer)) and task.horizon >= 1,
        f"horizon must be a positive integer, got {task.horizon!r}",
    )
    need(
        isinstance(task.ticks_per_step, (int, np.integer)) and task.ticks_per_step >= 1,
        f"ticks_per_step must be a positive integer, got {task.ticks_per_step!r}",
    )
    need(
        np.shape(task.capability_scale) == (C,) and bool(np.all(np.asarray(task.capability_scale) > 0)),
        f"capability_scale must be {C} positive value(s), one per capability {task.capabilities}, "
        f"got {task.capability_scale!r}",
    )
    weights = getattr(task, "reward_weights", {})
    unweighted = [t for t in task.reward_terms if t not in weights]
    need(
        not unweighted, f"reward_weights must give every reward term {task.reward_terms} a weight; missing {unweighted}"
    )
    need(
        task.best_constant_action in range(5),
        f"best_constant_action must be an action 0-4, got {task.best_constant_action!r}",
    )
    need(
        task.speed_capability is None or task.speed_capability in range(C),
        f"speed_capability must be None or a capability index 0-{C - 1}, got {task.speed_capability!r}",
    )


def _band_draw(rng: np.random.Generator, bands) -> float:
    """A value uniform over the union of ``bands`` (a band drawn in proportion to its width)."""
    widths = np.array([hi - lo for lo, hi in bands], dtype=float)
    k = int(rng.choice(len(bands), p=widths / widths.sum())) if widths.sum() > 0 else 0
    return float(rng.uniform(*bands[k]))


def _band_mean(bands) -> float:
    """The mean of :func:`_band_draw` over ``bands`` (what the type_only rung believes)."""
    widths = np.array([hi - lo for lo, hi in bands], dtype=float)
    mids = np.array([(lo + hi) / 2 for lo, hi in bands], dtype=float)
    return float(mids.mean() if widths.sum() <= 0 else (widths * mids).sum() / widths.sum())


def _draw_teams(where: str, task: TaskLogic, entry, seed: int) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """(set, type ids (n,), capabilities (n, C)) per team: one of each type in order while there is
    room, then types at random; each capability from its type's bands in the set."""
    kinds = entry.types
    largest = _call(where, "max_team_size", task.max_team_size)
    sizes = sorted({min(max(s, len(kinds.needed)), largest) for s in CHECK_SIZES})
    rng = np.random.default_rng([seed, 64])
    teams = []
    for i, n in enumerate(sizes):
        split = CHECK_SETS[i % len(CHECK_SETS)]
        first = np.arange(min(n, len(kinds.types)))
        type_ids = np.concatenate([first, rng.integers(0, len(kinds.types), n - first.size)])
        caps = np.array(
            [[_band_draw(rng, b) for b in entry.bands[split][kinds.types[t]]] for t in type_ids], dtype=float
        ).reshape(n, len(kinds.capabilities))
        teams.append((split, type_ids.astype(np.int64), caps))
    return teams


# -- a batch of teams, one rung ----------------------------------------------------------------------
def _call(where: str, what: str, fn, *args):
    """``fn(*args)``; whatever it raises, said in one line naming the hook."""
    try:
        return fn(*args)
    except TaskCheckError:
        raise
    except Exception as err:  # a task's own bug, said in one line with the hook
        raise TaskCheckError(f"{where}: {what} raised {type(err).__name__}: {' '.join(str(err).split())}") from err


class _Run:
    """B envs of a fresh task (one per team, N = the largest team's slots), played by one rung
    under ideal kinematics; ``digests``: one per step of everything the env would report."""

    def __init__(self, where: str, make, entry, teams, seed: int, rung: str) -> None:
        self.where, self.rung, self.entry, self.seed = where, rung, entry, seed
        self.task = task = make()
        B, N = len(teams), max(t[1].size for t in teams)
        self.B, self.N = B, N
        self.splits = [t[0] for t in teams]
        self.mask = np.arange(N)[None, :] < np.array([t[1].size for t in teams])[:, None]
        self.type_ids = np.zeros((B, N), np.int64)
        self.caps = np.zeros((B, N, len(task.capabilities)))
        for b, (_, ids, caps) in enumerate(teams):
            self.type_ids[b, : ids.size], self.caps[b, : ids.size] = ids, caps
        self.rngs = [np.random.default_rng([seed, b]) for b in range(B)]
        self.act_rng = np.random.default_rng([seed, 99])
        self.where_now = "reset"
        self._hook("check_team_size", task.check_team_size, N)
        if hasattr(task, "fit_teams"):
            self._hook("fit_teams", task.fit_teams, N)
        self.state = self._hook("new_state", task.new_state, B, N)
        if not isinstance(self.state, dict):
            self._fail(f"new_state must return a dict of arrays, got {type(self.state).__name__}")
        if hasattr(task, "reserve"):
            self._hook("reserve", task.reserve, self.state, N)
        self.poses = np.zeros((B, N, 3))
        self.steps = np.zeros(B, np.int64)
        self.episode = np.zeros(B, np.int64)
        self.first_progress = np.zeros(B)
        self.digests: list[str] = []
        self.coordination_kind: str | None = None
        self.global_width: int | None = None
        self.twins: dict[int, tuple[TaskLogic, dict]] = {}
        for b in range(B):
            self._reset(b)

    # -- plumbing --
    def _fail(self, what: str):
        raise TaskCheckError(f"{self.where}: {what} ({self.where_now})")

    def _hook(self, name: str, fn, *args):
        return _call(self.where, f"{name} ({self.where_now})", fn, *args)

    def _array(self, name: str, value, shape: tuple, finite: bool = True) -> np.ndarray:
        arr = np.asarray(value)
        if arr.shape != shape:
            self._fail(f"{name} must have shape {shape}, got {arr.shape}")
        if finite and not np.all(np.isfinite(arr)):
            self._fail(f"{name} must be finite, got {arr[~np.isfinite(arr)][:3].tolist()}")
        return arr

    # -- episodes --
    def _reset(self, b: int) -> None:
        task, n = self.task, int(self.mask[b].sum())
        self.where_now = f"rung {self.rung!r}, env {b} ({n} robots, set {self.splits[b]!r}), reset"
        rng = self.rngs[b]
        starts = np.asarray(self._hook("spawn", task.spawn, rng, n), dtype=float)
        self._array("spawn", starts, (n, 3))
        caps = self.caps[b, :n]
        if task.reset_uses_starts:
            self._hook("reset_env", task.reset_env, self.state, b, rng, caps, starts)
        else:
            self._hook("reset_env", task.reset_env, self.state, b, rng, caps)
        self.poses[b] = 0.0
        self.poses[b, :n] = starts
        self.steps[b] = 0
        if self.rung == LADDER[0] and self.episode[b] == 0:
            self.twins[b] = self._twin(b, starts)

    def _twin(self, b: int, starts: np.ndarray) -> tuple[TaskLogic, dict]:
        """Env ``b``'s episode as an exported script rebuilds it from its layout (module docstring)."""
        task, n = self.task, starts.shape[0]
        layout = self._hook("layout", task.layout, self.state, b)
        if not isinstance(layout, dict):
            self._fail(f"layout must return a dict, got {type(layout).__name__}")
        try:
            layout = json.loads(json.dumps(layout))
        except (TypeError, ValueError) as err:
            self._fail(f"layout must be plain JSON (lists, numbers, strings), got {' '.join(str(err).split())}")
        cls = type(task)
        options = self._hook("layout_options", cls.layout_options, layout)
        twin = self._hook(f"{cls.__name__}(**layout_options(layout))", lambda: cls(**options))
        state = self._hook("new_state", twin.new_state, 1, n)
        self._hook("reset_env", twin.reset_env, state, 0, np.random.default_rng([self.seed, 7, b]), self.caps[b, :n])
        self._hook("set_layout", twin.set_layout, state, 0, layout)
        self._hook("set_starts", twin.set_starts, state, 0, starts.copy())
        return twin, state

    def _actions(self, poses: np.ndarray) -> np.ndarray:
        task, args = self.task, (self.state, poses, self.type_ids, self.caps, self.mask)
        if self.rung == "heuristic":
            return self._hook("scripted_actions", task.scripted_actions, *args)
        if self.rung == "type_only":
            bands = self.entry.bands
            means = np.zeros_like(self.caps)
            for b, split in enumerate(self.splits):
                table = np.array([[_band_mean(c) for c in bands[split][t]] for t in self.entry.types.types])
                means[b] = table.reshape(len(self.entry.types.types), -1)[self.type_ids[b]]
            believed = np.where(self.mask[..., None], means, 0.0)
            return self._hook(
                "scripted_actions", task.scripted_actions, self.state, poses, self.type_ids, believed, self.mask
            )
        if self.rung == "blind":
            return self._hook("blind_scripted_actions", task.blind_scripted_actions, *args)
        if self.rung == "constant":
            return np.where(self.mask, task.best_constant_action, 0)
        return np.where(self.mask, self.act_rng.integers(0, 5, self.mask.shape), 0)

    def play(self, steps: int) -> None:
        task, B, N = self.task, self.B, self.N
        for k in range(steps):
            self.where_now = f"rung {self.rung!r}, step {k}"
            poses = self.poses.copy()
            obs = self._array(
                "observe",
                self._hook("observe", task.observe, self.state, poses, self.type_ids, self.caps, self.mask),
                (B, N, task.obs_size()),
            )
            centre = np.asarray(self._hook("global_features", task.global_features, self.state))
            if centre.ndim != 2 or centre.shape[0] != B or not np.all(np.isfinite(centre)):
                self._fail(f"global_features must be finite with shape (B, G) = ({B}, G), got shape {centre.shape}")
            if self.global_width not in (None, centre.shape[1]):
                self._fail(f"global_features' width G changed from {self.global_width} to {centre.shape[1]} in a batch")
            self.global_width = centre.shape[1]
            actions = np.asarray(self._actions(poses))
            self._check_actions(actions)
            step = self._array(
                "step_lengths_at",
                self._hook("step_lengths_at", task.step_lengths_at, self.caps, poses, self.state),
                (B, N),
            )
            if np.any(step[self.mask] < 0):
                self._fail(f"step_lengths_at must be >= 0 m, got {step[self.mask].min():g}")
            self._twins_before(poses, obs, actions)
            self._move(actions, step)
            raw = self._hook("update", task.update, self.state, self.poses, self.type_ids, self.caps, self.mask)
            terms = self._terms(raw)
            done = self._array("done", self._hook("done", task.done, self.state), (B,))
            if done.dtype != bool:
                self._fail(f"done must be bool, got {done.dtype}")
            progress = self._array("progress", self._hook("progress", task.progress, self.state), (B,)).astype(float)
            if np.any(progress < -1e-12) or np.any(progress > 1 + 1e-12):
                self._fail(f"progress must lie in [0, 1], got {progress.min():g} to {progress.max():g}")
            self._check_coordination()
            if self.rung == LADDER[0]:
                self._check_marks()
            self._twins_after(raw, progress, done)
            digest = hashlib.sha256()
            for part in (obs, actions.astype(np.int64), *(terms[t] for t in sorted(terms)), progress, done):
                digest.update(np.ascontiguousarray(part).tobytes())
            self.digests.append(digest.hexdigest())
            self.steps += 1
            for b in np.flatnonzero(done | (self.steps >= task.horizon)):
                if self.episode[b] == 0:
                    self.first_progress[b] = progress[b]
                self.twins.pop(int(b), None)
                self.episode[b] += 1
                self._reset(int(b))
        unfinished = self.episode == 0
        if unfinished.any():
            self.first_progress[unfinished] = np.asarray(task.progress(self.state), float)[unfinished]

    def _check_actions(self, actions: np.ndarray) -> None:
        if actions.shape != self.mask.shape:
            self._fail(f"actions must have shape (B, N) = {self.mask.shape}, got {actions.shape}")
        if not np.issubdtype(actions.dtype, np.integer):
            self._fail(f"actions must be whole numbers (an integer dtype), got {actions.dtype}")
        if np.any((actions < 0) | (actions > 4)):
            bad = sorted(set(actions.ravel().tolist()) - set(range(5)))[:5]
            self._fail(f"actions must be 0-4 (stay, +x, -x, +y, -y), got {bad}")
        if np.any(actions[~self.mask] != 0):
            self._fail("actions of padded slots must be 0 (stay)")

    def _move(self, actions: np.ndarray, step: np.ndarray) -> None:
        """Each real robot reaches its waypoint, facing the way it went (a robot that stays keeps its heading)."""
        xy = self.poses[..., :2]
        goals = waypoint_goals(xy, actions, step)
        d = goals - xy
        moved = self.mask & (np.hypot(d[..., 0], d[..., 1]) > 1e-12)
        self.poses[..., 2] = np.where(moved, np.arctan2(d[..., 1], d[..., 0]), self.poses[..., 2])
        self.poses[..., :2] = np.where(self.mask[..., None], goals, 0.0)

    def _terms(self, raw) -> dict[str, np.ndarray]:
        """The weighted reward terms (B,) the env would report: the task's from ``raw``, ``time`` 1,
        ``violation`` 0; their sum, the reward, must be finite."""
        if not isinstance(raw, dict):
            self._fail(f"update must return a dict of raw reward terms, got {type(raw).__name__}")
        task, B = self.task, self.B
        counted = {"time": np.ones(B), "violation": np.zeros(B)}
        terms = {}
        for name in task.reward_terms:
            if name in ENV_TERMS:
                value = counted[name]
            elif name not in raw:
                own = [t for t in task.reward_terms if t not in ENV_TERMS]
                self._fail(f"update must return every task reward term {own}; missing {name!r}")
            else:
                value = self._array(f"update's term {name!r}", raw[name], (B,)).astype(float)
            terms[name] = task.reward_weights[name] * value
        reward = sum(terms.values(), np.zeros(B))
        if not np.all(np.isfinite(reward)):
            self._fail("the reward (the sum of the weighted terms) must be finite")
        return terms

    def _check_coordination(self) -> None:
        task = self.task
        value = self._hook(
            "coordination", task.coordination, self.state, self.poses, self.type_ids, self.caps, self.mask
        )
        kind = "none" if value is None else "array"
        if self.coordination_kind is None:
            self.coordination_kind = kind
        elif kind != self.coordination_kind:
            self._fail("coordination must return None always or a (B,) array always")
        if value is not None:
            self._array("coordination", value, (self.B,))

    def _check_marks(self) -> None:
        """What each env draws now (frames, Rerun, the exported figure): it must come out."""
        for b in range(self.B):
            n = int(self.mask[b].sum())
            marks = self._hook(
                f"marks (env {b}: the drawing hooks areas, items, rings, bar, counters)",
                self.task.marks,
                self.state,
                b,
                self.caps[b, :n],
                self.type_ids[b, :n],
            )
            if not isinstance(marks, Marks):
                self._fail(f"marks must return comat.task_logic.Marks, got {type(marks).__name__}")

    # -- the export round trip --
    def _twins_before(self, poses: np.ndarray, obs: np.ndarray, actions: np.ndarray) -> None:
        """Every exported twin's observations and scripted actions at its env's poses, compared."""
        for b, (twin, state) in self.twins.items():
            n = int(self.mask[b].sum())
            args = (
                state,
                poses[b : b + 1, :n],
                self.type_ids[b : b + 1, :n],
                self.caps[b : b + 1, :n],
                self.mask[b : b + 1, :n],
            )
            seen = self._hook("the exported twin's observe", twin.observe, *args)
            acts = self._hook("the exported twin's scripted_actions", twin.scripted_actions, *args)
            self._same(b, "observations", obs[b, :n], np.asarray(seen)[0])
            self._same(b, "scripted actions", actions[b, :n], np.asarray(acts)[0])

    def _twins_after(self, raw: dict, progress: np.ndarray, done: np.ndarray) -> None:
        """Every exported twin updated at its env's new poses; its reward terms, progress and done compared."""
        for b, (twin, state) in self.twins.items():
            n = int(self.mask[b].sum())
            args = (
                state,
                self.poses[b : b + 1, :n],
                self.type_ids[b : b + 1, :n],
                self.caps[b : b + 1, :n],
                self.mask[b : b + 1, :n],
            )
            theirs = self._hook("the exported twin's update", twin.update, *args)
            for name in self.task.reward_terms:
                if name not in ENV_TERMS:
                    self._same(
                        b, f"reward term {name!r}", np.asarray(raw[name])[b], np.asarray(theirs.get(name, np.nan))[0]
                    )
            self._same(
                b,
                "progress",
                progress[b],
                np.asarray(self._hook("the exported twin's progress", twin.progress, state))[0],
            )
            self._same(b, "done flag", done[b], np.asarray(self._hook("the exported twin's done", twin.done, state))[0])

    def _same(self, b: int, what: str, mine, theirs) -> None:
        a, c = np.asarray(mine, float), np.asarray(theirs, float)
        if a.shape != c.shape or not np.allclose(a, c, rtol=ROUND_TRIP_TOL, atol=ROUND_TRIP_TOL):
            self._fail(
                f"the export round trip gives another episode: env {b}'s {what} differ from those of a fresh task "
                "given its layout (layout -> set_layout, set_starts): does layout carry all that reset_env drew?"
            )
