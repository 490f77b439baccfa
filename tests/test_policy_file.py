"""Policy files (``policy.pt``): what a finished run keeps to be evaluated again.

For every algorithm: the file holds only the acting weights (no optimizer, critic, mixer or
buffer), loads with ``weights_only=True`` and acts bit for bit as the checkpoint it came from;
``--policy`` takes it wherever a policy is run (eval from a folder without its checkpoint,
export), and refuses it where the learner is needed (probe, resume); ``comat policy`` makes one
from a checkpoint; the README's table of what a policy weighs is what the models measure."""

import json
import re
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from comat.cli import main
from comat.envs import make_vec_env
from comat.learners import learner_entry, learner_names
from comat.measure.episodes import run_episodes
from comat.rl import POLICY_FILE, load_policy, policy_file_of, train
from comat.rl.algos import env_slots
from comat.rl.checkpoint import CheckpointError, load_checkpoint, load_policy_file
from comat.team import random_team

sys.path.insert(0, str(Path(__file__).parent))
from test_rl import tiny

README = Path(__file__).resolve().parents[1] / "docs" / "policies.md"  # the table moved from the README
TINY_CLI = [
    "--steps",
    "20",
    "ppo.num_envs=2",
    "ppo.rollout_steps=8",
    "ppo.epochs=1",
    "ppo.minibatches=1",
    "eval_episodes_per_team=0",
    "models.comat.embed=16",
    "models.comat.heads=2",
    "models.comat.heat_blocks=1",
    "models.comat.edge_embed=8",
]


@pytest.fixture(scope="module")
def comat_run(tmp_path_factory):
    """A tiny finished COMAT run on PCP (20 env steps)."""
    run = tmp_path_factory.mktemp("policy") / "comat"
    train(tiny("comat", steps=20), run, quiet=True)
    return run


@pytest.mark.parametrize("algo", learner_names())
def test_the_policy_file_keeps_only_the_acting_weights_and_acts_exactly_as_the_checkpoint(tmp_path, algo):
    config = tiny(algo, steps=20)
    train(config, tmp_path / "run", quiet=True)
    ckpt_path, pol_path = tmp_path / "run" / "checkpoint.pt", tmp_path / "run" / POLICY_FILE
    ckpt = load_checkpoint(ckpt_path)
    raw = torch.load(pol_path, map_location="cpu", weights_only=True)  # plain tensors and data only
    assert raw["format"] == "comat-policy" and raw["format_version"] == 1
    assert (raw["algo"], raw["task"]) == (algo, "pcp") and raw["config"] == ckpt["config"]
    assert raw["env_steps"] == ckpt["progress"]["env_steps"] >= 20 and raw["updates"] == ckpt["progress"]["updates"]
    assert raw["dims"] == ckpt["progress"]["dims"] and raw["versions"]["commit"] == ckpt["versions"]["commit"]
    assert not {"trainer", "optimizer", "progress", "env_rngs", "torch_rng"} & set(raw)
    assert tuple(raw["weights"]) == learner_entry(algo).acts_with
    for name, state in raw["weights"].items():
        full = ckpt["trainer"][name]
        assert set(state) <= set(full)
        for key, tensor in state.items():
            assert tensor.dtype == torch.float32 and torch.equal(tensor, full[key]), (name, key)
    if algo == "mappo":  # the critic is not kept: acting does not need it
        assert any(k.startswith("critic.") for k in ckpt["trainer"]["policy"])
        assert not any(k.startswith("critic.") for k in raw["weights"]["policy"])
    assert raw["parameters"] == sum(t.numel() for s in raw["weights"].values() for t in s.values())
    assert pol_path.stat().st_size < ckpt_path.stat().st_size / 3

    act_ckpt, _ = load_policy(ckpt_path, algo=algo, task="pcp")
    act_pol, pol_config = load_policy(pol_path, algo=algo, task="pcp")
    assert pol_config.to_dict() == ckpt["config"]
    env = make_vec_env("pcp_v0", 3, seed=7, tier="unicycle", **env_slots(config))
    try:
        obs, info = env.reset()
        for _ in range(6):
            state = env.state()
            a = act_ckpt(obs, info["agent_mask"], state)
            np.testing.assert_array_equal(a, act_pol(obs, info["agent_mask"], state))
            np.testing.assert_array_equal(a, act_pol(obs, info["agent_mask"], None))  # acting needs no state
            obs, *_, info = env.step(a)
        teams = [random_team(np.random.default_rng(1), "pcp", "test", n) for n in (3, 5)]
        state = learner_entry(algo).uses_state
        one, two = (run_episodes(env, act, teams, seed=4, use_state=state) for act in (act_ckpt, act_pol))
    finally:
        env.close()
    assert one == two


def test_eval_from_a_folder_holding_only_policy_and_config(comat_run, tmp_path, capsys):
    """The committed form of a run (policy.pt + config.yaml, its checkpoint.pt deleted) evaluates
    with one command, to the same numbers as its checkpoint; probe and resume refuse it."""
    assert (
        main(
            [
                "eval",
                "--policy",
                str(comat_run),
                "--teams",
                "test",
                "--no-references",
                "--out",
                str(tmp_path / "from_ckpt"),
            ]
        )
        == 0
    )
    kept = tmp_path / "kept"
    shutil.copytree(comat_run, kept)
    for extra in kept.iterdir():
        if extra.name not in (POLICY_FILE, "config.yaml"):
            shutil.rmtree(extra) if extra.is_dir() else extra.unlink()
    assert sorted(p.name for p in kept.iterdir()) == ["config.yaml", POLICY_FILE]
    capsys.readouterr()
    assert (
        main(
            [
                "eval",
                "--policy",
                str(kept),
                "--teams",
                "test",
                "--no-references",
                "--out",
                str(tmp_path / "from_policy"),
            ]
        )
        == 0
    )
    assert "comat eval: " + str(kept / POLICY_FILE) in capsys.readouterr().err
    from comat.measure.metrics import read_results

    a, b = (read_results(tmp_path / f / "evaluation_unicycle.json") for f in ("from_ckpt", "from_policy"))
    assert a["rows"] and [r["metrics"] for r in a["rows"]] == [r["metrics"] for r in b["rows"]]
    assert [r["per_episode"] for r in a["rows"]] == [r["per_episode"] for r in b["rows"]]

    before = {p.name: p.read_bytes() for p in kept.iterdir()}
    for argv, expected in (
        (["probe", "--policy", str(kept)], "holds a policy.pt but no checkpoint.pt: comat probe reads"),
        (["probe", "--policy", str(kept / POLICY_FILE)], "is a policy file (the weights to act only): comat probe"),
        (["train", "--resume", "--out", str(kept), "--quiet"], "holds a finished run's policy.pt but no checkpoint.pt"),
        (
            ["train", "--algo", "comat", "--task", "pcp", "--out", str(kept), *TINY_CLI],
            "holds a finished run's policy.pt but no checkpoint.pt: it is not trained into again",
        ),
    ):
        assert main(argv) == 2, argv
        err = [line for line in capsys.readouterr().err.splitlines() if "error" in line]
        assert len(err) == 1 and expected in err[0], (argv, err)
    assert {p.name: p.read_bytes() for p in kept.iterdir()} == before


def test_export_from_a_policy_file_ships_the_checkpoints_weights(comat_run, tmp_path):
    from sim2real.export import export_submission

    team = random_team(np.random.default_rng(2), "pcp", "test", 4)
    a = export_submission(comat_run / "checkpoint.pt", "pcp", team, tmp_path / "a", seed=1)
    b = export_submission(comat_run / POLICY_FILE, "pcp", team, tmp_path / "b", seed=1)
    assert sorted(p.name for p in a.iterdir()) == sorted(p.name for p in b.iterdir())
    for name in ("weights.npy", "submission_config.py", "main.py"):
        assert (a / name).read_bytes() == (b / name).read_bytes(), name
    with pytest.raises(ValueError, match="for task 'pcp', expected 'hmt'"):
        export_submission(
            comat_run / POLICY_FILE, "hmt", random_team(np.random.default_rng(2), "hmt", "test", 3), tmp_path / "c"
        )


def test_train_prints_its_policy_file_and_comat_policy_makes_one_from_a_checkpoint(tmp_path, capsys):
    run = tmp_path / "run"
    assert main(["train", "--algo", "mappo", "--task", "pcp", "--out", str(run), "--quiet", *TINY_CLI]) == 0
    out = capsys.readouterr().out
    size = (run / POLICY_FILE).stat().st_size
    assert (
        f"{run / POLICY_FILE} ({max(size / 1000, 1):.0f} KB): weights and config to act; evaluate with comat eval "
        f"--policy {run / POLICY_FILE}" in out
    )
    made = load_policy_file(run / POLICY_FILE)

    # a run from before policy files: `comat policy RUN` makes it from the checkpoint, the same weights
    (run / POLICY_FILE).unlink()
    assert main(["policy", str(run)]) == 0
    assert f"{run / POLICY_FILE} (" in capsys.readouterr().out
    again = load_policy_file(run / POLICY_FILE)
    assert again["config"] == made["config"] and again["env_steps"] == made["env_steps"]
    for key, tensor in made["weights"]["policy"].items():
        assert torch.equal(tensor, again["weights"]["policy"][key]), key
    assert main(["policy", str(run)]) == 2  # never replaced without --force
    assert "policy.pt' already exists; pass --force" in capsys.readouterr().err
    (run / POLICY_FILE).unlink()  # resuming a finished run writes it again
    assert main(["train", "--resume", "--out", str(run), "--quiet"]) == 0
    assert f"{run / POLICY_FILE} (" in capsys.readouterr().out
    assert load_policy_file(run / POLICY_FILE)["env_steps"] == made["env_steps"]
    assert main(["policy", str(run / "checkpoint.pt"), "--out", str(tmp_path / "kept" / "mappo.pt")]) == 0
    assert load_policy_file(tmp_path / "kept" / "mappo.pt")["algo"] == "mappo"
    capsys.readouterr()
    # a policy file is described, not rewritten
    assert main(["policy", str(tmp_path / "kept" / "mappo.pt")]) == 0
    line = capsys.readouterr().out
    assert re.search(r"mappo\.pt \(\d+ KB\): mappo on pcp, [\d,]+ env steps, [\d,]+ parameters \(policy\)", line), line
    for argv, expected in (
        (["policy", str(tmp_path / "kept" / "mappo.pt"), "--out", str(tmp_path / "x.pt")], "is already a policy file"),
        (["policy", str(run), "--out", str(tmp_path / "x.txt"), "--force"], "--out must be a .pt file"),
        (["policy", str(tmp_path / "nothing")], "no such file or folder"),
        (["policy", str(tmp_path / "kept")], "is a folder without a checkpoint.pt or a policy.pt"),
    ):
        assert main(argv) == 2, argv
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and expected in err[0], (argv, err)
    assert not (tmp_path / "x.pt").exists() and not (tmp_path / "x.txt").exists()


def test_bad_policy_files_are_refused_naming_the_file_and_the_fault(comat_run, tmp_path):
    good = comat_run / POLICY_FILE
    data = torch.load(good, map_location="cpu", weights_only=True)
    with pytest.raises(CheckpointError, match="is a comat policy file .* this needs the run's checkpoint.pt"):
        load_checkpoint(good)
    with pytest.raises(CheckpointError, match="is a comat checkpoint, not a policy file; make its policy file with"):
        load_policy_file(comat_run / "checkpoint.pt")
    with pytest.raises(CheckpointError, match="policy file .* is for task 'pcp', expected 'hmt'"):
        load_policy(good, task="hmt")
    bad = tmp_path / "bad.pt"
    bad.write_bytes(good.read_bytes()[:3000])
    with pytest.raises(CheckpointError, match=r"bad.pt' \(3000 bytes\) is corrupt or not a comat checkpoint or policy"):
        load_policy(bad)
    for change, expected in (
        ({"format_version": 2}, "has format_version 2, this comat reads 1"),
        ({"weights": None}, "lacks 'weights'"),
        ({"env_id": "pcp_v7"}, "was trained on pcp_v7, but this comat has pcp_v0 .* train it again"),
        ({"dims": {"obs_dim": 3}}, "dims lack"),
        ({"weights": {"policy": {"w": "not a tensor"}}}, r"weights\['policy'\] must map parameter names to tensors"),
        ({"weights": {"agents": data["weights"]["policy"]}}, "has no weights for the comat 'policy' module"),
        (
            {"config": {**data["config"], "model": {**data["config"]["model"], "embed": 32}}},
            "the 'policy' weights do not fit the comat model its config builds",
        ),
    ):
        torch.save({**data, **change}, bad)
        with pytest.raises(CheckpointError, match=expected):
            load_policy(bad)
    with pytest.raises(ValueError, match="is a folder without a checkpoint.pt or a policy.pt"):
        policy_file_of(tmp_path)


def _readme_table() -> dict[tuple[str, str], tuple[float, int, int]]:
    """(algo, task) -> (KB, parameters kept, learner's parameters) from the docs' table."""
    text = README.read_text()
    section = text[text.index("## What one policy weighs") :]
    rows = {}
    by_label = {learner_entry(name).label: name for name in learner_names()}
    cell = r" ([\d.]+ [KM]B) \| ([\d,]+) \(([\d,]+)\) \|"  # size | kept (learner's)
    for label, size_pcp, p_pcp, l_pcp, size_hmt, p_hmt, l_hmt in re.findall(
        r"^\| ([^|]+) \| [^|]+ \|" + cell + cell, section, flags=re.MULTILINE
    ):
        kb = [float(x.split()[0]) * (1000 if x.endswith("MB") else 1) for x in (size_pcp, size_hmt)]
        n = [int(x.replace(",", "")) for x in (p_pcp, l_pcp, p_hmt, l_hmt)]
        algo = by_label[label]
        rows[algo, "pcp"], rows[algo, "hmt"] = (kb[0], *n[:2]), (kb[1], *n[2:])
    return rows


def test_the_readme_says_what_one_policy_weighs_with_the_grids_models(tmp_path):
    """benchmarks/policy_sizes.py measured it: the grid's model config (the sweep preset) built for
    each task, its policy file written; the README's table must be that measurement."""
    from comat.rl import policy_weights

    table = _readme_table()
    assert len(table) == 2 * len(learner_names()), table
    for row in policy_weights("sweep", tasks=("pcp", "hmt"), folder=tmp_path):  # the grid's tasks
        kb, kept, learner = table[row["algo"], row["task"]]
        assert (kept, learner) == (row["parameters"], row["learner_parameters"]), row
        # the versions it records differ by a few bytes; a size in MB is rounded to 0.1 MB
        assert abs(kb - row["bytes"] / 1000) <= (1.5 if kb < 1000 else 50), row
        assert load_policy_file(tmp_path / f"{row['algo']}_{row['task']}" / POLICY_FILE)["algo"] == row["algo"]


def test_a_finished_sweep_keeps_a_policy_file_in_every_run_folder(comat_run, tmp_path, capsys):
    """`comat sweep` on a recorded grid whose runs are all finished starts nothing, but gives a run
    trained before policy files existed (checkpoint, no policy.pt) its policy.pt."""
    from comat.eval import RECORD, prepare_sweep, run_sweep

    root = tmp_path / "sweep"
    run = root / "comat_pcp_s3"
    shutil.copytree(comat_run, run)
    assert main(["eval", "--policy", str(run), "--teams", "train", "--no-references", "--out", str(run)]) == 0
    expected = load_policy_file(run / POLICY_FILE)
    (run / POLICY_FILE).unlink()
    record, _ = prepare_sweep(
        root, {"algos": ["comat"], "tasks": ["pcp"], "seeds": [3], "preset": "quick", "eval_sets": ["train"]}
    )
    (root / RECORD).write_text(json.dumps(record))
    rows = run_sweep(record, progress=lambda m: None)
    assert [r["state"] for r in rows] == ["done"] and "error" not in rows[0]
    made = load_policy_file(run / POLICY_FILE)
    assert made["env_steps"] == expected["env_steps"] and made["config"] == expected["config"]
    for key, tensor in expected["weights"]["policy"].items():
        assert torch.equal(tensor, made["weights"]["policy"][key]), key
