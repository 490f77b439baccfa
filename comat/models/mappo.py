"""MAPPO as the paper ran it: actors shared within each robot type, a centralized critic.

Actor: one MLP per robot type (parameter sharing among robots of a type) on the robot's own
observation, which carries its type and capability vector. Critic: an MLP on the environment's
global state concatenated with the robot's observation, one value per robot. Fixed-size
baseline: the state covers ``state_robots`` (8) robots, so teams are at most that large.

Acting needs only the actors: ``Mappo(..., critic=False)`` is the policy a policy file holds
(:mod:`comat.rl.policy`), and ``act`` without a state returns no values.

Shapes: obs (B, N, D_obs), mask (B, N), state (B, S); A = 5 actions.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import nn

from comat.config import check_numbers
from comat.models.features import ObsLayout
from comat.models.layers import TypeHeads, choose_actions, mlp, score_actions

__all__ = ["Mappo", "MappoConfig", "build"]


@dataclass(frozen=True)
class MappoConfig:
    hidden: int = 128
    """Hidden width of the actors and the critic."""
    max_robots: int = 8
    """Robot slots of the environments, which the critic's global state covers too: the paper
    trains fixed-size baselines with at most eight robots; 20 lets them play U_scale."""

    def __post_init__(self) -> None:
        check_numbers(self, "models.mappo", at_least_one=("hidden", "max_robots"))


class Mappo(nn.Module):
    """Type-shared actors and a centralized critic (see module docstring)."""

    n_actions = 5

    def __init__(
        self, layout: ObsLayout, state_dim: int, config: MappoConfig | None = None, critic: bool = True
    ) -> None:
        super().__init__()
        cfg = config or MappoConfig()
        self.layout, self.config = layout, cfg
        self.actor = TypeHeads(layout.obs_dim, cfg.hidden, self.n_actions, layout.n_types)
        # Without the critic (a policy file's MAPPO) the module acts but cannot be trained or probed.
        self.critic = mlp([state_dim + layout.obs_dim, cfg.hidden, cfg.hidden, 1]) if critic else None

    def _logits(self, obs):
        return self.actor(obs, obs[..., 4 : 4 + self.layout.n_types])

    def values(self, obs, mask, state):
        if self.critic is None:
            raise ValueError(
                "this MAPPO has no critic (loaded from a policy file, which keeps the actors only): "
                "its values need the run's checkpoint.pt"
            )
        if state is None:
            raise ValueError("MAPPO's critic needs the global state (env.state())")
        s = state[:, None, :].expand(-1, obs.shape[1], -1)
        return self.critic(torch.cat([s, obs], -1))[..., 0] * mask

    def act(self, obs, mask, state=None, deterministic: bool = False, generator: torch.Generator | None = None):
        """Actions (B, N), their log-probabilities (B, N) and the critic's values (B, N) — None
        where acting alone is asked for: a module without a critic, or deterministic actions
        without a state (the actions depend on the actors only)."""
        logits = self._logits(obs)
        a, logp = choose_actions(logits, mask, deterministic, generator)
        acting_only = self.critic is None or (state is None and deterministic)
        return a, logp, None if acting_only else self.values(obs, mask, state)

    def evaluate_actions(self, obs, mask, actions, state=None):
        logp, entropy = score_actions(self._logits(obs), actions, mask)
        return logp, entropy, self.values(obs, mask, state)


def build(dims, config: MappoConfig, acting_only: bool = False) -> dict[str, nn.Module]:
    """MAPPO's networks (learner ``mappo``, :mod:`comat.learners`): the critic reads the state of
    ``dims.state_dim``; the actors alone where ``acting_only``."""
    return {"policy": Mappo(dims.layout, dims.state_dim, config, critic=not acting_only)}
