"""Trainers and runs: GAE against a plain loop, masking in PPO updates, QMIX's TD target,
checkpoint -> resume equality, policies from checkpoints on unseen team sizes, bad input."""

import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from comat.cli import main
from comat.envs import make_vec_env
from comat.learners import learner_names
from comat.measure.episodes import run_episodes
from comat.models import ObsLayout
from comat.models.mappo import Mappo
from comat.rl import CheckpointError, load_checkpoint, load_policy, load_preset, resolve, train
from comat.rl.gae import gae
from comat.rl.ppo import PPOConfig, PPOTrainer, Rollout
from comat.team import random_team

TINY_MODELS = {
    "comat": {"embed": 16, "heads": 2, "heat_blocks": 1, "edge_embed": 8},
    "mat": {"embed": 16, "heads": 1, "blocks": 1},
    "mappo": {"hidden": 16},
    "qmix": {"hidden": 16, "mixing_embed": 8, "hypernet_embed": 16},
    "ippo": {"hidden": 16},
    "cash": {"hidden": 16, "hyper_hidden": 8},
    "cash-caps": {"hidden": 16, "hyper_hidden": 16},
}


def tiny(algo: str, task: str = "pcp", steps: int = 12, **overrides):
    preset = {
        "total_env_steps": steps,
        "eval_every_steps": 10**9,
        "eval_episodes_per_team": 0,
        "checkpoint_every_steps": 6,
        "ppo": {"num_envs": 2, "rollout_steps": 3, "epochs": 2, "minibatches": 2},
        "qmix": {"num_envs": 2, "batch_episodes": 2, "buffer_episodes": 8, "updates_per_episode": 1.0},
        "models": TINY_MODELS,
        **overrides,
    }
    return resolve(preset, algo, task, seed=3)


def assert_same(a, b, path="state"):
    if isinstance(a, dict):
        assert a.keys() == b.keys(), path
        for k in a:
            assert_same(a[k], b[k], f"{path}.{k}")
    elif isinstance(a, (list, tuple)):
        assert len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b)):
            assert_same(x, y, f"{path}[{i}]")
    elif isinstance(a, torch.Tensor):
        assert torch.equal(a, b), path
    else:
        assert a == b, path


# -- GAE ------------------------------------------------------------------------------------------
def test_gae_equals_a_plain_reverse_loop():
    g = torch.Generator().manual_seed(0)
    T, B, gamma, lam = 13, 4, 0.97, 0.9
    rewards, values, next_values = (torch.randn(T, B, generator=g) for _ in range(3))
    dones = torch.rand(T, B, generator=g) < 0.2
    adv, ret = gae(rewards, values, next_values, dones, gamma, lam)
    for b in range(B):
        running = 0.0
        for t in reversed(range(T)):
            if dones[t, b]:
                running = 0.0
            delta = rewards[t, b] + gamma * next_values[t, b] - values[t, b]
            running = delta + gamma * lam * running
            assert abs(adv[t, b] - running) < 1e-5
    torch.testing.assert_close(ret, adv + values)


# -- PPO: padded slots do not change an update -------------------------------------------------------
def _pad(ro: Rollout, extra: int) -> Rollout:
    def pad(x, value=0):
        if x is None:
            return None
        shape = (*x.shape[:2], extra, *x.shape[3:])
        return torch.cat([x, torch.full(shape, value, dtype=x.dtype)], 2)

    return Rollout(
        obs=pad(ro.obs),
        mask=pad(ro.mask, False),
        state=ro.state,
        actions=pad(ro.actions),
        logp=pad(ro.logp),
        values=pad(ro.values),
        rewards=ro.rewards,
        terminated=ro.terminated,
        dones=ro.dones,
        next_obs=pad(ro.next_obs),
        next_mask=pad(ro.next_mask, False),
        next_state=ro.next_state,
        episodes=ro.episodes,
    )


@pytest.mark.parametrize("algo", ["comat", "mappo"])
def test_ppo_update_ignores_padded_slots(algo):
    from comat.models import Comat, ComatConfig

    env = make_vec_env("pcp_v0", 2, seed=0, tier="unicycle")
    env.reset()
    layout = ObsLayout.for_task(env.task)
    cfg = PPOConfig(num_envs=2, rollout_steps=4, epochs=2, minibatches=2)

    def trainer():
        torch.manual_seed(0)
        policy = Comat(layout, ComatConfig(16, 2, 1, 8)) if algo == "comat" else Mappo(layout, env.core.state_size())
        return PPOTrainer(policy, env, cfg, seed=0, use_state=algo == "mappo")

    t1, t2 = trainer(), trainer()
    ro = t1.collect()
    t1.update(ro)
    t2.update(_pad(ro, 3))
    for (k, p1), p2 in zip(t1.policy.named_parameters(), t2.policy.parameters()):
        torch.testing.assert_close(p1, p2, atol=1e-6, rtol=1e-5, msg=k)


def test_gae_value_target_is_the_td_target_at_lambda_zero():
    """value_target 'gae' regresses to each robot's GAE(λ) return: at λ = 0 that is r + γ·V(o')
    from the collecting critic, which is the 'td' target of a refresh every epoch (one epoch:
    identical updates); at λ = 0.95 the targets, and so the updates, differ."""
    from comat.models import Comat, ComatConfig

    env = make_vec_env("pcp_v0", 2, seed=0, tier="unicycle")
    env.reset()
    layout = ObsLayout.for_task(env.task)

    def updated(**changes):
        torch.manual_seed(0)
        cfg = PPOConfig(num_envs=2, rollout_steps=6, epochs=1, minibatches=2, target_update_epochs=1, **changes)
        tr = PPOTrainer(Comat(layout, ComatConfig(16, 2, 1, 8)), env, cfg, seed=0)
        tr.update(ro)
        return torch.cat([p.detach().flatten() for p in tr.policy.parameters()])

    torch.manual_seed(0)
    ro = PPOTrainer(
        Comat(layout, ComatConfig(16, 2, 1, 8)), env, PPOConfig(num_envs=2, rollout_steps=6), seed=0
    ).collect()
    td = updated(gae_lambda=0.0)
    torch.testing.assert_close(updated(gae_lambda=0.0, value_target="gae"), td, atol=1e-6, rtol=1e-5)
    assert not torch.allclose(updated(gae_lambda=0.95, value_target="gae"), updated(gae_lambda=0.95), atol=1e-5)
    with pytest.raises(ValueError, match=r"ppo.value_target must be one of \['td', 'gae'\], got 'mc'"):
        PPOConfig(value_target="mc")


# -- QMIX's TD target ------------------------------------------------------------------------------
def test_qmix_learn_step_matches_a_per_step_reference():
    from comat.models.qmix import QmixAgents, QmixMixer, QmixNetConfig
    from comat.rl import QmixConfig, QmixTrainer

    env = make_vec_env("pcp_v0", 2, seed=1, tier="unicycle", max_robots=8)
    env.reset()
    net = QmixNetConfig(16, 8, 16)
    torch.manual_seed(0)
    tr = QmixTrainer(
        QmixAgents(ObsLayout.for_task(env.task), net),
        QmixMixer(env.core.state_size(), net),
        env,
        QmixConfig(
            num_envs=2, batch_episodes=2, buffer_episodes=4, standardize_rewards=False, target_update_interval=1
        ),
        seed=0,
    )
    tr.collect()
    for p in tr.target_agents.parameters():  # make online and target nets differ
        p.data.add_(0.1)
    rng_state = tr.rng.bit_generator.state  # the batch learn_step will draw
    batch = tr.buffer.sample(2, tr.rng)
    tr.rng.bit_generator.state = rng_state
    agents = {k: v.clone() for k, v in tr.agents.state_dict().items()}
    loss = 0.0
    n = 0
    with torch.no_grad():
        for e in range(2):
            m = batch["mask"][e][None]
            for t in range(int(batch["filled"][e].sum())):
                o, o2 = batch["obs"][e, t][None], batch["obs"][e, t + 1][None]
                s, s2 = batch["state"][e, t][None], batch["state"][e, t + 1][None]
                a_star = tr.agents(o2, m).argmax(-1, keepdim=True)
                q_next = tr.target_mixer(tr.target_agents(o2, m).gather(-1, a_star)[..., 0], m, s2)
                y = batch["rewards"][e, t] + 0.99 * (not batch["terminated"][e, t]) * q_next
                q = tr.mixer(tr.agents(o, m).gather(-1, batch["actions"][e, t][None, :, None])[..., 0], m, s)
                loss += float((q - y) ** 2)
                n += 1
    stats = tr.learn_step()
    assert abs(stats["td_loss"] - loss / n) < 1e-4 * max(1.0, loss / n)
    assert any(not torch.equal(agents[k], v) for k, v in tr.agents.state_dict().items())  # it learned


@pytest.mark.parametrize("horizon_terminal", [False, True])
def test_qmix_stores_the_time_limit_as_terminal_only_when_asked(horizon_terminal):
    from comat.models.qmix import QmixAgents, QmixMixer, QmixNetConfig
    from comat.rl import QmixConfig, QmixTrainer

    env = make_vec_env("pcp_v0", 3, seed=2, tier="unicycle", max_robots=8)
    env.reset()
    net = QmixNetConfig(16, 8, 16)
    tr = QmixTrainer(
        QmixAgents(ObsLayout.for_task(env.task), net),
        QmixMixer(env.core.state_size(), net),
        env,
        QmixConfig(
            num_envs=3, batch_episodes=2, buffer_episodes=4, epsilon_start=1.0, horizon_terminal=horizon_terminal
        ),
        seed=0,
    )
    tr.collect()  # random actions: no team captures all prey, every episode hits the time limit
    buf = tr.buffer
    assert buf.size == 3 and buf.filled[:3].all()
    last = buf.terminated[:3, -1]
    assert last.all() if horizon_terminal else not last.any()
    assert not buf.terminated[:3, :-1].any()


# -- runs: checkpoint -> resume -----------------------------------------------------------------------


def test_collect_over_env_workers_assembles_rollout_in_env_order():
    """Shards stepped in turn with the policy: the rollout equals the one-process rollout
    (MAPPO samples each robot independently, so drawing shard by shard takes the same stream)."""
    from comat.rl import Dims, make_learner, make_run_env

    rollouts = []
    for workers in (1, 2):
        config = tiny(
            "mappo", env_workers=workers, ppo={"num_envs": 3, "rollout_steps": 4, "epochs": 1, "minibatches": 1}
        )
        torch.manual_seed(0)
        env = make_run_env(config, 3, seed=11)
        try:
            learner = make_learner(config, env, Dims.of(env))
            rollouts.append(learner.trainer.collect())
        finally:
            env.close()
    one, two = rollouts
    assert one.obs.shape[:2] == (4, 3) and one.state is not None
    for key in ("mask", "actions", "dones", "next_mask"):
        assert torch.equal(getattr(one, key), getattr(two, key)), key
    for key in ("obs", "state", "logp", "values", "rewards", "next_obs", "next_state"):
        torch.testing.assert_close(getattr(one, key), getattr(two, key), atol=2e-3, rtol=0, msg=key)


def test_comat_trained_on_357_acts_on_other_sizes(tmp_path):
    before = torch.get_num_threads()
    config = tiny("comat")
    assert config.torch_threads != before  # the run sets other threads than the test has
    train(config, tmp_path / "run", quiet=True)
    assert torch.get_num_threads() == before  # put back: later torch code here runs as before the run
    act, _config = load_policy(tmp_path / "run" / "checkpoint.pt", algo="comat", task="pcp")
    rng = np.random.default_rng(0)
    for n in (2, 8, 16, 32):
        team = random_team(rng, "pcp", "test", n)
        env = make_vec_env("pcp_v0", 2, seed=n, tier="unicycle", coalitions=[team])
        obs, info = env.reset()
        assert obs.shape[1] == n
        for _ in range(2):
            actions = act(obs, info["agent_mask"], None)
            assert actions.shape == (2, n) and actions.min() >= 0 and actions.max() < 5
            obs, *_, info = env.step(actions)
    episodes = run_episodes(
        make_vec_env("pcp_v0", 2, seed=0, tier="unicycle", ticks_per_step=2, max_robots=9),
        act,
        [random_team(rng, "pcp", "test", n) for n in (2, 9, 4)],
        seed=5,
    )
    assert [e["team_size"] for e in episodes] == [2, 9, 4]


def test_checkpoints_from_before_the_architecture_options_load_as_they_were(tmp_path):
    """A checkpoint written before ComatConfig's encoder/decision options and PPO's value_target
    existed has none of those keys: it loads as the paper-form COMAT with the TD(0) target it
    was, whatever today's defaults are, and acts exactly as it did."""
    from comat.rl.checkpoint import EARLIER_DEFAULTS

    paper = {**TINY_MODELS["comat"], **EARLIER_DEFAULTS["model"]["comat"]}
    train(tiny("comat", models={**TINY_MODELS, "comat": paper}), tmp_path / "run", quiet=True)
    path = tmp_path / "run" / "checkpoint.pt"
    data = torch.load(path, weights_only=True)
    for key in EARLIER_DEFAULTS["model"]["comat"]:
        del data["config"]["model"][key]
    del data["config"]["trainer"]["value_target"]
    torch.save(data, tmp_path / "old.pt")
    loaded = load_checkpoint(tmp_path / "old.pt")
    assert {k: loaded["config"]["model"][k] for k in paper} == paper
    assert loaded["config"]["trainer"]["value_target"] == "td"
    act_new, _ = load_policy(path)
    act_old, config = load_policy(tmp_path / "old.pt")
    assert config.model.obs_embed is False and config.model.heat_form == "paper"
    env = make_vec_env("pcp_v0", 2, seed=0, tier="unicycle")
    obs, info = env.reset()
    np.testing.assert_array_equal(act_old(obs, info["agent_mask"], None), act_new(obs, info["agent_mask"], None))


# -- bad input ----------------------------------------------------------------------------------------
def test_unknown_algo_task_and_preset_keys(tmp_path):
    preset = load_preset("quick")
    with pytest.raises(ValueError, match=rf"^algo must be one of {re.escape(str(list(learner_names())))}, got 'ppo'$"):
        resolve(preset, "ppo", "pcp")
    with pytest.raises(ValueError, match="task must be one of"):
        resolve(preset, "comat", "football")
    with pytest.raises(ValueError, match="unknown preset 'fast'"):
        load_preset("fast")
    bad = tmp_path / "bad.yaml"
    bad.write_text("total_env_steps: 100\nlearning_rate: 0.1\n")
    with pytest.raises(ValueError, match=r"unknown key\(s\) \['learning_rate'\]"):
        load_preset(bad)
    bad.write_text("ppo: {lr: 0.1, epoch: 3}\n")
    with pytest.raises(ValueError, match=r"unknown key\(s\) \['epoch'\] for ppo"):
        resolve(load_preset(bad), "comat", "pcp")
    bad.write_text("models: {comat: {embed: 'big'}}\n")
    with pytest.raises(TypeError, match="models.comat.embed must be"):
        resolve(load_preset(bad), "comat", "pcp")
    bad.write_text("total_env_steps: -5\n")
    with pytest.raises(ValueError, match="total_env_steps must be an integer >= 1, got -5"):
        resolve(load_preset(bad), "comat", "pcp")
    assert main(["train", "--algo", "comat", "--task", "pcp", "--preset", "nope", "--out", str(tmp_path / "x")]) == 2
    assert not (tmp_path / "x").exists()


def test_bad_checkpoints_are_refused_and_nothing_is_overwritten(tmp_path, capsys):
    run = tmp_path / "run"
    train(tiny("mappo"), run, quiet=True)
    ckpt = run / "checkpoint.pt"
    before = {p.name: p.read_bytes() for p in run.iterdir() if p.is_file()}
    with pytest.raises(CheckpointError, match="is for algo 'mappo', expected 'comat'"):
        load_checkpoint(ckpt, algo="comat")
    with pytest.raises(CheckpointError, match="is for task 'pcp', expected 'hmt'"):
        load_policy(ckpt, task="hmt")
    with pytest.raises(CheckpointError, match="for algo 'mappo', expected 'qmix'"):
        train(tiny("qmix"), run, resume=True, quiet=True)
    with pytest.raises(FileExistsError, match="already holds a run; pass --resume"):
        train(tiny("mappo"), run, quiet=True)
    assert main(["train", "--algo", "mappo", "--task", "pcp", "--preset", "quick", "--out", str(run)]) == 2
    assert "already holds a run" in capsys.readouterr().err
    assert main(["train", "--resume", "--algo", "comat", "--out", str(run)]) == 2
    assert "expected 'comat'" in capsys.readouterr().err
    after = {p.name: p.read_bytes() for p in run.iterdir() if p.is_file()}
    assert after == before
    corrupt = tmp_path / "corrupt.pt"
    corrupt.write_bytes(ckpt.read_bytes()[:1000])
    with pytest.raises(CheckpointError, match="is corrupt or not a comat checkpoint"):
        load_checkpoint(corrupt)
    corrupt.write_bytes(b"not a checkpoint at all")
    with pytest.raises(CheckpointError, match="is corrupt or not a comat checkpoint"):
        load_policy(corrupt)
    torch.save({"weights": torch.zeros(3)}, corrupt)
    with pytest.raises(CheckpointError, match="not a comat checkpoint"):
        load_checkpoint(corrupt)
    with pytest.raises(CheckpointError, match="does not exist"):
        load_checkpoint(tmp_path / "missing.pt")


@pytest.mark.parametrize("kind", ["empty", "random_bytes", "folder", "truncated"])
def test_every_command_reading_a_checkpoint_explains_a_bad_one_in_one_line(tmp_path, capsys, kind):
    """eval, probe, rollout, export and train --resume on a 0-byte file, random bytes, a folder
    or a truncated checkpoint: exit status 2, one line naming the file and what is wrong, no
    traceback (and no torch paragraph)."""
    bad = tmp_path / "run" / "checkpoint.pt"
    bad.parent.mkdir()
    if kind == "folder":
        bad.mkdir()
    elif kind == "truncated":
        train(tiny("comat"), tmp_path / "good", quiet=True)
        bad.write_bytes((tmp_path / "good" / "checkpoint.pt").read_bytes()[:2000])
    else:
        bad.write_bytes(b"" if kind == "empty" else np.random.default_rng(0).bytes(4096))
    expected = {
        "empty": "is empty (0 bytes)",
        "random_bytes": "is corrupt or not a comat checkpoint",
        "folder": "is a folder without a checkpoint.pt",
        "truncated": "is corrupt or not a comat checkpoint",
    }[kind]
    commands = [
        ["eval", "--policy", str(bad)],
        ["probe", "--policy", str(bad)],
        ["rollout", "--task", "pcp", "--policy", str(bad), "--out", str(tmp_path / "x.rrd")],
        ["export", "--policy", str(bad), "--task", "pcp", "--team", "test:0", "--out", str(tmp_path / "sub")],
    ]
    if kind != "folder":  # train --resume reads RUN/checkpoint.pt
        commands.append(["train", "--resume", "--out", str(bad.parent)])
    for argv in commands:
        assert main(argv) == 2, argv
        err = capsys.readouterr().err.strip().splitlines()
        errors = [line for line in err if "error" in line]  # a progress heading may come before
        assert len(errors) == 1 and err[-1] == errors[0] and expected in errors[0], (argv, err)
        assert not any("Traceback" in line or "PyTorch" in line or "weights_only" in line for line in err), (argv, err)
    assert not (tmp_path / "sub").exists() and not (tmp_path / "x.rrd").exists()


@pytest.mark.parametrize(
    "text, expected",
    [
        ("", "is empty; expected a mapping of settings"),
        ("total_env_steps: [1, 2\n", "is not valid YAML at line 2"),
        ("- 1\n- 2\n", "must be a mapping of settings, got list"),
    ],
)
def test_bad_preset_files_get_one_clear_line(tmp_path, capsys, text, expected):
    preset = tmp_path / "p.yaml"
    preset.write_text(text)
    assert (
        main(["train", "--algo", "comat", "--task", "pcp", "--preset", str(preset), "--out", str(tmp_path / "r")]) == 2
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and expected in err[0], err
    assert not (tmp_path / "r").exists()


@pytest.mark.parametrize("name", ["paper", "quick", "learning", "sweep"])
def test_every_preset_resolves_for_every_algo_and_task(name):
    preset = load_preset(name)
    for algo in ("comat", "mat", "mappo", "qmix"):
        for task in ("pcp", "hmt"):
            config = resolve(preset, algo, task)
            steps = (preset.get("by_task") or {}).get(task, {}).get("total_env_steps", preset["total_env_steps"])
            assert config.total_env_steps == steps and config.tier == "unicycle"


def test_train_records_evaluation_episodes(tmp_path):
    from comat.viz import record_training

    config = tiny("comat", steps=6, eval_every_steps=6, eval_episodes_per_team=1)
    train(config, tmp_path / "run", quiet=True, rrd_every=1, record=record_training)
    files = sorted((tmp_path / "run" / "rrd").glob("*.rrd"))
    assert [f.name for f in files] == ["eval_000000000006.rrd"]
    rerun = shutil.which("rerun") or str(Path(sys.executable).parent / "rerun")
    assert subprocess.run([rerun, "rrd", "verify", str(files[0])], capture_output=True, check=False).returncode == 0
    with pytest.raises(ValueError, match="eval_episodes_per_team is 0"):
        train(tiny("comat"), tmp_path / "other", quiet=True, rrd_every=1, record=record_training)
    with pytest.raises(ValueError, match="needs record="):
        train(config, tmp_path / "other", quiet=True, rrd_every=1)
    with pytest.raises(ValueError, match="rrd_every must be"):
        train(tiny("comat"), tmp_path / "other", quiet=True, rrd_every=-1)


@pytest.mark.parametrize(
    "case",
    [
        "team_missing",
        "team_folder",
        "team_empty",
        "team_bytes",
        "team_nan",
        "team_list",
        "preset_nan_lr",
        "preset_negative",
        "preset_wrong_type",
        "report_not_a_run",
        "check_not_a_submission",
        "eval_out_is_a_file",
    ],
)
def test_bad_user_files_and_values_get_one_line_and_leave_nothing(tmp_path, capsys, case):
    """Team files, preset values, folders given to report/--check and output paths: exit 2, one
    error line naming the argument and what was wrong, nothing written."""
    files = {
        "team_empty": b"",
        "team_bytes": np.random.default_rng(0).bytes(300),
        "team_nan": b'{"robots": [{"type": "sensing", "capabilities": [NaN, 0]}, '
        b'{"type": "capture", "capabilities": [0, 0.3]}]}',
        "team_list": b"[1, 2]",
        "preset_nan_lr": b"ppo: {lr: .nan}\n",
        "preset_negative": b"total_env_steps: -5\n",
        "preset_wrong_type": b"ppo: {lr: fast}\n",
    }
    path = tmp_path / ("in.yaml" if case.startswith("preset") else "in.json")
    if case in files:
        path.write_bytes(files[case])
    elif case in ("team_folder", "report_not_a_run", "check_not_a_submission"):
        path.mkdir()
    export = ["export", "--policy", "heuristic", "--task", "pcp", "--out", str(tmp_path / "out"), "--team", str(path)]
    argv, expected = {
        "team_missing": (export, "(no such file)"),
        "team_folder": (export, "(a folder)"),
        "team_empty": (export, "got a file that is empty"),
        "team_bytes": (export, "got a file that is not JSON"),
        "team_nan": (export, "sensing_radius_m must be in [0.0, 1.0] (physical limit), got nan"),
        "team_list": (export, "must hold a JSON object"),
        "preset_nan_lr": (
            ["train", "--algo", "comat", "--task", "pcp", "--preset", str(path), "--out", str(tmp_path / "out")],
            "ppo.lr must be a finite number > 0, got nan",
        ),
        "preset_negative": (
            ["train", "--algo", "mat", "--task", "hmt", "--preset", str(path), "--out", str(tmp_path / "out")],
            "total_env_steps must be an integer >= 1, got -5",
        ),
        "preset_wrong_type": (
            ["train", "--algo", "mappo", "--task", "pcp", "--preset", str(path), "--out", str(tmp_path / "out")],
            "ppo.lr must be float, got 'fast' (str)",
        ),
        "report_not_a_run": (["report", str(path), "--out", str(tmp_path)], "is not a run folder (no config.yaml)"),
        "check_not_a_submission": (["export", "--check", str(path)], "is not an exported submission"),
        "eval_out_is_a_file": (["eval", "--task", "pcp", "--out", str(path)], "is a file; expected a folder"),
    }[case]
    if case == "eval_out_is_a_file":
        path.write_text("a file, not a folder")
    assert main(argv) == 2
    err = [line for line in capsys.readouterr().err.strip().splitlines() if "error" in line]
    assert len(err) == 1 and expected in err[0], err
    assert not (tmp_path / "out").exists()


def test_overrides_and_base_presets(tmp_path, capsys):
    """``comat train ... ppo.lr=3e-4 models.comat.heads=2``: typed, checked like a preset, recorded
    in config.yaml as given and as resolved; a preset may name a base preset and change keys."""
    import yaml

    from comat.rl import apply_overrides, load_preset

    base = load_preset("quick")
    changed = apply_overrides(base, ["ppo.lr=3e-4", "models.comat.heads=2", "ppo.rollout_steps=null", "tier=wheels"])
    assert changed["ppo"]["lr"] == 3e-4 and changed["models"]["comat"]["heads"] == 2 and changed["tier"] == "wheels"
    assert changed["ppo"]["rollout_steps"] is None
    assert {k: v for k, v in changed["ppo"].items() if k not in ("lr", "rollout_steps")} == {
        k: v for k, v in base["ppo"].items() if k not in ("lr", "rollout_steps")
    }
    child = tmp_path / "child.yaml"
    child.write_text("base: quick\nppo: {lr: 0.001}\nmodels: {mat: {embed: 32}}\n")
    merged = load_preset(child)
    assert merged["ppo"] == {"num_envs": 32, "lr": 0.001} and merged["qmix"] == base["qmix"]
    assert merged["models"]["mat"]["embed"] == 32 and merged["total_env_steps"] == base["total_env_steps"]
    loop = tmp_path / "loop.yaml"
    loop.write_text("base: loop.yaml\n")
    with pytest.raises(ValueError, match="form a cycle"):
        load_preset(loop)
    run = tmp_path / "run"
    argv = [
        "train",
        "--algo",
        "comat",
        "--task",
        "pcp",
        "--preset",
        str(child),
        "--steps",
        "12",
        "--quiet",
        "--out",
        str(run),
    ]
    assert (
        main(
            [
                *argv,
                "ppo.num_envs=2",
                "ppo.rollout_steps=3",
                "ppo.epochs=1",
                "eval_episodes_per_team=0",
                "models.comat.embed=16",
                "models.comat.heads=2",
                "models.comat.edge_embed=8",
            ]
        )
        == 0
    )
    doc = yaml.safe_load((run / "config.yaml").read_text())
    assert doc["overrides"][0] == "ppo.num_envs=2" and doc["config"]["model"]["embed"] == 16
    assert doc["config"]["trainer"]["lr"] == 0.001 and doc["config"]["trainer"]["num_envs"] == 2
    for bad, message in (
        (["ppo.lrr=3"], "unknown key(s) ['lrr']"),
        (["ppo.lr=fast"], "ppo.lr must be float"),
        (["lr"], "overrides must be key=value"),
        (["zzz=1"], "unknown key(s) ['zzz'] in overrides"),
    ):
        assert main([*argv[:-1], str(tmp_path / "other"), *bad]) == 2
        assert message in capsys.readouterr().err
    assert not (tmp_path / "other").exists()
    assert main(["train", "--resume", "--out", str(run), "ppo.lr=1"]) == 2
    assert "overrides ['ppo.lr=1'] are for a new run" in capsys.readouterr().err
