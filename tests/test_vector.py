"""The vector env: padded arrays, autoreset, and equality with single environments."""

import numpy as np
import pytest

from comat.envs import make_env, make_vec_env
from comat.envs.heuristics import heuristic_actions, random_actions
from comat.measure.episodes import run_episodes
from comat.tasks import env_id
from comat.team import generate_coalitions


def test_padded_arrays_and_mask():
    env = make_vec_env("pcp_v0", 6, seed=1, tier="unicycle")
    obs, info = env.reset()
    mask = info["agent_mask"]
    assert obs.shape == (6, 7, 13) and mask.shape == (6, 7)
    sizes = mask.sum(1)
    assert len(set(sizes.tolist())) > 1  # teams of different sizes side by side
    assert np.all(obs[~mask] == 0) and np.all(np.abs(obs[mask]).sum(-1) > 0)
    assert env.state().shape[0] == 6
    g = env.graph()
    assert g["edge_attr"].shape == (6, 7, 7, 5)
    assert (g["edge_mask"].sum((1, 2)) == sizes * (sizes - 1)).all()


def test_vector_env_equals_single_envs():
    """B environments batched (one physics call, one QP per tick) = each run alone."""
    teams = generate_coalitions("pcp", "train")[:3]
    vec = make_vec_env("pcp_v0", 3, seed=5, tier="unicycle", coalitions=teams)
    obs, _info = vec.reset()
    singles = []
    for b in range(3):
        env = make_env("pcp_v0", tier="unicycle", coalitions=teams, max_robots=vec.max_robots)
        env._np_random = np.random.default_rng(np.random.SeedSequence(5).spawn(3)[b])
        o, _ = env.reset()
        singles.append(env)
        assert env.team == vec.teams()[b]
        assert list(o) == env.agents
        # looked up, the agents sitting the episode out read as zeros, the vector env's padded rows
        np.testing.assert_array_equal(np.stack([o[a] for a in env.possible_agents]), obs[b])
    rng = np.random.default_rng(0)
    for _ in range(15):
        actions = random_actions(rng, vec.agent_mask)
        obs, rewards, _term, _trunc, _ = vec.step(actions)
        for b, env in enumerate(singles):
            o, r, *_ = env.step({a: int(actions[b, i]) for i, a in enumerate(env.agents)})
            np.testing.assert_allclose(np.stack(list(o.values())), obs[b, : env.team.size], atol=1e-6)
            assert r["robot_0"] == pytest.approx(rewards[b])


def test_autoreset_same_step():
    env = make_vec_env("pcp_v0", 2, seed=0, tier="unicycle", ticks_per_step=2)
    env.reset()
    rng = np.random.default_rng(0)
    for _ in range(80):
        obs, _rewards, _term, trunc, info = env.step(random_actions(rng, env.agent_mask))
    assert trunc.all() and info["_episode"].all()
    assert (info["episode"]["steps"] == 80).all()
    assert "final_obs" in info and info["final_obs"].shape == obs.shape
    # the finished episode's record: progress after each of its 80 steps, per-robot counts, end counts
    assert info["episode_curve"].shape == (2, 80)
    np.testing.assert_array_equal(info["episode_curve"][:, -1], info["episode"]["progress"])
    assert set(info["episode_robots"]) == {"still_held", "still_idle", "sensed", "captured"}
    held_or_idle = info["episode_robots"]["still_held"] + info["episode_robots"]["still_idle"]
    assert held_or_idle.shape == (2, env.max_robots) and (held_or_idle <= 80).all() and held_or_idle.sum() > 0
    assert info["episode_end"]["sensed_not_captured"].shape == (2,)
    # The returned observation already belongs to the next episode, and so does the record.
    _obs2, *_ = env.step(random_actions(rng, env.agent_mask))
    assert (env.core.steps == 1).all()
    assert not env.core.record.curve[:, 1:].any() and (env.core.record.robots["still_held"] <= 1).all()


def test_bad_vector_actions():
    env = make_vec_env("hmt_v0", 2, seed=0, tier="unicycle")
    env.reset()
    with pytest.raises(ValueError, match=r"actions must have shape \(2, 7\) \(envs, robot slots\), got \(2, 3\)"):
        env.step(np.zeros((2, 3), int))
    bad = np.zeros((2, 7), int)
    bad[0, 0] = 9
    with pytest.raises(ValueError, match=r"actions must be integers in \[0, 5\) .* got \[9\]"):
        env.step(bad)
    with pytest.raises(ValueError, match="num_envs must be a positive integer, got 0"):
        make_vec_env("hmt_v0", 0)


def _heuristic_episodes(task: str, tier: str):
    teams = generate_coalitions(task, "train")
    env = make_vec_env(env_id(task), len(teams), seed=0, tier=tier, coalitions=teams)
    return run_episodes(env, lambda obs, mask, state: heuristic_actions(env.core), teams, seed=0)


def _check_heuristic(results):
    success = np.mean([r["finished"] for r in results])
    assert success >= 0.9, success
    assert sum(r["collisions"] + r["robotarium_collisions"] + r["boundary_exits"] for r in results) == 0


@pytest.mark.parametrize("task", ["pcp", "hmt"])
def test_heuristic_solves_training_coalitions_unicycle(task):
    _check_heuristic(_heuristic_episodes(task, "unicycle"))


@pytest.mark.slow
@pytest.mark.parametrize("task", ["pcp", "hmt"])
def test_heuristic_solves_training_coalitions_wheels(task):
    _check_heuristic(_heuristic_episodes(task, "wheels"))


def test_episodes_leave_no_osqp_problems_and_repeat_exactly():
    """``run_episodes`` ends by dropping the env's OSQP problems (an env waiting for its next
    batch holds none), and that changes nothing: the same batch again gives the same metrics."""
    teams = generate_coalitions("pcp", "train")[:4]
    env = make_vec_env("pcp_v0", 4, seed=0, tier="unicycle", coalitions=teams)
    env.reset(seed=0, teams=teams)
    for _ in range(3):
        env.step(random_actions(np.random.default_rng(0), env.agent_mask))
    assert env.core.safe._qp_cache, "the steps should have set up OSQP problems"
    first = run_episodes(env, lambda obs, mask, state: heuristic_actions(env.core), teams, seed=3)
    assert not env.core.safe._qp_cache and env.core.safe.filter._pattern_qp is None
    assert run_episodes(env, lambda obs, mask, state: heuristic_actions(env.core), teams, seed=3) == first
