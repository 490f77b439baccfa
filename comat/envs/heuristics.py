"""Scripted reference policies over a :class:`~comat.envs.core.TaskCore`: show each task is
solvable, and a reference row in evaluations.

The scripted policy itself is :meth:`comat.task_logic` ``scripted_actions`` (numpy only, so the
exported Robotarium script runs the same code). It reads the environment's full task state
(prey positions, material left): *privileged* information the learners do not get. Batched over
B environments; padded slots get ``stay``.

* PCP: each sensing robot heads for the nearest prey nobody has sensed yet; each capture robot
  for the nearest sensed, uncaptured prey (else the nearest uncaptured one, to be close when it
  is sensed).
* HMT: a loaded robot heads for the drop-off; an empty one for its zone — fast robots prefer
  zone 2 (far, smaller) and slow robots zone 1 (near, larger) while both have material.
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
