"""The fused short attention (:mod:`comat.models.attention_kernels`) against torch's path in
:class:`comat.models.layers.Attention` (issue 48): the same outputs and every gradient within float
rounding, for a team's sequence lengths, shared and per-team masks and rows with nothing to attend
to; and it is taken only where it applies (a gradient recorded, the compiled head width)."""

from __future__ import annotations

import pytest
import torch

from comat import kernels
from comat.models.attention_kernels import HEAD_WIDTH, short_attention
from comat.models.layers import Attention, causal


def _run(att, x, y, mask, fused: bool, monkeypatch):
    """Output and gradients (inputs, then parameters) of a cross attention, fused or torch's."""
    with monkeypatch.context() as m:
        if not fused:
            m.setattr(Attention, "_fused", lambda self, q, k: False)
        for t in (x, y, *att.parameters()):
            t.grad = None
        out = att(x, y, y, mask)
        (out * torch.linspace(-1.0, 1.0, out.shape[-1])).sum().backward()
    return [out.detach(), x.grad.clone(), y.grad.clone(), *(p.grad.clone() for p in att.parameters())]


@pytest.mark.parametrize("length", [1, 3, 7, 16])
@pytest.mark.parametrize("mask_kind", ["none", "causal", "per_team"])
def test_fused_attention_gives_torch_outputs_and_gradients(length, mask_kind, monkeypatch):
    g = torch.Generator().manual_seed(length)
    heads = 4
    torch.manual_seed(length)
    att = Attention(heads * HEAD_WIDTH, heads)
    B, D = 40, heads * HEAD_WIDTH
    x = torch.randn(B, length, D, generator=g, requires_grad=True)
    y = torch.randn(B, length, D, generator=g, requires_grad=True)
    mask = {
        "none": None,
        "causal": causal(length)[None],
        "per_team": torch.rand(B, length, length, generator=g) > 0.4,
    }[mask_kind]
    if mask is not None and mask.shape[0] == B:
        mask[0] = False  # a padded team: its rows attend to the first key (Attention.forward)
    assert att._fused(x, y)
    fused = _run(att, x, y, mask, True, monkeypatch)
    reference = _run(att, x, y, mask, False, monkeypatch)
    for got, want in zip(fused, reference, strict=True):
        assert torch.allclose(got, want, rtol=1e-4, atol=1e-6 * max(1.0, float(want.abs().max())))


def test_the_kernel_alone_is_masked_softmax_attention_per_head():
    g = torch.Generator().manual_seed(3)
    B, Lq, Lk, H = 6, 5, 4, 2
    q, k, v = (torch.randn(B, n, H * HEAD_WIDTH, generator=g, requires_grad=True) for n in (Lq, Lk, Lk))
    mask = torch.rand(B, Lq, Lk, generator=g) > 0.5
    mask[..., 0] = True
    out = short_attention(q, k, v, mask, H)
    split = [t.view(B, -1, H, HEAD_WIDTH).transpose(1, 2) for t in (q, k, v)]
    scores = (split[0] @ split[1].transpose(-2, -1)) / HEAD_WIDTH**0.5
    weights = torch.softmax(scores.masked_fill(~mask[:, None], float("-inf")), -1)
    ref = (weights @ split[2]).transpose(1, 2).reshape(B, Lq, -1)
    assert torch.allclose(out, ref, atol=1e-6)
    gout = torch.randn(out.shape, generator=g)
    for got, want in zip(torch.autograd.grad(out, (q, k, v), gout), torch.autograd.grad(ref, (q, k, v), gout)):
        assert torch.allclose(got, want, atol=1e-5)


def test_the_fused_path_is_taken_only_where_it_applies():
    att, wide = Attention(4 * HEAD_WIDTH, 4), Attention(64, 1)  # MAT's one 64-wide head: torch's path
    x = torch.zeros(2, 7, 4 * HEAD_WIDTH)
    assert att._fused(x, x) and not wide._fused(x, x)
    assert not att._fused(x, torch.zeros(2, 17, 4 * HEAD_WIDTH))  # longer than a team
    with torch.no_grad():
        assert not att._fused(x, x)  # acting and evaluation keep torch's bits
    with kernels.reference_path():
        assert not att._fused(x, x)
