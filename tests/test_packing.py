"""A batch of teams packed as one graph (:mod:`comat.models.packing`, issue 48): the team tables,
the edges' features equal to the padded graph's bit for bit, COMAT's packed scoring equal to its
padded scoring within float rounding, and when a batch is packed at all."""

from __future__ import annotations

import numpy as np
import torch

from comat import kernels
from comat.models import PAPER_FORM, Comat, ComatConfig
from comat.models.features import ObsLayout, edge_features, packed_edge_features
from comat.models.packing import pack, split_teams
from comat.tasks.pcp import PCP

LAYOUT = ObsLayout.for_task(PCP())


def _teams(sizes, N=None, seed=0):
    g = torch.Generator().manual_seed(seed)
    N = N or max(sizes)
    obs = torch.randn(len(sizes), N, LAYOUT.obs_dim, generator=g)
    theta = torch.rand(len(sizes), N, generator=g) * 6.28
    obs[..., 2], obs[..., 3] = torch.cos(theta), torch.sin(theta)
    types = torch.randint(0, LAYOUT.n_types, (len(sizes), N), generator=g)
    obs[..., 4 : 4 + LAYOUT.n_types] = torch.nn.functional.one_hot(types, LAYOUT.n_types).float()
    mask = torch.arange(N)[None] < torch.tensor(sizes)[:, None]
    return obs * mask[..., None], mask, torch.randint(0, 5, mask.shape, generator=g) * mask


def test_the_tables_list_each_teams_robots_and_edges_in_order():
    mask = torch.tensor([[1, 1, 0], [0, 0, 0], [1, 1, 1]], dtype=torch.bool)
    types = torch.tensor([[1, 0, 0], [0, 0, 0], [0, 1, 1]])
    p = pack(mask, types, 2)
    assert p.slots.tolist() == [0, 1, 6, 7, 8]
    assert p.first.tolist() == [True, False, True, False, False]
    assert p.size.tolist() == [2, 0, 3] and p.start.tolist() == [0, 2, 2] and p.edge_start.tolist() == [0, 4, 4]
    assert p.edge_i.tolist() == [0, 0, 1, 1] + [2, 2, 2, 3, 3, 3, 4, 4, 4]
    assert p.edge_j.tolist() == [0, 1, 0, 1] + [2, 3, 4] * 3
    assert p.types.tolist() == [1, 0, 0, 1, 1] and [r.tolist() for r in p.by_type] == [[1, 2], [0, 3, 4]]
    order = torch.cat(p.by_type)
    assert torch.equal(order[p.type_inverse], torch.arange(5))
    x = torch.arange(9.0).view(3, 3)
    assert torch.equal(p.scatter(p.gather(x)), x * mask)
    assert pack(torch.tensor([[True, False, True]]), torch.zeros(1, 3, dtype=torch.long), 1) is None


def test_packed_edges_are_the_padded_graphs_real_edges():
    obs, mask, _ = _teams([3, 1, 5, 4], N=6)
    p = pack(mask, LAYOUT.types(obs), LAYOUT.n_types)
    for world in (False, True):
        attr, etype, emask = edge_features(obs, mask, LAYOUT, world)
        packed_attr, packed_type = packed_edge_features(p.gather(obs), p, LAYOUT, world)
        want = attr[emask]
        assert torch.equal(packed_type, etype[emask])
        assert torch.equal(packed_attr[:, [0, 1, 3, 4]], want[:, [0, 1, 3, 4]])  # the same bits
        assert torch.allclose(packed_attr[:, 2], want[:, 2], rtol=2e-7, atol=0)  # distance: within one ulp


def test_packed_scoring_equals_padded_scoring_and_values():
    obs, mask, actions = _teams([3, 5, 7, 1, 7, 2, 6], N=8, seed=4)
    torch.manual_seed(0)
    net = Comat(LAYOUT)
    assert net._packing(obs, mask) is not None
    packed = net.evaluate_actions(obs, mask, actions)
    with kernels.reference_path():
        padded = net.evaluate_actions(obs, mask, actions)
    for got, want in zip(packed, padded, strict=True):
        assert torch.allclose(got, want, atol=1e-5) and not (got * ~mask).any()
    with torch.no_grad():
        values = net.values(obs, mask)
        with kernels.reference_path():
            assert torch.allclose(values, net.values(obs, mask) * mask, atol=1e-5)


def test_a_batch_is_packed_only_where_the_fused_kernels_apply():
    obs, mask, _ = _teams([3, 5], N=6)
    torch.manual_seed(0)
    assert Comat(LAYOUT)._packing(obs, mask) is not None
    assert Comat(LAYOUT)._packing(obs, mask.flip(1)) is None  # padding first
    assert Comat(LAYOUT, ComatConfig(**PAPER_FORM))._packing(obs, mask) is None  # no fused paper form
    assert Comat(LAYOUT, ComatConfig(embed=32))._packing(obs, mask) is None  # 8-wide heads
    assert Comat(LAYOUT).double()._packing(obs.double(), mask) is None
    with kernels.reference_path():
        assert Comat(LAYOUT)._packing(obs, mask) is None


def test_split_teams_covers_every_team_once_in_parts_of_about_equal_work():
    sizes = np.array([7, 3, 5, 7, 0, 2, 7, 7, 1])
    parts = split_teams(sizes, 2)
    assert len(parts) == 2 and parts[0].start == 0 and parts[0].stop == parts[1].start and parts[1].stop == len(sizes)
    work = [int((sizes[p] ** 2).sum()) for p in parts]
    assert abs(work[0] - work[1]) <= 49
    assert split_teams(sizes, 1) == [slice(0, len(sizes))]
    assert split_teams(sizes[:1], 2) == [slice(0, 1)]


def test_values_in_passes_of_about_the_chunks_edges_equal_one_pass(monkeypatch):
    import comat.models.comat as comat_module

    obs, mask, _ = _teams([3, 5, 7, 1, 7, 2, 6, 4, 0, 5], N=8, seed=5)
    torch.manual_seed(0)
    net = Comat(LAYOUT)
    with torch.no_grad():
        whole = net.values(obs, mask)  # 214 edges: one pass
        passes = []
        real = net._packed_values
        monkeypatch.setattr(net, "_packed_values", lambda o, m: passes.append(int((m.sum(1) ** 2).sum())) or real(o, m))
        monkeypatch.setattr(comat_module, "VALUE_CHUNK_EDGES", 60)
        chunked = net.values(obs, mask)
    assert len(passes) == 4 and sum(passes) == 214 and max(passes) <= 60 + 49  # split at team borders
    assert torch.allclose(chunked, whole, atol=1e-6) and not (chunked * ~mask).any()
