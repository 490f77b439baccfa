"""What a recording draws and where: entity paths, colours, labels and the static scene.

Series entities hold several named series (``SeriesLines`` names them), one row of scalars per
time. Entity tree of one episode (``E`` = ``episode_<k>``; arena metres, x right, y up):

| entity | archetype | logged |
|---|---|---|
| ``E/world`` | Transform3D (mirror y) | static; the viewer's 2D views point y down |
| ``E/world/arena`` | Boxes2D | static: the boundary, then the four walls |
| ``E/world/zones/*`` | Boxes2D / LineStrips2D | static geometry; HMT labels per step (material left) |
| ``E/world/prey`` | Points2D | PCP: static positions, colour per step (free, sensed, captured) |
| ``E/world/robots`` | Points2D | positions per step; radius, colour by type, label with capabilities static |
| ``E/world/robots/heading`` | Arrows2D | per step |
| ``E/world/trails`` | LineStrips2D | per step: the step's new piece of every path (appended) |
| ``E/world/capabilities/sensing``, ``…/capture`` | LineStrips2D | PCP: the radii as circle outlines (the robots stay visible), per step |
| ``E/world/capabilities/payload``, ``…/load`` | Boxes2D, LineStrips2D | HMT: capacity bar, load fill, per step |
| ``E/world/actions`` | Arrows2D + class ids | per step: the chosen waypoint (AnnotationContext names it) |
| ``E/world/safety/nominal``, ``…/filtered`` | Arrows2D | per step, robots the barrier changed |
| ``E/world/events`` | Points2D | per step, robots with a contact, collision or exit |
| ``E/events`` | TextLog | steps with events |
| ``E/reward/total`` | Scalars ×2 | per step: reward, return so far |
| ``E/reward/terms`` | Scalars ×terms | per step: each named reward term (task order) |
| ``E/task/prey`` (PCP), ``E/task/material`` (HMT) | Scalars | prey sensed, captured; material left per zone, carried, delivered |
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
from comat.envs.render import PREY_COLORS, TYPE_COLORS  # one palette for recordings and frames
from comat.task_logic import ACTION_NAMES, ZONE1_CENTRE, ZONE1_RADIUS, ZONE2_X
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
LOAD_BAR_M_PER_UNIT = 0.006
"""Width of an HMT payload bar per unit of payload (a 20-unit robot: 0.12 m)."""
LOAD_BAR_OFFSET_M = 0.1
"""The payload bar floats this far above the robot centre."""


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
        caps = ", ".join(_CAP_LABELS[n].format(v) for n, v in zip(names, r.capabilities) if v > 0)
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
    zones = f"{w}/zones"
    if task.name == "hmt":
        rec.log(
            f"{zones}/material_1",
            rr.LineStrips2D([circle_strip(ZONE1_CENTRE, ZONE1_RADIUS)], colors=[(230, 170, 20)], radii=[0.006]),
            static=True,
        )
        rec.log(
            f"{zones}/material_2",
            rr.Boxes2D(**_box(ZONE2_X, X1, Y0, Y1), colors=[(230, 170, 20)]),
            static=True,
        )
        rec.log(f"{zones}/dropoff", rr.Boxes2D(**_box(X0, -ZONE2_X, Y0, Y1), colors=[(50, 170, 80)]), static=True)
    else:
        rec.log(
            f"{zones}/spawn",
            rr.Boxes2D(**_box(*task.spawn_box), colors=[(160, 160, 160)], labels=["robot spawn"]),
            static=True,
        )
        rec.log(
            f"{zones}/prey_area",
            rr.Boxes2D(**_box(*task.prey_box), colors=[(80, 190, 80)], labels=["prey area"]),
            static=True,
        )
        prey = core.state["prey"][b][core.state["active"][b]]  # padded slots of a smaller team: not drawn
        rec.log(
            f"{w}/prey",
            rr.Points2D(prey, radii=[0.035], labels=[f"prey {k}" for k in range(prey.shape[0])], show_labels=False),
            static=True,
        )
    colors = np.array([TYPE_COLORS.get(r.type, (200, 200, 200)) for r in team.robots], dtype=np.uint8)
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
    caps = core.caps[b, : team.size]
    types = core.type_ids[b, : team.size]
    if task.name == "pcp":
        for k, name in enumerate(("sensing", "capture")):
            rgb = TYPE_COLORS[name]
            rec.log(  # outlines, not discs: a filled disc hides the robots in the web viewer
                f"{w}/capabilities/{name}",
                rr.LineStrips2D.from_fields(
                    radii=[0.004],
                    colors=[(*rgb, 170)],
                    labels=[f"robot_{i}: {name} radius {caps[i, k]:.2f} m" for i in np.flatnonzero(types == k)],
                    show_labels=False,
                ),
                static=True,
            )
    else:
        half = np.column_stack([caps[:, 1] * LOAD_BAR_M_PER_UNIT / 2, np.full(team.size, 0.014)])
        rec.log(
            f"{w}/capabilities/payload",
            rr.Boxes2D.from_fields(half_sizes=half, colors=[(80, 80, 80)]),
            static=True,
        )
        rec.log(
            f"{w}/capabilities/load",
            rr.LineStrips2D.from_fields(radii=[0.011], colors=[(230, 170, 20)]),
            static=True,
        )
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


def legend_items(task: str, types: list[str], measured: bool) -> list[tuple[str, tuple[int, ...]]]:
    """(label, colour) of each mark an arena shows, as the video's legend lists them: the robot types
    present, the task's marks, the filter's arrows and, under the reality layer, the measured pose."""
    items = [(kind, TYPE_COLORS.get(kind, (200, 200, 200))) for kind in dict.fromkeys(types)]
    if task == "pcp":
        items += [
            (f"prey {name}", tuple(int(c) for c in PREY_COLORS[k, :3]))
            for k, name in enumerate(("free", "sensed", "captured"))
        ]
        items.append(("ring: sensing / capture radius", (120, 120, 120)))
    else:
        items.append(("bar: load / payload", (230, 170, 20)))
    items.append(("red arrow: the filter changed the command", (220, 30, 30)))
    if measured:
        items.append(("grey ghost: measured pose", (150, 150, 150)))
    return items


def log_legend(rec: rr.RecordingStream, world: str, core, b: int) -> None:
    """The legend as labelled swatches in a row below the arena's bottom wall (``world/legend``)."""
    team = core.teams[b]
    items = legend_items(core.task.name, [r.type for r in team.robots], core.safe.reality is not None)
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
