"""Building blocks shared by the models: MLPs, attention with a key/value cache, masks.

Shapes: B batch, L/N sequence length (robots), D embedding, H heads. Boolean masks are True
where attention (or a robot) is allowed. Nothing here depends on the team size.
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from torch import nn

from comat.models.attention_kernels import causal_attention
from comat.models.comat_schema import DecisionMode, decision_shapes

__all__ = [
    "Attention",
    "KVCache",
    "TypeHeads",
    "causal",
    "choose_actions",
    "init_linear",
    "log_softmax_last",
    "mlp",
    "score_actions",
    "softmax_last",
]

SHORT_LAST_DIM = 16
"""Below this many entries, a softmax over the last dimension runs over the first instead (see
:func:`log_softmax_last`); measured crossover on a 2-core AVX-512 Xeon, torch 2.13 CPU."""


def _over_first(fn, x: torch.Tensor) -> torch.Tensor:
    return fn(x.movedim(-1, 0).contiguous(), 0).movedim(0, -1)


def log_softmax_last(x: torch.Tensor) -> torch.Tensor:
    """``torch.log_softmax(x, -1)``, the same bits, several times faster for a short last dimension.

    Why: torch's CPU kernel for the last dimension vectorizes along that dimension, so a row
    shorter than a vector register (16 floats with AVX-512) takes its scalar path: 10–30× slower
    than the kernel for another dimension, which vectorizes across rows (measured: 5 actions ×
    4,480 robots 301 against 31 µs; attention rows of 7 robots 1.1 ms against 0.09 ms). So a short
    last dimension is moved first, made contiguous, and moved back. For the log-softmax the two
    kernels gave the same bits on this machine (``tests/test_layers.py``; elsewhere they agree
    within the last bit, which moves no action: actions come from the logits)."""
    return _over_first(torch.log_softmax, x) if x.shape[-1] < SHORT_LAST_DIM else torch.log_softmax(x, -1)


def softmax_last(x: torch.Tensor) -> torch.Tensor:
    """``torch.softmax(x, -1)`` by the faster kernel of :func:`log_softmax_last` where the last
    dimension is short. Unlike the log-softmax, the two kernels' results differ in the last bit
    (the sum's order and a reciprocal), so :class:`Attention` takes this path only where a
    gradient is recorded (the PPO update): acting, and with it every evaluation, keeps torch's
    kernel and its bits."""
    return _over_first(torch.softmax, x) if x.shape[-1] < SHORT_LAST_DIM else torch.softmax(x, -1)


def init_linear(layer: nn.Linear, gain: float = 1.0) -> nn.Linear:
    """Orthogonal weights with ``gain``, zero bias (MAT's and cleanrl's initialisation)."""
    nn.init.orthogonal_(layer.weight, gain)
    if layer.bias is not None:
        nn.init.zeros_(layer.bias)
    return layer


def mlp(sizes: list[int], act: type[nn.Module] = nn.ReLU, out_gain: float = 1.0) -> nn.Sequential:
    """Linear–act–…–Linear; hidden layers get gain √2, the last ``out_gain``."""
    layers: list[nn.Module] = []
    for k in range(len(sizes) - 1):
        last = k == len(sizes) - 2
        layers.append(init_linear(nn.Linear(sizes[k], sizes[k + 1]), out_gain if last else math.sqrt(2)))
        if not last:
            layers.append(act())
    return nn.Sequential(*layers)


def causal(length: int, device=None) -> torch.Tensor:
    """(L, L) lower-triangular mask: position i attends to positions <= i."""
    return torch.ones(length, length, dtype=torch.bool, device=device).tril()


class KVCache:
    """Keys and values (B, H, L, dh) of the positions decoded so far, one step at a time.

    Grown by concatenation: for the few positions of a team that is 2 PyTorch calls per step,
    where writing into preallocated buffers and slicing them back takes 6 (each call costs
    more than the copy)."""

    def __init__(self) -> None:
        self.k: torch.Tensor | None = None
        self.v: torch.Tensor | None = None

    def append(self, k: torch.Tensor, v: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        if self.k is None:
            self.k, self.v = k, v
        else:
            self.k, self.v = torch.cat([self.k, k], 2), torch.cat([self.v, v], 2)
        return self.k, self.v


class Attention(nn.Module):
    """Multi-head scaled dot-product attention, with an incremental (cached) mode.

    ``forward(query (B, Lq, D), key (B, Lk, D), value (B, Lk, D), mask (B|1, Lq, Lk))``.
    ``step(q (B, H, 1, dh), key (B, 1, D), value (B, 1, D), cache)`` takes a query from
    :meth:`step_query` (which callers may compute for all positions at once), appends the
    new key and value to ``cache`` and attends over everything cached: equal to the causal
    forward pass at that position. Over a packed batch (COMAT's update, ``packed``) the causal
    attention runs in fused compiled kernels (:mod:`comat.models.attention_kernels`); elsewhere
    in torch, whose bits acting keeps.
    """

    def __init__(self, dim: int, heads: int) -> None:
        super().__init__()
        if dim % heads:
            raise ValueError(f"embedding dim {dim} must be divisible by heads {heads}")
        self.heads = heads
        self.q = init_linear(nn.Linear(dim, dim))
        self.kv = init_linear(nn.Linear(dim, 2 * dim))  # keys and values in one matmul
        self.o = init_linear(nn.Linear(dim, dim), 0.01)

    def _split(self, x: torch.Tensor) -> torch.Tensor:
        B, L, D = x.shape
        return x.view(B, L, self.heads, D // self.heads).transpose(1, 2)

    def _merge(self, x: torch.Tensor) -> torch.Tensor:
        B, H, L, dh = x.shape
        return self.o(x.transpose(1, 2).reshape(B, L, H * dh))

    def _kv_merged(self, key: torch.Tensor, value: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Keys and values (B, L, D), heads not split."""
        if key is value:
            return self.kv(key).chunk(2, dim=-1)
        D = key.shape[-1]
        w, b = self.kv.weight, self.kv.bias
        return F.linear(key, w[:D], b[:D]), F.linear(value, w[D:], b[D:])

    def _kv(self, key: torch.Tensor, value: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        k, v = self._kv_merged(key, value)
        return self._split(k), self._split(v)

    @staticmethod
    def _attend(q, k, v, mask: torch.Tensor | None = None, scaled: bool = False) -> torch.Tensor:
        # Plain matmul–softmax–matmul: for a few robots it is several times cheaper on the CPU
        # than the fused kernel. ``scaled``: q already carries the 1/√dh (cached steps).
        scores = q @ k.transpose(-2, -1)
        if not scaled:
            scores = scores * (q.shape[-1] ** -0.5)
        if mask is not None:
            # An added 0 / −inf bias of the mask's own (broadcast) shape: the same bits as
            # masked_fill on the scores, and 7× cheaper forward, 3× with the backward, because the
            # fill walks every score and the addition's gradient is the identity (measured on
            # (640, 4, 7, 7) scores with a causal mask).
            scores = scores + torch.zeros(mask.shape, dtype=scores.dtype, device=scores.device).masked_fill_(
                ~mask, float("-inf")
            )
        weights = softmax_last(scores) if torch.is_grad_enabled() else torch.softmax(scores, -1)
        return weights @ v

    def project_query(self, query: torch.Tensor) -> torch.Tensor:
        return self._split(self.q(query))

    def step_query(self, query: torch.Tensor) -> torch.Tensor:
        """Queries (B, H, L, dh) for :meth:`step`: projected, split and scaled by 1/√dh (callers
        may compute them for all positions, or all tokens, at once)."""
        q = self.project_query(query)
        return q * (q.shape[-1] ** -0.5)

    def forward(self, query, key, value, mask: torch.Tensor | None = None, packed=None) -> torch.Tensor:
        k, v = self._kv_merged(key, value)
        return self.attend(self.q(query), k, v, mask, packed)

    def attend(self, q, k, v, mask: torch.Tensor | None = None, packed=None) -> torch.Tensor:
        """:meth:`forward` from projected queries q (B, Lq, D), keys and values (B, Lk, D), heads
        not split (callers that project a few distinct inputs once, such as a decoder's tokens).
        ``packed`` (a :class:`~comat.models.packing.PackedTeams`; q, k, v then (R, D), ``mask``
        unused): each robot attends to its team's robots up to itself, in the fused kernels of
        :mod:`comat.models.attention_kernels` (COMAT's update; 16-wide heads)."""
        if packed is not None:
            return self.o(causal_attention(q, k, v, packed, self.heads))
        if mask is not None:
            # A query with nothing to attend to (a padded robot) attends to the first key only,
            # so no row is all -inf; its output is never used.
            empty = ~mask.any(-1, keepdim=True)
            mask = mask | (empty & (torch.arange(mask.shape[-1], device=mask.device) == 0))
        split = self._split
        return self._merge(self._attend(split(q), split(k), split(v), None if mask is None else mask[:, None]))

    def step(self, q: torch.Tensor, key, value, cache: KVCache) -> torch.Tensor:
        return self.step_projected(q, *self._kv(key, value), cache)

    def step_projected(self, q: torch.Tensor, k: torch.Tensor, v: torch.Tensor, cache: KVCache) -> torch.Tensor:
        """:meth:`step` with the new key and value already projected and split, (B, H, 1, dh)."""
        k, v = cache.append(k, v)
        x = self._attend(q, k, v, scaled=True)  # (B, H, 1, dh): already in (B, 1, H·dh) order
        return self.o(x.reshape(x.shape[0], 1, -1))


class TypeHeads(nn.Module):
    """One two-layer MLP per robot type, evaluated for all types in two matmuls.

    ``forward(x (B, L, in), type_onehot (B, L, T)) -> (B, L, out)``: each robot's output comes
    from the head of its own type (parameters shared by robots of a type, never by position).
    ``mode`` (a :class:`~comat.models.comat_schema.DecisionMode` or its string) fixes the form,
    and :func:`~comat.models.comat_schema.decision_shapes` the parameters' shapes:
    ``type_heads`` one hidden layer per type (``first`` (T·H, in)); ``shared_trunk`` the hidden
    layer shared by all types (``first`` (H, in)) and only the output layer per type;
    ``adapters`` the output layer shared too, each type adding its own part ``w2[t]``, ``b2[t]``,
    initialized at zero: the types start with one decision layer and part only as their
    gradients say.
    """

    def __init__(
        self,
        d_in: int,
        hidden: int,
        d_out: int,
        n_types: int,
        out_gain: float = 0.01,
        mode: DecisionMode | str = DecisionMode.TYPE_HEADS,
    ) -> None:
        super().__init__()
        self.mode = DecisionMode(mode)
        self.n_types, self.hidden = n_types, hidden
        shapes = decision_shapes(self.mode, d_in, hidden, d_out, n_types, trained=True)
        self.first = init_linear(nn.Linear(d_in, shapes["first.weight"][0]), math.sqrt(2))
        w2 = torch.empty(shapes["w2"])
        for t in range(n_types):
            nn.init.orthogonal_(w2[t], out_gain)
        if self.mode.adapters:  # one output layer for all types; each type's own part starts at zero
            w2_shared = torch.empty(shapes["w2_shared"])
            nn.init.orthogonal_(w2_shared, out_gain)
            self.w2_shared = nn.Parameter(w2_shared)
            self.b2_shared = nn.Parameter(torch.zeros(shapes["b2_shared"]))
            w2.zero_()
        self.w2 = nn.Parameter(w2)
        self.b2 = nn.Parameter(torch.zeros(shapes["b2"]))

    def output_layer(self) -> tuple[torch.Tensor, torch.Tensor]:
        """Each type's output weights (T, H, out) and biases (T, out): with adapters, the shared
        layer plus the type's own part (what the compiled kernels and the numpy runtime use)."""
        if self.mode.adapters:
            return self.w2 + self.w2_shared, self.b2 + self.b2_shared
        return self.w2, self.b2

    def acting_arrays(self) -> dict[str, torch.Tensor]:
        """The layer in acting form (``decision_shapes`` without ``trained``): ``first.weight``,
        ``first.bias``, and each type's whole output layer ``w2`` (T, H, out), ``b2`` (T, out)."""
        w2, b2 = self.output_layer()
        return {"first.weight": self.first.weight, "first.bias": self.first.bias, "w2": w2, "b2": b2}

    def forward(self, x: torch.Tensor, type_onehot: torch.Tensor) -> torch.Tensor:
        return self._second(F.relu(self.first(x)), type_onehot)

    def _second(self, h: torch.Tensor, type_onehot: torch.Tensor) -> torch.Tensor:
        w2, b2 = self.output_layer()
        if self.mode.shared_hidden:
            out = torch.einsum("...h,tho->...to", h, w2) + b2  # (..., T, out)
        else:
            h = h.unflatten(-1, (self.n_types, self.hidden))  # (..., T, H)
            out = torch.einsum("...th,tho->...to", h, w2) + b2  # (..., T, out)
        return (out * type_onehot[..., None]).sum(-2)

    def partial(self, c: torch.Tensor) -> torch.Tensor:
        """The first layer's share of trailing input features c (..., C), bias included: for
        inputs [h ‖ c] whose c is known before h (a decoder's capability vectors)."""
        return F.linear(c, self.first.weight[:, -c.shape[-1] :], self.first.bias)

    def finish(self, h: torch.Tensor, part: torch.Tensor, type_onehot: torch.Tensor) -> torch.Tensor:
        """``forward([h ‖ c], type_onehot)`` from h (..., D_h) and ``part = partial(c)``."""
        return self._second(F.relu(F.linear(h, self.first.weight[:, : h.shape[-1]]) + part), type_onehot)


def choose_actions(
    logits: torch.Tensor, mask: torch.Tensor, deterministic: bool, generator: torch.Generator | None
) -> tuple[torch.Tensor, torch.Tensor]:
    """Actions (B, N) from per-robot logits (B, N, A) — the argmax, or a Gumbel-max sample (an exact
    sample of softmax(logits)) — 0 in padded slots, and their log-probabilities (B, N), 0 there too.
    The per-robot policies (MAPPO's, IPPO's and CASH's actors) all act this way."""
    if deterministic:
        a = logits.argmax(-1)
    else:
        u = torch.rand(logits.shape, generator=generator).clamp_(1e-20, 1.0)
        a = (logits - torch.log(-torch.log(u))).argmax(-1)
    a = torch.where(mask, a, 0)
    return a, log_softmax_last(logits).gather(-1, a[..., None])[..., 0] * mask


def score_actions(
    logits: torch.Tensor, actions: torch.Tensor, mask: torch.Tensor | None
) -> tuple[torch.Tensor, torch.Tensor]:
    """Log-probabilities and entropies (B, N) of given actions under per-robot logits (B, N, A),
    0 in padded slots (PPO's update for the per-robot policies); ``mask`` None: every robot is
    real (a packed batch's rows (R, A))."""
    logp_all = log_softmax_last(logits)
    logp = logp_all.gather(-1, actions[..., None])[..., 0]
    entropy = -(logp_all.exp() * logp_all).sum(-1)
    return (logp, entropy) if mask is None else (logp * mask, entropy * mask)
