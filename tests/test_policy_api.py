"""``comat.load_policy``: the README's example as written, the shipped policies, bad inputs."""

import re
from pathlib import Path

import numpy as np
import pytest

import comat
from comat.rl import PRETRAINED, pretrained_path

README = Path(__file__).resolve().parents[1] / "README.md"


def test_the_readme_example_runs_as_written(capsys):
    text = README.read_text()
    block = text[text.index("<!-- python-api:start") : text.index("<!-- python-api:end -->")]
    (code,) = re.findall(r"```python\n(.*?)```", block, flags=re.DOTALL)
    scope: dict = {}
    exec(compile(code, "README python-api", "exec"), scope)  # noqa: S102 -- the README example, as written
    steps = scope["infos"]["robot_0"]["episode/steps"]
    assert scope["env"].agents == [] and 0 < steps < 80  # the shipped policy finished it
    assert scope["actions"].shape == scope["info"]["agent_mask"].shape
    assert "Policy(comat on pcp, any team size, deterministic" in capsys.readouterr().out


@pytest.mark.parametrize("name", sorted(PRETRAINED))
def test_every_shipped_policy_is_the_kept_one_and_loads(name):
    path = pretrained_path("pretrained:" + name)
    kept = Path(__file__).resolve().parents[1] / "results" / "policies" / path.stem / "policy.pt"
    assert path.read_bytes() == kept.read_bytes()
    policy = comat.load_policy("pretrained:" + name)
    assert (policy.algo, policy.task) == tuple(name.split("-"))


def test_the_dict_form_equals_the_batch_form_and_sampling_follows_its_seed():
    env = comat.make_env("hmt_v0", coalitions="test", tier="unicycle")
    observations, _ = env.reset(seed=3)
    policy = comat.load_policy("pretrained:comat-hmt")
    agents = sorted(observations, key=lambda a: int(a.split("_")[1]))
    batch = policy.act(np.stack([observations[a] for a in agents])[None])[0]
    assert policy(observations) == {a: int(x) for a, x in zip(agents, batch)}
    draws = [comat.load_policy("pretrained:comat-hmt", deterministic=False, seed=s) for s in (5, 5, 6)]
    obs = np.repeat(np.stack([observations[a] for a in agents])[None], 64, 0)
    acts = [d.act(obs) for d in draws]
    assert (acts[0] == acts[1]).all() and (acts[0] != acts[2]).any()


def test_a_baseline_pads_to_its_slots_and_refuses_larger_teams():
    policy = comat.load_policy("pretrained:mat-pcp")
    assert policy.slots == 20 and policy.act(np.zeros((3, 4, 13))).shape == (3, 4)
    with pytest.raises(ValueError, match="at most 20 robots"):
        policy.act(np.zeros((1, 21, 13)))


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda: comat.load_policy("pretrained:nope"), "path_or_name must be one of ['pretrained:comat-pcp'"),
        (lambda: comat.load_policy("no/such/file.pt"), "got 'no/such/file.pt' (no such file)"),
        (lambda: comat.load_policy("pretrained:comat-pcp", task="hmt"), "hmt"),
        (lambda: comat.load_policy("pretrained:comat-pcp")(np.zeros(3)), "observations must be a non-empty dict"),
        (lambda: comat.load_policy("pretrained:comat-pcp")({"a": np.zeros(13)}), "robot_<i>, got 'a'"),
        (lambda: comat.load_policy("pretrained:comat-pcp").act(np.zeros((1, 3, 15))), "obs must be (B, N, 13)"),
        (lambda: comat.load_policy("pretrained:mat-pcp", deterministic="yes"), "deterministic must be True or False"),
    ],
)
def test_bad_inputs_name_what_was_expected(call, message):
    with pytest.raises((ValueError, TypeError), match=re.escape(message)):
        call()


def test_pretrained_names_work_from_the_command_line(tmp_path, capsys):
    from comat.cli import main

    assert main(["policy", "pretrained:mat-hmt"]) == 0
    assert "mat" in capsys.readouterr().out
    out = tmp_path / "one.rrd"
    assert main(["rollout", "--policy", "pretrained:comat-hmt", "--team", "test:1", "--out", str(out)]) == 0
    assert out.is_file()
    assert main(["eval", "--policy", "pretrained:nope", "--teams", "test", "--out", str(tmp_path)]) == 2
    assert "--policy must be one of ['pretrained:comat-pcp'" in capsys.readouterr().err
