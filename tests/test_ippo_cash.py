"""IPPO, CASH and CASH-caps (issues 50 and 65). IPPO: independent PPO — each robot acts and is valued
on its own observation, its type's parameters the only thing robots share. CASH: the authors' code's
actor, a hidden layer generated per robot from its observation and capabilities (its model's own
tests: tests/test_cash.py). CASH-caps: comat's first CASH, a shared encoder and a capability
hypernetwork that generates each robot's output layer; the kept runs of issue 50 load as it. All
learn, play any team size, resume exactly (tests/test_rl_resume.py) and keep their actors in a
policy file (tests/test_policy_file.py)."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
import torch
import yaml
from test_rl import tiny

from comat.bench import bench_train
from comat.eval import evaluate_policies
from comat.eval.runs import evaluation_row, load_run
from comat.measure.metrics import read_results
from comat.models import ObsLayout
from comat.models.cash_caps import CashCaps, CashCapsConfig, team_summary
from comat.models.ippo import Ippo, IppoConfig
from comat.rl import CheckpointError, load_preset, load_trained, policy_modules, resolve, robot_slots, train
from comat.tasks.hmt import HMT
from comat.team import random_team


def _obs(layout: ObsLayout, types: list[int], seed: int = 0) -> torch.Tensor:
    g = torch.Generator().manual_seed(seed)
    obs = torch.randn(1, len(types), layout.obs_dim, generator=g)
    obs[..., 4 : 4 + layout.n_types] = torch.nn.functional.one_hot(torch.tensor(types), layout.n_types).float()
    return obs


def test_each_robot_acts_and_is_valued_on_its_own_observation_with_its_types_parameters():
    layout = ObsLayout.for_task(HMT())
    torch.manual_seed(0)
    net = Ippo(layout, IppoConfig(hidden=16))
    obs, mask = _obs(layout, [0, 0, 1]), torch.ones(1, 3, dtype=torch.bool)
    logp, _, values = net.evaluate_actions(obs, mask, torch.zeros(1, 3, dtype=torch.long))
    changed = obs.clone()
    changed[0, 2, :4] += 1.0  # robot 2 moves: robots 0 and 1 neither act nor value differently
    logp2, _, values2 = net.evaluate_actions(changed, mask, torch.zeros(1, 3, dtype=torch.long))
    assert torch.equal(logp[0, :2], logp2[0, :2]) and torch.equal(values[0, :2], values2[0, :2])
    assert not torch.equal(values[0, 2], values2[0, 2])
    # robots 0 and 1 share their type's networks: the same observation, the same output
    same = obs.clone()
    same[0, 1] = same[0, 0]
    logits = net.actor(same, same[..., 4 : 4 + layout.n_types])
    # equal within float rounding: a BLAS may round two rows of one product differently (torch's MKL
    # does on an AMD CPU); the other type's head differs in the first digits
    assert torch.allclose(logits[0, 0], logits[0, 1], rtol=1e-5, atol=1e-7)
    # a robot of the other type with that observation gets the other type's networks
    other = same.clone()
    other[0, 1, 4 : 4 + layout.n_types] = torch.tensor([0.0, 1.0])
    other[0, 0, 4 : 4 + layout.n_types] = torch.tensor([1.0, 0.0])
    values = net.critic(other, other[..., 4:6])
    assert not torch.allclose(values[0, 0], values[0, 1], rtol=1e-3)


@pytest.mark.learning
@pytest.mark.parametrize("algo", ["ippo", "cash", "cash-caps"])
def test_the_new_learners_learn_pcp(algo, tmp_path):
    """The paper's PPO settings, ten updates (25,600 env steps, ~25 s each): the return rises from
    the random start (about −3) past 10 (measured 2026-12-06, first → last update: IPPO −3.1 → 17.5,
    CASH-caps (then CASH) −2.9 → 23.6)."""
    config = resolve(
        {**load_preset("paper"), "total_env_steps": 25_600, "eval_episodes_per_team": 0}, algo, "pcp", seed=0
    )
    train(config, tmp_path / "run", quiet=True)
    rows = list(csv.DictReader((tmp_path / "run" / "progress.csv").open()))
    returns = [float(r["episode_return"]) for r in rows]
    assert len(returns) == 10 and returns[0] < 0 and np.mean(returns[-3:]) > 10, returns


@pytest.mark.parametrize("algo", ["ippo", "cash", "cash-caps"])
def test_the_new_learners_play_every_team_size_without_slots(algo, tmp_path):
    config = tiny(algo)
    assert robot_slots(config) is None
    train(config, tmp_path / "run", quiet=True)
    # U_scale's smallest and largest sizes, one team each: a slot limit (8 for the paper's baselines)
    # fails on the 20-robot team as it would on the set's twenty teams, at a tenth of the episodes
    rng = np.random.default_rng(0)
    teams = [random_team(rng, "pcp", "scale", n) for n in (10, 20)]
    result = evaluate_policies(
        tmp_path / "run" / "checkpoint.pt", sets=(("scale", teams),), references=False, progress=lambda m: None
    )
    (row,) = result["rows"]
    assert row["episodes"] == 2 and sorted(e["team_size"] for e in row["per_episode"]) == [10, 20]


def test_cash_caps_generates_each_robots_decoder_from_its_capabilities_and_its_teams():
    layout = ObsLayout.for_task(HMT())
    torch.manual_seed(0)
    net = CashCaps(layout, CashCapsConfig(hidden=8, hyper_hidden=8))
    torch.nn.init.normal_(net.hyper[-1].weight)  # away from the small start, so the decoders differ
    obs, mask = _obs(layout, [0, 1, 1, 0]), torch.tensor([[True, True, True, False]])
    caps = layout.capabilities(obs)
    summary = team_summary(caps, mask)
    real = caps[0, :3]
    assert torch.allclose(summary[0, 0], torch.cat([real.mean(0), real.amax(0)]))  # the padded robot left out
    assert torch.equal(summary[0, 0], summary[0, 2])  # one summary per team
    # the same observation, other capabilities: another decoder, so other action scores
    other = obs.clone()
    other[0, 1, 4 + layout.n_types :] += 0.5
    assert not torch.allclose(net._logits(obs, mask)[0, 1], net._logits(other, mask)[0, 1])
    # permuting the team changes no robot's scores (the summary is order-free); padding the team changes none
    perm = torch.tensor([2, 0, 1, 3])
    logits = net._logits(obs, mask)
    assert torch.allclose(net._logits(obs[:, perm], mask[:, perm])[0, :3], logits[0, perm[:3]], atol=1e-6)
    wide = torch.cat([obs, torch.zeros(1, 3, layout.obs_dim)], 1)
    wide_mask = torch.cat([mask, torch.zeros(1, 3, dtype=torch.bool)], 1)
    assert torch.allclose(net._logits(wide, wide_mask)[0, :3], logits[0, :3], atol=1e-6)


@pytest.mark.parametrize("algo", ["ippo", "cash", "cash-caps"])
def test_bench_learn_has_a_row_for_each(algo, tmp_path):
    preset = tmp_path / "tiny.yaml"
    preset.write_text(yaml.safe_dump({"ppo": {"num_envs": 2, "rollout_steps": 2, "epochs": 1, "minibatches": 1}}))
    row = bench_train(algo, iterations=1, preset=str(preset))
    assert row["algo"] == algo and row["env_steps"] == 4 and row["learn_s"] > 0


KEPT = Path(__file__).resolve().parents[1] / "results" / "new_learners" / "runs"
"""Issue 50's CASH runs, trained and committed as ``cash`` before issue 65 gave the name to the CASH
of the authors' code: their policies must still act as what they are, ``cash-caps``."""


@pytest.mark.parametrize("run", ["cash_pcp_off_s100", "cash_hmt_off_s101"])
def test_issue_50s_kept_cash_policies_load_as_cash_caps(run):
    data = load_trained(KEPT / run / "policy.pt")
    assert data["algo"] == data["config"]["algo"] == "cash-caps" and "version" not in data["config"]["model"]
    modules, config = policy_modules(data)
    assert config.algo == "cash-caps" and type(modules["policy"]) is CashCaps
    with pytest.raises(CheckpointError, match=r"is for algo 'cash-caps', expected 'cash'"):
        load_trained(KEPT / run / "policy.pt", algo="cash")
    # a run folder's config.yaml and evaluation rows (reports) say the same
    loaded = load_run(KEPT / run)
    assert loaded["algo"] == "cash-caps" and evaluation_row(loaded, "train") is not None


def test_a_kept_cash_policy_plays_its_committed_episodes_again():
    """PCP seed 100's policy, evaluated now as cash-caps, takes the steps and makes the progress its
    committed evaluation recorded, episode by episode (first episode of each U_train coalition)."""
    run = KEPT / "cash_pcp_off_s100"
    result = evaluate_policies(run / "policy.pt", sets=("train",), references=False, progress=lambda m: None)
    (row,) = result["rows"]
    committed = [e for e in read_results(run / "evaluation_unicycle.json")["rows"][0]["per_episode"]]
    committed = [e for e in committed if e["episode_in_coalition"] == 0]
    assert row["policy"] == "cash-caps" and len(row["per_episode"]) == len(committed) == 20
    for now, then in zip(row["per_episode"], committed):
        assert (now["steps"], now["progress"]) == (then["steps"], then["progress"])
        assert now["return"] == pytest.approx(then["return"], abs=1e-9)


@pytest.mark.parametrize("algo", ["cash", "cash-caps"])
def test_export_refuses_cash_in_one_line(algo, tmp_path):
    from sim2real.export import export_submission

    train(tiny(algo, steps=6), tmp_path / "run", quiet=True)
    team = random_team(np.random.default_rng(0), "pcp", "test", 3)
    with pytest.raises(ValueError, match=f"'{algo}' policy file") as err:
        export_submission(tmp_path / "run" / "policy.pt", "pcp", team, tmp_path / "sub")
    assert "\n" not in str(err.value) and not (tmp_path / "sub").exists()
