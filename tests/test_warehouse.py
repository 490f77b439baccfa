"""Warehouse (issue 64): lifting decided by the continuous load, deliveries, what the team learns of
its robots' loads, items every team can fetch, the planner's beliefs (scripted, type_only, blind),
the coordination metric, the observation layout against the spec sheet, the export layout."""

import re

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test

import comat.tasks.warehouse as warehouse_module
from comat.envs import make_env, make_vec_env
from comat.envs.heuristics import blind_actions, heuristic_actions, type_mean_capabilities, type_only_actions
from comat.tasks import task_entry
from comat.tasks.warehouse import CARRIED, DELIVERED, SHELF, UNKNOWN_LIMIT, Warehouse
from comat.team import generate_coalitions

STILL = np.zeros((1, 1, 3))


def _state(items, weights, n):
    task = Warehouse()
    state = task.new_state(1, n)
    task.set_layout(state, 0, {"items": items, "weight": weights})
    return task, state


def _poses(xy):
    xy = np.asarray(xy, dtype=float)
    return np.concatenate([xy[None], np.zeros((1, len(xy), 1))], -1)


def test_a_robot_lifts_an_item_when_it_stops_at_its_shelf_strong_enough_and_delivers_it_in_the_zone():
    task, state = _state([[0.2, 0.0]], [1.5], 2)
    caps = np.array([[[1.6, 0.1], [1.0, 0.15]]])
    mask, types = np.ones((1, 2), bool), np.array([[0, 1]])
    at = _poses([[0.25, 0.05], [-1.3, 0.5]])
    task.set_starts(state, 0, _poses([[0.0, 0.05], [-1.3, 0.5]])[0])  # robot 0 drove 0.25 m: passing
    assert task.update(state, at, types, caps, mask)["lifted"][0] == 0 and state["status"][0, 0] == SHELF
    raw = task.update(state, at, types, caps, mask)  # stopped within 0.14 m, load 1.6 >= 1.5: lifts
    assert raw["lifted"][0] == 1 and state["status"][0, 0] == CARRIED and state["carrying"][0].tolist() == [0, -1]
    assert state["lifted"][0, 0] == 1.5 and task.progress(state)[0] == 0.0
    away = _poses([[-0.5, 0.1], [-1.3, 0.5]])
    assert task.update(state, away, types, caps, mask)["delivered"][0] == 0
    np.testing.assert_allclose(state["items"][0, 0], [-0.5, 0.1])  # the item rides with its carrier
    home = _poses([[-1.05, 0.1], [-1.3, 0.5]])
    raw = task.update(state, home, types, caps, mask)
    assert raw["delivered"][0] == 1 and state["status"][0, 0] == DELIVERED and state["carrying"][0, 0] == -1
    assert task.progress(state)[0] == 1.0 and task.done(state)[0]
    assert task.update(state, home, types, caps, mask)["delivered"][0] == 0  # rewarded once


def test_a_failed_lift_is_remembered_and_a_robot_never_tries_as_heavy_an_item_again():
    """The picker (type of the light robots) is the strong one here: the continuous load decides."""
    task, state = _state([[0.2, 0.0], [0.8, 0.3]], [1.9, 2.2], 2)
    caps = np.array([[[1.5, 0.08], [2.0, 0.15]]])  # a weak forklift, a strong picker
    mask, types = np.ones((1, 2), bool), np.array([[0, 1]])
    here = _poses([[0.2, 0.05], [0.8, 0.25]])
    task.set_starts(state, 0, here[0])
    raw = task.update(state, here, types, caps, mask)
    assert raw["lifted"][0] == 0 and state["failed"][0].tolist() == [1.9, 2.2]
    assert state["attempts"][0] == 2 and state["failures"][0] == 2
    assert task.coordination(state, here, types, caps, mask)[0] == 1.0
    task.update(state, here, types, caps, mask)  # standing there: no new tries
    assert state["attempts"][0] == 2
    swap = _poses([[0.8, 0.25], [0.2, 0.05]])  # the picker lifts 1.9; the forklift does not try 2.2 >= 1.9
    task.set_starts(state, 0, swap[0])
    raw = task.update(state, swap, types, caps, mask)
    assert raw["lifted"][0] == 1 and state["carrying"][0].tolist() == [-1, 0] and state["attempts"][0] == 3
    assert task.coordination(state, swap, types, caps, mask)[0] == pytest.approx(2 / 3)
    assert task.end_counts(state)["failed_lifts"][0] == 2 and task.end_counts(state)["items_left"][0] == 2


def test_two_robots_at_one_item_only_the_first_able_one_lifts_it():
    task, state = _state([[0.2, 0.0]], [1.0], 3)
    caps = np.array([[[0.5, 0.1], [1.2, 0.1], [1.4, 0.1]]])
    here = _poses([[0.3, 0.0], [0.2, 0.1], [0.2, -0.1]])
    task.set_starts(state, 0, here[0])
    raw = task.update(state, here, np.array([[1, 1, 0]]), caps, np.ones((1, 3), bool))
    assert raw["lifted"][0] == 1 and state["carrying"][0].tolist() == [-1, 0, -1]
    assert state["failures"][0] == 1 and state["attempts"][0] == 2  # robot 2 found nothing left to try


@pytest.mark.parametrize("split", ["train", "capability", "scale"])
def test_every_robot_is_the_source_of_an_item_it_lifts_and_items_sit_on_distinct_shelves(split):
    env = make_vec_env("warehouse_v0", 6, coalitions=split, tier="unicycle", seed=3)
    env.reset()
    core = env.core
    slots = {tuple(p) for p in np.round(Warehouse().shelf_slots(), 6)}
    for b in range(6):
        n = core.teams[b].size
        on = core.state["active"][b]
        weights, loads = core.state["weight"][b][on], core.caps[b, :n, 0]
        assert on.sum() == Warehouse.items_for(n) and (weights > 0).all()
        assert (weights <= loads.max()).all()  # someone lifts every item...
        assert all((weights <= load).any() for load in loads)  # ...and every robot some item
        xy = {tuple(p) for p in np.round(core.state["items"][b][on], 6)}
        assert len(xy) == on.sum() and xy <= slots


def test_the_planner_reads_capabilities_only_through_caps():
    """One item of weight 1.9 and a weak forklift beside a strong picker. With the true loads the
    picker goes; believing type means (forklift 2.2, picker 1.1) the forklift goes; once the forklift
    has failed, the picker — believed too weak, but the strongest not known to fail — tries it."""
    task, state = _state([[0.2, 0.0]], [1.9], 2)
    centres = np.array([[[-0.5, 0.0], [-1.0, 0.0]]])
    mask = np.ones((1, 2), bool)
    true_caps = np.array([[[1.5, 0.08], [2.0, 0.15]]])
    means = type_mean_capabilities("warehouse", "train")[np.array([[0, 1]])]
    target, _ = task._plan(state, centres, true_caps[..., 0], true_caps[..., 1], mask)
    believed, _ = task._plan(state, centres, means[..., 0], means[..., 1], mask)
    assert target[0, 1].tolist() == [0.2, 0.0] and target[0, 0, 0] == task.park_x
    assert believed[0, 0].tolist() == [0.2, 0.0] and believed[0, 1, 0] == task.park_x
    state["failed"][0, 0] = 1.9
    adapted, _ = task._plan(state, centres, means[..., 0], means[..., 1], mask)
    assert adapted[0, 1].tolist() == [0.2, 0.0] and adapted[0, 0, 0] == task.park_x
    poses = np.concatenate([centres, np.zeros((1, 2, 1))], -1)
    state["failed"][0, 0] = UNKNOWN_LIMIT
    acts = task.scripted_actions(state, poses, np.array([[0, 1]]), true_caps, mask)
    assert acts[0].tolist() == [2, 1]  # forklift to the zone (parks), picker toward the item (+x)


def test_the_blind_plan_sends_the_nearest_robot_until_the_team_sees_it_fail():
    task, state = _state([[0.2, 0.0]], [1.9], 2)
    poses = _poses([[-0.5, 0.0], [-1.0, 0.0]])
    caps, mask = np.array([[[1.5, 0.08], [2.0, 0.15]]]), np.ones((1, 2), bool)
    assert task.blind_scripted_actions(state, poses, np.array([[0, 1]]), caps, mask)[0].tolist() == [1, 2]
    state["failed"][0, 0] = 1.9
    assert task.blind_scripted_actions(state, poses, np.array([[0, 1]]), caps, mask)[0].tolist() == [2, 1]


def test_a_carrier_heads_for_the_zone_and_a_robot_with_nothing_to_do_parks():
    task, state = _state([[0.2, 0.0], [0.5, 0.3]], [1.0, 1.0], 2)
    state["status"][0, 0], state["carrying"][0, 0] = CARRIED, 0
    state["status"][0, 1] = DELIVERED
    target, ok = task._plan(
        state, np.array([[[0.2, 0.0], [0.4, 0.5]]]), np.ones((1, 2)), np.ones((1, 2)), np.ones((1, 2), bool)
    )
    assert target[0].tolist() == [[task.delivery_x - task.drop_depth_m, 0.0], [task.park_x, 0.5]] and ok.all()


def _spec_rows():
    """(first, last, text) of each row of the spec sheet's observation table."""
    rows = re.findall(r"^\| (\d+)(?:–(\d+))? \| (.+) \|$", warehouse_module.__doc__, re.MULTILINE)
    return [(int(a), int(b or a), text) for a, b, text in rows]


def test_the_observation_is_laid_out_as_the_spec_sheet_says():
    rows = _spec_rows()
    task = Warehouse()
    assert [a for a, _, _ in rows] == [0] + [b + 1 for _, b, _ in rows[:-1]]  # contiguous from 0
    assert rows[-1][1] + 1 == task.obs_size() == 18
    assert f"Box({task.obs_size()},)" in warehouse_module.__doc__

    def at(start):  # the indices of the one row whose text starts so
        (found,) = [(a, b) for a, b, text in rows if text.startswith(start)]
        return found

    task, state = _state([[0.5, 0.15], [-0.1, -0.45], [1.1, 0.75]], [1.2, 2.6, 0.8], 2)
    state["steps"][0] = 15
    state["status"][0, 2], state["carrying"][0, 1] = CARRIED, 2
    poses = np.array([[[0.2, 0.0, 0.0], [1.0, 0.7, np.pi / 2]]])
    caps = np.array([[[2.4, 0.08], [1.0, 0.16]]])
    obs = task.observe(state, poses, np.array([[0, 1]]), caps, np.ones((1, 2), bool))[0]
    np.testing.assert_allclose(obs[0, :4], [0.2, 0.0, 1.0, 0.0])
    np.testing.assert_allclose(obs[:, 4:6], [[1, 0], [0, 1]])
    np.testing.assert_allclose(obs[0, 6:8], [0.6, 0.4])
    a, b = at("offset (m) to the nearest item on a shelf")
    np.testing.assert_allclose(obs[0, a : b + 1], [0.3, 0.15])  # item 0; item 2 is carried
    np.testing.assert_allclose(obs[0, at("that item's weight")[0]], 0.3)
    a, b = at("offset (m) to the second nearest item on a shelf")
    np.testing.assert_allclose(obs[0, a : b + 1], [-0.3, -0.45])
    np.testing.assert_allclose(obs[0, at("the second item's weight")[0]], 2.6 / 4)
    assert obs[:, at("1 if the robot carries an item")[0]].tolist() == [0.0, 1.0]
    np.testing.assert_allclose(obs[:, at("x-offset")[0]], [-1.2, -2.0])
    assert obs[0, at("team's fraction of the items delivered")[0]] == 0.0
    np.testing.assert_allclose(obs[0, at("steps left / horizon")[0]], 1 - 15 / task.horizon)
    assert task_entry("warehouse").types.types == ("forklift", "picker")


def test_the_coordination_hook_is_zero_before_any_try_and_documented():
    task, state = _state([[0.2, 0.0]], [1.0], 1)
    assert (
        task.coordination(state, STILL, np.zeros((1, 1), np.int64), np.ones((1, 1, 2)), np.ones((1, 1), bool))[0] == 0
    )
    assert task.coordination_name and "lower is better" in task.coordination_doc


def _progress(split, act, teams, seed=5):
    env = make_vec_env("warehouse_v0", len(teams), coalitions=split, tier="unicycle", seed=seed)
    env.reset(teams=teams)
    progress, seen = np.zeros(len(teams)), np.zeros(len(teams), bool)
    while not seen.all():
        info = env.step(act(env.core))[-1]
        if "episode" in info:
            new = info["_episode"] & ~seen
            progress[new], seen = info["episode"]["progress"][new], seen | info["_episode"]
    return progress


def test_the_ladder_scripted_above_type_only_on_unseen_capabilities_and_above_blind_on_large_teams():
    """Six U_cap teams and the six largest U_size teams (stored sets), one episode each."""
    cap = generate_coalitions("warehouse", "capability")[:6]
    means = type_mean_capabilities("warehouse", "capability")
    scripted = _progress("capability", heuristic_actions, cap)
    type_only = _progress("capability", lambda core: type_only_actions(core, means), cap)
    assert scripted.mean() >= 0.9 and type_only.mean() <= scripted.mean() - 0.1, (scripted, type_only)
    large = generate_coalitions("warehouse", "size")[-6:]
    scripted, blind = _progress("size", heuristic_actions, large), _progress("size", blind_actions, large)
    assert scripted.mean() >= 0.85 and blind.mean() <= scripted.mean() - 0.05, (scripted, blind)


def test_a_scripted_episode_is_deterministic():
    teams = generate_coalitions("warehouse", "test")[:3]
    out = []
    for _ in range(2):
        env = make_vec_env("warehouse_v0", 3, coalitions="test", tier="unicycle", seed=11)
        env.reset(teams=teams)
        for _ in range(25):
            env.step(heuristic_actions(env.core))
        out.append({k: v.copy() for k, v in env.core.state.items()})
    for key in out[0]:
        np.testing.assert_array_equal(out[0][key], out[1][key])


def test_parallel_api_on_an_unseen_capability_team():
    team = generate_coalitions("warehouse", "capability")[0]
    parallel_api_test(make_env("warehouse_v0", team=team, tier="unicycle", ticks_per_step=6), num_cycles=90)


def test_layout_round_trips_and_the_task_draws_itself():
    env = make_env("warehouse_v0", tier="unicycle", render_mode="rgb_array")
    env.reset(seed=4)
    core = env.core
    layout = core.task.layout(core.state, 0)
    fresh = core.task.new_state(1, core.N)
    core.task.set_layout(fresh, 0, layout)
    for key in ("items", "weight", "status", "active", "carrying", "failed", "lifted"):
        np.testing.assert_array_equal(fresh[key], core.state[key])
    n = env.team.size
    marks = core.task.marks(core.state, 0, core.caps[0, :n], core.type_ids[0, :n])
    assert marks.items.xy.shape == (len(layout["items"]), 2) and len(marks.items.labels) == len(layout["items"])
    assert marks.bar.width_m.shape == (n,) and "delivered 0/" in marks.status
    assert [a.name for a in marks.areas] == ["delivery", "shelves"]
    assert env.render().shape == (448, 640, 3)
