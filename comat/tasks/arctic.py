"""Arctic Transport (``arctic_v2``): every ice and water robot must cross a field of ice, open water
and snow to the far side. Ice cells hold pressure ridges and water cells currents, each needing a
speed on that ground that only some robots have, and the needs are drawn against the team's own
speeds: which cells a robot can cross, and whether a detour over its better ground pays, depend on
its actual speeds, not on its type. Crossers see little; the scout sees far, and what any robot
has seen the whole team knows.

Meant for both families of the reference ladder: *capability* (U_cap: the scripted plan knows each
robot's speeds, the type-only plan its type's mean) and *size* (U_size ∪ U_scale: the blind plan
knows neither types nor capabilities).

| | |
|---|---|
| Agents | ``robot_0 … robot_{n-1}``, n = 2…20; types ``ice``, ``water`` and ``scout``: >= 1 ice and >= 1 water robot, and one scout in every drawn team of 3 or more (a team may lack a scout: ``optional_types``); team changes every episode as in every comat task |
| Capabilities | [ice speed m, water speed m, sight m]: the waypoint step per env step on ice, in water (on snow: their mean); how far the robot sees |
| Actions | Discrete(5): 0 stay, 1 +x, 2 −x, 3 +y, 4 −y — a waypoint one step away for the robot's projected point, the step set by the cell under the robot |
| Step | 29 control ticks of 0.033 s (0.96 s): waypoint controller → safety filter → MuJoCo |
| Observation | Box(40,) float64, below |
| State | Box(121 + S·40,): the 8 × 5 cells' ground and needs as the team knows them (ground +1 ice, −1 water, 0 snow or not seen; need / 0.2 m, 0 none or not seen), which cells it has seen, the crossers' fraction arrived, then the observations of S = ``state_robots`` slots |
| Horizon | 40 steps; ends early when every crosser has arrived |
| Field | the arena in 0.4 m cells, 8 columns × 5 rows; the four middle columns (x ∈ [−0.8, 0.8]) are the field, each of its 20 cells drawn on its own per episode: ice (0.4), water (0.4) or snow (0.2); the rest is snow. An ice or water cell has, with probability 0.7, a *need*: U(0.8, 1.1) × the speed on that ground of one of the team's robots, drawn at random (a scout or a robot of the other type too). A field is drawn again (at most 30 draws; then the best) until every robot faster than 0.1 m on its better ground (every crosser of the training sets, no scout) has a way across, knowing the field, at most 1.5 times as long as were every field cell its better ground without needs |
| Goal | columns 6 and 7 (x >= 0.8 m) |
| Seen | a cell is seen, for good, once a robot stands in it or its centre lies within a robot's sight; at the start, from where the robots start |
| Spawn | robots >= 0.3 m apart in x ∈ [−1.45, −0.85], y ∈ [−0.85, 0.85] (widened toward +x for teams over 18), random headings |

Observation layout (per robot; the cells as the team knows them; the window: the robot's cell's row
and the rows beside it (row offsets −1, 0, +1) × its cell's column and the two ahead (column offsets
0, +1, +2), row offset major: window cell k = 3 · (row offset + 1) + column offset; a cell off the
arena reads need 1, seen 1):

| index | feature |
|---|---|
| 0–1 | x, y (m) |
| 2–3 | cos θ, sin θ |
| 4–6 | type one-hot (ice, water, scout) |
| 7–9 | capabilities: ice speed / 0.2 m, water speed / 0.2 m, sight / 1 m |
| 10–18 | the window's ground: +1 ice, −1 water, 0 snow or not seen |
| 19–27 | the window's needs / 0.2 m (0: none or not seen) |
| 28–36 | the window's seen flags |
| 37 | x-offset (m) to the goal (x = 0.8 m) |
| 38 | 1 if the robot has arrived |
| 39 | the team's fraction of the field's 20 cells seen |

What a robot must decide — can I cross that cell, is the detour worth it — it reads from its own
speeds (7–8) against the cells' ground and needs; its teammates' speeds and where they are come to
it through the model (edges, attention), not the observation.

Composition sets (``coalitions=``; :mod:`comat.team`; ice speed / water speed / sight, m):

* ``train`` (U_train): 3, 5 or 7 robots; ice robots U(0.12, 0.17) / U(0.03, 0.07) / U(0.25,
  0.45), water robots the two speeds swapped, scouts U(0.06, 0.085) on both grounds / U(0.8, 1.0):
  on its own ground a crosser is 1.7 to 5.7 times as fast as on the other.
* ``val``: like U_train from another stream; ``size``: sizes 2…20, U_train's ranges (a 2-robot
  team has no scout).
* ``test`` (U_test): 2, 4, 6 or 8 robots; own ground U(0.12, 0.18), other ground U(0.025, 0.08),
  crossers' sight U(0.2, 0.5); scouts U(0.055, 0.09) / U(0.7, 1.1); ``scale``: 10, 12, 16 or 20
  robots with U_test's ranges.
* ``capability`` (U_cap): every value outside its type's U_train range: crossers' own ground
  [0.09, 0.12) ∪ (0.17, 0.19], other ground [0.005, 0.03) ∪ (0.07, 0.11] (so a crosser's other
  ground may be nearly as fast as its own, or all but impassable), sight [0.15, 0.25) ∪ (0.45,
  0.6]; scouts [0.045, 0.06) ∪ (0.085, 0.1] / [0.55, 0.8) ∪ (1.0, 1.3] (0.19 m: 0.2 m/s over one
  0.96 s step).

Rules (after every step): a robot's waypoint step is its speed on the ground under its centre (on
snow the mean of its two speeds), or 0.01 m on a cell whose need is above that speed (a cell takes
40 steps to crawl across). An ice or water robot whose centre is in the goal (x >= 0.8 m) has
*arrived*, for good. Progress is the crossers' fraction arrived; a scout need not cross.

Reward (shared) = named terms: ``arrived`` +1 per crosser arriving, ``time`` −0.05 per step,
``violation`` −5 in a step with any robot–robot contact, Robotarium-style collision or boundary
exit.

References (the ladder, :mod:`comat.envs.heuristics`; ``results/sets/validity.md``): the scripted
plan gives each robot its own time-to-go field over the cells, for its own speeds (``caps``; the
state's copy of each robot's sight, kept for the rules, is never read), on the field as the team
knows it: a cell costs its crossing time (40 steps where the robot misses its need), a cell not
seen yet its expected crossing time over the ground's odds (no need), a move to another row 1.5
steps more (the robot turns); a robot heads for the neighbouring cell with the least time to leave
its own cell toward it plus the time to go from there, and drives on to the far wall once arrived;
scouts trail 0.4 m behind the rearmost crosser still crossing, on the nearest row border (between
the crossers' lanes), no closer to the goal than their sight. ``type_only`` is that plan with every
robot's capabilities its type's mean over the set's bands. The blind plan
(``blind_scripted_actions``) believes every robot 0.1 m fast on every ground (so it meets every
need up to 0.1 m): the quickest way around the needs it believes unmet, whatever the ground and
whoever the robot; scouts cross too. ``constant``: +x.

Coordination (:attr:`ArcticTransport.coordination_name`): *speed lost to the ground*, the mean over
the crossers still in the field of 1 − their step on the cell under them / their better speed
(ice or water): 0 when every crosser is on ground where it is at its best, near 1 for crawling;
lower is better.

Design measurements (coalition seed 1, episode seed 2,000,003, 20 coalitions × 3 episodes,
unicycle; progress %, paired 95 % t-intervals over coalitions): scripted 98.3 on U_train and 97.3
on U_size ∪ U_scale, where scripted − blind is 29.1 [25.3, 33.0]; scripted − type_only 19.3
[14.5, 24.1] on U_cap (2.7 on U_train); the blind plan 4–13 points above the constant action on
every set (U_train 69.2 against 65.5).

This follows MARBLER's and JaxRobotarium's Arctic Transport (ice and water robots crossing a
field, a drone that sees for them); here the far-seeing robot is a slow ground robot.

Version history: v0 — first version (issue 49): ice and water robots only, every robot seeing the
ground under it and next to it, every robot counted, the field all ice or water, a 55-step
horizon. v1 — the scout, the team's knowledge of the ground (seen cells) and the crossers' sight;
only crossers counted; snow cells in the field (probability 0.3); slow ground U(0.02, 0.03) in
U_train (v0: U(0.02, 0.035)) and a 48-step horizon (issue 49: in v0 the capability-blind
reference was 8 points below the scripted one on U_cap, where 15 were asked for). v2 (issue 64) —
v1 tested types, not capabilities (science review 2026-12b §D): with every cell's crossing cost
alike its blind twin took the straight +x way and equalled the constant action on four sets;
which ground is fast was fixed by the type (ratio >= 3 on every set); observations 11–12 handed
each robot its type's fast side; on U_scale the scripted plan (76.6) was below the constant action
(77.2), arrived robots parking in the one-column goal; v1 was re-tuned after v0 missed its
criterion and judged on the same seed. v2 adds the cells' needs, drawn against the team's actual
speeds, and draws a field until every crosser has a good way across; other-ground speeds U(0.03,
0.07) in U_train (a ratio of 1.7 to 5.7 to the own ground, so whether a detour pays depends on
the speeds) and U_cap bands that reach across the other type's (a crosser's two speeds may be
alike); a four-column field and a two-column goal (x >= 0.8 m; the arrived drive on to the far
wall); a 40-step horizon; observations of a 3 × 3 window of cells (ground, need, seen) in place
of the fast-side hint; a planner that reads capabilities only through ``caps``, a blind plan
believing one speed for every robot, and scouts that trail the crossers instead of standing in
their lanes. Designed on coalition seed 1 and episode seed 2,000,003 only.
"""

from __future__ import annotations

from dataclasses import replace
from typing import ClassVar

import numpy as np

# (an export ships this file beside task_logic.py, with this import made local: sim2real/export.py)
from comat.task_logic import ARENA, WAYPOINT_LIMITS, Area, Marks, Ring, TaskLogic

__all__ = ["ARCTIC", "ArcticTransport"]

ICE, WATER, SNOW = 1.0, -1.0, 0.0
"""Ground kinds as the state and observations hold them."""
SCOUT = 2
"""The scout's type id."""
CRAWL_M = 0.01
"""The waypoint step (m) of a robot on a cell whose need it does not meet: 40 env steps to cross."""

GROUND_COLORS: dict[str, tuple[int, int, int]] = {
    "ice": (60, 160, 230),
    "water": (20, 50, 150),
    "snow": (150, 150, 160),
}
"""How each ground kind is drawn (and named in the legend)."""

OWN = (0.12, 0.17)
OTHER = (0.03, 0.07)
SIGHT = (0.25, 0.45)
SCOUT_SPEED = (0.06, 0.085)
SCOUT_SIGHT = (0.8, 1.0)
"""U_train's ranges (m): a crosser's speed on its type's own ground (an ice robot's on ice) and on
the other, its sight; a scout's speed on either ground and its sight."""

OWN_OUT = ((0.09, 0.119999), (0.170001, 0.19))
OTHER_OUT = ((0.005, 0.029999), (0.070001, 0.11))
SIGHT_OUT = ((0.15, 0.249999), (0.450001, 0.6))
SCOUT_SPEED_OUT = ((0.045, 0.059999), (0.085001, 0.1))
SCOUT_SIGHT_OUT = ((0.55, 0.799999), (1.000001, 1.3))
"""U_cap's bands (m): every value outside its type's U_train range, below or above."""


class ArcticTransport(TaskLogic):
    """Arctic transport (module docstring). State per env: ground, need (m) and seen (B, 5, 8),
    arrived (B, N), who must cross (B, N) and each robot's sight (B, N) (for :meth:`set_starts`; the
    planners read capabilities only from their ``caps`` argument)."""

    name = "arctic"
    meant_for = ("capability", "size")
    """Both families (its spec sheet says why; :mod:`comat.eval.validity` measures them)."""
    version = 2
    title = "Arctic Transport"
    types = ("ice", "water", "scout")
    optional_types = ("scout",)
    capabilities = ("ice_speed_m", "water_speed_m", "sight_m")
    capability_scale = np.array([0.2, 0.2, 1.0])
    horizon = 40
    ticks_per_step = 29
    spawn_box = (-1.45, -0.85, -0.85, 0.85)
    cell_m = 0.4
    cols, rows = 8, 5
    field_cols = (2, 3, 4, 5)
    goal_col = 6
    """The goal: columns 6 and 7 (x >= 0.8 m)."""
    ground_odds = (0.4, 0.4)
    """Probability that a field cell is ice, water (else snow)."""
    need_odds = 0.7
    need_range = (0.8, 1.1)
    """An ice or water cell has, with probability ``need_odds``, a need (a pressure ridge, a current):
    the speed on that ground a robot must have to cross it (m per env step), drawn against the team
    as U(need_range) × the speed on that ground of one of its robots, chosen at random; a robot
    slower than the need crawls (:data:`CRAWL_M`), a robot as fast crosses at its speed."""
    need_scale_m = 0.2
    """Observations and the state hold needs / this."""
    window = ((0, 1, 2), (-1, 0, 1))
    """The cells a robot observes: column offsets (ahead in +x) × row offsets."""
    n_task_features = 3 * 9 + 3
    reward_terms = ("arrived", "time", "violation")
    reward_weights: ClassVar[dict] = {"arrived": 1.0, "time": -0.05, "violation": -5.0}
    reset_uses_starts = True

    capability_limits = ((0.005, 0.19), (0.005, 0.19), (0.1, 1.5))
    required = ((0, 1, 2), (0, 1, 2), (0, 1, 2))
    capability_bands: ClassVar[dict] = {
        "train": {
            "ice": ((OWN,), (OTHER,), (SIGHT,)),
            "water": ((OTHER,), (OWN,), (SIGHT,)),
            "scout": ((SCOUT_SPEED,), (SCOUT_SPEED,), (SCOUT_SIGHT,)),
        },
        "test": {
            "ice": (((0.12, 0.18),), ((0.025, 0.08),), ((0.2, 0.5),)),
            "water": (((0.025, 0.08),), ((0.12, 0.18),), ((0.2, 0.5),)),
            "scout": (((0.055, 0.09),), ((0.055, 0.09),), ((0.7, 1.1),)),
        },
        "capability": {
            "ice": (OWN_OUT, OTHER_OUT, SIGHT_OUT),
            "water": (OTHER_OUT, OWN_OUT, SIGHT_OUT),
            "scout": (SCOUT_SPEED_OUT, SCOUT_SPEED_OUT, SCOUT_SIGHT_OUT),
        },
    }
    set_streams = 30
    """The composition sets' random streams are 30… (PCP and HMT 0–11, forage 12–17, navigation
    18–23, sensors 24–29)."""

    # -- ground and speeds ------------------------------------------------------------------------
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

    def _steps_on(self, ground: np.ndarray, need: np.ndarray, caps: np.ndarray) -> np.ndarray:
        """Each robot's step (…) on cells of kinds ``ground`` (…) and needs ``need`` (…) for capabilities
        caps (…, 3): its speed on that ground where it meets the need, else :data:`CRAWL_M`; on snow
        the mean of its two speeds."""
        own = np.where(ground == ICE, caps[..., 0], np.where(ground == WATER, caps[..., 1], self.step_lengths(caps)))
        return np.where((ground == SNOW) | (own >= need), own, CRAWL_M)

    def step_lengths_at(self, caps: np.ndarray, poses: np.ndarray, state: dict) -> np.ndarray:
        xy = poses[..., :2]
        return self._steps_on(self._at(state["ground"], xy), self._at(state["need"], xy), caps)

    # -- episodes ---------------------------------------------------------------------------------
    def new_state(self, B: int, N: int) -> dict:
        return {
            "ground": np.zeros((B, self.rows, self.cols)),
            "need": np.zeros((B, self.rows, self.cols)),
            "seen": np.zeros((B, self.rows, self.cols), bool),
            "arrived": np.zeros((B, N), bool),
            "crosser": np.zeros((B, N), bool),
            "sight": np.zeros((B, N)),
        }

    route_slack = 1.5
    """A drawn field is kept when each robot fast enough to cross (:attr:`crosser_speed_m`) has a way
    across it (full knowledge, its own speeds, from where it starts) at most this many times as long
    as were every field cell its fastest ground without needs."""
    crosser_speed_m = 0.1
    """The robots the draw checks: those faster than this (m) on their better ground (every crosser
    of the training sets, no scout of any set; a reset is not told the robots' types)."""
    max_draws = 30

    def _random_field(self, rng: np.random.Generator, caps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Ground and needs (5, 8) for a team of capabilities caps (n, 3): snow without needs outside
        the field; each field cell ice, water or snow (:attr:`ground_odds`), an ice or water cell with
        a need (:attr:`need_odds`) drawn against the team's speeds on its ground."""
        p_ice, p_water = self.ground_odds
        cols = list(self.field_cols)
        shape = (self.rows, len(cols))
        u, has, scale = rng.random(shape), rng.random(shape) < self.need_odds, rng.uniform(*self.need_range, shape)
        who = rng.integers(0, caps.shape[0], shape)
        ground, need = np.full((self.rows, self.cols), SNOW), np.zeros((self.rows, self.cols))
        kind = np.where(u < p_ice, ICE, np.where(u < p_ice + p_water, WATER, SNOW))
        ground[:, cols] = kind
        speed = np.where(kind == ICE, caps[who, 0], caps[who, 1])
        need[:, cols] = np.where(has & (kind != SNOW), scale * speed, 0.0)
        return ground, need

    def route_ratios(self, ground: np.ndarray, need: np.ndarray, caps: np.ndarray, starts: np.ndarray) -> np.ndarray:
        """(n,) each robot's quickest time across the field ``ground``, ``need`` (5, 8) from its start
        (n, ≥2), over the same time were every field cell its fastest ground without needs, for speeds
        caps (n, 3)."""
        state = {"ground": ground[None], "need": need[None], "seen": np.ones((1, self.rows, self.cols), bool)}
        cross = self.crossing_steps(state, caps[None])  # (1, n, R, C)
        field = np.isin(np.arange(self.cols), self.field_cols)
        ideal = np.where(field, (self.cell_m / caps[:, :2].max(axis=-1))[None, :, None, None], cross)
        goal = self._goal_column()
        row, col = self.cells(np.asarray(starts, dtype=float)[:, :2])
        at = np.arange(caps.shape[0]), row, col
        return self.time_to_go(cross, goal)[0][at] / self.time_to_go(ideal, goal)[0][at]

    def draw_field(
        self, rng: np.random.Generator, caps: np.ndarray, starts: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """A new field (ground, need) for a team of capabilities caps (n, 3) starting at ``starts``
        (n, 3): drawn (:meth:`_random_field`) until every robot faster than :attr:`crosser_speed_m` has
        :meth:`route_ratios` at most :attr:`route_slack`; after :attr:`max_draws` draws, the draw whose
        worst ratio is least."""
        checked = caps[:, :2].max(axis=-1) > self.crosser_speed_m
        best, best_ratio = None, np.inf
        for _ in range(self.max_draws):
            field = self._random_field(rng, caps)
            worst = float(self.route_ratios(*field, caps[checked], starts[checked]).max()) if checked.any() else 0.0
            if best is None or worst < best_ratio:
                best, best_ratio = field, worst
            if worst <= self.route_slack:
                break
        return best

    def reset_env(self, state: dict, b: int, rng: np.random.Generator, caps: np.ndarray, starts=None) -> None:
        """A new field for the robots' caps (n, 3) starting at ``starts`` (n, 3) (:meth:`draw_field`),
        and what the team sees from there. Without ``starts`` (an exported script's first reset,
        whose field :meth:`set_layout` then replaces) the first draw is kept and nothing is seen."""
        if starts is None:
            state["ground"][b], state["need"][b] = self._random_field(rng, caps)
        else:
            state["ground"][b], state["need"][b] = self.draw_field(rng, caps, np.asarray(starts, dtype=float))
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
        new = (col >= self.goal_col) & state["crosser"] & ~state["arrived"]
        state["arrived"] |= new
        return {"arrived": new.sum(axis=1).astype(float)}

    def done(self, state: dict) -> np.ndarray:
        """Every crosser of the team arrived (B,) (a team without crossers never is)."""
        need = state["crosser"].sum(axis=1)
        return (need > 0) & (state["arrived"].sum(axis=1) >= need)

    def progress(self, state: dict) -> np.ndarray:
        """The crossers' fraction arrived (B,) (0 before the first step)."""
        return state["arrived"].sum(axis=1) / np.maximum(state["crosser"].sum(axis=1), 1)

    # -- what robots observe ----------------------------------------------------------------------
    def known(self, state: dict) -> tuple[np.ndarray, np.ndarray]:
        """(B, 5, 8) twice: the ground and the needs as the team knows them (snow, 0 where not seen)."""
        return np.where(state["seen"], state["ground"], SNOW), np.where(state["seen"], state["need"], 0.0)

    def _window(self, state: dict, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The ground (±1, 0), need (/ :attr:`need_scale_m`) and seen (1) channels (B, N, 9) of the cells
        around each robot (:attr:`window`; row offset major), as the team knows them; cells off the grid
        read as seen walls (need 1)."""
        row, col = self.cells(xy)
        dcol, drow = (np.array(d) for d in self.window)
        grid = row.shape + (drow.size, dcol.size)
        r = np.broadcast_to(row[..., None, None] + drow[:, None], grid).reshape(*row.shape, -1)  # (B, N, 9)
        c = np.broadcast_to(col[..., None, None] + dcol[None, :], grid).reshape(*col.shape, -1)
        off = (r < 0) | (r >= self.rows) | (c < 0) | (c >= self.cols)
        flat = (np.clip(r, 0, self.rows - 1) * self.cols + np.clip(c, 0, self.cols - 1)).reshape(xy.shape[0], -1)
        B = xy.shape[0]
        ground, need = (np.take_along_axis(g.reshape(B, -1), flat, 1).reshape(off.shape) for g in self.known(state))
        seen = np.take_along_axis(state["seen"].reshape(B, -1), flat, 1).reshape(off.shape)
        need = np.where(off, 1.0, need / self.need_scale_m)
        return np.where(off, 0.0, ground), need, (seen | off).astype(float)

    def task_features(self, state, poses, type_ids, caps, mask) -> np.ndarray:
        xy = poses[..., :2]
        ground, need, seen = self._window(state, xy)
        x_goal = ARENA[0] + self.goal_col * self.cell_m - xy[..., 0]
        field = state["seen"][:, :, list(self.field_cols)].mean(axis=(1, 2))
        B, N = mask.shape
        tail = np.stack([x_goal, state["arrived"].astype(float), np.broadcast_to(field[:, None], (B, N))], axis=-1)
        return np.concatenate([ground, need, seen, tail], axis=-1)

    def global_features(self, state: dict) -> np.ndarray:
        B = state["ground"].shape[0]
        ground, need = self.known(state)
        return np.concatenate(
            [
                ground.reshape(B, -1),
                need.reshape(B, -1) / self.need_scale_m,
                state["seen"].reshape(B, -1).astype(float),
                self.progress(state)[:, None],
            ],
            axis=-1,
        )

    # -- the scripted references ------------------------------------------------------------------
    def crossing_steps(self, state: dict, caps: np.ndarray) -> np.ndarray:
        """(B, N, 5, 8) env steps each robot of capabilities ``caps`` (B, N, 3) needs to cross each
        cell, on the field as the team knows it: a cell not seen yet costs its expected crossing time
        over the ground's odds (:attr:`ground_odds`; no need); outside the field: snow, known."""
        sp = caps[..., None, None, :]  # (B, N, 1, 1, 3)
        known = self.cell_m / np.maximum(self._steps_on(state["ground"][:, None], state["need"][:, None], sp), CRAWL_M)
        p_ice, p_water = self.ground_odds
        one = np.ones(known.shape[:2] + (1, 1))
        odds = ((ICE, p_ice), (WATER, p_water), (SNOW, 1 - p_ice - p_water))
        expected = sum(p * self.cell_m / np.maximum(self._steps_on(kind * one, 0.0, sp), CRAWL_M) for kind, p in odds)
        field = np.isin(np.arange(self.cols), self.field_cols)
        return np.where(state["seen"][:, None] | ~field, known, expected)

    turn_steps = 1.5
    """What a move to the next row costs in the plans beyond its cell's crossing time (env steps):
    a robot turns to ±y and back."""

    def time_to_go(self, cross: np.ndarray, goal: np.ndarray) -> np.ndarray:
        """(B, N, 5, 8) env steps from each cell to the goal cells ``goal`` (…, 5, 8) (0 there) for
        crossing times ``cross`` (B, N, 5, 8): the relaxation cost(cell) = crossing time + the least
        neighbour's, every robot at once (no per-robot loop)."""
        cost = np.where(goal, 0.0, np.inf) + np.zeros(cross.shape)
        for _ in range(self.rows * self.cols):
            pad = np.pad(cost, ((0, 0), (0, 0), (1, 1), (1, 1)), constant_values=np.inf)
            across = np.minimum(pad[..., :-2, 1:-1], pad[..., 2:, 1:-1]) + self.turn_steps
            best = np.minimum.reduce([across, pad[..., 1:-1, :-2], pad[..., 1:-1, 2:]])
            new = np.where(goal, 0.0, np.minimum(cost, cross + best))
            if np.array_equal(new, cost):
                break
            cost = new
        return cost

    def _next_cells(self, cost: np.ndarray, centres: np.ndarray, step: np.ndarray) -> np.ndarray:
        """Each robot's next cell centre (B, N, 2): the neighbour with the least time to leave its cell
        toward it (the distance to their border over the robot's ``step`` (B, N) here) plus the
        neighbour's time to go ``cost`` (B, N, 5, 8); a robot in a cell of time to go 0 stays there.
        Counting from where the robot is (not from its cell) takes a robot pushed into a cell it
        crawls in back out the way it came."""
        row, col = self.cells(centres)
        x0, _, y0, _ = ARENA
        left = x0 + col * self.cell_m - centres[..., 0]
        below = y0 + row * self.cell_m - centres[..., 1]
        moves = np.array([[0, 1], [0, -1], [1, 0], [-1, 0]])  # (drow, dcol): +x, -x, +y, -y
        to_border = np.stack([left + self.cell_m, -left, below + self.cell_m, -below], -1)  # (B, N, 4)
        r, c = row[..., None] + moves[:, 0], col[..., None] + moves[:, 1]
        inside = (r >= 0) & (r < self.rows) & (c >= 0) & (c < self.cols)
        B, N = centres.shape[:2]
        flat = np.clip(r, 0, self.rows - 1) * self.cols + np.clip(c, 0, self.cols - 1)
        there = np.take_along_axis(cost.reshape(B, N, -1), flat, 2)  # (B, N, 4)
        there = there + np.array([0.0, 0.0, self.turn_steps, self.turn_steps])
        value = np.where(inside, np.maximum(to_border, 0.0) / np.maximum(step, CRAWL_M)[..., None] + there, np.inf)
        k = np.argmin(value, axis=-1)
        tr, tc = np.take_along_axis(r, k[..., None], 2)[..., 0], np.take_along_axis(c, k[..., None], 2)[..., 0]
        here = np.take_along_axis(cost.reshape(B, N, -1), (row * self.cols + col)[..., None], 2)[..., 0]
        tr, tc = np.where(here == 0, row, tr), np.where(here == 0, col, tc)
        target = np.stack([x0 + (tc + 0.5) * self.cell_m, y0 + (tr + 0.5) * self.cell_m], -1)
        # in the goal: on to the far wall, out of the way of those still arriving
        target[..., 0] = np.where(tc >= self.goal_col, WAYPOINT_LIMITS[1], target[..., 0])
        return target

    def _goal_column(self) -> np.ndarray:
        """(1, 1, 5, 8) the goal's cells."""
        return (np.arange(self.cols) >= self.goal_col)[None, None, None, :] & np.ones((self.rows, 1), bool)

    scout_lag_m = 0.4
    """A scripted scout keeps this far (m) behind the rearmost crosser still crossing, out of the
    crossers' way."""

    def lookouts(self, state: dict, centres: np.ndarray, caps: np.ndarray, type_ids: np.ndarray, mask) -> np.ndarray:
        """(B, N, 2) where each scripted scout heads: forward only, to :attr:`scout_lag_m` behind the
        rearmost crosser still crossing but no further than where its sight (``caps``) reaches the
        goal column's edge, on the row border nearest to it (y = ±0.2, ±0.6 m: between the
        crossers' lanes along the row centres)."""
        x0 = ARENA[0]
        crossing = mask & (type_ids != SCOUT) & ~state["arrived"]
        goal_x = x0 + self.goal_col * self.cell_m
        rear = np.where(crossing, centres[..., 0], goal_x).min(axis=1, keepdims=True)  # (B, 1)
        x = np.maximum(np.minimum(rear - self.scout_lag_m, goal_x - caps[..., 2]), centres[..., 0])
        borders = np.array([-0.6, -0.2, 0.2, 0.6])
        y = borders[np.argmin(np.abs(centres[..., 1:2] - borders), axis=-1)]
        return np.stack([x, y], -1)

    def scripted_actions(self, state, poses, type_ids, caps, mask) -> np.ndarray:
        """The scripted reference (module docstring): each crosser follows its own time-to-go field
        over the ground as the team knows it, for its own speeds; scouts trail the crossers."""
        centres = poses[..., :2]
        cost = self.time_to_go(self.crossing_steps(state, caps), self._goal_column())
        target = self._next_cells(cost, centres, self.step_lengths_at(caps, poses, state))
        scout = (type_ids == SCOUT) & mask
        target = np.where(scout[..., None], self.lookouts(state, centres, caps, type_ids, mask), target)
        return self.drive(state, poses, caps, mask, target, mask)

    blind_speed_m = 0.1
    """What the blind twin believes every robot's step on ice, water and snow (m)."""

    def blind_scripted_actions(self, state, poses, type_ids, caps, mask) -> np.ndarray:
        """The plan without types or capabilities: every robot believed equally fast on ice, water
        and snow (:attr:`blind_speed_m`), so each takes the shortest way through the cells whose
        needs that speed meets, whatever the ground; scouts cross too."""
        centres = poses[..., :2]
        alike = np.broadcast_to(np.array([self.blind_speed_m, self.blind_speed_m, 0.0]), caps.shape)
        cost = self.time_to_go(self.crossing_steps(state, alike), self._goal_column())
        target = self._next_cells(cost, centres, self.step_lengths_at(alike, poses, state))
        return self.drive(state, poses, caps, mask, target, mask)

    # -- coordination -----------------------------------------------------------------------------
    coordination_name = "speed lost to the ground"
    coordination_doc = (
        "mean over the crossers still in the field of 1 − their step on the cell under them / their better "
        "speed (on ice or in water): how far the team keeps each crosser off ground and needs that slow it "
        "(1: crawling); lower is better"
    )

    def coordination(self, state, poses, type_ids, caps, mask) -> np.ndarray:
        """(B,) :attr:`coordination_doc` (0 where no crosser is in the field)."""
        _, col = self.cells(poses[..., :2])
        active = state["crosser"] & ~state["arrived"] & np.isin(col, self.field_cols)
        lost = 1.0 - self.step_lengths_at(caps, poses, state) / np.maximum(caps[..., :2].max(axis=-1), 1e-9)
        return np.where(active, lost, 0.0).sum(axis=1) / np.maximum(active.sum(axis=1), 1)

    # -- diagnostics, drawing and export ------------------------------------------------------------
    end_count_names = ("not_arrived",)

    def end_counts(self, state: dict) -> dict[str, np.ndarray]:
        return {"not_arrived": (state["crosser"] & ~state["arrived"]).sum(axis=1).astype(float)}

    type_colors: ClassVar[dict] = {"ice": (66, 133, 244), "water": (0, 150, 136), "scout": (244, 180, 0)}
    counters_name = "arrived"

    def _field_cells(self, state: dict, b: int) -> list[tuple[str, int, int, str]]:
        """Env ``b``'s field cells: (area name, row, column, kind)."""
        ground = state["ground"][b]
        names = {ICE: "ice", WATER: "water", SNOW: "snow"}
        return [
            (f"{names[ground[r, c]]}_{r}_{c}", r, c, names[ground[r, c]])
            for r in range(self.rows)
            for c in self.field_cols
        ]

    def areas(self, state: dict | None = None, b: int = 0) -> tuple[Area, ...]:
        """The goal (columns 6–7) and, with a state, env ``b``'s field cells, each drawn in its ground's
        colour (:data:`GROUND_COLORS`; labelled "?" while the team has not seen it, :meth:`area_labels`)."""
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
                out.append(Area(name, "box", box, GROUND_COLORS[kind], labels[name]))
        return tuple(out)

    def area_labels(self, state: dict, b: int) -> dict[str, str]:
        """Each field cell's label now: "?" until the team has seen it, then a cell's need (m), if any."""
        seen, need = state["seen"][b], state["need"][b]
        return {
            name: ("?" if not seen[r, c] else f"{need[r, c]:.2f}" if need[r, c] > 0 else "")
            for name, r, c, kind in self._field_cells(state, b)
        }

    def marks(self, state: dict, b: int, caps: np.ndarray, type_ids: np.ndarray) -> Marks:
        """The base's marks with the ground kinds in the legend ("ground: ice", … : the types are
        "ice" and "water" too)."""
        out = super().marks(state, b, caps, type_ids)
        return replace(out, legend=tuple((f"ground: {k}", c) for k, c in GROUND_COLORS.items()) + out.legend)

    def rings(self, caps: np.ndarray, type_ids: np.ndarray) -> tuple[Ring, ...]:
        return (Ring("sight", np.ones(caps.shape[0], bool), caps[:, 2], (120, 120, 120), "dotted ring: sight", True),)

    def counters(self, state: dict, b: int, n: int) -> dict[str, float]:
        return {"arrived": float(state["arrived"][b, :n].sum())}

    def status_text(self, state: dict, b: int, counters: dict[str, float]) -> str:
        return f"arrived {int(counters['arrived'])}/{int(state['crosser'][b].sum())}"

    def layout(self, state: dict, b: int) -> dict[str, list]:
        return {"ground": state["ground"][b].tolist(), "need": state["need"][b].tolist()}

    def set_layout(self, state: dict, b: int, layout: dict[str, list]) -> None:
        """The field; nothing seen yet (:meth:`set_starts` shows what the team sees from its starts)."""
        state["ground"][b] = np.asarray(layout["ground"], dtype=float)
        state["need"][b] = np.asarray(layout["need"], dtype=float)
        state["seen"][b] = False

    def set_starts(self, state: dict, b: int, starts: np.ndarray) -> None:
        n = starts.shape[0]
        xy = np.asarray(starts, dtype=float)[None, :, :2]
        state["seen"][b] |= self._sees(xy, state["sight"][b : b + 1, :n], np.ones((1, n), bool))[0]


ARCTIC = ArcticTransport
