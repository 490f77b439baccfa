"""Evaluation endpoints and per-robot diagnostics on scripted episodes with a known answer:
progress curve, its area and time to 90 %, idle and held robots, who delivered / sensed /
captured what, material left on board, episodes per coalition."""

import json

import numpy as np
import pytest

from comat.config import SimConfig
from comat.envs import make_vec_env
from comat.envs.core import TaskCore
from comat.envs.diagnostics import ROBOT_COUNTS, STILL_FRACTION
from comat.envs.heuristics import heuristic_actions
from comat.measure.episodes import run_episodes
from comat.measure.metrics import curve_endpoints
from comat.tasks import env_id
from comat.tasks.hmt import HMT
from comat.tasks.pcp import PCP
from comat.team import RobotSpec, TeamSpec, generate_coalitions


def _hand_endpoints(curve, horizon):
    """progress_auc, time_to_90, reached_90 written out step by step."""
    held = list(curve) + [curve[-1]] * (horizon - len(curve))
    first = next((t + 1 for t, p in enumerate(curve) if p >= 0.9), None)
    return sum(held) / horizon, float(first or horizon), float(first is not None)


def test_curve_endpoints_by_hand():
    assert curve_endpoints([0.0, 0.5, 0.95], 5) == pytest.approx(
        {"progress_auc": (0 + 0.5 + 0.95 * 3) / 5, "time_to_90": 3.0, "reached_90": 1.0}
    )
    never = curve_endpoints([0.1, 0.2], 4)  # censored at the horizon
    assert never == pytest.approx({"progress_auc": (0.1 + 0.2 * 3) / 4, "time_to_90": 4.0, "reached_90": 0.0})
    assert curve_endpoints([0.9], 1) == {"progress_auc": 0.9, "time_to_90": 1.0, "reached_90": 1.0}
    # finishing sooner scores higher
    assert curve_endpoints([0.5, 1.0], 10)["progress_auc"] > curve_endpoints([0.5, 0.5, 1.0], 10)["progress_auc"]
    with pytest.raises(ValueError, match=r"curve must be a 1-D sequence of 1 to horizon=2 values, got shape \(3,\)"):
        curve_endpoints([0.1, 0.2, 0.3], 2)
    with pytest.raises(ValueError, match="horizon must be a positive integer, got 0"):
        curve_endpoints([0.1], 0)


# -- per-robot counts on hand-placed robots ----------------------------------------------------------
def _core(task, team: TeamSpec, poses: np.ndarray) -> TaskCore:
    """One environment of ``task`` with ``team`` placed at ``poses`` (n, 3)."""
    core = TaskCore(task, 1, team.size, SimConfig(tier="unicycle"))
    task.spawn = lambda rng, n: poses.copy()  # this instance only: the robots start where the test says
    core.reset([0], [team], [np.random.default_rng(0)])
    return core


PCP_TEAM = TeamSpec(
    "pcp", (RobotSpec("sensing", (0.4, 0.0)), RobotSpec("capture", (0.0, 0.4)), RobotSpec("capture", (0.0, 0.4)))
)


def test_idle_robot_is_all_idle_and_robots_held_by_a_wall_and_each_other():
    """A robot that always stays: every step idle, none held. A robot at the arena's right edge
    that keeps choosing +x (its waypoint is clipped at the edge): every step held. Two robots
    pushing into the same corner: held most steps, counted exactly as their points moved."""
    wall = _core(PCP(), PCP_TEAM, np.array([[1.42, 0.0, 0.0], [-1.0, -0.6, 0.0], [-1.0, 0.6, 0.0]]))
    for _ in range(6):
        wall.step(np.array([[1, 0, 0]]))
    assert wall.record.robots["still_held"][0].tolist() == [6, 0, 0]
    assert wall.record.robots["still_idle"][0].tolist() == [0, 6, 6]
    # robot 0 drives +x into the top-right corner, robot 1 +y into it along the right edge
    corner = _core(PCP(), PCP_TEAM, np.array([[1.2, 0.8, 0.0], [1.42, 0.6, 0.0], [-1.2, 0.7, 0.0]]))
    held = np.zeros(3)
    for _ in range(10):
        points = corner.safe.points.copy()
        corner.step(np.array([[1, 3, 0]]))
        held[:2] += np.hypot(*(corner.safe.points - points).T)[:2] < STILL_FRACTION * 0.2
    r = corner.record.robots
    assert r["still_held"][0].tolist() == held.tolist() and (held[:2] >= 4).all()
    assert r["still_idle"][0].tolist() == [0, 0, 10]  # the robot that never moves: all idle ...
    assert r["still_held"][0, 2] == 0  # ... none held


def test_free_robots_are_never_held():
    """Robots far apart each driving across open ground move more than the threshold every step."""
    poses = np.array([[-1.3, -0.6, 0.0], [-1.3, 0.0, np.pi / 2], [-1.3, 0.6, np.pi]])  # facing +x, +y, -x
    core = _core(PCP(), PCP_TEAM, poses)
    points = core.safe.points.copy()
    for _ in range(5):
        core.step(np.array([[1, 1, 1]]))
    assert core.record.robots["still_held"][0].tolist() == [0, 0, 0]
    moved = np.hypot(*(core.safe.points - points).T)
    assert (moved > 0.3).all() and STILL_FRACTION * 0.2 < 0.3 / 5  # far above the threshold, turning included


def test_pcp_credit_goes_to_every_robot_in_range():
    """A prey inside the sensing robot's radius and both capture robots' radii is sensed and
    captured in one step: one sensing credit, a capture credit to each capture robot."""
    poses = np.array([[0.6, 0.0, 0.0], [0.9, 0.2, 0.0], [0.9, -0.2, 0.0]])
    core = _core(PCP(), PCP_TEAM, poses)
    K = core.state["prey"].shape[1]
    core.state["prey"][0] = [[1.35, -0.8 + 0.3 * k] for k in range(K)]  # out of everyone's reach ...
    core.state["prey"][0, 0] = [0.9, 0.0]  # ... but this one: 0.3 m from the sensing robot, 0.2 m from both others
    core.step(np.zeros((1, 3), int))
    r = core.record.robots
    assert r["sensed"][0].tolist() == [1, 0, 0] and r["captured"][0].tolist() == [0, 1, 1]
    assert core.record.end(core.state)["sensed_not_captured"][0] == 0
    core.step(np.zeros((1, 3), int))  # nothing new: no more credit
    assert r["sensed"][0].sum() == 1 and r["captured"][0].sum() == 2
    assert core.record.curve[0, :2] == pytest.approx([1 / K, 1 / K])


# -- whole episodes -----------------------------------------------------------------------------------
def _loaded_run(task: str, teams, policy, steps_cap=None):
    """Episodes of ``teams`` one per env; per env the episode row fields straight from ``info``,
    and (HMT) the material loaded, summed from the raw reward term."""
    env = make_vec_env(env_id(task), len(teams), seed=4, tier="unicycle", coalitions=teams)
    env.reset(seed=4, teams=teams)
    loaded = np.zeros(len(teams))
    stays = np.zeros(env.agent_mask.shape)
    out = [None] * len(teams)
    t = 0
    while any(o is None for o in out):
        actions = policy(env, t)
        stays += env.agent_mask & (actions == 0) & np.array([[o is None] for o in out])
        _, _, _, _, info = env.step(actions)
        t += 1
        if task == "hmt":
            loaded += np.where([o is None for o in out], info["reward/loaded"] / env.task.reward_weights["loaded"], 0)
        for b in np.flatnonzero(info.get("_episode", np.zeros(len(teams), bool))):
            if out[b] is None:
                steps = int(info["episode"]["steps"][b])
                out[b] = {
                    "steps": steps,
                    "progress": info["episode"]["progress"][b],
                    "loaded": loaded[b],
                    "stays": stays[b, : teams[b].size],
                    "curve": info["episode_curve"][b, :steps],
                    "robots": {k: v[b, : teams[b].size] for k, v in info["episode_robots"].items()},
                    "end": {k: v[b] for k, v in info["episode_end"].items()},
                }
    return out


def test_hmt_delivered_and_on_board_add_up():
    """Heuristic for 25 steps, then everyone stays: material is loaded but not all delivered.
    The robots' deliveries sum to the team's; what is on board at the end is loaded − delivered."""
    teams = generate_coalitions("hmt", "train")[:4]

    def policy(env, t):
        return heuristic_actions(env.core) if t < 25 else np.zeros_like(env.agent_mask, dtype=int)

    out = _loaded_run("hmt", teams, policy)
    for team, o in zip(teams, out):
        total = sum(HMT.zone_factors) * sum(r.capabilities[1] for r in team.robots)
        delivered = o["robots"]["delivered"].sum()
        assert delivered / total == pytest.approx(o["progress"], abs=1e-12)
        assert o["end"]["on_board_end"] == pytest.approx((o["loaded"] - delivered) / total, abs=1e-12)
        assert o["steps"] == HMT.horizon and o["curve"][-1] == o["progress"]
        assert o["robots"]["still_idle"].tolist() == o["stays"].tolist()  # every stay chosen, no other step
        assert (o["stays"] >= HMT.horizon - 25).all()
        assert (o["robots"]["carrying"] <= HMT.horizon).all()
    assert any(o["end"]["on_board_end"] > 0 for o in out) and all(o["progress"] > 0 for o in out)
    assert set(out[0]["robots"]) == set(ROBOT_COUNTS["hmt"])


def test_hmt_heuristic_rows_with_known_answers():
    teams = generate_coalitions("hmt", "train")[:4]
    env = make_vec_env("hmt_v0", 4, seed=0, tier="unicycle", coalitions=teams)
    rows = run_episodes(env, lambda obs, mask, state: heuristic_actions(env.core), teams, seed=0)
    for team, row in zip(teams, rows):
        total = sum(HMT.zone_factors) * sum(r.capabilities[1] for r in team.robots)
        assert len(row["progress_curve"]) == row["steps"] and row["progress_curve"][-1] == pytest.approx(
            row["progress"], abs=5e-5
        )
        assert sum(r["delivered"] for r in row["robots"]) / total == pytest.approx(row["progress"], abs=1e-6)
        assert row["finished"] == 1.0 and row["on_board_end"] == 0.0  # all delivered, nothing left on board
        auc, t90, reached = _hand_endpoints(row["progress_curve"], HMT.horizon)
        assert row["progress_auc"] == pytest.approx(auc, abs=1e-4)
        assert (row["time_to_90"], row["reached_90"]) == (t90, reached)
        assert [r["type"] for r in row["robots"]] == [r.type for r in team.robots]
        for t, agg in row["by_type"].items():
            mine = [r for r in row["robots"] if r["type"] == t]
            assert agg["robots"] == len(mine)
            assert agg["carrying"] == pytest.approx(np.mean([r["carrying"] for r in mine]), abs=1e-6)
            assert agg["delivered_sum"] == pytest.approx(sum(r["delivered"] for r in mine), abs=1e-5)
        assert (row["coalition"], row["episode_in_coalition"]) == (rows.index(row), 0)


def test_pcp_rows_deterministic_and_episodes_per_coalition():
    """Two coalitions, two episodes each: coalition i % 2, start i // 2; the same seed gives the
    same rows; sensed-not-captured counts real prey only."""
    teams = generate_coalitions("pcp", "train")[:2]

    def rows():
        env = make_vec_env("pcp_v0", 3, seed=0, tier="unicycle", coalitions=teams, ticks_per_step=6)
        rng = np.random.default_rng(1)
        return run_episodes(
            env, lambda o, m, s: np.where(m, rng.integers(0, 5, m.shape), 0), teams * 2, seed=9, n_coalitions=2
        )

    first = rows()
    assert rows() == first
    assert [(r["coalition"], r["episode_in_coalition"]) for r in first] == [(0, 0), (1, 0), (0, 1), (1, 1)]
    for row in first:
        assert 0 <= row["sensed_not_captured"] <= 6
        assert row["progress_curve"][-1] == pytest.approx(row["progress"], abs=5e-5)
        assert sum(r["captured"] for r in row["robots"]) >= round(row["progress"] * 6)
        assert sum(r["still_idle"] + r["still_held"] for r in row["robots"]) <= row["steps"] * row["team_size"]
        assert set(row["by_type"]) == {"sensing", "capture"}
        json.dumps(row)  # plain Python numbers only
    with pytest.raises(ValueError, match=r"teams must be 2 coalitions repeated 2 times"):
        run_episodes(
            make_vec_env("pcp_v0", 2, seed=0, tier="unicycle", coalitions=teams),
            lambda o, m, s: m * 0,
            [teams[0], teams[1], teams[1], teams[0]],
            seed=0,
            n_coalitions=2,
        )
    with pytest.raises(ValueError, match="n_coalitions must be a positive integer dividing the 4 teams, got 3"):
        run_episodes(None, None, teams * 2, seed=0, n_coalitions=3)
