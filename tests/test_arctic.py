"""Arctic Transport (issue 49): ground-dependent steps, arriving, the time-to-go field and the
capability-blind reference's cost."""

import numpy as np
import pytest
from reference_runs import headroom

from comat.envs import make_env
from comat.tasks import env_id
from comat.tasks.arctic import ICE, SNOW, WATER, ArcticTransport
from comat.team import RobotSpec, TeamSpec, random_team


def test_a_robot_s_step_is_its_speed_on_the_ground_under_it_and_only_crossers_must_arrive():
    task = ArcticTransport()
    state = task.new_state(1, 4)
    state["ground"][0, :, 2] = ICE
    state["ground"][0, :, 3] = WATER
    caps = np.array([[[0.16, 0.03, 0.3]] * 3 + [[0.07, 0.07, 0.9]]])
    poses = np.array([[[-0.6, 0.0, 0.0], [-0.2, 0.0, 0.0], [-1.4, 0.0, 0.0], [-1.4, 0.5, 0.0]]])  # ice, water, snow
    np.testing.assert_allclose(task.step_lengths_at(caps, poses, state)[0], [0.16, 0.03, 0.095, 0.07])
    types = np.array([[0, 1, 0, 2]])
    ends = np.array([[[1.3, 0.0, 0.0], [0.0, 0.0, 0.0], [1.25, 0.5, 0.0], [1.3, -0.5, 0.0]]])  # the scout arrives too
    arrived = task.update(state, ends, types, caps, np.ones((1, 4), bool))
    assert arrived["arrived"][0] == 2 and task.progress(state)[0] == pytest.approx(2 / 3)
    assert not task.done(state)[0] and task.end_counts(state)["not_arrived"][0] == 1
    task.update(
        state, ends + np.array([1.3, 0.0, 0.0]) * (np.arange(4) == 1)[:, None], types, caps, np.ones((1, 4), bool)
    )
    assert task.done(state)[0] and task.progress(state)[0] == 1.0


def test_the_team_sees_what_any_robot_sees_for_good():
    """A crosser sees the cell it stands in; the scout sees every cell whose centre is within its
    sight; what is seen stays seen, and observations and the state show only the seen ground."""
    task = ArcticTransport()
    state = task.new_state(1, 2)
    state["ground"][0, :, 2:6] = WATER
    caps = np.array([[[0.16, 0.02, 0.1], [0.07, 0.07, 0.85]]])
    starts = np.array([[-0.7, -0.7, 0.0], [-1.0, 0.2, 0.0]])  # column 2, row 0; column 1, row 2
    task.reset_env(state, 0, np.random.default_rng(0), caps[0], starts)
    state["ground"][0, :, 2:6] = WATER  # (the reset drew a ground: put the test's back)
    seen = state["seen"][0]
    assert seen[0, 2] and seen[2, 1]  # the cells they stand in
    centres_x = -1.6 + 0.4 * (np.arange(8) + 0.5)
    centres_y = -1.0 + 0.4 * (np.arange(5) + 0.5)
    d = np.hypot(centres_x[None, :] + 1.0, centres_y[:, None] - 0.2)
    expect = d <= 0.85
    expect[0, 2] = expect[2, 1] = True
    np.testing.assert_array_equal(seen, expect)
    mask = np.ones((1, 2), bool)
    obs = task.task_features(
        state, np.concatenate([starts[None, :, :2], np.zeros((1, 2, 1))], -1), np.array([[0, 2]]), caps, mask
    )
    assert obs[0, 0, 0] == WATER and obs[0, 0, 1] == (WATER if expect[0, 3] else SNOW)
    far = np.array([[[1.4, 0.8, 0.0], [1.4, 0.8, 0.0]]])  # both leave: nothing is forgotten
    task.update(state, far, np.array([[0, 2]]), caps, mask)
    assert (state["seen"][0] >= expect).all()
    known = task.global_features(state)[0, :40].reshape(5, 8)
    np.testing.assert_array_equal(known, np.where(state["seen"][0], state["ground"][0], SNOW))


def test_the_time_to_go_field_goes_around_slow_ground():
    """A water wall with one ice gap: an ice robot's field leads through the gap; the blind one's
    (every cell equally fast) goes straight."""
    task = ArcticTransport()
    state = task.new_state(1, 1)
    state["ground"][0, :, 2:6] = SNOW
    state["ground"][0, :, 3] = WATER
    state["ground"][0, 4, 3] = ICE  # the top row's cell is ice
    state["seen"][0] = True
    ice_robot = np.array([[[0.16, 0.01, 0.3]]])  # 40 steps through a water cell, 4.7 up each snow cell
    here = np.array([[[-0.6, -0.8]]])  # row 0, column 2, next to the water
    aware, _ = task._targets(state, here, ice_robot, np.ones((1, 1), bool))
    blind, _ = task._targets(state, here, ice_robot, np.ones((1, 1), bool), blind=True)
    state["seen"][0] = False  # the gap not seen: the water's mean crossing time, so straight on
    unseen, _ = task._targets(state, here, ice_robot, np.ones((1, 1), bool))
    assert aware[0, 0, 1] > here[0, 0, 1] and blind[0, 0, 0] > here[0, 0, 0]  # up toward the gap / straight on
    assert unseen[0, 0, 0] > here[0, 0, 0]


def test_composition_matters_the_blind_reference_arrives_less():
    out = headroom("arctic", "train")
    assert out["heuristic"] >= 0.95 and out["blind"] <= out["heuristic"] - 0.1, out


def test_layout_round_trips_and_the_ground_is_drawn():
    env = make_env("arctic_v1", tier="unicycle", render_mode="rgb_array")
    env.reset(seed=4)
    core = env.core
    fresh = core.task.new_state(1, core.N)
    core.task.set_layout(fresh, 0, core.task.layout(core.state, 0))
    np.testing.assert_array_equal(fresh["ground"], core.state["ground"])
    n = env.team.size
    marks = core.task.marks(core.state, 0, core.caps[0, :n], core.type_ids[0, :n])
    assert len(marks.areas) == 1 + int((core.state["ground"][0] != SNOW).sum())
    hidden = [a for a in marks.areas if a.label == "?"]
    assert len(hidden) == int(((core.state["ground"][0] != SNOW) & ~core.state["seen"][0]).sum())
    assert env.render().shape == (448, 640, 3)


def test_a_team_needs_ice_and_water_robots_and_may_lack_a_scout():
    two = TeamSpec("arctic", (RobotSpec("ice", (0.16, 0.02, 0.3)), RobotSpec("water", (0.02, 0.16, 0.3))))
    assert two.size == 2
    with pytest.raises(
        ValueError, match=r"needs at least one robot of each type \('ice', 'water'\); missing \['water'\]"
    ):
        TeamSpec("arctic", (RobotSpec("ice", (0.16, 0.02, 0.3)), RobotSpec("scout", (0.07, 0.07, 0.9))))
    drawn = {n: random_team(np.random.default_rng(n), "arctic", "train", n) for n in (2, 3, 5, 20)}
    assert sorted(r.type for r in drawn[2].robots) == ["ice", "water"]
    assert all({"ice", "water", "scout"} <= {r.type for r in t.robots} for n, t in drawn.items() if n >= 3)
    with pytest.raises(ValueError, match="needs at least 2 robots"):
        random_team(np.random.default_rng(0), "pcp", "train", 1)


def test_the_old_rules_are_refused_by_name():
    with pytest.raises(ValueError, match=r"got 'arctic_v0' \(arctic's rules changed: it is arctic_v1 now\)"):
        make_env("arctic_v0")
    assert env_id("arctic") == "arctic_v1" and env_id("pcp") == "pcp_v0"
