"""The HEAT block's per-edge stage fused into one compiled pass forward and one backward (numba),
for training on the CPU: the torch expression in :meth:`comat.models.comat.HEATBlock.forward` is
the reference and the general path, and ``tests/test_heat_kernels.py`` checks this against it
(outputs and every gradient, within float rounding).

Why: the stage is elementwise over the (B, N, N, d + K) edge tensor — robot j's share added, the
score's and the message's LeakyReLU, the masked softmax over neighbours, the attention-weighted sum
per head — and in torch each of those is a pass over that tensor forward and more backward, which
made COMAT's update half its training time (issue 48). Here each is one pass per (b, i), with
only the attention weights kept for the backward pass (the pre-activations are recomputed). The
loops run along the contiguous dimension (the message's d columns, each edge's heads), skip masked
edges, and robot j's gradient is summed while the edge's is written: 1.6 → 0.7 ms forward and
1.55 → 0.8 ms backward for 257 teams of 7 (alone, one core), COMAT's PPO update 1.82 → 1.63 s on
one PCP rollout (docs/speed.md).

Shapes: z (B, N, N, d + K) — the per-edge maps [ẽ^attr ‖ one-hot pair] @ W, the message's d
columns then the score's K; xj (B, N, d + K) robot j's share of both; ai (B, N, K) robot i's
share of the score; mask (B, N, N) the edges; out (B, N, d) the heads' weighted messages,
concatenated (head k the columns k·d/K … (k+1)·d/K − 1); alpha (B, N, N, K).
"""

from __future__ import annotations

import numpy as np
import torch
from numba import njit

__all__ = ["EdgeStage", "edge_stage"]

SLOPE = np.float32(0.2)
"""The LeakyReLU's negative slope (HEAT's); float32, so the kernels' arithmetic stays float32."""
_ONE = np.float32(1.0)

_jit = njit(cache=True, nogil=True)
# Serial on purpose: a numba parallel region (OpenMP layer) left threads that made every later
# single-threaded call of the process ~4x slower (COMAT's act 1.7 -> 7.8 ms, measured), and the
# workqueue layer gained nothing here (the update 1.47 s against 1.43 serial); the learner's
# matrix products keep torch's threads.


@_jit
def _softmax_rows(z, xj, ai, mask, b, i, heads, d, alpha, top, total):  # pragma: no cover - compiled
    """alpha[b, i, :, k] = the masked softmax over j of LeakyReLU(score), each head k; ``top`` and
    ``total`` (heads,) are scratch. Heads innermost: alpha's and z's contiguous order."""
    N = z.shape[1]
    top[:] = -np.inf
    for j in range(N):
        if mask[b, i, j]:
            for k in range(heads):
                s = z[b, i, j, d + k] + xj[b, j, d + k] + ai[b, i, k]
                s = max(s, SLOPE * s)  # LeakyReLU (slope < 1)
                alpha[b, i, j, k] = s
                top[k] = max(top[k], s)
    total[:] = 0.0
    for j in range(N):
        if mask[b, i, j]:
            for k in range(heads):
                e = np.exp(alpha[b, i, j, k] - top[k])
                alpha[b, i, j, k] = e
                total[k] += e
        else:
            alpha[b, i, j, :] = 0.0
    for j in range(N):
        if mask[b, i, j]:
            for k in range(heads):
                alpha[b, i, j, k] /= total[k]  # total >= 1 (the top score's term) where j is an edge


@_jit
def _forward(z, xj, ai, mask, heads, out, alpha):  # pragma: no cover - compiled
    B, N, _, width = z.shape
    d = width - heads
    dh = d // heads
    weight = np.empty(d, np.float32)  # edge (i, j)'s attention weight per message column
    acc = np.empty(d, np.float32)
    top, total = np.empty(heads, np.float32), np.empty(heads, np.float32)
    for b in range(B):
        for i in range(N):
            _softmax_rows(z, xj, ai, mask, b, i, heads, d, alpha, top, total)
            acc[:] = 0.0
            for j in range(N):
                if not mask[b, i, j]:
                    continue  # weight 0: adds nothing
                for k in range(heads):
                    weight[k * dh : (k + 1) * dh] = alpha[b, i, j, k]
                # One contiguous pass over the edge's d message columns (vectorized), summed over
                # neighbours j in order.
                for c in range(d):
                    m = z[b, i, j, c] + xj[b, j, c]
                    acc[c] += weight[c] * max(m, SLOPE * m)
            out[b, i, :] = acc


@_jit
def _backward(z, xj, ai, mask, alpha, gout, heads, dz, dxj, dai):  # pragma: no cover - compiled
    B, N, _, width = z.shape
    d = width - heads
    dh = d // heads
    weight = np.empty(d, np.float32)
    prod = np.empty(d, np.float32)  # gout · LeakyReLU(message), per column
    dalpha = np.empty((N, heads), np.float32)
    for b in range(B):
        dxj[b] = 0.0
        for i in range(N):
            g = gout[b, i]
            for j in range(N):
                if not mask[b, i, j]:
                    dz[b, i, j, :] = 0.0
                    dalpha[j, :] = 0.0
                    continue
                for k in range(heads):
                    weight[k * dh : (k + 1) * dh] = alpha[b, i, j, k]
                for c in range(d):
                    m = z[b, i, j, c] + xj[b, j, c]
                    prod[c] = g[c] * max(m, SLOPE * m)
                    dz[b, i, j, c] = weight[c] * g[c] * (_ONE if m > 0 else SLOPE)
                for k in range(heads):
                    dalpha[j, k] = _sum(prod, k * dh, (k + 1) * dh)
            for k in range(heads):
                dot = np.float32(0.0)
                for j in range(N):
                    dot += alpha[b, i, j, k] * dalpha[j, k]
                acc = np.float32(0.0)
                for j in range(N):
                    grad = np.float32(0.0)
                    if mask[b, i, j]:
                        s = z[b, i, j, d + k] + xj[b, j, d + k] + ai[b, i, k]
                        grad = alpha[b, i, j, k] * (dalpha[j, k] - dot) * (_ONE if s > 0 else SLOPE)
                    dz[b, i, j, d + k] = grad
                    acc += grad
                dai[b, i, k] = acc
            for j in range(N):  # robot j's share of every edge (i, j), summed over i in order
                if mask[b, i, j]:
                    for c in range(width):
                        dxj[b, j, c] += dz[b, i, j, c]


@njit(cache=True, nogil=True, fastmath=True)
def _sum(x, start, stop):  # pragma: no cover - compiled
    """x[start:stop].sum(), vectorized (fastmath lets the sum be reordered: float rounding only)."""
    total = np.float32(0.0)
    for c in range(start, stop):
        total += x[c]
    return total


class EdgeStage(torch.autograd.Function):
    """``out = edge_stage(z, xj, ai, mask, heads)`` with the fused backward (see the module)."""

    @staticmethod
    def forward(ctx, z, xj, ai, mask, heads):
        z, xj, ai, mask = (t.detach().contiguous() for t in (z, xj, ai, mask))
        B, N, _, width = z.shape
        out = torch.empty((B, N, width - heads), dtype=z.dtype)
        alpha = torch.empty((B, N, N, heads), dtype=z.dtype)
        _forward(*(t.numpy() for t in (z, xj, ai, mask)), heads, out.numpy(), alpha.numpy())
        ctx.save_for_backward(z, xj, ai, mask, alpha)
        ctx.heads = heads
        return out

    @staticmethod
    def backward(ctx, gout):
        z, xj, ai, mask, alpha = ctx.saved_tensors
        dz, dxj, dai = torch.empty_like(z), torch.empty_like(xj), torch.empty_like(ai)
        inputs = (z, xj, ai, mask, alpha, gout.contiguous())
        _backward(*(t.numpy() for t in inputs), ctx.heads, *(t.numpy() for t in (dz, dxj, dai)))
        return dz, dxj, dai, None, None


def edge_stage(z, xj, ai, mask, heads: int) -> torch.Tensor:
    """The heads' weighted messages (B, N, d) (see the module docstring); float32 CPU tensors."""
    return EdgeStage.apply(z, xj, ai, mask, heads)
