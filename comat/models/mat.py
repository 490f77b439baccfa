"""Vanilla MAT (Wen et al. 2022) as the paper ran it: MLP observation encoder, transformer
encoder/decoder, one shared action head.

Encoder: per-robot LN → Linear → GELU, LN, then post-LN blocks [self-attention over the team
(padded robots masked out as keys), MLP]; value head Linear → GELU → LN → Linear per robot.
Decoder blocks: causal self-attention over action tokens; causal attention with queries from
the encoder output and keys/values from the action stream (MAT's orientation), residual on the
encoder output; MLP. One head for every robot (type and capabilities only enter through the
observation). Fixed-size baseline: like the paper, it is trained on teams of at most
``max_robots`` (8) — a larger team raises — though masks are built per forward pass.

Shapes: obs (B, N, D_obs), mask (B, N); E embedding; A = 5 actions.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import nn

from comat.config import check_numbers
from comat.models.act_kernels import mat_decode
from comat.models.autoregressive import AutoregressivePolicy, numpy_view
from comat.models.features import ObsLayout
from comat.models.layers import Attention, KVCache, causal, init_linear, mlp

__all__ = ["Mat", "MatConfig", "build"]


@dataclass(frozen=True)
class MatConfig:
    """MAT sizes (the reference defaults: 1 block, 64 wide, 1 head)."""

    embed: int = 64
    heads: int = 1
    blocks: int = 1
    max_robots: int = 8
    """Largest team (the paper trains fixed-size baselines with at most eight robots)."""

    def __post_init__(self) -> None:
        check_numbers(self, "models.mat", at_least_one=("embed", "heads", "blocks", "max_robots"))
        if self.embed % self.heads:
            raise ValueError(
                f"models.mat.embed must be divisible by models.mat.heads, got embed {self.embed}, heads {self.heads}"
            )


class _EncodeBlock(nn.Module):
    def __init__(self, E: int, heads: int) -> None:
        super().__init__()
        self.attn = Attention(E, heads)
        self.ln1, self.ln2 = nn.LayerNorm(E), nn.LayerNorm(E)
        self.mlp = mlp([E, E, E], act=nn.GELU)

    def forward(self, x, key_mask):
        x = self.ln1(x + self.attn(x, x, x, key_mask))
        return self.ln2(x + self.mlp(x))


class _DecodeBlock(nn.Module):
    def __init__(self, E: int, heads: int) -> None:
        super().__init__()
        self.self_attn, self.cross_attn = Attention(E, heads), Attention(E, heads)
        self.ln1, self.ln2, self.ln3 = nn.LayerNorm(E), nn.LayerNorm(E), nn.LayerNorm(E)
        self.mlp = mlp([E, E, E], act=nn.GELU)

    def forward(self, x, rep, mask):
        x = self.ln1(x + self.self_attn(x, x, x, mask))
        x = self.ln2(rep + self.cross_attn(rep, x, x, mask))
        return self.ln3(x + self.mlp(x))

    def step(self, x, rep_m, caches):
        self_cache, cross_cache = caches
        x = self.ln1(x + self.self_attn.step(self.self_attn.step_query(x), x, x, self_cache))
        x = self.ln2(rep_m + self.cross_attn.step(self.cross_attn.step_query(rep_m), x, x, cross_cache))
        return self.ln3(x + self.mlp(x))


class Mat(AutoregressivePolicy):
    """MAT policy for a task's observation layout (see module docstring)."""

    def __init__(self, layout: ObsLayout, config: MatConfig | None = None) -> None:
        super().__init__()
        cfg = config or MatConfig()
        self.layout, self.config = layout, cfg
        E = cfg.embed
        self.obs_encoder = nn.Sequential(
            nn.LayerNorm(layout.obs_dim), init_linear(nn.Linear(layout.obs_dim, E)), nn.GELU()
        )
        self.enc_ln = nn.LayerNorm(E)
        self.encoder = nn.ModuleList(_EncodeBlock(E, cfg.heads) for _ in range(cfg.blocks))
        self.value_head = nn.Sequential(
            init_linear(nn.Linear(E, E)), nn.GELU(), nn.LayerNorm(E), init_linear(nn.Linear(E, 1))
        )
        self.action_encoder = nn.Sequential(init_linear(nn.Linear(self.n_actions + 1, E, bias=False)), nn.GELU())
        self.dec_ln = nn.LayerNorm(E)
        self.decoder = nn.ModuleList(_DecodeBlock(E, cfg.heads) for _ in range(cfg.blocks))
        self.head = nn.Sequential(
            init_linear(nn.Linear(E, E)), nn.GELU(), nn.LayerNorm(E), init_linear(nn.Linear(E, self.n_actions), 0.01)
        )

    def _check(self, mask: torch.Tensor) -> None:
        if mask.shape[1] > self.config.max_robots and bool(mask[:, self.config.max_robots :].any()):
            raise ValueError(
                f"MAT is a fixed-size baseline for teams of at most {self.config.max_robots} robots, "
                f"got a team of {int(mask.sum(1).max())}"
            )

    def encode(self, obs, mask):
        self._check(mask)
        x = self.enc_ln(self.obs_encoder(obs))
        key_mask = (mask[:, None, :]).expand(-1, obs.shape[1], -1)
        for block in self.encoder:
            x = block(x, key_mask)
        return x, self.value_head(x)[..., 0]

    def decode_all(self, rep, tokens, obs, mask):
        m = causal(tokens.shape[1], tokens.device)[None]
        x = self.dec_ln(self.action_encoder(tokens))
        for block in self.decoder:
            x = block(x, rep, m)
        return self.head(x)

    def decode_init(self, rep, obs):
        # The embedded token depends on the token alone: tabulated once per sequence.
        table = self.dec_ln(self.action_encoder(torch.eye(self.n_actions + 1, device=rep.device)))[:, None]
        return rep, table, [(KVCache(), KVCache()) for _ in self.decoder]

    @torch.no_grad()
    def decode_compiled(self, rep, obs, mask, noise):
        linears = [self.action_encoder[0]]
        vecs = [self.dec_ln.weight, self.dec_ln.bias]
        for block in self.decoder:
            sa, ca = block.self_attn, block.cross_attn
            block_linears = (sa.q, sa.kv, sa.o, ca.q, ca.kv, ca.o, block.mlp[0], block.mlp[2])
            linears += block_linears
            vecs += [layer.bias for layer in block_linears]
            vecs += [p for ln in (block.ln1, block.ln2, block.ln3) for p in (ln.weight, ln.bias)]
        linears += [self.head[0], self.head[3]]
        vecs += [self.head[0].bias, self.head[3].bias, self.head[2].weight, self.head[2].bias]
        noise_np, mask_np = self._compiled_inputs(noise, mask)
        actions, logits = mat_decode(
            tuple(numpy_view(layer.weight) for layer in linears),
            tuple(numpy_view(p) for p in vecs),
            numpy_view(rep),
            mask_np,
            noise_np,
            noise is None,
            self.config.heads,
        )
        return torch.from_numpy(actions), torch.from_numpy(logits)

    def decode_step(self, state, m: int, token):
        rep, table, caches = state
        x = table[token]  # (B, 1, E)
        for block, block_caches in zip(self.decoder, caches):
            x = block.step(x, rep[:, m : m + 1], block_caches)
        return self.head(x)[:, 0]


def build(dims, config: MatConfig, acting_only: bool = False) -> dict[str, nn.Module]:
    """MAT's network (learner ``mat``, :mod:`comat.learners`): acting needs all of it (its value
    head shares the encoder the actions are decoded from)."""
    return {"policy": Mat(dims.layout, config)}
