"""Warehouse (``warehouse_v0``): robots fetch items from the shelves and bring them to the delivery
zone, and each robot lifts only items no heavier than its load — which robot fetches which item
decides whether the team clears the shelves in time.

| | |
|---|---|
| Agents | ``robot_0 … robot_{n-1}``, n = 2…20; types ``forklift`` and ``picker``, >= 1 of each; team changes every episode as in every comat task (``possible_agents`` the largest team, ``agents`` this episode's) |
| Capabilities | [load, speed m]: load = the heaviest item the robot lifts (units); speed = waypoint step per env step |
| Actions | Discrete(5): 0 stay, 1 +x, 2 −x, 3 +y, 4 −y — a waypoint one speed-step away for the robot's projected point |
| Step | 29 control ticks of 0.033 s (0.96 s): waypoint controller → safety filter → MuJoCo |
| Observation | Box(18,) float64, below |
| State | Box(4K + S·18,): items (x, y) ×K, weight / 4 ×K, status / 2 ×K (0 on its shelf, 1 carried, 2 delivered) over the env's K_max item slots (a smaller team's unused slots parked at (2.6, 0), delivered), then the observations of S = ``state_robots`` slots |
| Horizon | 72 steps; ends early when every item is delivered |
| Layout | delivery zone x <= −1.0 m, the arena's whole height; shelves on a grid 0.3 m apart, 8 columns x ∈ {−0.7, …, 1.4} × 6 rows y ∈ {−0.75, …, 0.75} (48 shelves) |
| Items | K(N) = ceil(1.5 N) (3 for 2 robots, 30 for 20). Every robot of the team is the *source* of one item, K − N of them (drawn at random) of a second. An item weighs U(0.85, 1.0) × its source's load (rounded down to 0.01): its source lifts it, and so does every robot at least that strong, of either type — the continuous load decides, not the type. It wants a shelf U(7, 11) of its source's steps beyond the zone's edge at a uniform height and gets the free shelf nearest to that (items nearest the zone choose first): a slow robot's items lie near the zone |
| Spawn | robots >= 0.3 m apart in x ∈ [−1.45, −0.85], y ∈ [−0.85, 0.85] (mostly in the delivery zone), random headings |

Observation layout (per robot):

| index | feature |
|---|---|
| 0–1 | x, y (m) |
| 2–3 | cos θ, sin θ |
| 4–5 | type one-hot (forklift, picker) |
| 6–7 | capabilities (load / 4, speed / 0.2 m) |
| 8–9 | offset (m) to the nearest item on a shelf (0 when none is left) |
| 10 | that item's weight / 4 |
| 11–12 | offset (m) to the second nearest item on a shelf |
| 13 | the second item's weight / 4 |
| 14 | 1 if the robot carries an item |
| 15 | x-offset (m) to the delivery zone's edge (x = −1.0; negative: to go) |
| 16 | team's fraction of the items delivered |
| 17 | steps left / horizon |

Composition sets (``coalitions=``; :mod:`comat.team`; load / speed m per step). The two types'
loads overlap and each spreads widely: a strong picker lifts more than a weak forklift.

* ``train`` (U_train): 3, 5 or 7 robots; forklift U(1.4, 3.0) / U(0.06, 0.10), picker U(0.5, 1.7)
  / U(0.12, 0.17).
* ``val``: like U_train from another stream; ``size``: sizes 2…20, U_train's ranges.
* ``test`` (U_test): 2, 4, 6 or 8 robots; forklift U(1.2, 3.3) / U(0.05, 0.11), picker U(0.4, 1.9)
  / U(0.11, 0.18); ``scale``: 10, 12, 16 or 20 robots with U_test's ranges.
* ``capability`` (U_cap): every load and speed outside its type's U_train range: forklift load
  [0.9, 1.4) ∪ (3.0, 3.8], speed [0.045, 0.06) ∪ (0.10, 0.12]; picker load [0.25, 0.5) ∪
  (1.7, 2.3], speed [0.10, 0.12) ∪ (0.17, 0.19] (0.19 m: 0.2 m/s over one 0.96 s step).

Rules (after every step, on the true poses, in this order):

1. A robot carrying an item whose centre is in the delivery zone delivers it.
2. A robot carrying nothing that *stopped* (its centre moved less than half its step in the env
   step) with its centre within :attr:`Warehouse.reach_m` (0.14 m) of an item on a shelf tries to
   lift the nearest such item (robots in slot order; one lift per item): it lifts it when its load
   is at least the item's weight and carries it from then on; otherwise the lift *fails*. A robot
   does not try an item at least as heavy as one it failed to lift.

The state keeps, per robot, the heaviest item it lifted and the lightest it failed to lift: what the
team has *seen* of its loads (a real robot notices that a shelf does not come up). Every planner
below reads it, so the ``type_only`` and ``blind`` rungs stop sending a robot to items it has shown
it cannot lift, and try another: what remains between them and the scripted rung is what knowing
the capabilities decides in time.

Reward (shared) = named terms in ``infos[agent]["reward/<term>"]``: ``delivered`` +1 per item
delivered, ``lifted`` +0.2 per item lifted, ``time`` −0.05 per step, ``violation`` −5 in a step with
any robot–robot contact, Robotarium-style collision or boundary exit.

References (``results/sets/validity.md``; :meth:`Warehouse._plan`, re-planned every step): the
scripted policy lists the items on shelves heaviest first (the fewest robots lift them) and gives
each to the robot believed to lift it that would have it delivered soonest after the items it
already has (Manhattan distance over its speed, from where it will be free); a free robot heads for
the first item of its list, a carrier for the delivery zone, a robot without an item parks deep in
the zone. A robot is believed to lift an item when its load, clipped to what the team has seen of
it (rules), is at least the weight; an item nobody is believed to lift goes to the robots believed
strongest (a try). It reads the capabilities only through its ``caps`` argument: ``type_only``
(each robot its type's mean load and speed over the set's ranges) runs the same planner; the blind
twin (``blind_scripted_actions``) believes every robot lifts every item and is equally fast, until
the team sees a lift fail. Every constant action delivers nothing.

Coordination (``coordination``, lower is better): the share of the team's lift tries so far that
failed — robots sent to (or stopped at) items heavier than their load. A robot held by traffic
within reach of a shelf tries too, so the scripted rung's share is small but not 0 in large teams.

Family: meant for the *capability* family (scripted − type_only on U_cap) and the *size* family
(scripted and scripted − blind on U_size ∪ U_scale).

This follows the warehouse scenarios of MARBLER and JaxRobotarium (Warehouse, Continuous-RWARE)
and the multi-robot warehouse RWARE (Papoudakis et al. 2021): robots fetch items from shelves to a
delivery point; here robots differ in load and speed, and an item's weight is drawn against the
team's own loads.

Version history: v0 — first version (issue 64), designed on coalition seed 1 and episode seed
2,000,003 (20 coalitions a set, 3 episodes each, unicycle tier). Progress scripted / type_only /
blind: U_train 98.7 / 77.1 / 88.4 %, U_cap 96.6 / 62.7 / 88.5 %, U_size 94.6 / 74.6 / 82.5 %,
U_scale 93.3 / 71.1 / 76.1 %; scripted − type_only on U_cap 33.9 points (paired 95 % interval
[26.0, 41.8]); on U_size ∪ U_scale scripted 94.0 % and scripted − blind 14.7 points [12.2, 17.2].
Tried on the way (1 to 3 episodes): a first draft with items on uniform shelves and the free robots
given one item each by least summed squared time (scripted 75–81 %: a slow robot's heavy item far
out, and a robot that alone lifts an item took another first); a 75-step horizon (on U_size ∪
U_scale scripted 95.5 %, scripted − blind 12.9 points); an item's source drawn in proportion to its
load (scripted 84 %).
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

# (an export ships this file beside task_logic.py, with this import made local: sim2real/export.py)
from comat.task_logic import Area, Bar, Items, Ring, TaskLogic, grow_slots

__all__ = ["WAREHOUSE", "Warehouse"]

SHELF, CARRIED, DELIVERED = 0, 1, 2
"""An item's status: on its shelf (open), carried by a robot, delivered."""
UNKNOWN_LIMIT = 1e9
"""``failed`` of a robot that has not failed a lift yet (no limit seen; finite, so sums stay finite)."""


class Warehouse(TaskLogic):
    """Warehouse (module docstring). State per env: items (B, K, 2), weight (B, K), status (B, K),
    active (B, K); per robot (B, N) the item it carries (−1: none), the heaviest weight it has
    lifted and the lightest it failed to lift, and where it stood after the last step."""

    name = "warehouse"
    title = "Warehouse"
    meant_for = ("capability", "size")
    types = ("forklift", "picker")
    capabilities = ("load", "speed_m")
    capability_scale = np.array([4.0, 0.2])
    speed_capability = 1
    horizon = 72
    ticks_per_step = 29
    spawn_box = (-1.45, -0.85, -0.85, 0.85)
    shelf_box = (-0.7, 1.45, -0.85, 0.85)
    shelf_spacing = 0.3
    delivery_x = -1.0
    """The delivery zone: x <= this (m), the arena's whole height (HMT's drop-off)."""
    drop_depth_m = 0.12
    """Carriers head this far into the delivery zone (their centre must cross its edge)."""
    park_x = -1.35
    """Where the scripted references send a robot with nothing to do (deep in the zone, out of the way)."""
    reach_m = 0.14
    """A robot lifts an item whose shelf is within this of its centre (less than half the shelves'
    0.3 m spacing: one shelf at a time)."""
    stop_fraction = 0.5
    """Stopping at a shelf: the robot's centre moved less than this fraction of its step in the env step."""
    weight_fraction = (0.85, 1.0)
    shelf_steps = (7.0, 11.0)
    """An item lies U(7, 11) of its source robot's steps beyond the delivery zone's edge (where the
    shelves let it: :meth:`_shelves`)."""
    n_task_features = 10
    reward_terms = ("delivered", "lifted", "time", "violation")
    reward_weights: ClassVar[dict] = {"delivered": 1.0, "lifted": 0.2, "time": -0.05, "violation": -5.0}
    parked = (2.6, 0.0)
    reset_uses_starts = True
    best_constant_action = 3
    """+y: every constant action delivers nothing on U_train; +y earns the most (return −3.59 against
    −3.60 for the other four: a robot or two passing a shelf lift an item on the way; tests/test_eval.py)."""

    capability_limits = ((0.0, 5.0), (0.0, 0.19))
    """Physical limits: a load up to 5 units; a step up to 0.2 m/s × 0.96 s."""
    required = ((0, 1), (0, 1))
    capability_bands: ClassVar[dict] = {
        "train": {"forklift": (((1.4, 3.0),), ((0.06, 0.10),)), "picker": (((0.5, 1.7),), ((0.12, 0.17),))},
        "test": {"forklift": (((1.2, 3.3),), ((0.05, 0.11),)), "picker": (((0.4, 1.9),), ((0.11, 0.18),))},
        "capability": {
            "forklift": (((0.9, 1.399999), (3.000001, 3.8)), ((0.045, 0.059999), (0.100001, 0.12))),
            "picker": (((0.25, 0.499999), (1.700001, 2.3)), ((0.10, 0.119999), (0.170001, 0.19))),
        },
    }
    set_streams = 42
    """The composition sets' random streams are 42… (PCP and HMT 0–11, forage 12–17, navigation
    18–23, sensors 24–29, arctic 30–35)."""

    def __init__(self) -> None:
        self.largest_team: int | None = None

    @classmethod
    def items_for(cls, n_robots: int) -> int:
        """K(N) = ceil(1.5 N) items for a team of N robots."""
        return (3 * int(n_robots) + 1) // 2

    def max_team_size(self) -> int:
        n = self.spawn_capacity()
        while n > 0 and self.items_for(n) > self.shelf_slots().shape[0]:
            n -= 1
        return n

    def fit_teams(self, largest: int) -> None:
        self.largest_team = int(largest)

    def step_lengths(self, caps: np.ndarray) -> np.ndarray:
        return caps[..., 1]

    def new_state(self, B: int, N: int) -> dict:
        K = self.items_for(max(N, self.largest_team or 0))
        return {
            "items": np.broadcast_to(self.parked, (B, K, 2)).copy(),
            "weight": np.zeros((B, K)),
            "status": np.full((B, K), DELIVERED, np.int64),
            "active": np.zeros((B, K), bool),
            "carrying": np.full((B, N), -1, np.int64),
            "lifted": np.zeros((B, N)),
            "failed": np.full((B, N), UNKNOWN_LIMIT),
            "prev": np.zeros((B, N, 2)),
            "moved": np.zeros((B, N)),
            "attempts": np.zeros(B),
            "failures": np.zeros(B),
            "steps": np.zeros(B),
        }

    def reserve(self, state: dict, n_robots: int) -> None:
        """Grow every env's item slots to fit a team of ``n_robots`` (the added slots inactive)."""
        k, slots = self.items_for(n_robots), state["items"].shape[1]
        if k > slots:
            grow_slots(state, k - slots, {"items": self.parked, "weight": 0.0, "status": DELIVERED, "active": False})

    def reset_env(self, state: dict, b: int, rng: np.random.Generator, caps: np.ndarray, starts=None) -> None:
        """K(n) items on shelves for the team of caps (n, 2): each robot the source of one or two of
        them (module docstring: Items), each item as heavy as U(0.85, 1.0) × its source's load and
        U(7, 11) of its source's steps from the delivery zone; ``starts`` (n, 3): where the robots
        start (a robot that has not moved since has stopped)."""
        n, slots = caps.shape[0], state["items"].shape[1]
        k = self.items_for(n)
        assert k <= slots, "reserve() the item slots before resetting a larger team"
        sources = rng.permutation(np.concatenate([np.arange(n), rng.choice(n, k - n, replace=False)]))
        weights = np.floor(100.0 * caps[sources, 0] * rng.uniform(*self.weight_fraction, k)) / 100.0  # <= load
        state["items"][b] = self.parked
        state["items"][b, :k] = self._shelves(rng, caps[sources, 1])
        state["weight"][b] = 0.0
        state["weight"][b, :k] = weights
        state["active"][b] = np.arange(slots) < k
        state["status"][b] = np.where(state["active"][b], SHELF, DELIVERED)
        for key, value in (("carrying", -1), ("lifted", 0.0), ("failed", UNKNOWN_LIMIT), ("moved", 0.0)):
            state[key][b] = value
        state["attempts"][b] = state["failures"][b] = state["steps"][b] = 0
        state["prev"][b] = 0.0
        if starts is not None:
            self.set_starts(state, b, starts)

    def shelf_slots(self) -> np.ndarray:
        """(S, 2) the shelf grid: columns every :attr:`shelf_spacing` from the shelf area's left edge,
        rows every spacing centred on y = 0 (8 × 6 = 48 shelves)."""
        x0, x1, y0, y1 = self.shelf_box
        s = self.shelf_spacing
        xs = x0 + s * np.arange(int(np.floor((x1 - x0) / s + 1e-9)) + 1)
        rows = int(np.floor((y1 - y0) / s + 1e-9)) + 1
        ys = s * (np.arange(rows) - (rows - 1) / 2)
        return np.stack(np.meshgrid(xs, ys, indexing="ij"), -1).reshape(-1, 2)

    def _shelves(self, rng: np.random.Generator, speed: np.ndarray) -> np.ndarray:
        """(K, 2) shelves: item k wants a place U(shelf_steps) × speed[k] beyond the delivery
        zone's edge at a uniform height, and gets the free shelf nearest to it (items nearest the
        zone choose first)."""
        _, _, y0, y1 = self.shelf_box
        want = np.stack(
            [self.delivery_x + rng.uniform(*self.shelf_steps, speed.shape[0]) * speed,
             rng.uniform(y0, y1, speed.shape[0])], -1,
        )  # fmt: skip
        slots = self.shelf_slots()
        free = np.ones(slots.shape[0], bool)
        out = np.zeros_like(want)
        for k in np.argsort(want[:, 0], kind="stable"):
            d = np.where(free, np.hypot(*(slots - want[k]).T), np.inf)
            j = int(np.argmin(d))
            out[k], free[j] = slots[j], False
        return out

    def _open(self, state: dict) -> np.ndarray:
        """(B, K) items on their shelves."""
        return state["active"] & (state["status"] == SHELF)

    def update(self, state: dict, poses: np.ndarray, type_ids: np.ndarray, caps: np.ndarray, mask: np.ndarray) -> dict:
        """Deliveries, then lifts (module docstring: Rules)."""
        centres = poses[..., :2]
        B, N = mask.shape
        envs = np.arange(B)
        state["moved"] = np.hypot(*(centres - state["prev"]).transpose(2, 0, 1)) * mask
        stopped = state["moved"] < self.stop_fraction * caps[..., 1]
        state["prev"] = centres.copy()
        state["steps"] += 1
        carrying = state["carrying"]
        drop = mask & (carrying >= 0) & (centres[..., 0] <= self.delivery_x)
        bi, ri = np.nonzero(drop)
        state["status"][bi, carrying[bi, ri]] = DELIVERED
        state["items"][bi, carrying[bi, ri]] = centres[bi, ri]
        carrying[drop] = -1
        held = carrying >= 0
        bi, ri = np.nonzero(held)
        state["items"][bi, carrying[bi, ri]] = centres[bi, ri]
        # lifts: a free robot stopped at a shelf tries its item (robots in slot order: one lift per item)
        d = centres[:, :, None, :] - state["items"][:, None, :, :]
        dist2 = np.where(self._open(state)[:, None, :], d[..., 0] ** 2 + d[..., 1] ** 2, np.inf)  # (B, N, K)
        nearest = np.argmin(dist2, axis=-1)
        at = np.take_along_axis(dist2, nearest[..., None], -1)[..., 0] <= self.reach_m**2
        trying = at & stopped & mask & ~held
        lifted = np.zeros(B)
        for i in range(N):
            k = nearest[:, i]
            w = state["weight"][envs, k]
            # a robot does not try what is at least as heavy as an item it failed to lift
            go = trying[:, i] & (state["status"][envs, k] == SHELF) & (w < state["failed"][:, i])
            ok = go & (caps[:, i, 0] >= w - 1e-9)
            state["status"][envs[ok], k[ok]] = CARRIED
            carrying[ok, i] = k[ok]
            state["lifted"][:, i] = np.where(ok, np.maximum(state["lifted"][:, i], w), state["lifted"][:, i])
            state["failed"][:, i] = np.where(go & ~ok, np.minimum(state["failed"][:, i], w), state["failed"][:, i])
            state["attempts"] += go
            state["failures"] += go & ~ok
            lifted += ok
        return {"delivered": drop.sum(axis=1).astype(float), "lifted": lifted}

    def done(self, state: dict) -> np.ndarray:
        """Every item of the team delivered (B,)."""
        return ((state["status"] == DELIVERED) | ~state["active"]).all(axis=1)

    def progress(self, state: dict) -> np.ndarray:
        """Share of the team's items delivered (B,)."""
        delivered = (state["active"] & (state["status"] == DELIVERED)).sum(axis=1)
        return delivered / np.maximum(state["active"].sum(axis=1), 1)

    def task_features(self, state, poses, type_ids, caps, mask) -> np.ndarray:
        """[the two nearest open items' offsets (2) and weights / 4, each; carrying; x-offset to the
        delivery zone; fraction delivered; steps left / horizon] (module docstring)."""
        B, N = mask.shape
        d = state["items"][:, None, :, :] - poses[:, :, None, :2]
        dist2 = np.where(self._open(state)[:, None, :], d[..., 0] ** 2 + d[..., 1] ** 2, np.inf)
        order = np.argsort(dist2, axis=-1, kind="stable")[..., :2]
        if order.shape[-1] < 2:  # a single item slot: the second is never there
            order = np.concatenate([order, order], -1)
        parts = []
        for j in range(2):
            k = order[..., j]
            ok = np.isfinite(np.take_along_axis(dist2, k[..., None], -1))[..., 0]
            offset = np.take_along_axis(d, k[..., None, None], 2)[..., 0, :] * ok[..., None]
            weight = np.take_along_axis(state["weight"][:, None, :].repeat(N, 1), k[..., None], -1)[..., 0] * ok
            parts += [offset, (weight / self.capability_scale[0])[..., None]]
        frac = np.broadcast_to(self.progress(state)[:, None], (B, N))
        left = np.broadcast_to((1.0 - state["steps"] / self.horizon)[:, None], (B, N))
        rest = np.stack([(state["carrying"] >= 0).astype(float), self.delivery_x - poses[..., 0], frac, left], -1)
        return np.concatenate([*parts, rest], axis=-1)

    def global_features(self, state: dict) -> np.ndarray:
        """(B, 4 K_max) item positions, weights / 4 and status / 2 of every slot."""
        B = state["items"].shape[0]
        return np.concatenate(
            [state["items"].reshape(B, -1), state["weight"] / self.capability_scale[0], state["status"] / 2.0], -1
        )

    # -- the scripted references ------------------------------------------------------------------
    def _plan(self, state: dict, centres: np.ndarray, load: np.ndarray, speed: np.ndarray, mask: np.ndarray):
        """Each robot's target (B, N, 2), all with one: a carrier the delivery zone; the open items,
        heaviest first (the fewest robots lift them), each to the robot believed to lift it (below)
        that would have it delivered soonest after the items it already has (distance over ``speed``
        (B, N), Manhattan: the waypoints move along x or y); a free robot heads for the first item of
        its list, one without any parks in the zone. Re-planned every step, as robots free up.

        Belief: robot i lifts item k when ``load`` (B, N) >= its weight, the load clipped to what the
        team has seen of it (at least the heaviest item it lifted, below the lightest it failed to
        lift). An item no robot is believed to lift goes to the robots believed strongest (a try:
        they may be stronger than believed); a robot never gets an item it is known not to lift."""
        B, N = mask.shape
        believed = np.maximum(np.minimum(load, state["failed"] - 1e-6), state["lifted"])  # (B, N)
        w = state["weight"][:, None, :]  # (B, 1, K)
        known_not = state["failed"][..., None] <= w + 1e-9  # (B, N, K)
        can = (believed[..., None] >= w - 1e-9) & ~known_not & mask[..., None]
        candidates = np.where(~known_not & mask[..., None], believed[..., None], -np.inf)
        strongest = candidates >= candidates.max(axis=1, keepdims=True) - 1e-9
        allowed = np.where(can.any(axis=1, keepdims=True), can, strongest & np.isfinite(candidates))
        carrying = state["carrying"] >= 0
        target = np.stack([np.full((B, N), self.park_x), np.clip(centres[..., 1], -0.85, 0.85)], -1)
        target[..., 0] = np.where(carrying, self.delivery_x - self.drop_depth_m, target[..., 0])
        # when each robot is next free (env steps) and where: a carrier once it reaches the zone
        ready = np.where(carrying, np.maximum(centres[..., 0] - self.delivery_x, 0.0) / np.maximum(speed, 1e-9), 0.0)
        at = np.where(carrying[..., None], np.stack([np.full((B, N), self.delivery_x), centres[..., 1]], -1), centres)
        back = np.maximum(state["items"][..., 0] - self.delivery_x, 0.0)  # (B, K) item to zone
        open_ = self._open(state)
        for b in range(B):
            free = mask[b] & ~carrying[b]
            t, p, first = ready[b].copy(), at[b].copy(), np.full(N, -1)
            for k in np.flatnonzero(open_[b])[np.argsort(-state["weight"][b][open_[b]], kind="stable")]:
                finish = t + (np.abs(p - state["items"][b, k]).sum(-1) + back[b, k]) / np.maximum(speed[b], 1e-9)
                finish = np.where(allowed[b, :, k], finish, np.inf)
                i = int(np.argmin(finish))
                if not np.isfinite(finish[i]):
                    continue
                if free[i] and first[i] < 0:
                    first[i] = k
                t[i], p[i] = finish[i], (self.delivery_x, state["items"][b, k, 1])
            go = first >= 0
            target[b, go] = state["items"][b, first[go]]
        return target, mask

    def scripted_actions(self, state, poses, type_ids, caps, mask) -> np.ndarray:
        """The scripted reference (module docstring; :meth:`_plan` with the robots' loads and speeds)."""
        target, ok = self._plan(state, poses[..., :2], caps[..., 0], caps[..., 1], mask)
        return self.drive(state, poses, caps, mask, target, ok)

    def blind_scripted_actions(self, state, poses, type_ids, caps, mask) -> np.ndarray:
        """The same plan blind to types and capabilities: every robot believed to lift every item
        (until the team sees it fail) and equally fast (distance alone)."""
        load = np.full(mask.shape, UNKNOWN_LIMIT)
        target, ok = self._plan(state, poses[..., :2], load, np.ones(mask.shape), mask)
        return self.drive(state, poses, caps, mask, target, ok)

    # -- coordination and diagnostics ---------------------------------------------------------------
    coordination_name = "failed lifts"
    coordination_doc = (
        "share of the team's lift tries so far that failed (a robot sent to an item heavier than its "
        "load); 0 before any try; lower is better"
    )

    def coordination(self, state, poses, type_ids, caps, mask) -> np.ndarray:
        return state["failures"] / np.maximum(state["attempts"], 1)

    robot_count_names = ("still_held", "still_idle", "lifted", "failed_lifts")
    end_count_names = ("items_left", "failed_lifts")

    def count_before(self, state: dict) -> dict:
        return {"carrying": state["carrying"].copy(), "failed": state["failed"].copy()}

    def count_robots(self, before, raw, state, poses, type_ids, caps, mask) -> dict[str, np.ndarray]:
        """Items each robot lifted in the step, and lifts it failed (its lightest failure fell)."""
        lifted = (state["carrying"] >= 0) & (state["carrying"] != before["carrying"])
        return {"lifted": lifted.astype(float), "failed_lifts": (state["failed"] < before["failed"]).astype(float)}

    def end_counts(self, state: dict) -> dict[str, np.ndarray]:
        return {
            "items_left": (state["active"] & (state["status"] != DELIVERED)).sum(1).astype(float),
            "failed_lifts": state["failures"].copy(),
        }

    # -- drawing and export -----------------------------------------------------------------------
    type_colors: ClassVar[dict] = {"forklift": (230, 126, 34), "picker": (52, 152, 219)}
    counters_name = "items"
    bar_m_per_load = 0.04

    def areas(self, state: dict | None = None, b: int = 0) -> tuple[Area, ...]:
        return (
            Area("delivery", "box", (-1.6, self.delivery_x, -1.0, 1.0), (15, 157, 88), "delivery zone"),
            Area("shelves", "box", self.shelf_box, (200, 140, 60), "shelves"),
        )

    def items(self, state: dict, b: int) -> Items:
        on = state["active"][b]
        labels = tuple(f"{v:.2f}" for v in state["weight"][b][on])
        colors = ((200, 140, 60), (230, 170, 20), (15, 157, 88))
        return Items(
            "items", state["items"][b][on].copy(), state["status"][b][on].copy(), ("on shelf", "carried", "delivered"),
            colors, 0.04, labels,
        )  # fmt: skip

    def rings(self, caps: np.ndarray, type_ids: np.ndarray) -> tuple[Ring, ...]:
        return (Ring("step", np.ones(caps.shape[0], bool), caps[:, 1], (120, 120, 120), "dotted ring: step", True),)

    def bar(self, state: dict, b: int, caps: np.ndarray) -> Bar:
        """Width: the robot's load; filled to the weight it carries over its load."""
        n = caps.shape[0]
        k = state["carrying"][b, :n]
        carried = np.where(k >= 0, state["weight"][b][np.maximum(k, 0)], 0.0)
        return Bar(
            "load", "carried", caps[:, 0] * self.bar_m_per_load, carried / np.maximum(caps[:, 0], 1e-9), "bar: load"
        )

    def counters(self, state: dict, b: int, n: int) -> dict[str, float]:
        on = state["active"][b]
        status = state["status"][b][on]
        return {
            "delivered": float((status == DELIVERED).sum()),
            "carried": float((status == CARRIED).sum()),
            "failed lifts": float(state["failures"][b]),
        }

    def status_text(self, state: dict, b: int, counters: dict[str, float]) -> str:
        return (
            f"delivered {int(counters['delivered'])}/{int(state['active'][b].sum())}, carried "
            f"{int(counters['carried'])}, failed lifts {int(counters['failed lifts'])}"
        )

    def layout(self, state: dict, b: int) -> dict[str, list]:
        on = state["active"][b]
        return {"items": state["items"][b][on].tolist(), "weight": state["weight"][b][on].tolist()}

    def set_starts(self, state: dict, b: int, starts: np.ndarray) -> None:
        n = starts.shape[0]
        state["prev"][b] = 0.0
        state["prev"][b, :n] = np.asarray(starts, dtype=float)[:, :2]

    def set_layout(self, state: dict, b: int, layout: dict[str, list]) -> None:
        """Put the items back on their shelves (a fresh episode: nothing carried or tried)."""
        items = np.asarray(layout["items"], dtype=float).reshape(-1, 2)
        k = items.shape[0]
        state["items"][b] = self.parked
        state["items"][b, :k] = items
        state["weight"][b] = 0.0
        state["weight"][b, :k] = np.asarray(layout["weight"], dtype=float)
        state["active"][b] = np.arange(state["items"].shape[1]) < k
        state["status"][b] = np.where(state["active"][b], SHELF, DELIVERED)
        for key, value in (("carrying", -1), ("lifted", 0.0), ("failed", UNKNOWN_LIMIT)):
            state[key][b] = value
        state["attempts"][b] = state["failures"][b] = 0


WAREHOUSE = Warehouse
