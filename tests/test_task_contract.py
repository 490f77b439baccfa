"""A task is a contract (issue 64): required hooks refused at registration, comat.tasks.check_task on
every registered task and on broken ones (each message), a bad COMAT_TASKS in one line, a plug-in
task's run read without it, a task's bare name as its current env id, and every task's spec sheet on
the docs site."""

from __future__ import annotations

import importlib.util
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from test_write_a_task import page_task

import comat
from comat.envs.registry import env_class, make_local_vec_env
from comat.rl.checkpoint import FORMAT, FORMAT_VERSION, CheckpointError, _save, load_checkpoint
from comat.task_logic import REQUIRED_HOOKS, TaskLogic
from comat.tasks import (
    TASKS,
    check_task,
    entry_of,
    load_plugins,
    not_registered,
    task_entry,
    task_from_logic,
    task_names,
)
from comat.tasks.contract import TaskCheckError
from comat.tasks.pcp import PCP


@pytest.mark.parametrize("name", task_names())
def test_every_registered_task_keeps_the_contract(name):
    means = check_task(TASKS[name].logic)
    assert set(means) == {"heuristic", "type_only", "blind", "constant", "random"}
    assert all(0.0 <= v <= 1.0 for v in means.values())
    assert means["heuristic"] > means["random"], "the scripted planner must beat random actions"


# -- required hooks ----------------------------------------------------------------------------------
def _without(base: type, *hooks: str) -> type:
    """A subclass of ``base`` that has the base's placeholder for each of ``hooks``."""
    return type("Broken", (base,), {"name": "broken", "set_streams": 900, **{h: getattr(TaskLogic, h) for h in hooks}})


def test_the_required_hooks_are_abstract_and_listed():
    assert set(TaskLogic.__abstractmethods__) == {h for h in REQUIRED_HOOKS if " or " not in h}
    with pytest.raises(TypeError, match="abstract"):
        TaskLogic()
    for entry in TASKS.values():
        assert entry.logic.missing_hooks() == []


def test_a_class_lacking_a_hook_is_refused_at_registration_in_one_line():
    cls = _without(page_task(), "blind_scripted_actions", "progress")
    msg = r"^task 'broken': class Broken lacks the required hook\(s\) progress, blind_scripted_actions \(comat"
    with pytest.raises(ValueError, match=msg) as err:
        task_from_logic(cls, "Broken")
    assert "\n" not in str(err.value) and "broken" not in TASKS


def test_a_planner_is_either_scripted_hook():
    neither = _without(PCP, "scripted_targets", "scripted_actions")
    assert neither.missing_hooks() == ["scripted_actions or scripted_targets"]
    with pytest.raises(ValueError, match=r"lacks the required hook\(s\) scripted_actions or scripted_targets "):
        entry_of(neither, "Broken")
    assert _without(PCP, "scripted_actions").missing_hooks() == []  # PCP plans with scripted_targets
    assert _without(page_task(), "scripted_targets").missing_hooks() == []  # Gather overrides scripted_actions


def test_a_logic_that_is_not_a_task_logic_class_is_refused():
    class Loose:
        name = "loose"

    with pytest.raises(TypeError, match=r"task 'loose': its logic must be a class built on comat.task_logic.TaskLogic"):
        entry_of(Loose, "Loose")


# -- check_task on broken tasks: each says what it breaks ---------------------------------------------
def _broken(**body) -> type:
    """The page's Gather with ``body`` changed."""
    return type("Broken", (page_task(),), {"name": "broken", "set_streams": 900, **body})


def _features_one_short(self, state, poses, type_ids, caps, mask):
    return page_task().task_features(self, state, poses, type_ids, caps, mask)[..., :-1]


def _no_far(self, state, poses, type_ids, caps, mask):
    return {"near": page_task().update(self, state, poses, type_ids, caps, mask)["near"]}


def _nan_far(self, state, poses, type_ids, caps, mask):
    raw = page_task().update(self, state, poses, type_ids, caps, mask)
    return {**raw, "far": raw["far"] * np.nan}


def _unlaid_reset(self, state, b, rng, caps):  # draws what layout does not carry
    page_task().reset_env(self, state, b, rng, caps)
    state["steps"][b] = rng.integers(0, 10)


def _unseeded_blind(self, state, poses, type_ids, caps, mask):  # not the generators it is given
    return np.where(mask, np.random.default_rng().integers(0, 5, mask.shape), 0)


def _state_with_draw(self, B, N):
    return {**page_task().new_state(self, B, N), "draw": np.zeros(B, np.int64)}


def _reset_with_draw(self, state, b, rng, caps):  # a draw the plan reads and layout does not carry
    page_task().reset_env(self, state, b, rng, caps)
    state["draw"][b] = rng.integers(1, 5)


def _drawn_actions(self, state, poses, type_ids, caps, mask):
    return np.where(mask, state["draw"][:, None], 0)


def _padded_moves(self, state, poses, type_ids, caps, mask):
    return np.ones(mask.shape, np.int64)


def _float_actions(self, state, poses, type_ids, caps, mask):
    return page_task().scripted_actions(self, state, poses, type_ids, caps, mask).astype(float)


def _raises(self, state):
    raise KeyError("steps")


def _coordination_per_robot(self, state, poses, type_ids, caps, mask):
    return np.zeros(mask.shape)


@pytest.mark.parametrize(
    ("body", "message"),
    [
        (
            {"task_features": _features_one_short},
            r"observe must have shape \(4, 8, 13\), got \(4, 8, 12\) \(rung 'heuristic', step 0\)",
        ),
        ({"update": _no_far}, r"update must return every task reward term \['near', 'far'\]; missing 'far'"),
        ({"update": _nan_far}, r"update's term 'far' must be finite"),
        ({"progress": lambda self, state: page_task().progress(self, state) + 1.5}, r"progress must lie in \[0, 1\]"),
        ({"done": lambda self, state: page_task().done(self, state).astype(int)}, r"done must be bool, got int64"),
        (
            {"blind_scripted_actions": _unseeded_blind},
            r"not deterministic: rung 'blind' run twice from seed 0 differs at step 0",
        ),
        ({"reset_env": _unlaid_reset}, r"the export round trip gives another episode: env 0's observations differ"),
        ({"layout": lambda self, state, b: {"arrived": state["arrived"][b]}}, r"layout must be plain JSON .*ndarray"),
        ({"scripted_actions": _padded_moves}, r"actions of padded slots must be 0 \(stay\)"),
        (
            {"blind_scripted_actions": _float_actions},
            r"actions must be whole numbers \(an integer dtype\), got float64 \(rung 'blind'",
        ),
        ({"global_features": _raises}, r"global_features \(rung 'heuristic', step 0\) raised KeyError: 'steps'"),
        ({"coordination": _coordination_per_robot}, r"coordination must have shape \(4,\), got \(4, 8\)"),
        (
            {"reward_weights": {"near": 1.0, "far": 2.0, "time": -0.05}},
            r"reward_weights must give every reward term .* missing \['violation'\]",
        ),
        ({"capability_scale": np.array([0.2, 0.2])}, r"capability_scale must be 1 positive value\(s\)"),
        ({"horizon": 0}, r"horizon must be a positive integer, got 0"),
        ({"ticks_per_step": 0}, r"ticks_per_step must be a positive integer, got 0"),
        ({"best_constant_action": 9}, r"best_constant_action must be an action 0-4, got 9"),
        ({"speed_capability": 3}, r"speed_capability must be None or a capability index 0-0, got 3"),
        (
            {"reward_weights": {"near": np.nan, "far": 2.0, "time": -0.05, "violation": -5.0}},
            r"the reward \(the sum of the weighted terms\) must be finite",
        ),
        ({"new_state": lambda self, B, N: [B, N]}, r"new_state must return a dict of arrays, got list \(reset\)"),
        (
            {"spawn": lambda self, rng, n: np.zeros((n, 2))},
            (
                r"spawn must have shape \(2, 3\), got \(2, 2\) "
                r"\(rung 'heuristic', env 0 \(2 robots, set 'train'\), reset\)"
            ),
        ),
        ({"layout": lambda self, state, b: [1, 2]}, r"layout must return a dict, got list"),
        (
            {"marks": lambda self, state, b, caps, type_ids: None},
            r"marks must return comat.task_logic.Marks, got NoneType \(rung 'heuristic', step 0\)",
        ),
        (
            {"counters": lambda self, state, b, n: 1 / 0},
            (
                r"marks \(env 0: the drawing hooks areas, items, rings, bar, counters\) \(rung 'heuristic', step 0\) "
                r"raised ZeroDivisionError: division by zero"
            ),
        ),
        (
            {"global_features": lambda self, state: np.zeros((4, 2 + int(state["steps"][0] > 1)))},
            r"global_features' width G changed from 2 to 3 in a batch \(rung 'heuristic', step 2\)",
        ),
        ({"step_lengths": lambda self, caps: -caps[..., 0]}, r"step_lengths_at must be >= 0 m"),
        (
            {"global_features": lambda self, state: self.progress(state)},
            r"global_features must be finite with shape \(B, G\) = \(4, G\), got shape \(4,\)",
        ),
        (
            {"scripted_actions": lambda self, state, poses, t, c, mask: np.where(mask, 7, 0)},
            r"actions must be 0-4 \(stay, \+x, -x, \+y, -y\), got \[7\]",
        ),
        (
            {"scripted_actions": lambda self, state, poses, t, c, mask: np.zeros(mask.shape[0], np.int64)},
            r"actions must have shape \(B, N\) = \(4, 8\), got \(4,\)",
        ),
        (
            {"coordination": lambda self, state, *a: None if state["steps"][0] < 2 else np.zeros(4)},
            r"coordination must return None always or a \(B,\) array always",
        ),
        (
            {"new_state": _state_with_draw, "reset_env": _reset_with_draw, "scripted_actions": _drawn_actions},
            r"the export round trip gives another episode: env \d's scripted actions differ from those of a fresh task",
        ),
        (
            {"capability_bands": {"train": {}}},
            r"task 'broken': capability_bands must name the sets train, test, capability",
        ),
    ],
)
def test_check_task_names_what_a_task_breaks_in_one_line(body, message):
    with pytest.raises(TaskCheckError, match=r"^check_task\('Broken'\): " + message) as err:
        check_task(_broken(**body), steps=6)
    assert "\n" not in str(err.value)


def test_check_task_takes_an_instance_with_its_options():
    assert check_task(PCP(n_prey=3), steps=5)["heuristic"] >= 0.0


# -- plug-ins ----------------------------------------------------------------------------------------
def _comat(args, env_extra) -> subprocess.CompletedProcess:
    env = {**os.environ, **env_extra}
    return subprocess.run(
        [sys.executable, "-m", "comat.cli", *args],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )


@pytest.mark.parametrize("args", [["--help"], ["tasks"]])
def test_a_bad_comat_tasks_value_is_one_line_and_exit_2(args):
    proc = _comat(args, {"COMAT_TASKS": "nosuch:X"})
    assert proc.returncode == 2
    assert (
        proc.stderr
        == "comat: error: COMAT_TASKS entry 'nosuch:X': module 'nosuch' did not import (No module named 'nosuch')\n"
    )
    assert proc.stdout == ""


def test_a_bad_comat_tasks_value_does_not_break_importing_comat():
    code = (
        "import comat, comat.tasks as t; print(len(t.task_names())); print(t.plugin_error());"
        "comat.make_env('gather_v0')"
    )
    env = {**os.environ, "COMAT_TASKS": "nosuch:X,just_a_module"}
    proc = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120, check=False
    )
    lines = proc.stdout.splitlines()
    assert lines[0] == str(len(task_names()))
    assert lines[1] == (
        "COMAT_TASKS entry 'nosuch:X': module 'nosuch' did not import (No module named 'nosuch'); "
        "COMAT_TASKS entry 'just_a_module': expected module:Class"
    )
    assert "got 'gather_v0' (COMAT_TASKS entry 'nosuch:X'" in proc.stderr.splitlines()[-1]


def test_a_plugin_module_that_raises_or_lacks_the_class_is_named(tmp_path, monkeypatch):
    (tmp_path / "raising_task.py").write_text("raise RuntimeError('no numpy\\nhere')\n")
    (tmp_path / "empty_task.py").write_text("")
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(
        ValueError,
        match=r"^COMAT_TASKS entry 'raising_task:T': module 'raising_task' did not import "
        r"\(RuntimeError: no numpy here\)$",
    ):
        load_plugins("raising_task:T")
    with pytest.raises(ValueError, match=r"^COMAT_TASKS entry 'empty_task:T': module 'empty_task' has no 'T'$"):
        load_plugins("empty_task:T")


def test_a_plug_in_task_s_run_read_without_it_says_how_to_register_it(tmp_path):
    path = tmp_path / "checkpoint.pt"
    _save(
        path,
        {"format": FORMAT, "format_version": FORMAT_VERSION, "algo": "comat", "task": "gather", "env_id": "gather_v0"},
    )
    msg = (
        r"checkpoint '.*checkpoint.pt' was trained on gather_v0, but task 'gather' is not registered here "
        r"\(registered: pcp, .*\): register its task class with COMAT_TASKS=module:Class \(the module on PYTHONPATH\) "
        r"or a comat.tasks entry point"
    )
    with pytest.raises(CheckpointError, match=msg):
        load_checkpoint(path)
    assert not_registered("gather").startswith("task 'gather' is not registered here")
    with pytest.raises(ValueError, match=r"task must be one of \['pcp', .*\], got 'gather'$"):
        task_entry("gather")


# -- env ids -----------------------------------------------------------------------------------------
def test_a_task_s_bare_name_is_its_current_env_id():
    for name, entry in TASKS.items():
        assert env_class(name) is env_class(entry.env_id)
    env = comat.make_env("navigation")
    assert env.metadata["name"] == TASKS["navigation"].env_id
    vec = make_local_vec_env("pcp", 2, seed=0)
    assert vec.task.name == "pcp"
    with pytest.raises(ValueError, match=r"env_id must be one of \(.*\), got 'nosuch'$"):
        comat.make_env("nosuch")


# -- the docs site -----------------------------------------------------------------------------------
def test_the_tasks_page_shows_every_registered_task_s_spec_sheet():
    root = Path(__file__).resolve().parents[1]
    spec = importlib.util.spec_from_file_location("spec_sheets", root / "docs" / "_hooks" / "spec_sheets.py")
    hook = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(hook)
    page = (root / "docs" / "tasks.md").read_text()
    assert hook.MARKER in page and "docs/_hooks/spec_sheets.py" in (root / "mkdocs.yml").read_text()
    shown = re.findall(r"^::: (\S+)$", hook.on_page_markdown(page), flags=re.MULTILINE)
    assert shown == [TASKS[name].logic.__module__ for name in task_names()]
    assert hook.on_page_markdown("no marker") == "no marker"
