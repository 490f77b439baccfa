"""Task validity (comat.eval.validity, ``comat validity``): paired gaps over coalitions, the two families,
the page, and the type_only rung it rests on (comat.envs.heuristics)."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from comat.cli.main import main
from comat.envs.heuristics import band_mean, reference_policy, type_mean_capabilities, type_only_actions
from comat.eval.validity import (
    CAPABILITY_GAP,
    SIZE_GAP,
    families,
    summarize_task,
    validity_markdown,
    write_summary,
)
from comat.measure.metrics import mean_ci
from comat.tasks import COALITION_SETS, LADDER, task_names


def _row(split: str, policy: str, per_coalition: list[float], episodes: int = 2) -> dict:
    eps = [{"coalition": c, "progress": p} for _ in range(episodes) for c, p in enumerate(per_coalition)]
    return {"set": split, "policy": policy, "per_episode": eps}


def _result(progress: dict, task: str = "demo") -> dict:
    """A result as evaluate_policies returns it: progress[(set, policy)] = per-coalition shares."""
    rows = [_row(s, p, v) for (s, p), v in progress.items()]
    return {"task": task, "env_id": f"{task}_v0", "seed": 7, "episodes_per_coalition": 2, "rows": rows}


def _ladder(split: str, scripted, type_only, blind) -> dict:
    return {(split, "heuristic"): scripted, (split, "type_only"): type_only, (split, "blind"): blind}


def test_gaps_are_paired_by_coalition_with_a_t_interval():
    rng = np.random.default_rng(0)
    scripted = list(rng.uniform(0.8, 1.0, 20))
    type_only = [s - d for s, d in zip(scripted, rng.uniform(0.05, 0.25, 20))]
    summary = summarize_task(_result(_ladder("capability", scripted, type_only, type_only)))
    gap = summary["sets"]["capability"]["scripted_minus_type_only"]
    mean, half = mean_ci([100 * (a - b) for a, b in zip(scripted, type_only)])
    assert gap["n"] == 20 and gap["mean"] == pytest.approx(mean) and gap["low"] == pytest.approx(mean - half)
    # Unpaired, the coalitions' own spread would widen the interval: pairing is what makes it tight.
    assert half < mean_ci([100 * s for s in scripted])[1] + mean_ci([100 * t for t in type_only])[1]


def test_capability_family_needs_the_gap_and_the_lower_bound():
    flat = [1.0] * 20
    ok = summarize_task(_result(_ladder("capability", flat, [0.8 + 0.01 * (c % 3) for c in range(20)], flat)))
    assert ok["families"]["capability"][0], ok["families"]["capability"][1]
    # A 12-point mean from a few coalitions only: the interval reaches below 5, not in the family.
    spiky = [0.0] * 17 + [0.8] * 3
    noisy = summarize_task(_result(_ladder("capability", flat, [1 - s for s in spiky], flat)))
    gap = noisy["sets"]["capability"]["scripted_minus_type_only"]
    assert gap["mean"] >= CAPABILITY_GAP and gap["low"] <= 5 and not noisy["families"]["capability"][0]
    assert "lower bound ≤ 5" in noisy["families"]["capability"][1]


def test_size_family_pools_size_and_scale_and_needs_a_solvable_task():
    def result(scripted: float, blind: float) -> dict:
        progress = {}
        for split in ("size", "scale"):
            progress.update(_ladder(split, [scripted] * 20, [scripted] * 20, [blind] * 20))
        return _result(progress)

    good = summarize_task(result(0.95, 0.80))
    assert good["size_pooled"]["scripted_minus_blind"]["n"] == 40 and good["families"]["size"][0]
    assert not summarize_task(result(0.85, 0.60))["families"]["size"][0]  # scripted below 90 %
    assert not summarize_task(result(0.95, 0.95 - (SIZE_GAP - 1) / 100))["families"]["size"][0]
    assert families({"sets": {}})["size"] == (False, "no U_size / U_scale blind rows")


def test_page_and_summary_files(tmp_path):
    progress = {}
    for split in COALITION_SETS:
        progress.update(_ladder(split, [1.0] * 20, [0.7] * 20, [0.5] * 20))
        progress[(split, "constant")] = [0.1] * 20
        progress[(split, "random")] = [0.0] * 20
    data = write_summary(tmp_path, {"demo": summarize_task(_result(progress))})
    page = (tmp_path / "validity.md").read_text()
    assert json.loads((tmp_path / "validity.json").read_text()) == json.loads(json.dumps(data))
    assert (
        "| demo | demo_v0 | — | **yes**" in page and "1 tasks: 1 in the capability family, 1 in the size family" in page
    )
    assert "| U_cap | 100.0 | 70.0 | 50.0 | 10.0 | 0.0 | +30.0 [+30.0, +30.0] | +50.0 [+50.0, +50.0] |" in page
    # Merged: a second task's summary keeps the first one's.
    write_summary(tmp_path, {"other": summarize_task(_result(progress, "other"))})
    assert set(json.loads((tmp_path / "validity.json").read_text())["tasks"]) == {"demo", "other"}
    assert validity_markdown(data).startswith("# Task validity")


def test_band_mean_is_uniform_over_the_union():
    assert band_mean(((0.0, 1.0),)) == pytest.approx(0.5)
    # [0, 1] and [3, 4]: equal widths, mean 2; [0, 1] and [3, 6]: a draw lands in the wider band 3 times in 4.
    assert band_mean(((0.0, 1.0), (3.0, 4.0))) == pytest.approx(2.0)
    assert band_mean(((0.0, 1.0), (3.0, 6.0))) == pytest.approx(0.25 * 0.5 + 0.75 * 4.5)
    assert band_mean(((0.0, 0.0),)) == 0.0


def test_type_mean_capabilities_by_set_and_for_teams_of_ones_own():
    from comat.tasks import task_entry
    from comat.team import generate_coalitions

    entry = task_entry("forage")
    means = type_mean_capabilities("forage", "capability")
    for t, kind in enumerate(entry.types.types):
        assert means[t] == pytest.approx([band_mean(b) for b in entry.bands["capability"][kind]])
    teams = generate_coalitions("forage", "train", 5, seed=3)
    own = type_mean_capabilities("forage", None, teams)
    heavy = [r.capabilities for team in teams for r in team.robots if r.type == "heavy"]
    assert own[0] == pytest.approx(np.mean(heavy, axis=0))


def test_type_only_plays_the_planner_with_type_means():
    """The rung passes the type means, not the robots' own values, to the task's planner; on forage (whose
    planner reads levels) it acts differently from the scripted rung on some teams."""
    from comat.envs import make_vec_env
    from comat.team import generate_coalitions

    teams = generate_coalitions("forage", "capability", 4, seed=1)
    env = make_vec_env("forage_v0", 4, seed=0, coalitions=teams)
    env.reset(seed=5, teams=teams)
    seen = []
    env.task.scripted_actions = lambda state, poses, type_ids, caps, mask: (
        seen.append(caps.copy()) or np.zeros(mask.shape, np.int64)
    )
    means = type_mean_capabilities("forage", "capability")
    type_only_actions(env.core, means)
    core = env.core
    assert np.allclose(seen[0][core.mask], means[core.type_ids][core.mask])
    assert np.all(seen[0][~core.mask] == 0)
    assert not np.allclose(seen[0][core.mask], core.caps[core.mask])  # the robots' own values differ
    with pytest.raises(ValueError, match="reference policy must be one of"):
        reference_policy("greedy", core, 0)


def test_ladder_names_and_alias():
    assert LADDER == ("heuristic", "type_only", "blind", "constant", "random")
    from comat.cli.args import resolve_policy_arg

    assert resolve_policy_arg("scripted", "pcp").name == "heuristic"
    assert resolve_policy_arg("type_only", "pcp").name == "type_only"


def test_cli_summary_only_reads_the_written_evaluations(tmp_path, capsys):
    from comat.eval import evaluate_policies, write_results

    result = evaluate_policies(
        None, "pcp", [("capability", _pcp_teams())], 1, "unicycle", 11, references=LADDER, progress=lambda m: None
    )
    folder = tmp_path / "validity" / "pcp"
    folder.mkdir(parents=True)
    write_results(result, folder, "evaluation_unicycle")
    assert main(["validity", "--summary-only", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "pcp: capability no" in out and (tmp_path / "validity.md").is_file()
    summary = json.loads((tmp_path / "validity.json").read_text())["tasks"]["pcp"]
    # PCP's planner reads no capability: its type_only rung plays exactly as the scripted one.
    assert summary["sets"]["capability"]["scripted_minus_type_only"]["mean"] == 0.0
    assert main(["validity", "--out", str(tmp_path), "--tasks", "pcp"]) == 2  # results there: --force needed
    assert "--force replaces them" in capsys.readouterr().err


def _pcp_teams():
    from comat.team import generate_coalitions

    return generate_coalitions("pcp", "capability", 3, seed=1)


@pytest.mark.parametrize("rung", ["type_only", "blind", "random"])
def test_rungs_are_deterministic_per_seed(rung):
    from comat.eval import evaluate_policies

    def progress(seed: int) -> list[float]:
        result = evaluate_policies(
            None,
            "forage",
            [("test", _forage_teams())],
            1,
            "unicycle",
            seed,
            references=(rung,),
            progress=lambda m: None,
        )
        return [e["progress_curve"] for e in result["rows"][0]["per_episode"]]

    assert progress(3) == progress(3)


def _forage_teams():
    from comat.team import generate_coalitions

    return generate_coalitions("forage", "test", 2, seed=1)


@pytest.mark.parametrize("task", task_names())
def test_eval_type_only_runs_for_every_task(task, tmp_path, capsys, monkeypatch):
    """``comat eval --policy type_only --task T --teams capability`` (the issue's check), on every task,
    as written: without ``--out`` it writes to ``runs/type_only-T``."""
    monkeypatch.chdir(tmp_path)
    code = main(["eval", "--policy", "type_only", "--task", task, "--teams", "capability", "--no-references"])
    assert code == 0
    table = capsys.readouterr().out
    assert re.search(r"^type_only +capability +20 ", table, re.MULTILINE), table
    assert (tmp_path / "runs" / f"type_only-{task}" / "evaluation_unicycle.json").is_file()


def test_page_says_when_type_only_is_below_blind(tmp_path):
    progress = {}
    for split in COALITION_SETS:
        progress.update(_ladder(split, [1.0] * 20, [0.5] * 20, [0.8] * 20))
    write_summary(tmp_path, {"demo": summarize_task(_result(progress))})
    page = (tmp_path / "validity.md").read_text()
    assert "On U_cap type_only (50.0 %) is below blind (80.0 %)" in page
    assert "the scripted plan gains +20.0 [+20.0, +20.0] points there" in page


def test_recorded_families_are_of_every_task_as_it_is_now(capsys):
    """comat/data/validity.json (``comat validity --record``) holds every registered task at its current
    version: a task whose rules change (a new env id) must be judged again."""
    from comat.cli.tasks import recorded_families
    from comat.tasks import TASKS, env_id

    recorded = recorded_families()
    for task in task_names():
        if not TASKS[task].logic.__module__.startswith("comat.tasks."):
            continue  # a plug-in task another test registered (the docs page's example)
        assert recorded[task]["env_id"] == env_id(task), f"{task}: run comat validity --tasks {task} --record"
    assert main(["tasks"]) == 0
    assert "families (comat validity, seed 4000037): capability, size" in capsys.readouterr().out
