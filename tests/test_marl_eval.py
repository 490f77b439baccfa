"""``comat report --format marl-eval``: comat's run folders as marl-eval's raw JSON, read back by its keys.

The runs are the committed sweep (results/sweep: comat, mat, mappo, qmix on pcp and hmt, seeds 0-2),
real training curves and evaluations. marl-eval itself (PyPI ``id-marl-eval``) pins pandas 1.4.4 and
pulls jax and neptune, so it is no dependency of comat: where it is importable, its own loader and
checker read the file too; elsewhere that test is skipped and the key checks below stand alone.
"""

from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import pytest

from comat.cli import main
from comat.eval.marl_eval import METRICS, marl_eval_data
from comat.eval.runs import evaluation_row, load_run

ROOT = Path(__file__).resolve().parents[1]
SWEEP = sorted((ROOT / "results" / "sweep").glob("*_s[0-9]"))


def _write(tmp_path: Path, folders, *extra: str) -> dict:
    assert main(["report", *map(str, folders), "--format", "marl-eval", "--out", str(tmp_path), *extra]) == 0
    return json.loads((tmp_path / "marl_eval_train.json").read_text())


def test_the_file_has_marl_evals_keys_and_comats_numbers(tmp_path, capsys):
    assert len(SWEEP) == 24  # 4 learners x 2 tasks x 3 seeds
    data = _write(tmp_path, SWEEP)
    assert "wrote" in capsys.readouterr().out
    # env -> task -> algorithm -> seed_S -> step_i / absolute_metrics, as marl-eval's README and BenchMARL's JsonWriter
    assert list(data) == ["comat_unicycle"]
    tasks = data["comat_unicycle"]
    assert sorted(tasks) == ["hmt", "pcp"]
    for task, algos in tasks.items():
        assert sorted(algos) == ["comat", "mappo", "mat", "qmix"]
        for algo, runs in algos.items():
            assert sorted(runs) == ["seed_0", "seed_1", "seed_2"]
            for seed, run in runs.items():
                keys = list(run)
                assert keys[-1] == "absolute_metrics"  # marl-eval takes a run's last key as the absolute one
                assert keys[:-1] == [f"step_{i}" for i in range(len(keys) - 1)]
                counts = [run[k]["step_count"] for k in keys[:-1]]
                assert all(isinstance(c, int) for c in counts) and counts == sorted(counts) and counts[0] > 0
                for k in keys[:-1]:
                    assert set(run[k]) == {"step_count", *METRICS}
                    assert all(len(run[k][m]) == 1 for m in METRICS)
                assert set(run["absolute_metrics"]) == set(METRICS)
                # the numbers are the run's own: eval.csv's rows, and the final evaluation's episodes on U_train
                folder = ROOT / "results" / "sweep" / f"{algo}_{task}_s{seed.split('_')[1]}"
                with open(folder / "eval.csv", newline="") as fh:
                    rows = list(csv.DictReader(fh))
                assert counts == [int(float(r["env_steps"])) for r in rows]
                assert [run[k]["return"][0] for k in keys[:-1]] == [float(r["return"]) for r in rows]
                episodes = evaluation_row(load_run(folder), "train")["per_episode"]
                assert run["absolute_metrics"]["progress"] == [float(e["progress"]) for e in episodes]
                assert len(run["absolute_metrics"]["return"]) == 20  # 20 coalitions x 1 episode


def test_marl_evals_own_loader_reads_it(tmp_path):
    processing = pytest.importorskip("marl_eval.utils.data_processing_utils")
    diagnose = pytest.importorskip("marl_eval.utils.diagnose_data_errors")
    raw = _write(tmp_path, SWEEP)
    checks = diagnose.DiagnoseData(raw).check_data()["comat_unicycle"]
    assert all(checks.values()), checks
    processed = processing.data_process_pipeline(raw_data=raw, metrics_to_normalize=["return"])
    assert processed["extra"]["number_of_runs"] == 3 and processed["extra"]["number_of_steps"] == 6
    scores, _ = processing.create_matrices_for_rliable(
        data_dictionary=processed, environment_name="comat_unicycle", metrics_to_normalize=["return"]
    )
    assert scores["mean_progress"]["mat"].shape == (3, 2)  # seeds x tasks


def test_another_set_gives_the_absolute_metrics(tmp_path):
    folders = [f for f in SWEEP if f.name.startswith("comat_pcp")]
    assert (
        main(["report", *map(str, folders), "--format", "marl-eval", "--out", str(tmp_path), "--absolute-set", "test"])
        == 0
    )
    data = json.loads((tmp_path / "marl_eval_test.json").read_text())
    run = data["comat_unicycle"]["pcp"]["comat"]["seed_0"]
    episodes = evaluation_row(load_run(folders[0]), "test")["per_episode"]
    assert run["absolute_metrics"]["return"] == [float(e["return"]) for e in episodes]


def test_what_marl_eval_cannot_aggregate_is_refused_and_nothing_is_written(tmp_path, capsys):
    pcp = [f for f in SWEEP if "_pcp_" in f.name]
    with pytest.raises(ValueError, match="one per algorithm, task and seed; .* repeats comat pcp seed_0"):
        marl_eval_data([pcp[0], pcp[0]])
    with pytest.raises(ValueError, match=r"the same number of seeds for every algorithm and task of comat_unicycle"):
        marl_eval_data(pcp[:-1])  # qmix with two seeds, the others with three
    short = tmp_path / "comat_pcp_s0"  # a run with one evaluation fewer than the others
    shutil.copytree(pcp[0], short)
    lines = (short / "eval.csv").read_text().splitlines(keepends=True)
    (short / "eval.csv").write_text("".join(lines[:-1]))
    with pytest.raises(
        ValueError, match=rf"evaluations in every run of comat_unicycle: 2 runs have 6, but 5 in '{short}'"
    ):
        marl_eval_data([short, pcp[3], pcp[6]])  # comat seed 0 (cut short), mappo and mat seed 0
    out = tmp_path / "out"
    assert (
        main(["report", str(pcp[0]), "--format", "marl-eval", "--out", str(out), "--absolute-set", "capability"]) == 2
    )
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no comat evaluation on 'capability'" in err and "comat eval --policy" in err
    assert not out.exists()
