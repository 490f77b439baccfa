"""Predator Capture Prey (``pcp_v0``): sensing robots find prey, capture robots capture them.

| | |
|---|---|
| Agents | ``robot_0 … robot_{n-1}``, n = 2…; types ``sensing`` and ``capture``, >= 1 of each |
| Team changes | ``possible_agents`` = the largest team the env may get; ``agents`` = this episode's team, the first n of them. The others sit the episode out as agents done before it starts: ``reset``'s dicts hold the team's keys, and looking one of the others up gives a zero observation or an empty info (TorchRL's ``PettingZooWrapper(use_mask=True, done_on_any=False)`` reads every possible agent; SuperSuit's ``pad_observations_v0`` / ``black_death_v3`` and PettingZoo's conversions want the team's keys only); ``step`` ignores actions for them and returns none for them |
| Capabilities | [sensing radius m, capture radius m]: sensing robots (r_s, 0), capture robots (0, r_c) |
| Actions | Discrete(5): 0 stay, 1 +x, 2 −x, 3 +y, 4 −y — a 0.2 m waypoint for the robot's projected point |
| Step | 29 control ticks of 0.033 s (0.96 s): waypoint controller → safety filter → MuJoCo |
| Observation | Box(13,) float64, below |
| State | Box(4K + S·13,): prey (x, y) ×K, sensed ×K, captured ×K, then the observations of S = ``state_robots`` slots (default 8; a fixed-size baseline's run uses its ``max_robots``, 8 or 20) |
| Render | ``render_mode="rgb_array"``: ``env.render()`` → (448, 640, 3) uint8, the arena top-down (comat.viz.frames) |
| Horizon | 80 steps; ends early when every prey is captured |
| Prey | K = 6 static prey, ≥ 0.2 m apart in x ∈ [0.5, 1.4], y ∈ [−0.85, 0.85] |
| Spawn | robots ≥ 0.3 m apart in x ∈ [−1.4, −0.5], y ∈ [−0.85, 0.85], random headings |
| Large teams | U_scale has 10–20 robots. The 6 prey stay, so a 20-robot team has over three robots per prey; 16–20 robots take 16–20 of the spawn area's 24 places on its 0.3 m grid (random cells once random placement fails): a tight block at the start |

Observation layout (per robot, fixed length whatever the team size):

| index | feature |
|---|---|
| 0–1 | x, y (m) |
| 2–3 | cos θ, sin θ |
| 4–5 | type one-hot (sensing, capture) |
| 6–7 | capabilities / 0.5 m (sensing radius, capture radius) |
| 8 | 1 if an uncaptured prey is inside the robot's own sensing radius (sensing robots only) |
| 9–10 | offset (m) from the robot to that nearest prey, else 0 |
| 11–12 | team's fraction of prey sensed, captured |

Capture robots never see prey themselves: they learn where prey are from teammates (through
the model's communication; ``env.graph()`` gives the team graph).

Rules: a prey becomes *sensed*, for good, when a sensing robot's centre is within that robot's
sensing radius of it; a sensed prey is *captured* when a capture robot's centre is within its
capture radius (checked after every step).

Reward (shared by the team) = sum of named terms, each in ``infos[agent]["reward/<term>"]``:
``sensed`` +1 per newly sensed prey, ``captured`` +5 per capture, ``time`` −0.05 per step,
``violation`` −5 in a step with any robot–robot contact, Robotarium-style collision or boundary
exit. At the last step ``infos`` also hold ``episode/<metric>`` (comat.envs.core.EPISODE_METRICS).

Arguments: see :class:`comat.envs.base.TaskEnv`, plus ``n_prey`` (default 6).

Version history: v0 — first version (after MARBLER's PredatorCapturePrey and the COMAT paper).
"""

from __future__ import annotations

from typing import ClassVar

from comat.envs.base import TaskEnv
from comat.task_logic import PredatorCapturePrey

__all__ = ["PcpEnv"]


class PcpEnv(TaskEnv):
    """Predator Capture Prey as a PettingZoo parallel environment (spec sheet: module docstring)."""

    metadata: ClassVar[dict] = {"name": "pcp_v0", "render_modes": ["rgb_array"], "is_parallelizable": True}
    task_cls = PredatorCapturePrey
