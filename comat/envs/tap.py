"""Per-tick data of one team, gathered while an env step runs and summarized once per step.

A :class:`TickTap` is registered in :attr:`comat.control.SafeTeams.tick_observers`. Every
control tick it copies the team's rows of what the tick produced into preallocated buffers
(a handful of small array copies, no Python loop over robots); :meth:`TickTap.summarize` then
reduces the step's K ticks to what a recording shows per env step.

Shapes: n = robots of the recorded team, K = control ticks in the step.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from comat.safety import SafetyInfo
from comat.sim.kinematics import projected_points
from comat.sim.violations import TickEvents

__all__ = ["EVENT_KINDS", "MIN_CHANGE_MPS", "StepSummary", "TickTap"]

MIN_CHANGE_MPS = 1e-3
"""A command counts as changed by the filter, for drawing, when it moved by more than this
(m/s): the QP returns changes down to 1e-19 m/s that no arrow could show. (The per-step
``interventions`` count keeps the episode metric's definition: any change.)"""

EVENT_KINDS = ("contact", "robotarium_collision", "boundary", "wall_contact", "actuator")
"""Per-robot events of a tick: onset of a MuJoCo robot–robot contact, Robotarium collision
(offset centres <= 0.135 m), centre outside the arena, chassis touching a wall, wheel command
over the limit."""


@dataclass
class StepSummary:
    """One env step of one team, reduced from its ticks.

    Attributes:
        path: (n, K + 1, 2) robot centres at the step start and after every tick.
        end_poses: (n, 3) poses after the last tick.
        intervened: (n,) the filter changed the robot's command by more than
            :data:`MIN_CHANGE_MPS` in some tick.
        nominal, filtered: (n, 2) the robot's nominal and filtered projected-point velocity
            (m/s) at its tick of largest change (zero where ``intervened`` is False).
        origin: (n, 2) the projected point at that tick (before it ran).
        events: (n, len(EVENT_KINDS)) bool, the event happened in some tick.
        event_xy: (n, 2) centre at the first tick with any event.
        counts: per-step totals, named as :data:`comat.envs.core.EPISODE_METRICS`:
            ``collisions`` (contact onsets), ``robotarium_collisions`` (pair-ticks),
            ``boundary_exits`` (robot-ticks), ``actuator_errors`` (ticks), ``interventions``
            (ticks the filter changed a command), ``fallbacks`` (ticks the team braked),
            ``recoveries`` (ticks the team recovered from outside the safe set).
    """

    path: np.ndarray
    end_poses: np.ndarray
    intervened: np.ndarray
    nominal: np.ndarray
    filtered: np.ndarray
    origin: np.ndarray
    events: np.ndarray
    event_xy: np.ndarray
    counts: dict[str, int]


class TickTap:
    """Collects team ``team``'s rows of every tick of a :class:`comat.control.SafeTeams`.

    Args:
        teams: the SafeTeams whose ticks are observed (its layout must not change while the
            tap is attached: the environment resets teams only between episodes).
        team: index of the recorded team.
        ticks_per_step: expected ticks per env step (buffers grow if more arrive).
        projection_distance_m: where the filter's projected point sits ahead of the axle.
    """

    _BUFFERS = (
        "_poses",
        "_nominal",
        "_filtered",
        "_intervened",
        "_events",
        "_intervention",
        "_fallback",
        "_recovery",
        "_pairs",
    )

    def __init__(self, teams, team: int, ticks_per_step: int, projection_distance_m: float) -> None:
        lay = teams.world.layout
        self._layout = lay
        self._world = teams.world
        self._rows = slice(int(lay.offsets[team]), int(lay.offsets[team + 1]))
        self._team = team
        self._proj = projection_distance_m
        self.n = self._rows.stop - self._rows.start
        self._alloc(max(int(ticks_per_step), 1))
        self._last_contact = np.zeros(self.n, dtype=bool)  # contact state before the step (onsets)
        self.cpu_s = 0.0
        """Thread CPU seconds spent in the per-tick calls."""
        self.start_step(teams.world.poses[self._rows])

    def _alloc(self, k: int) -> None:
        n = self.n
        self._poses = np.zeros((k + 1, n, 3))
        self._nominal = np.zeros((k, n, 2))
        self._filtered = np.zeros((k, n, 2))
        self._intervened = np.zeros((k, n), dtype=bool)
        self._events = np.zeros((k, n, len(EVENT_KINDS)), dtype=bool)  # column 0: contact, not yet onsets
        self._intervention = np.zeros(k)
        self._fallback = np.zeros(k, dtype=bool)
        self._recovery = np.zeros(k, dtype=bool)
        self._pairs = np.zeros(k, dtype=np.int64)

    def _grow(self) -> None:
        old = [getattr(self, name) for name in self._BUFFERS]
        self._alloc(2 * self._nominal.shape[0])
        for name, prev in zip(self._BUFFERS, old):
            getattr(self, name)[: prev.shape[0]] = prev

    def start_step(self, poses: np.ndarray) -> None:
        """Begin a step from the team's poses (n, 3)."""
        self._k = 0
        self._poses[0] = poses

    def __call__(self, nominal: np.ndarray, filtered: np.ndarray, events: TickEvents, info: SafetyInfo) -> None:
        # Every tick pays for this: plain row copies only; all reductions wait for summarize().
        t0 = time.thread_time()
        k, rows, b = self._k, self._rows, self._team
        if self._world.layout is not self._layout:  # the rows would now belong to other robots
            raise RuntimeError(
                "the teams' layout changed while a tap was attached; end the recording before "
                "team sizes change (reset of the recorded environment or of another one)"
            )
        if k == self._nominal.shape[0]:
            self._grow()
        self._poses[k + 1] = self._world.pose_view[rows]  # read-only use of the world's own array
        self._nominal[k] = nominal[rows]
        self._filtered[k] = filtered[rows]
        self._intervened[k] = info.robot_intervened[rows]
        ev = self._events[k]
        ev[:, 0] = events.robot_contact[rows]
        ev[:, 1] = events.collision[rows]
        ev[:, 2] = events.boundary[rows]
        ev[:, 3] = events.wall_contact[rows]
        ev[:, 4] = events.actuator[rows]
        self._intervention[k] = info.intervention[b]
        self._fallback[k] = info.fallback[b]
        self._recovery[k] = info.recovery[b]
        self._pairs[k] = events.collision_pairs[b]
        self._k = k + 1
        self.cpu_s += time.thread_time() - t0

    def summarize(self) -> StepSummary:
        """Reduce the ticks since :meth:`start_step`, then start the next step from the last pose."""
        K, n = self._k, self.n
        poses = self._poses[: K + 1]
        nominal, filtered = self._nominal[:K], self._filtered[:K]
        size = np.linalg.norm(filtered - nominal, axis=-1)  # (K, n)
        changed = self._intervened[:K] & (size > MIN_CHANGE_MPS)
        worst = np.argmax(np.where(changed, size, -1.0), axis=0) if K else np.zeros(n, dtype=np.int64)
        robots = np.arange(n)
        intervened = changed.any(axis=0)
        keep = intervened[:, None]
        before = poses[worst, robots]  # the filter saw the pose before its tick
        events = self._events[:K].copy()
        contact = events[..., 0].copy()
        events[..., 0] &= ~np.concatenate([self._last_contact[None], contact[:-1]])  # onsets, as the metric counts
        if K:
            self._last_contact = contact[-1]
        any_event = events.any(axis=2)  # (K, n)
        first = np.argmax(any_event, axis=0) if K else np.zeros(n, dtype=np.int64)
        summary = StepSummary(
            path=poses[:, :, :2].transpose(1, 0, 2).copy(),
            end_poses=poses[-1].copy(),
            intervened=intervened,
            nominal=np.where(keep, nominal[worst, robots], 0.0) if K else np.zeros((n, 2)),
            filtered=np.where(keep, filtered[worst, robots], 0.0) if K else np.zeros((n, 2)),
            origin=projected_points(before, self._proj),
            events=events.any(axis=0),
            event_xy=poses[first + 1, robots, :2],
            counts={
                "collisions": int(events[..., 0].sum()),
                "robotarium_collisions": int(self._pairs[:K].sum()),
                "boundary_exits": int(events[..., 2].sum()),
                "actuator_errors": int(events[..., 4].any(axis=1).sum()),
                "interventions": int((self._intervention[:K] > 0).sum()),
                "fallbacks": int(self._fallback[:K].sum()),
                "recoveries": int(self._recovery[:K].sum()),
            },
        )
        self.start_step(poses[-1].copy())
        return summary
