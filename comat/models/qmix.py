"""QMIX as the paper ran it: agent Q-networks shared within each robot type, a monotonic mixer.

Agent network: one MLP per robot type on the robot's observation (type and capabilities
included) → Q(o, ·) over the 5 actions. Mixer (Rashid et al. 2018): hypernetworks on the global
state give non-negative weights, so Q_tot is monotonic in every robot's Q:

    hidden = ELU(q · |W1(s)| + b1(s)),   Q_tot = hidden · |W2(s)| + V(s)

Fixed-size baseline: the mixer takes ``max_robots`` (8) slots; padded (dead) slots enter with
Q = 0 and never affect the update. Shapes: obs (B, N, D_obs), mask (B, N), state (B, S).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
import torch.nn.functional as F
from torch import nn

from comat.config import check_numbers
from comat.models.features import ObsLayout
from comat.models.layers import TypeHeads, mlp

__all__ = ["QmixAgents", "QmixMixer", "QmixNetConfig", "build"]


@dataclass(frozen=True)
class QmixNetConfig:
    hidden: int = 64
    """Agent network width."""
    mixing_embed: int = 32
    """Mixer hidden width."""
    hypernet_embed: int = 64
    """Hypernetwork hidden width."""
    max_robots: int = 8
    """Mixer slots (the paper trains fixed-size baselines with at most eight robots)."""

    def __post_init__(self) -> None:
        check_numbers(self, "models.qmix", at_least_one=("hidden", "mixing_embed", "hypernet_embed", "max_robots"))


class QmixAgents(nn.Module):
    """Per-type agent Q-networks: Q (B, N, A); padded slots 0."""

    n_actions = 5

    def __init__(self, layout: ObsLayout, config: QmixNetConfig | None = None) -> None:
        super().__init__()
        cfg = config or QmixNetConfig()
        self.layout, self.config = layout, cfg
        self.net = TypeHeads(layout.obs_dim, cfg.hidden, self.n_actions, layout.n_types, out_gain=1.0)

    def forward(self, obs, mask):
        return self.net(obs, obs[..., 4 : 4 + self.layout.n_types]) * mask[..., None]


class QmixMixer(nn.Module):
    """Monotonic mixing of per-robot Q-values (B, N <= max_robots) into Q_tot (B,)."""

    def __init__(self, state_dim: int, config: QmixNetConfig | None = None) -> None:
        super().__init__()
        cfg = config or QmixNetConfig()
        self.config = cfg
        M, H = cfg.max_robots, cfg.mixing_embed
        self.w1 = mlp([state_dim, cfg.hypernet_embed, M * H])
        self.b1 = nn.Linear(state_dim, H)
        self.w2 = mlp([state_dim, cfg.hypernet_embed, H])
        self.v = mlp([state_dim, H, 1])

    def forward(self, q: torch.Tensor, mask: torch.Tensor, state: torch.Tensor) -> torch.Tensor:
        B, N = q.shape
        M, H = self.config.max_robots, self.config.mixing_embed
        if N > M and bool(mask[:, M:].any()):
            raise ValueError(f"QMIX's mixer has {M} robot slots, got a team of {int(mask.sum(1).max())}")
        qs = torch.zeros(B, M, device=q.device, dtype=q.dtype)
        n = min(N, M)
        qs[:, :n] = (q * mask)[:, :n]
        w1 = self.w1(state).abs().view(B, M, H)
        hidden = F.elu(torch.einsum("bm,bmh->bh", qs, w1) + self.b1(state))
        return (hidden * self.w2(state).abs()).sum(-1) + self.v(state)[:, 0]


def build(dims, config: QmixNetConfig, acting_only: bool = False) -> dict[str, nn.Module]:
    """QMIX's networks (learner ``qmix``, :mod:`comat.learners`): the agent Q-networks, and the
    mixer on the state of ``dims.state_dim`` unless ``acting_only``."""
    agents = {"agents": QmixAgents(dims.layout, config)}
    return agents if acting_only else {**agents, "mixer": QmixMixer(dims.state_dim, config)}
