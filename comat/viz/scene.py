"""What a recording draws and where: entity paths, colours, labels and the static scene.

Series entities hold several named series (``SeriesLines`` names them), one row of scalars per
time. Entity tree of one episode (``E`` = ``episode_<k>``; arena metres, x right, y up):

| entity | archetype | logged |
|---|---|---|
| ``E/world`` | Transform3D (mirror y) | static; the viewer's 2D views point y down |
| ``E/world/arena`` | Boxes2D | static: the boundary, then the four walls |
| ``E/world/zones/<area>`` | Boxes2D / LineStrips2D | the task's areas: static geometry; labels per step where the task changes them (HMT: material left) |
| ``E/world/<items>`` | Points2D | the task's items (PCP: ``prey``): positions and colour by state per step |
| ``E/world/robots`` | Points2D | positions per step; radius, colour by type, label with capabilities static |
| ``E/world/robots/heading`` | Arrows2D | per step |
| ``E/world/trails`` | LineStrips2D | per step: the step's new piece of every path (appended) |
| ``E/world/capabilities/<ring>`` | LineStrips2D | the task's capability rings as circle outlines (the robots stay visible), per step (PCP: ``sensing``, ``capture``; HMT: ``step``) |
| ``E/world/capabilities/<bar>``, ``…/<fill>`` | Boxes2D, LineStrips2D | the task's bar and its fill, per step (HMT: ``payload``, ``load``) |
| ``E/world/actions`` | Arrows2D + class ids | per step: the chosen waypoint (AnnotationContext names it) |
| ``E/world/safety/nominal``, ``…/filtered`` | Arrows2D | per step, robots the barrier changed |
| ``E/world/events`` | Points2D | per step, robots with a contact, collision or exit |
| ``E/events`` | TextLog | steps with events |
| ``E/reward/total`` | Scalars ×2 | per step: reward, return so far |
| ``E/reward/terms`` | Scalars ×terms | per step: each named reward term (task order) |
| ``E/task/<counters>`` | Scalars | the task's counters (PCP ``prey``: sensed, captured; HMT ``material``: left per zone, carried, delivered) |
| ``E/task/coordination`` | Scalars ×2 | per step, for a task with a coordination metric: its value after the step (named by the task's ``coordination_name``) and the episode's mean so far (at the last step, the episode's ``coordination``) |
| ``E/safety/counts`` | Scalars ×7 | per step: interventions, fallbacks, recoveries, collisions, robotarium_collisions, boundary_exits, actuator_errors |
| ``E/meta`` | TextDocument + AnyValues | static: task, team, policy, seed, tier, outcome |
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from typing import Any

import numpy as np
import rerun as rr

from comat import constants as C
from comat.envs.render import GREY, PREY_COLORS, TYPE_COLORS  # one palette for recordings and frames
from comat.task_logic import ACTION_NAMES, BAR_FILL, Area
from comat.team import TASK_TYPES

__all__ = [
    "ACTION_COLORS",
    "PREY_COLORS",
    "TYPE_COLORS",
    "circle_strip",
    "episode_path",
    "legend_items",
    "log_legend",
    "log_static_scene",
    "meta_markdown",
    "robot_labels",
]

LEGEND_DROP_M = 0.04
"""How far below the bottom wall's outer face the legend's row sits (inside the arena view's margin)."""
ACTION_COLORS = ((120, 120, 120), (230, 120, 20), (230, 120, 20), (20, 140, 230), (20, 140, 230))
"""Waypoint arrow colour per action (stay, ±x, ±y)."""

_CAP_LABELS = {
    "sensing_radius_m": "r_s {:.2f} m",
    "capture_radius_m": "r_c {:.2f} m",
    "speed_m": "step {:.2f} m",
    "payload": "payload {:.1f}",
}


def episode_path(index: int) -> str:
    """Entity prefix of episode ``index`` (``episode_<index>``)."""
    return f"episode_{index}"


def circle_strip(centre: tuple[float, float], radius: float, segments: int = 48) -> np.ndarray:
    """(segments + 1, 2) closed polyline of a circle."""
    a = np.linspace(0.0, 2.0 * np.pi, segments + 1)
    return np.column_stack([centre[0] + radius * np.cos(a), centre[1] + radius * np.sin(a)])


def robot_labels(team) -> list[str]:
    """One label per robot: ``robot_i type`` and its non-zero capabilities."""

    names = TASK_TYPES[team.task].capabilities
    out = []
    for i, r in enumerate(team.robots):
        caps = ", ".join(_CAP_LABELS.get(n, n + " {:g}").format(v) for n, v in zip(names, r.capabilities) if v > 0)
        out.append(f"robot_{i} {r.type}: {caps}")
    return out


def _box(x0: float, x1: float, y0: float, y1: float) -> dict[str, Any]:
    """Boxes2D arguments of the box x in [x0, x1], y in [y0, y1] (the tasks' box layout)."""
    return {"mins": [[x0, y0]], "sizes": [[x1 - x0, y1 - y0]]}


@functools.cache
def _action_names() -> rr.AnnotationContext:
    """Names and colours of the actions' class ids (built once per process: Rerun's first
    conversion of an annotation context takes a large fraction of a second)."""
    return rr.AnnotationContext(
        [rr.AnnotationInfo(id=k, label=name, color=ACTION_COLORS[k]) for k, name in enumerate(ACTION_NAMES)]
    )


def _log_capability_marks(rec: rr.RecordingStream, w: str, marks, names, caps: np.ndarray) -> None:
    """The task's capability marks (:meth:`~comat.task_logic.TaskLogic.marks`): each ring's outlines
    and the bar of every robot's capabilities (``names``; ``caps`` (N, C) of the team), static."""
    for ring in marks.rings:
        members = np.flatnonzero(ring.members)
        rec.log(  # outlines, not discs: a filled disc hides the robots in the web viewer
            f"{w}/capabilities/{ring.name}",
            rr.LineStrips2D.from_fields(
                radii=[0.004],
                colors=[(*ring.color, 170)],
                labels=[f"robot_{i}: {ring.name} {ring.radius_m[i]:.2f} m" for i in members],
                show_labels=False,
            ),
            static=True,
        )
    if marks.bar is not None:
        half = np.column_stack([marks.bar.width_m / 2, np.full(len(caps), 0.014)])
        rec.log(
            f"{w}/capabilities/{marks.bar.name}",
            rr.Boxes2D.from_fields(
                half_sizes=half,
                colors=[(80, 80, 80)],
                labels=[
                    f"robot_{i}: {' '.join(f'{n} {c:g}' for n, c in zip(names, caps[i]))}" for i in range(len(caps))
                ],
                show_labels=False,
            ),
            static=True,
        )
        rec.log(
            f"{w}/capabilities/{marks.bar.fill_name}",
            rr.LineStrips2D.from_fields(radii=[0.011], colors=[BAR_FILL]),
            static=True,
        )


def log_static_scene(rec: rr.RecordingStream, prefix: str, core, b: int) -> None:
    """Arena, walls, task zones, prey positions and the robots' constant attributes of env b."""
    team = core.teams[b]
    task = core.task
    X0, X1, Y0, Y1 = C.ARENA_BOUNDS_M
    t = C.WALL_THICKNESS_M
    w = f"{prefix}/world"
    rec.log(w, rr.Transform3D(scale=[1.0, -1.0, 1.0]), static=True)
    # The arena's boundary, then its four walls (their inner faces on the boundary), as in comat.mjcf.arena.
    hx, hy = (X1 - X0) / 2, (Y1 - Y0) / 2
    boxes = np.array(
        [
            [(X0 + X1) / 2, (Y0 + Y1) / 2, hx, hy],
            [X1 + t, 0.0, t, hy + 2 * t],
            [X0 - t, 0.0, t, hy + 2 * t],
            [0.0, Y1 + t, hx, t],
            [0.0, Y0 - t, hx, t],
        ]
    )
    rec.log(
        f"{w}/arena",
        rr.Boxes2D(
            centers=boxes[:, :2],
            half_sizes=boxes[:, 2:],
            colors=[(60, 60, 60)],
            labels=["arena 3.2 x 2 m", "wall", "wall", "wall", "wall"],
            show_labels=False,
        ),
        static=True,
    )
    marks = task.marks(core.state, b, core.caps[b, : team.size], core.type_ids[b, : team.size])
    for area in marks.areas:
        rec.log(f"{w}/zones/{area.name}", _area(area, marks.area_labels.get(area.name, area.label)), static=True)
    if marks.items is not None:  # positions and colours per step (the recorder)
        rec.log(
            f"{w}/{marks.items.name}",
            rr.Points2D(  # where the reset put them; the recorder logs them (and their colours) per step
                marks.items.xy, radii=[marks.items.radius_m], labels=marks.items.labels, show_labels=False
            ),
            static=True,
        )
    colors = np.array([task.type_colors.get(r.type, GREY) for r in team.robots], dtype=np.uint8)
    radius = C.PROFILES[core.sim_config.profile].radius_m
    rec.log(  # the full label (type, capabilities) shows on hover; always shown they overlap
        f"{w}/robots",
        rr.Points2D.from_fields(
            radii=np.full(team.size, radius), colors=colors, labels=robot_labels(team), show_labels=False
        ),
        static=True,
    )
    rec.log(f"{w}/robots/heading", rr.Arrows2D.from_fields(colors=colors, radii=[0.008]), static=True)
    rec.log(f"{w}/trails", rr.LineStrips2D.from_fields(colors=colors // 2 + 100, radii=[0.005]), static=True)
    _log_capability_marks(rec, w, marks, TASK_TYPES[team.task].capabilities, core.caps[b, : team.size])
    rec.log(f"{w}/actions", _action_names(), rr.Arrows2D.from_fields(radii=[0.006]), static=True)
    rec.log(
        f"{w}/safety/nominal",
        rr.Arrows2D.from_fields(colors=[(120, 120, 120)], radii=[0.007], labels=["nominal"], show_labels=False),
        static=True,
    )
    rec.log(
        f"{w}/safety/filtered",
        rr.Arrows2D.from_fields(colors=[(220, 30, 30)], radii=[0.007], labels=["filtered"], show_labels=False),
        static=True,
    )
    rec.log(f"{w}/events", rr.Points2D.from_fields(radii=[0.09], colors=[(255, 0, 0, 90)]), static=True)
    log_legend(rec, w, core, b)


def legend_items(task, types: list[str], measured: bool, marks=None) -> list[tuple[str, tuple[int, ...]]]:
    """(label, colour) of each mark an arena shows, as the video's legend lists them: the robot types
    present, the task's marks (``marks``: :class:`comat.task_logic.Marks`), the filter's arrows and,
    under the reality layer, the measured pose. ``task``: the task-logic instance."""
    items = [(kind, task.type_colors.get(kind, GREY)) for kind in dict.fromkeys(types)]
    items += list(marks.legend if marks is not None else ())
    items.append(("red arrow: the filter changed the command", (220, 30, 30)))
    if measured:
        items.append(("grey ghost: measured pose", (150, 150, 150)))
    return items


def _area(area: Area, label: str):
    """A task area as a Rerun archetype: a box, or a circle's outline."""
    if area.shape == "circle":
        cx, cy, r = area.geometry
        return rr.LineStrips2D([circle_strip((cx, cy), r)], colors=[area.color], radii=[0.006], labels=[label])
    x0, x1, y0, y1 = area.geometry
    return rr.Boxes2D(**_box(x0, x1, y0, y1), colors=[area.color], labels=[label])


def log_legend(rec: rr.RecordingStream, world: str, core, b: int) -> None:
    """The legend as labelled swatches in a row below the arena's bottom wall (``world/legend``)."""
    team = core.teams[b]
    marks = core.task.marks(core.state, b, core.caps[b, : team.size], core.type_ids[b, : team.size])
    items = legend_items(core.task, [r.type for r in team.robots], not core.safe.reality.is_off, marks)
    X0, X1, Y0, _ = C.ARENA_BOUNDS_M
    x = np.linspace(X0 + 0.05, X1 - 0.3, len(items))
    rec.log(
        f"{world}/legend",
        rr.Points2D(
            np.column_stack([x, np.full(len(items), Y0 - C.WALL_THICKNESS_M * 2 - LEGEND_DROP_M)]),
            radii=[0.02],
            colors=[c for _, c in items],
            labels=[label for label, _ in items],
            show_labels=True,
        ),
        static=True,
    )


def meta_markdown(meta: Mapping[str, Any], team, outcome: Mapping[str, float] | None) -> str:
    """The episode's metadata (and, once known, its outcome) as a markdown document."""

    caps = TASK_TYPES[team.task].capabilities
    lines = [f"# {meta.get('title', 'episode')}", ""]
    lines += [f"- **{k}**: {v}" for k, v in meta.items() if k != "title"]
    lines += ["", "| robot | type | " + " | ".join(caps) + " |", "|---|---|" + "---|" * len(caps)]
    lines += [
        f"| robot_{i} | {r.type} | " + " | ".join(f"{c:g}" for c in r.capabilities) + " |"
        for i, r in enumerate(team.robots)
    ]
    if outcome:
        lines += ["", "## Outcome", ""] + [f"- **{k}**: {v:g}" for k, v in outcome.items()]
    return "\n".join(lines)
