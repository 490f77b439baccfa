"""The coverage study's machinery (results/calibration/coverage.py runs twenty seeds; here two):
logs simulated at a known truth, fitted and written by ``comat calibrate``, every interval read back
from the written profile and judged against the truth it is for; the same seed gives the same
intervals; the committed table judges every parameter that claims 95 %."""

from __future__ import annotations

import runpy
from pathlib import Path

from comat.calibration.coverage import COVERAGE_TRUTH, JUDGED, fleet_truth, summarize
from comat.calibration.intervals import PARAMETER_KINDS

ROOT = Path(__file__).resolve().parents[1]
STUDY = runpy.run_path(str(ROOT / "results" / "calibration" / "coverage.py"))


def test_two_seeds_judge_every_written_interval_of_its_kind(tmp_path):
    results = [STUDY["run_seed"](seed, tmp_path) for seed in (0, 1)]
    for r in results:
        assert set(r) == {*JUDGED, "pose_delay_ticks"}
        for name in JUDGED:  # each written interval is of its parameter's kind and judged against the fleet's truth
            assert r[name]["kind"] == PARAMETER_KINDS[name] and r[name]["lo"] <= r[name]["hi"], (name, r[name])
            assert r[name]["truth"] == fleet_truth(COVERAGE_TRUTH)[name]
            assert r[name]["covered"] == (r[name]["lo"] - 1e-12 <= r[name]["truth"] <= r[name]["hi"] + 1e-12)
        assert r["pose_delay_ticks"]["truth"] in ([1, 2], [1, 3], [2, 3], [2, 2], [1, 1], [3, 3])
    assert STUDY["run_seed"](1, tmp_path / "again") == results[1]  # the same logs, the same intervals
    table = summarize(results)
    assert [row["name"] for row in table] == [*JUDGED, "pose_delay_ticks"]
    assert all(0 <= row["covered"] <= row["seeds"] == 2 for row in table)
    page = STUDY["render"](results, 60.0)
    assert page.count("\n| `") == len(table) + 0 and "≥ 2 of 2" in page and "| 1 |" in page


def test_the_committed_table_judges_every_parameter_that_claims_95():
    page = (ROOT / "results" / "calibration" / "coverage.md").read_text()
    for name in JUDGED:
        assert f"| `{name}` | {STUDY['KINDS'][PARAMETER_KINDS[name]]} |" in page, name
