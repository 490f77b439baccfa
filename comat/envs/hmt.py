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

from comat.envs.base import TaskEnv
from comat.task_logic import MaterialTransport

__all__ = ["HmtEnv"]


class HmtEnv(TaskEnv):
    """Heterogeneous Material Transport as a PettingZoo parallel environment (spec: module docstring)."""

    metadata: ClassVar[dict] = {"name": "hmt_v0", "render_modes": ["rgb_array"], "is_parallelizable": True}
    task_cls = MaterialTransport
