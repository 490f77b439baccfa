"""Heterogeneous Sensor Network (``sensors_v2``): robots with different sensing radii must take up
places from which, together, they cover every cluster of targets at once. A cluster is covered when
one robot sees all three of its targets, and each cluster's size is drawn against the team's own
radii, so which robot can cover which cluster is decided by how far it actually sees, not by its type.

Meant for both families: **capability** (scripted − type_only on U_cap: the types' radii overlap and
each type is wide, so a robot's type leaves open which clusters it covers) and **size** (scripted −
blind on U_size ∪ U_scale: one cluster per robot, 2 to 20 of them, shared out by radius).

| | |
|---|---|
| Agents | ``robot_0 … robot_{n-1}``, n = 2…20; types ``wide`` and ``narrow``, >= 1 of each; team changes every episode as in every comat task |
| Capabilities | [sensing radius m], physical limits 0.08–0.65 m |
| Actions | Discrete(5): 0 stay, 1 +x, 2 −x, 3 +y, 4 −y — a 0.08 m waypoint for the robot's projected point |
| Step | 29 control ticks of 0.033 s (0.96 s): waypoint controller → safety filter → MuJoCo |
| Observation | Box(15,) float64, below |
| State | Box(3K + K/3 + S·15,): targets (x, y) ×K, watched now ×K, each cluster's need / 0.5 m ×K/3, over the env's K = 3 × its largest team target slots (a smaller team's unused targets parked at (2.6, 0), their needs 0), then the observations of S = ``state_robots`` slots |
| Horizon | 60 steps; ends early when every cluster is covered at once |
| Clusters | one cluster of 3 targets per robot, centres in x ∈ [−0.6, 1.45], y ∈ [−0.85, 0.85], >= 0.7 m apart for teams of up to 9 robots, 0.6 m up to 12, 0.5 m up to 20 |
| Needs | each cluster is sized by one robot of the team (a random one, drawn apart from where it starts): its three targets lie 120° apart (± 0.3 rad) at its *need* from the centre, U(0.92, 1.0) × (that robot's radius − 0.06 m) (less where the arena's edge clips a target). A robot sees the whole cluster from anywhere within 0.06 m of the centre when radius − 0.06 m >= need: the robot that sized it, any wider one, and none much narrower, whatever its type |
| Spawn | robots >= 0.3 m apart in x ∈ [−1.45, −0.95], y ∈ [−0.85, 0.85], random headings |

Observation layout (per robot):

| index | feature |
|---|---|
| 0–1 | x, y (m) |
| 2–3 | cos θ, sin θ |
| 4–5 | type one-hot (wide, narrow) |
| 6 | own sensing radius / 0.5 m |
| 7–8 | offset (m) to the centre of the nearest *open* cluster (one no robot covers now); 0 when none |
| 9 | that cluster's need / 0.5 m |
| 10–11 | offset (m) to the centre of the nearest open cluster this robot can cover (need <= own radius − 0.06 m); 0 when none |
| 12 | the most targets of one cluster inside the robot's radius now / 3 (1: it covers a cluster) |
| 13 | team's fraction of clusters covered now |
| 14 | the best fraction covered at once so far (progress) |

Teammates' radii reach a robot through the model (their observations), not its own.

Composition sets (``coalitions=``; :mod:`comat.team`; sensing radius, m). The two types overlap, and
each spans a wide range:

* ``train`` (U_train): 3, 5 or 7 robots; wide U(0.30, 0.50), narrow U(0.15, 0.35).
* ``val``: like U_train from another stream; ``size``: sizes 2…20, U_train's ranges.
* ``test`` (U_test): 2, 4, 6 or 8 robots; wide U(0.27, 0.54), narrow U(0.12, 0.38); ``scale``: 10,
  12, 16 or 20 robots with U_test's ranges.
* ``capability`` (U_cap): every radius outside its type's U_train range, within the physical
  limits: wide [0.18, 0.30) ∪ (0.50, 0.62], narrow [0.08, 0.15) ∪ (0.35, 0.45].

Rules (after every step): a target is *watched* while some robot's centre is within that robot's
sensing radius of it; a cluster is *covered* while one robot watches all three of its targets (a
cluster's three readings are fused on one robot: two robots seeing parts of it do not cover it).
Progress is the largest share of the team's clusters covered at one time so far; the episode is
finished when all are covered at once. The state also keeps what the robots have *measured*, as a
real robot would (it counts the targets it sees): a robot stopped (moved < 0.01 m in the step)
within 0.06 m of a cluster's centre that sees all its targets can cover that need (``can_cover``,
the largest such need); one that does not has fallen short there (``fell_short``, per robot and
cluster); when a robot first falls short somewhere, the robots' positions then become the planners'
new starting point (``plan_from``; at first the starts).

Reward (shared) = named terms: ``coverage`` +1 per cluster by which the best count covered at once
grows, ``time`` −0.05 per step, ``violation`` −5 in a step with any robot–robot contact,
Robotarium-style collision or boundary exit.

Coordination (:meth:`SensorNetwork.coordination`, "clusters open, able robot idle"): the share of
the team's clusters that no robot covers while some robot able to cover it (radius − 0.06 m >= need)
stands still (moved < 0.01 m in the step) covering none; lower is better; an episode's value is its
mean over its steps. Travel does not count (a robot on its way is not idle), so the planners, which
stop only where they cover or measure, sit near 0 (design data, U_train, one episode per coalition:
scripted 0.001, type_only 0.004, blind 0.009) and a policy that parks robots where they are useless
does not (constant +x 0.37, random 0.52).

References (``results/sets/validity.md``): one planner for the three planning rungs. It pairs
robots and clusters with the least summed squared distance from ``plan_from``, plus 100 m² (and
100 m² more per 0.1 m of believed shortfall) for a pair it doubts and 10⁴ m² for a pair measured to
fall short, and sends each robot to its cluster's centre, around settled teammates rather than
behind them. The *scripted* rung believes the true radii (``caps``; never the state's), the
*type_only* rung its type's mean radius, and both infer from a robot falling short at one need that it
falls short at every larger one and from a success that it covers every smaller one; the *blind*
twin (``blind_scripted_actions``) knows neither types nor radii: it believes every robot able and
remembers only where each one fell short. All three re-plan when a robot finds it falls short (a fact
a robot measures), so what the scripted rung gains over the others is the time their trials cost.

Version history: v0 — first version (issue 49; a heterogeneous sensor network with sensing radius as
the capability, after the peers' coverage and discovery scenarios). v1 — the clusters 0.7 m apart
for teams of up to 9 robots and 0.6 m up to 12 (v0: 0.5 m for every team), the targets at 0.56 to
0.62 × the radius (v0: 0.5 to 0.62): in v0 a wide robot sent to a narrow robot's cluster watched
part of the next cluster too, and the capability-blind reference was 14 points below the scripted
one on U_cap, where 15 were asked for; v1 was re-tuned after v0 missed that and judged on the same
seed. v2 (issue 64) — in v1 a robot's type decided which clusters it could cover in 100 % of
robot–cluster pairs (wide U(0.45, 0.55) and narrow U(0.14, 0.18) were disjoint and every need
0.56–0.62 × a radius), so a planner knowing only types equalled the scripted one, robots did not
observe what a cluster needs, and learners sat below the blind reference. v2: overlapping, wide
radius bands (physical limits 0.08–0.65 m, v1 0–1) and needs of 0.92–1.0 × (a teammate's radius −
0.06 m), so covering turns on the radius itself; a cluster is covered only by one robot seeing all of
it and progress counts clusters (v1: targets, which partial views of neighbouring clusters padded);
observations with the nearest open cluster's need and the nearest one the robot can cover, the
state with every cluster's need; the measured records and the planners re-planning on them (type_only
and blind adapt where a robot notices failure); a 0.08 m step (v1 0.06) and 60 steps (v1 70); the
coordination metric. Designed on the design coalitions (seed 1) and episode seed 2,000,003 only;
there, 3 episodes per coalition: scripted 99.3, 98.7, 99.8, 96.6 and 96.8 % progress on U_train,
U_test, U_cap, U_size and U_scale; scripted − type_only on U_cap +24.8 points [18.5, 31.0] (95 % t
over the 20 coalitions' paired means); scripted − blind on U_size ∪ U_scale +17.4 [15.1, 19.6];
type_only above blind on U_train (+7.3), level with it on U_cap (−3.8 [−9.2, 1.6]).
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

# (an export ships this file beside task_logic.py, with this import made local: sim2real/export.py)
from comat.task_logic import (
    ACTIONS,
    WAYPOINT_LIMITS,
    Area,
    Items,
    Ring,
    TaskLogic,
    grid_cells,
    grow_slots,
    min_cost_assignment,
    spread_points,
)

__all__ = ["SENSORS", "SensorNetwork"]


class SensorNetwork(TaskLogic):
    """Heterogeneous sensor network (module docstring). State per env: targets (B, K, 2), watched now
    (B, K), active (B, K); the clusters' centres (B, C, 2), needs (B, C) and covered now (B, C) with
    C = K / 3 cluster slots; the best count; what the robots measured (``can_cover`` (B, N),
    ``fell_short`` (B, C, N)), where the planners start from (``plan_from`` (B, N, 2)) and where
    the robots were a step ago (``last_xy`` (B, N, 2))."""

    name = "sensors"
    meant_for = ("capability", "size")
    """Both families (its spec sheet says why; :mod:`comat.eval.validity` measures them)."""
    version = 2
    title = "Heterogeneous Sensor Network"
    types = ("wide", "narrow")
    capabilities = ("sensing_radius_m",)
    capability_scale = np.array([0.5])
    horizon = 60
    ticks_per_step = 29
    step_m = 0.08
    """Waypoint step, m: a robot the planner stops is within half a step of its cluster's centre on
    each axis (0.057 m at most; 99 % of the scripted rung's robots on U_train stop within 0.047 m)."""
    spawn_box = (-1.45, -0.95, -0.85, 0.85)
    cluster_box = (-0.6, 1.45, -0.85, 0.85)
    cluster_spacings = (0.7, 0.6, 0.5)
    """The clusters' centres are at least the first of these (m) apart whose grid holds the team's
    clusters: 0.7 m for up to 9 robots, 0.6 m up to 12, 0.5 m up to 20."""
    per_cluster = 3
    settle_m = 0.06
    """A robot within this distance (m) of a cluster's centre is *at* it (what it measures there is
    recorded); a radius covers a need when radius − settle_m >= need, so a robot that stops anywhere
    that close still watches every target."""
    still_m = 0.01
    """A robot that moved less than this (m) in the last step has stopped: it measures only then."""
    need_fraction = (0.92, 1.0)
    """A cluster's need is U(need_fraction) × (its sizing robot's radius − settle_m): at 1.0 only that
    robot and wider ones cover it; at 0.92 robots a few cm narrower do too."""
    n_task_features = 8
    reward_terms = ("coverage", "time", "violation")
    reward_weights: ClassVar[dict] = {"coverage": 1.0, "time": -0.05, "violation": -5.0}
    parked = (2.6, 0.0)
    reset_uses_starts = True
    doubt_cost_m2 = 100.0
    doubt_scale_m = 0.1
    """Extra cost of a robot–cluster pair the planner believes the robot cannot cover (m², far above
    any squared distance in the arena), growing by the same again per ``doubt_scale_m`` of believed
    shortfall: a cluster no robot is believed to cover goes to the one believed nearest to it."""
    short_cost_m2 = 1e4
    """Extra cost of a pair the robot has measured it cannot cover (m²): above any number of doubted
    pairs, so a plan tries what it only doubts before it keeps what it knows fails."""

    capability_limits = ((0.08, 0.65),)
    required = ((0,), (0,))
    capability_bands: ClassVar[dict] = {
        "train": {"wide": (((0.30, 0.50),),), "narrow": (((0.15, 0.35),),)},
        "test": {"wide": (((0.27, 0.54),),), "narrow": (((0.12, 0.38),),)},
        "capability": {
            "wide": (((0.18, 0.299999), (0.500001, 0.62)),),
            "narrow": (((0.08, 0.149999), (0.350001, 0.45)),),
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
            "covered": np.zeros((B, n), bool),
            "clusters": np.zeros(B, np.int64),
            "best": np.zeros(B),
            "can_cover": np.zeros((B, N)),
            "fell_short": np.zeros((B, n, N), bool),
            "plan_from": np.zeros((B, N, 2)),
            "last_xy": np.zeros((B, N, 2)),
            "still": np.zeros((B, N), bool),
        }

    def reserve(self, state: dict, n_robots: int) -> None:
        """Grow every env's target and cluster slots to fit a team of ``n_robots``."""
        n = state["centres"].shape[1]
        if n_robots <= n:
            return
        grow_slots(
            state, self.per_cluster * (n_robots - n), {"targets": self.parked, "watched": False, "active": False}
        )
        grow_slots(state, n_robots - n, {"centres": 0.0, "need": 0.0, "covered": False, "fell_short": False})

    def reset_env(self, state: dict, b: int, rng: np.random.Generator, caps: np.ndarray, starts=None) -> None:
        """One cluster of targets per robot of the team (caps (n, 1)), its need drawn against one
        robot's radius; ``starts`` (n, 3): where the robots start (the planners start from there)."""
        n, m = caps.shape[0], self.per_cluster
        spacing = next((d for d in self.cluster_spacings if grid_cells(self.cluster_box, d) >= n), 0.0)
        centres = spread_points(
            rng, n, self.cluster_box, spacing or min(self.cluster_spacings), "sensors cluster area", "clusters"
        )
        order = rng.permutation(n)  # which robot's radius sizes which cluster: drawn apart from where it starts
        reach = np.maximum(caps[order, 0] - self.settle_m, 0.0)
        dist = rng.uniform(*self.need_fraction, n) * reach
        angle = rng.uniform(-np.pi, np.pi, (n, 1)) + 2 * np.pi * np.arange(m) / m + rng.uniform(-0.3, 0.3, (n, m))
        targets = centres[:, None, :] + dist[:, None, None] * np.stack([np.cos(angle), np.sin(angle)], -1)
        targets = np.clip(targets, (-1.5, -0.9), (1.5, 0.9))  # towards the centre: a need only shrinks
        state["targets"][b] = self.parked
        state["targets"][b, : n * m] = targets.reshape(-1, 2)
        state["active"][b] = np.arange(state["targets"].shape[1]) < n * m
        state["watched"][b] = False
        state["centres"][b] = 0.0
        state["centres"][b, :n] = centres
        state["need"][b] = 0.0
        state["need"][b, :n] = np.hypot(*(targets - centres[:, None, :]).transpose(2, 0, 1)).max(axis=1)
        state["clusters"][b] = n
        state["covered"][b] = False
        state["best"][b] = 0.0
        state["can_cover"][b] = 0.0
        state["fell_short"][b] = False
        if starts is not None:
            self.set_starts(state, b, starts)

    def _inside(self, state: dict, poses: np.ndarray, caps: np.ndarray, mask: np.ndarray) -> np.ndarray:
        """(B, N, K) target k inside robot i's sensing radius (a real robot)."""
        d = poses[:, :, None, :2] - state["targets"][:, None, :, :]
        return (d[..., 0] ** 2 + d[..., 1] ** 2 <= caps[..., 0:1] ** 2) & mask[..., None]

    def _whole(self, inside: np.ndarray) -> np.ndarray:
        """(B, N, C) robot i watches every target of cluster c, from (B, N, K) :meth:`_inside`."""
        B, N, K = inside.shape
        return inside.reshape(B, N, K // self.per_cluster, self.per_cluster).all(-1)

    @staticmethod
    def _open(state: dict) -> np.ndarray:
        """(B, C) the team's clusters no robot covers now."""
        return (np.arange(state["centres"].shape[1]) < state["clusters"][:, None]) & ~state["covered"]

    def update(self, state: dict, poses: np.ndarray, type_ids: np.ndarray, caps: np.ndarray, mask: np.ndarray) -> dict:
        inside = self._inside(state, poses, caps, mask)
        state["watched"] = inside.any(axis=1) & state["active"]
        whole = self._whole(inside)
        state["covered"] = whole.any(axis=1)
        self._measure(state, poses, whole, mask)
        count = state["covered"].sum(axis=1).astype(float)
        gain = np.maximum(count - state["best"], 0.0)
        state["best"] = np.maximum(state["best"], count)
        return {"coverage": gain}

    def _measure(self, state: dict, poses: np.ndarray, whole: np.ndarray, mask: np.ndarray) -> None:
        """Record what each robot at a cluster's centre saw (module docstring, rules)."""
        C = state["centres"].shape[1]
        gap = state["centres"][:, None, :, :] - poses[:, :, None, :2]
        real = mask[..., None] & (np.arange(C) < state["clusters"][:, None])[:, None, :]
        still = (np.hypot(*(poses[..., :2] - state["last_xy"]).transpose(2, 0, 1)) < self.still_m) & mask
        state["last_xy"], state["still"] = poses[..., :2].copy(), still
        at = (gap[..., 0] ** 2 + gap[..., 1] ** 2 <= self.settle_m**2) & real & still[..., None]
        need = np.broadcast_to(state["need"][:, None, :], at.shape)
        state["can_cover"] = np.maximum(state["can_cover"], np.where(at & whole, need, 0.0).max(-1))
        short = (at & ~whole).transpose(0, 2, 1)  # (B, C, N)
        learned = (short & ~state["fell_short"]).any(axis=(1, 2))
        state["fell_short"] |= short
        state["plan_from"][learned] = poses[learned, :, :2]

    def done(self, state: dict) -> np.ndarray:
        """Every cluster of the team covered at once (B,)."""
        return state["best"] >= state["clusters"]

    def progress(self, state: dict) -> np.ndarray:
        """The largest share of the team's clusters covered at once so far (B,)."""
        return state["best"] / np.maximum(state["clusters"], 1)

    def task_features(self, state, poses, type_ids, caps, mask) -> np.ndarray:
        """(B, N, 8): the observation's task part (module docstring, indices 7–14)."""
        centres, need = state["centres"], state["need"]
        gap = centres[:, None, :, :] - poses[:, :, None, :2]  # (B, N, C, 2)
        dist2 = gap[..., 0] ** 2 + gap[..., 1] ** 2
        open_ = np.broadcast_to(self._open(state)[:, None, :], dist2.shape)
        able = need[:, None, :] <= caps[..., 0:1] - self.settle_m
        near, ok = self._nearest(dist2, open_)
        mine, mine_ok = self._nearest(dist2, open_ & able)
        offset = np.take_along_axis(gap, near[..., None, None], 2)[..., 0, :] * ok[..., None]
        its_need = np.take_along_axis(need[:, None, :], near[..., None], 2)[..., 0] * ok / self.capability_scale[0]
        coverable = np.take_along_axis(gap, mine[..., None, None], 2)[..., 0, :] * mine_ok[..., None]
        inside = self._inside(state, poses, caps, mask)
        B, N, K = inside.shape
        own = inside.reshape(B, N, K // self.per_cluster, self.per_cluster).sum(-1).max(-1) / self.per_cluster
        total = np.maximum(state["clusters"], 1)
        now = np.broadcast_to((state["covered"].sum(axis=1) / total)[:, None], (B, N))
        best = np.broadcast_to(self.progress(state)[:, None], (B, N))
        return np.concatenate([offset, its_need[..., None], coverable, np.stack([own, now, best], -1)], axis=-1)

    @staticmethod
    def _nearest(dist2: np.ndarray, allowed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Index (B, N) of the nearest allowed cluster by squared distance (B, N, C), and whether any."""
        d = np.where(allowed, dist2, np.inf)
        k = np.argmin(d, axis=-1)
        return k, np.isfinite(np.take_along_axis(d, k[..., None], -1))[..., 0]

    def global_features(self, state: dict) -> np.ndarray:
        B = state["targets"].shape[0]
        return np.concatenate(
            [
                state["targets"].reshape(B, -1),
                state["watched"].astype(float),
                state["need"] / self.capability_scale[0],
            ],
            axis=-1,
        )

    # -- the reference planners --------------------------------------------------------------------
    def _plan(self, state: dict, radius: np.ndarray | None, mask: np.ndarray) -> tuple:
        """Each robot's cluster centre (B, N, 2) and whether it has one (B, N): robots and clusters
        paired from ``plan_from`` with the least summed squared distance plus what the planner
        doubts (module docstring, references). ``radius`` (B, N): the radii it believes; None: the
        blind twin, which believes every robot able and knows only where each fell short."""
        B, N = mask.shape
        target = np.zeros((B, N, 2))
        has = np.zeros((B, N), bool)
        for b in range(B):  # one assignment per env (the Hungarian method is sequential)
            robots = np.flatnonzero(mask[b])
            clusters = np.arange(int(state["clusters"][b]))
            if not robots.size or not clusters.size:
                continue
            gap = state["centres"][b][None, clusters] - state["plan_from"][b, robots][:, None]
            need = state["need"][b, clusters][None]
            short = state["fell_short"][b][np.ix_(clusters, robots)].T  # (R, C) measured unable
            doubt = np.zeros(short.shape)
            if radius is not None:  # a radius short of one need is short of every larger one
                short = short | (need >= np.where(short, need, np.inf).min(-1, keepdims=True))
                lack = need - (radius[b, robots][:, None] - self.settle_m)  # believed shortfall, m
                can = need <= state["can_cover"][b, robots][:, None]
                doubt = np.where(~can & (lack > 1e-9), 1.0 + lack / self.doubt_scale_m, 0.0)
            cost = (gap**2).sum(-1) + self.doubt_cost_m2 * doubt + self.short_cost_m2 * short
            rows, cols = min_cost_assignment(cost)
            target[b, robots[rows]], has[b, robots[rows]] = state["centres"][b, clusters[cols]], True
        return target, has

    pass_clear_m = (0.3, 0.16)
    """A settled teammate (at its target, or without one) less than 0.3 m ahead along the axis a robot
    means to move on, and less than 0.22 m to its side, blocks that move (the safety filter would
    hold the robot behind it)."""

    def drive(self, state, poses, caps, mask, target, ok) -> np.ndarray:
        """Actions (B, N) toward ``target`` (B, N, 2), as :func:`toward` (the larger axis first), but
        around settled teammates (:attr:`pass_clear_m`) instead of waiting behind them for good: a
        robot keeps the way it faces while that move is free and brings it half a step or more
        nearer (or is its step aside), else takes the larger axis if free, else the other axis if
        free and useful, else steps aside, away from the blocker and never into the wall."""
        p = poses[..., :2]
        d = target - p
        half = 0.5 * self.step_m
        close = np.max(np.abs(d), axis=-1) < half
        settled = mask & (close | ~ok)  # robots that will not move out of the way
        others = settled[:, None, :] & ~np.eye(mask.shape[1], dtype=bool)
        rel = p[:, None, :, :] - p[:, :, None, :]  # [b, i, j] = p_j - p_i
        ahead = rel @ ACTIONS[1:].T  # (B, N, N, 4) along each move's direction
        side = rel @ np.abs(ACTIONS[1:, ::-1]).T  # across it: the other axis, in that axis's sign
        near, wide = self.pass_clear_m
        blocks = others[..., None] & (ahead > 0) & (ahead < near) & (np.abs(side) < wide)
        free = ~blocks.any(axis=2)  # (B, N, 4) per move 1..4
        gain = d @ ACTIONS[1:].T  # (B, N, 4) how much nearer each move brings the target, m
        along_x = np.abs(d[..., 0]) >= np.abs(d[..., 1])
        main = np.where(along_x, np.where(d[..., 0] > 0, 1, 2), np.where(d[..., 1] > 0, 3, 4))
        off = np.where(along_x, d[..., 1], d[..., 0])  # the target's offset across the main move
        other = np.where(along_x, np.where(off > 0, 3, 4), np.where(off > 0, 1, 2))
        # aside: away from the main move's nearest blocker (to the target's side when level with it)
        first = np.argmin(np.where(blocks, ahead, np.inf), axis=2)  # (B, N, 4)
        level = np.take_along_axis(
            np.take_along_axis(side, first[:, :, None, :], 2)[:, :, 0, :], (main - 1)[..., None], -1
        )
        away = np.where(np.abs(level[..., 0]) > 0.01, level[..., 0] < 0, off > 0)  # True: + on the other axis
        across = np.where(along_x, p[..., 1], p[..., 0])
        limit = np.where(along_x, WAYPOINT_LIMITS[3], WAYPOINT_LIMITS[1])
        away = np.where(np.abs(across) + self.step_m > limit, across < 0, away)  # not into the wall
        aside = np.where(along_x, np.where(away, 3, 4), np.where(away, 1, 2))
        facing = np.argmax(np.stack([np.cos(poses[..., 2]), np.sin(poses[..., 2])], -1) @ ACTIONS[1:].T, -1) + 1

        def pick(table, a):
            return np.take_along_axis(table, (a - 1)[..., None], -1)[..., 0]

        main_blocked = ~pick(free, main)
        keep = pick(free, facing) & ((pick(gain, facing) >= half) | (main_blocked & (facing == aside)))
        act = np.where(
            keep,
            facing,
            np.where(~main_blocked, main, np.where((np.abs(off) >= half) & pick(free, other), other, aside)),
        )
        return np.where(mask & ok & ~close, act, 0)

    def scripted_actions(self, state, poses, type_ids, caps, mask) -> np.ndarray:
        """The scripted reference (module docstring): the plan believing ``caps``, the radii given
        (the type_only rung passes its types' means here); never the state's."""
        target, ok = self._plan(state, caps[..., 0], mask)
        return self.drive(state, poses, caps, mask, target, ok)

    def blind_scripted_actions(self, state, poses, type_ids, caps, mask) -> np.ndarray:
        """The same plan without types or radii: every robot believed able until it measures that it
        is not."""
        target, ok = self._plan(state, None, mask)
        return self.drive(state, poses, caps, mask, target, ok)

    # -- coordination, diagnostics, drawing and export -----------------------------------------------
    coordination_name = "clusters open, able robot idle"
    coordination_doc = (
        "share of the team's clusters no robot covers while a robot able to cover it (radius − 0.06 m "
        ">= need) stands still covering none; lower is better"
    )

    def coordination(self, state, poses, type_ids, caps, mask) -> np.ndarray:
        """(B,) the share of clusters open while an able robot stands idle (module docstring), of the
        true radii, after a step's update."""
        idle = state["still"] & ~self._whole(self._inside(state, poses, caps, mask)).any(-1)  # (B, N)
        able = state["need"][:, None, :] <= caps[..., 0:1] - self.settle_m  # (B, N, C)
        waiting = self._open(state) & (able & idle[..., None]).any(axis=1)
        return waiting.sum(-1) / np.maximum(state["clusters"], 1)

    end_count_names = ("unwatched_end", "open_clusters_end")

    def end_counts(self, state: dict) -> dict[str, np.ndarray]:
        return {
            "unwatched_end": (state["active"] & ~state["watched"]).sum(1).astype(float),
            "open_clusters_end": self._open(state).sum(1).astype(float),
        }

    type_colors: ClassVar[dict] = {"wide": (66, 133, 244), "narrow": (244, 180, 0)}
    counters_name = "targets"

    def areas(self, state: dict | None = None, b: int = 0) -> tuple[Area, ...]:
        """The spawn and cluster areas and, with a state, env ``b``'s clusters: a circle of its need
        around each centre."""
        out = [
            Area("spawn", "box", self.spawn_box, (160, 160, 160), "robot spawn"),
            Area("cluster_area", "box", self.cluster_box, (120, 120, 200), "target clusters"),
        ]
        if state is not None:
            for c in range(int(state["clusters"][b])):
                (x, y), need = state["centres"][b, c], float(state["need"][b, c])
                out.append(Area(f"need_{c}", "circle", (x, y, need), (200, 200, 230), f"need {need:.2f} m"))
        return tuple(out)

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
        return {
            "watched": float(state["watched"][b].sum()),
            "covered": float(state["covered"][b].sum()),
            "best": float(state["best"][b]),
        }

    def status_text(self, state: dict, b: int, counters: dict[str, float]) -> str:
        k, n = int(state["active"][b].sum()), int(state["clusters"][b])
        return (
            f"targets watched {int(counters['watched'])}/{k}, clusters covered {int(counters['covered'])}/{n}, "
            f"best {int(counters['best'])}/{n}"
        )

    def layout(self, state: dict, b: int) -> dict[str, list]:
        n = int(state["clusters"][b])
        return {
            "targets": state["targets"][b][state["active"][b]].tolist(),
            "centres": state["centres"][b, :n].tolist(),
            "need": state["need"][b, :n].tolist(),
        }

    def set_starts(self, state: dict, b: int, starts: np.ndarray) -> None:
        n = starts.shape[0]
        state["plan_from"][b] = 0.0
        state["plan_from"][b, :n] = np.asarray(starts, dtype=float)[:, :2]
        state["last_xy"][b] = state["plan_from"][b]
        state["still"][b] = False

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
        state["covered"][b] = False
        state["best"][b] = 0.0
        state["can_cover"][b] = 0.0
        state["fell_short"][b] = False


SENSORS = SensorNetwork
