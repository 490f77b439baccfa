"""One vocabulary in everything comat writes (issue 32): ``progress`` (the fraction of prey captured
/ material delivered), ``finished`` (the share of episodes that completed the task; the paper's
"completion", named only where the paper is quoted) and ``fallbacks`` (the filter's brake). A tiny
training, its evaluation, the tables, the report and an export check are scanned: log lines, CSV
headers, JSON keys and TensorBoard tags."""

import json
import re

import pytest

from comat.cli import main
from comat.measure.metrics import RETIRED_NAMES, current_names

RETIRED = re.compile(r"\b(completion|success|brakes?)\b", re.IGNORECASE)
PAPER_QUOTES = ('the paper\'s "completion"', 'the paper\'s \\"completion\\"', "paper: completion")
"""Where the paper's own word stands, quoted as the paper's."""
TINY = [
    # the paper preset's two env worker processes would cost ~15 CPU seconds of start-up and write
    # nothing of their own: what the scan reads is the same from the learner's process
    "env_workers=1",
    "ppo.num_envs=2",
    "ppo.rollout_steps=8",
    "ppo.epochs=1",
    "ppo.minibatches=1",
    "eval_episodes_per_team=1",
    "eval_every_steps=32",  # one evaluation, at the end: its log line, CSV row and TensorBoard tags are scanned
    "models.comat.embed=16",
    "models.comat.heads=2",
    "models.comat.heat_blocks=1",
    "models.comat.edge_embed=8",
]


def _retired(text: str) -> list[str]:
    for quote in PAPER_QUOTES:
        text = text.replace(quote, "")
    return sorted({m.group(0) for m in RETIRED.finditer(text)})


def _keys(data) -> list[str]:
    if isinstance(data, dict):
        return [k for k, v in data.items() for k in (k, *_keys(v))]
    if isinstance(data, list):
        return [k for v in data for k in _keys(v)]
    return []


@pytest.mark.filterwarnings("ignore::UserWarning")
def test_no_output_uses_a_retired_word(tmp_path, capsys):
    run = tmp_path / "run"
    assert main(["train", "--algo", "comat", "--task", "pcp", "--steps", "32", "--out", str(run), *TINY]) == 0
    assert main(["eval", "--policy", str(run), "--teams", "test", "--episodes", "1", "--out", str(run)]) == 0
    assert main(["report", str(run), "--out", str(tmp_path / "report")]) == 0
    export = tmp_path / "export"
    assert main(["export", "--policy", "heuristic", "--task", "pcp", "--team", "test:1", "--out", str(export)]) == 0
    assert main(["export", "--check", str(export), "--tier", "unicycle"]) == 0
    printed = capsys.readouterr()
    found = {"printed": _retired(printed.out + printed.err)}
    for path in [*run.glob("*.csv"), *(tmp_path / "report").glob("*.csv"), *(tmp_path / "report").glob("*.md")]:
        text = path.read_text()
        found[path.name] = _retired(text if path.suffix == ".md" else text.splitlines()[0])  # CSV: the header
    for path in run.glob("*.json"):
        found[path.name] = _retired(" ".join(_keys(json.loads(path.read_text()))))
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    tags = EventAccumulator(str(run / "tb")).Reload().Tags()["scalars"]
    assert "eval/progress" in tags and "eval/finished" in tags, tags
    found["tensorboard"] = _retired(" ".join(tags))
    assert {k: v for k, v in found.items() if v} == {}


def test_files_written_before_the_rename_are_read_under_todays_names():
    old = {
        "rows": [{"metrics": {"completion": {"mean": 0.5}, "success": {"mean": 0.1}, "brakes": 2}}],
        "header": ["env_steps", "episode_completion", "episode_success"],
    }
    new = current_names(old)
    assert new["rows"][0]["metrics"] == {"progress": {"mean": 0.5}, "finished": {"mean": 0.1}, "fallbacks": 2}
    assert new["header"] == ["env_steps", "episode_progress", "episode_finished"]
    assert current_names(new) == new and set(RETIRED_NAMES.values()).isdisjoint(RETIRED_NAMES)


def test_a_run_started_under_the_old_names_resumes_under_todays(tmp_path):
    from comat.rl.logger import RunLogger

    (tmp_path / "progress.csv").write_text("env_steps,episode_completion,episode_success\n8,0.5,0.0\n")
    logger = RunLogger(tmp_path, resume_step=8, tensorboard=False)
    logger.log("progress", 16, {"episode_progress": 0.75, "episode_finished": 1.0})
    assert (tmp_path / "progress.csv").read_text().splitlines() == [
        "env_steps,episode_progress,episode_finished",
        "8,0.5,0.0",
        "16,0.75,1.0",
    ]
