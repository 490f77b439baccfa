import argparse
import json
import subprocess
import sys

import pytest

from comat.cli import build_parser, main


def _command_paths(parser: argparse.ArgumentParser, prefix: tuple[str, ...] = ()) -> list[tuple[str, ...]]:
    """Every command and sub-command the parser knows, found by walking its sub-parsers."""
    paths = [prefix]
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                paths += _command_paths(sub, (*prefix, name))
    return paths


def test_every_command_has_help(capsys):
    """Walks the parser, so a new command (or bench) cannot be missed: each prints its help, with a
    description, and exits 0."""
    parser = build_parser()
    paths = _command_paths(parser)
    assert {("calibrate",), ("probe",), ("bench", "safety"), ("bench", "viz"), ("export",)} <= set(paths)
    helps = {}
    for path in paths:
        with pytest.raises(SystemExit) as exc:
            parser.parse_args([*path, "--help"])
        assert exc.value.code == 0, path
        helps[path] = capsys.readouterr().out
        assert helps[path].startswith("usage: comat"), path
    assert "barrier filter" in helps[("demo",)] and "Robotarium" in helps[()]


def test_the_docs_command_table_has_every_command():
    """docs/commands.md's table has a row for every command and bench the parser knows, each linking
    to its section."""
    from pathlib import Path

    text = (Path(__file__).parents[1] / "docs" / "commands.md").read_text()
    rows = {line.split("`")[1]: line for line in text.splitlines() if line.startswith("| [`comat ")}
    for path in _command_paths(build_parser())[1:]:
        if path == ("bench",):
            continue  # the bench family: a row per benchmark
        name = " ".join(("comat", *path))
        assert name in rows, f"docs/commands.md has no row for {name}"
        anchor = rows[name].split("](#")[1].split(")")[0]
        assert f"{{#{anchor}}}" in text, f"docs/commands.md's row for {name} links to no section"


def test_mjcf_command_writes_the_golden_files(tmp_path, capsys):
    assert main(["mjcf", "--out", str(tmp_path)]) == 0
    assert (tmp_path / "scene_wheels_n8.xml").exists()
    assert "wrote" in capsys.readouterr().out


def test_demo_runs_safely_and_writes_a_summary(tmp_path, capsys):
    out = tmp_path / "demo.json"
    argv = ["demo", "--tier", "unicycle", "--robots", "4", "--episodes", "1", "--part", "physics", "--out", str(out)]
    assert main(argv) == 0
    physics = json.loads(out.read_text())["physics"]["results"]
    assert physics["safety filter"]["MuJoCo robot-robot contact ticks"] == 0
    assert physics["no filter"]["MuJoCo robot-robot contact ticks"] > 0
    assert "safety filter" in capsys.readouterr().out


def test_demo_shows_the_pretrained_policy_finishing_with_its_files(tmp_path, capsys):
    """make demo's last part, in a fast form (one unicycle episode): the shipped policy finishes
    an unseen team and leaves a recording, a video and an export that passes --check (issue 32)."""
    out, folder = tmp_path / "demo.json", tmp_path / "demo"
    assert (
        main(
            [
                "demo",
                "--tier",
                "unicycle",
                "--episodes",
                "1",
                "--part",
                "pretrained",
                "--folder",
                str(folder),
                "--out",
                str(out),
            ]
        )
        == 0
    )
    summary = json.loads(out.read_text())["pretrained"]
    assert (
        summary["ok"]
        and (folder / "comat_pcp.rrd").stat().st_size > 0
        and (folder / "comat_pcp.mp4").stat().st_size > 0
    )
    assert (folder / "robotarium_pcp" / "main.py").is_file()
    printed = capsys.readouterr().out
    assert "progress 100%" in printed and "all written and the export checked" in printed


@pytest.mark.slow
def test_demo_tasks_part(tmp_path):
    out = tmp_path / "demo.json"
    assert main(["demo", "--tier", "unicycle", "--episodes", "1", "--part", "tasks", "--out", str(out)]) == 0
    heuristic = [r for r in json.loads(out.read_text())["tasks"]["rows"] if r["policy"] == "heuristic"]
    assert len(heuristic) == 4 and all(r["finished"] == 1.0 for r in heuristic)


def test_a_typo_in_a_choice_is_one_line_not_the_usage_block(capsys):
    """argparse prints its 7-9-line usage before the error; comat's commands print the error and
    where the help is, one line (issue 67)."""
    for argv, where in ((["train", "--algo", "comatt", "--task", "pcp"], "comat train"),
                        (["eval", "--task", "pcpp"], "comat eval"),
                        (["bench", "sim", "--sizes", "x"], "comat bench sim"),
                        ([], "comat")):  # fmt: skip
        with pytest.raises(SystemExit) as exc:
            main(argv)
        err = capsys.readouterr().err
        assert exc.value.code == 2 and err.count("\n") == 1 and "usage:" not in err.split("(")[0], argv
        assert err.startswith(f"{where}: error: ") and err.endswith(f"(usage: {where} --help)\n"), err


@pytest.mark.parametrize("module", ["comat", "comat.cli", "comat.cli.main"])
def test_python_m_runs_the_command_without_a_warning(module):
    """``python -m comat.cli.main`` warned (the package imported its main module first, issue 67)."""
    done = subprocess.run(
        [sys.executable, "-W", "error", "-m", module, "--version"], capture_output=True, text=True, check=False
    )
    assert done.returncode == 0 and done.stdout.startswith("comat ") and done.stderr == "", done.stderr
    from comat.cli import main as entry

    assert callable(entry) and entry.__module__ == "comat.cli"  # the function, whatever was imported before


def test_bad_arguments_get_a_clear_error(capsys):
    assert main(["demo", "--robots", "40"]) == 2
    assert "--robots must be between 2 and 12" in capsys.readouterr().err
    # export: a wrong --policy is named before the flags left out, which come all in one line
    assert main(["export", "--policy", "runs/no_such_run", "--out", "x"]) == 2
    assert "--policy must be" in capsys.readouterr().err
    assert main(["export", "--policy", "pretrained:comat-pcp"]) == 2
    assert "comat export needs --team, --out (or --check DIR)" in capsys.readouterr().err


def test_bench_sim_small_grid_writes_json(tmp_path):
    out = tmp_path / "sim.json"
    cmd = [
        sys.executable,
        "-m",
        "comat.cli",
        "bench",
        "sim",
        "--sizes",
        "2",
        "--batches",
        "1",
        "2",
        "--tiers",
        "unicycle",
        "--ticks",
        "5",
        "--rps-ticks",
        "5",
        "--out",
        str(out),
    ]
    subprocess.run(cmd, check=True, capture_output=True, text=True)
    data = json.loads(out.read_text())
    rows = {(r["system"], r["batch"]) for r in data["rows"]}
    assert ("comat", 1) in rows and ("comat", 2) in rows
    assert all(r["tick_us"] > 0 for r in data["rows"])


def test_bench_env_rollout_split_adds_up(tmp_path, capsys):
    out = tmp_path / "rollout.json"
    assert (
        main(
            [
                "bench",
                "env",
                "--rollout",
                "--tasks",
                "pcp",
                "--tiers",
                "unicycle",
                "--rollout-batch",
                "4",
                "--steps",
                "2",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    data = json.loads(out.read_text())
    whole, shards = data["whole"], data["shards"]
    assert [s["envs"] for s in shards] == [[0, 1], [2, 3]] and data["single_env"]["envs"] == [0, 0]
    # the same environments (same seed streams) in one process and in two halves
    assert sum(s["robots"] for s in shards) == whole["robots"]
    for row in [whole, *shards]:
        parts = row["physics_ms"] + row["osqp_ms"] + row["tick_rest_ms"] + row["outside_ticks_ms"]
        assert abs(parts - row["step_ms"]) < 1e-6 and row["physics_ms"] > 0 and row["tick_rest_ms"] > 0
    assert data["sharded_step_ms_lower_bound"] == max(s["step_ms"] for s in shards)
    assert "2 env processes: a step costs at least" in capsys.readouterr().out


def test_bench_decode_times_each_path_with_its_own_encoder():
    from comat.bench.learn_bench import bench_decode

    for model in ("comat", "mat"):
        row = bench_decode(model, n_robots=4, batch=3, repeats=2)  # raises if cached != uncached actions
        assert row["act_cached_ms"] > 0 and row["act_uncached_ms"] > 0 and row["decode_speedup"] > 0
        # COMAT acts with its compiled encoder, MAT with the torch one
        assert (row["encode_act_ms"] == row["encode_ms"]) == (model == "mat")


def test_bench_learn_checks_comats_learning_against_mats_per_env_step():
    from comat.bench.learn_bench import _checks

    def row(algo, task, workers, learn_s, steps, overlap=False):
        return {
            "algo": algo,
            "overlap": overlap,
            "task": task,
            "env_workers": workers,
            "learn_s": learn_s,
            "env_steps": steps,
            "env_steps_per_s": 1.0,
        }

    train = [
        row("comat", "pcp", 2, 5.0, 7680),
        row("mat", "pcp", 2, 2.5, 7680),
        row("comat", "hmt", 2, 2.6, 3360),
        row("mat", "hmt", 2, 4.0, 6720),  # twice the steps: per env step COMAT is 1.3x
        row("comat", "hmt", 1, 1.0, 3360),  # no MAT row with one worker: no check
        row("comat", "pcp", 2, 0.1, 7680, overlap=True),  # the targets are the default's: not these
        row("mat", "hmt", 1, 1.0, 3360, overlap=True),
    ]
    checks = _checks([], train)
    assert checks["comat_learn_vs_mat_pcp_W2"]["value"] == 2.0 and not checks["comat_learn_vs_mat_pcp_W2"]["pass"]
    assert (
        abs(checks["comat_learn_vs_mat_hmt_W2"]["value"] - 1.3) < 1e-12 and checks["comat_learn_vs_mat_hmt_W2"]["pass"]
    )
    assert "comat_learn_vs_mat_hmt_W1" not in checks


def test_bench_learn_update_check_reads_each_rounds_ratio_so_a_drift_touches_both():
    """The update part's check: the median over rounds of COMAT's update over MAT's in the same round
    (per env step), so a round in which the machine slowed both does not move it."""
    from comat.bench.learn_bench import _checks

    def row(algo, task, seconds, steps=2560):
        return {"algo": algo, "task": task, "env_steps": steps, "update_s": seconds}

    update = [
        row("comat", "pcp", [1.2, 2.4, 1.2]),  # round 2: the machine twice as slow for both
        row("mat", "pcp", [1.0, 2.0, 1.0]),
        row("mappo", "pcp", [0.1, 0.1, 0.1]),
        row("comat", "hmt", [1.5, 1.5, 1.5], steps=1280),
        row("mat", "hmt", [2.0, 2.0, 2.0]),  # per env step COMAT is 1.5x
    ]
    checks = _checks([], [], update)
    pcp, hmt = checks["comat_update_vs_mat_pcp"], checks["comat_update_vs_mat_hmt"]
    assert abs(pcp["value"] - 1.2) < 1e-12 and pcp["pass"] and pcp["rounds"] == 3
    assert abs(hmt["value"] - 1.5) < 1e-12 and not hmt["pass"]
    # the sums would have read the slow round as the learners' own: the end-to-end check is apart
    assert not any(name.startswith("comat_learn_vs_mat") for name in checks)


def test_bench_update_times_each_ppo_learners_update_in_turns(tmp_path):
    from unittest import mock

    import torch
    import yaml

    from comat.bench.learn_bench import bench_update
    from comat.rl import PPOTrainer

    preset = tmp_path / "tiny.yaml"
    preset.write_text(
        yaml.safe_dump(
            {
                "ppo": {"num_envs": 2, "rollout_steps": 2, "epochs": 1, "minibatches": 1},
                "models": {"mappo": {"hidden": 16}, "comat": {"embed": 16, "heads": 1}},
            }
        )
    )
    order, starts, teams = [], [], []
    real = PPOTrainer.update

    def update(trainer, rollout, lagged=False):
        order.append(type(trainer.policy).__name__)
        weights = torch.cat([p.detach().flatten() for p in trainer.learner.parameters()])
        moments = [v for state in trainer.optimizer.state.values() for v in state.values()]
        starts.append((order[-1], weights, str(trainer.rng.bit_generator.state), len(moments)))
        teams.append((rollout.mask.sum(-1).tolist(), rollout.obs))
        return real(trainer, rollout, lagged)

    with mock.patch.object(PPOTrainer, "update", update):
        rows = bench_update(["comat", "mappo"], rounds=2, preset=str(preset))
    assert order == ["Comat", "Mappo"] * 3  # one untimed round, then two, taking turns
    # every round starts from the same weights, optimizer state and minibatch order, on a rollout of its own
    for name in ("Comat", "Mappo"):
        mine = [start for start in starts if start[0] == name]
        assert all(torch.equal(w, mine[0][1]) and rng == mine[0][2] and n == mine[0][3] for _, w, rng, n in mine)
    assert [t for t, _ in teams[0::2]] == [t for t, _ in teams[1::2]]  # each round, both on the same teams
    assert not torch.equal(teams[0][1], teams[2][1])  # a fresh rollout each round
    assert [r["algo"] for r in rows] == ["comat", "mappo"]
    for r in rows:
        assert r["env_steps"] == 4 and len(r["update_s"]) == 2 and r["median_s"] > 0 and r["task"] == "pcp"
        assert len(r["robots_per_team"]) == 2
    assert rows[0]["robots_per_team"] == rows[1]["robots_per_team"]  # the same teams for each learner
    with pytest.raises(ValueError, match="qmix"):
        bench_update(["qmix"], rounds=1, preset=str(preset))


def test_bench_train_times_an_overlapped_learner_as_update_plus_wait(tmp_path):
    """``--overlap``: the row of a PPO learner with ``ppo.overlap``: its iteration is the update and the
    wait for the collection beside it; QMIX has no such option."""
    from unittest import mock

    import yaml

    from comat.bench import bench_train, learn_bench

    preset = tmp_path / "tiny.yaml"
    preset.write_text(
        yaml.safe_dump(
            {
                "ppo": {"num_envs": 2, "rollout_steps": 2, "epochs": 1, "minibatches": 1},
                "models": {"mappo": {"hidden": 16}},
            }
        )
    )
    seen = []
    real = learn_bench.make_learner
    with mock.patch.object(
        learn_bench, "make_learner", side_effect=lambda c, *a: seen.append(c.trainer) or real(c, *a)
    ):
        plain, overlapped = (bench_train("mappo", iterations=2, preset=str(preset), overlap=o) for o in (False, True))
    assert [t.overlap for t in seen] == [False, True] and seen[0].num_envs == seen[1].num_envs == 2
    assert not plain["overlap"] and plain["wait_s"] is None and plain["env_s"] > 0 and plain["act_s"] > 0
    assert overlapped["overlap"] and overlapped["env_s"] is None and overlapped["act_s"] is None
    assert overlapped["env_steps"] == plain["env_steps"] == 8 and overlapped["wait_s"] >= 0
    # the iteration's wall time is the update and the wait (to the timer's rounding)
    total = overlapped["env_steps"] / overlapped["env_steps_per_s"]
    assert total >= overlapped["learn_s"] + overlapped["wait_s"] - 1e-3
    with pytest.raises(ValueError, match="overlap is a PPO option; qmix has none"):
        bench_train("qmix", iterations=1, preset=str(preset), overlap=True)


def test_bench_train_comat_paper_trains_the_paper_form(tmp_path):
    """``comat_paper`` in ``bench learn``: the same preset with COMAT's paper-form options; the
    ``comat_<option>`` rows change that one option."""
    from unittest import mock

    import yaml

    from comat.bench import bench_train, learn_bench
    from comat.models import PAPER_FORM

    preset = tmp_path / "tiny.yaml"
    preset.write_text(
        yaml.safe_dump(
            {
                "ppo": {"num_envs": 2, "rollout_steps": 2, "epochs": 1, "minibatches": 1},
                "models": {
                    "comat": {
                        "embed": 16,
                        "heads": 2,
                        "heat_blocks": 1,
                        "edge_embed": 8,
                        "obs_embed": True,
                        "node_ffn": True,
                    }
                },
            }
        )
    )
    seen = []
    real = learn_bench.make_learner
    with mock.patch.object(learn_bench, "make_learner", side_effect=lambda c, *a: seen.append(c.model) or real(c, *a)):
        names = ("comat", "comat_paper", "comat_shared_trunk", "comat_one_block", "comat_adapters")
        rows = [bench_train(name, iterations=1, preset=str(preset)) for name in names]
    assert [r["algo"] for r in rows] == list(names) and all(r["env_steps"] == 4 for r in rows)
    assert seen[0].obs_embed and seen[0].node_ffn and seen[0].embed == 16 and seen[0].decision == "adapters"
    assert {k: getattr(seen[1], k) for k in PAPER_FORM} == PAPER_FORM and seen[1].embed == 16
    assert seen[2].decision == "shared_trunk" and seen[2].obs_embed and seen[3].heat_blocks == 1 and seen[3].embed == 16
    assert seen[4].decision == "adapters"


def test_sweep_status_of_a_missing_folder_is_an_error(tmp_path, capsys):
    assert main(["sweep", "--preset", "quick", "--out", str(tmp_path / "nowhere"), "--status"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "does not exist: no sweep has run there" in err[0]
    assert not (tmp_path / "nowhere").exists()


def test_version_and_help_percent(capsys):
    from comat import __version__

    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0 and capsys.readouterr().out.startswith(f"comat {__version__}")
    with pytest.raises(SystemExit):
        main(["eval", "--help"])
    out = capsys.readouterr().out
    assert "95% confidence" in out and "%%" not in out


def test_train_without_a_preset_says_its_budget_and_time_first(tmp_path, capsys, monkeypatch):
    """Issue 32: ``comat train`` without --preset starts the paper's 4 M-step run; its first line
    says so, with the time it takes here, before anything else is printed."""
    # Stop where training would start: the line is printed before; the run itself is not the test.
    monkeypatch.setattr("comat.rl.runner.train", lambda *a, **k: (_ for _ in ()).throw(KeyboardInterrupt))
    with pytest.raises(KeyboardInterrupt):
        main(["train", "--algo", "comat", "--task", "pcp", "--out", str(tmp_path / "run")])
    first = capsys.readouterr().err.splitlines()[0]
    assert first.startswith("no --preset: the paper's budget, 4,000,000 env steps (about 2-6 h")
    assert "--preset quick" in first


def test_train_says_when_overlap_leaves_the_collection_no_core(tmp_path, capsys, monkeypatch):
    """``ppo.overlap`` with the env workers, the collecting thread and the learner's threads wanting
    more than the usable CPUs: a note before the run says so and what leaves each its own core."""
    monkeypatch.setattr("comat.rl.runner.train", lambda *a, **k: (_ for _ in ()).throw(KeyboardInterrupt))
    monkeypatch.setattr("comat.machine.usable_cpus", lambda: 4)
    args = ["train", "--algo", "comat", "--task", "pcp", "--preset", "quick", "--out", str(tmp_path / "run")]
    for extra, said in (
        (["ppo.overlap=true", "env_workers=2", "torch_threads=2"], "torch_threads=1 leave each its own"),
        (["ppo.overlap=true", "env_workers=1", "torch_threads=2"], None),  # 1 + 1 + 2 = 4 CPUs
        (["env_workers=2", "torch_threads=3"], None),  # no overlap
    ):
        with pytest.raises(KeyboardInterrupt):
            main(args + extra)
        err = capsys.readouterr().err
        notes = [line for line in err.splitlines() if line.startswith("note: ppo.overlap")]
        if said is None:
            assert not notes
        else:
            assert len(notes) == 1
            assert "2 env worker(s), the collecting thread and 2 learner thread(s) on 4 CPU(s)" in notes[0]
            assert notes[0].endswith(said)
        assert ("the next rollout collected beside each update (ppo.overlap)" in err) == ("ppo.overlap=true" in extra)
