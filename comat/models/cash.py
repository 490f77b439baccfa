"""CASH: a capability-aware shared hypernetwork policy (Fu et al., CoRL 2025), for teams of any size.

From the paper (arXiv 2501.06058): a *shared encoder* turns each robot's local observation into a
representation h_i (the team's common strategy); a *shared hypernetwork* reads the robot's own
capabilities and the team's, and generates the weights of an *adaptive decoder* that maps h_i to
the robot's action scores. Soft weight sharing: every robot runs the same networks, yet each gets
its own decoder from its capabilities, so unseen robots and unseen teams get decoders zero-shot.

What differs here, and why:

* **the team's capabilities as a summary** — the mean and the maximum of each capability over the
  team's robots (padded slots excluded): CASH's code fixes the team at four robots and concatenates
  their capabilities, which a team of 2–20 robots cannot; a permutation-invariant summary is the
  smallest change that takes any team size;
* **a critic** for this PPO harness (CASH's own runs pair the actor with MAPPO's centralized critic
  or QMIX's mixer, both sized by the team): an MLP on the robot's observation and the same team
  summary, one value per robot — nothing in CASH is sized by the team;
* the encoder is an MLP (CASH's recurrent encoder carries memory across steps; comat's learners are
  feed-forward, MAT's and MAPPO's included, so the comparison stays one of architecture).

Shapes: obs (B, N, D_obs), mask (B, N); C capabilities; H hidden; A = 5 actions.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import nn

from comat.config import check_numbers
from comat.models.features import ObsLayout
from comat.models.layers import choose_actions, mlp, score_actions

__all__ = ["Cash", "CashConfig"]


@dataclass(frozen=True)
class CashConfig:
    hidden: int = 64
    """Width of the shared encoder's output h_i and of the critic."""
    hyper_hidden: int = 64
    """Hidden width of the hypernetwork."""

    def __post_init__(self) -> None:
        check_numbers(self, "models.cash", at_least_one=("hidden", "hyper_hidden"))


def team_summary(caps: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """(B, N, 2C): every robot's view of its team's capabilities — their mean and maximum over the
    team's robots (padded slots excluded), the same for all robots of a team."""
    m = mask[..., None].to(caps.dtype)
    count = m.sum(1, keepdim=True).clamp(min=1.0)
    mean = (caps * m).sum(1, keepdim=True) / count
    top = torch.where(mask[..., None], caps, torch.finfo(caps.dtype).min).amax(1, keepdim=True)
    top = torch.where(mask.any(1)[:, None, None], top, 0.0)  # an empty team: 0, not -inf
    return torch.cat([mean, top], -1).expand(-1, caps.shape[1], -1)


class Cash(nn.Module):
    """Shared encoder, capability hypernetwork, generated decoder; a local critic (see the module)."""

    n_actions = 5

    def __init__(self, layout: ObsLayout, config: CashConfig | None = None, critic: bool = True) -> None:
        super().__init__()
        cfg = config or CashConfig()
        self.layout, self.config = layout, cfg
        H, C, A = cfg.hidden, layout.n_caps, self.n_actions
        self.encoder = nn.Sequential(mlp([layout.obs_dim, H, H]), nn.ReLU())
        # [own capabilities ‖ team mean ‖ team max] -> the decoder's weights (H × A) and biases (A);
        # its output layer starts small, so every robot starts with nearly the same decoder.
        self.hyper = mlp([3 * C, cfg.hyper_hidden, H * A + A], out_gain=0.01)
        self.critic = mlp([layout.obs_dim + 2 * C, H, H, 1]) if critic else None

    def _logits(self, obs: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        caps = self.layout.capabilities(obs)
        team = team_summary(caps, mask)
        generated = self.hyper(torch.cat([caps, team], -1))  # (B, N, H·A + A)
        H, A = self.config.hidden, self.n_actions
        w, b = generated[..., : H * A].unflatten(-1, (H, A)), generated[..., H * A :]
        h = self.encoder(obs)  # (B, N, H)
        return (h[..., None, :] @ w)[..., 0, :] + b

    def values(self, obs, mask, state=None):
        """Each robot's value (B, N) from its observation and its team's capability summary."""
        if self.critic is None:
            raise ValueError(
                "this CASH has no critic (loaded from a policy file, which keeps the actor only): "
                "its values need the run's checkpoint.pt"
            )
        team = team_summary(self.layout.capabilities(obs), mask)
        return self.critic(torch.cat([obs, team], -1))[..., 0] * mask

    def act(self, obs, mask, state=None, deterministic: bool = False, generator: torch.Generator | None = None):
        """Actions (B, N), their log-probabilities (B, N) and values (B, N) — None for a module
        without a critic."""
        logits = self._logits(obs, mask)
        a, logp = choose_actions(logits, mask, deterministic, generator)
        return a, logp, None if self.critic is None else self.values(obs, mask)

    def evaluate_actions(self, obs, mask, actions, state=None):
        logp, entropy = score_actions(self._logits(obs, mask), actions, mask)
        return logp, entropy, self.values(obs, mask)
