"""``comat probe``: is a trained learner's value estimate still tied to the rewards it earns?

A learner can fall back late in training while its own loss curves look calm (a value
normalizer hides a drifting critic; a TD loss stays low while Q runs away). The probe plays the
checkpoint's own policy on the training coalitions and puts its value estimates next to what
the episodes return, and next to a hard bound: no discounted return exceeds
``max step reward / (1 − γ)`` (the largest team reward seen in the probe's steps).

PPO learners (COMAT, MAT, MAPPO) — one training rollout (stochastic actions, exactly as
:meth:`comat.rl.ppo.PPOTrainer.collect` gathers it), per team size:

* ``value``: mean V̂ (the robots' mean value, de-normalized) over the rollout's team-steps;
* ``gae_return``: mean GAE(λ) return (the advantage's target, V̂ + Â);
* ``advantage``: mean advantage after the trainer's batch normalization.

and overall ``robot_weighted_advantage`` = Σ n·Â / Σ n (n robots per team): the per-robot
policy loss averages over robots, so at ratio 1 it equals minus this. Zero by construction
when all teams have one size; away from zero, the critic's error differs by team size (a
constant offset per team adds no gradient in expectation, but it adds variance).

QMIX — one greedy episode per environment, as the evaluation plays them:

* ``q_tot_start``: Q_tot(s_0, greedy actions) at episode starts, in the learner's units
  (standardized rewards), against ``discounted_return``, Σ γ^t r̃_t of the episode plus
  γ^L·Q_tot(s_L) where the time limit cut it (the learner's own target, bootstrapped alike;
  not with ``horizon_terminal``);
* ``action_gap``: mean Q_i(best) − Q_i(second best) over robot-steps; ``mixer_gain``: mean
  ∂Q_tot/∂Q_i at episode starts (how much an agent's action can move Q_tot);
* ``greedy_actions``: share of each action (stay, +x, −x, +y, −y) per robot type.

Output: a table on screen and ``probe.json`` (written atomically).
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import torch

from comat.files import relative_path, write_atomic
from comat.rl import Dims, RunConfig, load_checkpoint, make_learner, make_run_env

__all__ = ["print_probe", "probe_checkpoint", "write_probe"]

_ACTIONS = ("stay", "+x", "-x", "+y", "-y")


def probe_checkpoint(checkpoint: str | Path, seed: int | None = None, num_envs: int | None = None) -> dict:
    """Value-vs-reward diagnostics of a checkpoint (see the module docstring).

    Args:
        checkpoint: a run's ``checkpoint.pt``.
        seed: environment and sampling seed (default: the run's seed).
        num_envs: environments (default: the run's ``num_envs``).
    """

    data = load_checkpoint(checkpoint)
    config = RunConfig.from_dict(data["config"])
    if num_envs is not None:
        if isinstance(num_envs, bool) or not isinstance(num_envs, int) or num_envs < 1:
            raise ValueError(f"num_envs must be a positive integer, got {num_envs!r}")
        config = dataclasses.replace(config, trainer=dataclasses.replace(config.trainer, num_envs=num_envs))
    seed = config.seed if seed is None else int(seed)
    config = dataclasses.replace(config, seed=seed, env_workers=1)
    torch.manual_seed(seed)
    env = make_run_env(config, config.trainer.num_envs, seed)
    try:
        env.reset()
        learner = make_learner(config, env, Dims(**data["progress"]["dims"]))
        learner.load_state_dict(data["trainer"])
        for m in learner.modules.values():
            m.eval()
        body = {"ppo": _probe_ppo, "qmix": _probe_qmix}[learner.family](learner.trainer)
    finally:
        env.close()
    return {
        "checkpoint": str(checkpoint),
        "algo": config.algo,
        "task": config.task,
        "tier": config.tier,
        "env_steps": int(data["progress"]["env_steps"]),
        "seed": seed,
        "num_envs": config.trainer.num_envs,
        "gamma": config.trainer.gamma,
        **body,
    }


@torch.no_grad()
def _probe_ppo(trainer) -> dict:
    cfg = trainer.config
    ro = trainer.collect()
    mask = ro.mask.to(torch.float32)
    v_hat, _, ret, norm = trainer.advantages(ro)  # exactly what the update sees
    n = mask.sum(-1)
    T, B, N, D = ro.obs.shape
    _, entropy, _ = trainer.policy.evaluate_actions(
        ro.obs.reshape(T * B, N, D),
        ro.mask.reshape(T * B, N),
        ro.actions.reshape(T * B, N),
        None if ro.state is None else ro.state.reshape(T * B, -1),
    )
    sizes = [
        {
            "size": int(k),
            "share": float((n == k).float().mean()),
            "value": float(v_hat[n == k].mean()),
            "gae_return": float(ret[n == k].mean()),
            "advantage": float(norm[n == k].mean()),
        }
        for k in torch.unique(n).tolist()
    ]
    return {
        "kind": "ppo",
        "team_steps": T * B,
        "by_team_size": sizes,
        "value_start": float(v_hat[0].mean()),
        "episode_return": float(np.mean([e["return"] for e in ro.episodes])) if ro.episodes else float("nan"),
        "value_bound": float(ro.rewards.max()) / (1 - cfg.gamma),
        "robot_weighted_advantage": float((norm * n).sum() / n.sum()),
        "entropy": float((entropy.reshape(T, B, N) * mask).sum() / mask.sum()),
    }


def _probe_qmix(trainer) -> dict:
    env, cfg = trainer.env, trainer.config
    agents, mixer = trainer.agents, trainer.mixer

    def q_tot(obs, mask, state):  # (B,) of the greedy joint action; agent Q (B, N, A)
        q = agents(torch.as_tensor(obs, dtype=torch.float32), torch.as_tensor(mask))
        return mixer(q.max(-1).values, torch.as_tensor(mask), torch.as_tensor(state, dtype=torch.float32)), q

    obs, info = env.reset()
    mask, state = info["agent_mask"], env.state()
    B = env.num_envs
    q_taken = torch.zeros(B, mask.shape[1], requires_grad=True)
    with torch.no_grad():
        q0 = agents(torch.as_tensor(obs, dtype=torch.float32), torch.as_tensor(mask))
        q_taken.data.copy_(q0.max(-1).values)
    start = mixer(q_taken, torch.as_tensor(mask), torch.as_tensor(state, dtype=torch.float32))
    (gain,) = torch.autograd.grad(start.sum(), q_taken)
    mixer_gain = float(gain[torch.as_tensor(mask)].mean())
    start = start.detach().numpy()
    ret, disc = np.zeros(B), np.ones(B)
    ended = np.zeros(B, bool)
    gaps, counts, max_reward = [], {}, -np.inf
    with torch.no_grad():
        for _ in range(env.task.horizon):
            q = agents(torch.as_tensor(obs, dtype=torch.float32), torch.as_tensor(mask)).numpy()
            actions = np.where(mask, q.argmax(-1), 0)
            live = mask & ~ended[:, None]
            top2 = np.sort(q[live], axis=-1)[:, -2:]
            gaps.append(top2[:, 1] - top2[:, 0])
            for ty, a in zip(info["type_ids"][live], actions[live]):
                counts.setdefault(int(ty), np.zeros(len(_ACTIONS)))[a] += 1
            obs, rewards, terminated, truncated, info = env.step(actions)
            r = trainer.learner_rewards(rewards)
            max_reward = max(max_reward, float(r[~ended].max())) if (~ended).any() else max_reward
            ret += np.where(ended, 0.0, disc * r)
            cut = truncated & ~ended & (not cfg.horizon_terminal)
            if cut.any():  # the learner bootstraps at the time limit: so does the reference
                tail, _ = q_tot(info["final_obs"], mask, info["final_state"])
                ret += np.where(cut, disc * cfg.gamma * tail.numpy(), 0.0)
            disc = disc * cfg.gamma
            ended |= terminated | truncated
            if ended.all():
                break
            mask, state = info["agent_mask"], env.state()
    return {
        "kind": "qmix",
        "episodes": B,
        "q_tot_start": float(start.mean()),
        "discounted_return": float(ret.mean()),
        "value_bound": max_reward / (1 - cfg.gamma),
        "action_gap": float(np.concatenate(gaps).mean()),
        "mixer_gain": mixer_gain,
        "greedy_actions": {
            str(ty): dict(zip(_ACTIONS, (c / c.sum()).round(4).tolist())) for ty, c in sorted(counts.items())
        },
        **dict(zip(("reward_mean", "reward_std"), trainer.reward_standardization())),
    }


def print_probe(result: dict) -> None:
    """The probe as a short table."""
    head = f"{result['algo']} on {result['task']} after {result['env_steps']:,} env steps"
    if result["kind"] == "ppo":
        print(f"{head}: one training rollout of {result['team_steps']} team-steps")
        print(f"{'team size':>9} {'share':>6} {'value V̂':>10} {'GAE return':>11} {'advantage':>10}")
        for row in result["by_team_size"]:
            print(
                f"{row['size']:>9} {row['share']:>6.2f} {row['value']:>10.3f} {row['gae_return']:>11.3f} "
                f"{row['advantage']:>+10.3f}"
            )
        print(
            f"value at episode start {result['value_start']:.3f}; episodes returned {result['episode_return']:.3f}; "
            f"bound max r/(1-γ) {result['value_bound']:.3f}"
        )
        print(
            f"robot-weighted mean advantage {result['robot_weighted_advantage']:+.3f} (policy loss at ratio 1: its "
            f"negative); entropy {result['entropy']:.3f} (uniform: {np.log(5):.3f})"
        )
        return
    print(f"{head}: {result['episodes']} greedy episodes (standardized reward units)")
    print(
        f"Q_tot at episode start {result['q_tot_start']:.3f}; discounted return {result['discounted_return']:.3f}; "
        f"bound max r/(1-γ) {result['value_bound']:.3f}"
    )
    print(f"agent Q best-minus-second {result['action_gap']:.4f}; mixer gain dQ_tot/dQ_i {result['mixer_gain']:.3f}")
    for ty, shares in result["greedy_actions"].items():
        print(f"type {ty} greedy actions: " + ", ".join(f"{a} {s:.0%}" for a, s in shares.items()))


def write_probe(result: dict, out: str | Path) -> Path:
    """``out/probe.json``, atomically (``"checkpoint"`` relative to ``out``)."""
    path = Path(out) / "probe.json"
    if result.get("checkpoint") is not None:
        result = {**result, "checkpoint": relative_path(result["checkpoint"], out)}
    write_atomic(path, json.dumps(result, indent=2))
    return path
