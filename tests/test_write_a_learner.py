"""docs/write-a-learner.md, run as written (issue 65): its learner module registered, checked
against the contract, trained, evaluated and refused by the export in one line; a file of it read
where it is not registered is refused saying how to register it."""

import contextlib
import io
import os
import re
import shlex
import subprocess
import sys
import types
from pathlib import Path

import numpy as np
import pytest
import torch
import yaml
from test_rl import tiny

import comat
from comat import learners
from comat.cli import main
from comat.rl import train

PAGE = Path(__file__).resolve().parents[1] / "docs" / "write-a-learner.md"


def _blocks(lang: str) -> list[str]:
    return re.findall(rf"```{lang}\n(.*?)```", PAGE.read_text(), flags=re.DOTALL)


def _module_code() -> str:
    """The page's first python block: the learner module."""
    code = _blocks("python")[0]
    assert code.startswith("# solo_example.py"), "the page's first python block is the module"
    return code


@pytest.fixture
def solo(monkeypatch):
    """The page's module imported as ``solo_example`` and its entry registered, for this test only."""
    module = types.ModuleType("solo_example")
    exec(compile(_module_code(), "solo_example.py", "exec"), module.__dict__)  # noqa: S102 - the page's own code
    monkeypatch.setitem(sys.modules, "solo_example", module)
    monkeypatch.setitem(learners._LEARNERS, "solo", module.LEARNER)
    return module


def test_the_page_s_learner_keeps_the_contract_trains_acts_and_is_refused_by_the_export(solo, tmp_path, capsys):
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(_blocks("python")[1], {})  # noqa: S102 - the page's "Check it" block, as written
    assert out.getvalue().startswith("{'modules': ['policy'], 'acts_with': ['policy'], 'parameters': (")
    # a few PPO updates in this process, then its policy file acts and samples like any learner's
    config = tiny("solo", steps=12, models={"solo": {"hidden": 16}})
    assert train(config, tmp_path / "run", quiet=True)["env_steps"] == 12
    policy = comat.load_policy(str(tmp_path / "run"))
    sampling = comat.load_policy(str(tmp_path / "run"), deterministic=False, seed=1)
    kept = torch.load(tmp_path / "run" / "policy.pt", weights_only=True)
    assert tuple(kept["weights"]) == ("policy",) and not any(k.startswith("critic.") for k in kept["weights"]["policy"])
    obs = np.random.default_rng(0).normal(size=(5, kept["dims"]["obs_dim"])).astype(np.float32)
    assert policy.act(obs).shape == (5,) and set(sampling.act(obs)) <= set(range(5))
    code = main(
        ["export", "--policy", str(tmp_path / "run"), "--task", "pcp", "--team", "test:0", "--out", str(tmp_path / "s")]
    )
    err = capsys.readouterr().err.strip()
    assert code == 2 and "\n" not in err and not (tmp_path / "s").exists()
    assert err.startswith("comat export: error: --policy must be a checkpoint or policy file of comat here: an export ")
    assert err.endswith(f"got a solo checkpoint ({tmp_path / 'run' / 'checkpoint.pt'})")


def test_a_file_of_an_unregistered_learner_says_how_to_register_it(solo, tmp_path, monkeypatch):
    train(tiny("solo", steps=6, models={"solo": {"hidden": 8}}), tmp_path / "run", quiet=True)
    monkeypatch.delitem(learners._LEARNERS, "solo")
    with pytest.raises(
        ValueError, match=r"holds a 'solo' policy, but learner 'solo' is not registered .*COMAT_LEARNERS"
    ):
        comat.load_policy(str(tmp_path / "run"))


@pytest.mark.learning  # three PPO updates and an evaluation on U_val in subprocesses (~1 minute): CI's learning tier
def test_the_page_s_commands_run_as_written(tmp_path):
    (tmp_path / "solo_example.py").write_text(_module_code())
    preset = _blocks("yaml")[0]
    assert preset.startswith("# solo.yaml")
    (tmp_path / "solo.yaml").write_text(preset)
    assert yaml.safe_load(preset)["models"] == {"solo": {"hidden": 64}}
    lines = [line for line in _blocks("bash")[0].splitlines() if line.strip()]
    assert lines[0] == "export PYTHONPATH=$PWD COMAT_LEARNERS=solo_example:LEARNER"
    env = {**os.environ, "PYTHONPATH": str(tmp_path), "COMAT_LEARNERS": "solo_example:LEARNER"}

    def comat_cli(args: list[str]) -> subprocess.CompletedProcess:
        cmd = [sys.executable, "-m", "comat.cli", *args]
        return subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600, check=False)

    assert "solo" in comat_cli(["train", "--help"]).stdout
    *runs, export = [shlex.split(line) for line in lines[1:]]
    for args in runs:
        assert args[0] == "comat"
        proc = comat_cli(args[1:])
        assert proc.returncode == 0, f"{' '.join(args)}\n{proc.stdout[-2000:]}\n{proc.stderr[-3000:]}"
    assert (tmp_path / "runs" / "solo" / "policy.pt").is_file()
    assert (tmp_path / "runs" / "solo" / "eval").exists()
    proc = comat_cli(export[1:])
    said = _blocks("text")[0].strip()
    assert proc.returncode == 2 and proc.stderr.strip() == said, proc.stderr
    assert not (tmp_path / "submissions").exists()
