"""The layout a rollout file opens in: one tab per episode.

Each tab: the arena (left, 3/5 of the width) with trails shown from the episode start up to
the time cursor, and on the right the reward terms, the task progress and its coordination
metric, the safety counters, and a tab pair with the episode's metadata and its event log.
"""

from __future__ import annotations

from collections.abc import Sequence

import rerun.blueprint as rrb

from comat import constants as C
from comat.viz.scene import episode_path

__all__ = ["episode_view", "rollout_blueprint"]

_MARGIN_M = 0.15
_LEGEND_M = 0.1
"""Room below the arena's bottom wall for the legend's row (:func:`comat.viz.scene.log_legend`)."""


def _history() -> rrb.VisibleTimeRanges:
    """From the start of the timeline to the cursor, on both timelines."""
    start, end = rrb.TimeRangeBoundary.infinite(), rrb.TimeRangeBoundary.cursor_relative()
    return rrb.VisibleTimeRanges([rrb.VisibleTimeRange(t, start=start, end=end) for t in ("step", "sim_time")])


def episode_view(index: int) -> rrb.Horizontal:
    """The views of episode ``index`` (entity prefix :func:`comat.viz.scene.episode_path`)."""
    p = f"/{episode_path(index)}"
    x0, x1, y0, y1 = C.ARENA_BOUNDS_M
    arena = rrb.Spatial2DView(
        origin=p,
        contents=f"{p}/world/**",
        name=f"episode {index}: arena",
        # The scene is mirrored in y at {p}/world (2D views point y down), so y bounds flip too.
        visual_bounds=rrb.VisualBounds2D(
            x_range=(x0 - _MARGIN_M, x1 + _MARGIN_M), y_range=(-y1 - _MARGIN_M, -y0 + _MARGIN_M + _LEGEND_M)
        ),
        overrides={f"{p}/world/trails": _history()},
    )
    side = rrb.Vertical(
        rrb.TimeSeriesView(origin=f"{p}/reward", name="reward and terms"),
        rrb.TimeSeriesView(origin=f"{p}/task", name="task progress and coordination"),
        rrb.TimeSeriesView(origin=f"{p}/safety", name="safety filter and violations"),
        rrb.Tabs(
            rrb.TextDocumentView(origin=f"{p}/meta", name="episode"),
            rrb.TextLogView(origin=f"{p}/events", name="events"),
        ),
    )
    return rrb.Horizontal(arena, side, column_shares=[3, 2], name=f"episode {index}")


def rollout_blueprint(episodes: Sequence[int]) -> rrb.Blueprint:
    """One tab per episode index in ``episodes``; the first is active."""
    if not episodes:
        raise ValueError("rollout_blueprint needs at least one episode index, got none")
    tabs = rrb.Tabs(*[episode_view(k) for k in episodes], active_tab=0)
    return rrb.Blueprint(tabs, rrb.TimePanel(state="expanded"), collapse_panels=False)
