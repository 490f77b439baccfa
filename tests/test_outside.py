"""comat's trainer on an environment comat did not write (comat/envs/outside.py, issue 65): PettingZoo's
MPE simple_spread_v3 from mpe2 (the ``outside`` and ``test`` extras)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

pytest.importorskip("mpe2", reason="mpe2 (pip install 'comat[outside]') brings the outside env these tests train on")

from mpe2 import simple_spread_v3

from comat.cli.args import resolve_policy_arg
from comat.envs.outside import LAYOUT_PREFIX, OutsideVectorEnv, make_outside_env, play_outside
from comat.rl import RunConfig, apply_overrides, load_preset, resolve
from comat.rl.runner import evaluate, train

TASK = "outside:mpe2.simple_spread_v3"
B, N, D = 3, 3, 18  # environments; simple_spread's 3 agents and their 18 observation features


def rollout(env: OutsideVectorEnv, steps: int, seed: int = 5) -> list[tuple]:
    """``steps`` steps of actions drawn from ``seed``: every array the env returned."""
    rng = np.random.default_rng(seed)
    out = [env.reset()[0]]
    for _ in range(steps):
        obs, rew, term, trunc, info = env.step(rng.integers(0, 5, (env.num_envs, env.max_robots)))
        out.append((obs, rew, term, trunc, env.state(), info.get("final_obs")))
    return out


def test_shapes_layout_and_an_episode_end():
    env = OutsideVectorEnv(TASK, B, seed=0)
    obs, info = env.reset()
    assert obs.shape == (B, N, 5 + D) and env.task.obs_size() == 5 + D and env.task.horizon == 25
    assert (obs[..., :5] == LAYOUT_PREFIX).all()  # unused pose slots, the one type's one-hot
    assert info["agent_mask"].shape == (B, N) and info["agent_mask"].all()
    assert env.state().shape == (B, env.state_size()) == (B, 54)  # MPE's state: the 3 observations
    returns = np.zeros(B)
    for t in range(25):
        obs, rew, term, trunc, info = env.step(np.zeros((B, N), dtype=np.int64))
        returns += rew
        assert rew.shape == term.shape == trunc.shape == (B,)
        assert ("episode" in info) == (t == 24)
    assert trunc.all() and not term.any()  # MPE's time limit: PPO bootstraps from final_obs
    assert info["_episode"].all() and info["final_obs"].shape == (B, N, 5 + D)
    assert not np.allclose(info["final_obs"], obs)  # same-step autoreset: obs is the next episode's first
    np.testing.assert_allclose(info["episode"]["return"], returns)
    assert (info["episode"]["steps"] == 25).all() and np.isnan(info["episode"]["progress"]).all()


def test_observations_and_rewards_are_the_envs_own():
    """Environment 0's first episode against simple_spread_v3 itself, reset with the seed the adapter
    draws: the observation after the prefix and the mean of the agents' rewards."""
    env = OutsideVectorEnv(TASK, B, seed=11)
    episode_seed = int(np.random.default_rng(np.random.SeedSequence(11).spawn(B)[0]).integers(2**31 - 1))
    raw = simple_spread_v3.parallel_env()
    raw_obs, _ = raw.reset(seed=episode_seed)
    obs, _ = env.reset()
    rng = np.random.default_rng(2)
    for _ in range(10):
        np.testing.assert_allclose(obs[0, :, 5:], np.stack([raw_obs[a] for a in raw.possible_agents]), rtol=1e-6)
        actions = rng.integers(0, 5, (B, N))
        raw_obs, raw_rew, *_ = raw.step({a: int(actions[0, i]) for i, a in enumerate(raw.possible_agents)})
        obs, rew, *_ = env.step(actions)
        assert rew[0] == pytest.approx(np.mean(list(raw_rew.values())))


def test_same_seed_same_episodes_and_generator_state_round_trip():
    a, b, c = (OutsideVectorEnv(TASK, B, seed=s) for s in (4, 4, 5))
    ra, rb, rc = rollout(a, 30), rollout(b, 30), rollout(c, 30)
    for x, y in zip(ra[1:], rb[1:]):
        for u, v in zip(x, y):
            np.testing.assert_array_equal(u, v)
    assert not np.array_equal(ra[0], rc[0])
    states = a.rng_state()
    a.reset()
    first = a.reset()[0]  # two episodes on
    a.set_rng_state(states)
    a.reset()
    assert np.array_equal(a.reset()[0], first)


def test_bad_input_is_named_in_one_line():
    env = OutsideVectorEnv(TASK, B, seed=0)
    with pytest.raises(RuntimeError, match="call reset"):
        env.step(np.zeros((B, N), dtype=np.int64))
    env.reset()
    with pytest.raises(ValueError, match=r"actions must have shape \(3, 3\)"):
        env.step(np.zeros((B, N + 1), dtype=np.int64))
    with pytest.raises(ValueError, match=r"actions must be integers in \[0, 5\)"):
        env.step(np.full((B, N), 5))
    with pytest.raises(ValueError, match="teams must be None for an outside env"):
        env.reset(teams=[])
    with pytest.raises(ValueError, match="more than the learner's max_robots=2"):
        OutsideVectorEnv(TASK, 1, max_robots=2)
    with pytest.raises(ValueError, match=r"module 'nope\.env' did not import \(No module named 'nope'\)"):
        make_outside_env("outside:nope.env")
    with pytest.raises(ValueError, match="module 'json' has no parallel_env"):
        make_outside_env("outside:json")
    with pytest.raises(ValueError, match="task must be outside:MODULE"):
        make_outside_env("outside:")
    with pytest.raises(ValueError, match="choose among 5 discrete actions, but agent 'speaker_0' has action space"):
        OutsideVectorEnv("outside:mpe2.simple_speaker_listener_v4", 1)
    with pytest.raises(ValueError, match="one agent type needs one flat observation shape"):
        OutsideVectorEnv("outside:mpe2.simple_adversary_v3", 1)


def config(algo: str, steps: int, *overrides: str) -> RunConfig:
    preset = apply_overrides(load_preset("quick"), ["ppo.num_envs=4", "qmix.num_envs=4", "torch_threads=1", *overrides])
    return resolve(preset, algo, TASK, seed=3, total_env_steps=steps)


def test_learners_that_read_poses_or_capabilities_and_comat_world_settings_are_refused():
    for algo in ("comat", "cash", "cash-caps"):
        with pytest.raises(ValueError, match=f"algo '{algo}' cannot train on outside task .* learners that can: "):
            config(algo, 100)
    with pytest.raises(ValueError, match="reality: outside task .* has no reality layer .* got 'nominal'"):
        config("mappo", 100, "reality=nominal")
    with pytest.raises(ValueError, match="coalitions: outside task .* has its own team and world, got 'test'"):
        config("mappo", 100, "coalitions=test")
    cfg = config("mappo", 100, "env_workers=2")
    assert cfg.env_workers == 1 and cfg.coalitions == "own" and cfg.env_id == TASK


@pytest.mark.parametrize("algo", ["mappo", "ippo", "mat", "qmix"])
def test_a_few_updates_train_write_a_policy_and_evaluate(algo, tmp_path):
    cfg = config(algo, 300, "eval_episodes_per_team=3")
    summary = train(cfg, tmp_path / "run", quiet=True)
    assert summary["env_steps"] >= 300 and summary["task"] == TASK
    ev = summary["eval_train"]
    assert ev["steps"] == 25 and np.isfinite(ev["return"]) and np.isnan(ev["progress"])
    import comat

    policy = comat.load_policy(tmp_path / "run")
    obs = OutsideVectorEnv(TASK, 2, seed=0).reset()[0]
    assert policy.act(obs).shape == (2, N)
    with pytest.raises(ValueError, match="is a policy file for outside task .* runs comat's tasks only"):
        resolve_policy_arg(str(tmp_path / "run" / "policy.pt"), None)


def test_resume_continues_exactly_and_the_policy_plays_what_evaluate_reports(tmp_path):
    """Three MAPPO updates in one go and as one update, then two resumed: the same weights."""
    whole, part = config("mappo", 300), config("mappo", 100)
    train(whole, tmp_path / "whole", quiet=True)
    train(part, tmp_path / "part", quiet=True)
    train(RunConfig.from_dict({**part.to_dict(), "total_env_steps": 300}), tmp_path / "part", resume=True, quiet=True)
    a, b = (torch.load(tmp_path / name / "policy.pt", weights_only=False)["weights"] for name in ("whole", "part"))
    for module in a:
        for key in a[module]:
            torch.testing.assert_close(a[module][key], b[module][key], rtol=0, atol=0)
    import comat

    policy = comat.load_policy(tmp_path / "whole")
    env = OutsideVectorEnv(TASK, 3, seed=whole.seed + 1_000_003)
    rows = play_outside(env, lambda obs, mask, state: policy.act(obs, mask), 3, whole.seed + 1_000_003)
    modules = {name: m for name, m in policy.modules.items()}
    assert np.mean([r["return"] for r in rows]) == pytest.approx(evaluate(whole, modules, 3)["return"])
