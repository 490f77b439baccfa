"""The coordination metric (comat.task_logic.TaskLogic.coordination): PCP's, HMT's and forage's hooks
on hand-made states, an episode's value as the mean over its steps (vector env rows, PettingZoo
infos), a task without one (nothing written, no fake 0), a broken hook refused, and eval's footer
naming the task at hand."""

import re

import numpy as np
import pytest

import comat
from comat.envs.core import COORDINATION, TaskCore
from comat.envs.heuristics import heuristic_actions
from comat.eval.evaluate import print_table, table_lines, task_legend
from comat.measure.episodes import run_episodes
from comat.measure.metrics import REPORTED, summarize_ci
from comat.tasks import TASKS, env_id
from comat.tasks.forage import LevelForaging
from comat.tasks.hmt import HMT
from comat.tasks.pcp import PCP
from comat.team import generate_coalitions


# -- the hooks on hand-made states -------------------------------------------------------------------
def test_pcp_counts_sensed_prey_waiting_for_capture():
    task = PCP()
    state = task.new_state(3, 4)  # 6 prey slots
    state["active"][:] = [True] * 4 + [False] * 2  # a team with 4 prey; inactive slots sensed and captured
    state["sensed"][:] = ~state["active"]
    state["captured"][:] = ~state["active"]
    state["sensed"][1, :3] = True  # env 1: three sensed, one of them captured -> 2 of 4 waiting
    state["captured"][1, 0] = True
    state["sensed"][2, :4] = state["captured"][2, :4] = True  # env 2: everything captured
    poses, mask = np.zeros((3, 4, 3)), np.ones((3, 4), bool)
    caps, type_ids = np.zeros((3, 4, 2)), np.zeros((3, 4), np.int64)
    np.testing.assert_array_equal(task.coordination(state, poses, type_ids, caps, mask), [0.0, 0.5, 0.0])
    assert task.coordination_name and task.coordination_doc


def test_hmt_counts_the_usable_payload_riding_empty():
    task = HMT()
    state = task.new_state(4, 3)
    caps = np.zeros((4, 3, 2))
    caps[..., 1] = [10.0, 20.0, 0.0]  # two robots (payload 30); slot 2 is padding
    mask = np.array([[True, True, False]] * 4)
    state["left"][:] = [[40.0, 0.0], [40.0, 0.0], [5.0, 0.0], [0.0, 0.0]]
    state["load"][1] = [10.0, 0.0, 0.0]  # env 1: the 10-unit robot loaded, the 20-unit one empty
    state["load"][2] = [0.0, 20.0, 0.0]  # env 2: 5 left + 20 carried < 30 payload: 25 usable
    state["load"][3] = [10.0, 0.0, 0.0]  # env 3: nothing left to load: nobody idles
    got = task.coordination(state, np.zeros((4, 3, 3)), np.zeros((4, 3), np.int64), caps, mask)
    np.testing.assert_allclose(got, [1.0, 20 / 30, 5 / 25, 0.0])


def test_forage_counts_robots_waiting_at_items_too_heavy_for_them():
    task = LevelForaging()
    state = task.new_state(2, 4)  # 3 item slots
    state["items"][:, :3] = [[0.0, 0.0], [1.0, 0.0], [0.0, 0.6]]
    state["level"][:, :3] = [3.0, 1.0, 2.0]
    state["active"][:, :3] = True
    state["collected"][:] = [[False, True, False], [False, False, False]]
    poses = np.zeros((2, 4, 3))
    poses[:, :, :2] = [[0.1, 0.0], [1.0, 0.1], [0.0, 0.5], [-1.0, 0.0]]  # at item 0, 1, 2, none
    caps = np.ones((2, 4, 2))
    mask = np.array([[True] * 4, [True, True, True, False]])
    got = task.coordination(state, poses, np.zeros((2, 4), np.int64), caps, mask)
    # env 0: robots at open items 0 and 2 wait (item 1 is collected); env 1: three of its three robots
    np.testing.assert_allclose(got, [2 / 4, 3 / 3])
    state["collected"][1, 1] = False
    task.update(state, poses, np.zeros((2, 4), np.int64), caps, mask)  # item 1 (level 1) lifted at once
    np.testing.assert_allclose(task.coordination(state, poses, np.zeros((2, 4), np.int64), caps, mask), [0.5, 2 / 3])


# -- an episode's value: the mean over its steps -----------------------------------------------------
@pytest.mark.parametrize("task", ["pcp", "hmt", "forage"])
def test_an_episode_carries_the_mean_over_its_steps(task):
    teams = generate_coalitions(task, "train", 2, seed=1)
    env = comat.make_vec_env(env_id(task), 2, seed=5, tier="unicycle", ticks_per_step=8, coalitions=teams)
    env.reset(seed=5, teams=teams)
    core, seen, rows = env.core, [[], []], {}
    while len(rows) < 2:
        _, _, term, trunc, info = env.step(heuristic_actions(core))
        for b in range(2):
            if b not in rows:  # the value after this step (a reset leaves the last one in place)
                seen[b].append(core.coordination_now[b])
        for b in np.flatnonzero(term | trunc):
            rows.setdefault(int(b), info["episode"])
    for b, metrics in rows.items():
        assert len(seen[b]) == int(metrics["steps"][b])
        assert metrics[COORDINATION][b] == pytest.approx(np.mean(seen[b]), abs=1e-12)
    # one episode stepped by hand on the PettingZoo env: the value after every step, their mean at the end
    penv = comat.make_env(env_id(task), team=teams[0], tier="unicycle", ticks_per_step=8)
    penv.reset(seed=3)
    values, info = [], {}
    while penv.agents:
        act = heuristic_actions(penv.core)[0]
        _, _, _, _, infos = penv.step({a: int(act[i]) for i, a in enumerate(penv.agents)})
        values.append(float(penv.core.coordination_now[0]))
        info = infos["robot_0"]
    assert info[f"episode/{COORDINATION}"] == pytest.approx(np.mean(values), abs=1e-12)
    assert len(set(values)) > 1  # it moves during an episode


def test_run_episodes_rows_carry_it_and_a_task_without_one_writes_nothing(monkeypatch):
    teams = generate_coalitions("pcp", "train", 2, seed=1)
    env = comat.make_vec_env("pcp_v0", 2, seed=5, tier="unicycle", ticks_per_step=8, coalitions=teams)
    act = lambda obs, mask, state: np.where(mask, 1, 0)
    rows = run_episodes(env, act, teams, seed=5)
    assert all(0.0 <= r[COORDINATION] <= 1.0 for r in rows)
    assert summarize_ci(rows)[COORDINATION]["n"] == 2
    # a task whose hook returns None: the rows and the infos leave the metric out (no fake 0)
    monkeypatch.setattr(PCP, "coordination", lambda self, *args: None)
    env = comat.make_vec_env("pcp_v0", 2, seed=5, tier="unicycle", ticks_per_step=8, coalitions=teams)
    rows_none = run_episodes(env, act, teams, seed=5)
    assert all(COORDINATION not in r for r in rows_none)
    assert [r["return"] for r in rows_none] == [r["return"] for r in rows]  # nothing else changes
    assert COORDINATION not in summarize_ci(rows_none)
    lines = table_lines(
        {"rows": [{"policy": "constant", "set": "x", "episodes": 2, "metrics": summarize_ci(rows_none)}]}
    )
    head = re.split(r" {2,}", lines[0])
    assert re.split(r" {2,}", lines[2])[head.index("coord.")] == "n/a"
    penv = comat.make_env("pcp_v0", team=teams[0], tier="unicycle", ticks_per_step=8)
    penv.reset(seed=3)
    info = {}
    while penv.agents:
        _, _, _, _, infos = penv.step({a: 1 for a in penv.agents})
        info = infos["robot_0"]
    assert "episode/steps" in info and f"episode/{COORDINATION}" not in info
    assert penv.core.coordination_now is None


def test_a_hook_returning_the_wrong_shape_or_nan_is_refused():
    class Broken(PCP):
        def coordination(self, state, poses, type_ids, caps, mask):
            return np.full(mask.shape[0] + 1, 0.5)

    class NotANumber(PCP):
        def coordination(self, state, poses, type_ids, caps, mask):
            return np.full(mask.shape[0], np.nan)

    team = generate_coalitions("pcp", "train", 1, seed=1)[0]
    for task, message in ((Broken(), r"Broken.coordination must return None or \(1,\) finite values .* shape \(2,\)"),
                          (NotANumber(), r"NotANumber.coordination .* got shape \(1,\): \[nan\]")):  # fmt: skip
        core = TaskCore(task, 1, team.size, ticks_per_step=4)
        core.reset([0], [team], [np.random.default_rng(0)])
        with pytest.raises(ValueError, match=message):
            core.step(np.zeros((1, team.size), np.int64))


# -- eval's footer: the task at hand ---------------------------------------------------------------
def test_footer_describes_the_task_at_hand():
    pcp, hmt = task_legend("pcp"), task_legend("hmt")
    assert pcp[0] == "progress (pcp) = fraction of the active prey captured"
    assert hmt[0] == "progress (hmt) = fraction of the material delivered"
    assert "every prey of the team captured" in pcp[1] and "all the material delivered" in hmt[1]
    assert pcp[2] == f"coord. = {PCP.coordination_name}: {PCP.coordination_doc}"
    assert "prey" not in " ".join(task_legend("forage"))
    # every registered task gets its own words; one not registered here gets general ones
    for name, entry in TASKS.items():
        legend = task_legend(name)
        assert len(legend) == 3 and all(len(line) < 400 for line in legend), name
        assert ("n/a" in legend[2]) == (not entry.logic.coordination_name), name
    assert task_legend("no_such_task") == [
        "progress (no_such_task) = the task's share of its work done",
        'finished = share of episodes done before the horizon (the paper\'s "completion")',
        "coord. = n/a (no_such_task has no coordination metric)",
    ]
    # the footer is a few short lines, whatever the task
    metrics = {m: {"mean": 0.5, "ci95": 0.1, "n": 2} for m in REPORTED}
    result = {"task": "hmt", "rows": [{"policy": "heuristic", "set": "train", "episodes": 2, "metrics": metrics}]}
    lines = []
    print_table({**result, "episodes_per_coalition": 1, "reality": "off", "seed": 7}, out=lines.append)
    footer = lines[lines.index("") + 1 :]  # the notes, after the tables and a blank line
    notes = "\n".join(footer).replace("\n  ", " ").splitlines()  # each note on one line again
    assert notes[:3] == hmt and len(footer) <= 16 and max(len(x) for x in footer) <= 120
    assert "prey" not in "\n".join(footer)


# -- the video's header ----------------------------------------------------------------------------
def test_frames_show_the_metric_at_the_header_right_after_the_first_step(monkeypatch):
    """The header's right end stays blank before the first step and for a task without the metric."""
    team = generate_coalitions("hmt", "train", 1, seed=1)[0]

    def corner_after_steps(steps: int) -> np.ndarray:
        env = comat.make_env("hmt_v0", team=team, tier="unicycle", ticks_per_step=8, render_mode="rgb_array")
        env.reset(seed=3)
        env.render_caption = "x"  # a short caption: the right end of its line is free
        for _ in range(steps):
            env.step({a: 1 for a in env.agents})
        corner = env.render()[:20, 440:]
        env.close()
        return corner

    blank = corner_after_steps(0)
    assert (blank == blank[0, 0]).all()
    assert (corner_after_steps(2) != blank[0, 0]).any()
    monkeypatch.setattr(HMT, "coordination", lambda self, *args: None)
    assert (corner_after_steps(2) == blank[0, 0]).all()
