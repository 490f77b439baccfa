"""COMAT's weight description (``comat.models.comat_schema``) is the single source: the torch
model holds exactly its parameters, and every array it lists is produced by the model and read by
the compiled kernels and the numpy runtime; a changed shape fails with the array's name, the
expected and the received shape; the decision mode reaches every implementation by name."""

import numpy as np
import pytest
import torch

from comat.models import Comat, ComatConfig, ObsLayout
from comat.models import comat_schema as schema
from comat.models.act_kernels import (
    COMAT_DECODE_MATS,
    COMAT_DECODE_VECS,
    comat_decode,
    comat_decode_args,
    comat_encode,
    comat_encode_args,
)
from comat.models.layers import TypeHeads
from sim2real.runtime import ComatRuntime
from sim2real.weights import comat_arrays

LAYOUT = ObsLayout(obs_dim=11, n_types=2, n_caps=3)
SMALL = {"embed": 8, "heads": 2, "heat_blocks": 2, "edge_embed": 4}
CONFIGS = {
    "type_heads": {"decision": "type_heads"},
    "shared_trunk": {"decision": "shared_trunk", "heat_form": "paper", "obs_embed": False, "node_ffn": False},
    "adapters": {"decision": "adapters", "root_weight": True, "edge_frame": "world"},
}


def model(options: dict) -> Comat:
    torch.manual_seed(0)
    m = Comat(LAYOUT, ComatConfig(**SMALL, **options)).eval()
    with torch.no_grad():
        for p in m.parameters():  # off the initialization: no zero part, logits of order 1
            p.add_(0.3 * torch.randn_like(p))
    return m


def team(n: int = 4, seed: int = 0) -> np.ndarray:
    """(N, D) float32 observations of one team with both types and valid headings."""
    g = np.random.default_rng(seed)
    obs = g.normal(size=(n, LAYOUT.obs_dim)).astype(np.float32)
    theta = g.uniform(-3, 3, n)
    obs[:, 2], obs[:, 3] = np.cos(theta), np.sin(theta)
    obs[:, 4:6] = np.eye(2, dtype=np.float32)[np.arange(n) % 2]
    return obs


def numpy_arrays(m: Comat, critic: bool) -> dict[str, np.ndarray]:
    return {k: v.detach().numpy().copy() for k, v in m.acting_arrays(critic=critic).items()}


def run_kernels(arrays: dict, config: dict, obs: np.ndarray):
    """rep, values and logits of the compiled encoder and decoder for one team."""
    enc = {k: arrays[k] for k in schema.encoder_shapes(config, critic=True)}
    dec = {k: arrays[k] for k in schema.decoder_shapes(config)}
    node_ws, mats, vecs, flags = comat_encode_args(enc, config)
    mask = np.ones((1, len(obs)), bool)
    rep, values = comat_encode(node_ws, mats, vecs, obs[None], mask, config["heads"], config["n_types"], *flags)
    mats, vecs, shared = comat_decode_args(dec, config)
    noise = np.zeros((len(obs), 1, schema.N_ACTIONS), np.float32)
    _, logits = comat_decode(mats, vecs, rep, obs[None], mask, noise, True, config["heads"], config["n_types"], shared)
    return rep, values, logits


@pytest.mark.parametrize("name", list(CONFIGS))
def test_the_torch_model_holds_exactly_the_described_parameters(name):
    m = model(CONFIGS[name])
    config = m.weights_config
    assert config["decision"] == name and m.decision == schema.DecisionMode(name) and m.heads.mode == m.decision
    assert {k: tuple(v.shape) for k, v in m.state_dict().items()} == schema.parameter_shapes(config)
    acting = m.acting_arrays(critic=True)
    assert list(acting) == list(schema.weight_shapes(config, critic=True))
    assert {k: tuple(v.shape) for k, v in acting.items()} == schema.weight_shapes(config, critic=True)
    # the export's arrays are the acting ones, critic excluded, in the file's order
    exported_config, arrays = comat_arrays(m)
    assert exported_config == config and list(arrays) == list(schema.weight_shapes(config))


@pytest.mark.parametrize("name", list(CONFIGS))
def test_every_described_array_is_read_by_the_kernels_and_the_runtime(name):
    """Each array, moved, changes what the compiled kernels and the numpy runtime compute: none
    is listed but unused, and the kernels' argument tuples hold every decoder array once."""
    m = model(CONFIGS[name])
    config = m.weights_config
    arrays = numpy_arrays(m, critic=True)
    obs = team()
    assert sorted(COMAT_DECODE_MATS + COMAT_DECODE_VECS) == sorted(schema.decoder_shapes(config))
    base = run_kernels(arrays, config, obs)
    runtime_arrays = {k: arrays[k] for k in schema.weight_shapes(config)}
    probs = ComatRuntime(config, runtime_arrays).action_probs(obs)[1]
    # the three implementations agree (float32 kernels, float64 runtime)
    with torch.no_grad():
        rep_t, values_t = m.encode(torch.from_numpy(obs)[None], torch.ones(1, len(obs), dtype=torch.bool))
    np.testing.assert_allclose(base[0], rep_t.numpy(), atol=2e-5)
    np.testing.assert_allclose(base[1], values_t.numpy(), atol=5e-5)
    np.testing.assert_allclose(probs, torch.softmax(torch.from_numpy(base[2][0]).double(), -1).numpy(), atol=2e-5)
    rng = np.random.default_rng(1)
    for name_, array in arrays.items():
        # random, not constant: a constant shift is lost in a LayerNorm or a softmax
        moved = {**arrays, name_: array + rng.normal(0, 0.5, array.shape).astype(np.float32)}
        out = run_kernels(moved, config, obs)
        changed = [not np.array_equal(a, b) for a, b in zip(out, base)]
        assert any(changed), f"the kernels do not read {name_}"
        if name_.startswith("critic."):
            continue
        moved_probs = ComatRuntime(config, {k: moved[k] for k in runtime_arrays}).action_probs(obs)[1]
        assert not np.array_equal(moved_probs, probs), f"the runtime does not read {name_}"


def test_a_changed_shape_names_the_array_expected_and_received():
    m = model(CONFIGS["shared_trunk"])
    config = m.weights_config
    arrays = numpy_arrays(m, critic=True)
    E, C, T = SMALL["embed"], LAYOUT.n_caps, LAYOUT.n_types
    wrong = np.zeros((T * E, E + C), np.float32)  # the per-type hidden layer of type_heads
    message = rf"heads\.first\.weight: expected \({E}, {E + C}\), got \({T * E}, {E + C}\)"
    dec = {k: arrays[k] for k in schema.decoder_shapes(config)}
    with pytest.raises(ValueError, match=message):
        comat_decode_args({**dec, "heads.first.weight": wrong}, config)
    runtime_arrays = {k: arrays[k] for k in schema.weight_shapes(config)}
    with pytest.raises(ValueError, match=message):
        ComatRuntime(config, {**runtime_arrays, "heads.first.weight": wrong})
    enc = {k: arrays[k] for k in schema.encoder_shapes(config, critic=True)}
    with pytest.raises(ValueError, match=r"critic\.2\.weight: expected \(1, 8\), got \(2, 8\)"):
        comat_encode_args({**enc, "critic.2.weight": np.zeros((2, E), np.float32)}, config)
    with pytest.raises(ValueError, match=r"missing \['ln1\.bias'\]"):
        comat_decode_args({k: v for k, v in dec.items() if k != "ln1.bias"}, config)
    # a parameter of the torch model replaced with another shape: its compiled acting refuses
    with torch.no_grad():
        m.ln4.weight = torch.nn.Parameter(torch.ones(E + 1))
    obs = torch.from_numpy(team())[None]
    mask = torch.ones(1, obs.shape[1], dtype=torch.bool)
    with torch.no_grad(), pytest.raises(ValueError, match=rf"ln4\.weight: expected \({E},\), got \({E + 1},\)"):
        m.decode_compiled(torch.zeros(1, obs.shape[1], E), obs, mask, None)


def test_a_model_that_departs_from_the_description_is_refused_when_built(monkeypatch):
    """Changing the torch module without the description (here: the description changed) fails at
    construction, naming the array."""
    real = schema.parameter_shapes

    def changed(config, critic=True):
        return {**real(config, critic), "fc.0.weight": (3, 3)}

    monkeypatch.setattr("comat.models.comat.parameter_shapes", changed)
    with pytest.raises(ValueError, match=r"fc\.0\.weight: expected \(3, 3\), got \(8, 8\)"):
        Comat(LAYOUT, ComatConfig(**SMALL))


@pytest.mark.parametrize("mode", schema.DECISIONS)
def test_the_decision_mode_fixes_the_decision_layer(mode):
    """``TypeHeads(mode=...)`` builds the trained form ``decision_shapes`` gives, and its acting
    form is that of ``decision_shapes`` without ``trained``."""
    heads = TypeHeads(6, 8, 5, 3, mode=mode)
    trained = schema.decision_shapes(mode, 6, 8, 5, 3, trained=True)
    assert {k: tuple(v.shape) for k, v in heads.state_dict().items()} == trained
    acting = {k: tuple(v.shape) for k, v in heads.acting_arrays().items()}
    assert acting == schema.decision_shapes(mode, 6, 8, 5, 3)
    assert acting["first.weight"][0] == (8 if schema.DecisionMode(mode).shared_hidden else 24)


def test_configs_name_their_keys_and_modes():
    config = schema.weights_config(LAYOUT, ComatConfig(**SMALL))
    assert tuple(config) == schema.CONFIG_KEYS and config["decision"] == "adapters"
    with pytest.raises(ValueError, match=r"decision must be one of \['type_heads', 'shared_trunk', 'adapters'\]"):
        schema.weight_shapes({**config, "decision": "mixture"})
    with pytest.raises(ValueError, match=r"missing \['decision'\]"):
        schema.weight_shapes({k: v for k, v in config.items() if k != "decision"})
