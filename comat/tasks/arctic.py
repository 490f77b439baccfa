"""Arctic Transport (``arctic_v1``): every robot must cross a field of ice and open water to the far
side. Ice robots are fast on ice and slow in water, water robots the other way round, and neither
sees more than the cell it is on; the scout is slow everywhere but sees far, and what any robot has
seen the whole team knows. The crossers' best route is through their own fast ground, and only the
scout can show it to them in time.

| | |
|---|---|
| Agents | ``robot_0 … robot_{n-1}``, n = 2…20; types ``ice``, ``water`` and ``scout``: >= 1 ice and >= 1 water robot, and one scout in every drawn team of 3 or more (a team may lack a scout: ``optional_types``); team changes every episode as in every comat task |
| Capabilities | [ice speed m, water speed m, sight m]: the waypoint step per env step on ice, in water (on snow: their mean); how far the robot sees |
| Actions | Discrete(5): 0 stay, 1 +x, 2 −x, 3 +y, 4 −y — a waypoint one step away for the robot's projected point, the step set by the ground under the robot |
| Step | 29 control ticks of 0.033 s (0.96 s): waypoint controller → safety filter → MuJoCo |
| Observation | Box(16,) float64, below |
| State | Box(81 + S·16,): the 8 × 5 ground cells as the team knows them (+1 ice, −1 water, 0 snow or not seen), which cells it has seen, the team's fraction arrived, then the observations of S = ``state_robots`` slots |
| Horizon | 48 steps; ends early when every robot has arrived |
| Ground | the arena in 0.4 m cells, 8 columns × 5 rows: the two columns on each side snow, the four in the middle (x ∈ [−0.8, 0.8]) each ice or water with probability 0.35, else snow, drawn per episode; the goal is the last column (x ≥ 1.2) |
| Seen | a cell is seen, for good, once a robot stands in it or its centre lies within a robot's sight; at the start, from where the robots start |
| Spawn | robots >= 0.3 m apart in x ∈ [−1.45, −0.85], y ∈ [−0.85, 0.85], random headings |

Observation layout (per robot; the ground as the team knows it: +1 ice, −1 water, 0 snow or not seen):

| index | feature |
|---|---|
| 0–1 | x, y (m) |
| 2–3 | cos θ, sin θ |
| 4–6 | type one-hot (ice, water, scout) |
| 7–9 | capabilities: ice speed / 0.2 m, water speed / 0.2 m, sight / 1 m |
| 10 | the ground under the robot |
| 11–12 | the ground one cell ahead in +x, and in the better of ±y (the robot's fast ground; a scout: −y) |
| 13 | x-offset (m) to the goal column |
| 14 | 1 if the robot has arrived |
| 15 | the team's fraction of the field's 20 cells seen |

Composition sets (``coalitions=``; :mod:`comat.team`; ice speed / water speed / sight, m):

* ``train`` (U_train): 3, 5 or 7 robots; ice robots U(0.14, 0.18) / U(0.02, 0.03) / U(0.25,
  0.35), water robots the two speeds swapped, scouts U(0.065, 0.085) on both grounds / U(0.8, 1.0):
  on its own ground a crosser is five to nine times as fast as on the other.
* ``val``: like U_train from another stream; ``size``: sizes 2…20, U_train's ranges (a 2-robot
  team has no scout).
* ``test`` (U_test): 2, 4, 6 or 8 robots; fast ground U(0.12, 0.19), slow ground U(0.018, 0.035),
  crossers' sight U(0.2, 0.4); scouts U(0.06, 0.09) / U(0.7, 1.1); ``scale``: 10, 12, 16 or 20
  robots with U_test's ranges.
* ``capability`` (U_cap): every value outside its type's U_train range: crossers' fast ground
  [0.11, 0.14) ∪ (0.18, 0.19], slow ground [0.016, 0.02) ∪ (0.03, 0.036], sight [0.18, 0.25) ∪
  (0.35, 0.45]; scouts [0.055, 0.065) ∪ (0.085, 0.095] / [0.6, 0.8) ∪ (1.0, 1.2] (0.19 m: 0.2 m/s
  over one 0.96 s step).

Rule (after every step): an ice or water robot whose centre is in the goal column has *arrived*,
for good. Progress is the crossers' fraction arrived; a scout need not cross.

Reward (shared) = named terms: ``arrived`` +1 per crosser arriving, ``time`` −0.05 per step,
``violation`` −5 in a step with any robot–robot contact, Robotarium-style collision or boundary
exit.

References (``results/sets/references.md``): the scripted crossers head, cell by cell, for the
neighbouring cell with the least time left to the goal over their own ground speeds (a time-to-go
field over the cells, per robot) on the ground as the team knows it (a cell not seen yet costs the
mean of its two crossing times); the scripted scouts go to a lookout in the field's middle (x = 0,
|y| <= 0.4 m). Its capability-blind twin (``blind_scripted_actions``) computes the same field as if
every robot were equally fast on every cell: everyone, scouts too, takes the shortest way, whatever
the ground.

This follows MARBLER's and JaxRobotarium's Arctic Transport (ice and water robots crossing a
field, a drone that sees for them); here the far-seeing robot is a slow ground robot.

Version history: v0 — first version (issue 49): ice and water robots only, every robot seeing the
ground under it and next to it, every robot counted, the field all ice or water, a 55-step
horizon. v1 — the scout, the team's knowledge of the ground (seen cells) and the crossers' sight;
only crossers counted; snow cells in the field (probability 0.3); slow ground U(0.02, 0.03) in
U_train (v0: U(0.02, 0.035)) and a 48-step horizon (issue 49: in v0 the capability-blind
reference was 8 points below the scripted one on U_cap, where 15 were asked for).
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

# (an export ships this file beside task_logic.py, with this import made local: sim2real/export.py)
from comat.task_logic import ARENA, Area, Ring, TaskLogic

__all__ = ["ARCTIC", "ArcticTransport"]

ICE, WATER, SNOW = 1.0, -1.0, 0.0
"""Ground kinds as the state and observations hold them."""
SCOUT = 2
"""The scout's type id."""

FAST_OUT = ((0.11, 0.139999), (0.180001, 0.19))
SLOW_OUT = ((0.016, 0.019999), (0.030001, 0.036))
SIGHT_OUT = ((0.18, 0.249999), (0.350001, 0.45))
SCOUT_SPEED_OUT = ((0.055, 0.064999), (0.085001, 0.095))
SCOUT_SIGHT_OUT = ((0.6, 0.799999), (1.000001, 1.2))
"""U_cap's bands (m): every value outside its type's U_train range, below or above."""


class ArcticTransport(TaskLogic):
    """Arctic transport (module docstring). State per env: ground (B, 5, 8), seen (B, 5, 8), arrived
    (B, N), who must cross (B, N) and each robot's sight (B, N)."""

    name = "arctic"
    version = 1
    title = "Arctic Transport"
    types = ("ice", "water", "scout")
    optional_types = ("scout",)
    capabilities = ("ice_speed_m", "water_speed_m", "sight_m")
    capability_scale = np.array([0.2, 0.2, 1.0])
    horizon = 48
    ticks_per_step = 29
    spawn_box = (-1.45, -0.85, -0.85, 0.85)
    cell_m = 0.4
    cols, rows = 8, 5
    random_cols = (2, 3, 4, 5)
    goal_col = 7
    ground_odds = (0.35, 0.35)
    """Probability that a field cell is ice, water (else snow)."""
    n_task_features = 6
    reward_terms = ("arrived", "time", "violation")
    reward_weights: ClassVar[dict] = {"arrived": 1.0, "time": -0.05, "violation": -5.0}
    reset_uses_starts = True

    capability_limits = ((0.0, 0.19), (0.0, 0.19), (0.0, 1.5))
    required = ((0, 1, 2), (0, 1, 2), (0, 1, 2))
    capability_bands: ClassVar[dict] = {
        "train": {
            "ice": (((0.14, 0.18),), ((0.02, 0.03),), ((0.25, 0.35),)),
            "water": (((0.02, 0.03),), ((0.14, 0.18),), ((0.25, 0.35),)),
            "scout": (((0.065, 0.085),), ((0.065, 0.085),), ((0.8, 1.0),)),
        },
        "test": {
            "ice": (((0.12, 0.19),), ((0.018, 0.035),), ((0.2, 0.4),)),
            "water": (((0.018, 0.035),), ((0.12, 0.19),), ((0.2, 0.4),)),
            "scout": (((0.06, 0.09),), ((0.06, 0.09),), ((0.7, 1.1),)),
        },
        "capability": {
            "ice": (FAST_OUT, SLOW_OUT, SIGHT_OUT),
            "water": (SLOW_OUT, FAST_OUT, SIGHT_OUT),
            "scout": (SCOUT_SPEED_OUT, SCOUT_SPEED_OUT, SCOUT_SIGHT_OUT),
        },
    }
    set_streams = 30
    """The composition sets' random streams are 30… (PCP and HMT 0–11, forage 12–17, navigation
    18–23, sensors 24–29)."""

    def step_lengths(self, caps: np.ndarray) -> np.ndarray:
        """The step on snow (B, N): the mean of the two speeds."""
        return caps[..., :2].mean(axis=-1)

    def cells(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Row and column (…,) of the cells holding points xy (…, 2) (clipped to the grid)."""
        x0, _, y0, _ = ARENA
        col = np.clip(((xy[..., 0] - x0) // self.cell_m).astype(np.int64), 0, self.cols - 1)
        row = np.clip(((xy[..., 1] - y0) // self.cell_m).astype(np.int64), 0, self.rows - 1)
        return row, col

    def _at(self, grid: np.ndarray, xy: np.ndarray) -> np.ndarray:
        """(B, N) values of a per-env cell grid (B, 5, 8) under points xy (B, N, 2)."""
        row, col = self.cells(xy)
        return np.take_along_axis(grid.reshape(xy.shape[0], -1), row * self.cols + col, 1)

    def known(self, state: dict) -> np.ndarray:
        """(B, 5, 8) the ground as the team knows it: its kind where seen, 0 elsewhere."""
        return np.where(state["seen"], state["ground"], SNOW)

    def step_lengths_at(self, caps: np.ndarray, poses: np.ndarray, state: dict) -> np.ndarray:
        ground = self._at(state["ground"], poses[..., :2])
        return np.where(ground == ICE, caps[..., 0], np.where(ground == WATER, caps[..., 1], self.step_lengths(caps)))

    def new_state(self, B: int, N: int) -> dict:
        return {
            "ground": np.zeros((B, self.rows, self.cols)),
            "seen": np.zeros((B, self.rows, self.cols), bool),
            "arrived": np.zeros((B, N), bool),
            "crosser": np.zeros((B, N), bool),
            "sight": np.zeros((B, N)),
        }

    def reset_env(self, state: dict, b: int, rng: np.random.Generator, caps: np.ndarray, starts=None) -> None:
        """A new ground (the robots' caps (n, 3)); ``starts`` (n, 3): what the team sees from there."""
        state["ground"][b] = SNOW
        cols = list(self.random_cols)
        u = rng.random((self.rows, len(cols)))
        p_ice, p_water = self.ground_odds
        state["ground"][b][:, cols] = np.where(u < p_ice, ICE, np.where(u < p_ice + p_water, WATER, SNOW))
        state["arrived"][b] = False
        state["crosser"][b] = False
        state["sight"][b] = 0.0
        state["sight"][b, : caps.shape[0]] = caps[:, 2]
        state["seen"][b] = False
        if starts is not None:
            self.set_starts(state, b, starts)

    def _sees(self, xy: np.ndarray, sight: np.ndarray, mask: np.ndarray) -> np.ndarray:
        """(B, 5, 8) the cells that robots at xy (B, N, 2) with ``sight`` (B, N) see now (or stand in)."""
        x0, _, y0, _ = ARENA
        cx = x0 + (np.arange(self.cols) + 0.5) * self.cell_m
        cy = y0 + (np.arange(self.rows) + 0.5) * self.cell_m
        dx = cx[None, None, None, :] - xy[..., 0][..., None, None]  # (B, N, 1, C)
        dy = cy[None, None, :, None] - xy[..., 1][..., None, None]  # (B, N, R, 1)
        within = dx**2 + dy**2 <= (sight**2)[..., None, None]  # (B, N, R, C)
        row, col = self.cells(xy)
        on = (np.arange(self.rows)[:, None] == row[..., None, None]) & (np.arange(self.cols) == col[..., None, None])
        return ((within | on) & mask[..., None, None]).any(axis=1)

    def update(self, state: dict, poses: np.ndarray, type_ids: np.ndarray, caps: np.ndarray, mask: np.ndarray) -> dict:
        state["seen"] |= self._sees(poses[..., :2], caps[..., 2], mask)
        # who must cross: known from the first step on (a reset is not told the robots' types)
        state["crosser"] = mask & (type_ids != SCOUT)
        _, col = self.cells(poses[..., :2])
        new = (col == self.goal_col) & state["crosser"] & ~state["arrived"]
        state["arrived"] |= new
        return {"arrived": new.sum(axis=1).astype(float)}

    def done(self, state: dict) -> np.ndarray:
        need = state["crosser"].sum(axis=1)
        return (need > 0) & (state["arrived"].sum(axis=1) >= need)

    def progress(self, state: dict) -> np.ndarray:
        """The crossers' fraction arrived (B,) (0 before the first step)."""
        return state["arrived"].sum(axis=1) / np.maximum(state["crosser"].sum(axis=1), 1)

    def task_features(self, state, poses, type_ids, caps, mask) -> np.ndarray:
        xy = poses[..., :2]
        known = self.known(state)
        here = self._at(known, xy)
        ahead = self._at(known, xy + np.array([self.cell_m, 0.0]))
        up, down = (self._at(known, xy + np.array([0.0, s * self.cell_m])) for s in (1.0, -1.0))
        # the better side for this robot: the one whose ground is its fast one (a scout has none: −y)
        fast = np.where(type_ids == 0, ICE, np.where(type_ids == 1, WATER, np.nan))
        side = np.where(up == fast, up, down)
        x_goal = ARENA[0] + self.goal_col * self.cell_m - xy[..., 0]
        field = state["seen"][:, :, list(self.random_cols)].mean(axis=(1, 2))
        B, N = mask.shape
        return np.stack(
            [here, ahead, side, x_goal, state["arrived"].astype(float), np.broadcast_to(field[:, None], (B, N))],
            axis=-1,
        )

    def global_features(self, state: dict) -> np.ndarray:
        B = state["ground"].shape[0]
        return np.concatenate(
            [
                self.known(state).reshape(B, -1),
                state["seen"].reshape(B, -1).astype(float),
                self.progress(state)[:, None],
            ],
            axis=-1,
        )

    # -- the scripted references ------------------------------------------------------------------
    def _time_to_go(self, state: dict, speeds: np.ndarray, blind: bool = False) -> np.ndarray:
        """(B, N, rows, cols) time (env steps) from each cell to the goal column for each robot of
        ground speeds ``speeds`` (B, N, 2), on the ground as the team knows it (a cell not seen yet
        costs the mean of its two crossing times; snow is known); ``blind``: every cell equally
        fast. Relaxation of cost(cell) = crossing time + the least neighbour's, all robots at once
        (no per-robot loop)."""
        B, N = speeds.shape[:2]
        if blind:
            cross = np.full((B, N, self.rows, self.cols), self.cell_m / 0.1)
        else:
            g, seen = state["ground"][:, None], state["seen"][:, None]  # (B, 1, R, C)
            t_ice = self.cell_m / np.maximum(speeds[..., 0], 1e-6)[..., None, None]
            t_water = self.cell_m / np.maximum(speeds[..., 1], 1e-6)[..., None, None]
            t_snow = self.cell_m / np.maximum(self.step_lengths(speeds), 1e-6)[..., None, None]
            known = np.where(g == ICE, t_ice, np.where(g == WATER, t_water, t_snow))
            cross = np.where(seen | (g == SNOW), known, (t_ice + t_water) / 2)
        cost = np.full(cross.shape, np.inf)
        cost[..., self.goal_col] = 0.0
        for _ in range(self.rows * self.cols):
            pad = np.pad(cost, ((0, 0), (0, 0), (1, 1), (1, 1)), constant_values=np.inf)
            best = np.minimum.reduce([pad[..., :-2, 1:-1], pad[..., 2:, 1:-1], pad[..., 1:-1, :-2], pad[..., 1:-1, 2:]])
            new = np.minimum(cost, cross + best)
            new[..., self.goal_col] = 0.0
            if np.array_equal(new, cost):
                break
            cost = new
        return cost

    def _targets(self, state: dict, centres: np.ndarray, speeds: np.ndarray, mask: np.ndarray, blind=False) -> tuple:
        """Each robot's next cell centre (B, N, 2): the neighbour (or its own cell) with the least time to go."""
        cost = self._time_to_go(state, speeds, blind)  # (B, N, R, C)
        row, col = self.cells(centres)
        moves = np.array([[0, 0], [0, 1], [0, -1], [1, 0], [-1, 0]])  # (drow, dcol)
        r = np.clip(row[..., None] + moves[:, 0], 0, self.rows - 1)
        c = np.clip(col[..., None] + moves[:, 1], 0, self.cols - 1)
        B, N = mask.shape
        flat = cost.reshape(B, N, -1)
        here = np.take_along_axis(flat, (r * self.cols + c), 2)  # (B, N, 5)
        here[..., 0] += 1e-9  # ties: move on rather than stay
        k = np.argmin(here, axis=-1)
        tr, tc = np.take_along_axis(r, k[..., None], 2)[..., 0], np.take_along_axis(c, k[..., None], 2)[..., 0]
        x0, _, y0, _ = ARENA
        target = np.stack([x0 + (tc + 0.5) * self.cell_m, y0 + (tr + 0.5) * self.cell_m], -1)
        target[..., 0] = np.where(tc == self.goal_col, np.maximum(target[..., 0], centres[..., 0]), target[..., 0])
        return target, mask & ~state["arrived"]

    lookout = (0.0, 0.4)
    """Where the scripted scouts go: x = 0 (m), the field's middle, at most this far from y = 0 (m)
    (they keep their start's side); from there a sight of 0.8 m sees nearly every cell."""

    def scripted_actions(self, state, poses, type_ids, caps, mask) -> np.ndarray:
        """The scripted reference (module docstring): crossers follow their time-to-go field over the
        ground as the team knows it; scouts go to the lookout in the field's middle."""
        centres = poses[..., :2]
        target, ok = self._targets(state, centres, caps, mask)
        x, reach = self.lookout
        scout = (type_ids == SCOUT) & mask
        look = np.stack([np.full(centres.shape[:-1], x), np.clip(centres[..., 1], -reach, reach)], -1)
        target = np.where(scout[..., None], look, target)
        return self.drive(state, poses, caps, mask, target, ok | scout)

    def blind_scripted_actions(self, state, poses, type_ids, caps, mask) -> np.ndarray:
        """The same, every robot believed equally fast on every cell: the shortest way, whatever the
        ground and whoever the robot."""
        centres = poses[..., :2]
        target, ok = self._targets(state, centres, caps, mask, blind=True)
        return self.drive(state, poses, caps, mask, target, ok)

    # -- diagnostics, drawing and export ------------------------------------------------------------
    end_count_names = ("not_arrived",)

    def end_counts(self, state: dict) -> dict[str, np.ndarray]:
        return {"not_arrived": (state["crosser"] & ~state["arrived"]).sum(axis=1).astype(float)}

    type_colors: ClassVar[dict] = {"ice": (66, 133, 244), "water": (0, 150, 136), "scout": (244, 180, 0)}
    counters_name = "arrived"

    def _field_cells(self, state: dict, b: int) -> list[tuple[str, int, int, str]]:
        """Env ``b``'s ice and water cells: (area name, row, column, kind)."""
        ground = state["ground"][b]
        kinds = [("ice" if ground[r, c] == ICE else "water", r, c) for r, c in zip(*np.nonzero(ground != SNOW))]
        return [(f"{kind}_{r}_{c}", int(r), int(c), kind) for kind, r, c in kinds]

    def areas(self, state: dict | None = None, b: int = 0) -> tuple[Area, ...]:
        """The goal column and, with a state, env ``b``'s ice (light) and water (dark) cells (their
        labels: "?" while the team has not seen the cell, :meth:`area_labels`)."""
        x0, x1, y0, y1 = ARENA
        g = self.goal_col * self.cell_m + x0
        out = [Area("goal", "box", (g, x1, y0, y1), (50, 170, 80), "goal")]
        if state is not None:
            labels = self.area_labels(state, b)
            for name, r, c, kind in self._field_cells(state, b):
                box = (
                    x0 + c * self.cell_m,
                    x0 + (c + 1) * self.cell_m,
                    y0 + r * self.cell_m,
                    y0 + (r + 1) * self.cell_m,
                )
                out.append(Area(name, "box", box, (150, 200, 240) if kind == "ice" else (20, 60, 160), labels[name]))
        return tuple(out)

    def area_labels(self, state: dict, b: int) -> dict[str, str]:
        """Each ice or water cell's label now: "?" until the team has seen it."""
        seen = state["seen"][b]
        return {name: "" if seen[r, c] else "?" for name, r, c, _ in self._field_cells(state, b)}

    def rings(self, caps: np.ndarray, type_ids: np.ndarray) -> tuple[Ring, ...]:
        return (Ring("sight", np.ones(caps.shape[0], bool), caps[:, 2], (120, 120, 120), "dotted ring: sight", True),)

    def counters(self, state: dict, b: int, n: int) -> dict[str, float]:
        return {"arrived": float(state["arrived"][b, :n].sum())}

    def status_text(self, state: dict, b: int, counters: dict[str, float]) -> str:
        return f"arrived {int(counters['arrived'])}/{int(state['crosser'][b].sum())}"

    def layout(self, state: dict, b: int) -> dict[str, list]:
        return {"ground": state["ground"][b].tolist()}

    def set_layout(self, state: dict, b: int, layout: dict[str, list]) -> None:
        """The ground; nothing seen yet (:meth:`set_starts` shows what the team sees from its starts)."""
        state["ground"][b] = np.asarray(layout["ground"], dtype=float)
        state["seen"][b] = False

    def set_starts(self, state: dict, b: int, starts: np.ndarray) -> None:
        n = starts.shape[0]
        xy = np.asarray(starts, dtype=float)[None, :, :2]
        state["seen"][b] |= self._sees(xy, state["sight"][b : b + 1, :n], np.ones((1, n), bool))[0]


ARCTIC = ArcticTransport
