"""Multi-head attention over a few robots fused into one compiled pass forward and one backward
(numba), for training on the CPU: :meth:`comat.models.layers.Attention._attend` is the reference
and the general path, and ``tests/test_attention_kernels.py`` checks this against it (outputs and
every gradient, within float rounding).

Why: with a team's few robots the attention's matrices are 3–8 wide, so torch's path (heads split
and merged by copies, two tiny batched matmuls, the mask added, a softmax, and twice the matmuls
backward) cost more in calls and copies than in arithmetic: 2.4 ms forward and backward for 400
teams of 7 with 4 heads, against 2.8 ms for the attention's three projections (issue 48). Here each
(team, query) row is one pass over its keys, in the projections' own (B, L, H·dh) layout, keeping
only the attention weights for the backward pass: the whole attention 5.2 → 5.0 ms for 400 teams
of 7 and 1.9 → 1.5 ms for 250 teams of 3, and COMAT's PPO update about 5 % shorter (alternating
runs on one PCP rollout, docs/speed.md). Serial, as the HEAT edge stage (``heat_kernels``).

Shapes: q (B, Lq, D), k and v (B, Lk, D) with head h the columns h·dh … (h+1)·dh − 1 (D = H·dh);
mask (B or 1, Lq, Lk), True where query i may attend to key j, at least one True per row;
out (B, Lq, D), the heads concatenated; weights (B, Lq, H, Lk).
"""

from __future__ import annotations

import numpy as np
import torch
from numba import njit

__all__ = ["HEAD_WIDTH", "SHORT_KEYS", "short_attention"]

SHORT_KEYS = 16
"""Sequences up to this many keys take the fused kernels (a team's robots); longer ones torch's."""
HEAD_WIDTH = 16
"""The one head width dh the kernels are compiled for (COMAT's 64 / 4 heads): loops of a length
known when compiling vectorize whole; with dh a run-time number the same kernels were 2.3× slower
(numba 0.68, measured on the 2-core Xeon). Other widths take torch's path."""

_jit = njit(cache=True, nogil=True, fastmath={"reassoc", "contract"})
# Sums may be reordered and multiply-adds fused, so the dot products over a head's columns
# vectorize: float rounding only (no flag assumes finite numbers; masked keys are skipped, never
# -inf).


@_jit
def _forward(q, k, v, mask, heads, scale, out, weights):  # pragma: no cover - compiled
    B, Lq, D = q.shape
    Lk = k.shape[1]
    dh = HEAD_WIDTH
    mb = mask.shape[0] > 1
    top = np.empty(heads, np.float32)
    total = np.empty(heads, np.float32)
    for b in range(B):
        bm = b if mb else 0
        for i in range(Lq):
            w = weights[b, i]  # (H, Lk)
            first = True
            for j in range(Lk):
                if not mask[bm, i, j]:
                    continue
                for h in range(heads):
                    s = np.float32(0.0)
                    for c in range(dh):
                        s += q[b, i, h * dh + c] * k[b, j, h * dh + c]
                    s *= scale
                    w[h, j] = s
                    top[h] = s if first else max(top[h], s)
                first = False
            total[:] = 0.0
            for h in range(heads):
                for j in range(Lk):
                    if mask[bm, i, j]:
                        e = np.exp(w[h, j] - top[h])
                        w[h, j] = e
                        total[h] += e
                    else:
                        w[h, j] = 0.0
                for j in range(Lk):
                    w[h, j] /= total[h]
            for c in range(D):
                out[b, i, c] = 0.0
            for j in range(Lk):
                if mask[bm, i, j]:
                    for h in range(heads):
                        wj = w[h, j]
                        for c in range(h * dh, h * dh + dh):
                            out[b, i, c] += wj * v[b, j, c]


@_jit
def _backward(q, k, v, mask, weights, gout, heads, scale, dq, dk, dv):  # pragma: no cover - compiled
    B, Lq, D = q.shape
    Lk = k.shape[1]
    dh = HEAD_WIDTH
    mb = mask.shape[0] > 1
    dw = np.empty(Lk, np.float32)
    for b in range(B):
        for j in range(Lk):
            for c in range(D):
                dk[b, j, c] = 0.0
                dv[b, j, c] = 0.0
        bm = b if mb else 0
        for i in range(Lq):
            for c in range(D):
                dq[b, i, c] = 0.0
            for h in range(heads):
                c0 = h * dh
                dot = np.float32(0.0)
                for j in range(Lk):
                    if mask[bm, i, j]:
                        wj = weights[b, i, h, j]
                        s = np.float32(0.0)
                        for c in range(c0, c0 + dh):
                            s += gout[b, i, c] * v[b, j, c]
                            dv[b, j, c] += wj * gout[b, i, c]
                        dw[j] = s
                        dot += wj * s
                for j in range(Lk):
                    if mask[bm, i, j]:
                        ds = weights[b, i, h, j] * (dw[j] - dot) * scale  # the softmax's backward, then the scale
                        for c in range(c0, c0 + dh):
                            dq[b, i, c] += ds * k[b, j, c]
                            dk[b, j, c] += ds * q[b, i, c]


class ShortAttention(torch.autograd.Function):
    """``out = short_attention(q, k, v, mask, heads)`` with the fused backward (see the module)."""

    @staticmethod
    def forward(ctx, q, k, v, mask, heads):
        q, k, v, mask = (t.detach().contiguous() for t in (q, k, v, mask))
        B, Lq, D = q.shape
        scale = np.float32((D // heads) ** -0.5)
        out = torch.empty_like(q)
        weights = torch.empty((B, Lq, heads, k.shape[1]), dtype=q.dtype)
        _forward(*(t.numpy() for t in (q, k, v, mask)), heads, scale, out.numpy(), weights.numpy())
        ctx.save_for_backward(q, k, v, mask, weights)
        ctx.heads, ctx.scale = heads, scale
        return out

    @staticmethod
    def backward(ctx, gout):
        q, k, v, mask, weights = ctx.saved_tensors
        dq, dk, dv = torch.empty_like(q), torch.empty_like(k), torch.empty_like(v)
        inputs = (q, k, v, mask, weights, gout.contiguous())
        _backward(*(t.numpy() for t in inputs), ctx.heads, ctx.scale, *(t.numpy() for t in (dq, dk, dv)))
        return dq, dk, dv, None, None


def short_attention(q, k, v, mask, heads: int) -> torch.Tensor:
    """softmax(q_h k_hᵀ/√dh, masked) v_h for every head h, heads concatenated (B, Lq, D) (see the
    module docstring); float32 CPU tensors, ``mask`` a bool tensor (B or 1, Lq, Lk)."""
    return ShortAttention.apply(q, k, v, mask, heads)
