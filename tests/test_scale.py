"""U_scale (teams of 10-20 robots) and the fixed-size baselines with 20 slots."""

import pytest
from test_rl import TINY_MODELS, tiny

from comat.cli import main
from comat.envs.base import resolve_coalitions
from comat.eval import evaluate_policies
from comat.rl import train
from comat.team import CAPABILITY_RANGES, COALITION_SETS, SIZES, generate_coalitions


@pytest.mark.parametrize("task", ["pcp", "hmt"])
def test_scale_set_has_teams_past_eight_slots_with_the_unseen_ranges(task):
    teams = resolve_coalitions("scale", task)
    assert COALITION_SETS[:4] == ("train", "val", "test", "scale") and len(teams) == 20
    assert {t.size for t in teams} == set(SIZES["scale"]) == {10, 12, 16, 20}
    assert CAPABILITY_RANGES[(task, "scale")] == CAPABILITY_RANGES[(task, "test")]
    # Adding the set changed neither of the others (each set has its own random stream).
    assert generate_coalitions(task, "scale") != generate_coalitions(task, "test")


@pytest.mark.parametrize(
    "algo", ["mappo", pytest.param("mat", marks=pytest.mark.slow), pytest.param("qmix", marks=pytest.mark.slow)]
)
def test_baselines_with_20_slots_train_on_u_train_and_play_u_scale(tmp_path, algo):
    """A tiny run with 20 slots, then all 20 U_scale teams (MAPPO's critic state covers the 20)."""
    wide = {**TINY_MODELS, algo: {**TINY_MODELS[algo], "max_robots": 20}}
    config = tiny(algo, models=wide)
    assert config.model.max_robots == 20
    train(config, tmp_path / "run", quiet=True)
    result = evaluate_policies(
        tmp_path / "run" / "checkpoint.pt", sets=("scale",), references=False, progress=lambda m: None
    )
    (row,) = result["rows"]
    assert row["set"] == "scale" and row["episodes"] == 20
    assert max(e["team_size"] for e in row["per_episode"]) == 20


def test_an_eight_slot_baseline_is_refused_on_u_scale(tmp_path, capsys):
    train(tiny("mat"), tmp_path / "run", quiet=True)
    assert main(["eval", "--checkpoint", str(tmp_path / "run" / "checkpoint.pt"), "--set", "scale"]) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert "teams of up to 20 robots" in err and "8 robot slots" in err and "models.mat.max_robots=20" in err


def test_a_20_robot_recording_costs_no_more_per_robot_than_an_8_robot_one(tmp_path):
    """Rerun bytes per robot-step of a scripted 20-robot U_scale episode < 2x an 8-robot U_test
    one (measured 2026-12-01: PCP 854 vs 1414 B, HMT 291 vs 675 B per robot-step)."""
    from comat.viz.rollout import record_episodes

    per_robot_step = {}
    for name, split, n in (("8", "test", 8), ("20", "scale", 20)):
        team = next(t for t in resolve_coalitions(split, "pcp") if t.size == n)
        path = tmp_path / f"pcp_{name}.rrd"
        result = record_episodes(path, "pcp", "heuristic", teams=[team], tier="unicycle", max_robots=n)
        per_robot_step[name] = path.stat().st_size / (n * result.episodes[0]["steps"])
    assert per_robot_step["20"] < 2 * per_robot_step["8"]


def test_layouts_of_changing_vectors_of_large_teams_hold_little_memory():
    """A vector env's tuple of team sizes changes with nearly every reset: 300 distinct vectors of
    32 U_scale teams leave at most 16 layouts cached (~2.4 MB at 20 robots each), where a cache of
    256 had held ~21 MiB (the U_scale soak's memory growth, issue 21)."""
    import numpy as np

    from comat.sim.layout import team_layout

    rng = np.random.default_rng(0)
    team_layout.cache_clear()
    for _ in range(300):
        team_layout(tuple(rng.choice(SIZES["scale"], 32).tolist()))
    largest = team_layout((20,) * 32)
    held = sum(
        a.nbytes for a in (largest.offsets, largest.robot_team, largest.pair_i, largest.pair_j, largest.pair_team)
    )
    assert team_layout.cache_info().currsize <= 16 and 16 * held < 3 * 2**20
