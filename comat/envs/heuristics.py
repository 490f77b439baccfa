"""Reference policies over a :class:`~comat.envs.core.TaskCore`: show each task is solvable,
and reference rows in evaluations.

The scripted policy is the tasks' ``scripted_actions`` in :mod:`comat.task_logic` (numpy only,
so the exported Robotarium script runs the same code; each task's ``scripted_targets`` says
what it does). It reads the full task state (prey positions, material left): *privileged*
information the learners do not get. Batched over B environments; padded slots get ``stay``.
"""

from __future__ import annotations

import numpy as np

from comat.envs.core import TaskCore
from comat.tasks import TASKS

__all__ = ["BEST_CONSTANT_ACTION", "blind_actions", "has_blind", "heuristic_actions", "random_actions"]

BEST_CONSTANT_ACTION = {name: entry.logic.best_constant_action for name, entry in TASKS.items()}
"""Per task registered when this module loaded, its ``best_constant_action``: the action (0 stay,
1 +x, 2 −x, 3 +y, 4 −y) that earns the highest return on U_train when every robot always takes
it (all five tried, one episode per coalition, the evaluation seed; tests/test_eval.py, slow
tier): +x on the four built-in tasks (forage: return −2.2 against −4.0 for each of the others;
navigation: −1.45 against −1.75 to −1.8). On PCP it captures half the prey (return 16.4, 20 % of
the episodes finished): early learning curves must beat it to mean anything."""


def heuristic_actions(core: TaskCore) -> np.ndarray:
    """Actions (B, N) of the scripted policy for every environment of ``core``."""
    return core.task.scripted_actions(core.state, core.poses(), core.type_ids, core.caps, core.mask)


def has_blind(task) -> bool:
    """Whether ``task`` has a capability-blind scripted reference (``blind_scripted_actions``)."""
    return callable(getattr(task, "blind_scripted_actions", None))


def blind_actions(core: TaskCore) -> np.ndarray:
    """Actions (B, N) of the task's capability-blind scripted reference: the scripted policy's plan
    made without the robots' capabilities and types (composition matters by as much as it loses)."""
    return core.task.blind_scripted_actions(core.state, core.poses(), core.type_ids, core.caps, core.mask)


def random_actions(rng: np.random.Generator, mask: np.ndarray) -> np.ndarray:
    """Uniformly random actions (B, N) for the real robots, stay for padded slots."""
    return np.where(mask, rng.integers(0, 5, mask.shape), 0)
