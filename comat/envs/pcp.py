"""Predator Capture Prey (``pcp_v0``): sensing robots find prey, capture robots capture them.

| | |
|---|---|
| Agents | ``robot_0 … robot_{n-1}``, n = 2…; types ``sensing`` and ``capture``, >= 1 of each |
| Team changes | ``possible_agents`` = the largest team the env may get; ``agents`` = this episode's team, the first n of them. The others sit the episode out as agents done before it starts: ``reset``'s dicts hold the team's keys, and looking one of the others up gives a zero observation or an empty info (TorchRL's ``PettingZooWrapper(use_mask=True, done_on_any=False)`` reads every possible agent; SuperSuit's ``pad_observations_v0`` / ``black_death_v3`` and PettingZoo's conversions want the team's keys only); ``step`` ignores actions for them and returns none for them |
| Capabilities | [sensing radius m, capture radius m]: sensing robots (r_s, 0), capture robots (0, r_c) |
| Actions | Discrete(5): 0 stay, 1 +x, 2 −x, 3 +y, 4 −y — a 0.2 m waypoint for the robot's projected point |
| Step | 29 control ticks of 0.033 s (0.96 s): waypoint controller → safety filter → MuJoCo |
| Observation | Box(13,) float64, below |
| State | Box(4K + S·13,): prey (x, y) ×K, sensed ×K, captured ×K over the env's K = K_max prey slots (K(N) of its largest coalition: 6 up to 8 robots, 24 for U_scale's and U_size's 20; a smaller team's unused slots are parked at (2.6, 0), sensed and captured), then the observations of S = ``state_robots`` slots (default 8, or the env's robot slots when larger: 20 for `scale` and `size`, so every set has a state; a fixed-size baseline's run uses its ``max_robots``, 8 or 20) |
| Render | ``render_mode="rgb_array"``: ``env.render()`` → (448, 640, 3) uint8, the arena top-down (comat.envs.render) |
| Horizon | 80 steps; ends early when every prey of the team is captured |
| Prey | K(N) static prey for a team of N robots: 6 for N ≤ 8 (every U_train, U_val, U_test and U_cap team: the paper's 6), round(1.2·N) above (11 at 9, 12 at 10, 14 at 12, 19 at 16, 24 at 20); ≥ 0.2 m apart in x ∈ [0.5, 1.4], y ∈ [−0.85, 0.85] (45 places on that grid); ``n_prey=K`` gives every team K instead |
| Spawn | robots ≥ 0.3 m apart in x ∈ [−1.4, −0.5], y ∈ [−0.85, 0.85], random headings |
| Large teams | U_scale and U_size have up to 20 robots. Prey grow with the team (K(N) above: 1.2 prey per robot, as at the paper's 5 robots and 6 prey), so prey per robot do not fall as the team grows (yet a wall of 16–20 robots that only steps +x still sweeps most prey: ``results/sets/PREY_RULE.md``; progress over time, AUC and time to 90 %, separates policies there); 16–20 robots take 16–20 of the spawn area's 24 places on its 0.3 m grid (random cells once random placement fails): a tight block at the start. Before the rule (issue 28) every team had 6 prey: U_scale PCP results from then (``results/grid_scale``) are saturated — over three robots per prey at 20 robots, 99–100 % progress for every policy-gradient method — and are not comparable with later ones |

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
the model's communication; ``env.graph()`` gives the team graph). Fractions (11–12) and the
``progress`` metric count the team's own K(N) prey.

Composition sets (``coalitions=``; :mod:`comat.team`), 20 teams each, at least one robot of each type:

* ``train`` (U_train): 3, 5 or 7 robots; sensing radius U(0.30, 0.55) m, capture radius
  U(0.35, 0.45) m. 6 prey.
* ``val`` (U_val): drawn like U_train from another stream, no team equal to a U_train team; the
  only set model selection may look at. 6 prey.
* ``test`` (U_test, the paper's): 2, 4, 6 or 8 robots; sensing U(0.20, 0.40), capture
  U(0.25, 0.40). 6 prey.
* ``scale`` (U_scale): 10, 12, 16 or 20 robots with U_test's radii; 12–24 prey.
* ``size`` (U_size): two teams of each size 2, 4, …, 20, U_train's radii: only the size differs
  from U_train; 6 prey up to 8 robots, then 12–24.
* ``capability`` (U_cap): 3, 5 or 7 robots like U_train, every radius outside U_train's: sensing
  [0.18, 0.30) ∪ (0.55, 0.75] m, capture [0.22, 0.35) ∪ (0.45, 0.60] m (a side with probability
  proportional to its width): smaller radii that must search and close in more, larger ones
  that reach prey from farther. 6 prey.

Rules: a prey becomes *sensed*, for good, when a sensing robot's centre is within that robot's
sensing radius of it; a sensed prey is *captured* when a capture robot's centre is within its
capture radius (checked after every step).

Reward (shared by the team) = sum of named terms, each in ``infos[agent]["reward/<term>"]``:
``sensed`` +1 per newly sensed prey, ``captured`` +5 per capture, ``time`` −0.05 per step,
``violation`` −5 in a step with any robot–robot contact, Robotarium-style collision or boundary
exit. At the last step ``infos`` also hold ``episode/<metric>`` (comat.envs.core.EPISODE_METRICS).

Arguments: see :class:`comat.envs.base.TaskEnv`, plus ``n_prey`` (default None: the rule K(N);
an integer: that many prey for every team, the behaviour before the rule).

Version history: v0 — first version (after MARBLER's PredatorCapturePrey and the COMAT paper).
Issue 28: the prey count K(N) grows with teams above 8 robots (U_train and U_test episodes are
unchanged, bit for bit; ``results/sets/PREY_RULE.md``: the rule and the scripted policy's figures
that accepted it).
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
