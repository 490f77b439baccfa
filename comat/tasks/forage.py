"""Level-Based Foraging (``forage_v0``): robots of different levels collect items that only a strong
enough group can lift — the team's composition decides which items it can take.

| | |
|---|---|
| Agents | ``robot_0 … robot_{n-1}``, n = 2…20; types ``heavy`` and ``light``, >= 1 of each; team changes every episode as in every comat task (``possible_agents`` the largest team, ``agents`` this episode's) |
| Capabilities | [level, speed m]: level = what the robot adds to a lift; speed = waypoint step per env step |
| Actions | Discrete(5): 0 stay, 1 +x, 2 −x, 3 +y, 4 −y — a waypoint one speed-step away for the robot's projected point |
| Step | 29 control ticks of 0.033 s (0.96 s): waypoint controller → safety filter → MuJoCo |
| Observation | Box(14,) float64, below |
| State | Box(4K + S·14,): items (x, y) ×K, level / 5 ×K, collected ×K over the env's K_max item slots (a smaller team's unused slots parked at (2.6, 0), collected), then the observations of S = ``state_robots`` slots |
| Horizon | 80 steps; ends early when every item is collected |
| Items | K(N) = 3 for N <= 5 robots, round(0.6·N) above (5 at 8, 12 at 20); >= 0.4 m apart in x ∈ [−0.3, 1.4], y ∈ [−0.8, 0.8]. Each item's level is the summed level of 1, 2 or 3 of the team's own robots (probabilities 0.1 / 0.4 / 0.5; at most the team), drawn at random, times U(0.85, 1.0): every item can be lifted by the robots it was drawn from, and most need two or three |
| Spawn | robots >= 0.3 m apart in x ∈ [−1.45, −0.75], y ∈ [−0.85, 0.85], random headings |

Observation layout (per robot):

| index | feature |
|---|---|
| 0–1 | x, y (m) |
| 2–3 | cos θ, sin θ |
| 4–5 | type one-hot (heavy, light) |
| 6–7 | capabilities (level / 5, speed / 0.2 m) |
| 8–9 | offset (m) to the nearest item not collected |
| 10 | that item's level / 5 |
| 11 | summed level of the team's robots within reach of that item / 5 (what is already there) |
| 12 | team's fraction of the item levels collected |
| 13 | 1 if any item is left |

Composition sets (``coalitions=``; :mod:`comat.team`; level / speed m per step):

* ``train`` (U_train): 3, 5 or 7 robots; heavy U(2.4, 3.4) / U(0.08, 0.12), light U(0.6, 1.0) /
  U(0.13, 0.18): heavy robots lift three times what light ones do, and move slower.
* ``val``: like U_train from another stream; ``size``: sizes 2…20, U_train's ranges.
* ``test`` (U_test): 2, 4, 6 or 8 robots; heavy U(2.2, 3.8) / U(0.07, 0.13), light U(0.5, 1.2) /
  U(0.12, 0.19); ``scale``: 10, 12, 16 or 20 robots with U_test's ranges.
* ``capability`` (U_cap): every level and speed outside its type's U_train range: heavy level
  [1.6, 2.4) ∪ (3.4, 4.4], speed [0.06, 0.08) ∪ (0.12, 0.15]; light level [0.3, 0.6) ∪ (1.0, 1.4],
  speed [0.10, 0.13) ∪ (0.18, 0.19] (0.19 m: 0.2 m/s over one 0.96 s step, the physical limit).

Rule (after every step): an item is *collected*, for good, when the levels of the robots whose
centres are within :attr:`LevelForaging.reach_m` (0.25 m) of it add up to its level or more. A
robot can help lift several items in one step.

Reward (shared) = named terms in ``infos[agent]["reward/<term>"]``: ``collected`` +1 per unit of
level collected, ``time`` −0.05 per step, ``violation`` −5 in a step with any robot–robot contact,
Robotarium-style collision or boundary exit.

References (``results/sets/validity.md``): the scripted policy forms, item by item, a group of
the nearest free robots whose levels reach the item's level (robots left over go to an item no
group could be formed for, or wait); its capability-blind twin (``blind_scripted_actions``) forms
the same groups believing every robot has the training mean level (1.85): a group of weaker robots
than it believes waits at its item for good, one of stronger robots ties up more than needed.

Version history: v0 — first version (issue 49; after level-based foraging, Papoudakis et al. 2021,
and JaxRobotarium's Foraging).
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

# (an export ships this file beside task_logic.py, with this import made local: sim2real/export.py)
from comat.task_logic import Area, Bar, Items, Ring, TaskLogic, grid_cells, grow_slots, spread_points

__all__ = ["FORAGE", "LevelForaging"]


class LevelForaging(TaskLogic):
    """Level-based foraging (module docstring). State per env: item positions (B, K, 2), levels
    (B, K), collected (B, K), active (B, K); inactive slots are parked and collected."""

    name = "forage"
    meant_for = ("capability", "size")
    """Continuous levels decide which groups can lift an item; teams 2-20 (:mod:`comat.eval.validity`)."""
    types = ("heavy", "light")
    capabilities = ("level", "speed_m")
    capability_scale = np.array([5.0, 0.2])
    speed_capability = 1
    horizon = 80
    ticks_per_step = 29
    spawn_box = (-1.45, -0.75, -0.85, 0.85)
    item_box = (-0.3, 1.4, -0.8, 0.8)
    item_spacing = 0.4
    reach_m = 0.25
    """An item counts the levels of robots whose centres are this close (up to five robots fit
    around it at the barrier's 0.2 m spacing of projected points)."""
    level_scale = 5.0
    n_task_features = 6
    reward_terms = ("collected", "time", "violation")
    reward_weights: ClassVar[dict] = {"collected": 1.0, "time": -0.05, "violation": -5.0}
    group_sizes = (1, 2, 3)
    group_probs = (0.1, 0.4, 0.5)
    blind_level = 1.85
    """The level the capability-blind reference believes every robot has: the mean of the two types'
    U_train level ranges ((2.4 + 3.4) / 2 and (0.6 + 1.0) / 2, averaged)."""
    parked = (2.6, 0.0)

    # -- what the composition sets draw (comat.tasks registers them in comat.team) ---------------
    capability_limits = ((0.0, 5.0), (0.0, 0.19))
    """Physical limits: a level up to 5; a step up to 0.2 m/s × 0.96 s."""
    required = ((0, 1), (0, 1))
    capability_bands: ClassVar[dict] = {
        "train": {"heavy": (((2.4, 3.4),), ((0.08, 0.12),)), "light": (((0.6, 1.0),), ((0.13, 0.18),))},
        "test": {"heavy": (((2.2, 3.8),), ((0.07, 0.13),)), "light": (((0.5, 1.2),), ((0.12, 0.19),))},
        "capability": {
            "heavy": (((1.6, 2.399999), (3.400001, 4.4)), ((0.06, 0.079999), (0.120001, 0.15))),
            "light": (((0.3, 0.599999), (1.000001, 1.4)), ((0.10, 0.129999), (0.180001, 0.19))),
        },
    }
    set_streams = 12
    """The composition sets' random streams are 12… (PCP's and HMT's are 0–11)."""

    def __init__(self) -> None:
        self.largest_team: int | None = None

    @staticmethod
    def items_for(n_robots: int) -> int:
        """K(N): 3 items up to 5 robots, round(0.6 N) above."""
        return 3 if n_robots <= 5 else (6 * int(n_robots) + 5) // 10

    def max_team_size(self) -> int:
        n = self.spawn_capacity()
        while n > 0 and self.items_for(n) > grid_cells(self.item_box, self.item_spacing):
            n -= 1
        return n

    def fit_teams(self, largest: int) -> None:
        self.largest_team = int(largest)

    def step_lengths(self, caps: np.ndarray) -> np.ndarray:
        return caps[..., 1]

    def new_state(self, B: int, N: int) -> dict:
        K = self.items_for(self.largest_team if self.largest_team is not None else N)
        return {
            "items": np.broadcast_to(self.parked, (B, K, 2)).copy(),
            "level": np.zeros((B, K)),
            "collected": np.ones((B, K), bool),
            "active": np.zeros((B, K), bool),
        }

    def reserve(self, state: dict, n_robots: int) -> None:
        """Grow every env's item slots to fit a team of ``n_robots`` (the added slots inactive)."""
        k, slots = self.items_for(n_robots), state["items"].shape[1]
        if k <= slots:
            return
        grow_slots(state, k - slots, {"items": self.parked, "level": 0.0, "collected": True, "active": False})

    def reset_env(self, state: dict, b: int, rng: np.random.Generator, caps: np.ndarray) -> None:
        """K(n) items for the team of caps (n, 2), each as heavy as 1–3 of its robots together."""
        n, slots = caps.shape[0], state["items"].shape[1]
        k = self.items_for(n)
        assert k <= slots, "reserve() the item slots before resetting a larger team"
        state["items"][b] = self.parked
        state["items"][b, :k] = spread_points(rng, k, self.item_box, self.item_spacing, "forage item area", "items")
        sizes = np.minimum(rng.choice(self.group_sizes, size=k, p=self.group_probs), n)
        levels = [caps[rng.choice(n, size=int(m), replace=False), 0].sum() for m in sizes]
        state["level"][b] = 0.0
        state["level"][b, :k] = np.round(np.array(levels) * rng.uniform(0.85, 1.0, k), 2)
        state["active"][b] = np.arange(slots) < k
        state["collected"][b] = ~state["active"][b]

    def _near(self, state: dict, poses: np.ndarray, mask: np.ndarray) -> np.ndarray:
        """(B, N, K) robot i's centre within reach of item k (a real robot)."""
        d = poses[:, :, None, :2] - state["items"][:, None, :, :]
        return (d[..., 0] ** 2 + d[..., 1] ** 2 <= self.reach_m**2) & mask[..., None]

    def _present(self, state: dict, poses: np.ndarray, caps: np.ndarray, mask: np.ndarray) -> np.ndarray:
        """(B, K) summed level of the robots within reach of each item."""
        return np.einsum("bnk,bn->bk", self._near(state, poses, mask).astype(float), caps[..., 0])

    def update(self, state: dict, poses: np.ndarray, type_ids: np.ndarray, caps: np.ndarray, mask: np.ndarray) -> dict:
        lift = (self._present(state, poses, caps, mask) >= state["level"] - 1e-9) & ~state["collected"]
        state["collected"] |= lift
        return {"collected": (state["level"] * lift).sum(axis=1)}

    def done(self, state: dict) -> np.ndarray:
        """Every item of the team collected (B,)."""
        return state["collected"].all(axis=1)

    def progress(self, state: dict) -> np.ndarray:
        """Share of the team's item levels collected (B,)."""
        total = (state["level"] * state["active"]).sum(axis=1)
        return (state["level"] * (state["collected"] & state["active"])).sum(axis=1) / np.maximum(total, 1e-9)

    def _nearest_open(self, state: dict, centres: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per robot (B, N): the nearest item not collected — its index, offset (B, N, 2), and whether
        there is one."""
        d = state["items"][:, None, :, :] - centres[:, :, None, :]
        dist2 = np.where(~state["collected"][:, None, :], d[..., 0] ** 2 + d[..., 1] ** 2, np.inf)
        k = np.argmin(dist2, axis=-1)
        ok = np.isfinite(np.take_along_axis(dist2, k[..., None], -1))[..., 0]
        return k, np.take_along_axis(d, k[..., None, None], 2)[..., 0, :] * ok[..., None], ok

    def task_features(self, state, poses, type_ids, caps, mask) -> np.ndarray:
        """[offset to the nearest open item (2), its level, the level within reach of it, the
        fraction collected, any item left]; levels / 5."""
        k, offset, ok = self._nearest_open(state, poses[..., :2])
        level = np.take_along_axis(state["level"], k, 1) * ok
        present = np.take_along_axis(self._present(state, poses, caps, mask), k, 1) * ok
        B, N = mask.shape
        frac = np.broadcast_to(self.progress(state)[:, None], (B, N))
        left = np.broadcast_to((~state["collected"]).any(axis=1)[:, None], (B, N)).astype(float)
        return np.concatenate(
            [offset, np.stack([level / self.level_scale, present / self.level_scale, frac, left], -1)], -1
        )

    def global_features(self, state: dict) -> np.ndarray:
        """(B, 4 K_max) item positions, levels / 5 and collected flags of every slot."""
        B = state["items"].shape[0]
        return np.concatenate(
            [
                state["items"].reshape(B, -1),
                state["level"] / self.level_scale,
                state["collected"].astype(float),
            ],
            axis=-1,
        )

    # -- the scripted references ------------------------------------------------------------------
    def _groups(self, state: dict, centres: np.ndarray, levels: np.ndarray, mask: np.ndarray) -> tuple:
        """Each robot's item (B, N, 2) and whether it has one. Items in slot order each get the nearest
        robots not yet given one, until their ``levels`` (B, N) reach the item's level; a robot left
        over goes to the nearest item that got no group (it cannot be lifted yet), and waits where
        it is when every open item has one. Runs once per env step (B × K small steps)."""
        B, N = mask.shape
        d = np.hypot(*(state["items"][:, None, :, :] - centres[:, :, None, :]).transpose(3, 0, 1, 2))  # (B, N, K)
        target = np.zeros((B, N), np.int64)
        has = np.zeros((B, N), bool)
        for b in range(B):
            free = mask[b].copy()
            uncovered = []
            for k in np.flatnonzero(~state["collected"][b]):
                order = [i for i in np.argsort(d[b, :, k]) if free[i]]
                enough = np.flatnonzero(np.cumsum(levels[b, order]) >= state["level"][b, k] - 1e-9)
                if not enough.size:
                    uncovered.append(k)
                    continue
                chosen = order[: enough[0] + 1]
                target[b, chosen], has[b, chosen] = k, True
                free[chosen] = False
            if uncovered:
                for i in np.flatnonzero(free):
                    target[b, i], has[b, i] = uncovered[int(np.argmin(d[b, i, uncovered]))], True
        items = np.take_along_axis(state["items"], target[..., None].repeat(2, -1), 1)
        return items, has

    def scripted_targets(self, state: dict, centres: np.ndarray, type_ids: np.ndarray, caps=None, mask=None):
        levels = caps[..., 0] if caps is not None else np.ones(type_ids.shape)
        return self._groups(state, centres, levels, np.ones(type_ids.shape, bool) if mask is None else mask)

    def scripted_actions(self, state, poses, type_ids, caps, mask) -> np.ndarray:
        """Actions (B, N) of the scripted reference: groups whose levels reach each item's level."""
        centres = poses[..., :2]
        target, ok = self.scripted_targets(state, centres, type_ids, caps, mask)
        return self.drive(state, poses, caps, mask, target, ok)

    def blind_scripted_actions(self, state, poses, type_ids, caps, mask) -> np.ndarray:
        """The scripted reference blind to capabilities and types: the same groups, believing every
        robot has level :attr:`blind_level` (its steps are the robots' own: the env moves them)."""
        centres = poses[..., :2]
        target, ok = self._groups(state, centres, np.full(mask.shape, self.blind_level), mask)
        return self.drive(state, poses, caps, mask, target, ok)

    # -- diagnostics ------------------------------------------------------------------------------
    robot_count_names = ("still_held", "still_idle", "lifting")
    end_count_names = ("items_left",)

    def count_before(self, state: dict) -> dict:
        return {"collected": state["collected"].copy()}

    def count_robots(self, before, raw, state, poses, type_ids, caps, mask) -> dict[str, np.ndarray]:
        """Items collected in the step, credited to every robot within reach of them."""
        new = state["collected"] & ~before["collected"]
        return {"lifting": (self._near(state, poses, mask) & new[:, None, :]).sum(-1)} if new.any() else {}

    def end_counts(self, state: dict) -> dict[str, np.ndarray]:
        return {"items_left": (state["active"] & ~state["collected"]).sum(1).astype(float)}

    # -- coordination ---------------------------------------------------------------------------
    coordination_name = "robots waiting"
    coordination_doc = (
        "share of the robots at an item too heavy for those there (waiting for help), mean over the steps; lower "
        "is better (0 also when no robot reaches an item)"
    )

    def coordination(self, state, poses, type_ids, caps, mask) -> np.ndarray:
        """(B,) share of the team's robots within reach of an open item. Read after the step's lifts,
        every item still open lacks level: those robots wait for help (a group formed too weak waits
        for good). An item lifted with more level than needed is not seen here (it is lifted at once)."""
        waiting = (self._near(state, poses, mask) & ~state["collected"][:, None, :]).any(axis=-1)
        return waiting.sum(axis=1) / np.maximum(mask.sum(axis=1), 1)

    # -- drawing and export -----------------------------------------------------------------------
    type_colors: ClassVar[dict] = {"heavy": (121, 85, 72), "light": (0, 172, 193)}
    counters_name = "items"
    bar_m_per_level = 0.04

    def areas(self, state: dict | None = None, b: int = 0) -> tuple[Area, ...]:
        return (
            Area("spawn", "box", self.spawn_box, (160, 160, 160), "robot spawn"),
            Area("item_area", "box", self.item_box, (200, 140, 60), "item area"),
        )

    def items(self, state: dict, b: int) -> Items:
        on = state["active"][b]
        labels = tuple(f"{v:.1f}" for v in state["level"][b][on])
        status = state["collected"][b][on].astype(np.int64)
        colors = ((200, 140, 60), (15, 157, 88))
        return Items("items", state["items"][b][on].copy(), status, ("open", "collected"), colors, 0.05, labels)

    def rings(self, caps: np.ndarray, type_ids: np.ndarray) -> tuple[Ring, ...]:
        return (Ring("step", np.ones(caps.shape[0], bool), caps[:, 1], (120, 120, 120), "dotted ring: step", True),)

    def bar(self, state: dict, b: int, caps: np.ndarray) -> Bar:
        return Bar("level", "level_fill", caps[:, 0] * self.bar_m_per_level, np.ones(caps.shape[0]), "bar: level")

    def counters(self, state: dict, b: int, n: int) -> dict[str, float]:
        on = state["active"][b]
        done = state["collected"][b][on]
        return {"collected": float(done.sum()), "level collected": float(state["level"][b][on][done].sum())}

    def status_text(self, state: dict, b: int, counters: dict[str, float]) -> str:
        on = state["active"][b]
        return (
            f"items {int(counters['collected'])}/{int(on.sum())}, level {counters['level collected']:.1f}"
            f"/{float(state['level'][b][on].sum()):.1f}"
        )

    def layout(self, state: dict, b: int) -> dict[str, list]:
        on = state["active"][b]
        return {"items": state["items"][b][on].tolist(), "level": state["level"][b][on].tolist()}

    def set_layout(self, state: dict, b: int, layout: dict[str, list]) -> None:
        items = np.asarray(layout["items"], dtype=float).reshape(-1, 2)
        k = items.shape[0]
        state["items"][b] = self.parked
        state["items"][b, :k] = items
        state["level"][b] = 0.0
        state["level"][b, :k] = np.asarray(layout["level"], dtype=float)
        state["active"][b] = np.arange(state["items"].shape[1]) < k
        state["collected"][b] = ~state["active"][b]


FORAGE = LevelForaging
