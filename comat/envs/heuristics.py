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

__all__ = ["heuristic_actions", "random_actions"]


def heuristic_actions(core: TaskCore) -> np.ndarray:
    """Actions (B, N) of the scripted policy for every environment of ``core``."""
    return core.task.scripted_actions(core.state, core.poses(), core.type_ids, core.caps, core.mask)


def random_actions(rng: np.random.Generator, mask: np.ndarray) -> np.ndarray:
    """Uniformly random actions (B, N) for the real robots, stay for padded slots."""
    return np.where(mask, rng.integers(0, 5, mask.shape), 0)
