"""Heterogeneous Sensor Network v2 (issue 64): a cluster covered only by one robot seeing all of it,
needs drawn against the team's own radii so that the type does not decide who covers what, what the
robots measure and the planners re-plan on, radii read only through ``caps``, the drive around
settled teammates, the coordination metric, the observation layout of the spec sheet, determinism,
the reference ladder on design teams and the export layout."""

import re

import numpy as np
import pytest

import comat.tasks.sensors as sensors_module
from comat.envs import make_env, make_vec_env
from comat.envs.heuristics import reference_policy, type_mean_capabilities
from comat.tasks.sensors import SensorNetwork
from comat.team import generate_coalitions

DESIGN_SEED, EPISODE_SEED = 1, 2_000_003
"""The design coalitions and episode seed (the held-out ones are the lead's)."""


def _layout(task, centres, needs, starts):
    """A state (1 env) with clusters of three targets at ``needs`` (m) around ``centres``, targets
    at 0°, 120° and 240°, robots starting at ``starts`` (n, 2)."""
    angles = np.deg2rad([0.0, 120.0, 240.0])
    targets = [[cx + r * np.cos(a), cy + r * np.sin(a)] for (cx, cy), r in zip(centres, needs) for a in angles]
    state = task.new_state(1, len(starts))
    task.set_layout(state, 0, {"targets": targets, "centres": centres, "need": needs})
    task.set_starts(state, 0, np.column_stack([starts, np.zeros(len(starts))]))
    return state


def _poses(*xy):
    return np.array([[[x, y, 0.0] for x, y in xy]])


def test_a_cluster_is_covered_only_when_one_robot_sees_all_its_targets():
    task = SensorNetwork()
    state = _layout(task, [[0.0, 0.0], [1.0, 0.0]], [0.2, 0.1], [[-1.0, 0.0], [-1.0, 0.5]])
    caps, mask, types = np.array([[[0.3], [0.2]]]), np.ones((1, 2), bool), np.array([[0, 1]])
    one = _poses((0.0, 0.0), (-1.0, 0.5))
    assert task.update(state, one, types, caps, mask)["coverage"][0] == 1.0
    assert task.update(state, one, types, caps, mask)["coverage"][0] == 0.0  # no new best, no reward
    # cluster 0 split between the two robots: each sees part of it, neither covers it
    split = _poses((0.28, 0.0), (-0.18, 0.0))
    task.update(state, split, types, caps, mask)
    assert state["watched"][0, :3].all() and not state["covered"][0, 0]
    assert task.progress(state)[0] == pytest.approx(0.5) and not task.done(state)[0]
    both = _poses((0.0, 0.0), (1.05, 0.0))
    assert task.update(state, both, types, caps, mask)["coverage"][0] == 1.0 and task.done(state)[0]


@pytest.mark.parametrize("split", ["train", "capability", "scale"])
def test_needs_are_drawn_against_the_teams_own_radii(split):
    env = make_vec_env("sensors_v2", 8, coalitions=split, tier="unicycle", seed=3)
    env.reset()
    core, task = env.core, env.core.task
    for b in range(8):
        n = core.teams[b].size
        need, reach = np.sort(core.state["need"][b, :n]), np.sort(core.caps[b, :n, 0] - task.settle_m)
        # one cluster per robot, each sized by one robot: sorted, they pair up, each coverable by its own
        assert (need <= reach + 1e-9).all()
        assert np.median(need / reach) >= task.need_fraction[0] - 1e-9  # only the arena's edge clips


@pytest.mark.parametrize(("split", "least"), [("train", 0.1), ("capability", 0.2)])
def test_the_type_does_not_decide_who_covers_what(split, least):
    """Share of robot–cluster pairs where the robot's type's mean radius misjudges whether it covers
    the cluster (v1: 0 % on every set but U_cap's 0.55 %)."""
    teams = generate_coalitions("sensors", split, 20, seed=DESIGN_SEED)
    env = make_vec_env("sensors_v2", 20, coalitions=teams, tier="unicycle", seed=EPISODE_SEED)
    env.reset(teams=teams)
    core, task = env.core, env.core.task
    means = type_mean_capabilities("sensors", split)[:, 0]
    wrong = []
    for b in range(20):
        n = core.teams[b].size
        need = core.state["need"][b, :n][None]
        able = core.caps[b, :n, 0][:, None] - task.settle_m >= need
        believed = means[core.type_ids[b, :n]][:, None] - task.settle_m >= need
        wrong.append((able != believed).mean())
    assert np.mean(wrong) >= least


def test_a_robot_measures_only_when_stopped_at_a_centre_and_the_team_replans_from_there():
    task = SensorNetwork()
    state = _layout(task, [[0.0, 0.0], [1.0, 0.0]], [0.3, 0.1], [[-1.0, 0.0], [-1.0, 0.5]])
    caps, mask, types = np.array([[[0.2], [0.45]]]), np.ones((1, 2), bool), np.array([[1, 0]])
    passing = _poses((0.01, 0.0), (1.0, 0.0))  # robot 0 arrives: it moved this step
    task.update(state, passing, types, caps, mask)
    assert not state["fell_short"].any() and state["can_cover"][0].tolist() == [0.0, 0.0]
    task.update(state, passing, types, caps, mask)  # both stopped: now they measure
    assert state["fell_short"][0, :, 0].tolist() == [True, False] and not state["fell_short"][0, :, 1].any()
    assert state["can_cover"][0, 1] == pytest.approx(0.1)
    assert np.allclose(state["plan_from"][0], passing[0, :, :2])  # the plans start again from here
    # the informed plan (it believes robot 0 wide) and the blind one both swap the robots now
    for radius in (np.array([[0.5, 0.45]]), None):
        target, has = task._plan(state, radius, mask)
        assert has.all() and target[0].tolist() == [[1.0, 0.0], [0.0, 0.0]]


def test_falling_short_at_one_need_rules_out_larger_ones_for_the_informed_planner_only():
    task = SensorNetwork()
    state = _layout(task, [[0.0, 0.0], [0.0, 0.7], [1.0, 0.0]], [0.2, 0.3, 0.1], [[-0.2, 0.7], [-1.0, 0.0], [1.0, 0.3]])
    mask = np.ones((1, 3), bool)
    state["fell_short"][0, 0, 0] = True  # robot 0 fell short at need 0.2
    believed = np.array([[0.5, 0.5, 0.5]])
    informed, _ = task._plan(state, believed, mask)
    blind, _ = task._plan(state, None, mask)
    assert informed[0, 0].tolist() == [1.0, 0.0]  # not the 0.3 cluster beside it: 0.3 > 0.2
    assert blind[0, 0].tolist() == [0.0, 0.7]  # blind: only that pair is ruled out


def test_the_planner_reads_radii_only_through_caps():
    """Two clusters, the big one nearer the narrow robot: the scripted plan sends the wide one there;
    swap the radii it is given and it swaps the robots; the blind plan (distance alone) reads
    neither radii nor types."""
    task = SensorNetwork()
    starts = [[0.0, 0.3], [0.0, 0.5]]
    state = _layout(task, [[0.0, 0.0], [0.0, 0.8]], [0.35, 0.1], starts)
    poses, mask = _poses(*starts), np.ones((1, 2), bool)
    caps, types = np.array([[[0.2], [0.5]]]), np.array([[1, 0]])
    aware = task.scripted_actions(state, poses, types, caps, mask)
    swapped = task.scripted_actions(state, poses, types, caps[:, ::-1], mask)
    assert aware[0].tolist() == [3, 4] and swapped[0].tolist() == [4, 3]  # 3: +y, 4: -y
    rng = np.random.default_rng(0)
    for _ in range(5):
        noise, kinds = rng.uniform(0.08, 0.65, (1, 2, 1)), rng.integers(0, 2, (1, 2))
        assert task.blind_scripted_actions(state, poses, kinds, noise, mask)[0].tolist() == [4, 3]


def test_the_drive_goes_around_a_settled_teammate():
    task = SensorNetwork()
    state = task.new_state(1, 2)
    poses, mask, caps = _poses((0.0, 0.0), (0.2, 0.02)), np.ones((1, 2), bool), np.full((1, 2, 1), 0.3)
    target = np.array([[[1.0, 0.0], [0.2, 0.02]]])  # robot 1 sits at its target
    act = task.drive(state, poses, caps, mask, target, np.ones((1, 2), bool))
    assert act[0].tolist() == [4, 0]  # aside, away from the teammate (it is a little above)
    alone = task.drive(state, poses, caps, mask, target, np.array([[True, False]]) & mask)
    assert alone[0, 0] == 4  # a robot without a target does not move out of the way either
    clear = task.drive(state, _poses((0.0, 0.0), (0.2, 0.4)), caps, mask, target, np.ones((1, 2), bool))
    assert clear[0, 0] == 1


def test_coordination_counts_clusters_open_while_an_able_robot_idles():
    task = SensorNetwork()
    state = _layout(task, [[0.0, 0.0], [1.0, 0.0]], [0.3, 0.1], [[-1.0, 0.0], [-1.0, 0.5]])
    caps, mask, types = np.array([[[0.45], [0.2]]]), np.ones((1, 2), bool), np.array([[0, 1]])

    def coordination(*xy):
        poses = _poses(*xy)
        task.update(state, poses, types, caps, mask)
        return float(task.coordination(state, poses, types, caps, mask)[0])

    assert coordination((-0.5, 0.0), (-0.5, 0.5)) == 0.0  # both on their way: nobody idles
    assert coordination((-0.5, 0.0), (-0.5, 0.5)) == 1.0  # both idle: the wide one could cover either
    assert coordination((0.0, 0.0), (-0.5, 0.5)) == 0.5  # cluster 0 covered; the narrow one idles, able
    caps[0, 1, 0] = 0.15  # now the narrow robot cannot cover cluster 1 (0.15 - 0.06 < 0.1)
    assert coordination((0.0, 0.0), (-0.5, 0.5)) == 0.0  # and the wide one is busy covering: no waste


def test_the_observation_layout_is_the_spec_sheets():
    task = SensorNetwork()
    doc = sensors_module.__doc__
    assert f"Box({task.obs_size()},)" in doc and "Box(3K + K/3 + S·15,)" in doc
    rows = re.findall(r"^\| (\d+)(?:–(\d+))? \|", doc, re.MULTILINE)
    assert int(rows[-1][1] or rows[-1][0]) == task.obs_size() - 1 == 14
    state = _layout(task, [[0.0, 0.0], [1.0, 0.0], [0.0, 0.8]], [0.3, 0.1, 0.2], [[-1.0, 0.0], [-1.0, 0.5], [1.0, 0.8]])
    poses = _poses((-0.5, 0.0), (0.98, 0.0), (1.0, 0.8))
    caps, mask, types = np.array([[[0.3], [0.2], [0.3]]]), np.ones((1, 3), bool), np.array([[0, 1, 0]])
    task.update(state, poses, types, caps, mask)
    obs = task.observe(state, poses, types, caps, mask)[0]
    assert obs.shape == (3, 15) and np.allclose(obs[:, 6], [0.6, 0.4, 0.6])
    assert np.allclose(obs[0, 7:10], [0.5, 0.0, 0.6])  # nearest open cluster (0, 0), need 0.3
    assert np.allclose(obs[0, 10:12], [0.5, 0.8])  # cannot cover it (0.3 - 0.06 < 0.3): the 0.2 one
    assert np.allclose(obs[1, 12:15], [1.0, 1 / 3, 1 / 3])  # robot 1 covers cluster 1; 1 of 3 covered
    assert obs[2, 12] < 1.0  # robot 2 sees no cluster whole


def test_same_seed_same_episode():
    def run():
        env = make_vec_env("sensors_v2", 3, coalitions="test", tier="unicycle", seed=11)
        obs, _ = env.reset(seed=11)
        act = reference_policy("type_only", env.core, 0, "test")
        out = [obs]
        for _ in range(12):
            obs, reward, *_ = env.step(act(None, None, None))
            out += [obs, reward]
        return out

    for a, b in zip(run(), run()):
        np.testing.assert_array_equal(a, b)


def _ladder(split: str, rungs: tuple[str, ...]) -> dict[str, float]:
    """Mean final progress of each rung over one episode of each of the 20 design coalitions."""
    teams = generate_coalitions("sensors", split, 20, seed=DESIGN_SEED)
    out = {}
    for rung in rungs:
        env = make_vec_env("sensors_v2", 20, coalitions=teams, tier="unicycle", seed=EPISODE_SEED)
        env.reset(teams=teams)
        act = reference_policy(rung, env.core, 0, split)
        for _ in range(env.core.task.horizon):
            env.core.step(act(None, None, None))
        out[rung] = float(env.core.task.progress(env.core.state).mean())
    return out


def test_the_ladder_on_design_teams():
    """Design data (measured: U_train 100 / 92 / 84 %, U_cap 100 / 77 %)."""
    train = _ladder("train", ("heuristic", "type_only", "blind"))
    assert train["heuristic"] >= 0.97 and train["heuristic"] - train["type_only"] >= 0.03, train
    assert train["type_only"] >= train["blind"], train
    cap = _ladder("capability", ("heuristic", "type_only"))
    assert cap["heuristic"] - cap["type_only"] >= 0.1, cap


def test_layout_round_trips_and_the_task_draws_itself():
    env = make_env("sensors_v2", tier="unicycle", render_mode="rgb_array")
    env.reset(seed=4)
    core = env.core
    fresh = core.task.new_state(1, core.N)
    core.task.set_layout(fresh, 0, core.task.layout(core.state, 0))
    for key in ("targets", "active", "centres", "need", "clusters"):
        np.testing.assert_array_equal(fresh[key], core.state[key])
    n = int(core.state["clusters"][0])
    assert sum(a.name.startswith("need_") for a in core.task.areas(core.state, 0)) == n
    assert env.render().shape == (448, 640, 3)
