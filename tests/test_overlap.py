"""``ppo.overlap``: the next rollout is collected by a thread, with the weights from before the update,
while the update runs. What it changes is exactly the policy lag of one update: the first update
equals the sequential one, the rollout collected beside it is the one the old weights would collect,
the lagged update's decoupled loss is the plain one where there is no lag, a run is reproducible and
resumes exactly (the pending rollout is in the checkpoint), and a checkpoint holding one is refused by
a run without ``overlap``."""

import copy
import threading

import pytest
import torch
from test_rl import TINY_MODELS, assert_same, tiny

from comat.envs import make_vec_env
from comat.models import Comat, ComatConfig, ObsLayout
from comat.rl import load_checkpoint, train
from comat.rl.ppo import CollectionStopped, PPOConfig, PPOTrainer

TINY_PPO = {"num_envs": 2, "rollout_steps": 3, "epochs": 2, "minibatches": 2}


@pytest.fixture
def pcp_env():
    """A factory of reset 2-environment PCP vector envs, closed after the test."""
    made = []

    def make():
        env = make_vec_env("pcp_v0", 2, seed=0, tier="unicycle")
        made.append(env)
        env.reset()
        return env

    yield make
    for env in made:
        env.close()


def _trainer(env, overlap: bool) -> PPOTrainer:
    torch.manual_seed(0)
    policy = Comat(ObsLayout.for_task(env.task), ComatConfig(**TINY_MODELS["comat"]))
    return PPOTrainer(policy, env, PPOConfig(**TINY_PPO, overlap=overlap), seed=0)


def _weights(trainer: PPOTrainer) -> dict:
    return {k: v.clone() for k, v in trainer.policy.state_dict().items()}


def test_overlap_is_the_sequential_update_with_a_rollout_of_the_weights_before_it(pcp_env):
    env_a, env_b = pcp_env(), pcp_env()
    a, b = _trainer(env_a, overlap=True), _trainer(env_b, overlap=False)
    before = copy.deepcopy(b.policy)
    # The collection beside the update starts only once the update has changed the weights (one
    # of the orders the threads may take), so a collector acting with the live weights is seen.
    updated, update, collect = threading.Event(), a.update, a.collect

    def update_then_tell(ro, lagged=False):
        stats = update(ro, lagged)
        updated.set()
        return stats

    def collect_after_the_update(policy=None, stop=None):
        if threading.current_thread() is not threading.main_thread():
            assert updated.wait(60)
        return collect(policy, stop)

    a.update, a.collect = update_then_tell, collect_after_the_update
    ro_a, stats_a = a.iterate()
    ro_b, stats_b = b.iterate()
    # The first update learns from the same rollout, to the same weights: the collection beside
    # it touches neither the learner nor the update's random stream.
    assert_same(ro_a.actions, ro_b.actions, "first rollout")
    assert stats_a == {**stats_b, "lag_kl": 0.0}
    assert_same(_weights(a), _weights(b), "weights after one update")
    assert set(a.timing) == {"collect_s", "update_s", "wait_s"} and set(b.timing) == {"collect_s", "update_s"}
    # The rollout collected beside the update is the one the weights before it collect.
    lagged = b.collect(before)
    assert_same(a.pending.actions, lagged.actions, "pending rollout")
    assert_same(a.pending.logp, lagged.logp, "its log-probs")
    assert not torch.equal(b.collect(b.policy).logp, lagged.logp)  # which the new weights would not
    # and the second update learns from it.
    ro_a2, _ = a.iterate()
    assert ro_a2.actions.data_ptr() == lagged.actions.data_ptr() or torch.equal(ro_a2.actions, lagged.actions)


@pytest.mark.parametrize("workers", [1, 2])
def test_an_overlapped_run_is_reproducible_and_resumes_exactly(tmp_path, workers):
    ppo = {**TINY_PPO, "overlap": True}
    straight = train(tiny("comat", ppo=ppo, env_workers=workers), tmp_path / "straight", quiet=True)
    train(tiny("comat", steps=6, ppo=ppo, env_workers=workers), tmp_path / "split", quiet=True)
    resumed = train(tiny("comat", ppo=ppo, env_workers=workers), tmp_path / "split", resume=True, quiet=True)
    assert straight["env_steps"] == resumed["env_steps"] == 12
    a = load_checkpoint(tmp_path / "straight" / "checkpoint.pt")
    b = load_checkpoint(tmp_path / "split" / "checkpoint.pt")
    assert a["trainer"]["pending"] is not None  # the next update's rollout travels with the checkpoint
    assert_same(a["trainer"], b["trainer"], "trainer")
    assert_same(a["env_rngs"], b["env_rngs"], "env_rngs")
    again = train(tiny("comat", ppo=ppo, env_workers=workers), tmp_path / "again", quiet=True)
    assert again == {**straight, "wall_s": again["wall_s"]}
    assert_same(a["trainer"], load_checkpoint(tmp_path / "again" / "checkpoint.pt")["trainer"], "a second run")


def test_a_pending_rollout_is_refused_by_a_run_without_overlap(pcp_env):
    env = pcp_env()
    overlapped = _trainer(env, overlap=True)
    overlapped.iterate()
    state = overlapped.state_dict()
    with pytest.raises(ValueError, match=r"ppo.overlap=true .* this run has ppo.overlap=false"):
        _trainer(env, overlap=False).load_state_dict(state)
    plain = _trainer(env, overlap=False)
    plain.iterate()
    assert plain.state_dict()["pending"] is None
    resumed = _trainer(env, overlap=True)
    resumed.load_state_dict(state)
    assert_same(resumed.pending.obs, overlapped.pending.obs, "pending rollout")


def test_overlap_must_be_a_bool():
    with pytest.raises(TypeError, match=r"ppo.overlap must be true or false, got 'yes'"):
        PPOConfig(overlap="yes")


def test_a_failing_update_stops_the_collection_beside_it(pcp_env):
    env = pcp_env()
    a = _trainer(env, overlap=True)
    a.iterate()
    started, outcome, collect = threading.Event(), [], a.collect

    def collect_once_told(policy=None, stop=None):
        started.set()
        stop.wait(60)  # the order under test: the update fails while the collection runs
        try:
            return collect(policy, stop)
        except BaseException as e:
            outcome.append(type(e))
            raise

    def failing_update(ro, lagged=False):
        assert started.wait(60)
        raise RuntimeError("update failed")

    a.collect, a.update = collect_once_told, failing_update
    with pytest.raises(RuntimeError, match="update failed"):
        a.iterate()
    assert outcome == [CollectionStopped]


def test_the_lagged_loss_is_the_plain_one_without_lag_and_weighs_a_real_lag(pcp_env):
    """The decoupled loss (clip centred on the update's starting weights, terms weighted by
    π_prox / π_behaviour) on a rollout of those very weights is PPO's own, to float rounding (the
    proximal log-probs come from the teacher-forced pass, the behaviour ones from acting's kernels);
    on a rollout of older weights it reports the lag."""
    env = pcp_env()
    plain, lagged = _trainer(env, overlap=False), _trainer(env, overlap=True)
    ro = plain.collect()
    s_plain, s_lagged = plain.update(ro), lagged.update(ro, lagged=True)
    assert s_lagged["lag_kl"] < 1e-8, s_lagged["lag_kl"]
    for name, p in plain.policy.named_parameters():
        torch.testing.assert_close(lagged.policy.state_dict()[name], p, atol=1e-5, rtol=1e-4, msg=name)
    # a rollout of weights well apart from the learner's (a lag larger than one tiny update's)
    with torch.no_grad():
        for trainer in (plain, lagged):
            g = torch.Generator().manual_seed(1)
            for p in trainer.policy.parameters():
                p.add_(0.05 * torch.randn(p.shape, generator=g))
    s_plain, s_lagged = plain.update(ro), lagged.update(ro, lagged=True)
    assert s_lagged["lag_kl"] > 1e-3 and "lag_kl" not in s_plain
    # centred on the new weights, the clip cuts far fewer terms than around the behaviour policy
    assert s_lagged["clip_frac"] < s_plain["clip_frac"] / 2
