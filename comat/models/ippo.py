"""IPPO: independent PPO, each robot learning from what it observes alone.

What the robots share is only what a team whose size and make-up change every episode forces: the
parameters of one robot type (a new robot of a type takes its type's networks; a per-robot network
could not follow a robot that exists for one episode). Nothing else: no centralized critic, no
global state, no attention to the others. Actor: one MLP per robot type on the robot's own
observation (its type and capability vector included), as MAPPO's actors. Critic: one MLP per robot
type on the same observation, one value per robot. With no state the team size has no limit:
IPPO plays every set, U_scale's 20 robots included, with no slot setting.

Heterogeneous-MARL benchmarks (HeMAC, ECAI 2025) find independent learners ahead of MAPPO as
heterogeneity grows: the comparison reviewers ask for (issue 50).

Shapes: obs (B, N, D_obs), mask (B, N); A = 5 actions.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import nn

from comat.config import check_numbers
from comat.models.features import ObsLayout
from comat.models.layers import TypeHeads, choose_actions, score_actions

__all__ = ["Ippo", "IppoConfig", "build"]


@dataclass(frozen=True)
class IppoConfig:
    hidden: int = 128
    """Hidden width of each type's actor and critic."""

    def __post_init__(self) -> None:
        check_numbers(self, "models.ippo", at_least_one=("hidden",))


class Ippo(nn.Module):
    """Type-shared actors and type-shared local critics (see module docstring)."""

    n_actions = 5

    def __init__(self, layout: ObsLayout, config: IppoConfig | None = None, critic: bool = True) -> None:
        super().__init__()
        cfg = config or IppoConfig()
        self.layout, self.config = layout, cfg
        self.actor = TypeHeads(layout.obs_dim, cfg.hidden, self.n_actions, layout.n_types)
        # Without the critic (a policy file's IPPO) the module acts but cannot be trained or probed.
        self.critic = TypeHeads(layout.obs_dim, cfg.hidden, 1, layout.n_types, out_gain=1.0) if critic else None

    def _types(self, obs: torch.Tensor) -> torch.Tensor:
        return obs[..., 4 : 4 + self.layout.n_types]

    def values(self, obs, mask, state=None):
        """Each robot's value (B, N) from its own observation; ``state`` is not read."""
        if self.critic is None:
            raise ValueError(
                "this IPPO has no critic (loaded from a policy file, which keeps the actors only): "
                "its values need the run's checkpoint.pt"
            )
        return self.critic(obs, self._types(obs))[..., 0] * mask

    def act(self, obs, mask, state=None, deterministic: bool = False, generator: torch.Generator | None = None):
        """Actions (B, N), their log-probabilities (B, N) and values (B, N) — None for a module
        without a critic."""
        logits = self.actor(obs, self._types(obs))
        a, logp = choose_actions(logits, mask, deterministic, generator)
        return a, logp, None if self.critic is None else self.values(obs, mask)

    def evaluate_actions(self, obs, mask, actions, state=None):
        logp, entropy = score_actions(self.actor(obs, self._types(obs)), actions, mask)
        return logp, entropy, self.values(obs, mask)


def build(dims, config: IppoConfig, acting_only: bool = False) -> dict[str, nn.Module]:
    """IPPO's networks (learner ``ippo``, :mod:`comat.learners`): the actors alone where ``acting_only``."""
    return {"policy": Ippo(dims.layout, config, critic=not acting_only)}
