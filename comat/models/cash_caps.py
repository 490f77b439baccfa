"""CASH-caps (``--algo cash-caps``): comat's first CASH, a capability-conditioned decoder, kept so
that its runs keep their numbers. The code-faithful CASH is :mod:`comat.models.cash` (issue 65).

What it is: a *shared encoder* turns each robot's whole observation (type one-hot and capabilities
included) into h_i; a *hypernetwork* reads only capabilities — the robot's own, the team's mean and
the team's maximum — and generates the weights and biases of the robot's output layer (H × A),
which maps h_i to its action scores; a local critic reads the observation and the same team
summary. Trained and committed as ``cash`` before issue 65 (``results/new_learners/``); files
stored then load as this learner (``comat/rl/checkpoint.py``).

How it departs from the authors' code (GT-STAR-Lab/CASH; ``comat/models/cash.py`` follows it):
the hypernetwork reads capabilities only, so a robot's decoder is fixed for a whole episode, where
CASH's reads the local observation with the capabilities; the encoder reads the capabilities and
the type, where CASH's reads the observation without them; it generates the output layer, where
CASH's policy-gradient actor generates a hidden layer followed by a shared output layer; its
hypernetwork is one 2-layer MLP for weights and biases without LayerNorm, where CASH's has separate
weight and bias networks with LayerNorm and their own initialisation. Its encoder is an MLP (CASH's
is recurrent); its critic reads the robot's observation and the team summary (CASH's MAPPO critic
reads every agent's observation of a fixed team); the team's capabilities enter as their mean and
maximum over the team (CASH's code concatenates a fixed team's).

Shapes: obs (B, N, D_obs), mask (B, N); C capabilities; H hidden; A = 5 actions.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import nn

from comat.config import check_numbers
from comat.models.features import ObsLayout
from comat.models.layers import choose_actions, mlp, score_actions

__all__ = ["CashCaps", "CashCapsConfig", "build", "team_summary"]


@dataclass(frozen=True)
class CashCapsConfig:
    hidden: int = 64
    """Width of the shared encoder's output h_i and of the critic."""
    hyper_hidden: int = 64
    """Hidden width of the hypernetwork."""

    def __post_init__(self) -> None:
        check_numbers(self, "models.cash-caps", at_least_one=("hidden", "hyper_hidden"))


def team_summary(caps: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """(B, N, 2C): every robot's view of its team's capabilities — their mean and maximum over the
    team's robots (padded slots excluded), the same for all robots of a team. Any features
    (B, N, F) give (B, N, 2F) (:mod:`comat.models.cash` pools whole observations with it)."""
    m = mask[..., None].to(caps.dtype)
    count = m.sum(1, keepdim=True).clamp(min=1.0)
    mean = (caps * m).sum(1, keepdim=True) / count
    top = torch.where(mask[..., None], caps, torch.finfo(caps.dtype).min).amax(1, keepdim=True)
    top = torch.where(mask.any(1)[:, None, None], top, 0.0)  # an empty team: 0, not -inf
    return torch.cat([mean, top], -1).expand(-1, caps.shape[1], -1)


class CashCaps(nn.Module):
    """Shared encoder, capability hypernetwork, generated decoder; a local critic (see the module)."""

    n_actions = 5

    def __init__(self, layout: ObsLayout, config: CashCapsConfig | None = None, critic: bool = True) -> None:
        super().__init__()
        cfg = config or CashCapsConfig()
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
                "this CASH-caps has no critic (loaded from a policy file, which keeps the actor only): "
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


def build(dims, config: CashCapsConfig, acting_only: bool = False) -> dict[str, nn.Module]:
    """CASH-caps' networks (learner ``cash-caps``, :mod:`comat.learners`): encoder and hypernetwork,
    with the critic unless ``acting_only``."""
    return {"policy": CashCaps(dims.layout, config, critic=not acting_only)}
