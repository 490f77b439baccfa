"""What each robot did in an episode, and the task's progress after every env step.

:class:`EpisodeRecorder` keeps, for B environments of up to N robots, per-robot counters (B, N)
and the progress curve (B, H) of the current episode; :class:`comat.envs.core.TaskCore` adds
one env step to it, and the vector env hands a finished episode's arrays out in ``info``
(``episode_curve``, ``episode_robots``, ``episode_end``). Everything is counted per env step,
vectorized over (B, N): no per-tick cost.

Per-robot counts (:data:`ROBOT_COUNTS`), in env steps unless said otherwise:

* ``still_idle``: the robot chose ``stay`` (whatever the filter or a push then did to it).
* ``still_held``: it chose a moving action, but its projected point (the point its waypoint
  moves and the barrier holds apart) moved less than :data:`STILL_FRACTION` of its own
  waypoint step in that env step: held by the safety filter, a wall (a waypoint clipped at the
  arena's edge) or a teammate in the way.
* the task's own (its ``count_robots``): HMT ``carrying``: its load was > 0 at the end of the env
  step; ``delivered``: material units it unloaded in the drop-off. PCP ``sensed`` /
  ``captured``: prey that became sensed / captured in an env step while the robot was within
  its sensing / capture radius of it (every robot in range gets the credit, so the team's sum
  can exceed the number of prey when two robots reach one prey together). Forage ``lifting``:
  items collected in an env step while the robot was within reach of them.

Episode-level counts at the end (:data:`END_COUNTS`, the task's ``end_counts``): HMT
``on_board_end``, the material still on the robots as a fraction of all material; PCP
``sensed_not_captured``, real prey sensed but not captured (padded prey slots are sensed and
captured from the start, so they never count); forage ``items_left``.
"""

from __future__ import annotations

import numpy as np

from comat.tasks import TASKS

__all__ = ["END_COUNTS", "ROBOT_COUNTS", "STILL_FRACTION", "EpisodeRecorder"]

STILL_FRACTION = 0.1
"""A moving action whose projected point moved less than this fraction of the robot's waypoint
step in that env step counts as ``still_held``. Relative to the robot's own step, because steps
span 0.06–0.45 m across the HMT sets (slowest robot: 0.006 m) and are 0.2 m in PCP (0.02 m).
Measured on U_test (16 teams, 40 steps, unicycle): a moving action covers a median 100 % (HMT)
and 64 % (PCP, 29 ticks) of its step, turning included; the distribution has a gap below
~20 %, and under 10 % sit 0.5 % / 0.3 % of the scripted policy's moving steps and 7.7 % / 5.1 %
of random actions' (most of those under 2 %: robots pressed against the arena's edge)."""

ROBOT_COUNTS: dict[str, tuple[str, ...]] = {n: tuple(e.logic.robot_count_names) for n, e in TASKS.items()}
"""Per-robot counters of each task registered when this module loaded (a task's
``robot_count_names``), in the order rows list them."""

END_COUNTS: dict[str, tuple[str, ...]] = {n: tuple(e.logic.end_count_names) for n, e in TASKS.items()}
"""Episode-level counts of each task (its ``end_count_names``), read from the task state when an
episode ends."""


class EpisodeRecorder:
    """Per-robot counters (B, N) and progress curves (B, H = the task's horizon) of B episodes.

    Args:
        task: a task-logic instance (:mod:`comat.tasks`): its ``robot_count_names``,
            ``count_before``, ``count_robots`` and ``end_counts`` say what it counts.
        num_envs: B.
        max_robots: N.
    """

    def __init__(self, task, num_envs: int, max_robots: int) -> None:
        self.task = task
        self.names = tuple(task.robot_count_names)
        self.robots = {name: np.zeros((num_envs, max_robots)) for name in self.names}
        self.curve = np.zeros((num_envs, task.horizon))
        self._envs = np.arange(num_envs)

    def zero(self, envs: np.ndarray) -> None:
        """Forget the episodes of ``envs`` (a new episode starts there)."""
        for v in self.robots.values():
            v[envs] = 0.0
        self.curve[envs] = 0.0

    def before(self, state: dict) -> dict:
        """What :meth:`add` needs of the task state before the env step's task update."""
        return self.task.count_before(state)

    def add(
        self,
        before: dict,
        raw: dict,
        state: dict,
        actions: np.ndarray,
        moved: np.ndarray,
        step: np.ndarray,
        poses: np.ndarray,
        type_ids: np.ndarray,
        caps: np.ndarray,
        mask: np.ndarray,
        steps: np.ndarray,
        progress: np.ndarray,
    ) -> None:
        """Count one env step.

        Args:
            before: :meth:`before` of this step; raw: the task update's raw counts; state: the
                task state after the update.
            actions (B, N): the actions taken; moved (B, N): how far each projected point moved
                in the env step (m); step (B, N): each robot's waypoint step (m).
            poses (B, N, 3), type_ids (B, N), caps (B, N, C), mask (B, N): the team after the step.
            steps (B,): env steps taken so far in each episode, this one included.
            progress (B,): the task's progress after the step.
        """
        r = self.robots
        moving = mask & (actions != 0)
        r["still_idle"] += mask & (actions == 0)
        r["still_held"] += moving & (moved < STILL_FRACTION * step)
        inside = steps <= self.curve.shape[1]  # a PettingZoo env stepped past its horizon records nothing more
        self.curve[self._envs[inside], steps[inside] - 1] = progress[inside]
        for name, value in self.task.count_robots(before, raw, state, poses, type_ids, caps, mask).items():
            r[name] += value

    def end(self, state: dict) -> dict[str, np.ndarray]:
        """Episode-level counts (B,) of :data:`END_COUNTS` from the current task state."""
        return self.task.end_counts(state)
