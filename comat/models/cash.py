"""CASH (``--algo cash``): capability-aware shared hypernetworks (Fu et al., CoRL 2025, arXiv
2501.06058), built as the authors' code builds its policy-gradient actor, for teams of any size.

| part | reads (B, N, ·) | is | gives |
|---|---|---|---|
| encoder | observation without type and capabilities: D − T − C | Linear(H) ReLU Linear(H) ReLU | h (B, N, H) |
| weight hypernetwork | observation ‖ team summary: D + 2C | (L − 1)×[Linear(K) LN ReLU], Linear(H²) | W (B, N, H, H) |
| bias hypernetwork | the same | a twin of it, Linear(H) last | b (B, N, H) |
| generated layer | h | ReLU(h W + b): each robot's own, new every step | (B, N, H) |
| shared output layer | that | Linear(A), gain 0.01 | scores (B, N, A) |
| critic | own observation ‖ team's mean and max observation: 3D | 3 × [Linear(H) ReLU], Linear(1) | values (B, N) |

H = ``hidden`` (128), K = ``hyper_hidden`` (16), L = ``hyper_layers`` (4), LN LayerNorm, A = 5 actions; D, T, C
the task's observation size, robot types and capabilities (:class:`comat.models.features.ObsLayout`).
The team summary is the mean and the maximum of each capability over the team's robots, padded
slots left out (:func:`comat.models.cash_caps.team_summary`). Everything a robot is (its type and
capabilities) reaches the actor only through the hypernetworks, so robots share every weight and
still act each by its own generated layer; no weight is sized by the team (2–20 robots play).

What follows the authors' code (GT-STAR-Lab/CASH, read 2026-12: ``baselines/MAPPO/mappo_rnn_mpe.py``,
``ActorHyperRNN`` and ``CriticRNN``; ``jaxmarl/policies/policies.py``, ``HyperNetwork``;
``baselines/MAPPO/config/mappo_homogenous_rnn_mpe.yaml``; the observation of
``jaxmarl/environments/mpe/simple_fire.py``):

* the hypernetworks read the robot's whole local observation, capabilities included (CASH's
  ``hyper_in`` is the observation its env builds with the robot's own and its teammates'
  capabilities last), so the generated layer changes every step with the context;
* the encoder reads that observation with the capabilities cut off;
* the hypernetworks generate a hidden H × H layer and its biases, followed by ReLU and a shared
  output layer with orthogonal gain 0.01 and zero bias (the actor of CASH's MAPPO; a generated
  H × A head is its DAgger/QMIX variant);
* weights and biases come from two separate hypernetworks, each L = 4 layers of width K = 16 with
  LayerNorm (ε 1e-6, Flax's) before every ReLU; every linear layer of the weight network starts
  orthogonal with gain 0.2 (CASH's ``INIT_SCALE``, "MUST TUNE"), zero bias; the bias network starts
  at gain 0 (all zero), as in the code. A consequence the code has as well: a bias network that is
  zero everywhere passes no gradient to any of its layers but its last bias, so the generated
  biases stay one learned vector shared by every robot (``tests/test_cash.py`` keeps it so);
* the encoder's first layer orthogonal with gain √2, zero bias; H = 128.

Where it departs, and why:

* **the team's capabilities as their mean and maximum** (appended to the hypernetworks' input):
  CASH's observation holds each teammate's capabilities for a fixed team (3–4 robots); comat's
  observation has no teammates' capabilities and its teams have 2–20 robots, so an order-free
  summary is the smallest change that takes any size;
* **the type one-hot** goes to the hypernetworks with the capabilities (CASH's environments have no
  types): it is part of what a comat robot observes, some tasks' rules depend on it (arctic's
  scouts), and in navigation and sensors the types' capability ranges overlap; like the
  capabilities it stays out of the encoder;
* **an MLP where CASH has a GRU** (the encoder's second layer; the critic's): comat's learners are
  feed-forward, so comparisons between them stay ones of architecture;
* **the critic reads a pooled world state**: CASH's MAPPO critic reads every agent's observation
  concatenated (sized by the team) and gives one value for the team; here each robot's critic reads
  its own observation with the team's mean and maximum observation (padded slots left out), one
  value per robot as comat's PPO wants (comat's MAPPO critic also adds the robot's own observation);
  its layers keep CASH's gains (√2, then 2 after the recurrent layer's place, then 1);
* **the trainer** is comat's PPO with the settings every PPO learner shares (``ppo:`` of the
  presets; ``docs/learners.md`` lists them beside CASH's own).

Version history (``CashConfig.version``): 2 — this module (issue 65). 1 — comat's first CASH
(issue 50), now ``--algo cash-caps`` (:mod:`comat.models.cash_caps`); checkpoints, policy files and
run folders stored as ``cash`` before version 2 existed load and evaluate as ``cash-caps``
(``comat.rl.checkpoint.RENAMED``).

Shapes: obs (B, N, D), mask (B, N) True for real robots; actions, log-probabilities, values (B, N).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
from torch import nn

from comat.config import check_numbers
from comat.models.cash_caps import team_summary
from comat.models.features import ObsLayout
from comat.models.layers import choose_actions, init_linear, mlp, score_actions

__all__ = ["VERSION", "Cash", "CashConfig", "build"]

VERSION = 2
"""The CASH this module builds: 2, the authors' code (issue 65). Files stored before it hold
version 1, the learner now named ``cash-caps`` (:mod:`comat.models.cash_caps`)."""
LAYER_NORM_EPS = 1e-6
"""ε of the hypernetworks' LayerNorm: Flax's default, which CASH's code uses (torch's is 1e-5)."""


@dataclass(frozen=True)
class CashConfig:
    hidden: int = 128
    """H: width of the encoder, the generated hidden layer and the critic (CASH's ``GRU_HIDDEN_DIM``)."""
    hyper_hidden: int = 16
    """K: width of each hypernetwork's hidden layers (CASH's ``HIDDEN_DIM``)."""
    hyper_layers: int = 4
    """L: linear layers per hypernetwork, its output layer included (CASH's ``NUM_LAYERS``)."""
    hyper_init: float = 0.2
    """Orthogonal gain of every linear layer of the weight hypernetwork (CASH's ``INIT_SCALE``)."""
    version: int = VERSION
    """Which CASH: 2 (this module). Version 1, comat's first CASH, is ``--algo cash-caps``."""

    def __post_init__(self) -> None:
        check_numbers(self, "models.cash", at_least_one=("hidden", "hyper_hidden", "hyper_layers"))
        check_numbers(self, "models.cash", non_negative=("hyper_init",))
        if self.version != VERSION:
            raise ValueError(
                f"models.cash.version must be {VERSION} (the CASH of the authors' code), got {self.version!r}; "
                "version 1, comat's first CASH, is --algo cash-caps"
            )


def hypernetwork(in_dim: int, width: int, out_dim: int, layers: int, gain: float) -> nn.Sequential:
    """CASH's hypernetwork: (layers − 1) × [Linear(width) LayerNorm ReLU], then Linear(out_dim);
    every linear layer orthogonal with ``gain``, zero bias."""
    parts: list[nn.Module] = []
    for k in range(layers - 1):
        parts += [
            init_linear(nn.Linear(in_dim if k == 0 else width, width), gain),
            nn.LayerNorm(width, eps=LAYER_NORM_EPS),
            nn.ReLU(),
        ]
    parts.append(init_linear(nn.Linear(width if layers > 1 else in_dim, out_dim), gain))
    return nn.Sequential(*parts)


class Cash(nn.Module):
    """Shared encoder, a hidden layer generated per robot by two hypernetworks, a shared output
    layer; a pooled-state critic (see the module)."""

    n_actions = 5

    def __init__(self, layout: ObsLayout, config: CashConfig | None = None, critic: bool = True) -> None:
        super().__init__()
        cfg = config or CashConfig()
        self.layout, self.config = layout, cfg
        H, C, D, A = cfg.hidden, layout.n_caps, layout.obs_dim, self.n_actions
        self._identity = slice(4, 4 + layout.n_types + C)  # type one-hot and capabilities
        self.encoder = nn.Sequential(mlp([D - layout.n_types - C, H, H]), nn.ReLU())
        hyper_in = D + 2 * C
        self.weight_net = hypernetwork(hyper_in, cfg.hyper_hidden, H * H, cfg.hyper_layers, cfg.hyper_init)
        self.bias_net = hypernetwork(hyper_in, cfg.hyper_hidden, H, cfg.hyper_layers, 0.0)
        self.head = init_linear(nn.Linear(H, A), 0.01)
        if critic:
            self.critic = nn.Sequential(
                init_linear(nn.Linear(3 * D, H), math.sqrt(2)),
                nn.ReLU(),
                init_linear(nn.Linear(H, H), math.sqrt(2)),
                nn.ReLU(),
                init_linear(nn.Linear(H, H), 2.0),
                nn.ReLU(),
                init_linear(nn.Linear(H, 1), 1.0),
            )
        else:
            self.critic = None

    def _hyper_input(self, obs: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        return torch.cat([obs, team_summary(self.layout.capabilities(obs), mask)], -1)

    def _encode(self, obs: torch.Tensor) -> torch.Tensor:
        return self.encoder(torch.cat([obs[..., : self._identity.start], obs[..., self._identity.stop :]], -1))

    def generated_layer(self, obs: torch.Tensor, mask: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Each robot's generated hidden layer: weights (B, N, H, H) (input, output) and biases (B, N, H)."""
        x = self._hyper_input(obs, mask)
        H = self.config.hidden
        return self.weight_net(x).unflatten(-1, (H, H)), self.bias_net(x)

    def _hidden(self, obs: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """ReLU(h W + b) (B, N, H) without building W: W's last hypernetwork layer is linear in its
        input z (K), so h W = (h ⊗ z) L + h W₀ with L the last layer's weights as (H·K, H) and W₀ its
        bias as (H, H). The same numbers as :meth:`generated_layer` (within rounding) with one
        (B·N, H·K) × (H·K, H) product instead of a (B, N, H, H) tensor: 8× less memory at K = 16,
        which a 20-robot minibatch of the update feels."""
        x = self._hyper_input(obs, mask)
        h = self._encode(obs)  # (B, N, H)
        H = self.config.hidden
        z = self.weight_net[:-1](x)  # (B, N, K)
        last = self.weight_net[-1]
        K = z.shape[-1]
        L = last.weight.view(H, H, K).transpose(1, 2).reshape(H * K, H)  # [j·K + m, k] = weight[j·H + k, m]
        outer = (h[..., :, None] * z[..., None, :]).flatten(-2)  # (B, N, H·K)
        pre = outer @ L + h @ last.bias.view(H, H) + self.bias_net(x)
        return torch.relu(pre)

    def _logits(self, obs: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        return self.head(self._hidden(obs, mask))

    def values(self, obs, mask, state=None):
        """Each robot's value (B, N) from its observation and the team's pooled observation."""
        if self.critic is None:
            raise ValueError(
                "this CASH has no critic (loaded from a policy file, which keeps the actor only): "
                "its values need the run's checkpoint.pt"
            )
        pooled = team_summary(obs, mask)  # (B, N, 2D): the team's mean and max observation, any size
        return self.critic(torch.cat([obs, pooled], -1))[..., 0] * mask

    def act(self, obs, mask, state=None, deterministic: bool = False, generator: torch.Generator | None = None):
        """Actions (B, N), their log-probabilities (B, N) and values (B, N) — None for a module
        without a critic."""
        a, logp = choose_actions(self._logits(obs, mask), mask, deterministic, generator)
        return a, logp, None if self.critic is None else self.values(obs, mask)

    def evaluate_actions(self, obs, mask, actions, state=None):
        logp, entropy = score_actions(self._logits(obs, mask), actions, mask)
        return logp, entropy, self.values(obs, mask)


def build(dims, config: CashConfig, acting_only: bool = False) -> dict[str, nn.Module]:
    """CASH's networks (learner ``cash``, :mod:`comat.learners`): encoder, hypernetworks and output
    layer, with the critic unless ``acting_only``."""
    return {"policy": Cash(dims.layout, config, critic=not acting_only)}
