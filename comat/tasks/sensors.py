"""Heterogeneous Sensor Network (``sensors_v1``): robots with different sensing radii must take up
places from which, together, they watch every target at once — a wide cluster of targets needs a
robot that sees wide.

| | |
|---|---|
| Agents | ``robot_0 … robot_{n-1}``, n = 2…20; types ``wide`` and ``narrow``, >= 1 of each; team changes every episode as in every comat task |
| Capabilities | [sensing radius m] |
| Actions | Discrete(5): 0 stay, 1 +x, 2 −x, 3 +y, 4 −y — a 0.06 m waypoint for the robot's projected point |
| Step | 29 control ticks of 0.033 s (0.96 s): waypoint controller → safety filter → MuJoCo |
| Observation | Box(12,) float64, below |
| State | Box(3K + S·12,): targets (x, y) ×K, watched now ×K over the env's K_max = 3 × its largest team target slots (a smaller team's unused slots parked at (2.6, 0)), then the observations of S = ``state_robots`` slots |
| Horizon | 70 steps; ends early when every target is watched at once |
| Targets | one cluster of 3 targets per robot: the clusters' centres in x ∈ [−0.6, 1.45], y ∈ [−0.85, 0.85], >= 0.7 m apart for teams of up to 9 robots, 0.6 m up to 12, 0.5 m up to 20; each cluster sized by one robot of the team (drawn apart from where it starts): its targets at U(0.56, 0.62) × that robot's radius from the centre, 120° apart (± 0.3 rad). From the centre that robot watches all three, and a robot whose radius is less than 0.56 of it watches none of them from there |
| Spawn | robots >= 0.3 m apart in x ∈ [−1.45, −0.95], y ∈ [−0.85, 0.85], random headings |

Observation layout (per robot):

| index | feature |
|---|---|
| 0–1 | x, y (m) |
| 2–3 | cos θ, sin θ |
| 4–5 | type one-hot (wide, narrow) |
| 6 | sensing radius / 0.5 m |
| 7–8 | offset (m) to the nearest target no robot watches now |
| 9 | targets inside the robot's own radius now / 3 |
| 10 | team's fraction of targets watched now |
| 11 | the best fraction watched at once so far (progress) |

Composition sets (``coalitions=``; :mod:`comat.team`; sensing radius, m):

* ``train`` (U_train): 3, 5 or 7 robots; wide U(0.45, 0.55), narrow U(0.14, 0.18).
* ``val``: like U_train from another stream; ``size``: sizes 2…20, U_train's ranges.
* ``test`` (U_test): 2, 4, 6 or 8 robots; wide U(0.42, 0.60), narrow U(0.12, 0.20); ``scale``: 10,
  12, 16 or 20 robots with U_test's ranges.
* ``capability`` (U_cap): every radius outside its type's U_train range: wide [0.40, 0.45) ∪
  (0.55, 0.65], narrow [0.11, 0.14) ∪ (0.18, 0.21].

Rule (after every step): a target is *watched* while some robot's centre is within that robot's
sensing radius of it. Progress is the largest share of the team's targets watched at one time so
far; the episode is finished when all are watched at once.

Reward (shared) = named terms: ``coverage`` +1 per target by which the best count watched at once
grows, ``time`` −0.05 per step, ``violation`` −5 in a step with any robot–robot contact,
Robotarium-style collision or boundary exit.

References (``results/sets/references.md``): the scripted policy sends every robot to a cluster's
centre, the clusters shared out so that each robot's radius reaches its cluster's targets and the
summed squared distances are least; its capability-blind twin (``blind_scripted_actions``) shares
them out by distance alone.

Version history: v0 — first version (issue 49; a heterogeneous sensor network with sensing radius as
the capability, after the peers' coverage and discovery scenarios). v1 — the clusters 0.7 m apart
for teams of up to 9 robots and 0.6 m up to 12 (v0: 0.5 m for every team), the targets at 0.56 to
0.62 × the radius (v0: 0.5 to 0.62): in v0 a wide robot sent to a narrow robot's cluster watched
part of the next cluster too, and the capability-blind reference was 14 points below the scripted
one on U_cap, where 15 were asked for. v0's spec sheet gave an earlier draft's horizon, step,
target distances and ranges; this one gives the code's.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

# (an export ships this file beside task_logic.py, with this import made local: sim2real/export.py)
from comat.task_logic import Area, Items, Ring, TaskLogic, grid_cells, grow_slots, min_cost_assignment, spread_points

__all__ = ["SENSORS", "SensorNetwork"]


class SensorNetwork(TaskLogic):
    """Heterogeneous sensor network (module docstring). State per env: targets (B, K, 2), watched now
    (B, K), active (B, K), the clusters' centres (B, N, 2) and needed radii (B, N), the best count."""

    name = "sensors"
    version = 1
    title = "Heterogeneous Sensor Network"
    types = ("wide", "narrow")
    capabilities = ("sensing_radius_m",)
    capability_scale = np.array([0.5])
    horizon = 70
    ticks_per_step = 29
    step_m = 0.06
    """Waypoint step, m: fine enough that a robot settles within ~0.05 m of a cluster's centre (its
    projected point stops within half a step of the waypoint on each axis)."""
    spawn_box = (-1.45, -0.95, -0.85, 0.85)
    cluster_box = (-0.6, 1.45, -0.85, 0.85)
    cluster_spacings = (0.7, 0.6, 0.5)
    """The clusters' centres are at least the first of these (m) apart whose grid holds the team's
    clusters: 0.7 m for up to 9 robots, 0.6 m up to 12, 0.5 m up to 20. Far apart, a wide robot
    watches no other cluster's targets, so a cluster left to a robot that sees too little is lost."""
    per_cluster = 3
    spread = (0.56, 0.62)
    n_task_features = 5
    reward_terms = ("coverage", "time", "violation")
    reward_weights: ClassVar[dict] = {"coverage": 1.0, "time": -0.05, "violation": -5.0}
    parked = (2.6, 0.0)
    reset_uses_starts = True

    capability_limits = ((0.0, 1.0),)
    required = ((0,), (0,))
    capability_bands: ClassVar[dict] = {
        "train": {"wide": (((0.45, 0.55),),), "narrow": (((0.14, 0.18),),)},
        "test": {"wide": (((0.42, 0.60),),), "narrow": (((0.12, 0.20),),)},
        "capability": {
            "wide": (((0.40, 0.449999), (0.550001, 0.65)),),
            "narrow": (((0.11, 0.139999), (0.180001, 0.21)),),
        },
    }
    set_streams = 24
    """The composition sets' random streams are 24… (PCP and HMT 0–11, forage 12–17, navigation 18–23)."""

    def __init__(self) -> None:
        self.largest_team: int | None = None

    def max_team_size(self) -> int:
        return min(self.spawn_capacity(), grid_cells(self.cluster_box, min(self.cluster_spacings)))

    def fit_teams(self, largest: int) -> None:
        self.largest_team = int(largest)

    def step_lengths(self, caps: np.ndarray) -> np.ndarray:
        return np.full(caps.shape[:-1], self.step_m)

    def new_state(self, B: int, N: int) -> dict:
        n = max(N, self.largest_team or 0)
        K = self.per_cluster * n
        return {
            "targets": np.broadcast_to(self.parked, (B, K, 2)).copy(),
            "watched": np.zeros((B, K), bool),
            "active": np.zeros((B, K), bool),
            "centres": np.zeros((B, n, 2)),
            "need": np.zeros((B, n)),
            "clusters": np.zeros(B, np.int64),
            "best": np.zeros(B),
            "start": np.zeros((B, N, 2)),
        }

    def reserve(self, state: dict, n_robots: int) -> None:
        """Grow every env's target and cluster slots to fit a team of ``n_robots``."""
        n = state["centres"].shape[1]
        if n_robots <= n:
            return
        grow_slots(
            state, self.per_cluster * (n_robots - n), {"targets": self.parked, "watched": False, "active": False}
        )
        grow_slots(state, n_robots - n, {"centres": 0.0, "need": 0.0})

    def reset_env(self, state: dict, b: int, rng: np.random.Generator, caps: np.ndarray, starts=None) -> None:
        """One cluster of targets per robot of the team (caps (n, 1)), sized by that robot's radius;
        ``starts`` (n, 3): where the robots start (the scripted plans start from there)."""
        n, m = caps.shape[0], self.per_cluster
        if starts is not None:
            self.set_starts(state, b, starts)
        spacing = next((d for d in self.cluster_spacings if grid_cells(self.cluster_box, d) >= n), 0.0)
        centres = spread_points(
            rng, n, self.cluster_box, spacing or min(self.cluster_spacings), "sensors cluster area", "clusters"
        )
        order = rng.permutation(n)  # which robot's radius sizes which cluster: drawn apart from where it starts
        dist = rng.uniform(*self.spread, (n, m)) * caps[order, 0][:, None]
        angle = rng.uniform(-np.pi, np.pi, (n, 1)) + 2 * np.pi * np.arange(m) / m + rng.uniform(-0.3, 0.3, (n, m))
        targets = centres[:, None, :] + dist[..., None] * np.stack([np.cos(angle), np.sin(angle)], -1)
        targets = np.clip(targets, (-1.5, -0.9), (1.5, 0.9))
        state["targets"][b] = self.parked
        state["targets"][b, : n * m] = targets.reshape(-1, 2)
        state["active"][b] = np.arange(state["targets"].shape[1]) < n * m
        state["watched"][b] = False
        state["centres"][b] = 0.0
        state["centres"][b, :n] = centres
        state["need"][b] = 0.0
        state["need"][b, :n] = np.hypot(*(targets - centres[:, None, :]).transpose(2, 0, 1)).max(axis=1)
        state["clusters"][b] = n
        state["best"][b] = 0.0

    def _inside(self, state: dict, poses: np.ndarray, caps: np.ndarray, mask: np.ndarray) -> np.ndarray:
        """(B, N, K) target k inside robot i's sensing radius (a real robot)."""
        d = poses[:, :, None, :2] - state["targets"][:, None, :, :]
        return (d[..., 0] ** 2 + d[..., 1] ** 2 <= caps[..., 0:1] ** 2) & mask[..., None]

    def update(self, state: dict, poses: np.ndarray, type_ids: np.ndarray, caps: np.ndarray, mask: np.ndarray) -> dict:
        state["watched"] = self._inside(state, poses, caps, mask).any(axis=1) & state["active"]
        count = state["watched"].sum(axis=1).astype(float)
        gain = np.maximum(count - state["best"], 0.0)
        state["best"] = np.maximum(state["best"], count)
        return {"coverage": gain}

    def done(self, state: dict) -> np.ndarray:
        return state["best"] >= state["active"].sum(axis=1)

    def progress(self, state: dict) -> np.ndarray:
        """The largest share of the team's targets watched at once so far (B,)."""
        return state["best"] / np.maximum(state["active"].sum(axis=1), 1)

    def task_features(self, state, poses, type_ids, caps, mask) -> np.ndarray:
        d = state["targets"][:, None, :, :] - poses[:, :, None, :2]
        open_ = state["active"] & ~state["watched"]
        dist2 = np.where(open_[:, None, :], d[..., 0] ** 2 + d[..., 1] ** 2, np.inf)
        k = np.argmin(dist2, axis=-1)
        ok = np.isfinite(np.take_along_axis(dist2, k[..., None], -1))[..., 0]
        offset = np.take_along_axis(d, k[..., None, None], 2)[..., 0, :] * ok[..., None]
        own = self._inside(state, poses, caps, mask).sum(-1) / self.per_cluster
        B, N = mask.shape
        total = np.maximum(state["active"].sum(axis=1), 1)
        now = np.broadcast_to((state["watched"].sum(axis=1) / total)[:, None], (B, N))
        best = np.broadcast_to(self.progress(state)[:, None], (B, N))
        return np.concatenate([offset, np.stack([own, now, best], -1)], axis=-1)

    def global_features(self, state: dict) -> np.ndarray:
        B = state["targets"].shape[0]
        return np.concatenate([state["targets"].reshape(B, -1), state["watched"].astype(float)], axis=-1)

    # -- the scripted references ------------------------------------------------------------------
    def _plan(self, state: dict, centres: np.ndarray, radius: np.ndarray | None, mask: np.ndarray) -> tuple:
        """Each robot's cluster centre (B, N, 2): robots and clusters paired, from where the robots
        started (a plan made at departure that holds over the episode), with the least summed
        squared distance, where a robot whose ``radius`` (B, N) falls short of a cluster's need costs
        100 m² more (``radius`` None: radii unknown, distance alone)."""
        B, N = mask.shape
        target = np.zeros((B, N, 2))
        has = np.zeros((B, N), bool)
        for b in range(B):
            robots = np.flatnonzero(mask[b])
            clusters = np.arange(int(state["clusters"][b]))
            if not robots.size or not clusters.size:
                continue
            gap = state["centres"][b][None, clusters] - state["start"][b, robots][:, None]
            cost = (gap**2).sum(-1)
            if radius is not None:
                cost = cost + 100.0 * (radius[b, robots][:, None] < state["need"][b, clusters][None] - 1e-9)
            rows, cols = min_cost_assignment(cost)
            target[b, robots[rows]], has[b, robots[rows]] = state["centres"][b, clusters[cols]], True
        return target, has

    def scripted_actions(self, state, poses, type_ids, caps, mask) -> np.ndarray:
        """The scripted reference (module docstring)."""
        centres = poses[..., :2]
        target, ok = self._plan(state, centres, caps[..., 0], mask)
        return self.drive(state, poses, caps, mask, target, ok)

    def blind_scripted_actions(self, state, poses, type_ids, caps, mask) -> np.ndarray:
        """The same plan without the radii: clusters shared out by distance alone."""
        centres = poses[..., :2]
        target, ok = self._plan(state, centres, None, mask)
        return self.drive(state, poses, caps, mask, target, ok)

    # -- diagnostics, drawing and export ------------------------------------------------------------
    end_count_names = ("unwatched_end",)

    def end_counts(self, state: dict) -> dict[str, np.ndarray]:
        return {"unwatched_end": (state["active"] & ~state["watched"]).sum(1).astype(float)}

    type_colors: ClassVar[dict] = {"wide": (66, 133, 244), "narrow": (244, 180, 0)}
    counters_name = "targets"

    def areas(self, state: dict | None = None, b: int = 0) -> tuple[Area, ...]:
        return (
            Area("spawn", "box", self.spawn_box, (160, 160, 160), "robot spawn"),
            Area("cluster_area", "box", self.cluster_box, (120, 120, 200), "target clusters"),
        )

    def items(self, state: dict, b: int) -> Items:
        on = state["active"][b]
        status = state["watched"][b][on].astype(np.int64)
        return Items(
            "targets",
            state["targets"][b][on].copy(),
            status,
            ("unwatched", "watched"),
            ((219, 68, 55), (15, 157, 88)),
            0.03,
        )

    def rings(self, caps: np.ndarray, type_ids: np.ndarray) -> tuple[Ring, ...]:
        return tuple(
            Ring(name, type_ids == k, caps[:, 0], self.type_colors[name], f"ring: {name} sensing radius")
            for k, name in enumerate(self.types)
        )

    def counters(self, state: dict, b: int, n: int) -> dict[str, float]:
        return {"watched": float(state["watched"][b].sum()), "best": float(state["best"][b])}

    def status_text(self, state: dict, b: int, counters: dict[str, float]) -> str:
        k = int(state["active"][b].sum())
        return f"targets watched {int(counters['watched'])}/{k}, best {int(counters['best'])}/{k}"

    def layout(self, state: dict, b: int) -> dict[str, list]:
        n = int(state["clusters"][b])
        return {
            "targets": state["targets"][b][state["active"][b]].tolist(),
            "centres": state["centres"][b, :n].tolist(),
            "need": state["need"][b, :n].tolist(),
        }

    def set_starts(self, state: dict, b: int, starts: np.ndarray) -> None:
        n = starts.shape[0]
        state["start"][b] = 0.0
        state["start"][b, :n] = np.asarray(starts, dtype=float)[:, :2]

    def set_layout(self, state: dict, b: int, layout: dict[str, list]) -> None:
        targets = np.asarray(layout["targets"], dtype=float).reshape(-1, 2)
        n = len(layout["centres"])
        state["targets"][b] = self.parked
        state["targets"][b, : targets.shape[0]] = targets
        state["active"][b] = np.arange(state["targets"].shape[1]) < targets.shape[0]
        state["watched"][b] = False
        state["centres"][b] = 0.0
        state["centres"][b, :n] = np.asarray(layout["centres"], dtype=float).reshape(-1, 2)
        state["need"][b] = 0.0
        state["need"][b, :n] = np.asarray(layout["need"], dtype=float)
        state["clusters"][b] = n
        state["best"][b] = 0.0


SENSORS = SensorNetwork
