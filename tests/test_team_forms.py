"""The Python API takes teams the way the CLI does (issue 49): a mapping, a plain list of robots, a
team file; a one-team file is a set of one; bad forms get one clear error. And ``comat tasks``
lists every task with its types and capabilities."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

import comat
from comat.cli import main
from comat.tasks import env_id
from comat.team import TASK_TYPES

ROBOTS = [
    {"type": "sensing", "capabilities": [0.5, 0.0]},
    {"type": "capture", "capabilities": [0.0, 0.4]},
    {"type": "capture", "capabilities": [0.0, 0.35]},
]


def _first_obs(**options):
    env = comat.make_env("pcp_v0", **options)
    obs, _ = env.reset(seed=0)
    return env.agents, np.stack([obs[a] for a in env.agents])


@pytest.mark.parametrize("form", ["mapping", "list", "yaml", "json"])
def test_make_env_takes_a_team_as_a_mapping_a_list_of_robots_or_a_file(form, tmp_path):
    path = tmp_path / ("team.json" if form == "json" else "team.yaml")
    path.write_text(yaml.safe_dump({"robots": ROBOTS}, default_flow_style=form == "json"))
    team = {"mapping": {"robots": ROBOTS}, "list": ROBOTS, "yaml": str(path), "json": path}[form]
    agents, obs = _first_obs(team=team)
    reference_agents, reference = _first_obs(team={"robots": ROBOTS})
    assert agents == reference_agents and len(agents) == 3
    np.testing.assert_array_equal(obs, reference)  # the same team, whatever the form


def test_a_one_team_file_is_a_set_of_one(tmp_path):
    path = tmp_path / "one.yaml"
    path.write_text(yaml.safe_dump({"robots": ROBOTS}))
    agents, obs = _first_obs(coalitions=str(path))
    assert len(agents) == 3 and np.array_equal(obs, _first_obs(team=ROBOTS)[1])


@pytest.mark.parametrize(
    ("team", "error", "words"),
    [
        (["sensing", "capture"], TypeError, "a list of robots"),
        ("no_such_team.yaml", ValueError, "no such file"),
        ([{"type": "flyer", "capabilities": [0.5, 0.0]}], ValueError, "flyer"),
        ([{"type": "sensing", "capabilities": [5.0, 0.0]}], ValueError, "sensing_radius_m"),
    ],
)
def test_bad_teams_get_one_clear_error(team, error, words):
    with pytest.raises(error) as info:
        comat.make_env("pcp_v0", team=team)
    assert words in str(info.value) and "\n" not in str(info.value)


def test_comat_tasks_lists_every_task_with_its_types_and_capabilities(capsys):
    assert main(["tasks"]) == 0
    out = capsys.readouterr().out
    for task, kinds in TASK_TYPES.items():
        assert f"{task} ({env_id(task)})" in out
        assert all(f"'{t}'" in out for t in kinds.types) and all(c in out for c in kinds.capabilities)


def test_every_registered_task_has_its_env_logic_and_types():
    from comat.envs.registry import _env_class, env_ids
    from comat.tasks import TASKS, task_entry

    assert sorted(env_ids()) == sorted(e.env_id for e in TASKS.values())
    for entry in TASKS.values():
        assert _env_class(entry.env_id).task_cls is entry.logic and entry.types is TASK_TYPES[entry.name]
    with pytest.raises(ValueError, match="task must be one of"):
        task_entry("soccer")
