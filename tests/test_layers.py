"""The attention and action-scoring layers' fast paths against torch's own kernels (issue 48):
the additive attention mask gives the same bits; the log-softmax over a short last dimension the
same bits here and the last bit at most elsewhere; the softmax over a short last dimension, taken
only where a gradient is recorded, differs from torch's in the last bit at most, and the update's
loss and gradients stay within float rounding."""

import pytest
import torch

from comat.models.layers import SHORT_LAST_DIM, Attention, log_softmax_last, score_actions, softmax_last


def _scores(shape, seed=0, masked=0.3):
    g = torch.Generator().manual_seed(seed)
    x = torch.randn(shape, generator=g) * 3
    x = x.masked_fill(torch.rand(shape, generator=g) < masked, float("-inf"))
    x[..., 0] = 0.5  # no row all -inf, as attention guarantees
    return x


@pytest.mark.parametrize("shape", [(640, 7, 5), (33, 5), (64, 4, 7, 7), (5, 1), (8, 15), (8, 16), (8, 40)])
def test_log_softmax_last_agrees_with_torch(shape):
    # The same bits on the 2-core AVX-512 machine it was measured on; the last bit is all another
    # CPU's vector path may change, so the test asks for that much.
    x = torch.randn(shape, generator=torch.Generator().manual_seed(1)) * 4
    assert torch.allclose(log_softmax_last(x), torch.log_softmax(x, -1), rtol=1e-6, atol=1e-7)
    if shape[-1] >= SHORT_LAST_DIM:
        assert torch.equal(log_softmax_last(x), torch.log_softmax(x, -1))


@pytest.mark.parametrize("shape", [(640, 4, 7, 7), (64, 1, 3, 3), (8, 2, 15, 15), (8, 2, 16, 16), (4, 20, 20)])
def test_softmax_last_agrees_with_torch_within_rounding(shape):
    x = _scores(shape)
    fast, ref = softmax_last(x), torch.softmax(x, -1)
    assert torch.allclose(fast, ref, rtol=0, atol=2e-7)
    assert torch.equal(fast == 0, ref == 0)  # masked entries exactly 0 in both
    if shape[-1] >= SHORT_LAST_DIM:
        assert torch.equal(fast, ref)  # long rows keep torch's kernel


def _masked_fill_attend(q, k, v, mask):
    """The attention as it was before the additive mask (the reference)."""
    scores = (q @ k.transpose(-2, -1)) * (q.shape[-1] ** -0.5)
    return torch.softmax(scores.masked_fill(~mask, float("-inf")), -1) @ v


@pytest.mark.parametrize("mask_shape", [(1, 1, 7, 7), (32, 1, 1, 7), (32, 1, 7, 7)])
def test_additive_mask_is_masked_fill_bit_for_bit_when_acting(mask_shape):
    g = torch.Generator().manual_seed(2)
    q, k, v = (torch.randn(32, 4, 7, 16, generator=g) for _ in range(3))
    mask = torch.ones(7, 7, dtype=torch.bool).tril().expand(mask_shape) if mask_shape[-2] == 7 else None
    if mask is None:
        mask = torch.rand(mask_shape, generator=g) > 0.3
        mask[..., 0] = True
    with torch.no_grad():  # acting: torch's softmax, so the same bits as before
        assert torch.equal(Attention._attend(q, k, v, mask), _masked_fill_attend(q, k, v, mask))


def test_update_path_gives_the_references_loss_and_gradients_within_rounding(monkeypatch):
    torch.manual_seed(3)
    attn = Attention(64, 4)
    x = torch.randn(96, 7, 64)
    mask = torch.ones(7, 7, dtype=torch.bool).tril()[None]
    actions = torch.randint(0, 5, (96, 7))
    robots = torch.rand(96, 7) > 0.2

    def loss_and_grads(attend):
        attn.zero_grad()
        with torch.enable_grad():
            logits = attn(x, x, x, mask)[..., :5] * 10
            if attend is _masked_fill_attend:
                logp_all = torch.log_softmax(logits, -1)
                logp = logp_all.gather(-1, actions[..., None])[..., 0] * robots
                entropy = -(logp_all.exp() * logp_all).sum(-1) * robots
            else:
                logp, entropy = score_actions(logits, actions, robots)
            loss = -(logp.sum() + 0.01 * entropy.sum())
            loss.backward()
        return loss.detach(), [p.grad.clone() for p in attn.parameters()]

    fast_loss, fast_grads = loss_and_grads(Attention._attend)
    reference = staticmethod(lambda q, k, v, mask=None, scaled=False: _masked_fill_attend(q, k, v, mask))
    monkeypatch.setattr(Attention, "_attend", reference)
    ref_loss, ref_grads = loss_and_grads(_masked_fill_attend)
    assert torch.allclose(fast_loss, ref_loss, rtol=1e-6, atol=0)
    for fast, ref in zip(fast_grads, ref_grads):
        assert torch.allclose(fast, ref, rtol=1e-5, atol=1e-6 * ref.abs().max().item())
