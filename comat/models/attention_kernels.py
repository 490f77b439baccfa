"""COMAT's decoder attention over a packed batch (each robot attending to its team's robots up to
itself) fused into one compiled pass forward and one backward (numba), for training on the CPU:
:meth:`comat.models.layers.Attention._attend` on the padded batch with a causal mask is the
reference and the general path, and ``tests/test_attention_kernels.py`` checks this against it
(outputs and every gradient, within float rounding).

Why: with a team's few robots the attention's matrices are 3–8 wide, so torch's path (heads split
and merged by copies, two tiny batched matmuls, the mask added, a softmax, and twice the matmuls
backward) cost more in calls and copies than in arithmetic: 2.4 ms forward and backward for 400
teams of 7 with 4 heads, against 2.8 ms for the attention's three projections (issue 48). Here each
robot's row is one pass over its team's earlier robots, in the projections' own (R, H·dh) layout,
keeping only the attention weights for the backward pass. Where torch may use two threads, the
teams are split in two halves, one in a helper thread (``comat.models.packing.on_threads``).

Shapes (a :class:`~comat.models.packing.PackedTeams` of R robots): q, k and v (R, D) with head h
the columns h·dh … (h+1)·dh − 1 (D = H·dh); out (R, D), the heads concatenated; weights
(R, H, n_max), robot i's over its team's robots 0 … i.
"""

from __future__ import annotations

import numpy as np
import torch
from numba import njit

from comat.models.packing import on_threads, parts

__all__ = ["HEAD_WIDTH", "causal_attention"]

HEAD_WIDTH = 16
"""The one head width dh the kernels are compiled for (COMAT's 64 / 4 heads): loops of a length
known when compiling vectorize whole; with dh a run-time number the same kernels were 2.3× slower
(numba 0.68, measured on the 2-core Xeon). Other widths take torch's path."""

_jit = njit(cache=True, nogil=True, fastmath={"reassoc", "contract"})
# Sums may be reordered and multiply-adds fused, so the dot products over a head's columns
# vectorize: float rounding only (no flag assumes finite numbers; masked keys are skipped, never
# -inf).


@_jit
def _forward(q, k, v, size, start, heads, scale, out, weights):  # pragma: no cover - compiled
    D = q.shape[1]
    dh = HEAD_WIDTH
    top = np.empty(heads, np.float32)
    total = np.empty(heads, np.float32)
    for b in range(size.shape[0]):
        s0 = start[b]
        for i in range(size[b]):
            r = s0 + i
            w = weights[r]  # (H, n_max): keys 0 … i of the team
            for j in range(i + 1):
                for h in range(heads):
                    s = np.float32(0.0)
                    for c in range(dh):
                        s += q[r, h * dh + c] * k[s0 + j, h * dh + c]
                    s *= scale
                    w[h, j] = s
                    top[h] = s if j == 0 else max(top[h], s)
            total[:] = 0.0
            for h in range(heads):
                for j in range(i + 1):
                    x = np.exp(w[h, j] - top[h])
                    w[h, j] = x
                    total[h] += x
                for j in range(i + 1):
                    w[h, j] /= total[h]
            for c in range(D):
                out[r, c] = 0.0
            for j in range(i + 1):
                for h in range(heads):
                    wj = w[h, j]
                    for c in range(h * dh, h * dh + dh):
                        out[r, c] += wj * v[s0 + j, c]


@_jit
def _backward(q, k, v, size, start, weights, gout, heads, scale, dq, dk, dv):  # pragma: no cover - compiled
    dh = HEAD_WIDTH
    dw = np.empty(weights.shape[2], np.float32)
    for b in range(size.shape[0]):
        s0 = start[b]
        for i in range(size[b]):
            r = s0 + i
            for h in range(heads):
                c0 = h * dh
                dot = np.float32(0.0)
                for j in range(i + 1):
                    wj = weights[r, h, j]
                    s = np.float32(0.0)
                    for c in range(c0, c0 + dh):
                        s += gout[r, c] * v[s0 + j, c]
                        dv[s0 + j, c] += wj * gout[r, c]
                    dw[j] = s
                    dot += wj * s
                for j in range(i + 1):
                    ds = weights[r, h, j] * (dw[j] - dot) * scale  # the softmax's backward, then the scale
                    for c in range(c0, c0 + dh):
                        dq[r, c] += ds * k[s0 + j, c]
                        dk[s0 + j, c] += ds * q[r, c]


class CausalAttention(torch.autograd.Function):
    """``out = causal_attention(q, k, v, packed, heads)`` with the fused backward (see the module)."""

    @staticmethod
    def forward(ctx, q, k, v, packed, heads):
        q, k, v = (t.detach().contiguous() for t in (q, k, v))
        scale = np.float32((q.shape[1] // heads) ** -0.5)
        out = torch.empty_like(q)
        weights = torch.empty((q.shape[0], heads, max(int(packed.size.max(initial=0)), 1)), dtype=q.dtype)
        arrays = (q.numpy(), k.numpy(), v.numpy())

        def run(teams, part):
            _forward(*arrays, packed.size[teams], packed.start[teams], heads, scale, out.numpy(), weights.numpy())

        on_threads(run, packed.size, parts())
        ctx.save_for_backward(q, k, v, weights)
        ctx.packed, ctx.heads, ctx.scale = packed, heads, scale
        return out

    @staticmethod
    def backward(ctx, gout):
        q, k, v, weights = ctx.saved_tensors
        packed = ctx.packed
        grads = [torch.zeros_like(t) for t in (q, k, v)]
        inputs = (q.numpy(), k.numpy(), v.numpy())
        gout = gout.contiguous()

        def run(teams, part):
            rest = (weights.numpy(), gout.numpy(), ctx.heads, ctx.scale, *(g.numpy() for g in grads))
            _backward(*inputs, packed.size[teams], packed.start[teams], *rest)

        on_threads(run, packed.size, parts())
        return *grads, None, None


def causal_attention(q, k, v, packed, heads: int) -> torch.Tensor:
    """softmax(q_h k_hᵀ/√dh) v_h for every head h, each robot attending to its team's robots up to
    itself, heads concatenated (R, D) (see the module docstring); float32 CPU tensors of a packed
    batch (``packed``, a :class:`~comat.models.packing.PackedTeams`)."""
    return CausalAttention.apply(q, k, v, packed, heads)
