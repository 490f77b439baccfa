"""CASH as the authors' code builds it (issue 65, ``comat/models/cash.py``): what each part reads,
the generated hidden layer, the hypernetworks' LayerNorm and initialisation, any team size, and
determinism. Training, resume, policy files and the bench for ``cash`` and ``cash-caps`` are in
tests/test_ippo_cash.py, tests/test_rl_resume.py and tests/test_policy_file.py."""

from __future__ import annotations

import pytest
import torch
from torch import nn

from comat.models import ObsLayout
from comat.models.cash import Cash, CashConfig
from comat.tasks.arctic import ArcticTransport
from comat.tasks.pcp import PCP

SMALL = CashConfig(hidden=16, hyper_hidden=8)


def _team(layout: ObsLayout, n: int, seed: int = 0) -> tuple[torch.Tensor, torch.Tensor]:
    """(1, n, D) observations with valid type one-hots, and an all-real mask."""
    g = torch.Generator().manual_seed(seed)
    obs = torch.randn(1, n, layout.obs_dim, generator=g)
    types = torch.arange(n) % layout.n_types
    obs[..., 4 : 4 + layout.n_types] = torch.nn.functional.one_hot(types, layout.n_types).float()
    return obs, torch.ones(1, n, dtype=torch.bool)


def _net(layout: ObsLayout, config: CashConfig = SMALL, seed: int = 0, spread: bool = True) -> Cash:
    torch.manual_seed(seed)
    net = Cash(layout, config)
    if spread:  # away from CASH's near-zero start, so generated layers differ visibly between inputs
        for layer in (*net.bias_net, net.weight_net[-1]):
            if isinstance(layer, nn.Linear):
                nn.init.normal_(layer.weight)
    return net


def _identity(layout: ObsLayout) -> slice:
    return slice(4, 4 + layout.n_types + layout.n_caps)


def test_shapes_and_defaults_are_cashs():
    layout = ObsLayout.for_task(PCP())
    net = Cash(layout)
    assert (net.config.hidden, net.config.hyper_hidden, net.config.hyper_layers, net.config.hyper_init) == (
        128,
        16,
        4,
        0.2,
    )
    obs, mask = _team(layout, 5)
    obs, mask = obs.expand(3, -1, -1), mask.expand(3, -1)
    actions, logp, values = net.act(obs, mask)
    assert actions.shape == logp.shape == values.shape == (3, 5)
    weights, biases = net.generated_layer(obs, mask)
    assert weights.shape == (3, 5, 128, 128) and biases.shape == (3, 5, 128)
    assert net.head.in_features == 128 and net.head.out_features == 5  # the shared output layer


def test_the_hidden_layer_is_generated_per_robot_and_the_fast_path_equals_building_it():
    layout = ObsLayout.for_task(PCP())
    net = _net(layout)
    obs, mask = _team(layout, 4)
    weights, biases = net.generated_layer(obs, mask)
    h = net._encode(obs)
    explicit = torch.relu((h[..., None, :] @ weights)[..., 0, :] + biases)
    torch.testing.assert_close(net._hidden(obs, mask), explicit, rtol=1e-5, atol=1e-5)
    assert not torch.allclose(weights[0, 0], weights[0, 1])  # each robot its own layer
    torch.testing.assert_close(net._logits(obs, mask), net.head(explicit), rtol=1e-5, atol=1e-5)


def test_the_encoder_reads_neither_type_nor_capabilities_and_the_hypernetworks_read_the_observation():
    layout = ObsLayout.for_task(ArcticTransport())  # three types, three capabilities
    net = _net(layout)
    obs, mask = _team(layout, 3)
    other_identity = obs.clone()
    other_identity[..., _identity(layout)] = torch.rand_like(obs[..., _identity(layout)])
    assert torch.equal(net._encode(obs), net._encode(other_identity))
    # the same capabilities, another place: CASH's generated layer moves with the context
    moved = obs.clone()
    moved[0, 0, :2] += 0.5
    assert not torch.allclose(net.generated_layer(obs, mask)[0][0, 0], net.generated_layer(moved, mask)[0][0, 0])
    # other capabilities (and so another team summary): another generated layer for every robot
    caps = slice(4 + layout.n_types, 4 + layout.n_types + layout.n_caps)
    other_caps = obs.clone()
    other_caps[0, 1, caps] += 0.3
    before, after = net.generated_layer(obs, mask)[0], net.generated_layer(other_caps, mask)[0]
    assert all(not torch.allclose(before[0, i], after[0, i]) for i in range(3))


def test_the_hypernetworks_are_separate_with_layer_norm_before_every_relu_and_cashs_initialisation():
    layout = ObsLayout.for_task(PCP())
    net = Cash(layout)
    for hyper, out in ((net.weight_net, 128 * 128), (net.bias_net, 128)):
        kinds = [type(m) for m in hyper]
        assert kinds == [nn.Linear, nn.LayerNorm, nn.ReLU] * 3 + [nn.Linear]
        assert all(m.normalized_shape == (16,) and m.eps == 1e-6 for m in hyper if isinstance(m, nn.LayerNorm))
        assert hyper[-1].out_features == out
    assert not set(map(id, net.weight_net.parameters())) & set(map(id, net.bias_net.parameters()))
    # orthogonal with gain 0.2: the rows (or columns) of every linear weight are orthogonal, of norm 0.2
    for layer in (m for m in net.weight_net if isinstance(m, nn.Linear)):
        w = layer.weight if layer.weight.shape[0] <= layer.weight.shape[1] else layer.weight.T
        torch.testing.assert_close(w @ w.T, 0.04 * torch.eye(w.shape[0]), atol=1e-5, rtol=0)
        assert not layer.bias.any()
    assert not any(p.any() for p in net.bias_net.parameters() if p.dim() == 2)  # gain 0: all zero
    assert not net.head.bias.any() and torch.linalg.matrix_norm(net.head.weight, 2) < 0.0101


def test_the_bias_network_at_cashs_zero_start_stays_one_learned_bias():
    """A consequence of CASH's code kept on purpose: only the bias network's last bias gets a gradient."""
    layout = ObsLayout.for_task(PCP())
    torch.manual_seed(0)
    net = Cash(layout, SMALL)
    obs, mask = _team(layout, 5)
    logp, _, values = net.evaluate_actions(obs, mask, torch.ones(1, 5, dtype=torch.long))
    (logp.sum() + values.sum()).backward()
    grads = {name: p.grad for name, p in net.bias_net.named_parameters()}
    last = f"{len(net.bias_net) - 1}.bias"
    assert grads[last].abs().sum() > 0
    assert all(not g.any() for name, g in grads.items() if name != last)


@pytest.mark.parametrize("task", [PCP(), ArcticTransport()])
def test_every_team_size_from_2_to_20_with_the_same_weights_and_padding_changes_nothing(task):
    layout = ObsLayout.for_task(task)
    net = _net(layout)
    for n in range(2, 21):
        obs, mask = _team(layout, n, seed=n)
        logits = net._logits(obs, mask)
        values = net.values(obs, mask)
        padded = torch.cat([obs, torch.randn(1, 20 - n + 1, layout.obs_dim)], 1)  # junk in the padded slots
        padded_mask = torch.cat([mask, torch.zeros(1, 20 - n + 1, dtype=torch.bool)], 1)
        torch.testing.assert_close(net._logits(padded, padded_mask)[:, :n], logits, rtol=1e-5, atol=1e-6)
        torch.testing.assert_close(net.values(padded, padded_mask)[:, :n], values, rtol=1e-5, atol=1e-6)
        assert not net.values(padded, padded_mask)[:, n:].any()
        # robots' order is not information: permuting the team permutes the outputs
        perm = torch.randperm(n, generator=torch.Generator().manual_seed(n))
        torch.testing.assert_close(net._logits(obs[:, perm], mask)[0], logits[0, perm], rtol=1e-5, atol=1e-6)


def test_same_seed_same_network_and_same_actions():
    layout = ObsLayout.for_task(PCP())
    a, b = _net(layout, spread=False), _net(layout, spread=False)
    for (name, p), q in zip(a.state_dict().items(), b.state_dict().values()):
        assert torch.equal(p, q), name
    obs, mask = _team(layout, 6)
    first = a.act(obs, mask, generator=torch.Generator().manual_seed(1))
    second = b.act(obs, mask, generator=torch.Generator().manual_seed(1))
    for x, y in zip(first, second):
        assert torch.equal(x, y)


def test_an_acting_only_cash_refuses_values_in_one_line():
    layout = ObsLayout.for_task(PCP())
    net = Cash(layout, SMALL, critic=False)
    obs, mask = _team(layout, 3)
    assert net.act(obs, mask, deterministic=True)[2] is None
    with pytest.raises(ValueError, match=r"has no critic .*checkpoint\.pt"):
        net.values(obs, mask)


@pytest.mark.parametrize(
    "field, value, match",
    [
        ("version", 1, r"models\.cash\.version must be 2 .* got 1; version 1, comat's first CASH, is --algo cash-caps"),
        ("hyper_layers", 0, r"models\.cash\.hyper_layers must be an integer >= 1, got 0"),
        ("hyper_init", -0.1, r"models\.cash\.hyper_init must be a finite number >= 0, got -0\.1"),
    ],
)
def test_bad_config_is_refused_naming_the_field(field, value, match):
    with pytest.raises(ValueError, match=match):
        CashConfig(**{field: value})
