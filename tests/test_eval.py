"""Evaluation: confidence intervals on hand-made episodes, `comat eval`, `comat report` on
hand-made run folders (`comat sweep`: tests/test_sweep.py)."""

import csv
import io
import json
import math

import matplotlib.colors as mcolors
import numpy as np
import pytest
import yaml

from comat.cli import main
from comat.eval.metrics import REPORTED, mean_ci, summarize_ci, violations
from comat.eval.report import PAPER_TABLE1, REPORT_FILES, make_report

T_975_3 = 3.182446305284263  # Student t quantile, 97.5 %, 3 degrees of freedom


def _episode(ret, steps=80.0, completion=0.5, success=0.0, collisions=0.0, rc=0.0, be=0.0, ae=0.0):
    return {"return": ret, "steps": steps, "completion": completion, "success": success, "collisions": collisions,
            "robotarium_collisions": rc, "boundary_exits": be, "actuator_errors": ae, "interventions": 3.0,
            "fallbacks": 0.0, "recoveries": 1.0}


# -- metrics ---------------------------------------------------------------------------------------
def test_mean_ci_by_hand():
    mean, half = mean_ci([1.0, 2.0, 3.0, 4.0])
    assert mean == 2.5
    assert half == pytest.approx(T_975_3 * np.std([1, 2, 3, 4], ddof=1) / 2, rel=1e-9)
    assert mean_ci([5.0, 5.0, 5.0]) == (5.0, 0.0)
    m, h = mean_ci([7.0])
    assert m == 7.0 and math.isnan(h)
    assert mean_ci([0.0, 1.0], confidence=0.5)[1] == pytest.approx(0.5, rel=1e-9)  # t(0.75, 1) = 1
    with pytest.raises(ValueError, match="non-empty"):
        mean_ci([])
    with pytest.raises(ValueError, match="confidence"):
        mean_ci([1.0, 2.0], confidence=1.5)


def test_summarize_ci_by_hand():
    eps = [_episode(10.0, success=1.0, rc=1.0, be=2.0), _episode(20.0, ae=1.0), _episode(30.0, collisions=3.0),
           _episode(40.0, success=1.0)]
    assert [violations(e) for e in eps] == [3.0, 1.0, 0.0, 0.0]
    table = summarize_ci(eps)
    assert list(table) == list(REPORTED)
    assert table["return"]["mean"] == 25.0 and table["return"]["n"] == 4
    assert table["return"]["ci95"] == pytest.approx(T_975_3 * np.std([10, 20, 30, 40], ddof=1) / 2)
    assert table["success"]["mean"] == 0.5
    assert table["violations"]["mean"] == 1.0
    assert table["collisions"]["mean"] == 0.75
    assert table["interventions"] == {"mean": 3.0, "ci95": 0.0, "n": 4}
    assert table["recoveries"] == {"mean": 1.0, "ci95": 0.0, "n": 4}


# -- comat eval -------------------------------------------------------------------------------------
def test_eval_cli_checkpoint_and_references(tmp_path, capsys):
    from test_rl import tiny

    from comat.rl.runner import train

    train(tiny("comat"), tmp_path / "run", quiet=True)
    ckpt = tmp_path / "run" / "checkpoint.pt"
    assert main(["eval", "--policy", str(tmp_path / "run"), "--teams", "test"]) == 0  # a run folder: its checkpoint
    out = capsys.readouterr().out
    assert "comat" in out and "heuristic" in out and "constant" in out and "random" in out and "±" in out
    result = json.loads((tmp_path / "run" / "evaluation_unicycle.json").read_text())
    rows = {r["policy"]: r for r in result["rows"]}
    assert set(rows) == {"comat", "heuristic", "constant", "random"} and all(r["set"] == "test" for r in rows.values())
    assert all(r["episodes"] == 20 for r in rows.values())  # the 20 unseen coalitions, one episode each
    # the table's numbers are the per-episode metrics' means
    for r in rows.values():
        assert r["metrics"]["return"]["mean"] == pytest.approx(np.mean([e["return"] for e in r["per_episode"]]))
    assert rows["heuristic"]["metrics"]["success"]["mean"] > rows["random"]["metrics"]["success"]["mean"]
    csv_text = (tmp_path / "run" / "evaluation_unicycle.csv").read_text().splitlines()
    assert csv_text[0] == "policy,task,set,tier,episodes,metric,mean,ci95" and len(csv_text) == 1 + 4 * len(REPORTED)
    # the constant row is every robot always taking the task's best constant action (+x on PCP)
    from comat.envs import make_vec_env
    from comat.envs.base import resolve_coalitions
    from comat.eval.episodes import run_episodes

    env = make_vec_env("pcp_v0", 20, seed=2_000_003, tier="unicycle", coalitions="test")
    direct = run_episodes(env, lambda o, m, s: np.where(m, 1, 0), resolve_coalitions("test", "pcp"), seed=2_000_003)
    assert [e["return"] for e in rows["constant"]["per_episode"]] == pytest.approx([e["return"] for e in direct])
    assert rows["constant"]["metrics"]["completion"]["mean"] > rows["random"]["metrics"]["completion"]["mean"]
    # --out: never overwritten without --force (the old spellings still work, with a note)
    assert main(["eval", "--checkpoint", str(ckpt), "--set", "test", "--no-references"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert err[0].startswith("comat: --checkpoint is deprecated") and err[1].startswith("comat: --set is deprecated")
    assert "evaluation_unicycle.json', '" in err[2] and "' already exist; pass --force to replace" in err[2]
    # a team file of one's own, an --out created on the way, and the rows named by the file
    teams = tmp_path / "teams.yaml"
    own = resolve_coalitions("train", "pcp")[:2]
    teams.write_text(yaml.safe_dump({"coalitions": [{"robots": [r.to_dict() for r in t.robots]} for t in own]}))
    fresh = tmp_path / "new" / "deeper"
    assert main(["eval", "--policy", "constant", "--task", "pcp", "--teams", str(teams), "--no-references",
                 "--out", str(fresh)]) == 0
    capsys.readouterr()
    mine = json.loads((fresh / "evaluation_unicycle.json").read_text())["rows"]
    assert [(r["policy"], r["set"], r["episodes"]) for r in mine] == [("constant", str(teams), 2)]
    env = make_vec_env("pcp_v0", 2, seed=2_000_003, tier="unicycle", coalitions=own)
    direct = run_episodes(env, lambda o, m, s: np.where(m, 1, 0), own, seed=2_000_003)
    assert [e["return"] for e in mine[0]["per_episode"]] == pytest.approx([e["return"] for e in direct])
    # bad input: clear errors, and a failed command leaves no folder behind
    assert main(["eval", "--policy", str(ckpt), "--task", "hmt"]) == 2
    assert "--task 'hmt' disagrees with the checkpoint, which is for task 'pcp'" in capsys.readouterr().err
    assert main(["eval", "--policy", str(tmp_path / "missing.pt")]) == 2
    assert "(no such file)" in capsys.readouterr().err
    assert main(["eval", "--policy", "heuristic"]) == 2
    assert "--task is needed with --policy heuristic" in capsys.readouterr().err
    assert main(["eval", "--policy", "heuristic", "--task", "pcp"]) == 2
    assert "--out is needed with --policy heuristic" in capsys.readouterr().err
    assert main(["eval", "--policy", str(ckpt), "--episodes", "0", "--out", str(tmp_path / "failed" / "x")]) == 2
    assert "episodes must be an integer >= 1" in capsys.readouterr().err
    assert not (tmp_path / "failed").exists()


# -- comat report --------------------------------------------------------------------------------------
def _fake_run(folder, algo, task, seed, train_return, test_return, success, scale_return=None, progress=0.5):
    """A run folder as `comat train` + `comat eval` leave it: two episodes per set (team sizes 3, 5 on
    U_train; 2, 4 on U_test; 10, 20 on U_scale when ``scale_return`` is given)."""
    folder.mkdir(parents=True)
    config = {"algo": algo, "task": task, "seed": seed, "tier": "unicycle", "total_env_steps": 25600}
    (folder / "config.yaml").write_text(yaml.safe_dump({"config": config}))
    lines = ["env_steps,updates,episode_return"] + [f"{2560 * k},{k},{train_return * k / 10}" for k in range(1, 11)]
    (folder / "progress.csv").write_text("\n".join(lines) + "\n")

    def row(split, ret, sizes, prog):
        eps = [{**_episode(ret - 1.0, success=success, completion=prog), "team_size": sizes[0]},
               {**_episode(ret + 1.0, success=success, completion=prog), "team_size": sizes[1]}]
        return {"policy": algo, "task": task, "set": split, "tier": "unicycle", "episodes": 2,
                "metrics": summarize_ci(eps), "per_episode": eps}

    rows = [row("train", train_return, (3, 5), progress), row("test", test_return, (2, 4), progress / 2)]
    if scale_return is not None:
        rows.append(row("scale", scale_return, (10, 20), progress / 4))
    result = {"episodes_per_coalition": 1, "rows": rows}
    (folder / "evaluation_unicycle.json").write_text(json.dumps(result))


def test_retention_names_the_seeds_it_covers(tmp_path):
    """A seed with no U_train progress has no retention: the mean is over the others, and the table
    says so instead of printing the seed count of the row."""
    for seed, progress in enumerate((0.8, 0.4, 0.0)):
        _fake_run(tmp_path / f"r{seed}", "qmix", "pcp", seed, 40.0, 30.0, 0.0, progress=progress)
    out = tmp_path / "results"
    out.mkdir()
    gen = make_report([tmp_path / f"r{seed}" for seed in range(3)], out)["generalization"][0]
    assert gen["seeds"] == 3 and gen["test_retention_seeds"] == 2 and gen["test_retention"] == pytest.approx(0.5)
    row = next(line for line in (out / "generalization.md").read_text().splitlines() if line.startswith("| PCP"))
    assert row.endswith("| 50.0 ± 0.0 (2 of 3 seeds) |"), row


def test_report_on_fake_runs(tmp_path, capsys):
    _fake_run(tmp_path / "a", "comat", "pcp", 0, 40.0, 30.0, 1.0, progress=0.8)
    _fake_run(tmp_path / "b", "comat", "pcp", 1, 60.0, 50.0, 0.5, progress=0.4)
    out = tmp_path / "results"
    out.mkdir()
    result = make_report([tmp_path / "a", tmp_path / "b"], out)
    assert result["groups"] == {"comat/pcp": 2} and result["sets"] == ["train", "test"]
    assert sorted(result["files"]) == sorted(REPORT_FILES)
    for name in REPORT_FILES:
        assert (out / name).stat().st_size > 0
        magic = {"png": b"\x89PNG\r\n\x1a\n", "pdf": b"%PDF"}.get(name.rsplit(".", 1)[1])
        if magic:
            assert (out / name).read_bytes()[: len(magic)] == magic
    md = (out / "table1.md").read_text()
    # mean over the two seeds ± t(0.975, 1) · sd/√2 = 12.706 · 14.142 / 1.414
    assert "| PCP | Mean return | 50.00 ± 127.06 | 82.47 |" in md
    assert "| PCP | Completion | 75.0% ± 317.7 | 92.8% |" in md
    assert "| PCP | Env-step budget per run | 25,600 | 4,000,000 |" in md
    gen = result["generalization"][0]
    assert gen["train_return"] == 50.0 and gen["test_return"] == 40.0 and gen["test_return_ratio"] == pytest.approx(0.8)
    # progress retention: per seed progress on U_test / on U_train (0.4/0.8 and 0.2/0.4), then the mean
    assert gen["train_progress"] == pytest.approx(0.6) and gen["test_retention"] == pytest.approx(0.5)
    assert not any(k.startswith("scale") for k in gen)  # old runs: train and test only
    assert gen["paper_retention_return_ratio"] == 0.88
    assert PAPER_TABLE1[("pcp", "return")][3] == 82.47
    with pytest.raises(FileNotFoundError, match="not a run folder"):
        make_report([tmp_path / "results"], out)
    # Runs without `comat eval`: a warning for some, an error (nothing written) for all.
    (tmp_path / "b" / "evaluation_unicycle.json").unlink()
    out2 = tmp_path / "results2"
    out2.mkdir()
    assert make_report([tmp_path / "a", tmp_path / "b"], out2)["runs"] == 2
    assert "b has no evaluation" in capsys.readouterr().err
    (tmp_path / "a" / "evaluation_unicycle.json").unlink()
    with pytest.raises(ValueError, match=r"none of the 2 run folder\(s\) has an evaluation"):
        make_report([tmp_path / "a", tmp_path / "b"], out2)
    assert main(["report", str(tmp_path / "a"), "--out", str(tmp_path / "fresh")]) == 2
    assert "has an evaluation" in capsys.readouterr().err and not (tmp_path / "fresh").exists()  # no folder left


def test_report_with_u_scale_team_size_and_fixed_colours(tmp_path, monkeypatch, capsys):
    from comat.eval import figures

    for seed in range(3):
        _fake_run(tmp_path / f"c{seed}", "comat", "hmt", seed, 10.0 + seed, 8.0, 1.0, scale_return=5.0 + seed,
                  progress=0.6 + 0.1 * seed)
    _fake_run(tmp_path / "m0", "mat", "hmt", 0, 9.0, 7.0, 1.0)  # an old run: no U_scale evaluation
    drawn = {}
    real_save = figures.save

    def keep(fig, stem):
        drawn[stem.name] = fig
        return real_save(fig, stem)

    monkeypatch.setattr(figures, "save", keep)
    colours = []
    for order in ([*[tmp_path / f"c{s}" for s in range(3)], tmp_path / "m0"],
                  [tmp_path / "m0", *[tmp_path / f"c{s}" for s in range(3)]]):
        out = tmp_path / f"out{len(colours)}"
        assert main(["report", *map(str, order), "--out", str(out)]) == 0
        printed = capsys.readouterr().out
        assert "scale/train retention" in printed
        gen = {r["algo"]: r for r in csv.DictReader(io.StringIO((out / "generalization.csv").read_text()))}
        assert float(gen["comat"]["scale_retention"]) == pytest.approx(0.25)  # progress/4 over progress, every seed
        assert gen["mat"]["scale_retention"] == "nan"  # U_scale columns, empty for the run without it
        # bars: each algorithm's colour, whatever the order the runs came in; sets by hatching only
        ax = drawn["fig5_generalization"].axes[0]
        bars = {(round(p.get_x() + p.get_width() / 2, 3), p.get_hatch()): p.get_facecolor()[:3] for p in ax.patches
                if hasattr(p, "get_hatch") and p.get_width() > 0}
        colours.append(sorted({tuple(round(c, 3) for c in v) for v in bars.values()}))
        assert {h for _, h in bars} == {figures.SET_HATCHES[s] for s in ("train", "test", "scale")}
        # team size figure: every size evaluated, the training sizes marked, intervals over 3 seeds
        lines = {ln.get_label(): ln for ln in drawn["fig6_team_size"].axes[0].get_lines()}
        comat = next(ln for k, ln in lines.items() if k.startswith("COMAT (3 seeds)"))
        assert list(comat.get_xdata()) == [2, 3, 4, 5, 10, 20]
        assert comat.get_color() == figures.ALGO_COLORS["comat"]
        assert "U_train's sizes 3, 5, 7" in drawn["fig6_team_size"].axes[0].get_xlabel()
        rows = list(csv.DictReader(io.StringIO((out / "aggregates.csv").read_text())))
        assert {(r["algo"], r["set"]) for r in rows} >= {("comat", "scale"), ("mat", "test")}
    assert colours[0] == colours[1]
    expected = sorted(tuple(round(c, 3) for c in mcolors.to_rgb(figures.ALGO_COLORS[a])) for a in ("comat", "mat"))
    assert all(any(np.allclose(c, e, atol=0.01) for e in expected) for c in colours[0])


def test_generalization_table_decides_the_claim_only_where_intervals_allow(tmp_path):
    """generalization.md: progress ± interval per set, and per unseen set whether COMAT's 95 %
    interval over seeds lies above each baseline's — "above", "overlapping", "not decidable" with
    one seed, "not evaluated" for a baseline that cannot play the set."""
    runs = []
    finished = {"comat": (1.0, 1.0, 1.0), "mappo": (0.5, 0.5, 0.5), "qmix": (0.0, 0.5, 1.0)}
    for algo, base, step in (("comat", 0.8, 0.02), ("mappo", 0.2, 0.02), ("qmix", 0.6, 0.3)):
        for seed in range(3):
            runs.append(tmp_path / f"{algo}{seed}")
            _fake_run(runs[-1], algo, "pcp", seed, 10.0, 8.0, finished[algo][seed], scale_return=5.0,
                      progress=base + step * seed)
    runs.append(tmp_path / "mat0")
    _fake_run(runs[-1], "mat", "pcp", 0, 9.0, 7.0, 1.0)  # one seed, no U_scale
    runs.append(tmp_path / "comat_hmt")
    _fake_run(runs[-1], "comat", "hmt", 0, 9.0, 7.0, 1.0)  # a task no baseline ran
    out = tmp_path / "out"
    out.mkdir()
    make_report(runs, out)
    md = (out / "generalization.md").read_text()
    assert "| PCP | COMAT | 3 | 82.0 ± 5.0 | 41.0 ± 2.5 | 20.5 ± 1.2 | 50.0 ± 0.0 | 25.0 ± 0.0 |" in md
    assert "| PCP | MAT | 1 | 50.0 | 25.0 | — | 50.0 | — |" in md
    scale = next(line for line in md.splitlines() if line.startswith("* PCP, U_scale"))
    # the verdict compares progress (not retention), and says so
    assert "COMAT reaches 20.5 ± 1.2 % progress (25.0 ± 0.0 % of its U_train progress); its 95 % progress interval vs" in scale
    assert "MAPPO: above" in scale and "QMIX: overlapping" in scale and "MAT: not evaluated on U_scale" in scale
    test = next(line for line in md.splitlines() if line.startswith("* PCP, U_test"))
    assert "MAT: not decidable (needs 2+ seeds each)" in test
    assert "MAPPO: no runs; QMIX: no runs; MAT: no runs." in next(ln for ln in md.splitlines() if ln.startswith("* HMT, U_test"))
    # the finished share per set, with its own verdicts: where progress saturates, it still separates
    assert "| PCP | MAPPO | 3 | 50.0 ± 0.0 | 50.0 ± 0.0 | 50.0 ± 0.0 |" in md
    assert "| PCP | QMIX | 3 | 50.0 ± 124.2 | 50.0 ± 124.2 | 50.0 ± 124.2 |" in md
    scale = [line for line in md.splitlines() if line.startswith("* PCP, U_scale")]
    assert len(scale) == 2 and "COMAT finishes 100.0 ± 0.0 % of its episodes; its 95 % finished-share interval" in scale[1]
    assert "MAPPO: above" in scale[1] and "QMIX: overlapping" in scale[1]
    # COMAT's runs alone (e.g. its wheels-tier report): the lines say there is nothing to compare with
    alone = tmp_path / "alone"
    alone.mkdir()
    make_report([r for r in runs if r.name.startswith("comat")], alone)
    lines = [ln for ln in (alone / "generalization.md").read_text().splitlines() if ln.startswith("* PCP, U_scale")]
    assert lines[0].endswith("(25.0 ± 0.0 % of its U_train progress); no baseline in these runs.")


def test_a_report_written_twice_is_the_same_bytes(tmp_path):
    """Every file of a report, the PDFs included (no creation date), so regenerating committed
    results shows a diff only where a number or a figure changed."""
    for seed in range(2):
        _fake_run(tmp_path / f"c{seed}", "comat", "pcp", seed, 10.0 + seed, 8.0, 1.0, scale_return=5.0)
    written = []
    for k in range(2):
        out = tmp_path / f"out{k}"
        out.mkdir()
        make_report([tmp_path / "c0", tmp_path / "c1"], out)
        written.append({f.name: f.read_bytes() for f in sorted(out.iterdir())})
    assert any(name.endswith(".pdf") for name in written[0])
    assert written[0] == written[1]


def test_aggregate_iqm_and_stratified_bootstrap_by_hand():
    from scipy import stats

    from comat.eval.report import aggregate

    rng = np.random.default_rng(0)
    scores = rng.normal(size=(5, 20))
    agg = aggregate(scores)
    assert agg["mean"] == pytest.approx(scores.mean())
    assert agg["iqm"] == pytest.approx(stats.trim_mean(scores.ravel(), 0.25))  # rliable's IQM: pooled, 25 % cut
    assert agg["mean_lo"] < agg["mean"] < agg["mean_hi"] and agg["iqm_lo"] < agg["iqm"] < agg["iqm_hi"]
    np.random.seed(5)
    before = np.random.random()
    np.random.seed(5)
    assert aggregate(scores) == agg  # a fixed random state: the same intervals every time ...
    assert np.random.random() == before  # ... and numpy's global generator left as it was
    # one seed: nothing to resample within a coalition, the interval collapses onto the point
    one = aggregate(scores[:1])
    assert one["mean_lo"] == pytest.approx(one["mean"]) == pytest.approx(one["mean_hi"])
    with pytest.raises(ValueError, match=r"\(seeds, coalitions\) array, got shape \(3,\)"):
        aggregate(np.ones(3))


# -- comat probe ---------------------------------------------------------------------------------------
def test_probe_ppo_statistics_are_consistent(tmp_path, capsys):
    from test_rl import tiny

    from comat.eval.probe import probe_checkpoint
    from comat.rl.runner import train

    train(tiny("mappo", "hmt"), tmp_path / "run", quiet=True)
    ckpt = tmp_path / "run" / "checkpoint.pt"
    assert main(["probe", "--policy", str(ckpt), "--envs", "4"]) == 0
    assert "robot-weighted mean advantage" in capsys.readouterr().out
    result = json.loads((tmp_path / "run" / "probe.json").read_text())
    assert result["kind"] == "ppo" and result["algo"] == "mappo" and result["num_envs"] == 4
    rows = result["by_team_size"]
    assert result["team_steps"] == 4 * 3  # tiny preset: rollouts of 3 steps
    assert sum(r["share"] for r in rows) == pytest.approx(1.0)
    # advantages are normalized over team-steps: their team-step mean is 0 ...
    assert sum(r["share"] * r["advantage"] for r in rows) == pytest.approx(0.0, abs=1e-5)
    # ... and the robot-weighted mean is the same numbers weighted by team size
    weighted = sum(r["share"] * r["size"] * r["advantage"] for r in rows) / sum(r["share"] * r["size"] for r in rows)
    assert result["robot_weighted_advantage"] == pytest.approx(weighted, abs=1e-5)
    assert 0.0 < result["entropy"] <= math.log(5) + 1e-6
    again = json.loads(json.dumps(probe_checkpoint(ckpt, num_envs=4)))  # through JSON, as the file was
    assert again["by_team_size"] == rows  # same seed, same rollout
    assert main(["probe", "--policy", str(tmp_path / "missing.pt")]) == 2
    assert "got '" + str(tmp_path / "missing.pt") + "' (no such file)" in capsys.readouterr().err
    assert main(["probe", "--policy", "heuristic"]) == 2
    assert "--policy must be a checkpoint or run folder here, got 'heuristic'" in capsys.readouterr().err
    assert main(["probe", "--policy", str(tmp_path / "run")]) == 2  # probe.json exists: not replaced
    assert "probe.json' already exists; pass --force" in capsys.readouterr().err


def test_probe_qmix_action_gap_and_mixer_gain(tmp_path):
    import torch
    from test_rl import tiny

    from comat.eval.probe import probe_checkpoint
    from comat.rl.runner import train

    train(tiny("qmix", "pcp"), tmp_path / "run", quiet=True)
    ckpt = tmp_path / "run" / "checkpoint.pt"
    result = probe_checkpoint(ckpt, num_envs=3)
    assert result["kind"] == "qmix" and result["episodes"] == 3
    assert result["action_gap"] > 0.0 and result["mixer_gain"] > 0.0  # abs() weights: monotonic mixing
    for shares in result["greedy_actions"].values():
        assert sum(shares.values()) == pytest.approx(1.0, abs=1e-3)
    # agents whose Q ignores the action: no gap, and every robot's greedy choice is action 0
    data = torch.load(ckpt, weights_only=False)
    agents = data["trainer"]["agents"]
    for k in ("net.w2", "net.b2"):  # the type heads' output layer
        agents[k] = torch.zeros_like(agents[k])
    torch.save(data, tmp_path / "flat.pt")
    flat = probe_checkpoint(tmp_path / "flat.pt", num_envs=3)
    assert flat["action_gap"] == 0.0
    assert all(shares["stay"] == 1.0 for shares in flat["greedy_actions"].values())


@pytest.mark.slow
@pytest.mark.parametrize("task", ["pcp", "hmt"])
def test_best_constant_action_is_the_best_of_the_five(task):
    """BEST_CONSTANT_ACTION: of the five actions, taken by every robot at every step, the one with
    the highest mean return on U_train (one episode per coalition, the evaluation seed)."""
    from comat.envs import make_vec_env
    from comat.envs.base import resolve_coalitions
    from comat.eval.episodes import run_episodes
    from comat.eval.evaluate import BEST_CONSTANT_ACTION, EVAL_SEED

    teams = resolve_coalitions("train", task)
    env = make_vec_env(f"{task}_v0", 20, seed=0, tier="unicycle", coalitions="train")
    returns = [np.mean([e["return"] for e in run_episodes(env, lambda o, m, s, a=a: np.where(m, a, 0), teams, EVAL_SEED)])
               for a in range(5)]
    assert int(np.argmax(returns)) == BEST_CONSTANT_ACTION[task], returns
