"""The sharded vector env: the same episodes as one process, its own exact determinism."""

import numpy as np
import pytest

from comat.envs import ShardedVectorEnv, make_vec_env

OPTS = {"tier": "unicycle", "ticks_per_step": 6}


def _run(env, steps: int, seed: int = 0) -> dict:
    """Random actions for ``steps`` steps; everything the env returned, stacked."""
    rng = np.random.default_rng(seed)
    obs, info = env.reset()
    out = {"obs": [obs], "mask": [info["agent_mask"]], "rewards": [], "done": [], "final": [], "state": [env.state()]}
    for _ in range(steps):
        actions = np.where(info["agent_mask"], rng.integers(0, 5, info["agent_mask"].shape), 0)
        obs, rewards, terminated, truncated, info = env.step(actions)
        for key, value in (
            ("obs", obs),
            ("mask", info["agent_mask"]),
            ("rewards", rewards),
            ("done", terminated | truncated),
            ("state", env.state()),
        ):
            out[key].append(value)
        if "_episode" in info:
            out["final"].append((info["_episode"], info["episode"]["progress"], info["final_obs"], info["final_state"]))
            out.setdefault("record", []).append((info["episode_curve"], info["episode_robots"], info["episode_end"]))
    return out


@pytest.fixture(scope="module")
def runs():
    single = make_vec_env("pcp_v0", 5, seed=3, max_robots=8, **OPTS)
    with make_vec_env("pcp_v0", 5, workers=2, seed=3, max_robots=8, **OPTS) as sharded:
        assert isinstance(sharded, ShardedVectorEnv) and sharded.max_robots == single.max_robots
        assert sharded.state_size() == single.state_size()
        a = _run(sharded, 90)
        teams_sharded = sharded.teams()
        rngs = sharded.rng_state()
    b = _run(single, 90)
    return a, b, teams_sharded, single.teams(), rngs, single.rng_state()


def test_same_teams_and_episodes_as_one_process(runs):
    a, b, teams_a, teams_b, rngs_a, rngs_b = runs
    assert teams_a == teams_b and rngs_a == rngs_b  # same seed streams per environment
    for key in ("mask", "done"):
        np.testing.assert_array_equal(np.stack(a[key]), np.stack(b[key]))
    # Physics and task logic are per environment; only the QP tolerance differs.
    np.testing.assert_allclose(np.stack(a["obs"]), np.stack(b["obs"]), atol=2e-3)
    np.testing.assert_allclose(np.stack(a["state"]), np.stack(b["state"]), atol=2e-3)
    assert len(a["final"]) == len(b["final"]) > 0  # PCP's horizon is 80: episodes ended and reset
    for (ea, ca, oa, sa), (eb, cb, ob, sb) in zip(a["final"], b["final"]):
        np.testing.assert_array_equal(ea, eb)
        np.testing.assert_allclose(oa[ea], ob[eb], atol=2e-3)
        np.testing.assert_allclose(sa[ea], sb[eb], atol=2e-3)


def test_episode_record_crosses_the_worker_processes(runs):
    """The finished episodes' progress curves and per-robot counts come back from the workers in
    environment order, as one process records them."""
    a, b = runs[0], runs[1]
    assert len(a["record"]) == len(b["record"]) > 0
    for (ea, *_), (ca, ra, enda), (cb, rb, endb) in zip(a["final"], a["record"], b["record"]):
        assert ca.shape == cb.shape == (5, 80) and set(ra) == set(rb) and set(enda) == set(endb)
        np.testing.assert_array_equal(ca[ea], cb[ea])
        for name in ra:
            np.testing.assert_array_equal(ra[name][ea], rb[name][ea])
        for name in enda:
            np.testing.assert_array_equal(enda[name][ea], endb[name][ea])


def test_merged_record_of_a_worker_without_finished_episodes_is_zeros():
    from comat.envs.sharded import _merge_infos

    done_env = make_vec_env("pcp_v0", 2, seed=0, ticks_per_step=2, tier="unicycle", max_robots=8)
    busy_env = make_vec_env("pcp_v0", 3, seed=1, ticks_per_step=2, tier="unicycle", max_robots=8)
    team_mask = done_env.reset()[1]["agent_mask"]
    busy_env.reset()
    for _ in range(80):
        obs_a, *_, info_a = done_env.step(np.zeros((2, 8), int))
    obs_b, *_, info_b = busy_env.step(np.zeros((3, 8), int))
    assert "_episode" in info_a and "_episode" not in info_b
    merged = _merge_infos([info_b, info_a], [obs_b, obs_a], done_env.state_size())
    assert merged["episode_curve"].shape == (5, 80) and not merged["episode_curve"][:3].any()
    np.testing.assert_array_equal(merged["episode_curve"][3:], info_a["episode_curve"])
    for name, v in info_a["episode_robots"].items():
        assert merged["episode_robots"][name].shape == (5, 8) and not merged["episode_robots"][name][:3].any()
        np.testing.assert_array_equal(merged["episode_robots"][name][3:], v)
    np.testing.assert_array_equal(merged["episode_robots"]["still_idle"][3:], 80 * team_mask)  # all stayed
    np.testing.assert_array_equal(
        merged["episode_end"]["sensed_not_captured"][3:], info_a["episode_end"]["sensed_not_captured"]
    )


def test_sharded_is_deterministic():
    with (
        make_vec_env("pcp_v0", 4, workers=2, seed=7, **OPTS) as env1,
        make_vec_env("pcp_v0", 4, workers=2, seed=7, **OPTS) as env2,
    ):
        a, b = _run(env1, 12, seed=1), _run(env2, 12, seed=1)
    for key in ("obs", "rewards", "state"):
        np.testing.assert_array_equal(np.stack(a[key]), np.stack(b[key]))


def test_sharded_rng_state_round_trip_and_errors():
    with make_vec_env("pcp_v0", 3, workers=2, seed=1, **OPTS) as env:
        env.reset()
        saved = env.rng_state()
        teams = [env.reset()[0].shape, env.teams()]
        env.set_rng_state(saved)
        env.reset()
        assert env.teams() == teams[1]
        with pytest.raises(ValueError, match="actions must have shape"):
            env.step(np.zeros((2, 7), int))
        with pytest.raises(ValueError, match=r"integers in \[0, 5\)"):
            env.step(np.full((3, env.max_robots), 9))
        with pytest.raises(ValueError, match="3 generator states"):
            env.set_rng_state(saved[:2])
    with pytest.raises(RuntimeError, match="closed"):
        env.reset()
    with pytest.raises(ValueError, match="workers must be"):
        make_vec_env("pcp_v0", 2, workers=3, **OPTS)
    with pytest.raises(ValueError, match="unknown option"):
        make_vec_env("pcp_v0", 2, workers=2, colour="red")


def test_shard_by_shard_steps_equal_whole_steps():
    """step_send/step_recv, one worker at a time and overlapping, give what step() gives."""
    with (
        make_vec_env("pcp_v0", 5, workers=2, seed=5, **OPTS) as whole,
        make_vec_env("pcp_v0", 5, workers=2, seed=5, **OPTS) as parts,
    ):
        rng = np.random.default_rng(2)
        _, info = whole.reset()
        parts.reset()
        assert [(s.start, s.stop) for s in parts.slices] == [(0, 2), (2, 5)]
        for _ in range(4):
            actions = np.where(info["agent_mask"], rng.integers(0, 5, info["agent_mask"].shape), 0)
            obs, rewards, terminated, truncated, info = whole.step(actions)
            for i, sl in enumerate(parts.slices):  # both in flight before either is collected
                parts.step_send(i, actions[sl], with_state=i == 1)
            got = [parts.step_recv(i) for i in range(2)]
            assert len(got[0]) == 5 and len(got[1]) == 6
            np.testing.assert_array_equal(np.concatenate([g[0] for g in got]), obs)
            np.testing.assert_array_equal(np.concatenate([g[1] for g in got]), rewards)
            np.testing.assert_array_equal(np.concatenate([g[2] | g[3] for g in got]), terminated | truncated)
            np.testing.assert_array_equal(parts.agent_mask, info["agent_mask"])
            np.testing.assert_array_equal(got[1][5], whole.state()[2:])
        with pytest.raises(ValueError, match=r"actions of worker 1 must have shape \(3, "):
            parts.step_send(1, actions)


def test_evaluation_episodes_run_on_a_sharded_env():
    """``run_episodes`` (evaluation) works on a sharded env, whose workers drop their OSQP problems
    at its end, and gives the same episodes again."""
    from comat.envs.heuristics import random_actions
    from comat.measure.episodes import run_episodes
    from comat.team import generate_coalitions

    def random_policy():
        rng = np.random.default_rng(0)
        return lambda obs, mask, state: random_actions(rng, mask)

    teams = generate_coalitions("pcp", "train")[:4]
    with make_vec_env("pcp_v0", 4, workers=2, seed=0, coalitions=teams, **OPTS) as env:
        first = run_episodes(env, random_policy(), teams, seed=5)
        assert run_episodes(env, random_policy(), teams, seed=5) == first and len(first) == 4
