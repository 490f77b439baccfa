"""Heterogeneous Material Transport (``hmt_v0``): fast and slow robots carry material to a drop-off.

| | |
|---|---|
| Agents | ``robot_0 … robot_{n-1}``, n = 2…; types ``fast`` and ``slow``, >= 1 of each |
| Team changes | ``possible_agents`` = the largest team the env may get; ``agents`` = this episode's team, the first n of them. The others sit the episode out as agents done before it starts: ``reset``'s dicts hold the team's keys, and looking one of the others up gives a zero observation or an empty info (TorchRL's ``PettingZooWrapper(use_mask=True, done_on_any=False)`` reads every possible agent; SuperSuit's ``pad_observations_v0`` / ``black_death_v3`` and PettingZoo's conversions want the team's keys only); ``step`` ignores actions for them and returns none for them |
| Capabilities | [speed m, payload units]: speed = waypoint step per env step, payload = what it carries |
| Actions | Discrete(5): 0 stay, 1 +x, 2 −x, 3 +y, 4 −y — a waypoint one speed-step away |
| Step | 74 control ticks of 0.033 s (2.44 s): waypoint controller → safety filter → MuJoCo |
| Observation | Box(15,) float64, below |
| State | Box(4 + S·15,): material left per zone, initial amount per zone, then the observations of S = ``state_robots`` slots (default 8, or the env's robot slots when larger: 20 for `scale` and `size`, so every set has a state; a fixed-size baseline's run uses its ``max_robots``, 8 or 20) |
| Render | ``render_mode="rgb_array"``: ``env.render()`` → (448, 640, 3) uint8, the arena top-down (comat.envs.render) |
| Horizon | 70 steps; ends early when all material is delivered |
| Zones | zone 1: circle r = 0.35 m at the centre; zone 2: x > 1.0 m; drop-off: x < −1.0 m |
| Material | zone 1 = 1.5 × and zone 2 = 0.5 × the team's total payload (two full team loads) |
| Spawn | robots ≥ 0.3 m apart in x ∈ [−1.45, −0.75], y ∈ [−0.85, 0.85], random headings |
| Large teams | U_scale has 10–20 robots. Material follows the team's payload (two full team loads), so a 20-robot team moves about three times a 7-robot team's material through the same zones and drop-off; teams of 19–20 get the spawn area widened by 0.3 m (x ≤ −0.45: 24 places on its 0.3 m grid) |

Observation layout (per robot, fixed length whatever the team size):

| index | feature |
|---|---|
| 0–1 | x, y (m) |
| 2–3 | cos θ, sin θ |
| 4–5 | type one-hot (fast, slow) |
| 6–7 | capabilities (speed / 0.5 m, payload / 20) |
| 8 | own load / own payload |
| 9–10 | fraction of material left in zone 1, zone 2 |
| 11–12 | offset (m) from the robot to zone 1's centre |
| 13 | x-offset (m) to zone 2's edge (x = 1.0) |
| 14 | x-offset (m) to the drop-off's edge (x = −1.0) |

Composition sets (``coalitions=``; :mod:`comat.team`), 20 teams each, at least one robot of each type
(speed m per step / payload units):

* ``train`` (U_train): 3, 5 or 7 robots; fast U(0.19, 0.45) / U(5, 12), slow U(0.10, 0.15) / U(16, 22).
* ``val`` (U_val): drawn like U_train from another stream, no team equal to a U_train team; the
  only set model selection may look at.
* ``test`` (U_test, the paper's): 2, 4, 6 or 8 robots; fast U(0.15, 0.35) / U(7, 15), slow
  U(0.08, 0.18) / U(13, 28).
* ``scale`` (U_scale): 10, 12, 16 or 20 robots with U_test's capabilities.
* ``size`` (U_size): two teams of each size 2, 4, …, 20, U_train's capabilities: only the size
  differs from U_train (the material follows the team's payload, so a larger team moves more).
* ``capability`` (U_cap): 3, 5 or 7 robots like U_train, every speed and payload outside its
  type's U_train range, below or above (a side with probability proportional to its width): fast
  [0.12, 0.19) ∪ (0.45, 0.488] / [2, 5) ∪ (12, 16], slow [0.06, 0.10) ∪ (0.15, 0.19] /
  [10, 16) ∪ (22, 30] (0.488 m is the physical limit). Slow fast robots, fast slow ones, light
  and heavy loads the policy has not met.

Rules, after every step: a loaded robot whose centre is in the drop-off unloads everything; an
empty robot in a zone with material left loads min(payload, left) — zone 2 first, robots in
order.

Reward (shared) = sum of named terms in ``infos[agent]["reward/<term>"]``: ``loaded`` +0.025
per unit loaded, ``unloaded`` +0.075 per unit delivered, ``time`` −0.1 per step, ``violation``
−6 in a step with any robot–robot contact, Robotarium-style collision or boundary exit. At the
last step ``infos`` also hold ``episode/<metric>``.

Arguments: see :class:`comat.envs.base.TaskEnv`.

Version history: v0 — first version (after MARBLER's MaterialTransport and the COMAT paper).
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

# (an export ships this file beside task_logic.py, with this import made local: sim2real/export.py)
from comat.task_logic import ARENA, Area, Bar, Ring, TaskLogic

__all__ = ["HMT", "ZONE1_CENTRE", "ZONE1_RADIUS", "ZONE2_X", "MaterialTransport"]


ZONE1_CENTRE = (0.0, 0.0)
ZONE1_RADIUS = 0.35
ZONE2_X = 1.0
"""HMT material zone 2 is x > ZONE2_X; the drop-off is x < -ZONE2_X (MARBLER layout)."""


class MaterialTransport(TaskLogic):
    """HMT: fast and slow robots carry material from two zones to the drop-off.

    State per env: material left in zone 1 (circle r = 0.35 m at the centre) and zone 2
    (x > 1.0 m), (B, 2), the initial amounts, and each robot's load (B, N). Amounts scale with
    the team: zone 1 holds 1.5x and zone 2 0.5x the team's total payload (two full team loads).
    An empty robot inside a zone with material loads min(payload, what is left) (zone 2 first);
    a loaded robot inside the drop-off (x < -1.0 m) unloads everything.
    """

    name = "hmt"
    meant_for = ("capability", "size")
    """The paper's question (unseen capabilities and team sizes; :mod:`comat.eval.validity` measures which
    its references can ask)."""
    types = ("fast", "slow")
    capabilities = ("speed_m", "payload")
    capability_scale = np.array([0.5, 20.0])
    speed_capability = 0
    horizon = 70
    ticks_per_step = 74
    spawn_box = (-1.45, -0.75, -0.85, 0.85)
    zone_factors = (1.5, 0.5)
    n_task_features = 7
    reward_terms = ("loaded", "unloaded", "time", "violation")
    reward_weights: ClassVar[dict] = {"loaded": 0.025, "unloaded": 0.075, "time": -0.1, "violation": -6.0}

    # -- what the composition sets draw (comat.tasks registers them; the spec sheet above) -------
    capability_limits = ((0.0, 0.488), (0.0, 100.0))
    """Physical limits: a step of at most 0.2 m/s over one 74-tick step (2.44 s), 0.488 m; payload units."""
    required = ((0, 1), (0, 1))
    capability_bands: ClassVar[dict] = {
        "train": {"fast": (((0.19, 0.45),), ((5.0, 12.0),)), "slow": (((0.10, 0.15),), ((16.0, 22.0),))},
        "test": {"fast": (((0.15, 0.35),), ((7.0, 15.0),)), "slow": (((0.08, 0.18),), ((13.0, 28.0),))},
        # Below and above the training range, each band one rounding step (1e-6) short of it; the
        # fast robots' upper speed band ends at the physical limit.
        "capability": {
            "fast": (((0.12, 0.189999), (0.450001, 0.488)), ((2.0, 4.999999), (12.000001, 16.0))),
            "slow": (((0.06, 0.099999), (0.150001, 0.19)), ((10.0, 15.999999), (22.000001, 30.0))),
        },
    }
    set_streams: ClassVar[dict] = {"test": 0, "train": 1, "scale": 4, "val": 6, "size": 8, "capability": 10}
    """The sets' random streams, fixed when they were first drawn (the stored sets must not change)."""

    def step_lengths(self, caps: np.ndarray) -> np.ndarray:
        """Waypoint step (B, N), m: the robot's speed capability."""
        return caps[..., 0]

    def new_state(self, B: int, N: int) -> dict:
        return {
            "left": np.zeros((B, 2)),
            "initial": np.ones((B, 2)),
            "load": np.zeros((B, N)),
            "delivered": np.zeros(B),
        }

    def reset_env(self, state: dict, b: int, rng: np.random.Generator, caps: np.ndarray) -> None:
        total = float(caps[:, 1].sum())
        state["initial"][b] = np.array(self.zone_factors) * total
        state["left"][b] = state["initial"][b]
        state["load"][b] = 0.0
        state["delivered"][b] = 0.0

    @staticmethod
    def zones(poses: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(B, N) robot centre in zone 1, zone 2, drop-off."""
        x, y = poses[..., 0], poses[..., 1]
        z1 = (x - ZONE1_CENTRE[0]) ** 2 + (y - ZONE1_CENTRE[1]) ** 2 <= ZONE1_RADIUS**2
        return z1, x >= ZONE2_X, x <= -ZONE2_X

    def update(self, state: dict, poses: np.ndarray, type_ids: np.ndarray, caps: np.ndarray, mask: np.ndarray) -> dict:
        z1, z2, drop = self.zones(poses)
        load, left = state["load"], state["left"]
        unload = np.where(drop & mask & (load > 0), load, 0.0)
        load -= unload
        state["delivered"] += unload.sum(axis=1)
        loaded = np.zeros_like(load)
        # Robots load one after another (robot order), zone 2 checked first, as in MARBLER.
        for i in range(load.shape[1]):
            empty = mask[:, i] & (load[:, i] <= 0)
            for z, inside in ((1, z2[:, i]), (0, z1[:, i])):
                take = np.where(empty & inside & (left[:, z] > 0), np.minimum(caps[:, i, 1], left[:, z]), 0.0)
                left[:, z] -= take
                loaded[:, i] += take
                empty &= take <= 0
        load += loaded
        # unloaded_by_robot (B, N): who delivered what (per-robot diagnostics; not a reward term)
        return {"loaded": loaded.sum(axis=1), "unloaded": unload.sum(axis=1), "unloaded_by_robot": unload}

    def done(self, state: dict) -> np.ndarray:
        """All the material delivered (B,)."""
        return state["delivered"] >= state["initial"].sum(axis=1) * (1.0 - 1e-12)

    def progress(self, state: dict) -> np.ndarray:
        """Fraction of the material delivered (B,)."""
        return state["delivered"] / state["initial"].sum(axis=1)

    def task_features(self, state, poses, type_ids, caps, mask) -> np.ndarray:
        """[own load / payload, zone 1 and zone 2 fraction left, vector to zone 1's centre (2),
        x-distance to zone 2's edge, x-distance to the drop-off's edge]."""
        B, N = mask.shape
        frac = state["left"] / np.maximum(state["initial"], 1e-9)
        load = state["load"] / np.maximum(caps[..., 1], 1e-9)
        x, y = poses[..., 0], poses[..., 1]
        return np.stack(
            [
                load,
                *np.broadcast_to(frac[:, None, :], (B, N, 2)).transpose(2, 0, 1),
                ZONE1_CENTRE[0] - x,
                ZONE1_CENTRE[1] - y,
                ZONE2_X - x,
                -ZONE2_X - x,
            ],
            axis=-1,
        )

    def scripted_targets(self, state: dict, centres: np.ndarray, type_ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """A loaded robot: the drop-off; an empty one: a zone with material, fast robots
        preferring zone 2 (far, smaller) and slow robots zone 1 (near, larger)."""
        left = state["left"]  # (B, 2)
        loaded = state["load"] > 0
        y = np.clip(centres[..., 1], -0.8, 0.8)
        drop = np.stack([np.full_like(y, -ZONE2_X - 0.25), y], -1)
        zone1 = np.broadcast_to(np.array(ZONE1_CENTRE), centres.shape)
        zone2 = np.stack([np.full_like(y, ZONE2_X + 0.25), y], -1)
        has1, has2 = (left[:, 0] > 0)[:, None], (left[:, 1] > 0)[:, None]
        prefer2 = np.where(type_ids == 0, has2, has2 & ~has1)
        empty_target = np.where((prefer2 | (has2 & ~has1))[..., None], zone2, zone1)
        return np.where(loaded[..., None], drop, empty_target), loaded | has1 | has2

    def blind_scripted_actions(self, state, poses, type_ids, caps, mask) -> np.ndarray:
        """The scripted policy without types or capabilities: not knowing which robots are fast,
        every empty robot follows one rule — the near zone 1 while it has material, then zone 2 —
        and a loaded one the drop-off."""
        target, ok = self.scripted_targets(state, poses[..., :2], np.ones_like(type_ids))
        return self.drive(state, poses, caps, mask, target, ok)

    state_amount_scale = 160.0
    """Material units per 1.0 in :meth:`global_features`: eight robots' loads at the payload
    scale (8 × 20). Raw amounts reach ~155; centralized critics and QMIX's mixer take the state
    unnormalized, and MAPPO's critic diverged on raw amounts (results/README.md)."""

    def global_features(self, state: dict) -> np.ndarray:
        """(B, 4) material left and initial per zone, in units of :attr:`state_amount_scale`."""
        return np.concatenate([state["left"], state["initial"]], axis=-1) / self.state_amount_scale

    # -- diagnostics ----------------------------------------------------------------------------
    robot_count_names = ("carrying", "still_held", "still_idle", "delivered")
    end_count_names = ("on_board_end",)

    def count_robots(self, before, raw, state, poses, type_ids, caps, mask) -> dict[str, np.ndarray]:
        return {"carrying": mask & (state["load"] > 0), "delivered": raw["unloaded_by_robot"]}

    def end_counts(self, state: dict) -> dict[str, np.ndarray]:
        return {"on_board_end": state["load"].sum(1) / state["initial"].sum(1)}

    # -- coordination ---------------------------------------------------------------------------
    coordination_name = "payload empty"
    coordination_doc = (
        "share of the payload that the material left could fill riding empty, mean over the steps; lower is better "
        "(loads held but never delivered keep it low too: read it beside progress)"
    )

    def coordination(self, state, poses, type_ids, caps, mask) -> np.ndarray:
        """(B,) share of the team's usable payload that is empty now: 1 − carried / usable, usable =
        min(the team's payload, material left in the zones + carried). 0 once no material is left to
        load (nobody can carry more); a team that never loads scores 1; lower is better. Loads
        never delivered keep it low: the constant +x action, whose robots load in zone 2 and stay
        there, scores below the scripted policy (0.30 against 0.43 on U_cap's design coalitions)."""
        carried = (state["load"] * mask).sum(axis=1)
        usable = np.minimum((caps[..., 1] * mask).sum(axis=1), state["left"].sum(axis=1) + carried)
        return np.where(usable > 1e-9, 1.0 - carried / np.maximum(usable, 1e-9), 0.0)

    # -- drawing ----------------------------------------------------------------------------------
    type_colors: ClassVar[dict] = {"fast": (15, 157, 88), "slow": (142, 68, 173)}
    counters_name = "material"
    bar_m_per_unit = 0.006
    """Width of a payload bar per unit of payload (a 20-unit robot: 0.12 m)."""

    def areas(self, state: dict | None = None, b: int = 0) -> tuple[Area, ...]:
        x0, x1, y0, y1 = ARENA
        amber, green = (230, 170, 20), (50, 170, 80)
        return (
            Area("material_1", "circle", (*ZONE1_CENTRE, ZONE1_RADIUS), amber, "zone 1"),
            Area("material_2", "box", (ZONE2_X, x1, y0, y1), amber, "zone 2"),
            Area("dropoff", "box", (x0, -ZONE2_X, y0, y1), green, "drop-off"),
        )

    def area_labels(self, state: dict, b: int) -> dict[str, str]:
        left, initial = state["left"][b], state["initial"][b]
        return {
            "material_1": f"zone 1: {left[0]:.1f} of {initial[0]:.1f} left",
            "material_2": f"zone 2: {left[1]:.1f} of {initial[1]:.1f} left",
            "dropoff": f"drop-off: {float(state['delivered'][b]):.1f} delivered",
        }

    def rings(self, caps: np.ndarray, type_ids: np.ndarray) -> tuple[Ring, ...]:
        return (Ring("step", np.ones(caps.shape[0], bool), caps[:, 0], (120, 120, 120), "dotted ring: step", True),)

    def bar(self, state: dict, b: int, caps: np.ndarray) -> Bar:
        n = caps.shape[0]
        payload = caps[:, 1]
        fraction = state["load"][b, :n] / np.maximum(payload, 1e-9)
        return Bar("payload", "load", payload * self.bar_m_per_unit, fraction, "bar: load / payload")

    def counters(self, state: dict, b: int, n: int) -> dict[str, float]:
        return {
            "left in zone 1": float(state["left"][b, 0]),
            "left in zone 2": float(state["left"][b, 1]),
            "carried": float(state["load"][b, :n].sum()),
            "delivered": float(state["delivered"][b]),
        }

    def status_text(self, state: dict, b: int, counters: dict[str, float]) -> str:
        c = counters
        return (
            f"left {c['left in zone 1']:.1f} + {c['left in zone 2']:.1f}, carried {c['carried']:.1f}, "
            f"delivered {c['delivered']:.1f}"
        )


HMT = MaterialTransport
