"""Arctic Transport (``arctic_v0``): every robot must cross a field of ice and open water to the far
side; ice robots are fast on ice and slow in water, water robots the other way round — each must
find the route its own ground makes fast.

| | |
|---|---|
| Agents | ``robot_0 … robot_{n-1}``, n = 2…20; types ``ice`` and ``water``, >= 1 of each; team changes every episode as in every comat task |
| Capabilities | [ice speed m, water speed m]: the waypoint step per env step on ice, in water (on snow: their mean) |
| Actions | Discrete(5): 0 stay, 1 +x, 2 −x, 3 +y, 4 −y — a waypoint one step away for the robot's projected point, the step set by the ground under the robot |
| Step | 29 control ticks of 0.033 s (0.96 s): waypoint controller → safety filter → MuJoCo |
| Observation | Box(13,) float64, below |
| State | Box(41 + S·13,): the 8 × 5 ground cells (+1 ice, −1 water, 0 snow), the team's fraction arrived, then the observations of S = ``state_robots`` slots |
| Horizon | 55 steps; ends early when every robot has arrived |
| Ground | the arena in 0.4 m cells, 8 columns × 5 rows: the two columns on each side snow, the four in the middle (x ∈ [−0.8, 0.8]) each ice or water with probability 1/2, drawn per episode; the goal is the last column (x ≥ 1.2) |
| Spawn | robots >= 0.3 m apart in x ∈ [−1.45, −0.85], y ∈ [−0.85, 0.85], random headings |

Observation layout (per robot):

| index | feature |
|---|---|
| 0–1 | x, y (m) |
| 2–3 | cos θ, sin θ |
| 4–5 | type one-hot (ice, water) |
| 6–7 | capabilities / 0.2 m (ice speed, water speed) |
| 8 | the ground under the robot (+1 ice, −1 water, 0 snow) |
| 9–10 | the ground one cell ahead in +x, and in the better of ±y (+1 ice, −1 water, 0 snow or wall) |
| 11 | x-offset (m) to the goal column |
| 12 | 1 if the robot has arrived |

Composition sets (``coalitions=``; :mod:`comat.team`; ice speed / water speed, m per step):

* ``train`` (U_train): 3, 5 or 7 robots; ice robots U(0.14, 0.18) / U(0.02, 0.035), water robots
  U(0.02, 0.035) / U(0.14, 0.18): on its own ground a robot is five to six times as fast.
* ``val``: like U_train from another stream; ``size``: sizes 2…20, U_train's ranges.
* ``test`` (U_test): 2, 4, 6 or 8 robots; fast ground U(0.12, 0.19), slow ground U(0.018, 0.04);
  ``scale``: 10, 12, 16 or 20 robots with U_test's ranges.
* ``capability`` (U_cap): every speed outside its type's U_train range: fast ground [0.11, 0.14)
  ∪ (0.18, 0.19], slow ground [0.015, 0.02) ∪ (0.035, 0.05] (0.19 m: 0.2 m/s over one 0.96 s step).

Rule (after every step): a robot whose centre is in the goal column has *arrived*, for good.
Progress is the team's fraction arrived.

Reward (shared) = named terms: ``arrived`` +1 per robot arriving, ``time`` −0.05 per step,
``violation`` −5 in a step with any robot–robot contact, Robotarium-style collision or boundary
exit.

References (``results/sets/references.md``): the scripted robot heads, cell by cell, for the
neighbouring cell with the least time left to the goal over its own ground speeds (a time-to-go
field over the cells, per robot); its capability-blind twin (``blind_scripted_actions``) computes
the same field as if every cell were equally fast: the shortest way, whatever the ground.

This follows MARBLER's and JaxRobotarium's Arctic Transport (ice and water robots crossing a
field); their drones that see far and move slowly are not here: every robot here senses the ground
under it and next to it.

Version history: v0 — first version (issue 49).
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

# (an export ships this file beside task_logic.py, with this import made local: sim2real/export.py)
from comat.task_logic import ARENA, Area, Ring, TaskLogic

__all__ = ["ARCTIC", "ArcticTransport"]

ICE, WATER, SNOW = 1.0, -1.0, 0.0
"""Ground kinds as the state and observations hold them."""


class ArcticTransport(TaskLogic):
    """Arctic transport (module docstring). State per env: ground (B, 5, 8) and arrived (B, N)."""

    name = "arctic"
    title = "Arctic Transport"
    types = ("ice", "water")
    capabilities = ("ice_speed_m", "water_speed_m")
    capability_scale = np.array([0.2, 0.2])
    horizon = 55
    ticks_per_step = 29
    spawn_box = (-1.45, -0.85, -0.85, 0.85)
    cell_m = 0.4
    cols, rows = 8, 5
    random_cols = (2, 3, 4, 5)
    goal_col = 7
    n_task_features = 5
    reward_terms = ("arrived", "time", "violation")
    reward_weights: ClassVar[dict] = {"arrived": 1.0, "time": -0.05, "violation": -5.0}

    capability_limits = ((0.0, 0.19), (0.0, 0.19))
    required = ((0, 1), (0, 1))
    capability_bands: ClassVar[dict] = {
        "train": {"ice": (((0.14, 0.18),), ((0.02, 0.035),)), "water": (((0.02, 0.035),), ((0.14, 0.18),))},
        "test": {"ice": (((0.12, 0.19),), ((0.018, 0.04),)), "water": (((0.018, 0.04),), ((0.12, 0.19),))},
        "capability": {
            "ice": (((0.11, 0.139999), (0.180001, 0.19)), ((0.015, 0.019999), (0.035001, 0.05))),
            "water": (((0.015, 0.019999), (0.035001, 0.05)), ((0.11, 0.139999), (0.180001, 0.19))),
        },
    }
    set_streams = 30
    """The composition sets' random streams are 30… (PCP and HMT 0–11, forage 12–17, navigation
    18–23, sensors 24–29)."""

    def step_lengths(self, caps: np.ndarray) -> np.ndarray:
        """The step on snow (B, N): the mean of the two speeds."""
        return caps.mean(axis=-1)

    def cells(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Row and column (…,) of the cells holding points xy (…, 2) (clipped to the grid)."""
        x0, _, y0, _ = ARENA
        col = np.clip(((xy[..., 0] - x0) // self.cell_m).astype(np.int64), 0, self.cols - 1)
        row = np.clip(((xy[..., 1] - y0) // self.cell_m).astype(np.int64), 0, self.rows - 1)
        return row, col

    def _ground_at(self, state: dict, xy: np.ndarray) -> np.ndarray:
        """(B, N) ground kind under points xy (B, N, 2)."""
        row, col = self.cells(xy)
        return np.take_along_axis(state["ground"].reshape(xy.shape[0], -1), row * self.cols + col, 1)

    def step_lengths_at(self, caps: np.ndarray, poses: np.ndarray, state: dict) -> np.ndarray:
        ground = self._ground_at(state, poses[..., :2])
        return np.where(ground == ICE, caps[..., 0], np.where(ground == WATER, caps[..., 1], caps.mean(axis=-1)))

    def new_state(self, B: int, N: int) -> dict:
        return {"ground": np.zeros((B, self.rows, self.cols)), "arrived": np.zeros((B, N), bool), "team": np.ones(B)}

    def reset_env(self, state: dict, b: int, rng: np.random.Generator, caps: np.ndarray) -> None:
        state["ground"][b] = SNOW
        cols = list(self.random_cols)
        state["ground"][b][:, cols] = np.where(rng.random((self.rows, len(cols))) < 0.5, ICE, WATER)
        state["arrived"][b] = False
        state["team"][b] = caps.shape[0]

    def update(self, state: dict, poses: np.ndarray, type_ids: np.ndarray, caps: np.ndarray, mask: np.ndarray) -> dict:
        _, col = self.cells(poses[..., :2])
        new = (col == self.goal_col) & mask & ~state["arrived"]
        state["arrived"] |= new
        return {"arrived": new.sum(axis=1).astype(float)}

    def done(self, state: dict) -> np.ndarray:
        return state["arrived"].sum(axis=1) >= state["team"]

    def progress(self, state: dict) -> np.ndarray:
        return state["arrived"].sum(axis=1) / state["team"]

    def task_features(self, state, poses, type_ids, caps, mask) -> np.ndarray:
        xy = poses[..., :2]
        here = self._ground_at(state, xy)
        ahead = self._ground_at(state, xy + np.array([self.cell_m, 0.0]))
        up, down = (self._ground_at(state, xy + np.array([0.0, s * self.cell_m])) for s in (1.0, -1.0))
        # the better side for this robot: the one whose ground is its fast one
        fast = np.where(type_ids == 0, ICE, WATER)
        side = np.where(up == fast, up, down)
        x_goal = ARENA[0] + self.goal_col * self.cell_m - xy[..., 0]
        return np.stack([here, ahead, side, x_goal, state["arrived"].astype(float)], axis=-1)

    def global_features(self, state: dict) -> np.ndarray:
        B = state["ground"].shape[0]
        return np.concatenate([state["ground"].reshape(B, -1), self.progress(state)[:, None]], axis=-1)

    # -- the scripted references ------------------------------------------------------------------
    def _time_to_go(self, state: dict, speeds: np.ndarray) -> np.ndarray:
        """(B, N, rows, cols) time (env steps) from each cell to the goal column for each robot of
        ground speeds ``speeds`` (B, N, 2): relaxation of cost(cell) = crossing time + the least
        neighbour's, all robots at once (no per-robot loop)."""
        g = state["ground"][:, None]  # (B, 1, R, C)
        ice, water = speeds[..., 0][..., None, None], speeds[..., 1][..., None, None]
        speed = np.where(g == ICE, ice, np.where(g == WATER, water, (ice + water) / 2))
        cross = self.cell_m / np.maximum(speed, 1e-6)
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

    def _targets(self, state: dict, centres: np.ndarray, speeds: np.ndarray, mask: np.ndarray) -> tuple:
        """Each robot's next cell centre (B, N, 2): the neighbour (or its own cell) with the least time to go."""
        cost = self._time_to_go(state, speeds)  # (B, N, R, C)
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

    def scripted_actions(self, state, poses, type_ids, caps, mask) -> np.ndarray:
        """The scripted reference (module docstring)."""
        centres = poses[..., :2]
        target, ok = self._targets(state, centres, caps, mask)
        return self.drive(state, poses, caps, mask, target, ok)

    def blind_scripted_actions(self, state, poses, type_ids, caps, mask) -> np.ndarray:
        """The same, every cell believed equally fast: the shortest way, whatever the ground."""
        centres = poses[..., :2]
        target, ok = self._targets(state, centres, np.full(caps.shape, 0.1), mask)
        return self.drive(state, poses, caps, mask, target, ok)

    # -- diagnostics, drawing and export ------------------------------------------------------------
    end_count_names = ("not_arrived",)

    def end_counts(self, state: dict) -> dict[str, np.ndarray]:
        return {"not_arrived": state["team"] - state["arrived"].sum(axis=1)}

    type_colors: ClassVar[dict] = {"ice": (66, 133, 244), "water": (0, 150, 136)}
    counters_name = "arrived"

    def areas(self, state: dict | None = None, b: int = 0) -> tuple[Area, ...]:
        """The goal column and, with a state, env ``b``'s ice (light) and water (dark) cells."""
        x0, x1, y0, y1 = ARENA
        g = self.goal_col * self.cell_m + x0
        out = [Area("goal", "box", (g, x1, y0, y1), (50, 170, 80), "goal")]
        if state is not None:
            for r, c in zip(*np.nonzero(state["ground"][b] != SNOW)):
                kind = "ice" if state["ground"][b, r, c] == ICE else "water"
                box = (
                    x0 + c * self.cell_m,
                    x0 + (c + 1) * self.cell_m,
                    y0 + r * self.cell_m,
                    y0 + (r + 1) * self.cell_m,
                )
                out.append(Area(f"{kind}_{r}_{c}", "box", box, (150, 200, 240) if kind == "ice" else (20, 60, 160), ""))
        return tuple(out)

    def rings(self, caps: np.ndarray, type_ids: np.ndarray) -> tuple[Ring, ...]:
        return (
            Ring(
                "step",
                np.ones(caps.shape[0], bool),
                caps.mean(axis=-1),
                (120, 120, 120),
                "dotted ring: step on snow",
                True,
            ),
        )

    def counters(self, state: dict, b: int, n: int) -> dict[str, float]:
        return {"arrived": float(state["arrived"][b, :n].sum())}

    def status_text(self, state: dict, b: int, counters: dict[str, float]) -> str:
        return f"arrived {int(counters['arrived'])}/{int(state['team'][b])}"

    def layout(self, state: dict, b: int) -> dict[str, list]:
        return {"ground": state["ground"][b].tolist()}

    def set_layout(self, state: dict, b: int, layout: dict[str, list]) -> None:
        state["ground"][b] = np.asarray(layout["ground"], dtype=float)


ARCTIC = ArcticTransport
