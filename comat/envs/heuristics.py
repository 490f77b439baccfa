"""The reference ladder: policies over a :class:`~comat.envs.core.TaskCore` that show each task is
solvable and measure what a task demands of its learners.

Rungs, from most to least informed (:data:`LADDER`; ``comat eval --policy RUNG``):

* ``heuristic`` — the *scripted* rung: the task's ``scripted_actions``, reading the full task state
  (prey positions, material left) and every robot's type and capabilities: privileged information
  the learners do not get. ``scripted`` is accepted as its other name.
* ``type_only`` — the same planner given every robot's *type* but not its capabilities: each robot's
  capabilities replaced by its type's mean over the set's ranges (:func:`type_mean_capabilities`).
  What the scripted rung gains over it is what continuous capabilities decide beyond the type.
  It learns only what the task's planner learns from what robots measure (a failed lift, a
  cluster seen short: warehouse, sensors), never the capabilities themselves.
* ``blind`` — the task's ``blind_scripted_actions``: the planner with neither types nor
  capabilities (each task says how its plan reads without them).
* ``constant`` — every robot always the task's ``best_constant_action``.
* ``random`` — uniformly random actions.

The task logic (numpy only) holds the planners, so the exported Robotarium script runs the same
code. Batched over B environments; padded slots get ``stay``.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from comat.envs.core import TaskCore
from comat.tasks import LADDER, RUNG_ALIASES, TASKS, task_entry

__all__ = [
    "BEST_CONSTANT_ACTION",
    "LADDER",
    "RUNG_ALIASES",
    "blind_actions",
    "has_blind",
    "heuristic_actions",
    "random_actions",
    "reference_policy",
    "type_mean_capabilities",
    "type_only_actions",
]


BEST_CONSTANT_ACTION = {name: entry.logic.best_constant_action for name, entry in TASKS.items()}
"""Per task registered when this module loaded, its ``best_constant_action``: an action (0 stay,
1 +x, 2 −x, 3 +y, 4 −y) that earns the highest return on U_train when every robot always takes
it (all five tried, one episode per coalition, the evaluation seed; tests/test_eval.py, slow
tier; where actions tie, as +x, +y and −y do on navigation_v1, the task names one of them). On
PCP it captures half the prey (return 16.4, 20 % of the episodes finished): early learning
curves must beat it to mean anything."""


def heuristic_actions(core: TaskCore) -> np.ndarray:
    """Actions (B, N) of the scripted policy for every environment of ``core``."""
    return core.task.scripted_actions(core.state, core.poses(), core.type_ids, core.caps, core.mask)


def band_mean(bands) -> float:
    """The mean of a value drawn uniformly over the union of ``bands`` ((low, high), ...): each band's
    midpoint weighted by its width (:mod:`comat.team` draws a band with probability proportional to
    its width); a band of width 0 (a capability the type lacks) is its value."""
    widths = np.array([hi - lo for lo, hi in bands], dtype=float)
    mids = np.array([(lo + hi) / 2 for lo, hi in bands], dtype=float)
    return float(mids.mean() if widths.sum() <= 0 else (widths * mids).sum() / widths.sum())


def type_mean_capabilities(task: str, split: str | None = None, teams=None) -> np.ndarray:
    """(T, C) each robot type's mean capabilities: over the bands set ``split`` draws them from
    (:attr:`comat.tasks.TaskEntry.bands`), or, for teams of one's own (``teams``: TeamSpecs, no
    ``split``), the mean over those teams' robots of each type (a type none of them has: its U_train
    mean). What the ``type_only`` rung believes every robot of a type has."""
    entry = task_entry(task)
    kinds = entry.types
    out = np.zeros((len(kinds.types), len(kinds.capabilities)))
    bands = entry.bands["train" if split is None else split]
    for t, kind in enumerate(kinds.types):
        out[t] = [band_mean(b) for b in bands[kind]]
    if split is None and teams:
        rows = [(r.type, r.capabilities) for team in teams for r in team.robots]
        for t, kind in enumerate(kinds.types):
            mine = [np.asarray(c, dtype=float) for k, c in rows if k == kind]
            if mine:
                out[t] = np.mean(mine, axis=0)
    return out


def type_only_actions(core: TaskCore, type_caps: np.ndarray) -> np.ndarray:
    """Actions (B, N) of the scripted planner believing every robot has its type's capabilities
    ``type_caps`` (T, C) (:func:`type_mean_capabilities`); the robots still move as they are."""
    believed = np.where(core.mask[..., None], type_caps[core.type_ids], 0.0)
    return core.task.scripted_actions(core.state, core.poses(), core.type_ids, believed, core.mask)


def has_blind(task) -> bool:
    """Whether ``task`` has a blind scripted reference (``blind_scripted_actions``)."""
    return callable(getattr(task, "blind_scripted_actions", None))


def blind_actions(core: TaskCore) -> np.ndarray:
    """Actions (B, N) of the task's blind scripted reference: the scripted policy's plan made
    without the robots' capabilities and types (composition matters by as much as it loses)."""
    return core.task.blind_scripted_actions(core.state, core.poses(), core.type_ids, core.caps, core.mask)


def random_actions(rng: np.random.Generator, mask: np.ndarray) -> np.ndarray:
    """Uniformly random actions (B, N) for the real robots, stay for padded slots."""
    return np.where(mask, rng.integers(0, 5, mask.shape), 0)


def reference_policy(name: str, core: TaskCore, seed: int, split: str | None = None, teams=None) -> Callable:
    """The rung ``name`` of :data:`LADDER` (or an alias) as a policy ``act(obs, mask, state) ->
    actions (B, N)`` over ``core``'s environments; ``split`` / ``teams``: the set the teams come from
    (the type_only rung's means, :func:`type_mean_capabilities`); ``seed``: the random rung's."""
    name = RUNG_ALIASES.get(name, name)
    if name == "heuristic":
        return lambda obs, mask, state: heuristic_actions(core)
    if name == "type_only":
        caps = type_mean_capabilities(core.task.name, split, teams)
        return lambda obs, mask, state: type_only_actions(core, caps)
    if name == "blind":
        if not has_blind(core.task):
            raise ValueError(f"task {core.task.name!r} has no blind reference (blind_scripted_actions)")
        return lambda obs, mask, state: blind_actions(core)
    if name == "constant":
        action = core.task.best_constant_action
        return lambda obs, mask, state: np.where(mask, action, 0)
    if name == "random":
        rng = np.random.default_rng(seed)
        return lambda obs, mask, state: random_actions(rng, mask)
    raise ValueError(f"reference policy must be one of {[*LADDER, *RUNG_ALIASES]}, got {name!r}")
