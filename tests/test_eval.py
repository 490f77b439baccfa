"""Evaluation: confidence intervals on hand-made episodes, `comat eval`, `comat probe` (`comat report`:
tests/test_report.py; `comat sweep`: tests/test_sweep.py)."""

import json
import math
import re

import numpy as np
import pytest
import yaml

from comat.cli import main
from comat.measure.metrics import REPORTED, mean_ci, read_results, summarize_ci, violations
from comat.tasks import env_id, task_names

T_975_3 = 3.182446305284263  # Student t quantile, 97.5 %, 3 degrees of freedom


def _episode(ret, steps=80.0, completion=0.5, success=0.0, collisions=0.0, rc=0.0, be=0.0, ae=0.0):
    return {
        "return": ret,
        "steps": steps,
        "progress": completion,
        "finished": success,
        "collisions": collisions,
        "robotarium_collisions": rc,
        "boundary_exits": be,
        "actuator_errors": ae,
        "interventions": 3.0,
        "fallbacks": 0.0,
        "recoveries": 1.0,
    }


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
    eps = [
        _episode(10.0, success=1.0, rc=1.0, be=2.0),
        _episode(20.0, ae=1.0),
        _episode(30.0, collisions=3.0),
        _episode(40.0, success=1.0),
    ]
    assert [violations(e) for e in eps] == [3.0, 1.0, 0.0, 0.0]
    table = summarize_ci(eps)
    # rows from before the progress curve (older files) have no AUC or t90, and none from before the
    # coordination metric (or of a task without one) has it: left out, not made up
    assert list(table) == [m for m in REPORTED if m not in ("progress_auc", "time_to_90", "coordination")]
    full = summarize_ci([{**e, "progress_auc": 0.5, "time_to_90": 70.0, "coordination": 0.25} for e in eps])
    assert list(full) == list(REPORTED) and full["time_to_90"] == {"mean": 70.0, "ci95": 0.0, "n": 4}
    assert table["return"]["mean"] == 25.0 and table["return"]["n"] == 4
    assert table["return"]["ci95"] == pytest.approx(T_975_3 * np.std([10, 20, 30, 40], ddof=1) / 2)
    assert table["finished"]["mean"] == 0.5
    assert table["violations"]["mean"] == 1.0
    assert table["collisions"]["mean"] == 0.75
    assert table["interventions"] == {"mean": 3.0, "ci95": 0.0, "n": 4}
    assert table["recoveries"] == {"mean": 1.0, "ci95": 0.0, "n": 4}


def test_summarize_ci_averages_within_coalitions_first():
    """K episodes of a coalition are one unit: 5 identical copies per coalition give the interval
    of 1 episode each, where pooling the 100 episodes would have shrunk it by ~sqrt(5)."""
    rng = np.random.default_rng(0)
    once = [_episode(float(r), completion=float(c)) for r, c in zip(rng.normal(10, 3, 20), rng.uniform(0, 1, 20))]
    five = [{**once[i % 20], "coalition": i % 20, "episode_in_coalition": i // 20} for i in range(100)]
    a, b = summarize_ci(once), summarize_ci(five)
    for m in ("return", "progress"):
        assert b[m]["mean"] == pytest.approx(a[m]["mean"]) and b[m]["ci95"] == pytest.approx(a[m]["ci95"])
        assert b[m]["n"] == 20 and a[m]["ci95"] > 0
        pooled = mean_ci([e[m] for e in five])[1]  # the old rule: every episode a unit
        assert pooled < 0.5 * a[m]["ci95"]
    # rows of older files carry no coalition: episode i is coalition i % n_coalitions
    legacy = [{k: v for k, v in e.items() if k not in ("coalition", "episode_in_coalition")} for e in five]
    assert summarize_ci(legacy, n_coalitions=20)["return"] == b["return"]
    assert summarize_ci(legacy)["return"]["n"] == 100  # unknown design: every episode its own unit
    # coalitions differ, episodes within one vary: the interval is over the 2 coalition means
    eps = [{**_episode(v), "coalition": c} for v, c in ((1.0, 0), (3.0, 0), (10.0, 1), (12.0, 1))]
    t = summarize_ci(eps)["return"]
    assert t["mean"] == 6.5 and t["n"] == 2 and t["ci95"] == pytest.approx(mean_ci([2.0, 11.0])[1])
    with pytest.raises(ValueError, match="n_coalitions must be a positive integer or None, got 0"):
        summarize_ci(eps, n_coalitions=0)


def test_eval_table_and_file_carry_the_endpoints(tmp_path):
    """Two episodes per coalition of a two-team set: rows name their coalition and start, the
    table shows AUC, t90 and the task's coordination metric with a footer saying what each means
    for this task and what ± is over, the file round-trips."""
    from comat.envs.base import resolve_coalitions
    from comat.eval.evaluate import evaluate_policies, print_table, table_lines, write_results

    own = resolve_coalitions("train", "pcp")[:2]
    result = evaluate_policies(
        None,
        task="pcp",
        sets=[("two", own)],
        episodes=2,
        tier="unicycle",
        references=("constant",),
        progress=lambda s: None,
    )
    row = result["rows"][0]
    eps = row["per_episode"]
    assert [(e["coalition"], e["episode_in_coalition"]) for e in eps] == [(0, 0), (1, 0), (0, 1), (1, 1)]
    assert row["metrics"]["progress_auc"]["n"] == 2 and row["episodes"] == 4
    for e in eps:
        assert {
            "progress_curve",
            "progress_auc",
            "time_to_90",
            "reached_90",
            "robots",
            "by_type",
            "sensed_not_captured",
            "coordination",
        } <= set(e)
    assert row["metrics"]["coordination"]["n"] == 2
    lines = []
    print_table(result, out=lines.append)
    head = lines[0].split()
    assert head[head.index("finished") + 1 : head.index("finished") + 4] == ["AUC", "t90", "coord."]
    footer = lines[lines.index("") + 1 :]  # the notes, after the tables and a blank line
    notes = "\n".join(footer).replace("\n  ", " ").splitlines()  # each note on one line again
    assert footer[0] == "progress (pcp) = fraction of the active prey captured" and max(map(len, footer)) <= 120
    assert notes[2].startswith("coord. = sensed prey waiting: share of the team's prey sensed but not yet captured")
    assert "reality layer off (comat eval --reality)" in notes
    assert any(
        "t-interval over the coalitions' means (each coalition's 2 episode(s) averaged first" in x for x in notes
    )
    assert notes[-1].startswith(f"start states: drawn from seed {result['seed']}")
    json_path, detail_path, csv_path = write_results(result, tmp_path)
    assert read_results(json_path) == result  # the summary with its per-episode detail put back
    assert detail_path.name == "eval.episodes.json.gz" and '"per_episode":' not in json_path.read_text()
    assert "constant,pcp,two,unicycle,4,progress_auc," in csv_path.read_text()
    assert "constant,pcp,two,unicycle,4,coordination," in csv_path.read_text()
    # a file from before the metric: its column says n/a
    old = {**result, "rows": [{**row, "metrics": {k: v for k, v in row["metrics"].items() if k != "coordination"}}]}
    old_lines = table_lines(old)
    cells = re.split(r" {2,}", old_lines[2])
    assert cells[re.split(r" {2,}", old_lines[0]).index("coord.")] == "n/a"


def test_a_reference_rung_plays_once_per_process_and_its_rows_equal_a_fresh_play():
    """The ladder's episodes are kept by everything they depend on: a second evaluation on the same
    sets reuses them (and says so), equal to playing them afresh; another seed plays again; a
    caller that changes its rows does not change what the next evaluation gets."""
    from comat.envs.base import resolve_coalitions
    from comat.eval import evaluate as ev

    own = resolve_coalitions("train", "pcp")[:2]
    said = []

    def run(seed=5):
        return ev.evaluate_policies(None, "pcp", [("two", own)], 1, "unicycle", seed, ("heuristic",), said.append)

    ev._REFERENCE_EPISODES.clear()
    first = run()
    first["rows"][0]["per_episode"][0]["progress"] = -1.0  # the caller's copy, not the kept one
    again = run()
    assert "played earlier in this process" in said[-1] and "played earlier" not in said[0]
    ev._REFERENCE_EPISODES.clear()
    fresh = run()
    assert "played earlier" not in said[-1]
    assert json.dumps(again["rows"], sort_keys=True, default=str) == json.dumps(
        fresh["rows"], sort_keys=True, default=str
    )
    run(seed=6)
    assert "played earlier" not in said[-1]


def test_eval_table_fits_a_terminal_and_names_the_privileged_rows():
    """Issue 67's newcomer: the table was ~190 characters wide, its footer one long paragraph, and
    the heuristic beat COMAT with no word that it reads the task's full state."""
    from comat.eval import print_table
    from comat.measure.metrics import REPORTED

    metrics = {m: {"mean": 0.97, "ci95": 0.05, "n": 20} for m in REPORTED}
    metrics |= {m: {"mean": 0.0, "ci95": 0.0, "n": 20} for m in ("collisions", "violations", "fallbacks", "recoveries")}
    metrics |= {
        "return": {"mean": 32.77, "ci95": 1.93, "n": 20},
        "interventions": {"mean": 244.5, "ci95": 101.62, "n": 20},
    }
    rows = [
        {"policy": p, "set": "capability", "episodes": 100, "metrics": metrics}
        for p in ("comat", "heuristic", "random")
    ]
    lines = []
    print_table(
        {"task": "pcp", "rows": rows, "episodes_per_coalition": 5, "reality": "off", "seed": 7}, out=lines.append
    )
    text = "\n".join(lines).splitlines()
    assert max(map(len, text)) <= 140
    heads = [line.split() for line in text if line.startswith("policy ")]
    assert heads == [["policy", "set", "n", "return", "steps", "progress", "finished", "AUC", "t90", "coord."],
                     ["policy", "set", "n", "interv."]]  # fmt: skip
    assert "0 in every row: collisions, violations, fallbacks, recoveries (the JSON and CSV hold every column)" in text
    assert any(line.startswith("heuristic: the scripted planner, reading the task's full state") for line in text)
    # every column zero in some row but not all stays; a run without the scripted rows has no such note
    rows[0]["metrics"] = {**metrics, "collisions": {"mean": 0.1, "ci95": 0.2, "n": 20}}
    lines = []
    print_table({"task": "pcp", "rows": [rows[0], rows[2]]}, out=lines.append)
    text = "\n".join(lines)
    heads = [line.split() for line in text.splitlines() if line.startswith("policy ")]
    assert heads[1] == ["policy", "set", "n", "collisions", "interv."]
    assert "0 in every row: violations, fallbacks, recoveries" in text and "privileged" not in text


# -- comat eval -------------------------------------------------------------------------------------
def test_eval_cli_checkpoint_and_references(tmp_path, capsys):
    from test_rl import tiny

    from comat.rl import train

    train(tiny("comat"), tmp_path / "run", quiet=True)
    ckpt = tmp_path / "run" / "checkpoint.pt"
    assert main(["eval", "--policy", str(tmp_path / "run"), "--teams", "test"]) == 0  # a run folder: its checkpoint
    out = capsys.readouterr().out
    assert "comat" in out and "heuristic" in out and "constant" in out and "random" in out and "±" in out
    result = read_results(tmp_path / "run" / "evaluation_unicycle.json")
    rows = {r["policy"]: r for r in result["rows"]}
    assert set(rows) == {"comat", "heuristic", "type_only", "blind", "constant", "random"}
    assert all(r["set"] == "test" for r in rows.values())
    assert all(r["episodes"] == 20 for r in rows.values())  # the 20 unseen coalitions, one episode each
    # the table's numbers are the per-episode metrics' means
    for r in rows.values():
        assert r["metrics"]["return"]["mean"] == pytest.approx(np.mean([e["return"] for e in r["per_episode"]]))
    assert rows["heuristic"]["metrics"]["finished"]["mean"] > rows["random"]["metrics"]["finished"]["mean"]
    csv_text = (tmp_path / "run" / "evaluation_unicycle.csv").read_text().splitlines()
    assert csv_text[0] == "policy,task,set,tier,episodes,metric,mean,ci95" and len(csv_text) == 1 + 6 * len(REPORTED)
    # the constant row is every robot always taking the task's best constant action (+x on PCP)
    from comat.envs import make_vec_env
    from comat.envs.base import resolve_coalitions
    from comat.measure.episodes import run_episodes

    env = make_vec_env("pcp_v0", 20, seed=2_000_003, tier="unicycle", coalitions="test")
    direct = run_episodes(env, lambda o, m, s: np.where(m, 1, 0), resolve_coalitions("test", "pcp"), seed=2_000_003)
    assert [e["return"] for e in rows["constant"]["per_episode"]] == pytest.approx([e["return"] for e in direct])
    assert rows["constant"]["metrics"]["progress"]["mean"] > rows["random"]["metrics"]["progress"]["mean"]
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
    assert (
        main(
            [
                "eval",
                "--policy",
                "constant",
                "--task",
                "pcp",
                "--teams",
                str(teams),
                "--no-references",
                "--out",
                str(fresh),
            ]
        )
        == 0
    )
    capsys.readouterr()
    mine = read_results(fresh / "evaluation_unicycle.json")["rows"]
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
    assert main(["eval", "--policy", "heuristic", "--task", "pcp", "--episodes", "0"]) == 2
    assert "episodes must be an integer >= 1" in capsys.readouterr().err
    assert main(["eval", "--policy", str(ckpt), "--episodes", "0", "--out", str(tmp_path / "failed" / "x")]) == 2
    assert "episodes must be an integer >= 1" in capsys.readouterr().err
    assert not (tmp_path / "failed").exists()


# -- comat probe ---------------------------------------------------------------------------------------
def test_probe_ppo_statistics_are_consistent(tmp_path, capsys):
    from test_rl import tiny

    from comat.eval import probe_checkpoint
    from comat.rl import train

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

    from comat.eval import probe_checkpoint
    from comat.rl import train

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
@pytest.mark.parametrize("task", task_names())
def test_best_constant_action_is_the_best_of_the_five(task):
    """BEST_CONSTANT_ACTION: of the five actions, taken by every robot at every step, one with the
    highest mean return on U_train (one episode per coalition, the evaluation seed)."""
    from comat.envs import make_vec_env
    from comat.envs.base import resolve_coalitions
    from comat.envs.heuristics import BEST_CONSTANT_ACTION
    from comat.eval import EVAL_SEED
    from comat.measure.episodes import run_episodes

    teams = resolve_coalitions("train", task)
    env = make_vec_env(env_id(task), 20, seed=0, tier="unicycle", coalitions="train")
    returns = [
        np.mean([e["return"] for e in run_episodes(env, lambda o, m, s, a=a: np.where(m, a, 0), teams, EVAL_SEED)])
        for a in range(5)
    ]
    # Ties are possible (navigation_v1: +x, +y and -y earn the same): the declared action earns the most.
    assert returns[BEST_CONSTANT_ACTION[task]] == pytest.approx(max(returns)), returns


def test_share_intervals_stay_inside_0_1_and_one_unit_says_it_has_none():
    """Two episodes printed ``progress 0.33 ± 4.24`` (issue 32): a share's interval is cut to its
    range; one seed prints no interval, in words; other metrics keep their symmetric interval."""
    from comat.measure.metrics import interval_text, mean_ci

    mean, half = mean_ci([0.0, 0.66])
    assert half > 1 and interval_text(mean, half, share=True) == "0.33 [0.00, 1.00]"
    assert interval_text(0.5, 0.1, share=True) == "0.50 ± 0.10"
    assert interval_text(0.75, 3.177, share=True, scale=100, digits=1) == "75.0 [0.0, 100.0]"
    assert interval_text(-3.0, 5.0) == "-3.00 ± 5.00"
    assert interval_text(0.9, float("nan")) == "0.90 (1 seed, no interval)"
    assert interval_text(0.9, float("nan"), unit=None) == "0.90"
