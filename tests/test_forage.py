"""Level-Based Foraging (issue 49): the lifting rule, items every team can lift, the scripted
reference and its capability-blind twin, the drawing and the export layout."""

import numpy as np
import pytest
from reference_runs import headroom

from comat.envs import make_env, make_vec_env
from comat.tasks.forage import LevelForaging


def _state(items, levels):
    task = LevelForaging()
    state = task.new_state(1, 3)
    k = len(items)
    state["items"][0, :k], state["level"][0, :k] = items, levels
    state["active"][0] = np.arange(state["items"].shape[1]) < k
    state["collected"][0] = ~state["active"][0]
    return task, state


def test_an_item_is_lifted_exactly_when_the_levels_within_reach_add_up():
    task, state = _state([[0.0, 0.0], [1.0, 0.5]], [3.0, 1.0])
    caps = np.array([[[1.0, 0.1], [1.9, 0.1], [2.5, 0.1]]])
    mask, types = np.ones((1, 3), bool), np.array([[1, 0, 0]])
    r = task.reach_m
    # 1.0 + 1.9 = 2.9 < 3.0 within reach of item 0; the 2.5 robot just outside it
    poses = np.array([[[0.1, 0.0, 0.0], [-0.2, 0.0, 0.0], [r + 0.01, 0.0, 0.0]]])
    raw = task.update(state, poses, types, caps, mask)
    assert not state["collected"][0, :2].any() and raw["collected"][0] == 0.0
    poses[0, 2, 0] = r - 0.01  # now 5.4 >= 3.0
    raw = task.update(state, poses, types, caps, mask)
    assert state["collected"][0].tolist()[:2] == [True, False] and raw["collected"][0] == pytest.approx(3.0)
    assert task.progress(state)[0] == pytest.approx(0.75) and not task.done(state)[0]
    raw = task.update(state, poses, types, caps, mask)  # collected for good, rewarded once
    assert raw["collected"][0] == 0.0


@pytest.mark.parametrize("split", ["train", "capability", "scale"])
def test_every_item_can_be_lifted_by_robots_of_its_team(split):
    env = make_vec_env("forage_v0", 8, coalitions=split, tier="unicycle", seed=3)
    env.reset()
    core = env.core
    for b in range(8):
        n = core.teams[b].size
        on = core.state["active"][b]
        assert on.sum() == LevelForaging.items_for(n)
        levels, team = core.state["level"][b][on], np.sort(core.caps[b, :n, 0])[::-1]
        assert (levels > 0).all() and (levels <= team[:3].sum() + 1e-9).all()


def test_the_blind_reference_sends_too_few_robots_where_they_are_weaker_than_it_believes():
    """One item of level 3: two light robots near it, a heavy one farther. The scripted policy sends
    all three; the blind one sends the two nearest (2 × 1.85 >= 3) and they wait for good."""
    task, state = _state([[0.5, 0.0]], [3.0])
    centres = np.array([[[0.3, 0.0], [0.3, 0.3], [-1.0, 0.0]]])
    caps = np.array([[[0.8, 0.15], [0.8, 0.15], [2.6, 0.1]]])
    mask = np.ones((1, 3), bool)
    _, aware = task._groups(state, centres, caps[..., 0], mask)
    _, blind = task._groups(state, centres, np.full((1, 3), task.blind_level), mask)
    assert aware.tolist() == [[True, True, True]] and blind.tolist() == [[True, True, False]]


def test_composition_matters_the_blind_reference_finishes_fewer_episodes():
    """One episode per U_cap coalition: the scripted policy lifts everything; the blind one leaves items."""
    out = headroom("forage", "capability")
    assert out["heuristic"] >= 0.95 and out["blind"] <= out["heuristic"] - 0.05, out


def test_layout_round_trips_and_the_task_draws_itself():
    env = make_env("forage_v0", tier="unicycle", render_mode="rgb_array")
    env.reset(seed=4)
    core = env.core
    layout = core.task.layout(core.state, 0)
    fresh = core.task.new_state(1, core.N)
    core.task.set_layout(fresh, 0, layout)
    for key in ("items", "level", "active", "collected"):
        np.testing.assert_array_equal(fresh[key], core.state[key])
    n = env.team.size
    marks = core.task.marks(core.state, 0, core.caps[0, :n], core.type_ids[0, :n])
    assert marks.items.xy.shape == (len(layout["items"]), 2) and len(marks.items.labels) == len(layout["items"])
    assert marks.bar.width_m.shape == (n,) and "items 0/" in marks.status
    assert env.render().shape == (448, 640, 3)
