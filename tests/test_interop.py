"""comat envs under the standard wrappers (optional extra ``comat[interop]``; skipped without it):
TorchRL's PettingZooWrapper across resets whose team sizes differ, SuperSuit's wrapper chain over
full episodes of the training set."""

import numpy as np
import pytest

import comat
from comat.tasks import env_id, task_names
from comat.team import random_team

SIZES = (2, 3, 4, 5, 6, 7, 8)


@pytest.mark.filterwarnings("ignore:PettingZoo in TorchRL is tested:UserWarning")
@pytest.mark.parametrize("task", task_names())
def test_torchrl_rollout_across_team_changes_passes_the_spec_check(task):
    pytest.importorskip("torchrl")
    from torchrl.envs.libs.pettingzoo import PettingZooWrapper
    from torchrl.envs.utils import check_env_specs

    rng = np.random.default_rng(0)
    teams = [random_team(rng, task, "test", n) for n in SIZES]
    # One control tick per step keeps the test short; the agent bookkeeping is the same.
    env = comat.make_env(env_id(task), coalitions=teams, tier="unicycle", ticks_per_step=1)
    # done_on_any=False: the episode ends when every agent is done; the agents outside this episode's
    # team are done from its start (the spec sheet's "Team changes").
    wrapped = PettingZooWrapper(
        env, use_mask=True, categorical_actions=True, return_state=True, done_on_any=False, seed=0
    )
    check_env_specs(wrapped)
    td = wrapped.rollout(12 * 80, break_when_any_done=False)
    mask = td["robot", "mask"]  # (T, 8): this step's team
    sizes = mask.sum(-1)
    assert (mask == (np.arange(8)[None, :] < sizes[:, None].numpy())).all()  # the first n robots
    ends = td["next", "done"][:, 0].nonzero()[:, 0].tolist()
    starts = [0, *[e + 1 for e in ends[:-1]]]
    episodes = [sizes[s : e + 1] for s, e in zip(starts, ends)]
    assert len(episodes) >= 5
    assert all(len(ep) > 1 and (ep == ep[0]).all() for ep in episodes)  # one team per episode, no early done
    assert len({int(ep[0]) for ep in episodes}) >= 5 and {int(ep[0]) for ep in episodes} <= set(SIZES)
    obs = td["robot", "observation"]
    assert (obs[~mask] == 0).all() and (obs[mask].abs().sum(-1) > 0).all()
    assert td["state"].shape[-1] == env.state_space.shape[0]


@pytest.mark.parametrize("task", task_names())
def test_supersuit_chain_runs_full_episodes_on_the_training_set(task):
    ss = pytest.importorskip("supersuit")
    env = comat.make_env(env_id(task), coalitions="train", tier="unicycle", ticks_per_step=2)
    wrapped = ss.black_death_v3(ss.pad_observations_v0(env))
    sizes = set()
    for episode in range(8):
        obs, infos = wrapped.reset(seed=episode)
        assert wrapped.agents == env.agents and set(env.agents) <= set(obs) and set(env.agents) <= set(infos)
        sizes.add(len(wrapped.agents))
        steps, played, ended = 0, 0, False
        while wrapped.agents:
            actions = {a: wrapped.action_space(a).sample() for a in env.possible_agents}
            played += bool(env.agents)  # steps of the episode itself
            obs, rewards, terminations, truncations, infos = wrapped.step(actions)
            steps += 1
            ended = all(terminations[a] or truncations[a] for a in rewards)
        assert ended and played <= env.task.horizon
        # SuperSuit 3.11's black_death_v3 waits for terminated *and* truncated, so it reports the end
        # of a truncated episode one step late, as a step of zero observations.
        assert steps <= played + 1 and all(not o.any() for o in obs.values())
    assert len(sizes) >= 2  # the training set's teams change size between episodes
