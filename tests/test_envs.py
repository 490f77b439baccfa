"""The PettingZoo environments: API, determinism, rewards, graphs, bad input."""

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test

import comat
from comat.envs import PcpEnv, make_env
from comat.tasks import env_id, task_names
from comat.tasks.hmt import MaterialTransport
from comat.team import RobotSpec, TeamSpec, generate_coalitions, random_team

TASKS = list(task_names())


def _pick(task, split):
    teams = generate_coalitions(task, split)
    sizes = [t.size for t in teams]
    mixed = max(teams, key=lambda t: min(np.bincount(t.type_ids(), minlength=2)))
    return {"smallest": teams[int(np.argmin(sizes))], "largest": teams[int(np.argmax(sizes))], "mixed": mixed}


CASES = [
    (task, split, kind) for task in TASKS for split in ("train", "test") for kind in ("smallest", "largest", "mixed")
]


@pytest.mark.parametrize("task,split,kind", CASES)
def test_parallel_api(task, split, kind):
    team = _pick(task, split)[kind]
    env = make_env(env_id(task), team=team, tier="unicycle", ticks_per_step=6)
    parallel_api_test(env, num_cycles=90)


@pytest.mark.parametrize("task", TASKS)
@pytest.mark.parametrize("n", [2, 20])
def test_parallel_api_two_and_twenty_robots(task, n):
    team = random_team(np.random.default_rng(3), task, "train", n)
    env = make_env(env_id(task), team=team, tier="unicycle", ticks_per_step=6)
    parallel_api_test(env, num_cycles=90)
    assert env.graph()["edge_attr"].shape == (n, n, 5)


def _episode(env, seed, action_seed, steps=None):
    obs, infos = env.reset(seed=seed)
    trace = [(obs, None, None, None, infos)]
    rng = np.random.default_rng(action_seed)
    n = 0
    while env.agents and (steps is None or n < steps):
        actions = {a: int(rng.integers(5)) for a in env.agents}
        trace.append(env.step(actions))
        n += 1
    return trace


@pytest.mark.parametrize("task", TASKS)
def test_full_episode_determinism(task):
    env = make_env(env_id(task), tier="unicycle")
    a = _episode(env, seed=7, action_seed=1)
    b = _episode(make_env(env_id(task), tier="unicycle"), seed=7, action_seed=1)
    assert len(a) == len(b) > 0.75 * env.task.horizon  # a whole episode, to the horizon
    for step_a, step_b in zip(a, b):
        for part_a, part_b in zip(step_a, step_b):
            if part_a is None:
                continue
            assert part_a.keys() == part_b.keys()
            for k in part_a:
                if isinstance(part_a[k], dict):
                    assert part_a[k] == part_b[k]
                else:
                    np.testing.assert_array_equal(part_a[k], part_b[k])


@pytest.mark.parametrize("task", TASKS)
def test_different_seeds_give_different_starts_and_teams(task):
    env = make_env(env_id(task), tier="unicycle")
    starts, teams = [], []
    for seed in range(6):
        obs, _ = env.reset(seed=seed)
        starts.append(obs["robot_0"][:4])
        teams.append(env.team)
    assert len({tuple(s) for s in starts}) == 6
    assert len({t for t in teams}) > 1


@pytest.mark.parametrize("task", TASKS)
def test_reward_is_exactly_the_sum_of_its_terms(task):
    env = make_env(env_id(task), tier="unicycle")
    trace = _episode(env, seed=3, action_seed=2, steps=40)
    for _, rewards, _, _, infos in trace[1:]:
        for agent, reward in rewards.items():
            terms = [v for k, v in infos[agent].items() if k.startswith("reward/")]
            assert len(terms) == len(env.task.reward_terms)
            assert reward == sum(terms)  # bit for bit: the reward is built as this sum


def test_episode_metrics_at_the_end():
    env = make_env("pcp_v0", tier="unicycle", ticks_per_step=4)
    trace = _episode(env, seed=0, action_seed=0)
    last = trace[-1][4]["robot_0"]
    for name in comat.envs.core.EPISODE_METRICS:
        assert f"episode/{name}" in last
    assert last["episode/steps"] == 80 and last["episode/collisions"] == 0
    assert "episode/return" not in trace[-2][4]["robot_0"]


def test_reset_with_an_explicit_team_and_observation_layout():
    team = {
        "robots": [{"type": "capture", "capabilities": [0.0, 0.4]}, {"type": "sensing", "capabilities": [0.5, 0.0]}]
    }
    env = make_env("pcp_v0", tier="unicycle")
    obs, _ = env.reset(seed=0, options={"team": team})
    assert env.agents == ["robot_0", "robot_1"]
    o = obs["robot_0"]
    assert o.shape == (13,)
    np.testing.assert_allclose(o[4:6], [0, 1])  # capture one-hot
    np.testing.assert_allclose(o[6:8], [0.0, 0.8])  # capabilities / 0.5
    assert o[8] == 0  # capture robots never see prey
    assert env.state().shape == env.state_space.shape


@pytest.mark.parametrize("task,split,slots", [("pcp", "test", 8), ("hmt", "test", 8), ("pcp", "scale", 20)])
def test_global_state_is_order_one_for_the_largest_teams(task, split, slots):
    # Centralized critics and QMIX's mixer take the state as it is: no entry may carry raw
    # amounts (HMT's material reached ~155 before it was scaled, and MAPPO's critic diverged);
    # PCP's parked prey slots (x = 2.6 m) included.
    env = comat.make_vec_env(
        env_id(task), 8, seed=0, tier="unicycle", max_robots=slots, state_robots=slots, coalitions=split
    )
    _, info = env.reset()
    rng = np.random.default_rng(0)
    for _ in range(5):
        state = env.state()
        assert np.abs(state).max() <= 3.0, np.abs(state).max(axis=0)
        info = env.step(np.where(info["agent_mask"], rng.integers(0, 5, info["agent_mask"].shape), 0))[-1]


def test_graph_inputs_any_size():
    team = random_team(np.random.default_rng(0), "pcp", "train", 12)
    env = make_env("pcp_v0", team=team, tier="unicycle")
    env.reset(seed=0)
    g = env.graph()
    assert g["nodes"].shape == (12, 13) and g["edge_attr"].shape == (12, 12, 5)
    assert not g["edge_mask"].diagonal().any() and g["edge_mask"].sum() == 12 * 11
    i, j = 0, 1
    p = env.core.poses()[0]
    d = p[j, :2] - p[i, :2]
    assert g["edge_attr"][i, j, 2] == pytest.approx(np.hypot(*d))
    # Edge types are ordered type pairs: type_i * 2 + type_j.
    t = team.type_ids()
    assert g["edge_type"][i, j] == t[i] * 2 + t[j]


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"colour": "red"}, r"unknown option\(s\) \['colour'\] for pcp_v0; valid options:"),
        ({"tier": "legs"}, r"SimConfig.tier must be one of"),
        (
            {"coalitions": "validation"},
            (
                r"coalitions must be one of 'train', 'val', 'test', 'scale', 'size', 'capability', "
                r"a YAML path or a non-empty list"
            ),
        ),
        ({"team": {"robots": []}}, r"needs at least one robot of each type"),
        ({"team": {"robots": [{"type": "sensing", "capabilities": [0.4, 0.0]}]}}, r"missing \['capture'\]"),
        (
            {
                "team": {
                    "robots": [
                        {"type": "sensing", "capabilities": [2.0, 0.0]},
                        {"type": "capture", "capabilities": [0.0, 0.3]},
                    ]
                }
            },
            r"sensing_radius_m must be in \[0.0, 1.0\]",
        ),
        ({"n_prey": 0}, r"n_prey must be a positive integer \(that many prey for every team\) or None .*, got 0"),
        ({"n_prey": True}, r"n_prey must be a positive integer .*, got True"),
    ],
)
def test_bad_constructor_options(kwargs, match):
    with pytest.raises(ValueError, match=match):
        make_env("pcp_v0", **kwargs)


def test_unknown_env_id():
    with pytest.raises(ValueError, match=r"env_id must be one of \(.*'hmt_v0'.*'pcp_v0'.*\), got 'soccer_v0'"):
        make_env("soccer_v0")


def test_large_teams_widen_the_spawn_area_until_the_arena_is_full():
    task = MaterialTransport()
    poses = task.spawn(np.random.default_rng(0), 30)  # 18 fit the usual area; it grows to the right
    assert poses[:, 0].max() > task.spawn_box[1]
    d = np.hypot(*(poses[:, None, :2] - poses[None, :, :2]).transpose(2, 0, 1)) + np.eye(30)
    assert d.min() >= task.spawn_spacing - 1e-9
    team = random_team(np.random.default_rng(0), "hmt", "train", 61)
    with pytest.raises(ValueError, match=r"hmt takes teams of at most 60 robots, got 61: robots start 0.3 m apart"):
        make_env("hmt_v0", team=team, tier="unicycle")  # said when the env is made, not at its first reset


def test_the_largest_team_each_task_takes_is_said_as_a_limit():
    """PCP's prey grow with the team (K(N) = round(1.2 N) above 8 robots): 37 robots take 44 prey of
    the 45 that fit the prey area, 38 would take 46. The message says the limit, why, and the way out
    (n_prey), and n_prey lifts the limit to the spawn area's."""
    from comat.tasks.hmt import MaterialTransport
    from comat.tasks.pcp import PredatorCapturePrey

    assert PredatorCapturePrey().max_team_size() == 37 and MaterialTransport().max_team_size() == 60
    assert PredatorCapturePrey().prey_capacity() == 45 and PredatorCapturePrey(n_prey=6).max_team_size() == 60
    make_env("pcp_v0", team=random_team(np.random.default_rng(0), "pcp", "train", 37), tier="unicycle").reset(seed=0)
    team = random_team(np.random.default_rng(0), "pcp", "train", 40)
    with pytest.raises(
        ValueError,
        match=r"pcp takes teams of at most 37 robots, got 40: prey grow with the team, "
        r"K\(N\) = round\(1.2·N\) above 8 robots, so 48 prey for 40, and at most 45 fit .* n_prey=K",
    ):
        make_env("pcp_v0", team=team, tier="unicycle")
    env = make_env("pcp_v0", tier="unicycle", max_robots=40)  # a larger team passed to a reset: the same
    with pytest.raises(ValueError, match="pcp takes teams of at most 37 robots, got 40"):
        env.reset(seed=0, options={"team": team})
    with pytest.raises(ValueError, match="n_prey must be at most 45"):
        PredatorCapturePrey(n_prey=46)


def test_bad_actions():
    env = make_env("pcp_v0", tier="unicycle")
    env.reset(seed=0)
    good = {a: 0 for a in env.agents}
    with pytest.raises(ValueError, match=r"action of robot_0 must be an integer in \[0, 5\) .* got 7"):
        env.step({**good, "robot_0": 7})
    with pytest.raises(ValueError, match=r"missing \['robot_1'\]"):
        env.step({k: v for k, v in good.items() if k != "robot_1"})
    with pytest.raises(ValueError, match=r"not possible agents \['robot_9'\]"):
        env.step({**good, "robot_9": 0})
    with pytest.raises(ValueError, match=r"larger than this environment's 2 agents"):
        pair = TeamSpec("pcp", (RobotSpec("sensing", (0.4, 0)), RobotSpec("capture", (0, 0.4))))
        small = PcpEnv(coalitions=[pair], tier="unicycle")
        small.reset(seed=0, options={"team": random_team(np.random.default_rng(0), "pcp", "train", 5)})


def _pixel(xy):
    """(row, col) of arena point xy in a frame (comat.envs.render.arena_axes: the arena's axes and view)."""
    from comat.envs.render import FRAME_SIZE, arena_axes

    h, w = FRAME_SIZE
    (left, bottom, width, height), (x0, x1, y0, y1) = arena_axes()
    col = (left + (xy[0] - x0) / (x1 - x0) * width) * w
    row = (1 - bottom - (xy[1] - y0) / (y1 - y0) * height) * h
    return int(row), int(col)


@pytest.mark.parametrize("task", TASKS)
def test_render_rgb_array_draws_the_team_and_leaves_the_episode_unchanged(task):
    from comat.envs.render import FRAME_SIZE, TYPE_COLORS

    env = make_env(env_id(task), tier="unicycle", render_mode="rgb_array")
    assert env.metadata["render_modes"] == ["rgb_array"] and env.render_mode == "rgb_array"
    traced = _episode(env, seed=7, action_seed=1, steps=5)
    frame = env.render()
    assert frame.shape == (*FRAME_SIZE, 3) and frame.dtype == np.uint8
    # each robot is a disc of its type's colour (sampled behind its centre, off the heading line)
    for pose, robot in zip(env.core.poses()[0], env.team.robots):
        back = pose[:2] - 0.04 * np.array([np.cos(pose[2]), np.sin(pose[2])])
        assert np.abs(frame[_pixel(back)].astype(int) - TYPE_COLORS[robot.type]).max() < 40, robot.type
    # rendering observes only: the same episode without a render mode, bit for bit
    plain = _episode(make_env(env_id(task), tier="unicycle"), seed=7, action_seed=1, steps=5)
    for a, b in zip(traced, plain):
        np.testing.assert_array_equal(np.stack(list(a[0].values())), np.stack(list(b[0].values())))
    # the same episode draws the same frames; another step draws another
    again = make_env(env_id(task), tier="unicycle", render_mode="rgb_array")
    _episode(again, seed=7, action_seed=1, steps=5)
    np.testing.assert_array_equal(again.render(), frame)
    again.step({a: 1 for a in again.agents})
    assert (again.render() != frame).any()
    # a new episode starts a fresh drawing (trails of the new team only)
    again.reset(seed=8)
    assert again.render().shape == frame.shape


def test_render_without_a_mode_warns_and_bad_modes_are_refused():
    env = make_env("pcp_v0", tier="unicycle")
    env.reset(seed=0)
    with pytest.warns(UserWarning, match="render_mode"):
        assert env.render() is None
    with pytest.raises(ValueError, match=r"render_mode must be None or one of \['rgb_array'\], got 'human'"):
        make_env("pcp_v0", render_mode="human")
    with pytest.raises(RuntimeError, match="before begin"):
        make_env("pcp_v0", render_mode="rgb_array").render()
    with pytest.raises(ValueError, match=r"unknown option\(s\) \['render_mode'\]"):
        comat.make_vec_env("pcp_v0", 2, render_mode="rgb_array")
