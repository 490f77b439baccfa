"""The matched arm's equivalence test (results/benchmarl/matched/analyze.py, issue 65): TOST against
statsmodels' own and a case worked by hand, its verdicts, and the report over kept runs."""

import json
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "results" / "benchmarl" / "matched"))
import analyze
from analyze import tost, verdict


def test_tost_equals_statsmodels_welch_tost():
    weightstats = pytest.importorskip("statsmodels.stats.weightstats")
    rng = np.random.default_rng(0)
    for shift, spread_b in ((0.0, 3.0), (2.5, 6.0), (-4.0, 1.5), (7.0, 4.0)):
        a = rng.normal(90, 4, 8)
        b = rng.normal(90 - shift, spread_b, 9)
        ours = tost(a, b, 5.0)
        p, (_, p1, _), (_, p2, _) = weightstats.ttost_ind(a, b, -5.0, 5.0, usevar="unequal")
        assert ours["p"] == pytest.approx(p, rel=1e-9)
        assert ours["p_low"] == pytest.approx(p1, rel=1e-9)
        assert ours["p_high"] == pytest.approx(p2, rel=1e-9)


def test_tost_on_a_case_worked_by_hand():
    """a = 1…4 (mean 2.5, var 5/3), b = a + 1: diff −1, se = √(2·(5/3)/4) = 0.9129, df = 6.
    t_low = (−1 + 2)/0.9129 = 1.0954, p_low = P(T6 > 1.0954) = 0.1577; t_high = (−1 − 2)/0.9129 =
    −3.2863, p_high = 0.00834; p = 0.1577: not equivalent within ±2. The 90 % interval: −1 ± 1.9432 ·
    0.9129 = [−2.774, 0.774], which crosses −2."""
    a = np.array([1.0, 2.0, 3.0, 4.0])
    r = tost(a, a + 1.0, 2.0)
    assert r["diff"] == pytest.approx(-1.0)
    assert r["se"] == pytest.approx(0.912871, abs=1e-6)
    assert r["df"] == pytest.approx(6.0)
    assert r["p_low"] == pytest.approx(0.1577, abs=1e-4)
    assert r["p_high"] == pytest.approx(0.00834, abs=1e-5)
    assert (r["lo"], r["hi"]) == (pytest.approx(-2.774, abs=1e-3), pytest.approx(0.774, abs=1e-3))
    assert not r["equivalent"] and verdict(r, 2.0).startswith("not shown equivalent")
    # With a margin of 3 the 90 % interval lies inside it: equivalent (p < 0.05 exactly when it does).
    wide = tost(a, a + 1.0, 3.0)
    assert wide["equivalent"] and -3 < wide["lo"] and wide["hi"] < 3 and wide["p"] < 0.05
    assert verdict(wide, 3.0) == "equivalent within ±3 points"


def test_tost_verdicts_a_difference_beyond_the_margin_and_a_sample_without_spread():
    far = tost([80.0, 81.0, 79.0, 80.5], [95.0, 96.0, 94.5, 95.5], 5.0)
    assert not far["equivalent"] and far["hi"] < -5
    assert verdict(far).startswith("different by more than 5 points")
    same = tost([100.0, 100.0, 100.0], [100.0, 100.0], 5.0)
    assert same["equivalent"] and same["p"] == 0.0
    assert not tost([100.0, 100.0], [90.0, 90.0], 5.0)["equivalent"]
    with pytest.raises(ValueError, match="a and b must be 1-D with at least 2 values each"):
        tost([1.0], [1.0, 2.0], 5.0)
    with pytest.raises(ValueError, match="margin must be > 0"):
        tost([1.0, 2.0], [1.0, 2.0], 0.0)


def _fake_run(root: Path, name: str, progress: float, arm: str) -> None:
    run = root / name
    run.mkdir(parents=True)
    mean = {"return": 5.0, "progress": progress, "finished": 0.5, "steps": 60.0, "collisions": 0.0}
    (run / "eval.json").write_text(json.dumps({"episodes": 20, "mean": mean}))
    if arm == "comat":
        rows = ["env_steps,episode_return,entropy_fast,entropy_slow"]
        rows += [f"{s},{s / 1e5},0.3,0.9" for s in range(2240, 22401, 2240)]
        (run / "progress.csv").write_text("\n".join(rows) + "\n")
    else:
        rows = ["env_steps,return"] + [f"{s},{s / 1e5}" for s in range(2240, 22401, 2240)]
        (run / "curve.csv").write_text("\n".join(rows) + "\n")
        scalars = run / "mappo_hmt" / "mappo_hmt" / "scalars"  # BenchMARL's CSV logger: step,value rows
        scalars.mkdir(parents=True)
        for group, h in (("fast", 0.3), ("slow", 1.5)):
            (scalars / f"train_{group}_entropy.csv").write_text("".join(f"{k},{h}\n" for k in range(10)))


def test_the_report_gives_each_team_its_verdict_once_both_arms_have_eight_seeds(tmp_path, monkeypatch):
    rng = np.random.default_rng(1)
    for seed in range(8):
        for arm, centre in (("comat", 0.95), ("benchmarl", 0.96)):
            _fake_run(tmp_path / "runs", f"{arm}_hmt5_s{seed}", centre + rng.normal(0, 0.01), arm)
            eight = (0.9 if arm == "comat" else 0.6) + rng.normal(0, 0.01)  # 30 points apart
            _fake_run(tmp_path / "runs", f"{arm}_hmt8_s{seed}", eight, arm)
    _fake_run(tmp_path / "runs", "comat_hmt5_s8", 0.2, "comat")  # a seed without its BenchMARL twin: left out
    monkeypatch.setattr(analyze, "HERE", tmp_path)
    found = analyze.runs(tmp_path / "runs")
    five, ok5 = analyze.team_section(5, found)
    eight, ok8 = analyze.team_section(8, found)
    assert ok5 is True and ok8 is False
    assert "seeds [0, 1, 2, 3, 4, 5, 6, 7]" in five[0]
    assert any("entropy of the slow robots" in line for line in five)
    assert "different by more than 5 points" in eight[-2]
    del found[("benchmarl", 8)][7]
    assert analyze.team_section(8, found)[1] is None  # 7 seeds: no verdict yet
