"""Result files (issue 46): an evaluation's summary with its per-episode detail gzipped beside it,
read back as written (and the plain files written before as they are); no absolute path of the
machine in what a command writes; the commit of the source in every run's config.yaml; the eval
table's columns never touching."""

import gzip
import json
import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from comat.files import (
    detail_name,
    portable_command,
    read_json_detail,
    relative_path,
    write_json_detail,
)
from comat.measure.metrics import REPORTED, read_results

ROOT = Path(__file__).resolve().parents[1]


def _episode(i: int, **extra) -> dict:
    return {
        "return": 1.5 * i,
        "steps": 40.0 + i,
        "progress": 0.25 * (i % 5),
        "finished": float(i % 2),
        "coalition": i % 3,
        "progress_curve": [0.1 * k for k in range(i + 2)],
        "robots": [{"type": "fast", "delivered": 0.5 * i}],
        **extra,
    }


def _result(checkpoint=None) -> dict:
    rows = [
        {
            "policy": p,
            "task": "pcp",
            "set": s,
            "tier": "unicycle",
            "reality": "off",
            "episodes": 6,
            "metrics": {
                "return": {"mean": 42.6, "ci95": 9.45, "n": 3},
                "progress": {"mean": 0.97, "ci95": 0.2, "n": 3},
            },
            "per_episode": [_episode(i) for i in range(6)],
        }
        for p in ("comat", "heuristic")
        for s in ("train", "test")
    ]
    return {
        "checkpoint": checkpoint,
        "algo": "comat",
        "task": "pcp",
        "tier": "unicycle",
        "seed": 2_000_003,
        "episodes_per_coalition": 2,
        "reality": "off",
        "rows": rows,
    }


def _strings(node):
    if isinstance(node, dict):
        for k, v in node.items():
            yield k
            yield from _strings(v)
    elif isinstance(node, list):
        for v in node:
            yield from _strings(v)
    elif isinstance(node, str):
        yield node


# -- the format --------------------------------------------------------------------------------------
def test_summary_and_detail_round_trip(tmp_path):
    result = _result()
    sweep = {
        "component": "pose_delay_ticks",
        "values": [0, 2],
        "points": [{"value": v, "rows": _result()["rows"]} for v in (0, 2)],
    }
    for name, doc in (("evaluation_unicycle.json", result), ("evaluation_unicycle_sweep_x.json", sweep)):
        paths = write_json_detail(tmp_path / name, doc)
        assert [p.name for p in paths] == [name, detail_name(name)]
        assert paths[1].name.endswith(".episodes.json.gz")
        assert read_json_detail(paths[0]) == doc == read_results(paths[0])  # the document as it was written
        summary = json.loads(paths[0].read_text())
        assert '"per_episode":' not in paths[0].read_text() and summary["detail"]["file"] == paths[1].name
        assert paths[1].stat().st_size < len(json.dumps([r["per_episode"] for r in result["rows"]])) / 3
        # detail=False: the summary alone, as a reader of the metrics wants it
        slim = read_results(paths[0], detail=False)
        assert "detail" not in slim and not any("per_episode" in r for r in slim.get("rows", []))
        # the same document gives the same bytes (re-running the conversion changes nothing)
        before = [p.read_bytes() for p in paths]
        write_json_detail(tmp_path / name, doc)
        assert [p.read_bytes() for p in paths] == before
    # a document without detail is one plain file
    assert write_json_detail(tmp_path / "plain.json", {"rows": [{"metrics": {}}]}) == [tmp_path / "plain.json"]
    assert not (tmp_path / detail_name("plain.json")).exists()


def test_old_plain_files_and_gzipped_files_still_read(tmp_path):
    old = _result()
    old["rows"][0]["metrics"]["completion"] = old["rows"][0]["metrics"].pop("progress")  # before issue 32
    (tmp_path / "old.json").write_text(json.dumps(old))
    got = read_results(tmp_path / "old.json")
    assert got["rows"][0]["metrics"]["progress"] == {"mean": 0.97, "ci95": 0.2, "n": 3}
    assert got["rows"][1]["per_episode"] == old["rows"][1]["per_episode"]
    (tmp_path / "whole.json.gz").write_bytes(gzip.compress(json.dumps(_result()).encode()))
    assert read_results(tmp_path / "whole.json.gz") == _result()


def test_a_missing_or_foreign_detail_file_is_an_error(tmp_path):
    a, b = _result(), _result()
    b["rows"][0]["per_episode"][0]["return"] = -1.0
    (tmp_path / "a").mkdir()
    write_json_detail(tmp_path / "a" / "e.json", a)
    write_json_detail(tmp_path / "b.json", b)
    shutil.copy(tmp_path / detail_name("b.json"), tmp_path / "a" / detail_name("e.json"))
    with pytest.raises(ValueError, match="does not belong to"):
        read_results(tmp_path / "a" / "e.json")
    os.remove(tmp_path / "a" / detail_name("e.json"))
    with pytest.raises(FileNotFoundError, match="e.episodes.json.gz"):
        read_results(tmp_path / "a" / "e.json")
    assert read_results(tmp_path / "a" / "e.json", detail=False)["rows"][0]["metrics"] == a["rows"][0]["metrics"]


# -- relative paths ----------------------------------------------------------------------------------
def test_written_results_hold_no_absolute_path(tmp_path):
    from comat.eval import result_files, sweep_files, write_probe, write_results, write_sweep

    run = tmp_path / "runs" / "mine"
    run.mkdir(parents=True)
    paths = write_results(_result(checkpoint=run / "checkpoint.pt"), run, "evaluation_unicycle")
    assert [p.name for p in paths] == result_files("evaluation_unicycle")
    assert read_results(run / "evaluation_unicycle.json")["checkpoint"] == "checkpoint.pt"
    other = tmp_path / "elsewhere"
    other.mkdir()
    write_results(_result(checkpoint=run / "checkpoint.pt"), other, "evaluation_unicycle")
    assert read_results(other / "evaluation_unicycle.json")["checkpoint"] == "../runs/mine/checkpoint.pt"
    sweep = {
        "component": "fault_prob",
        "base": "off",
        "values": [0.0],
        "task": "pcp",
        "tier": "unicycle",
        "episodes_per_coalition": 2,
        "points": [{"value": 0.0, "rows": _result()["rows"]}],
    }
    assert [p.name for p in write_sweep(sweep, run, "evaluation_unicycle_sweep_fault_prob")] == sweep_files(
        "evaluation_unicycle_sweep_fault_prob"
    )
    write_probe({"checkpoint": str(run / "checkpoint.pt"), "algo": "comat"}, run)
    assert json.loads((run / "probe.json").read_text())["checkpoint"] == "checkpoint.pt"
    for path in [*run.iterdir(), *other.iterdir()]:
        text = gzip.decompress(path.read_bytes()).decode() if path.suffix == ".gz" else path.read_text()
        assert str(tmp_path) not in text, path.name
        if path.suffix in (".json", ".gz"):
            assert not [s for s in _strings(json.loads(text)) if s.startswith("/")], path.name


def test_config_yaml_records_a_portable_command_and_the_commit(tmp_path, monkeypatch):
    import yaml
    from test_rl import tiny

    from comat.rl import source_commit
    from comat.rl.runner import _write_config

    monkeypatch.chdir(tmp_path)
    out = tmp_path / "runs" / "a"
    out.mkdir(parents=True)
    argv = ["/opt/venv/bin/comat", "train", "--out", str(out), f"--preset={tmp_path / 'p.yaml'}", "seed=3"]
    _write_config(out, tiny("comat"), None, command=argv)
    doc = yaml.safe_load((out / "config.yaml").read_text())
    assert doc["command"] == ["comat", "train", "--out", "runs/a", "--preset=p.yaml", "seed=3"]
    assert doc["versions"]["commit"] == source_commit()
    assert str(tmp_path) not in (out / "config.yaml").read_text()
    assert portable_command([]) == [] and portable_command(["x", "/e/f", "k=/e"], "/e/g") == ["x", "../f", "k=.."]
    assert relative_path(tmp_path / "a" / "b.pt", tmp_path / "c") == "../a/b.pt"


# -- the commit --------------------------------------------------------------------------------------
@pytest.mark.skipif(shutil.which("git") is None, reason="git is not installed")
def test_source_commit_names_the_checkout_its_state_or_why_not(tmp_path, monkeypatch):
    from comat.rl.checkpoint import SOURCE_COMMIT_ENV, source_commit, versions

    source_commit.cache_clear()
    monkeypatch.delenv(SOURCE_COMMIT_ENV, raising=False)
    repo = tmp_path / "src"
    repo.mkdir()
    env = {
        **os.environ,
        "GIT_AUTHOR_NAME": "t",
        "GIT_AUTHOR_EMAIL": "t@t",
        "GIT_COMMITTER_NAME": "t",
        "GIT_COMMITTER_EMAIL": "t@t",
    }

    def git(*args):
        return subprocess.run(
            ["git", "-C", str(repo), *args], check=True, capture_output=True, text=True, env=env
        ).stdout.strip()

    git("init", "-q")
    (repo / "a.py").write_text("x = 1\n")
    git("add", "a.py")
    git("commit", "-q", "-m", "one")
    head = git("rev-parse", "HEAD")
    assert source_commit(repo) == head
    (repo / "a.py").write_text("x = 2\n")  # an uncommitted change to a tracked file
    assert source_commit(str(repo)) == head + "-dirty"  # another cache key: computed again
    (tmp_path / "copy").mkdir()  # a snapshot without .git: said so, or the commit its maker names
    assert source_commit(tmp_path / "copy") == "unknown (not a git checkout)"
    monkeypatch.setenv(SOURCE_COMMIT_ENV, "abc123-dirty")
    (tmp_path / "copy2").mkdir()
    assert source_commit(tmp_path / "copy2") == "abc123-dirty (snapshot)"
    monkeypatch.delenv(SOURCE_COMMIT_ENV)
    monkeypatch.setenv("PATH", str(tmp_path / "nowhere"))  # no git at all: training goes on
    assert source_commit(tmp_path / "copy3") == "unknown (git not found)"
    monkeypatch.undo()
    source_commit.cache_clear()
    if (ROOT / ".git").exists():  # this checkout: its commit, never unknown
        assert re.fullmatch(r"[0-9a-f]{40}(-dirty)?", versions()["commit"])


# -- the eval table ----------------------------------------------------------------------------------
def test_eval_table_columns_never_touch():
    from comat.eval.evaluate import TABLE_NAMES, table_lines
    from comat.measure.metrics import SHARES, interval_text

    wide = {"mean": 0.97, "ci95": 0.05, "n": 20}  # a share near 1: written "0.97 [0.92, 1.00]"
    metrics = {m: wide for m in REPORTED}
    metrics["return"] = {"mean": 42.6, "ci95": 9.45, "n": 20}
    rows = [
        {"policy": "comat", "set": "train", "episodes": 100, "metrics": metrics},
        {"policy": "heuristic", "set": "capability", "episodes": 5, "metrics": {"return": metrics["return"]}},
    ]
    lines = table_lines({"rows": rows})
    head, rule, *body = lines
    assert set(rule) == {"-"} and len(rule) == len(head)
    assert "9.450.97" not in "".join(body) and "42.60 ± 9.45  " in body[0] and "0.97 [0.92, 1.00]" in body[0]
    names = ["policy", "set", "n", *(TABLE_NAMES[m] for m in REPORTED)]
    # every column at least one space from the next: split at runs of 2+ spaces, each line gives its cells
    assert re.split(r" {2,}", head) == names
    assert re.split(r" {2,}", body[0]) == [
        "comat",
        "train",
        "100",
        *(interval_text(v["mean"], v["ci95"], share=m in SHARES, unit=None) for m, v in metrics.items()),
    ]
    assert re.split(r" {2,}", body[1]) == [
        "heuristic",
        "capability",
        "5",
        "42.60 ± 9.45",
        *["n/a"] * (len(REPORTED) - 1),
    ]
    # right-aligned number columns end where their header ends, in every line
    for name in names[2:]:
        end = head.index(name) + len(name) if name != "n" else head.index(" n ") + 2
        assert all(line[end - 1] != " " and (end == len(line) or line[end] == " ") for line in body), name


def test_replace_block_rewrites_only_what_stands_between_its_markers(tmp_path):
    from comat.files import replace_block

    readme = tmp_path / "README.md"
    readme.write_text(
        "intro\n<!-- table:begin -->\nold\n<!-- table:end -->\nafter <!-- other:begin -->x<!-- other:end -->\n"
    )
    replace_block(readme, "table", "| a |\n")
    assert readme.read_text() == (
        "intro\n<!-- table:begin -->\n| a |\n<!-- table:end -->\nafter <!-- other:begin -->x<!-- other:end -->\n"
    )
    with pytest.raises(ValueError, match="expected the markers <!-- verdict:begin -->"):
        replace_block(readme, "verdict", "y")
