"""COMAT's update fast paths against the slow reference (issue 48): the batch packed as one graph
(:mod:`comat.models.packing`) with the fused HEAT edge stage (:mod:`comat.models.heat_kernels`),
the merged per-edge maps of :class:`HEATBlock`, and scoring a padded batch one group of team sizes
at a time — the loss and every gradient equal the straightforward implementation's within float
rounding, on a batch of teams of every size with padded slots."""

from __future__ import annotations

import itertools

import pytest
import torch
import torch.nn.functional as F

from comat import kernels
from comat.models import PAPER_FORM, Comat, ComatConfig, ObsLayout
from comat.models.autoregressive import size_buckets
from comat.models.heat_kernels import edge_stage
from comat.models.packing import pack
from comat.tasks.hmt import HMT
from comat.tasks.pcp import PCP


def reference_block(block, x, types, edge_attr, edge_type, edge_mask, packed=None):
    """HEATBlock.forward as it read before issue 48 (one map per term, one pass per op), on a padded
    batch (``packed`` None): the reference."""
    xt = sum(torch.where((types == t)[..., None], layer(x), 0.0) for t, layer in enumerate(block.node))
    xt = F.leaky_relu(xt, 0.2)
    ea = F.leaky_relu(block.edge_attr(edge_attr), 0.2)
    et = F.leaky_relu(block.edge_type.weight, 0.2)
    pair = F.one_hot(edge_type, et.shape[0]).to(x.dtype)
    score = block.att_i(xt)[:, :, None] + block.att_attr(ea) + pair @ block.att_type(et) + block.att_j(xt)[:, None]
    score = F.leaky_relu(score, 0.2).masked_fill(~edge_mask[..., None], float("-inf"))
    alpha = torch.softmax(score, dim=2).nan_to_num(0.0)
    if block.form == "paper":
        w = alpha.mean(-1)[..., None]
        out = block.msg_attr((w * ea).sum(2)) + block.msg_type((w * pair).sum(2) @ et) + block.msg_j(w[..., 0] @ xt)
    else:
        msg = F.leaky_relu(block.msg_attr(ea) + pair @ block.msg_type(et) + block.msg_j(xt)[:, None], 0.2)
        B, N, _, E = msg.shape
        K = block.heads
        out = block.msg_out((alpha[..., None] * msg.view(B, N, N, K, E // K)).sum(2).reshape(B, N, E))
    return out + xt if block.root else out


def _batch(task, n_max: int, batch: int = 96, seed: int = 0):
    """Observations of teams of every size up to n_max, padded at the end, with types one-hot."""
    layout = ObsLayout.for_task(task)
    g = torch.Generator().manual_seed(seed)
    obs = torch.randn(batch, n_max, layout.obs_dim, generator=g)
    obs[..., 2:4] = F.normalize(obs[..., 2:4], dim=-1)  # heading cos, sin
    types = torch.randint(0, layout.n_types, (batch, n_max), generator=g)
    obs[..., 4 : 4 + layout.n_types] = F.one_hot(types, layout.n_types).float()
    sizes = torch.randint(1, n_max + 1, (batch,), generator=g)
    mask = torch.arange(n_max)[None] < sizes[:, None]
    actions = torch.randint(0, 5, (batch, n_max), generator=g) * mask
    return layout, obs, mask, actions


def _loss_and_grads(net, obs, mask, actions):
    net.zero_grad()
    logp, entropy, values = net.evaluate_actions(obs, mask, actions)
    loss = 1.3 * logp.sum() + 0.7 * entropy.sum() + (values**2).sum()
    loss.backward()
    return loss.detach(), {n: p.grad.clone() for n, p in net.named_parameters() if p.grad is not None}


@pytest.mark.parametrize("form", ["default", "paper", "root"])
@pytest.mark.parametrize("task", [PCP(), HMT()], ids=["pcp", "hmt"])
def test_fast_paths_give_the_reference_loss_and_gradients(form, task, monkeypatch):
    config = {"default": ComatConfig(), "paper": ComatConfig(**PAPER_FORM), "root": ComatConfig(root_weight=True)}[form]
    layout, obs, mask, actions = _batch(task, 8)
    torch.manual_seed(0)
    net = Comat(layout, config)
    fast = _loss_and_grads(net, obs, mask, actions)
    assert (net._packing(obs, mask) is not None) == (form != "paper")  # the paper form: padded groups
    # the reference: every block as it was, the whole batch padded to 8 slots in one pass
    monkeypatch.setattr(type(net.heat[0]), "forward", reference_block)
    monkeypatch.setattr(Comat, "_packing", lambda self, obs, mask: None)
    monkeypatch.setattr(Comat, "group_by_team_size", False)
    slow = _loss_and_grads(net, obs, mask, actions)
    assert torch.allclose(fast[0], slow[0], rtol=1e-5)
    assert fast[1].keys() == slow[1].keys() and len(fast[1]) == len(list(net.parameters()))
    for name, grad in slow[1].items():
        assert torch.allclose(fast[1][name], grad, rtol=1e-4, atol=1e-5 * grad.abs().max()), name


def _packed_stage_inputs(sizes, d=16, K=4, pairs=4, seed=1):
    g = torch.Generator().manual_seed(seed)
    sizes = torch.tensor(sizes)
    mask = torch.arange(int(sizes.max()))[None] < sizes[:, None]
    packed = pack(mask, torch.zeros(mask.shape, dtype=torch.long), 1)
    M, R = packed.edge_i.shape[0], packed.slots.shape[0]
    z = torch.randn(M, d + K, generator=g, requires_grad=True)
    node = torch.randn(R, d + 2 * K, generator=g, requires_grad=True)
    table = torch.randn(pairs, d + K, generator=g, requires_grad=True)
    pair = torch.randint(0, pairs, (M,), generator=g)
    return packed, (z, node, table, pair), torch.randn(R, d, generator=g)


def torch_stage(z, node, table, pair, packed, K):
    """The packed edge stage in torch: each robot i's softmax over its team's edges, per head."""
    R, d = node.shape[0], z.shape[1] - K
    i, j = packed.edge_i, packed.edge_j
    zm, zs = (z + table[pair] + node[j, : d + K]).split([d, K], -1)
    score = F.leaky_relu(zs + node[i, d + K :], 0.2)
    top = torch.full((R, K), -torch.inf).scatter_reduce(0, i[:, None].expand(-1, K), score.detach(), "amax")
    w = torch.exp(score - top[i])
    alpha = w / torch.zeros(R, K).index_add(0, i, w)[i]
    msg = alpha.repeat_interleave(d // K, -1) * F.leaky_relu(zm, 0.2)
    return torch.zeros(R, d).index_add(0, i, msg)


@pytest.mark.parametrize("threads", [1, 2])
def test_the_fused_edge_stage_is_the_torch_stage_forward_and_backward(threads):
    packed, inputs, gout = _packed_stage_inputs([3, 0, 1, 7, 5, 2, 7, 4])  # an empty team too
    before = torch.get_num_threads()
    torch.set_num_threads(threads)  # 2: the teams in two halves, one in a helper thread
    try:
        fused = edge_stage(*inputs, packed, 4)
        grads = torch.autograd.grad(fused, inputs[:3], gout)
    finally:
        torch.set_num_threads(before)
    ref = torch_stage(*inputs, packed, 4)
    ref_grads = torch.autograd.grad(ref, inputs[:3], gout)
    assert torch.allclose(fused, ref, atol=1e-5)
    for got, want in zip(grads, ref_grads, strict=True):
        assert torch.allclose(got, want, atol=1e-4)


def test_without_kernels_the_block_runs_the_torch_stage(monkeypatch):
    layout, obs, mask, actions = _batch(PCP(), 7)
    torch.manual_seed(0)
    net = Comat(layout, ComatConfig())
    with_kernels = _loss_and_grads(net, obs, mask, actions)
    with kernels.reference_path():
        without = _loss_and_grads(net, obs, mask, actions)
    assert torch.allclose(with_kernels[0], without[0], rtol=1e-5)


def test_size_buckets_are_contiguous_cover_every_size_and_group_when_groups_cost_more():
    buckets = size_buckets([2, 3, 4, 5, 6, 7, 8], [100] * 7)
    assert buckets[0][0] == 2 and buckets[-1][1] == 8
    assert all(a[1] < b[0] for a, b in itertools.pairwise(buckets))
    assert size_buckets([7], [640]) == [(7, 7)]
    assert size_buckets([3, 5, 7], [1440, 320, 800]) == [(3, 3), (5, 5), (7, 7)]  # a large batch: every size
    assert size_buckets([2, 3], [1, 1]) == [(2, 3)]  # two teams: one call
