"""The README's five minutes and the getting-started page's "Common tasks" run as written (a tiny
training budget appended to `comat train`)."""

import re
import shlex
import sys
import time
from pathlib import Path

import imageio.v3 as iio
import yaml

from comat.cli import main

README = Path(__file__).resolve().parents[1] / "README.md"
GETTING_STARTED = README.parent / "docs" / "getting-started.md"  # the common tasks moved off the front page
# Appended after the README's own overrides: 2 updates of one minibatch, small models.
TINY = [
    "ppo.num_envs=2",
    "ppo.rollout_steps=8",
    "ppo.epochs=1",
    "ppo.minibatches=1",
    "eval_episodes_per_team=0",
    "models.comat.embed=16",
    "models.comat.heads=2",
    "models.comat.heat_blocks=1",
    "models.comat.edge_embed=8",
    "models.mat.embed=16",
    "models.mat.heads=1",
    "models.mat.blocks=1",
]


def _section() -> str:
    """docs/getting-started.md's "Common tasks", between its markers."""
    text = GETTING_STARTED.read_text()
    start, end = "<!-- common-tasks:start -->", "<!-- common-tasks:end -->"
    return text[text.index(start) : text.index(end)]


def test_five_minutes_with_a_shipped_policy_run_as_written(tmp_path, monkeypatch):
    """The README's first section after the front page: a shipped policy measured and watched."""
    text = README.read_text()
    section = text[text.index("<!-- --8<-- [start:quickstart] -->") : text.index("<!-- --8<-- [end:quickstart] -->")]
    commands = [
        line.split("  #")[0]
        for block in re.findall(r"```bash\n(.*?)```", section, flags=re.DOTALL)
        for line in block.splitlines()
        if line.startswith("comat ")
    ]
    assert [c.split()[1] for c in commands] == ["eval", "rollout"]
    monkeypatch.chdir(tmp_path)
    for command in commands:
        assert main(shlex.split(command)[1:]) == 0, command
    assert (tmp_path / "runs" / "pretrained-comat-pcp" / "evaluation_unicycle.json").is_file()
    assert (tmp_path / "comat_pcp.rrd").is_file() and iio.imread("comat_pcp.mp4", index=None).shape[0] >= 2


def test_common_tasks_run_as_written(tmp_path, monkeypatch, capsys):
    section = _section()
    files = re.findall(r"```yaml\n# (\S+)\n(.*?)```", section, flags=re.DOTALL)
    commands = [
        line
        for block in re.findall(r"```bash\n(.*?)```", section, flags=re.DOTALL)
        for line in block.splitlines()
        if line.startswith("comat ")
    ]
    kinds = {c.split()[1] for c in commands}
    assert kinds == {"train", "eval", "report", "rollout"} and len(commands) >= 8
    monkeypatch.chdir(tmp_path)
    for name, body in files:
        Path(name).write_text(body)
        assert yaml.safe_load(body)["robots"]
    notes = []
    for command in commands:
        argv = shlex.split(command)[1:]
        if argv[0] == "train":
            argv = ["train", "--steps", "20", *argv[1:], *TINY]
        t0 = time.perf_counter()
        assert main(argv) == 0, command
        print(f"{time.perf_counter() - t0:.1f} s: {command}", file=sys.__stderr__)
        notes.append(capsys.readouterr())
    # PPO trains whole rollouts: 20 steps of 2 envs x 8 run as 32, and it says so
    assert (
        "note: PPO trains in whole rollouts of 16 env steps (2 environments × 8 steps): 20 env steps run as 32"
        in notes[0].err
    )
    # the overrides went into the run's config, as given and as resolved
    lr = yaml.safe_load(Path("runs/lr/config.yaml").read_text())
    assert lr["config"]["trainer"]["lr"] == 1e-4 and lr["config"]["trainer"]["clip"] == 0.1
    assert "ppo.lr=1e-4" in lr["overrides"]
    # the report holds both algorithms; the own-team evaluation names the file; the video decodes
    md = Path("runs/cmp/report/table1.md").read_text()
    assert "COMAT (ours)" in md and "MAT (ours)" in md and "Env-step budget per run | 20 | 4,000,000" in md
    from comat.measure.metrics import read_results

    rows = read_results("runs/mine/evaluation_unicycle.json")["rows"]
    assert {r["set"] for r in rows} == {"my_team.yaml"} and all(r["episodes"] == 2 for r in rows)
    assert {r["per_episode"][0]["team_size"] for r in rows} == {4}
    frames = iio.imread("my_team.mp4", index=None)
    assert frames.ndim == 4 and frames.shape[0] >= 2
