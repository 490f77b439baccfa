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

import numpy as np

# (an export ships this file beside task_logic.py, with this import made local: sim2real/export.py)
from comat.task_logic import Area, Items, Ring, TaskLogic, grid_cells, nearest, spread_points

__all__ = ["PCP", "PREY_COLORS", "PredatorCapturePrey"]

PREY_COLORS = ((150, 150, 150), (244, 180, 0), (15, 157, 88))
"""Prey colour by state (RGB): free, sensed, captured."""


class PredatorCapturePrey(TaskLogic):
    """PCP: sensing robots find static prey, capture robots capture the sensed ones.

    State per env: prey positions (B, K, 2), sensed (B, K), captured (B, K), active (B, K). A
    prey becomes sensed (for good) when a sensing robot is within its sensing radius; a sensed
    prey is captured when a capture robot is within its capture radius.

    Prey per team (:meth:`prey_for`): K(N) = 6 for N <= 8 robots (the paper's 6: every U_train and
    U_test team), round(1.2 N) above (12 at 10 robots, 24 at 20), so prey per robot do not fall
    as teams grow; ``n_prey=K`` instead gives every team K prey (before the rule every team had
    6). Teams of one batch may differ in K: the arrays hold K_max prey slots (the count
    of the largest team the environment may get, :meth:`fit_teams`), and a slot past a team's K
    is *inactive*: ``active`` False, sensed and captured from the start, parked outside the arena
    (:attr:`parked`). Rewards, observations, the scripted policy, ``done`` and ``progress`` see
    active prey only; :meth:`global_features` keeps all K_max slots (a fixed length).
    """

    name = "pcp"
    meant_for = ("capability", "size")
    """The paper's question (unseen capabilities and team sizes; :mod:`comat.eval.validity` measures which
    its references can ask)."""
    types = ("sensing", "capture")
    capabilities = ("sensing_radius_m", "capture_radius_m")
    capability_scale = np.array([0.5, 0.5])
    horizon = 80
    ticks_per_step = 29
    step_m = 0.2
    spawn_box = (-1.4, -0.5, -0.85, 0.85)
    prey_box = (0.5, 1.4, -0.85, 0.85)
    prey_spacing = 0.2
    n_task_features = 5
    reward_terms = ("sensed", "captured", "time", "violation")
    reward_weights: ClassVar[dict] = {"sensed": 1.0, "captured": 5.0, "time": -0.05, "violation": -5.0}

    base_prey = 6
    """Prey of every team of up to :attr:`base_team` robots (the paper's 6)."""
    base_team = 8
    """The largest team the rule leaves at :attr:`base_prey` prey: U_test's (and the paper's) largest."""
    prey_per_robot = 1.2
    """Prey per robot above :attr:`base_team` (1.2 × 5 = the paper's 6 for its 5-robot teams)."""
    parked = (2.6, 0.0)
    """Where inactive prey slots sit, m: 1 m outside the arena, where no robot can be."""

    # -- what the composition sets draw (comat.tasks registers them; the spec sheet above) -------
    capability_limits = ((0.0, 1.0), (0.0, 1.0))
    """Physical limits, m: radii beyond 1 m would see or reach most of the 3.2 x 2 m arena from anywhere."""
    required = ((0,), (1,))
    ignored = ((1,), (0,))
    """A sensing robot captures nothing and a capture robot senses nothing: that radius is 0."""
    capability_bands: ClassVar[dict] = {
        "train": {"sensing": (((0.30, 0.55),), ((0.0, 0.0),)), "capture": (((0.0, 0.0),), ((0.35, 0.45),))},
        "test": {"sensing": (((0.20, 0.40),), ((0.0, 0.0),)), "capture": (((0.0, 0.0),), ((0.25, 0.40),))},
        # Below and above the training range, each band one rounding step (1e-6) short of it; radii
        # of 0.18-0.75 m keep the set physically sensible.
        "capability": {
            "sensing": (((0.18, 0.299999), (0.550001, 0.75)), ((0.0, 0.0),)),
            "capture": (((0.0, 0.0),), ((0.22, 0.349999), (0.450001, 0.60))),
        },
    }
    set_streams: ClassVar[dict] = {"test": 2, "train": 3, "scale": 5, "val": 7, "size": 9, "capability": 11}
    """The sets' random streams, fixed when they were first drawn (the stored sets must not change)."""

    def __init__(self, n_prey: int | None = None):
        bad = isinstance(n_prey, bool) or not isinstance(n_prey, (int, np.integer)) or n_prey < 1
        if n_prey is not None and bad:
            raise ValueError(
                f"n_prey must be a positive integer (that many prey for every team) or None "
                f"(the rule K(N) of PredatorCapturePrey.prey_for), got {n_prey!r}"
            )
        self.n_prey = None if n_prey is None else int(n_prey)
        if self.n_prey is not None and self.n_prey > self.prey_capacity():
            raise ValueError(
                f"n_prey must be at most {self.prey_capacity()} (the prey that fit {self.prey_spacing} m "
                f"apart in the prey area {self.prey_box} m), got {n_prey!r}"
            )
        self.largest_team: int | None = None

    @classmethod
    def prey_for(cls, n_robots: int) -> int:
        """K(N): prey of a team of ``n_robots`` under the rule (:attr:`base_prey` up to
        :attr:`base_team` robots, else round(:attr:`prey_per_robot` · N))."""
        if n_robots <= cls.base_team:
            return cls.base_prey
        # 1.2 N in integers: 12 N is even, so 12 N / 10 is never halfway and +5 // 10 rounds it.
        return (round(10 * cls.prey_per_robot) * int(n_robots) + 5) // 10

    def prey_capacity(self) -> int:
        """The most prey the prey area holds :attr:`prey_spacing` apart."""
        return grid_cells(self.prey_box, self.prey_spacing)

    def max_team_size(self) -> int:
        """The largest team PCP takes: its robots fit the spawn area and its prey K(N) the prey area."""
        n = self.spawn_capacity()
        while n > 0 and self.team_prey(n) > self.prey_capacity():
            n -= 1
        return n

    def _too_large(self, n: int) -> str:
        if self.team_prey(n) <= self.prey_capacity():
            return super()._too_large(n)
        x0, x1, y0, y1 = self.prey_box
        rule = (
            f"every team has n_prey={self.n_prey}"
            if self.n_prey is not None
            else f"prey grow with the team, K(N) = round({self.prey_per_robot}·N) above {self.base_team} robots"
        )
        return (
            f"pcp takes teams of at most {self.max_team_size()} robots, got {n}: {rule}, so {self.team_prey(n)} "
            f"prey for {n}, and at most {self.prey_capacity()} fit {self.prey_spacing} m apart in the prey area "
            f"x [{x0}, {x1}] m, y [{y0}, {y1}] m; for a bigger team give every team fewer prey "
            f"(make_env(..., n_prey=K) with K <= {self.prey_capacity()}) or lower "
            f"PredatorCapturePrey.prey_per_robot"
        )

    def team_prey(self, n_robots: int) -> int:
        """Prey of a team of ``n_robots`` in this task: ``n_prey`` if fixed, else :meth:`prey_for`."""
        return self.n_prey if self.n_prey is not None else self.prey_for(n_robots)

    def fit_teams(self, largest: int) -> None:
        """Size the prey slots of later :meth:`new_state` calls for teams of up to ``largest`` robots
        (the environment's largest coalition; without it, the robot slots N of ``new_state``)."""
        self.largest_team = int(largest)

    def step_lengths(self, caps: np.ndarray) -> np.ndarray:
        """Waypoint step (B, N), m: fixed 0.2 m in PCP."""
        return np.full(caps.shape[:-1], self.step_m)

    def new_state(self, B: int, N: int) -> dict:
        """Task state of B environments with N robot slots: K_max prey slots each."""
        K = self.team_prey(self.largest_team if self.largest_team is not None else N)
        return {
            "prey": np.zeros((B, K, 2)),
            "sensed": np.zeros((B, K), bool),
            "captured": np.zeros((B, K), bool),
            "active": np.ones((B, K), bool),
        }

    def reserve(self, state: dict, n_robots: int) -> None:
        """Grow every environment's prey slots, in place in ``state``, to fit a team of
        ``n_robots`` (a team larger than the environment's largest coalition, passed to a reset);
        the added slots are inactive. The global state grows with them: a learner that reads it
        never meets such a team in training (its slots come from its training coalitions)."""
        k, slots = self.team_prey(n_robots), state["prey"].shape[1]
        if k <= slots:
            return
        B, extra = state["prey"].shape[0], k - slots
        state["prey"] = np.concatenate([state["prey"], np.broadcast_to(self.parked, (B, extra, 2))], axis=1)
        for key, value in (("sensed", True), ("captured", True), ("active", False)):
            state[key] = np.concatenate([state[key], np.full((B, extra), value)], axis=1)

    def reset_env(self, state: dict, b: int, rng: np.random.Generator, caps: np.ndarray) -> None:
        """Place env b's prey for its team (capabilities ``caps`` (n, 2): only n is used): K(n)
        active prey, the remaining slots inactive."""
        k, slots = self.team_prey(caps.shape[0]), state["prey"].shape[1]
        assert k <= slots, "reserve() the prey slots before resetting a larger team"
        inactive = np.arange(slots) >= k
        state["prey"][b, :k] = spread_points(rng, k, self.prey_box, self.prey_spacing, "pcp prey area", "prey")
        state["prey"][b, k:] = self.parked
        state["active"][b] = ~inactive
        state["sensed"][b] = inactive
        state["captured"][b] = inactive

    def _within(self, state: dict, poses: np.ndarray, radius: np.ndarray, mask: np.ndarray) -> np.ndarray:
        """(B, N, K) robot i within radius_i of prey k (and a real robot)."""
        d = poses[:, :, None, :2] - state["prey"][:, None, :, :]
        return (d[..., 0] ** 2 + d[..., 1] ** 2 <= radius[..., None] ** 2) & mask[..., None]

    def update(self, state: dict, poses: np.ndarray, type_ids: np.ndarray, caps: np.ndarray, mask: np.ndarray) -> dict:
        """Advance the task state after a step; returns the raw (unweighted) reward counts (B,)."""
        sensing = self._within(state, poses, caps[..., 0], mask & (type_ids == 0)).any(axis=1)
        new_sensed = sensing & ~state["sensed"] & ~state["captured"]
        state["sensed"] |= sensing
        capture = self._within(state, poses, caps[..., 1], mask & (type_ids == 1)).any(axis=1)
        new_captured = capture & state["sensed"] & ~state["captured"]
        state["captured"] |= new_captured
        return {"sensed": new_sensed.sum(axis=1).astype(float), "captured": new_captured.sum(axis=1).astype(float)}

    def done(self, state: dict) -> np.ndarray:
        """Every prey of the team captured (B,)."""
        return state["captured"].all(axis=1)

    def progress(self, state: dict) -> np.ndarray:
        """Fraction of the active prey captured (B,)."""
        return self._fraction(state["captured"], state)

    @staticmethod
    def _fraction(flags: np.ndarray, state: dict) -> np.ndarray:
        """(B,) share of the active prey whose flag (B, K) is set."""
        return (flags & state["active"]).sum(axis=1) / state["active"].sum(axis=1)

    def task_features(self, state, poses, type_ids, caps, mask) -> np.ndarray:
        """[seen, dx, dy] to the nearest uncaptured prey inside the robot's own sensing radius
        (only sensing robots see prey), then the team's fractions of its (active) prey sensed and
        captured. Inactive slots count as captured, so no robot ever sees one."""
        d = state["prey"][:, None, :, :] - poses[:, :, None, :2]  # (B, N, K, 2)
        dist2 = d[..., 0] ** 2 + d[..., 1] ** 2
        visible = (dist2 <= caps[..., 0:1] ** 2) & ~state["captured"][:, None, :] & (type_ids == 0)[..., None]
        dist2 = np.where(visible, dist2, np.inf)
        k = np.argmin(dist2, axis=-1)
        seen = np.isfinite(np.take_along_axis(dist2, k[..., None], -1))[..., 0]
        near = np.take_along_axis(d, k[..., None, None], 2)[..., 0, :] * seen[..., None]
        _B, N = mask.shape
        progress = np.stack([self._fraction(state["sensed"], state), self._fraction(state["captured"], state)], -1)[
            :, None, :
        ].repeat(N, 1)
        return np.concatenate([seen[..., None].astype(float), near, progress], axis=-1)

    def scripted_targets(self, state: dict, centres: np.ndarray, type_ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Sensing robots: the nearest prey nobody has sensed yet; capture robots: the nearest
        sensed, uncaptured prey; either, when it has none: the nearest uncaptured prey (to be
        close when it is sensed). Inactive slots are captured: never a target."""
        B, N = type_ids.shape
        K = state["prey"].shape[1]
        open_prey = ~state["captured"]
        sensing = (type_ids == 0)[..., None]
        t_sense, ok_sense = nearest(
            centres, state["prey"], np.broadcast_to((~state["sensed"] & open_prey)[:, None], (B, N, K))
        )
        t_capture, ok_capture = nearest(
            centres, state["prey"], np.broadcast_to((state["sensed"] & open_prey)[:, None], (B, N, K))
        )
        t_any, ok_any = nearest(centres, state["prey"], np.broadcast_to(open_prey[:, None], (B, N, K)))
        target = np.where(
            sensing, np.where(ok_sense[..., None], t_sense, t_any), np.where(ok_capture[..., None], t_capture, t_any)
        )
        ok = np.where(sensing[..., 0], ok_sense | ok_any, ok_capture | ok_any)
        return target, ok

    def blind_scripted_actions(self, state, poses, type_ids, caps, mask) -> np.ndarray:
        """The scripted policy without types or radii: a robot that does not know whether it senses
        or captures heads for the nearest prey not captured yet, sensed or not (the plan's fallback
        for either role)."""
        centres = poses[..., :2]
        B, N = mask.shape
        open_prey = np.broadcast_to((~state["captured"])[:, None], (B, N, state["prey"].shape[1]))
        target, ok = nearest(centres, state["prey"], open_prey)
        return self.drive(state, poses, caps, mask, target, ok)

    def global_features(self, state: dict) -> np.ndarray:
        """(B, 4 K_max) prey positions, sensed and captured flags of every slot (inactive slots:
        parked, sensed and captured; K_max = 6 for teams of up to 8 robots, as before the rule)."""
        return np.concatenate(
            [
                state["prey"].reshape(state["prey"].shape[0], -1),
                state["sensed"].astype(float),
                state["captured"].astype(float),
            ],
            axis=-1,
        )

    # -- diagnostics --------------------------------------------------------------------------
    robot_count_names = ("still_held", "still_idle", "sensed", "captured")
    end_count_names = ("sensed_not_captured",)

    def count_before(self, state: dict) -> dict:
        return {"sensed": state["sensed"].copy(), "captured": state["captured"].copy()}

    def count_robots(self, before, raw, state, poses, type_ids, caps, mask) -> dict[str, np.ndarray]:
        """Prey that became sensed / captured in the step, credited to every robot of the right type
        within its radius of them."""
        out = {}
        for name, radius, kind in (("sensed", caps[..., 0], 0), ("captured", caps[..., 1], 1)):
            new = state[name] & ~before[name]  # (B, K) prey that became sensed / captured in this step
            if new.any():
                near = self._within(state, poses, radius, mask & (type_ids == kind))  # (B, N, K)
                out[name] = (near & new[:, None, :]).sum(-1)
        return out

    def end_counts(self, state: dict) -> dict[str, np.ndarray]:
        return {"sensed_not_captured": (state["sensed"] & ~state["captured"]).sum(1).astype(float)}

    # -- coordination ---------------------------------------------------------------------------
    coordination_name = "sensed prey waiting"
    coordination_doc = (
        "share of the team's prey sensed but not yet captured (the hand-off to capture robots lagging), mean over "
        "the steps; lower is better (0 also when nothing is sensed)"
    )

    def coordination(self, state, poses, type_ids, caps, mask) -> np.ndarray:
        """(B,) share of the team's prey sensed but not captured now: prey the sensing robots found that
        no capture robot has reached yet. Its mean over an episode's steps is the mean time a prey
        waits between sensed and captured, per prey, in shares of the episode; lower is better."""
        return self._fraction(state["sensed"] & ~state["captured"], state)

    # -- drawing and export -------------------------------------------------------------------
    type_colors: ClassVar[dict] = {"sensing": (66, 133, 244), "capture": (219, 68, 55)}
    counters_name = "prey"

    def areas(self, state: dict | None = None, b: int = 0) -> tuple[Area, ...]:
        return (
            Area("spawn", "box", self.spawn_box, (160, 160, 160), "robot spawn"),
            Area("prey_area", "box", self.prey_box, (80, 190, 80), "prey area"),
        )

    def items(self, state: dict, b: int) -> Items:
        """The team's prey (a smaller team's inactive slots left out), coloured free / sensed / captured."""
        on = state["active"][b]
        status = np.where(state["captured"][b][on], 2, np.where(state["sensed"][b][on], 1, 0))
        return Items("prey", state["prey"][b][on].copy(), status, ("free", "sensed", "captured"), PREY_COLORS, 0.035)

    def rings(self, caps: np.ndarray, type_ids: np.ndarray) -> tuple[Ring, ...]:
        return tuple(
            Ring(name, type_ids == k, caps[:, k], self.type_colors[name], f"ring: {name} radius")
            for k, name in enumerate(self.types)
        )

    def counters(self, state: dict, b: int, n: int) -> dict[str, float]:
        on = state["active"][b]
        return {"sensed": float(state["sensed"][b][on].sum()), "captured": float(state["captured"][b][on].sum())}

    def status_text(self, state: dict, b: int, counters: dict[str, float]) -> str:
        k = int(state["active"][b].sum())
        return f"prey sensed {int(counters['sensed'])}/{k}, captured {int(counters['captured'])}/{k}"

    def layout(self, state: dict, b: int) -> dict[str, list]:
        """The team's prey positions."""
        return {"prey": state["prey"][b][state["active"][b]].tolist()}

    def set_layout(self, state: dict, b: int, layout: dict[str, list]) -> None:
        prey = np.asarray(layout["prey"], dtype=float).reshape(-1, 2)
        state["prey"][b, : prey.shape[0]] = prey

    @classmethod
    def layout_options(cls, layout: dict[str, list]) -> dict:
        return {"n_prey": len(layout["prey"])}


PCP = PredatorCapturePrey
