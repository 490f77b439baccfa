"""Top-down pictures of an episode, drawn with matplotlib (Agg: headless, no display, no GPU).

One drawing serves ``env.render()`` (``render_mode="rgb_array"``) and ``comat rollout --video``:

* :class:`EpisodeFrames` follows one team of a :class:`comat.envs.core.TaskCore` through an
  episode — ``begin`` after a reset, ``after_step`` after every env step — keeping the robots'
  trails and what the safety filter changed in the last step (through a
  :class:`comat.envs.tap.TickTap` on the team's control ticks), and ``frame()`` draws the
  current state as an (H, W, 3) uint8 array, H × W = :data:`FRAME_SIZE`.
* :func:`draw_frame` draws a :class:`FrameState` (plain arrays, no env needed).

What a frame shows (arena metres, x right, y up): the arena and its walls; the task's marks
(:meth:`comat.task_logic.TaskLogic.marks`: its areas with their labels, its items coloured by
state — PCP's prey free / sensed / captured —, each robot's capability rings and bar — PCP's
sensing or capture radius, HMT's step length and payload filled to its load); every robot as a
disc of its body radius coloured by type, with its heading; its trail; a red ring and the nominal
(grey) → filtered (red) velocity arrow where the barrier filter changed its command in the last
step; a red cross where a contact, collision or boundary exit happened. Above it, the caption and
the task's status line, and at the right, for a task with a coordination metric, its value after
the last step and its episode mean so far.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from comat import constants as C
from comat.envs.tap import TickTap
from comat.task_logic import BAR_FILL, BAR_HEIGHT_M, BAR_OFFSET_M, Marks
from comat.tasks import TASKS
from comat.tasks.pcp import PREY_COLORS as _PREY_RGB

__all__ = [
    "FRAME_SIZE",
    "PREY_COLORS",
    "TYPE_COLORS",
    "EpisodeFrames",
    "FrameState",
    "arena_axes",
    "draw_frame",
]

FRAME_SIZE = (448, 640)
"""(H, W) of a frame in pixels: both multiples of 16 (what H.264 encoders want): a 48 px header,
the arena's 3.2 × 2 m (with its walls and a thin margin) at 169 px/m, and a 40 px legend strip
below it (:func:`arena_axes`)."""
_DPI = 100
_HEADER_PX = 48
_LEGEND_PX = 40
"""The strip under the arena that holds the legend, so that it hides no part of the arena."""
_TITLE_GAP_PX = 12
"""Least room between the header's title and the coordination metric at its right."""
_VIEW_PAD_M = 0.1
"""Margin around the arena in the view (m), in x; y's is the same over 1.6 (room for the walls)."""

TYPE_COLORS: dict[str, tuple[int, int, int]] = {k: v for e in TASKS.values() for k, v in e.logic.type_colors.items()}
"""Robot colour by type (RGB) of the tasks registered when this module loaded; frames and
recordings read each task's own ``type_colors``."""
GREY = (200, 200, 200)
"""Colour of a robot type a task gives none."""

PREY_COLORS = np.array([[*c, 255] for c in _PREY_RGB], dtype=np.uint8)
"""PCP's prey colour by state (RGBA): free, sensed, captured."""

TRAIL_POINTS_PER_STEP = 4
"""Path points kept per robot and env step for the trails (evenly spaced ticks, the last always)."""
SAFETY_ARROW_S = 0.6
"""Velocity arrows show where the point would be after this long (0.2 m/s → 0.12 m)."""


def _rgb(color: tuple[int, ...]) -> tuple[float, ...]:
    return tuple(c / 255 for c in color)


@dataclass
class FrameState:
    """What one frame draws; arrays are row-per-robot, n robots, K prey.

    Attributes:
        task: the task's name (the header).
        poses: (n, 3) x, y (m), heading (rad).
        types: n robot type names.
        caps: (n, C) capabilities.
        robot_radius_m: body radius.
        trails: (n, P, 2) path so far (P >= 1).
        intervened: (n,) the filter changed the robot's command in the last step.
        origin, nominal, filtered: (n, 2) projected point and its nominal / filtered velocity
            (m/s) at the tick of the largest change (rows where ``intervened``).
        events: (n,) a contact, collision or boundary exit in the last step; ``event_xy`` (n, 2).
        marks: what the task draws now (areas, items, rings, bar, status; :class:`Marks`).
        type_colors: robot colour per type (RGB).
        step, horizon, ret: env steps so far, the horizon, return so far.
        title: first header line (e.g. the policy).
        measured, faulty: the reality layer's measured poses (a dashed ghost and an error line
            per robot) and faulty motors (a black ring and "fault"); None without a layer.
    """

    task: str
    poses: np.ndarray
    types: list[str]
    caps: np.ndarray
    robot_radius_m: float
    trails: np.ndarray
    intervened: np.ndarray
    origin: np.ndarray
    nominal: np.ndarray
    filtered: np.ndarray
    events: np.ndarray
    event_xy: np.ndarray
    marks: Marks
    type_colors: dict[str, tuple[int, int, int]]
    step: int = 0
    horizon: int = 0
    ret: float = 0.0
    title: str = ""
    measured: np.ndarray | None = None
    """(n, 3) the poses the robots' script saw (reality layer on), drawn as ghosts; None: off."""
    faulty: np.ndarray | None = None
    """(n,) the robot's motors run at a fault's fraction now (reality layer faults)."""
    coordination: tuple[float, float] | None = None
    """The task's coordination metric after the last step and its episode mean so far (drawn at the
    header's right); None before the first step or for a task without one."""
    coordination_name: str = "coordination"
    """What the task calls its coordination metric (its ``coordination_name``)."""


def _figure():
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    h, w = FRAME_SIZE
    fig = Figure(figsize=(w / _DPI, h / _DPI), dpi=_DPI)
    FigureCanvasAgg(fig)  # Agg canvas bound to this figure only: pyplot's global state is never touched
    return fig


def arena_axes() -> tuple[tuple[float, float, float, float], tuple[float, float, float, float]]:
    """Where the arena sits in a frame: the axes' (left, bottom, width, height) as fractions of the
    frame, and the view's (x0, x1, y0, y1) in m. The view keeps the arena's 3.2 × 2 m aspect (one
    scale in x and y) in the height left between the header and the legend strip, centred in x."""
    h, w = FRAME_SIZE
    X0, X1, Y0, Y1 = C.ARENA_BOUNDS_M
    view = (X0 - _VIEW_PAD_M, X1 + _VIEW_PAD_M, Y0 - _VIEW_PAD_M / 1.6, Y1 + _VIEW_PAD_M / 1.6)
    height_px = h - _HEADER_PX - _LEGEND_PX
    width_px = height_px * (view[1] - view[0]) / (view[3] - view[2])
    box = ((1 - width_px / w) / 2, _LEGEND_PX / h, width_px / w, height_px / h)
    return box, view


def draw_frame(state: FrameState, fig=None) -> np.ndarray:
    """The (H, W, 3) uint8 picture of ``state`` (:data:`FRAME_SIZE`); ``fig``: a figure to reuse."""
    fig = fig or _figure()
    fig.clear()
    h = FRAME_SIZE[0]
    box, (x0, x1, y0, y1) = arena_axes()
    ax = fig.add_axes(box)
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect("auto")
    ax.set_axis_off()
    _draw_arena(ax)
    _draw_task(ax, state.marks)
    _draw_robots(ax, state)
    _draw_reality(ax, state)
    _draw_safety(ax, state)
    fig.text(0.01, 1 - 26 / h, _status_line(state), ha="left", va="top", fontsize=8, family="monospace")
    title_end = FRAME_SIZE[1]
    if state.coordination is not None:
        now, mean = state.coordination
        text = f"{state.coordination_name} {now:.2f} (episode {mean:.2f})"
        metric = fig.text(0.99, 1 - 6 / h, text, ha="right", va="top", fontsize=8, family="monospace")
        title_end = metric.get_window_extent(fig.canvas.get_renderer()).x0 - _TITLE_GAP_PX
    title = fig.text(0.01, 1 - 6 / h, state.title, ha="left", va="top", fontsize=8, family="monospace")
    _shorten(title, title_end, fig.canvas.get_renderer())
    _draw_legend(fig, state)
    fig.canvas.draw()
    rgba = np.asarray(fig.canvas.buffer_rgba())
    assert rgba.shape[:2] == FRAME_SIZE, rgba.shape  # fixed figure size and dpi
    return np.ascontiguousarray(rgba[..., :3])


def _shorten(text, end_px: float, renderer) -> None:
    """Cut a header line (ending it with "…") until it ends left of ``end_px``: a long title (a
    rollout's policy, episode and seed) never runs under the coordination metric at the header's right."""
    full = text.get_text()
    while full and text.get_window_extent(renderer).x1 > end_px:
        full = full[:-1].rstrip()
        text.set_text(full + "…")


def _draw_legend(fig, s: FrameState) -> None:
    """What the marks mean, in the strip under the arena (never over it): the robot types present, then
    the task's marks (item states, capability rings, the bar, any other entry of its legend, e.g. the
    kinds of its areas), the filter's ring and, under the reality layer, the measured-pose ghost."""
    from matplotlib.lines import Line2D

    def dot(color, label, marker="o", size=7, fill=True, ls="none"):
        return Line2D(
            [],
            [],
            marker=marker,
            ms=size,
            ls=ls,
            color=color,
            markerfacecolor=color if fill else "none",
            markeredgecolor="k" if fill else color,
            label=label,
        )

    m = s.marks
    items = [dot(_rgb(s.type_colors.get(kind, GREY)), kind) for kind in dict.fromkeys(s.types)]
    if m.items is not None:
        items += [dot(_rgb(c), f"{m.items.name} {name}", size=5) for name, c in zip(m.items.states, m.items.colors)]
    items += [dot(_rgb(r.color), r.label, size=9, fill=False) for r in m.rings]
    if m.bar is not None:
        items.append(dot(_rgb(BAR_FILL), m.bar.label, marker="s", size=6))
    shown = {h.get_label() for h in items}  # the task's other legend entries (Arctic's ground kinds): squares
    items += [dot(_rgb(c), label, marker="s", size=7) for label, c in m.legend if label not in shown]
    items.append(dot("red", "red ring: filter changed the command", size=9, fill=False))
    if s.measured is not None:
        items.append(Line2D([], [], color="#404040", ls="--", label="dashed: measured pose"))
    rows = -(-len(items) // 5)  # as few rows as five columns allow: three fit the strip at this size
    fig.legend(
        handles=items,
        loc="lower center",
        bbox_to_anchor=(0.5, 0.0),
        ncol=-(-len(items) // rows),
        fontsize=6.5 if rows < 3 else 5.5,
        frameon=False,
        handletextpad=0.3,
        columnspacing=0.9,
        borderpad=0.2,
        labelspacing=0.2,
    )


def _status_line(s: FrameState) -> str:
    head = f"{s.task.upper()} step {s.step}/{s.horizon} · return {s.ret:.2f} · "
    return head + s.marks.status + f" · filtered {int(s.intervened.sum())}"


def reality_view(core, b: int, n: int) -> dict[str, np.ndarray | None]:
    """``measured`` (n, 3) and ``faulty`` (n,) of env ``b``'s team under a reality layer, else None."""
    layer = core.safe.reality
    if layer.is_off:
        return {"measured": None, "faulty": None}
    return {"measured": core.measured_poses()[b, :n].copy(), "faulty": core.padded(layer.speed_fraction)[b, :n] < 1.0}


def _draw_arena(ax) -> None:
    from matplotlib.patches import Rectangle

    X0, X1, Y0, Y1 = C.ARENA_BOUNDS_M
    t = C.WALL_THICKNESS_M
    ax.add_patch(Rectangle((X0, Y0), X1 - X0, Y1 - Y0, facecolor="#f7f7f2", edgecolor="#3c3c3c", lw=1.2))
    for x, y, w, h in (
        (X0 - t, Y0 - t, t, Y1 - Y0 + 2 * t),
        (X1, Y0 - t, t, Y1 - Y0 + 2 * t),
        (X0, Y0 - t, X1 - X0, t),
        (X0, Y1, X1 - X0, t),
    ):
        ax.add_patch(Rectangle((x, y), w, h, facecolor="#9a9a9a", edgecolor="none"))


def _draw_task(ax, m: Marks) -> None:
    """The task's areas (dashed boxes, circles) with their labels, then its items by state."""
    from matplotlib.patches import Circle, Rectangle

    for area in m.areas:
        color = _rgb(area.color)
        label = m.area_labels.get(area.name, area.label)
        if area.shape == "circle":
            cx, cy, r = area.geometry
            ax.add_patch(Circle((cx, cy), r, facecolor=(*color, 0.15), edgecolor=color, lw=1.0))
            ax.text(cx, cy - r - 0.02, label, ha="center", va="top", fontsize=7, color=color)
            continue
        x0, x1, y0, y1 = area.geometry
        ax.add_patch(
            Rectangle((x0, y0), x1 - x0, y1 - y0, facecolor=(*color, 0.12), edgecolor=(*color, 0.7), lw=0.8, ls="--")
        )
        ax.text((x0 + x1) / 2, y1 - 0.02, label, ha="center", va="top", fontsize=7, color=color)
    it = m.items
    if it is None:
        return
    for k, ((x, y), status) in enumerate(zip(it.xy, it.status)):
        ax.add_patch(Circle((x, y), it.radius_m, facecolor=_rgb(it.colors[status]), edgecolor="k", lw=0.5, zorder=3))
        if it.labels is not None:
            ax.text(x, y, it.labels[k], ha="center", va="center", fontsize=6, zorder=4)


def _draw_robots(ax, s: FrameState) -> None:
    from matplotlib.patches import Circle, Rectangle

    m = s.marks
    for i, (pose, kind) in enumerate(zip(s.poses, s.types)):
        color = _rgb(s.type_colors.get(kind, GREY))
        trail = s.trails[i]
        ax.plot(trail[:, 0], trail[:, 1], color=color, alpha=0.45, lw=1.0, zorder=2)
        x, y, th = pose
        for ring in m.rings:
            if not ring.members[i]:
                continue
            if ring.dotted:
                ax.add_patch(
                    Circle((x, y), ring.radius_m[i], fill=False, edgecolor=(*color, 0.5), lw=0.7, ls=":", zorder=2)
                )
            else:
                ax.add_patch(
                    Circle(
                        (x, y), ring.radius_m[i], facecolor=(*color, 0.10), edgecolor=(*color, 0.6), lw=0.8, zorder=2
                    )
                )
        if m.bar is not None:
            width = float(m.bar.width_m[i])
            bx, by = x - width / 2, y + BAR_OFFSET_M
            fill = width * float(np.clip(m.bar.fraction[i], 0.0, 1.0))
            ax.add_patch(
                Rectangle((bx, by), width, BAR_HEIGHT_M, facecolor="white", edgecolor="#505050", lw=0.6, zorder=4)
            )
            ax.add_patch(Rectangle((bx, by), fill, BAR_HEIGHT_M, facecolor=_rgb(BAR_FILL), edgecolor="none", zorder=4))
        ax.add_patch(Circle((x, y), s.robot_radius_m, facecolor=color, edgecolor="k", lw=0.6, zorder=5))
        ax.plot([x, x + 0.08 * np.cos(th)], [y, y + 0.08 * np.sin(th)], color="k", lw=1.2, zorder=6)
        ax.text(x, y, str(i), ha="center", va="center", fontsize=7.5, fontweight="bold", color="white", zorder=7)


def _draw_reality(ax, s: FrameState) -> None:
    """Measured poses as dashed ghosts joined to the true ones; faulty robots ringed in black."""
    from matplotlib.patches import Circle

    if s.measured is not None:
        for (x, y, _), (mx, my, mth) in zip(s.poses, s.measured):
            ax.add_patch(Circle((mx, my), s.robot_radius_m, fill=False, edgecolor="#404040", lw=0.8, ls="--", zorder=6))
            ax.plot(
                [mx, mx + 0.08 * np.cos(mth)], [my, my + 0.08 * np.sin(mth)], color="#404040", lw=0.8, ls="--", zorder=6
            )
            ax.plot([x, mx], [y, my], color="#d01010", lw=1.0, zorder=6)
    if s.faulty is not None:
        for i in np.flatnonzero(s.faulty):
            x, y = s.poses[i, :2]
            ax.add_patch(Circle((x, y), s.robot_radius_m * 1.35, fill=False, edgecolor="k", lw=1.6, zorder=7))
            ax.text(x, y - 1.6 * s.robot_radius_m, "fault", ha="center", va="top", fontsize=6, zorder=7)


def _draw_safety(ax, s: FrameState) -> None:
    from matplotlib.patches import Circle

    for i in np.flatnonzero(s.intervened):
        x, y = s.poses[i, :2]
        ax.add_patch(Circle((x, y), s.robot_radius_m * 1.6, fill=False, edgecolor="red", lw=1.2, zorder=8))
        ox, oy = s.origin[i]
        for vec, color in ((s.nominal[i], "#787878"), (s.filtered[i], "red")):
            dx, dy = vec * SAFETY_ARROW_S
            ax.annotate(
                "", (ox + dx, oy + dy), (ox, oy), zorder=9, arrowprops={"arrowstyle": "->", "color": color, "lw": 1.0}
            )
    hits = np.flatnonzero(s.events)
    if hits.size:
        ax.scatter(s.event_xy[hits, 0], s.event_xy[hits, 1], marker="x", s=60, color="red", zorder=10)


class EpisodeFrames:
    """Follows env ``b`` of a TaskCore through an episode and draws it (see the module docstring).

    Args:
        title: first header line of every frame (e.g. the policy).
    """

    def __init__(self, title: str = "") -> None:
        self.title = title
        self._core = self._tap = self._last = self._fig = None
        self._b = 0
        self._trails: list[np.ndarray] = []
        self._return = 0.0

    def begin(self, core, b: int = 0) -> None:
        """Start following env ``b`` of ``core``, just reset (a new team: a new tick tap)."""

        self.close()
        self._core, self._b = core, b
        self._tap = TickTap(core.safe, b, core.ticks_per_step, core.safety_config.projection_distance_m)
        core.safe.tick_observers.append(self._tap)
        n = core.teams[b].size
        self._trails = [core.poses()[b, :n, :2].copy()[:, None]]
        self._last = None
        self._return = 0.0

    def after_step(self, reward: float) -> None:
        """Take in the env step just run (its team reward)."""
        if self._tap is None:
            raise RuntimeError("after_step() before begin(): reset the environment first")
        summary = self._tap.summarize()
        K = summary.path.shape[1] - 1
        keep = np.unique(np.round(np.linspace(0, K, min(K, TRAIL_POINTS_PER_STEP) + 1)).astype(np.int64))[1:]
        self._trails.append(summary.path[:, keep])
        self._last = summary
        self._return += float(reward)

    def frame(self) -> np.ndarray:
        """(H, W, 3) uint8 picture of the followed team now."""
        if self._core is None:
            raise RuntimeError("frame() before begin(): reset the environment first")
        core, b = self._core, self._b
        n = core.teams[b].size
        last = self._last
        zeros2, none = np.zeros((n, 2)), np.zeros(n, dtype=bool)
        task = core.task
        state = FrameState(
            task=task.name,
            poses=core.poses()[b, :n].copy(),
            types=[r.type for r in core.teams[b].robots],
            caps=core.caps[b, :n].copy(),
            robot_radius_m=C.PROFILES[core.sim_config.profile].radius_m,
            trails=np.concatenate(self._trails, axis=1),
            intervened=none if last is None else last.intervened,
            origin=zeros2 if last is None else last.origin,
            nominal=zeros2 if last is None else last.nominal,
            filtered=zeros2 if last is None else last.filtered,
            events=none if last is None else last.events[:, [0, 1, 2]].any(axis=1),
            event_xy=zeros2 if last is None else last.event_xy,
            marks=task.marks(core.state, b, core.caps[b, :n], core.type_ids[b, :n]),
            type_colors=task.type_colors,
            step=int(core.steps[b]),
            horizon=int(task.horizon),
            ret=self._return,
            title=self.title,
            **reality_view(core, b, n),
        )
        if core.coordination_now is not None and core.steps[b] > 0:
            mean = core.episode_metrics(b).get("coordination", float(core.coordination_now[b]))
            state.coordination = (float(core.coordination_now[b]), mean)
            state.coordination_name = task.coordination_name or "coordination"
        if self._fig is None:
            self._fig = _figure()  # one figure per follower: drawing reuses it
        return draw_frame(state, self._fig)

    def close(self) -> None:
        """Stop observing the team's ticks (before its environment resets)."""
        if self._tap is not None and self._core is not None:
            observers = self._core.safe.tick_observers
            if self._tap in observers:
                observers.remove(self._tap)
        self._tap = None
