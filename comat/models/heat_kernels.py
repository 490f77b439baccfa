"""The HEAT block's per-edge stage over a packed batch fused into one compiled pass forward and one
backward (numba), for training on the CPU: the torch expression in
:meth:`comat.models.comat.HEATBlock.forward` (on the padded batch) is the reference and the general
path, and ``tests/test_heat_kernels.py`` checks this against it and against a torch version of
the packed stage (outputs and every gradient, within float rounding).

Why: the stage is elementwise over the edges' (M, d + K) matrix — the type pair's row and robot
j's share added, the score's and the message's LeakyReLU, the softmax over each robot's team, the
attention-weighted sum per head — and in torch each of those is a pass over that matrix forward
and more backward, which made COMAT's update half its training time (issue 48). Here each is one
pass per robot, with only the attention weights kept for the backward pass (the pre-activations
are recomputed). The loops run along the contiguous dimension (the message's d columns, each
edge's heads), and robot j's and the type pair's gradients are summed while the edge's is
written. Where torch may use two threads, the teams are split in two halves, one in a helper
thread (``comat.models.packing.on_threads``; the type-pair table's gradient is summed per half).

Shapes (a :class:`~comat.models.packing.PackedTeams` of R robots and M edges): z (M, d + K) —
the per-edge map ẽ^attr @ W, the message's d columns then the score's K; table (T², d + K) each
ordered type pair's share of both, pair (M,) each edge's row of it; node (R, d + 2K) each robot's
share of both as robot j, then its share of the score as robot i; out (R, d) the heads' weighted messages, concatenated
(head k the columns k·d/K … (k+1)·d/K − 1); alpha (M, K).
"""

from __future__ import annotations

import numpy as np
import torch
from numba import njit

from comat.models.packing import on_threads, parts

__all__ = ["EdgeStage", "edge_stage"]

SLOPE = np.float32(0.2)
"""The LeakyReLU's negative slope (HEAT's); float32, so the kernels' arithmetic stays float32."""
_ONE = np.float32(1.0)

_jit = njit(cache=True, nogil=True)
# Serial kernels, split over threads by the caller: a numba parallel region (OpenMP layer) left
# threads that made every later single-threaded call of the process ~4x slower (COMAT's act 1.7 ->
# 7.8 ms, measured), and the workqueue layer gained nothing (the update 1.47 s against 1.43 serial).


@_jit
def _softmax_row(z, node, pair, table, r, s0, e, n, heads, d, alpha, top, total):  # pragma: no cover - compiled
    """alpha[e + j, k] = the softmax over the team's robots j of LeakyReLU(score), each head k, for
    robot i at row r (its edges at rows e … e + n − 1); ``top`` and ``total`` (heads,) are scratch.
    Heads innermost: alpha's and z's contiguous order."""
    top[:] = -np.inf
    for j in range(n):
        for k in range(heads):
            s = z[e + j, d + k] + table[pair[e + j], d + k] + node[s0 + j, d + k] + node[r, d + heads + k]
            s = max(s, SLOPE * s)  # LeakyReLU (slope < 1)
            alpha[e + j, k] = s
            top[k] = max(top[k], s)
    total[:] = 0.0
    for j in range(n):
        for k in range(heads):
            x = np.exp(alpha[e + j, k] - top[k])
            alpha[e + j, k] = x
            total[k] += x
    for j in range(n):
        for k in range(heads):
            alpha[e + j, k] /= total[k]  # total >= 1 (the top score's term)


@_jit
def _forward(z, node, pair, table, size, start, edge_start, heads, out, alpha):  # pragma: no cover - compiled
    d = z.shape[1] - heads
    dh = d // heads
    weight = np.empty(d, np.float32)  # edge (i, j)'s attention weight per message column
    acc = np.empty(d, np.float32)
    top, total = np.empty(heads, np.float32), np.empty(heads, np.float32)
    for b in range(size.shape[0]):
        n, s0 = size[b], start[b]
        for i in range(n):
            r, e = s0 + i, edge_start[b] + i * n
            _softmax_row(z, node, pair, table, r, s0, e, n, heads, d, alpha, top, total)
            acc[:] = 0.0
            for j in range(n):
                for k in range(heads):
                    weight[k * dh : (k + 1) * dh] = alpha[e + j, k]
                p = pair[e + j]
                # One contiguous pass over the edge's d message columns (vectorized), summed over
                # neighbours j in order.
                for c in range(d):
                    m = z[e + j, c] + table[p, c] + node[s0 + j, c]
                    acc[c] += weight[c] * max(m, SLOPE * m)
            out[r, :] = acc


@_jit
def _backward(
    z, node, pair, table, size, start, edge_start, alpha, gout, heads, dz, dnode, dtable
):  # pragma: no cover - compiled
    width = z.shape[1]
    d = width - heads
    dh = d // heads
    weight = np.empty(d, np.float32)
    prod = np.empty(d, np.float32)  # gout · LeakyReLU(message), per column
    dalpha = np.empty(heads, np.float32)
    for b in range(size.shape[0]):
        n, s0 = size[b], start[b]
        for i in range(n):
            r, e = s0 + i, edge_start[b] + i * n
            g = gout[r]
            for j in range(n):
                for k in range(heads):
                    weight[k * dh : (k + 1) * dh] = alpha[e + j, k]
                p = pair[e + j]
                for c in range(d):
                    m = z[e + j, c] + table[p, c] + node[s0 + j, c]
                    prod[c] = g[c] * max(m, SLOPE * m)
                    dz[e + j, c] = weight[c] * g[c] * (_ONE if m > 0 else SLOPE)
                for k in range(heads):
                    dalpha[k] = _sum(prod, k * dh, (k + 1) * dh)
                    dz[e + j, d + k] = dalpha[k]  # parked here until the softmax's backward below
            for k in range(heads):
                dot = np.float32(0.0)
                for j in range(n):
                    dot += alpha[e + j, k] * dz[e + j, d + k]
                acc = np.float32(0.0)
                for j in range(n):
                    s = z[e + j, d + k] + table[pair[e + j], d + k] + node[s0 + j, d + k] + node[r, d + heads + k]
                    grad = alpha[e + j, k] * (dz[e + j, d + k] - dot) * (_ONE if s > 0 else SLOPE)
                    dz[e + j, d + k] = grad
                    acc += grad
                dnode[r, d + heads + k] = acc
            for j in range(n):  # robot j's and the type pair's shares of every edge (i, j), in order
                p = pair[e + j]
                for c in range(width):
                    dnode[s0 + j, c] += dz[e + j, c]
                    dtable[p, c] += dz[e + j, c]


@njit(cache=True, nogil=True, inline="always")
def _sum(x, start, stop):  # pragma: no cover - compiled
    """x[start:stop].sum() for a length that is a multiple of 4 (a head's 16 columns), in four
    interleaved partial sums: four add chains at once instead of one, and inlined (numba's IR), where
    a call per head to a fastmath-vectorized sum cost a sixth of the backward pass (1.86 -> 1.55 ms
    for a PCP minibatch's edges, one thread). The order of the additions differs from a plain sum's:
    float rounding only."""
    a0 = a1 = a2 = a3 = np.float32(0.0)
    for c in range(start, stop, 4):
        a0 += x[c]
        a1 += x[c + 1]
        a2 += x[c + 2]
        a3 += x[c + 3]
    return (a0 + a1) + (a2 + a3)


class EdgeStage(torch.autograd.Function):
    """``out = edge_stage(z, node, table, pair, packed, heads)`` with the fused backward (see the
    module)."""

    @staticmethod
    def forward(ctx, z, node, table, pair, packed, heads):
        z, node, table = (t.detach().contiguous() for t in (z, node, table))
        out = torch.empty((node.shape[0], z.shape[1] - heads), dtype=z.dtype)
        alpha = torch.empty((z.shape[0], heads), dtype=z.dtype)
        arrays = (z.numpy(), node.numpy(), pair.numpy(), table.numpy())
        tables = (packed.size, packed.start, packed.edge_start)

        def run(teams, part):
            _forward(*arrays, *(t[teams] for t in tables), heads, out.numpy(), alpha.numpy())

        on_threads(run, packed.size, parts())
        ctx.save_for_backward(z, node, table, pair, alpha)
        ctx.packed, ctx.heads = packed, heads
        return out

    @staticmethod
    def backward(ctx, gout):
        z, node, table, pair, alpha = ctx.saved_tensors
        packed, n_parts = ctx.packed, parts()
        dz, dnode = torch.empty_like(z), torch.zeros_like(node)
        dtables = torch.zeros((n_parts, *table.shape), dtype=table.dtype)  # one per part, summed after
        arrays = (z.numpy(), node.numpy(), pair.numpy(), table.numpy())
        tables = (packed.size, packed.start, packed.edge_start)
        gout = gout.contiguous()

        def run(teams, part):
            inputs = (*arrays, *(t[teams] for t in tables), alpha.numpy(), gout.numpy())
            _backward(*inputs, ctx.heads, dz.numpy(), dnode.numpy(), dtables[part].numpy())

        on_threads(run, packed.size, n_parts)
        return dz, dnode, dtables.sum(0), None, None, None


def edge_stage(z, node, table, pair, packed, heads: int) -> torch.Tensor:
    """The heads' weighted messages (R, d) of a packed batch (``packed``, a
    :class:`~comat.models.packing.PackedTeams`; see the module docstring); float32 CPU tensors,
    ``pair`` (M,) int64 each edge's row of ``table`` (T², d + K)."""
    return EdgeStage.apply(z, node, table, pair, packed, heads)
