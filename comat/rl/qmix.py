"""QMIX (Rashid et al. 2018) with EPyMARL's defaults, readable top to bottom.

One round:

1. **Collect** one episode per environment: every environment is reset, then stepped until its
   first episode ends (ε-greedy on the agents' Q-values, ε decaying linearly with env steps).
   An environment whose episode ended early keeps running on autoreset until the round is over;
   those extra steps are not stored and not counted. Rounds start from fresh episodes, which is
   what makes ``--resume`` continue exactly.
2. **Store** the episodes in a replay buffer of whole episodes (padded to the horizon, with a
   ``filled`` mask).
3. **Learn**: ``updates_per_episode`` learner steps per stored episode, each on a batch of
   episodes drawn uniformly. The TD target is double-Q:

       y_t = r_t + γ (1 − terminated_t) · Q_tot⁻(s_{t+1}, Q⁻(o_{t+1}, argmax_a Q(o_{t+1}, a)))

   (``horizon_terminal``: the time limit counts as terminated too.)

   with the target networks (⁻) hard-copied every ``target_update_interval`` learner steps. Loss:
   mean squared TD error over filled steps. Rewards are standardized by running statistics.

Padded robot slots (mask False) enter the mixer with Q = 0 and take no part in the loss.
Shapes: E episodes, T horizon, N robot slots, D observation, S state.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np
import torch
import torch.nn.functional as F

from comat.config import check_numbers
from comat.rl.device import learner_copy, to_cpu

__all__ = ["EpisodeBuffer", "QmixConfig", "QmixTrainer"]


@dataclass(frozen=True)
class QmixConfig:
    """QMIX settings (EPyMARL's qmix.yaml unless said otherwise)."""

    num_envs: int = 32
    """Environments stepped together; each round stores one episode per environment."""
    buffer_episodes: int = 5000
    batch_episodes: int = 32
    updates_per_episode: float = 1.0
    """Learner steps per stored episode (EPyMARL: one per episode)."""
    lr: float = 5e-4
    gamma: float = 0.99
    max_grad_norm: float = 10.0
    target_update_interval: int = 200
    """Learner steps between hard target-network updates."""
    epsilon_start: float = 1.0
    epsilon_finish: float = 0.05
    epsilon_anneal_steps: int = 50_000
    """Env steps over which ε decays linearly."""
    standardize_rewards: bool = True
    horizon_terminal: bool = False
    """Treat the task's time limit as terminal (no bootstrap from the last state), as MARBLER's
    QMIX runs did (its wrapper reports done at the horizon; EPyMARL's own limit was longer).
    False: bootstrap there, the textbook choice for a policy that does not see the time."""

    def __post_init__(self) -> None:
        check_numbers(
            self,
            "qmix",
            positive=("lr", "max_grad_norm", "updates_per_episode"),
            unit=("epsilon_start", "epsilon_finish"),
            discount=("gamma",),
            at_least_one=(
                "num_envs",
                "buffer_episodes",
                "batch_episodes",
                "target_update_interval",
                "epsilon_anneal_steps",
            ),
        )


class EpisodeBuffer:
    """Ring buffer of whole episodes, padded to the horizon T.

    Stores obs (E, T+1, N, D), state (E, T+1, S), mask (E, N), actions (E, T, N), rewards
    (E, T), terminated (E, T), filled (E, T).
    """

    def __init__(self, capacity: int, horizon: int, n_slots: int, obs_dim: int, state_dim: int) -> None:
        E, T, N = capacity, horizon, n_slots
        self.capacity, self.horizon = capacity, horizon
        self.obs = np.zeros((E, T + 1, N, obs_dim), np.float32)
        self.state = np.zeros((E, T + 1, state_dim), np.float32)
        self.mask = np.zeros((E, N), bool)
        self.actions = np.zeros((E, T, N), np.int64)
        self.rewards = np.zeros((E, T), np.float32)
        self.terminated = np.zeros((E, T), bool)
        self.filled = np.zeros((E, T), bool)
        self.next_index = 0
        self.size = 0

    def add(self, episode: dict[str, np.ndarray]) -> None:
        """Adds one episode: obs (L+1, N, D), state (L+1, S), mask (N,), actions (L, N),
        rewards (L,), terminated (L,)."""
        i, L = self.next_index, len(episode["rewards"])
        for name in ("obs", "state", "actions", "rewards", "terminated"):
            arr = getattr(self, name)[i]
            arr[:] = 0
            arr[: len(episode[name])] = episode[name]
        self.mask[i] = episode["mask"]
        self.filled[i] = np.arange(self.horizon) < L
        self.next_index = (i + 1) % self.capacity
        self.size = min(self.size + 1, self.capacity)

    def sample(self, batch: int, rng: np.random.Generator) -> dict[str, torch.Tensor]:
        idx = rng.integers(self.size, size=batch)
        return {
            name: torch.as_tensor(getattr(self, name)[idx])
            for name in ("obs", "state", "mask", "actions", "rewards", "terminated", "filled")
        }

    def state_dict(self) -> dict:
        n = self.size
        return {
            "next_index": self.next_index,
            "size": n,
            **{
                name: getattr(self, name)[:n].copy()
                for name in ("obs", "state", "mask", "actions", "rewards", "terminated", "filled")
            },
        }

    def load_state_dict(self, state: dict) -> None:
        n = state["size"]
        if n > self.capacity:
            raise ValueError(f"checkpoint buffer holds {n} episodes, this buffer's capacity is {self.capacity}")
        for name in ("obs", "state", "mask", "actions", "rewards", "terminated", "filled"):
            getattr(self, name)[:n] = state[name]
        self.next_index, self.size = state["next_index"], n


class _RunningStats:
    """Running mean/variance (parallel Welford), for reward standardization."""

    def __init__(self) -> None:
        self.mean, self.var, self.count = 0.0, 1.0, 1e-4

    def update(self, x: np.ndarray) -> None:
        n, mean, var = x.size, float(x.mean()), float(x.var())
        delta, total = mean - self.mean, self.count + n
        self.var = (self.var * self.count + var * n + delta**2 * self.count * n / total) / total
        self.mean += delta * n / total
        self.count = total


class QmixTrainer:
    """Trains QMIX agents and mixer on a :class:`comat.envs.VectorEnv`.

    Args:
        agents: :class:`comat.models.qmix.QmixAgents`.
        mixer: :class:`comat.models.qmix.QmixMixer`.
        env: the vector environment (``num_envs`` must equal ``config.num_envs``).
        config: QMIX settings.
        seed: seeds exploration and replay sampling.
        device: None to learn in place on the CPU; else the learner steps run on copies of the
            networks on this device, mirrored to the CPU ones after every update (:mod:`comat.rl.device`).
    """

    def __init__(self, agents, mixer, env, config: QmixConfig, seed: int, device: str | None = None) -> None:
        if env.num_envs != config.num_envs:
            raise ValueError(f"env has {env.num_envs} environments, config.num_envs is {config.num_envs}")
        self.agents, self.mixer, self.env, self.config = agents, mixer, env, config
        self.device = device
        # Acting stays on `agents` (CPU); the learner steps train these.
        self.learn_agents, self.learn_mixer = learner_copy(agents, device), learner_copy(mixer, device)
        self.params = list(self.learn_agents.parameters()) + list(self.learn_mixer.parameters())
        self.optimizer = torch.optim.Adam(self.params, lr=config.lr, fused=True)  # as PPO's
        self.target_agents = copy.deepcopy(self.learn_agents).requires_grad_(False)
        self.target_mixer = copy.deepcopy(self.learn_mixer).requires_grad_(False)
        env.reset()
        self.buffer = EpisodeBuffer(
            config.buffer_episodes,
            env.task.horizon,
            env.max_robots,
            env.single_observation_space.shape[0],
            env.state().shape[-1],
        )
        self.reward_stats = _RunningStats()
        self.rng = np.random.default_rng(seed)
        self.env_steps = 0
        self.learner_steps = 0
        self._update_credit = 0.0

    def epsilon(self) -> float:
        c = self.config
        frac = min(1.0, self.env_steps / max(1, c.epsilon_anneal_steps))
        return c.epsilon_start + frac * (c.epsilon_finish - c.epsilon_start)

    # -- acting ---------------------------------------------------------------------------------
    @torch.no_grad()
    def act(self, obs: np.ndarray, mask: np.ndarray, epsilon: float) -> np.ndarray:
        """ε-greedy actions (B, N) from Q (greedy when ``epsilon`` is 0)."""
        q = self.agents(torch.as_tensor(obs, dtype=torch.float32), torch.as_tensor(mask))
        actions = q.argmax(-1).numpy()
        if epsilon > 0:
            explore = self.rng.random(actions.shape) < epsilon
            actions = np.where(explore, self.rng.integers(0, q.shape[-1], actions.shape), actions)
        return np.where(mask, actions, 0)

    # -- 1-2. collect and store ---------------------------------------------------------------------
    def collect(self) -> list[dict]:
        """One round: stores one episode per environment; returns their metrics."""
        env, T, B = self.env, self.env.task.horizon, self.env.num_envs
        obs, info = env.reset()
        mask = start_mask = info["agent_mask"]
        state = env.state()
        traj = {k: [] for k in ("obs", "state", "actions", "rewards", "terminated")}
        ended = np.full(B, -1)  # step at which each env's first episode ended
        final_obs, final_state = np.zeros_like(obs), np.zeros_like(state)
        episodes: list[dict] = [{} for _ in range(B)]
        eps = self.epsilon()
        for t in range(T):
            actions = self.act(obs, mask, eps)
            next_obs, rewards, terminated, truncated, info = env.step(actions)
            stops = terminated | truncated if self.config.horizon_terminal else terminated
            for k, v in (
                ("obs", obs),
                ("state", state),
                ("actions", actions),
                ("rewards", rewards),
                ("terminated", stops),
            ):
                traj[k].append(v)
            done = (terminated | truncated) & (ended < 0)
            for b in np.flatnonzero(done):
                ended[b] = t
                final_obs[b], final_state[b] = info["final_obs"][b], info["final_state"][b]
                episodes[b] = {k: float(v[b]) for k, v in info["episode"].items()}
            if (ended >= 0).all():
                break
            obs, mask, state = next_obs, info["agent_mask"], env.state()
        stacked = {k: np.stack(v, 1) for k, v in traj.items()}  # (B, t, ...)
        for b in range(B):
            L = ended[b] + 1
            self.buffer.add(
                {
                    "obs": np.concatenate([stacked["obs"][b, :L], final_obs[b][None]]),
                    "state": np.concatenate([stacked["state"][b, :L], final_state[b][None]]),
                    "mask": start_mask[b],
                    "actions": stacked["actions"][b, :L],
                    "rewards": stacked["rewards"][b, :L],
                    "terminated": stacked["terminated"][b, :L],
                }
            )
            self.reward_stats.update(stacked["rewards"][b, :L])
            self.env_steps += int(L)
        self._update_credit += B * self.config.updates_per_episode
        return episodes

    # -- 3. learn --------------------------------------------------------------------------------
    def _q_tot_target(self, obs, mask, state):
        """Double-Q value of the next states: (E, T)."""
        E, T1, N, D = obs.shape
        o, m = obs.reshape(E * T1, N, D), mask[:, None].expand(E, T1, N).reshape(E * T1, N)
        greedy = self.learn_agents(o, m).argmax(-1, keepdim=True)
        q_target = self.target_agents(o, m).gather(-1, greedy)[..., 0]
        return self.target_mixer(q_target, m, state.reshape(E * T1, -1)).reshape(E, T1)

    def reward_standardization(self) -> tuple[float, float]:
        """(mean, std) that :meth:`learner_rewards` applies: the running statistics when
        ``standardize_rewards``, else (0, 1)."""
        if not self.config.standardize_rewards:
            return 0.0, 1.0
        return float(self.reward_stats.mean), float(np.sqrt(max(self.reward_stats.var, 1e-8)))

    def learner_rewards(self, rewards):
        """Rewards in the units the TD targets use (standardized by the running statistics when
        ``standardize_rewards``)."""
        if not self.config.standardize_rewards:
            return rewards
        mean, std = self.reward_standardization()
        return (rewards - mean) / std

    def learn_step(self) -> dict[str, float]:
        cfg = self.config
        batch = {k: v.to(self.device or "cpu") for k, v in self.buffer.sample(cfg.batch_episodes, self.rng).items()}
        obs, state, mask = batch["obs"], batch["state"], batch["mask"]
        E, T1, N, D = obs.shape
        T = T1 - 1
        rewards = self.learner_rewards(batch["rewards"])
        filled = batch["filled"].to(torch.float32)
        with torch.no_grad():
            next_q = self._q_tot_target(obs, mask, state)[:, 1:]
            y = rewards + cfg.gamma * (~batch["terminated"]).to(torch.float32) * next_q
        m = mask[:, None].expand(E, T, N).reshape(E * T, N)
        q = self.learn_agents(obs[:, :T].reshape(E * T, N, D), m)
        q_taken = q.gather(-1, batch["actions"].reshape(E * T, N, 1))[..., 0]
        q_tot = self.learn_mixer(q_taken, m, state[:, :T].reshape(E * T, -1)).reshape(E, T)
        loss = (F.mse_loss(q_tot, y, reduction="none") * filled).sum() / filled.sum()
        self.optimizer.zero_grad(set_to_none=True)
        loss.backward()
        grad_norm = torch.nn.utils.clip_grad_norm_(self.params, cfg.max_grad_norm)
        self.optimizer.step()
        self.learner_steps += 1
        if self.learner_steps % cfg.target_update_interval == 0:
            self.target_agents.load_state_dict(self.learn_agents.state_dict())
            self.target_mixer.load_state_dict(self.learn_mixer.state_dict())
        if self.device is not None:  # the next rollout acts with these weights
            self.agents.load_state_dict(self.learn_agents.state_dict())
            self.mixer.load_state_dict(self.learn_mixer.state_dict())
        return {
            "td_loss": loss.item(),
            "grad_norm": float(grad_norm),
            "q_taken": float((q_tot.detach() * filled).sum() / filled.sum()),
        }

    def update(self) -> dict[str, float]:
        """The learner steps owed for the episodes collected so far."""
        stats: dict[str, list[float]] = {"td_loss": [], "grad_norm": [], "q_taken": []}
        if self.buffer.size < self.config.batch_episodes:  # learning has not started
            self._update_credit = 0.0
        while self._update_credit >= 1.0:
            self._update_credit -= 1.0
            for k, v in self.learn_step().items():
                stats[k].append(v)
        means = {k: float(np.mean(v)) if v else float("nan") for k, v in stats.items()}
        return {"epsilon": self.epsilon(), "learner_steps": float(self.learner_steps), **means}

    # -- checkpoint state -------------------------------------------------------------------------
    def state_dict(self) -> dict:
        return {
            "agents": self.agents.state_dict(),
            "mixer": self.mixer.state_dict(),
            "target_agents": to_cpu(self.target_agents.state_dict()),
            "target_mixer": to_cpu(self.target_mixer.state_dict()),
            "optimizer": to_cpu(self.optimizer.state_dict()),
            "buffer": self.buffer.state_dict(),
            "reward_stats": vars(self.reward_stats).copy(),
            "rng": self.rng.bit_generator.state,
            "env_steps": self.env_steps,
            "learner_steps": self.learner_steps,
            "update_credit": self._update_credit,
        }

    def load_state_dict(self, state: dict) -> None:
        for module in {id(m): m for m in (self.agents, self.learn_agents)}.values():
            module.load_state_dict(state["agents"])
        for module in {id(m): m for m in (self.mixer, self.learn_mixer)}.values():
            module.load_state_dict(state["mixer"])
        self.target_agents.load_state_dict(state["target_agents"])
        self.target_mixer.load_state_dict(state["target_mixer"])
        self.optimizer.load_state_dict(state["optimizer"])
        self.buffer.load_state_dict(state["buffer"])
        vars(self.reward_stats).update(state["reward_stats"])
        self.rng.bit_generator.state = state["rng"]
        self.env_steps, self.learner_steps = state["env_steps"], state["learner_steps"]
        self._update_credit = state["update_credit"]
