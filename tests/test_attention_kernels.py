"""The fused causal attention of a packed batch (:mod:`comat.models.attention_kernels`) against
torch's path in :class:`comat.models.layers.Attention` on the same teams padded: the same outputs
and every gradient within float rounding, for teams of every size (an empty one too), on one thread
and split over two."""

from __future__ import annotations

import pytest
import torch

from comat.models.attention_kernels import HEAD_WIDTH, causal_attention
from comat.models.layers import Attention, causal
from comat.models.packing import pack


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("sizes", [[1], [3, 0, 7, 1, 5, 16, 2], [7] * 9])
def test_fused_attention_gives_torch_outputs_and_gradients(sizes, threads):
    g = torch.Generator().manual_seed(len(sizes))
    heads = 4
    torch.manual_seed(len(sizes))
    att = Attention(heads * HEAD_WIDTH, heads)
    B, N, D = len(sizes), max(sizes), heads * HEAD_WIDTH
    mask = torch.arange(N)[None] < torch.tensor(sizes)[:, None]
    packed = pack(mask, torch.zeros(B, N, dtype=torch.long), 1)
    x = torch.randn(B, N, D, generator=g, requires_grad=True)
    y = torch.randn(B, N, D, generator=g, requires_grad=True)
    weight = torch.linspace(-1.0, 1.0, D)

    def outputs_and_grads(packed_path: bool):
        for t in (x, y, *att.parameters()):
            t.grad = None
        if packed_path:
            out = packed.scatter(att(packed.gather(x), packed.gather(y), packed.gather(y), packed=packed))
        else:
            out = att(x, y, y, causal(N)[None]) * mask[..., None]
        (out * weight).sum().backward()
        return [out.detach(), x.grad.clone(), y.grad.clone(), *(p.grad.clone() for p in att.parameters())]

    before = torch.get_num_threads()
    torch.set_num_threads(threads)  # 2: the teams in two halves, one in a helper thread
    try:
        fused = outputs_and_grads(True)
    finally:
        torch.set_num_threads(before)
    reference = outputs_and_grads(False)
    for got, want in zip(fused, reference, strict=True):
        assert torch.allclose(got, want, rtol=1e-4, atol=1e-6 * max(1.0, float(want.abs().max())))


def test_the_kernel_alone_is_causal_softmax_attention_per_head():
    g = torch.Generator().manual_seed(3)
    H, n = 2, 5
    packed = pack(torch.ones(1, n, dtype=torch.bool), torch.zeros(1, n, dtype=torch.long), 1)
    q, k, v = (torch.randn(n, H * HEAD_WIDTH, generator=g, requires_grad=True) for _ in range(3))
    out = causal_attention(q, k, v, packed, H)
    split = [t.view(n, H, HEAD_WIDTH).transpose(0, 1) for t in (q, k, v)]
    scores = (split[0] @ split[1].transpose(-2, -1)) / HEAD_WIDTH**0.5
    weights = torch.softmax(scores.masked_fill(~causal(n), float("-inf")), -1)
    ref = (weights @ split[2]).transpose(0, 1).reshape(n, -1)
    assert torch.allclose(out, ref, atol=1e-6)
    gout = torch.randn(out.shape, generator=g)
    for got, want in zip(torch.autograd.grad(out, (q, k, v), gout), torch.autograd.grad(ref, (q, k, v), gout)):
        assert torch.allclose(got, want, atol=1e-5)
