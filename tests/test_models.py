"""Models: autoregressive decoding (torch step loop and compiled kernels) agrees with teacher
forcing and with itself uncached; padding is invisible; per-type sharing; QMIX's mixer is
monotonic; graphs match the environment's."""

from unittest import mock

import numpy as np
import pytest
import torch

from comat import kernels
from comat.envs import make_vec_env
from comat.models import PAPER_FORM, Comat, ComatConfig
from comat.models.features import ObsLayout, edge_features
from comat.models.mappo import Mappo
from comat.models.mat import Mat, MatConfig
from comat.models.qmix import QmixAgents, QmixMixer
from comat.tasks.hmt import MaterialTransport
from comat.tasks.pcp import PredatorCapturePrey

LAYOUT = ObsLayout.for_task(PredatorCapturePrey())


def fake_obs(B: int, N: int, layout: ObsLayout = LAYOUT, seed: int = 0, n_real=None):
    """Observations with valid type one-hots, headings and capabilities; padded slots zero."""
    g = torch.Generator().manual_seed(seed)
    obs = torch.randn(B, N, layout.obs_dim, generator=g)
    theta = torch.rand(B, N, generator=g) * 6.28
    obs[..., 2], obs[..., 3] = torch.cos(theta), torch.sin(theta)
    types = torch.randint(0, layout.n_types, (B, N), generator=g)
    obs[..., 4 : 4 + layout.n_types] = torch.nn.functional.one_hot(types, layout.n_types).float()
    n_real = torch.full((B,), N) if n_real is None else torch.as_tensor(n_real)
    mask = torch.arange(N)[None] < n_real[:, None]
    return obs * mask[..., None], mask


def models():
    torch.manual_seed(0)
    return {
        "comat": Comat(LAYOUT),
        "comat_paper": Comat(LAYOUT, ComatConfig(**PAPER_FORM)),
        "mat": Mat(LAYOUT, MatConfig(max_robots=64)),
        # the encoder options (HEAT root term, per-robot feed-forward sublayer)
        "comat_options": Comat(LAYOUT, ComatConfig(root_weight=True, node_ffn=True)),
        # the audit's options: observation embedding with residual blocks, small messages,
        # a shared decision trunk; HEAT's reference message form with world-frame edges
        "comat_embed": Comat(
            LAYOUT, ComatConfig(obs_embed=True, message_gain=0.01, node_ffn=True, decision="shared_trunk")
        ),
        "comat_reference": Comat(LAYOUT, ComatConfig(obs_embed=True, heat_form="reference", edge_frame="world")),
        "comat_adapters": Comat(LAYOUT, ComatConfig(decision="adapters")),
    }


def decoding(path: str):
    """``act``'s decoding path: the torch step loop, or the compiled kernels (which it takes
    when no gradient is recorded)."""
    return kernels.reference_path() if path == "loop" else torch.no_grad()


PATHS = ["loop", "compiled"]


@pytest.mark.parametrize("path", PATHS)
@pytest.mark.parametrize(
    "name", ["comat", "comat_paper", "comat_options", "comat_embed", "comat_reference", "comat_adapters", "mat"]
)
@pytest.mark.parametrize("n", list(range(1, 17)))
def test_autoregressive_logps_equal_teacher_forced(name, n, path):
    model = models()[name]
    obs, mask = fake_obs(4, n, seed=n)
    gen = torch.Generator().manual_seed(n)
    # the compiled path takes no torch decoder step
    with decoding(path), mock.patch.object(model, "decode_step", wraps=model.decode_step) as step:
        actions, logp, values = model.act(obs, mask, generator=gen)
    assert step.call_count == (n if path == "loop" else 0)
    logp_tf, entropy, values_tf = model.evaluate_actions(obs, mask, actions)
    torch.testing.assert_close(logp, logp_tf, atol=1e-5, rtol=0)
    # COMAT's compiled path encodes compiled too: float32 rounding, not bit for bit
    torch.testing.assert_close(values, values_tf, atol=1e-6 if path == "loop" else 1e-5, rtol=0)
    assert (entropy > 0).all() and (logp < 0).all()


@pytest.mark.parametrize("path", PATHS)
@pytest.mark.parametrize(
    "name", ["comat", "comat_paper", "comat_options", "comat_embed", "comat_reference", "comat_adapters", "mat"]
)
@pytest.mark.parametrize("n", [1, 3, 8, 16])
def test_cached_decoding_equals_uncached(name, n, path):
    model = models()[name]
    obs, mask = fake_obs(5, n, seed=100 + n, n_real=[n, max(1, n - 1), n, 1, max(1, n // 2)])
    for deterministic in (True, False):
        with decoding(path):
            a1, l1, v1 = model.act(obs, mask, deterministic=deterministic, generator=torch.Generator().manual_seed(3))
        with decoding(path):  # the same encoder path (the reference path's is torch's alone)
            a2, l2, v2 = model.act_uncached(
                obs, mask, deterministic=deterministic, generator=torch.Generator().manual_seed(3)
            )
        assert torch.equal(a1, a2)
        torch.testing.assert_close(l1, l2, atol=1e-5, rtol=0)
        torch.testing.assert_close(v1, v2, atol=0 if path == "loop" else 1e-5, rtol=0)


def _with_padding(obs, mask, extra: int, seed: int = 9):
    """The same teams with ``extra`` more slots holding garbage (masked out)."""
    B, _N, D = obs.shape
    junk = torch.randn(B, extra, D, generator=torch.Generator().manual_seed(seed)) * 5
    junk[..., 4:6] = torch.nn.functional.one_hot(torch.randint(0, 2, (B, extra)), 2).float()
    return torch.cat([obs, junk], 1), torch.cat([mask, torch.zeros(B, extra, dtype=torch.bool)], 1)


@pytest.mark.parametrize("name", ["comat", "comat_embed", "comat_reference", "mat", "mappo"])
def test_padding_slots_change_nothing(name):
    torch.manual_seed(0)
    model = models()[name] if name != "mappo" else Mappo(LAYOUT, state_dim=7)
    obs, mask = fake_obs(6, 5, seed=1, n_real=[5, 3, 4, 2, 5, 1])
    obs_p, mask_p = _with_padding(obs, mask, 3)
    state = torch.randn(6, 7)
    actions = torch.randint(0, 5, (6, 5)) * mask
    l1, e1, v1 = model.evaluate_actions(obs, mask, actions, state)
    l2, e2, v2 = model.evaluate_actions(obs_p, mask_p, torch.cat([actions, torch.randint(0, 5, (6, 3))], 1), state)
    torch.testing.assert_close(l1, l2[:, :5], atol=1e-6, rtol=0)
    torch.testing.assert_close(e1 * mask, e2[:, :5] * mask, atol=1e-6, rtol=0)
    torch.testing.assert_close(v1, v2[:, :5], atol=1e-6, rtol=0)
    assert (l2[:, 5:] == 0).all() and (v2[:, 5:] == 0).all()
    # Sampled too for the autoregressive models: their noise is drawn robot-major (N, B, A), so
    # padding slots at the end leave the real robots' draws unchanged.
    for path in PATHS:
        for deterministic in (True, False) if name != "mappo" else (True,):
            g1, g2 = torch.Generator().manual_seed(4), torch.Generator().manual_seed(4)
            with decoding(path):
                a1, _, _ = model.act(obs, mask, state, deterministic=deterministic, generator=g1)
                a2, _, _ = model.act(obs_p, mask_p, state, deterministic=deterministic, generator=g2)
            assert torch.equal(a1, a2[:, :5]) and (a2[:, 5:] == 0).all()


@pytest.mark.parametrize("task", [PredatorCapturePrey(), MaterialTransport()], ids=["pcp", "hmt"])
@pytest.mark.parametrize(
    "config",
    [
        ComatConfig(),
        ComatConfig(**PAPER_FORM),
        ComatConfig(embed=32, heads=2, heat_blocks=3, edge_embed=16, **{**PAPER_FORM, "root_weight": True}),
        ComatConfig(obs_embed=True, message_gain=0.01, node_ffn=True, decision="shared_trunk"),
        ComatConfig(
            embed=32,
            heads=2,
            heat_blocks=3,
            edge_embed=16,
            obs_embed=True,
            heat_form="reference",
            edge_frame="world",
            node_ffn=True,
            root_weight=True,
        ),
        ComatConfig(heat_form="reference", edge_frame="world"),
    ],
    ids=["default", "paper", "paper_other", "embed", "reference", "raw_reference"],
)
def test_compiled_encoder_equals_torch(task, config):
    """COMAT's compiled HEAT encoder and critic (used by ``act``) against ``encode``: teams of
    every size 1–7 padded to 7, weights moved off their initialisation."""
    layout = ObsLayout.for_task(task)
    torch.manual_seed(0)
    model = Comat(layout, config)
    for p in model.parameters():
        p.data.add_(0.3 * torch.randn_like(p))
    obs, mask = fake_obs(9, 7, layout, seed=3, n_real=[7, 3, 5, 1, 2, 7, 4, 6, 5])
    with torch.no_grad():
        rep, values = model.encode(obs, mask)
        rep_c, values_c = model.encode_compiled(obs, mask)
    assert values.abs().max() > 1.0
    torch.testing.assert_close(rep_c[mask], rep[mask], atol=1e-5, rtol=1e-5)
    torch.testing.assert_close(values_c[mask], values[mask], atol=2e-5, rtol=1e-5)


@pytest.mark.parametrize(
    "name", ["comat", "comat_paper", "comat_heads", "comat_shared", "comat_adapters", "mat", "mat_deep"]
)
@pytest.mark.parametrize("batch", [1, 7, 64])
def test_compiled_decoding_equals_the_torch_loop(name, batch):
    """Same actions and logits (to float32 rounding) as the step-by-step torch reference, for
    greedy and sampled decoding, teams of mixed sizes with padding, other head/block counts."""
    torch.manual_seed(1)
    layout = ObsLayout.for_task(MaterialTransport())  # three robot types
    model = {
        "comat": lambda: Comat(layout),
        "comat_heads": lambda: Comat(layout, ComatConfig(embed=48, heads=3)),
        "comat_shared": lambda: Comat(layout, ComatConfig(decision="shared_trunk")),
        "comat_adapters": lambda: Comat(layout, ComatConfig(decision="adapters")),
        "comat_paper": lambda: Comat(layout, ComatConfig(**PAPER_FORM)),
        "mat": lambda: Mat(layout, MatConfig(max_robots=64)),
        "mat_deep": lambda: Mat(layout, MatConfig(embed=32, heads=2, blocks=2, max_robots=64)),
    }[name]()
    for p in model.parameters():  # away from the near-zero initial heads: logits of order 1
        p.data.add_(0.3 * torch.randn_like(p))
    n_real = torch.randint(1, 10, (batch,), generator=torch.Generator().manual_seed(batch))
    obs, mask = fake_obs(batch, 9, layout, seed=batch, n_real=n_real)
    with torch.no_grad():
        rep, _ = model.encode(obs, mask)
        for noise in (None, -torch.log(-torch.log(torch.rand(9, batch, 5).clamp(1e-20, 1.0)))):
            a_loop, logits_loop = model._decode_loop(rep, obs, mask, noise)
            a_fast, logits_fast = model.decode_compiled(rep, obs, mask, noise)
            assert torch.equal(a_fast, a_loop)
            assert logits_loop.abs().max() > 0.5
            torch.testing.assert_close(logits_fast, logits_loop, atol=2e-5, rtol=1e-5)


@pytest.mark.parametrize("name", ["comat", "mat", "mappo"])
def test_padded_robots_get_zero_gradient(name):
    torch.manual_seed(0)
    model = models()[name] if name != "mappo" else Mappo(LAYOUT, state_dim=7)
    obs, mask = fake_obs(4, 6, seed=2, n_real=[6, 3, 4, 2])
    obs = obs.clone().requires_grad_(True)
    state = torch.randn(4, 7)
    actions = torch.randint(0, 5, (4, 6)) * mask
    logp, entropy, values = model.evaluate_actions(obs, mask, actions, state)
    (logp.sum() + entropy.sum() + values.sum()).backward()
    assert obs.grad[~mask].abs().max() == 0
    assert obs.grad[mask].abs().max() > 0
    # and the parameter gradients are those of the unpadded teams
    grads = {k: p.grad.clone() for k, p in model.named_parameters() if p.grad is not None}
    obs_p, mask_p = _with_padding(obs.detach(), mask, 2)
    model.zero_grad()
    lp, en, va = model.evaluate_actions(
        obs_p, mask_p, torch.cat([actions, torch.zeros(4, 2, dtype=torch.long)], 1), state
    )
    (lp.sum() + en.sum() + va.sum()).backward()
    for k, p in model.named_parameters():
        if k in grads:
            torch.testing.assert_close(p.grad, grads[k], atol=1e-5, rtol=1e-4)


@pytest.mark.parametrize("n", [2, 8, 16, 32, 40])
def test_comat_acts_on_any_team_size(n):
    model = models()["comat"]
    obs, mask = fake_obs(3, n, seed=n)
    actions, logp, values = model.act(obs, mask, generator=torch.Generator().manual_seed(0))
    assert actions.shape == (3, n) and torch.isfinite(logp).all() and torch.isfinite(values).all()
    torch.testing.assert_close(logp, model.evaluate_actions(obs, mask, actions)[0], atol=1e-5, rtol=0)


def test_mat_refuses_teams_over_its_maximum():
    model = Mat(LAYOUT)  # max_robots 8, as the paper trains it
    obs, mask = fake_obs(2, 9, seed=0)
    with pytest.raises(ValueError, match="at most 8 robots"):
        model.act(obs, mask)
    obs, mask = fake_obs(2, 9, seed=0, n_real=[8, 5])  # 9 slots, the 9th padded: fine
    model.act(obs, mask)


def test_comat_uses_capabilities_and_types():
    """The decision layer reads [h ‖ c]: changing only a robot's capability changes its policy."""
    model = models()["comat"]
    for p in model.heads.parameters():  # the default init makes the heads near-zero
        torch.nn.init.normal_(p, std=0.5)
    obs, mask = fake_obs(1, 4, seed=3)
    logp_all = lambda o: torch.log_softmax(
        model.decode_all(model.encode(o, mask)[0], model._start(1, None).repeat(1, 4, 1), o, mask), -1
    )
    base = logp_all(obs)
    changed = obs.clone()
    changed[0, 2, 4 + LAYOUT.n_types] += 0.5  # robot 2's first capability
    assert not torch.allclose(logp_all(changed)[0, 2], base[0, 2], atol=1e-4)


def test_type_heads_share_within_a_type():
    """MAPPO's actor and QMIX's agents: same type and observation -> same output; another type
    with the same observation otherwise -> another head."""
    torch.manual_seed(0)
    mappo, agents = Mappo(LAYOUT, state_dim=3), QmixAgents(LAYOUT)
    for p in list(mappo.actor.parameters()) + list(agents.parameters()):
        torch.nn.init.normal_(p, std=0.3)
    obs, mask = fake_obs(1, 3, seed=5)
    obs[0, 1] = obs[0, 0]
    obs[0, 2] = obs[0, 0]
    obs[0, 2, 4:6] = 1 - obs[0, 0, 4:6]  # robot 2: the other type
    for out in (mappo._logits(obs), agents(obs, mask)):
        torch.testing.assert_close(out[0, 0], out[0, 1])
        assert not torch.allclose(out[0, 0], out[0, 2])


def test_qmix_mixer_is_monotonic_and_ignores_dead_slots():
    torch.manual_seed(0)
    mixer = QmixMixer(state_dim=6)
    q = torch.randn(16, 8, requires_grad=True)
    mask = torch.arange(8)[None] < torch.randint(1, 9, (16, 1))
    state = torch.randn(16, 6)
    q_tot = mixer(q, mask, state)
    q_tot.sum().backward()
    assert (q.grad >= 0).all() and (q.grad[~mask] == 0).all()
    q2 = q.detach().clone()
    q2[~mask] = 1e3
    torch.testing.assert_close(mixer(q2, mask, state), q_tot.detach())
    with pytest.raises(ValueError, match="8 robot slots"):
        mixer(torch.randn(2, 9), torch.ones(2, 9, dtype=torch.bool), torch.randn(2, 6))


@pytest.mark.parametrize("env_id, task", [("pcp_v0", PredatorCapturePrey()), ("hmt_v0", MaterialTransport())])
def test_model_graph_matches_the_environment(env_id, task):
    """COMAT rebuilds the team graph from observations: it equals env.graph() (plus self-loops)."""
    env = make_vec_env(env_id, 3, seed=2, tier="unicycle")
    _obs, _info = env.reset()
    env.step(np.random.default_rng(0).integers(0, 5, (3, env.max_robots)))
    g = env.graph()
    layout = ObsLayout.for_task(task)
    o, m = torch.as_tensor(g["nodes"], dtype=torch.float32), torch.as_tensor(g["mask"])
    attr, etype, emask = edge_features(o, m, layout)
    off = torch.as_tensor(g["edge_mask"])
    np.testing.assert_allclose(attr[off].numpy(), g["edge_attr"][g["edge_mask"]], atol=1e-5)
    assert torch.equal(etype[off], torch.as_tensor(g["edge_type"])[off])
    assert torch.equal(emask & ~torch.eye(o.shape[1], dtype=torch.bool), off)
    assert torch.equal(layout.types(o)[m], torch.as_tensor(g["node_type"])[m])


@pytest.mark.parametrize("task", [PredatorCapturePrey(), MaterialTransport()], ids=["pcp", "hmt"])
def test_default_comat_keeps_each_robots_own_observation(task):
    """The encoder audit's measure at initialization: how much more a robot's action logits
    and value move with its own observation than with a teammate's (‖∂/∂o_i‖ : mean_j ‖∂/∂o_j‖).
    The paper form mixes the team before a robot sees itself (2–12×); the default keeps each
    robot's own state, as MAT does (hundreds×)."""
    layout = ObsLayout.for_task(task)

    def ratio(config):
        torch.manual_seed(0)
        model = Comat(layout, config)
        obs, mask = fake_obs(16, 5, layout, seed=7)
        obs.requires_grad_(True)
        rep, values = model.encode(obs, mask)
        tokens = torch.cat([model._start(16, None), model._token(torch.zeros(16, 4, dtype=torch.long))], 1)
        logits = model.decode_all(rep, tokens, obs, mask)
        out = []
        for y in (logits[:, 2].sum(-1), values[:, 2]):  # robot 2's outputs
            (g,) = torch.autograd.grad(y.sum(), obs, retain_graph=True)
            g = g.norm(dim=-1).mean(0)  # (N,) per input robot
            out.append(float(g[2] / torch.cat([g[:2], g[3:]]).mean()))
        return out

    assert min(ratio(ComatConfig())) > 50
    assert max(ratio(ComatConfig(**PAPER_FORM))) < 20


@pytest.mark.parametrize(
    "override, message",
    [
        ("models.comat.heads=0", "models.comat.heads must be an integer >= 1, got 0"),
        ("models.comat.embed=0", "models.comat.embed must be an integer >= 1, got 0"),
        ("models.comat.heads=-2", "models.comat.heads must be an integer >= 1, got -2"),
        ("models.comat.heat_blocks=0", "models.comat.heat_blocks must be an integer >= 1, got 0"),
        ("models.mat.embed=6", "models.mat.embed must be divisible by models.mat.heads"),
        ("models.mappo.hidden=0", "models.mappo.hidden must be an integer >= 1, got 0"),
        ("models.qmix.mixing_embed=0", "models.qmix.mixing_embed must be an integer >= 1, got 0"),
    ],
)
def test_model_sizes_out_of_range_get_one_line_errors_and_leave_nothing(tmp_path, capsys, override, message):
    from comat.cli import main

    algo = override.split(".")[1]
    extra = ["models.mat.heads=4"] if algo == "mat" else []
    out = tmp_path / "run"
    assert main(["train", "--algo", algo, "--task", "pcp", "--steps", "6", "--out", str(out), override, *extra]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err
    assert not out.exists()


@pytest.mark.parametrize(
    "override, message",
    [
        ("ppo.lr=abc", "ppo.lr must be float, got 'abc'"),
        ("ppo.clip=-1", "ppo.clip must be"),
    ],
)
def test_trainer_errors_name_the_key_as_overrides_spell_it(tmp_path, capsys, override, message):
    """``ppo.lr=abc`` was reported as ``trainer.lr`` (issue 32 item 9)."""
    from comat.cli import main

    out = tmp_path / "run"
    assert main(["train", "--algo", "mappo", "--task", "pcp", "--steps", "6", "--out", str(out), override]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err and "trainer." not in err
    assert not out.exists()


def test_an_empty_out_is_refused_before_anything_is_written(tmp_path, monkeypatch, capsys):
    """``rollout --out ''`` wrote into the current folder (issue 32 item 9)."""
    from comat.cli import main

    monkeypatch.chdir(tmp_path)
    assert main(["rollout", "--policy", "heuristic", "--task", "pcp", "--out", ""]) == 2
    assert "--out must be a file or folder path, got '' (empty)" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_adapters_start_as_one_decision_layer_that_every_type_trains():
    """``decision: adapters``: at initialization both types' output layers are the shared one (the
    types' own parts are zero), and a loss on one type's robots moves the shared layer."""
    from comat.models.layers import TypeHeads

    torch.manual_seed(0)
    heads = TypeHeads(6, 8, 5, 2, mode="adapters")
    x = torch.randn(4, 3, 6)
    one_hot = torch.nn.functional.one_hot(torch.tensor([0, 1, 1]), 2).float().expand(4, 3, 2)
    w2, b2 = heads.output_layer()
    assert torch.equal(w2[0], w2[1]) and torch.equal(b2[0], b2[1]) and heads.first.weight.shape == (8, 6)
    other = torch.nn.functional.one_hot(torch.tensor([1, 0, 0]), 2).float().expand(4, 3, 2)
    assert torch.allclose(heads(x, one_hot), heads(x, other))
    heads(x, torch.nn.functional.one_hot(torch.ones(4, 3, dtype=torch.long), 2).float()).sum().backward()
    assert heads.w2_shared.grad.abs().sum() > 0 and heads.w2.grad[0].abs().sum() == 0 < heads.w2.grad[1].abs().sum()
