"""Episode recorder: what one team did in an episode, and why, into a Rerun recording.

``EpisodeRecorder(recording)`` is bound to a ``rerun.RecordingStream`` that the caller owns
(no global Rerun state); ``EpisodeRecorder(None)`` is disabled and every method returns at
once, so code that drives episodes calls it unconditionally.

Per episode::

    recorder.begin(core, b, episode=k, metadata={...})   # after core/env reset
    recorder.step(actions (n,), reward, terms)            # after every env step
    recorder.end()                                        # before the next reset

``begin`` logs the static scene (:mod:`comat.viz.scene`) and hooks a
:class:`~comat.envs.tap.TickTap` into the team's control ticks; ``step`` only appends arrays
to buffers; ``end`` sends every per-step entity in one ``send_columns`` call each, on the
timelines ``step`` (sequence) and ``sim_time`` (duration, step × ticks × 0.033 s). Row counts
per entity for an episode of T steps: state entities (robots, prey, task series) T + 1 rows,
steps 0…T; per-step outcomes (rewards, trails, safety arrows, events markers, safety series,
the task's coordination metric) T rows, steps 1…T; actions T rows, steps 0…T−1 (the state they were chosen in).
"""

from __future__ import annotations

import functools
import time
from collections.abc import Mapping
from typing import Any

import numpy as np
import rerun as rr

from comat import constants as C
from comat.envs.core import COORDINATION
from comat.envs.render import reality_view
from comat.envs.tap import EVENT_KINDS, StepSummary, TickTap
from comat.sim.kinematics import projected_points
from comat.task_logic import BAR_OFFSET_M, waypoint_goals
from comat.viz.scene import episode_path, log_static_scene, meta_markdown

__all__ = [
    "CAPABILITY_RING_SEGMENTS",
    "HEADING_ARROW_M",
    "NO_EVENTS",
    "SAFETY_ARROW_S",
    "TRAIL_POINTS_PER_STEP",
    "EpisodeRecorder",
]

TRAIL_POINTS_PER_STEP = 8
"""Path points kept per robot and env step (evenly spaced ticks, the last one always)."""
CAPABILITY_RING_SEGMENTS = 24
"""Segments of a capability ring (PCP's sensing / capture radius; an outline per robot and step)."""
HEADING_ARROW_M = 0.09
"""Length of the heading arrows."""
SAFETY_ARROW_S = 0.6
"""Velocity arrows show where the point would be after this long (0.2 m/s → 0.12 m)."""
SAFETY_COUNTS = (
    "interventions",
    "fallbacks",
    "recoveries",
    "collisions",
    "robotarium_collisions",
    "boundary_exits",
    "actuator_errors",
)


def _when_enabled(method):
    """Run ``method`` only on an enabled recorder, adding the thread CPU time it takes to ``cpu_s``."""

    @functools.wraps(method)
    def wrapper(self, *args, **kwargs):
        if self.recording is None:
            return None
        t0 = time.thread_time()
        try:
            return method(self, *args, **kwargs)
        finally:
            self.cpu_s += time.thread_time() - t0

    return wrapper


class EpisodeRecorder:
    """Records episodes of one environment of a :class:`comat.envs.core.TaskCore`.

    Args:
        recording: the stream to log into, or None for a recorder that does nothing.

    Attributes:
        cpu_s: CPU seconds spent recording on the calling thread so far (this object's methods
            and its per-tick taps; Rerun's own encoder and writer threads not included).
    """

    def __init__(self, recording: rr.RecordingStream | None) -> None:
        if recording is not None and not isinstance(recording, rr.RecordingStream):
            raise TypeError(f"recording must be a rerun.RecordingStream or None, got {type(recording).__name__}")
        self.recording = recording
        self.cpu_s = 0.0
        self._core = None

    @property
    def enabled(self) -> bool:
        return self.recording is not None

    # -- episode ------------------------------------------------------------------------------------
    @_when_enabled
    def begin(self, core, b: int = 0, *, episode: int = 0, metadata: Mapping[str, Any] | None = None) -> None:
        """Start recording env ``b`` of ``core`` (just reset) as episode ``episode``.

        ``metadata`` (e.g. policy, seed) joins what the env knows (task, tier, ticks per step,
        the team) in ``E/meta``, with the episode's outcome added at :meth:`end`.
        """
        if self._core is not None:
            raise RuntimeError("begin() called while an episode is being recorded; call end() first")
        team = core.teams[b]
        if team is None:
            raise ValueError(f"environment {b} has no team yet; reset it before begin()")
        self._core, self._b, self._n = core, b, team.size
        # This episode's team, kept: by end() an autoresetting env may hold the next one's.
        self._team, self._caps = team, core.caps[b, : team.size].copy()
        self._prefix = episode_path(episode)
        # What the env itself knows is recorded whatever the caller passes.
        self._meta = {
            "task": core.task.name,
            "tier": core.sim_config.tier,
            "ticks per step": core.ticks_per_step,
            **dict(metadata or {}),
        }
        self._proj = core.safety_config.projection_distance_m
        self._tap = TickTap(core.safe, b, core.ticks_per_step, self._proj)
        core.safe.tick_observers.append(self._tap)
        log_static_scene(self.recording, self._prefix, core, b)
        self._poses = [core.poses()[b, : self._n].copy()]
        self._reality = [reality_view(core, b, self._n)] if not core.safe.reality.is_off else None
        self._task = [_snapshot(core, b, self._n)]
        self._actions: list[np.ndarray] = []
        self._action_origin: list[np.ndarray] = []
        self._action_vec: list[np.ndarray] = []
        self._rewards: list[float] = []
        self._terms: dict[str, list[float]] = {name: [] for name in core.task.reward_terms}
        self._coordination: list[float] = []
        self._summaries: list[StepSummary] = []

    @_when_enabled
    def step(self, actions: np.ndarray, reward: float, terms: Mapping[str, float]) -> None:
        """Record the env step just taken with ``actions`` (n,) (this team's robots) and its
        reward and named reward terms."""
        if self._core is None:
            raise RuntimeError("step() called outside an episode; call begin() first")
        core, b, n = self._core, self._b, self._n
        actions = np.asarray(actions)
        if actions.shape != (n,):
            raise ValueError(f"actions must have shape ({n},) (this team's robots), got {actions.shape}")
        points = projected_points(self._poses[-1], self._proj)
        one = {k: v[b : b + 1] for k, v in core.state.items()}
        step = core.task.step_lengths_at(core.caps[b : b + 1, :n], self._poses[-1][None], one)[0]
        goals = waypoint_goals(points, actions, step)
        self._actions.append(actions.astype(np.int64))
        self._action_origin.append(points)
        self._action_vec.append(goals - points)
        self._summaries.append(self._tap.summarize())
        self._poses.append(core.poses()[b, :n].copy())
        if self._reality is not None:
            self._reality.append(reality_view(core, b, n))
        self._task.append(_snapshot(core, b, n))
        self._rewards.append(float(reward))
        if core.coordination_now is not None:  # a task with a coordination metric
            self._coordination.append(float(core.coordination_now[b]))
        for name in self._terms:
            self._terms[name].append(float(terms[name]))

    @_when_enabled
    def end(self, outcome: Mapping[str, float] | None = None) -> dict[str, float] | None:
        """Send the episode's per-step data; returns its metrics (None when disabled).

        ``outcome``: the episode's metrics where the env has already moved on (an autoreset
        PettingZoo env reports them in ``infos``); default: the env's counters now."""
        if self._core is None:
            raise RuntimeError("end() called outside an episode; call begin() first")
        core, b = self._core, self._b
        try:
            core.safe.tick_observers.remove(self._tap)
            self.cpu_s += self._tap.cpu_s
            outcome = dict(outcome) if outcome is not None else core.episode_metrics(b)
            self._send()
            meta = {"title": f"{self._prefix}: {core.task.name.upper()}", **self._meta}
            team = self._team
            text = meta_markdown(meta, team, outcome)
            rec = self.recording
            values = {k.replace(" ", "_"): str(v) for k, v in self._meta.items()}
            values.update(
                robot_types=[r.type for r in team.robots],
                capabilities=self._caps.ravel(),
                capability_names=list(core.task.capabilities),
                **{f"outcome_{k}": v for k, v in outcome.items()},
            )
            rec.log(
                f"{self._prefix}/meta",
                rr.TextDocument(text, media_type=rr.MediaType.MARKDOWN),
                rr.AnyValues(**values),
                static=True,
            )
        finally:
            self._core = None
        return outcome

    # -- sending --------------------------------------------------------------------------------------
    def _send(self) -> None:
        rec, p, n, core = self.recording, self._prefix, self._n, self._core
        T = len(self._rewards)
        dt = core.ticks_per_step * C.CONTROL_DT_S
        steps = np.arange(T + 1)

        def index(s: np.ndarray) -> list[rr.TimeColumn]:
            return [rr.TimeColumn("step", sequence=s), rr.TimeColumn("sim_time", duration=s * dt)]

        states, after, chosen = index(steps), index(steps[1:]), index(steps[:-1])
        poses = np.stack(self._poses)  # (T+1, n, 3)
        w = f"{p}/world"
        xy = poses[..., :2].reshape(-1, 2)
        every = [n] * (T + 1)
        rec.send_columns(f"{w}/robots", states, rr.Points2D.columns(positions=xy).partition(every))
        heading = HEADING_ARROW_M * np.stack([np.cos(poses[..., 2]), np.sin(poses[..., 2])], -1).reshape(-1, 2)
        rec.send_columns(
            f"{w}/robots/heading", states, rr.Arrows2D.columns(origins=xy, vectors=heading).partition(every)
        )
        if self._reality is not None:
            self._send_reality(w, states, poses, every)
        if T:
            self._send_steps(after, chosen, poses)
        _send_task(rec, p, core, self._b, self._task, states, poses)
        if T:
            rewards = np.asarray(self._rewards)
            _series(rec, f"{p}/reward/total", after, {"reward": rewards, "return": np.cumsum(rewards)})
            _series(rec, f"{p}/reward/terms", after, {k: np.asarray(v) for k, v in self._terms.items()})
        if len(self._coordination) == T and T:
            # Beside the task's counters: the metric after each step and the episode's value so far.
            now = np.asarray(self._coordination)
            name = core.task.coordination_name or COORDINATION
            _series(rec, f"{p}/task/{COORDINATION}", after, {name: now, "episode mean": np.cumsum(now) / steps[1:]})

    def _send_reality(self, w: str, states, poses: np.ndarray, every: list[int]) -> None:
        """The reality layer's view: measured poses (grey ghosts), a red line from each true pose to
        its measurement, and faulty robots (black rings), per step."""
        rec = self.recording
        seen = np.stack([v["measured"] for v in self._reality])  # (T+1, n, 3)
        mxy = seen[..., :2].reshape(-1, 2)
        rec.send_columns(
            f"{w}/robots/measured",
            states,
            rr.Points2D.columns(
                positions=mxy, radii=[0.055] * len(mxy), colors=[(90, 90, 90, 110)] * len(mxy)
            ).partition(every),
        )
        strips = np.stack([poses[..., :2], seen[..., :2]], axis=2).reshape(-1, 2, 2)
        rec.send_columns(
            f"{w}/robots/pose_error",
            states,
            rr.LineStrips2D.columns(strips=list(strips), colors=[(210, 20, 20, 255)] * len(strips)).partition(every),
        )
        faulty = [np.flatnonzero(v["faulty"]) for v in self._reality]
        fxy = np.concatenate([poses[t, f, :2] for t, f in enumerate(faulty)]) if faulty else np.zeros((0, 2))
        rec.send_columns(
            f"{w}/robots/fault",
            states,
            rr.Points2D.columns(
                positions=fxy, radii=[0.075] * len(fxy), colors=[(0, 0, 0, 200)] * len(fxy), labels=["fault"] * len(fxy)
            ).partition([len(f) for f in faulty]),
        )

    def _send_steps(self, after, chosen, poses: np.ndarray) -> None:
        rec, p, n = self.recording, self._prefix, self._n
        w = f"{p}/world"
        T = len(self._summaries)
        rows = [n] * T
        actions = np.concatenate(self._actions)
        rec.send_columns(
            f"{w}/actions",
            chosen,
            rr.Arrows2D.columns(
                origins=np.concatenate(self._action_origin),
                vectors=np.concatenate(self._action_vec),
                class_ids=actions,
            ).partition(rows),
        )
        # Trails: each step adds only its own piece of every path (never the whole path again).
        paths = np.stack([s.path for s in self._summaries])  # (T, n, K+1, 2)
        K = paths.shape[2] - 1
        keep = np.unique(np.round(np.linspace(0, K, min(K, TRAIL_POINTS_PER_STEP) + 1)).astype(np.int64))
        strips = paths[:, :, keep].reshape(T * n, keep.size, 2)
        rec.send_columns(f"{w}/trails", after, rr.LineStrips2D.columns(strips=strips).partition(rows))
        # Barrier interventions: nominal vs filtered velocity of the robots it changed.
        hit = np.stack([s.intervened for s in self._summaries])  # (T, n)
        lengths = hit.sum(axis=1)
        origin = np.concatenate([s.origin[s.intervened] for s in self._summaries])
        for name in ("nominal", "filtered"):
            vec = np.concatenate([getattr(s, name)[s.intervened] for s in self._summaries]) * SAFETY_ARROW_S
            rec.send_columns(
                f"{w}/safety/{name}",
                after,
                rr.Arrows2D.columns(origins=origin, vectors=vec).partition(lengths),
            )
        counts = {k: np.array([s.counts[k] for s in self._summaries], dtype=np.float64) for k in SAFETY_COUNTS}
        _series(rec, f"{p}/safety/counts", after, counts)
        # Events: a marker at each robot that had one, and a log line per step that had any.
        ev = np.stack([s.events for s in self._summaries])  # (T, n, E)
        anyev = ev.any(axis=2)
        where = np.argwhere(anyev)
        labels = [f"robot_{i}: " + ", ".join(np.asarray(EVENT_KINDS)[ev[t, i]]) for t, i in where]
        xy = np.stack([s.event_xy for s in self._summaries])[anyev]
        rec.send_columns(
            f"{w}/events",
            after,
            rr.Points2D.columns(positions=xy, labels=labels).partition(anyev.sum(axis=1)),
        )
        fallback = counts["fallbacks"] > 0
        recovery = counts["recoveries"] > 0
        log_steps = np.flatnonzero(anyev.any(axis=1) | fallback | recovery)
        if not log_steps.size:  # say so: an empty log view reads like a broken one
            rec.send_columns(
                f"{p}/events",
                [rr.TimeColumn("step", sequence=[0]), rr.TimeColumn("sim_time", duration=[0.0])],
                rr.TextLog.columns(text=[NO_EVENTS], level=["INFO"]),
            )
        if log_steps.size:
            by_step = {int(t): [] for t in log_steps}
            for (t, _), text in zip(where, labels):
                by_step[int(t)].append(text)
            for t in np.flatnonzero(fallback):
                by_step[int(t)].append(f"barrier fallback (team braked) in {int(counts['fallbacks'][t])} ticks")
            for t in np.flatnonzero(recovery):
                by_step[int(t)].append(f"outside the safe set: recovering in {int(counts['recoveries'][t])} ticks")
            text = [f"step {t + 1}: " + "; ".join(v) for t, v in by_step.items()]
            level = ["ERROR" if fallback[t] else "WARN" for t in by_step]
            idx = np.array(list(by_step)) + 1
            dt = self._core.ticks_per_step * C.CONTROL_DT_S
            rec.send_columns(
                f"{p}/events",
                [rr.TimeColumn("step", sequence=idx), rr.TimeColumn("sim_time", duration=idx * dt)],
                rr.TextLog.columns(text=text, level=level),
            )


NO_EVENTS = (
    "no events in this episode: no contact, Robotarium collision, boundary exit, wall contact or "
    "actuator error, and the filter never recovered or braked"
)
"""The event log's one line when nothing happened."""


def _series(rec: rr.RecordingStream, path: str, index: list[rr.TimeColumn], series: dict[str, np.ndarray]) -> None:
    """Several named time series (T,) on one entity: one row of len(series) scalars per time,
    so the per-row index is paid once rather than once per series."""
    values = np.stack([np.asarray(v, dtype=np.float64) for v in series.values()], axis=1)  # (T, S)
    rec.log(path, rr.SeriesLines(names=list(series)), static=True)
    rec.send_columns(
        path, index, rr.Scalars.columns(scalars=values.ravel()).partition([values.shape[1]] * values.shape[0])
    )


# -- the task's marks (comat.task_logic.Marks): a snapshot after every step, sent per episode --
def _snapshot(core, b: int, n: int):
    """What env ``b``'s task draws now (its items, area labels, counters, bar are copies)."""
    return core.task.marks(core.state, b, core.caps[b, :n], core.type_ids[b, :n])


def _send_task(rec, p: str, core, b: int, snaps: list, states, poses: np.ndarray) -> None:
    """Items by state, area labels, the counters' series, capability rings and the bar, per step
    (poses (T+1, n, 3))."""
    w = f"{p}/world"
    T1, n = poses.shape[:2]
    first = snaps[0]
    if first.items is not None:
        xy = np.concatenate([s.items.xy for s in snaps])
        colors = np.concatenate([np.asarray(s.items.colors, dtype=np.uint8)[s.items.status] for s in snaps])
        rows = [s.items.xy.shape[0] for s in snaps]
        rec.send_columns(
            f"{w}/{first.items.name}", states, rr.Points2D.columns(positions=xy, colors=colors).partition(rows)
        )
    if first.counters:
        _series(
            rec,
            f"{p}/task/{core.task.counters_name}",
            states,
            {k: [s.counters[k] for s in snaps] for k in first.counters},
        )
    for area in first.areas:
        if area.name in first.area_labels:
            archetype = rr.LineStrips2D if area.shape == "circle" else rr.Boxes2D
            labels = [s.area_labels[area.name] for s in snaps]
            rec.send_columns(f"{w}/zones/{area.name}", states, archetype.columns(labels=labels))
    ring = np.linspace(0.0, 2.0 * np.pi, CAPABILITY_RING_SEGMENTS + 1)
    unit = np.stack([np.cos(ring), np.sin(ring)], -1)  # (S+1, 2)
    for r in first.rings:
        mine = poses[:, r.members, :2]  # (T+1, m, 2)
        strips = mine[:, :, None, :] + r.radius_m[r.members][None, :, None, None] * unit  # (T+1, m, S+1, 2)
        rec.send_columns(
            f"{w}/capabilities/{r.name}",
            states,
            rr.LineStrips2D.columns(strips=strips.reshape(-1, *strips.shape[2:])).partition([mine.shape[1]] * T1),
        )
    if first.bar is not None:
        width = first.bar.width_m
        fraction = np.clip(np.stack([s.bar.fraction for s in snaps]), 0.0, 1.0)  # (T+1, n)
        centre = poses[..., :2] + np.array([0.0, BAR_OFFSET_M])  # (T+1, n, 2)
        rows = [n] * T1
        rec.send_columns(
            f"{w}/capabilities/{first.bar.name}",
            states,
            rr.Boxes2D.columns(centers=centre.reshape(-1, 2)).partition(rows),
        )
        left_end = centre - np.stack([width / 2, np.zeros(n)], -1)
        fill = left_end + np.stack([width * fraction, np.zeros_like(fraction)], -1)
        bars = np.stack([left_end, fill], axis=2).reshape(-1, 2, 2)  # (T+1)·n strips of 2 points
        rec.send_columns(
            f"{w}/capabilities/{first.bar.fill_name}", states, rr.LineStrips2D.columns(strips=bars).partition(rows)
        )
