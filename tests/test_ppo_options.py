"""PPO's trainer options (issue 65's matched arm): per-robot GAE against a hand computation, raw
advantages without normalization, the squared value loss, raw value targets, separate gradient
clipping, the entropy of each robot type, and the defaults unchanged."""

from pathlib import Path

import numpy as np
import pytest
import torch
from test_rl import tiny
from torch import nn

from comat.envs import make_vec_env
from comat.models import Comat, ComatConfig, ObsLayout
from comat.models.mappo import Mappo
from comat.rl import load_preset, resolve, train
from comat.rl.ppo import PPOConfig, PPOTrainer, Rollout

MATCHED = Path(__file__).resolve().parents[1] / "results" / "benchmarl" / "matched" / "matched.yaml"
GAMMA, LAM = 0.9, 0.8


class ValueFromObs(nn.Module):
    """A stub learner whose value of a robot is its observation's first feature and whose policy is
    one learned logit vector: advantages and value losses are then computable by hand."""

    def __init__(self) -> None:
        super().__init__()
        self.logits = nn.Parameter(torch.zeros(5))
        self.critic = nn.Linear(1, 1)  # unused by the values; gives grad_clip=separate its two groups

    def values(self, obs, mask, state=None):
        return obs[..., 0] * mask

    def evaluate_actions(self, obs, mask, actions, state=None):
        logp_all = torch.log_softmax(self.logits, -1).expand(*actions.shape, 5)
        logp = logp_all.gather(-1, actions[..., None])[..., 0] * mask
        entropy = -(logp_all.exp() * logp_all).sum(-1) * mask
        return logp, entropy, self.values(obs, mask)


def _tiny_rollout(obs_dim: int) -> Rollout:
    """T = 4 steps of B = 2 teams of up to N = 2 robots (team 1 has one: slot 1 padded). Team 0 is
    truncated at t = 1 (bootstrapped) and terminated at t = 3; team 1 terminates at t = 2."""
    g = torch.Generator().manual_seed(7)
    T, B, N = 4, 2, 2
    mask = torch.tensor([[True, True], [True, False]]).expand(T, B, N).clone()
    values = torch.randn(T, B, N, generator=g) * mask
    next_values = torch.randn(T, B, N, generator=g) * mask
    obs, next_obs = torch.zeros(T, B, N, obs_dim), torch.zeros(T, B, N, obs_dim)
    obs[..., 0], next_obs[..., 0] = values, next_values
    terminated = torch.zeros(T, B, dtype=torch.bool)
    dones = torch.zeros(T, B, dtype=torch.bool)
    dones[1, 0] = True  # truncated: the value of the next state counts
    terminated[3, 0] = dones[3, 0] = terminated[2, 1] = dones[2, 1] = True
    return Rollout(
        obs=obs,
        mask=mask,
        state=None,
        actions=torch.zeros(T, B, N, dtype=torch.long),
        logp=torch.full((T, B, N), -float(np.log(5))) * mask,
        values=values,
        rewards=torch.randn(T, B, generator=g),
        terminated=terminated,
        dones=dones,
        next_obs=next_obs,
        next_mask=mask.clone(),
        next_state=None,
        episodes=[],
    )


def _hand_gae(ro: Rollout, cut_is_terminal: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Each robot's advantage and GAE(λ) return by the textbook recursion, one robot at a time;
    ``cut_is_terminal``: no bootstrap where the episode was truncated either."""
    T, B, N = ro.values.shape
    adv = np.zeros((T, B, N))
    for b in range(B):
        for i in range(N):
            if not ro.mask[0, b, i]:
                continue
            running = 0.0
            for t in reversed(range(T)):
                ended = ro.dones[t, b] if cut_is_terminal else ro.terminated[t, b]
                bootstrap = 0.0 if ended else float(ro.next_obs[t, b, i, 0])
                delta = float(ro.rewards[t, b]) + GAMMA * bootstrap - float(ro.values[t, b, i])
                running = delta + (0.0 if ro.dones[t, b] else GAMMA * LAM * running)
                adv[t, b, i] = running
    return adv, adv + ro.values.numpy()


def _stub_trainer(**options) -> tuple[PPOTrainer, Rollout]:
    env = make_vec_env("pcp_v0", 2, seed=0, tier="unicycle")
    config = PPOConfig(num_envs=2, rollout_steps=4, gamma=GAMMA, gae_lambda=LAM, **options)
    return PPOTrainer(ValueFromObs(), env, config, seed=0), _tiny_rollout(env.task.obs_size())


def test_per_robot_gae_equals_a_hand_computation():
    trainer, ro = _stub_trainer(advantage="per_robot", normalize_advantage=False, value_norm=False)
    _, _, returns, adv, robot_returns = trainer._advantages(ro)
    hand_adv, hand_ret = _hand_gae(ro)
    np.testing.assert_allclose(adv.numpy(), hand_adv, atol=1e-6)
    real = ro.mask.numpy()
    np.testing.assert_allclose(robot_returns.numpy()[real], hand_ret[real], atol=1e-6)
    # The team's figures (what comat probe reads) are the means over its real robots.
    np.testing.assert_allclose(returns.numpy(), (hand_ret * real).sum(-1) / real.sum(-1), atol=1e-6)
    # The joint advantage of the same rollout is another number: one GAE on the team's mean value.
    joint, _ = _stub_trainer(normalize_advantage=False, value_norm=False)
    assert not np.allclose(joint._advantages(ro)[3].numpy(), hand_adv[..., 0], atol=1e-3)


def test_time_limit_terminal_ends_the_truncated_episode_without_its_final_value():
    """``time_limit: terminal``: the truncated step (team 0, t = 1) takes no value of its final
    observation; the default bootstraps it. Both against the hand recursion."""
    for time_limit, cut_is_terminal in (("terminal", True), ("bootstrap", False)):
        trainer, ro = _stub_trainer(
            advantage="per_robot", normalize_advantage=False, value_norm=False, time_limit=time_limit
        )
        adv = trainer._advantages(ro)[3]
        np.testing.assert_allclose(adv.numpy(), _hand_gae(ro, cut_is_terminal)[0], atol=1e-6)
    assert not np.allclose(_hand_gae(ro, True)[0][1, 0], _hand_gae(ro, False)[0][1, 0], atol=1e-3)
    with pytest.raises(ValueError, match=r"ppo.time_limit must be one of \['bootstrap', 'terminal'\], got 'cut'"):
        PPOConfig(time_limit="cut")


def test_normalize_advantage_off_leaves_the_raw_advantages_and_on_standardizes_the_real_robots():
    raw_trainer, ro = _stub_trainer(advantage="per_robot", normalize_advantage=False, value_norm=False)
    raw = raw_trainer._advantages(ro)[3]
    normed = _stub_trainer(advantage="per_robot", value_norm=False)[0]._advantages(ro)[3]
    real = ro.mask
    expected = (raw - raw[real].mean()) / (raw[real].std() + 1e-8)
    torch.testing.assert_close(normed[real], expected[real])
    assert float(normed[real].mean()) == pytest.approx(0.0, abs=1e-6)
    assert float(normed[real].std()) == pytest.approx(1.0, abs=1e-5)
    assert (normed[~real] == 0).all()
    # The joint advantage without normalization is the raw GAE on the team's mean value.
    joint_trainer = _stub_trainer(normalize_advantage=False, value_norm=False)[0]
    v_hat, _, returns, joint = joint_trainer._advantages(ro)[:4]
    torch.testing.assert_close(joint, returns - v_hat)
    assert float(joint.std()) != pytest.approx(1.0, abs=1e-2)


@pytest.mark.parametrize("value_loss", ["mse", "huber"])
def test_value_loss_is_the_mean_squared_error_or_huber_over_the_real_robots(value_loss):
    """One epoch of one minibatch: the logged value loss is the loss at the collecting weights,
    against each robot's raw GAE(λ) return (``value_norm: false``)."""
    trainer, ro = _stub_trainer(
        advantage="per_robot", value_target="gae", value_norm=False, value_loss=value_loss, epochs=1, minibatches=1
    )
    _, hand_ret = _hand_gae(ro)
    errors = (ro.values.numpy() - hand_ret)[ro.mask.numpy()]
    assert np.abs(errors).max() < trainer.config.huber_delta  # where Huber is ½ e², half the squared error
    expected = np.mean(errors**2) * (1.0 if value_loss == "mse" else 0.5)
    assert trainer.update(ro)["value_loss"] == pytest.approx(expected, rel=1e-5)


def test_value_norm_off_regresses_to_the_raw_targets_and_leaves_the_normalizer_alone():
    trainer, ro = _stub_trainer(value_target="gae", value_norm=False, epochs=1, minibatches=1, value_loss="mse")
    before = {k: v.clone() for k, v in trainer.value_norm.state_dict().items()}
    trainer.update(ro)
    assert all(torch.equal(before[k], v) for k, v in trainer.value_norm.state_dict().items())
    normed, ro = _stub_trainer(value_target="gae", epochs=1, minibatches=1, value_loss="mse")
    normed.update(ro)
    assert float(normed.value_norm.debias) > 0  # the default updates it


def test_grad_clip_separate_clips_the_critic_and_the_rest_each_on_its_own():
    env = make_vec_env("hmt_v0", 2, seed=0, tier="unicycle", max_robots=8)
    layout = ObsLayout.for_task(env.task)
    mappo = Mappo(layout, env.core.state_size())
    trainer = PPOTrainer(mappo, env, PPOConfig(num_envs=2, grad_clip="separate"), seed=0, use_state=True)
    actor, critic = trainer.clip_groups
    assert {id(p) for p in critic} == {id(p) for p in mappo.critic.parameters()}
    assert {id(p) for p in actor} == {id(p) for p in mappo.actor.parameters()}
    assert len(PPOTrainer(mappo, env, PPOConfig(num_envs=2), seed=0, use_state=True).clip_groups) == 1
    # COMAT: its value head (``critic``) on its own, the shared encoder with the actor's part.
    comat = Comat(layout, ComatConfig(16, 2, 1, 8))
    rest, head = PPOTrainer(comat, env, PPOConfig(num_envs=2, grad_clip="separate"), seed=0).clip_groups
    assert {id(p) for p in head} == {id(p) for p in comat.critic.parameters()} and len(rest) > len(head)
    with pytest.raises(ValueError, match=r"ppo.grad_clip=separate needs a model with a submodule named 'critic'"):
        PPOTrainer(nn.Sequential(nn.Linear(2, 5)), env, PPOConfig(num_envs=2, grad_clip="separate"), seed=0)


def test_entropy_of_each_robot_type_is_the_masked_mean_over_its_robots():
    """HMT (fast and slow robots), one epoch of one minibatch: each type's entropy is the mean over its
    real robot-steps at the collecting weights, and the all-robot mean is their count-weighted mean."""
    env = make_vec_env("hmt_v0", 3, seed=2, tier="unicycle", max_robots=8)
    layout = ObsLayout.for_task(env.task)
    torch.manual_seed(0)
    trainer = PPOTrainer(
        Mappo(layout, env.core.state_size()),
        env,
        PPOConfig(num_envs=3, rollout_steps=5, epochs=1, minibatches=1),
        seed=0,
        use_state=True,
    )
    ro = trainer.collect()
    T, B, N, D = ro.obs.shape
    with torch.no_grad():
        _, entropy, _ = trainer.policy.evaluate_actions(
            ro.obs.reshape(T * B, N, D), ro.mask.reshape(T * B, N), ro.actions.reshape(T * B, N),
            ro.state.reshape(T * B, -1),
        )  # fmt: skip
    types, real = layout.types(ro.obs.reshape(T * B, N, D)), ro.mask.reshape(T * B, N)
    stats = trainer.update(ro)
    counts = []
    for k, name in enumerate(env.task.types):
        chosen = real & (types == k)
        counts.append(int(chosen.sum()))
        assert counts[-1] > 0
        assert stats[f"entropy_{name}"] == pytest.approx(float(entropy[chosen].mean()), rel=1e-5)
    pooled = sum(n * stats[f"entropy_{name}"] for n, name in zip(counts, env.task.types)) / sum(counts)
    assert stats["entropy"] == pytest.approx(pooled, rel=1e-5)
    # The types' entropies differ (MAPPO's actors are one per type), so the columns carry information.
    assert stats["entropy_fast"] != stats["entropy_slow"]


def test_the_options_at_their_defaults_train_exactly_as_the_trainer_without_them(tmp_path):
    """The options are the trainer as before: a run with every option written out at its default
    equals the run without them, parameter for parameter (the golden values of the trainer before
    the options were compared once, 3 updates of MAPPO, COMAT and MAPPO with value_target gae on HMT:
    bit-identical; issue 65)."""
    defaults = {"advantage": "joint", "normalize_advantage": True, "value_loss": "huber", "value_norm": True,
                "grad_clip": "joint"}  # fmt: skip
    assert PPOConfig(**defaults) == PPOConfig()
    base = tiny("mappo")
    ppo = {"num_envs": 2, "rollout_steps": 3, "epochs": 2, "minibatches": 2}
    explicit = tiny("mappo", ppo={**ppo, **defaults})
    a = train(base, tmp_path / "implicit", quiet=True)
    b = train(explicit, tmp_path / "explicit", quiet=True)
    assert a["env_steps"] == b["env_steps"] == 12
    pa = torch.load(tmp_path / "implicit" / "checkpoint.pt", weights_only=False)["trainer"]["policy"]
    pb = torch.load(tmp_path / "explicit" / "checkpoint.pt", weights_only=False)["trainer"]["policy"]
    assert all(torch.equal(pa[k], pb[k]) for k in pa)
    header = (tmp_path / "implicit" / "progress.csv").read_text().splitlines()[0].split(",")
    assert {"entropy", "entropy_sensing", "entropy_capture"} <= set(header)


def test_the_matched_arm_preset_sets_benchmarls_choices():
    config = resolve(load_preset(MATCHED), "mappo", "hmt", seed=0)
    ppo = config.trainer
    assert (ppo.advantage, ppo.normalize_advantage, ppo.value_target, ppo.value_loss, ppo.value_norm) == (
        "per_robot", False, "gae", "mse", False,
    )  # fmt: skip
    assert ppo.grad_clip == "separate" and ppo.gae_lambda == 0.95 and ppo.entropy_coef == 0.01
    assert config.model.max_robots == 8


@pytest.mark.parametrize(
    "field, value, error, message",
    [
        ("advantage", "team", ValueError, r"ppo.advantage must be one of \['joint', 'per_robot'\], got 'team'"),
        ("value_loss", "l1", ValueError, r"ppo.value_loss must be one of \['huber', 'mse'\], got 'l1'"),
        ("grad_clip", "none", ValueError, r"ppo.grad_clip must be one of \['joint', 'separate'\], got 'none'"),
        ("normalize_advantage", "no", TypeError, r"ppo.normalize_advantage must be true or false, got 'no'"),
        ("value_norm", 0, TypeError, r"ppo.value_norm must be true or false, got 0"),
    ],
)
def test_bad_option_values_are_named_in_one_line(field, value, error, message):
    with pytest.raises(error, match=message):
        PPOConfig(**{field: value})


@pytest.mark.parametrize("preset", ["paper", "sweep", "quick"])
def test_the_study_presets_end_the_episode_at_the_horizon_where_the_observation_shows_the_clock(preset):
    """navigation and warehouse put the steps left in every observation: their runs take
    ``time_limit: terminal``; the tasks without a clock keep the bootstrap (issue 65's diagnosis)."""
    for task, expected in (
        ("navigation", "terminal"),
        ("warehouse", "terminal"),
        ("hmt", "bootstrap"),
        ("forage", "bootstrap"),
    ):
        assert resolve(load_preset(preset), "mat", task).trainer.time_limit == expected, (preset, task)
