"""sim2real runtime: the numpy COMAT forward pass equals torch's on real observations; the
weights file round-trips, refuses another model, and the runtime imports only numpy + stdlib."""

import ast
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from comat import make_vec_env
from comat.models import PAPER_FORM, Comat, ComatConfig, ObsLayout
from comat.tasks.hmt import MaterialTransport
from comat.tasks.pcp import PredatorCapturePrey
from comat.team import random_team
from sim2real import runtime
from sim2real.runtime import ComatRuntime, load_weights, pack_weights, save_weights, unpack_weights
from sim2real.weights import comat_arrays, export_weights

TASKS = {"pcp": ("pcp_v0", PredatorCapturePrey()), "hmt": ("hmt_v0", MaterialTransport())}


def make_model(task: str, kind: str, config: ComatConfig | None = None) -> Comat:
    """A seeded COMAT; "trained" adds noise everywhere and moves every LayerNorm off identity,
    and widens the actor heads so the action distributions are neither uniform nor one-hot."""
    torch.manual_seed(0 if kind == "init" else 1)
    model = Comat(ObsLayout.for_task(TASKS[task][1]), config)
    if kind == "trained":
        with torch.no_grad():
            for name, p in model.named_parameters():
                if name.startswith(("ln", "heat_norm")) and name.endswith("weight"):
                    p.copy_(1 + 0.3 * torch.randn_like(p))
                else:
                    p.add_(0.1 * torch.randn_like(p))
            model.heads.w2.mul_(5.0)
    return model.eval()


def team_obs(task: str, size: int) -> np.ndarray:
    """(N, D) observations of a mixed team of ``size`` robots, a few random steps into an episode."""
    rng = np.random.default_rng(size)
    env = make_vec_env(TASKS[task][0], 1, seed=size, tier="unicycle", team=random_team(rng, task, "test", size))
    obs, _info = env.reset()
    for _ in range(3):
        obs, *_ = env.step(rng.integers(0, 5, (1, obs.shape[1])))
    mask = env.agent_mask[0]
    assert mask.sum() == size and mask[:size].all()
    return obs[0, mask]


def torch_probs(model: Comat, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Greedy actions from ``act`` and the distributions they came from, by teacher forcing."""
    o = torch.as_tensor(obs, dtype=torch.float32)[None]
    mask = torch.ones(1, len(obs), dtype=torch.bool)
    with torch.no_grad():
        actions, logp, _ = model.act(o, mask, deterministic=True)
        rep, _ = model.encode(o, mask)
        tokens = torch.cat([model._start(1, o.device), model._token(actions[:, :-1])], 1)
        probs = torch.softmax(model.decode_all(rep, tokens, o, mask), -1)
    # The teacher-forced pass is the one act() took: same log-prob of every chosen action.
    torch.testing.assert_close(probs.gather(-1, actions[..., None])[..., 0].log(), logp, atol=1e-5, rtol=0)
    return actions[0].numpy(), probs[0].numpy()


@pytest.mark.parametrize("kind", ["init", "trained"])
@pytest.mark.parametrize("task", ["pcp", "hmt"])
def test_runtime_matches_torch(task, kind, tmp_path):
    model = make_model(task, kind)
    path = tmp_path / "comat.npy"
    export_weights(model, path)
    policy = ComatRuntime.from_file(path)
    types_seen = set()
    for size in range(2, 9):
        obs = team_obs(task, size)
        types_seen.add(len(set(obs[:, 4:6].argmax(-1))))
        actions, probs = policy.action_probs(obs)
        actions_t, probs_t = torch_probs(model, obs)
        assert actions.shape == (size,) and probs.shape == (size, 5)
        np.testing.assert_allclose(probs, probs_t, atol=1e-5, rtol=0)
        np.testing.assert_array_equal(actions, actions_t)
        np.testing.assert_array_equal(actions, probs.argmax(-1))
        if kind == "trained":  # the check would be weak on near-uniform distributions
            assert probs.max(-1).mean() > 0.4
    assert types_seen == {2}  # every team mixes both robot types


OPTIONS = {
    "sizes": {},
    "root": {"root_weight": True},
    "embed": {"obs_embed": True, "message_gain": 0.01, "node_ffn": True, "decision": "shared_trunk"},
    "reference": {"obs_embed": True, "heat_form": "reference", "edge_frame": "world", "root_weight": True},
    "raw_reference_ffn": {"heat_form": "reference", "node_ffn": True},
    "adapters": {"decision": "adapters"},
}


@pytest.mark.parametrize("options", list(OPTIONS.values()), ids=list(OPTIONS))
def test_runtime_matches_torch_other_sizes(tmp_path, options):
    """Non-default widths, heads, depth and every architecture option of ComatConfig: nothing in
    the runtime assumes the defaults."""
    model = make_model("hmt", "trained", ComatConfig(embed=24, heads=3, heat_blocks=3, edge_embed=8, **options))
    save_weights(tmp_path / "w.npy", *reversed(comat_arrays(model)))
    policy = ComatRuntime.from_file(tmp_path / "w.npy")
    obs = team_obs("hmt", 5)
    actions, probs = policy.action_probs(obs)
    actions_t, probs_t = torch_probs(model, obs)
    np.testing.assert_allclose(probs, probs_t, atol=1e-5, rtol=0)
    np.testing.assert_array_equal(actions, actions_t)


def test_weights_files_without_the_architecture_flags_still_load(tmp_path):
    """Files written before the flags (root_weight, obs_embed, ...) read them as 0: the paper form."""
    config, arrays = comat_arrays(make_model("pcp", "trained", ComatConfig(**PAPER_FORM)))
    for key in runtime.FLAG_KEYS:
        del config[key]
    save_weights(tmp_path / "old.npy", arrays, config)
    assert all(ComatRuntime.from_file(tmp_path / "old.npy").config[k] == 0 for k in runtime.FLAG_KEYS)


def test_weights_file_round_trips(tmp_path):
    config, arrays = comat_arrays(make_model("pcp", "trained"))
    path = tmp_path / "w.npy"
    save_weights(path, arrays, config)
    raw = np.load(path, allow_pickle=False)  # a plain .npy: no pickle needed to read it
    assert raw.dtype.names == ("manifest", "params") and raw.dtype.hasobject is False
    config2, arrays2 = load_weights(path)
    assert config2 == config and list(arrays2) == list(runtime.expected_shapes(config))
    for name, a in arrays.items():
        assert arrays2[name].dtype == np.float32
        np.testing.assert_array_equal(arrays2[name], a)
    assert not any(k.startswith("critic.") for k in arrays2)


def test_weights_of_another_model_are_refused(tmp_path):
    changed = make_model("pcp", "init")
    changed.extra = torch.nn.Linear(2, 2)  # a module the runtime does not know: refused, not dropped
    with pytest.raises(
        ValueError, match=r"does not match the numpy runtime.*unexpected \['extra.bias', 'extra.weight'\]"
    ):
        comat_arrays(changed)
    config, arrays = comat_arrays(make_model("pcp", "init"))
    # HMT observations are wider than PCP's: an HMT config cannot take PCP weights.
    hmt_config = {**config, "obs_dim": ObsLayout.for_task(MaterialTransport()).obs_dim}
    with pytest.raises(ValueError, match=r"does not match a COMAT model.*obs_encoder\.1\.weight: expected \(64, 15\)"):
        ComatRuntime(hmt_config, arrays)
    with pytest.raises(ValueError, match=r"missing \['heads\.b2'\]"):
        pack_weights({k: v for k, v in arrays.items() if k != "heads.b2"}, config)
    # A file whose manifest lies about the config is caught on load.
    record = pack_weights(arrays, config)
    forged = record["manifest"].tobytes().replace(b'"embed":64', b'"embed":32')
    bad = np.zeros((), dtype=[("manifest", np.uint8, (len(forged),)), ("params", np.float32, record["params"].shape)])
    bad["manifest"], bad["params"] = np.frombuffer(forged, np.uint8), record["params"]
    with pytest.raises(ValueError, match="does not match a COMAT model"):
        unpack_weights(bad)
    np.save(tmp_path / "other.npy", np.zeros((3, 4), np.float32))
    with pytest.raises(ValueError, match="is not a comat-numpy-weights file"):
        load_weights(tmp_path / "other.npy")
    with pytest.raises(ValueError, match=r"obs must have shape \(N, 13\)"):
        ComatRuntime(config, arrays).action_probs(np.zeros((3, 15)))


def _imports(path) -> set[str]:
    modules = set()
    for node in ast.walk(ast.parse(Path(path).read_text())):
        if isinstance(node, ast.Import):
            modules |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            assert node.level == 0, "relative import: the file is copied into a flat submission folder"
            modules.add(node.module.split(".")[0])
    return modules


def test_runtime_imports_only_numpy_stdlib_and_the_schema_shipped_beside_it():
    from comat.models import comat_schema

    stdlib = set(sys.stdlib_module_names) | {"__future__"}
    modules = _imports(runtime.__file__)
    assert modules - {"numpy", "comat_schema"} <= stdlib, modules
    assert {"numpy", "comat_schema"} <= modules
    schema_modules = _imports(comat_schema.__file__)
    assert schema_modules - {"numpy"} <= stdlib, schema_modules


def test_version_1_files_with_the_shared_trunk_flag_still_load(tmp_path):
    """Version 1 recorded the decision layer as ``shared_trunk`` (1 for shared_trunk and adapters,
    whose output layers it stored folded): such a file reads as the same policy."""
    import json

    for decision in ("type_heads", "shared_trunk", "adapters"):
        model = make_model(
            "hmt", "trained", ComatConfig(embed=24, heads=3, heat_blocks=1, edge_embed=8, decision=decision)
        )
        config, arrays = comat_arrays(model)
        record = pack_weights(arrays, config)
        manifest = json.loads(record["manifest"].tobytes())
        old = {k: v for k, v in manifest["config"].items() if k != "decision"}
        old["shared_trunk"] = int(decision != "type_heads")
        manifest.update(version=1, config=old)
        text = json.dumps(manifest).encode()
        v1 = np.zeros((), dtype=[("manifest", np.uint8, (len(text),)), ("params", np.float32, record["params"].shape)])
        v1["manifest"], v1["params"] = np.frombuffer(text, np.uint8), record["params"]
        np.save(tmp_path / "v1.npy", v1, allow_pickle=False)
        policy = ComatRuntime.from_file(tmp_path / "v1.npy")
        assert policy.config["decision"] == ("type_heads" if decision == "type_heads" else "shared_trunk")
        obs = team_obs("hmt", 4)
        want = ComatRuntime(config, arrays).action_probs(obs)
        got = policy.action_probs(obs)
        np.testing.assert_array_equal(got[0], want[0])
        np.testing.assert_array_equal(got[1], want[1])
