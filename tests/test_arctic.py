"""Arctic Transport (issue 49): ground-dependent steps, arriving, the time-to-go field and the
capability-blind reference's cost."""

import numpy as np
import pytest
from reference_runs import headroom

from comat.envs import make_env
from comat.tasks.arctic import ICE, SNOW, WATER, ArcticTransport


def test_a_robot_s_step_is_its_speed_on_the_ground_under_it():
    task = ArcticTransport()
    state = task.new_state(1, 3)
    state["team"][0] = 3
    state["ground"][0, :, 2] = ICE
    state["ground"][0, :, 3] = WATER
    caps = np.array([[[0.16, 0.03]] * 3])
    poses = np.array([[[-0.6, 0.0, 0.0], [-0.2, 0.0, 0.0], [-1.4, 0.0, 0.0]]])  # ice, water, snow
    np.testing.assert_allclose(task.step_lengths_at(caps, poses, state)[0], [0.16, 0.03, 0.095])
    arrived = task.update(
        state, np.array([[[1.3, 0.0, 0.0], [0.0, 0.0, 0.0], [1.25, 0.5, 0.0]]]), None, caps, np.ones((1, 3), bool)
    )
    assert arrived["arrived"][0] == 2 and task.progress(state)[0] == pytest.approx(2 / 3)


def test_the_time_to_go_field_goes_around_slow_ground():
    """A water wall with one ice gap: an ice robot's field leads through the gap; the blind one's
    (every cell equally fast) goes straight."""
    task = ArcticTransport()
    state = task.new_state(1, 1)
    state["ground"][0, :, 2:6] = SNOW
    state["ground"][0, :, 3] = WATER
    state["ground"][0, 4, 3] = ICE  # the top row's cell is ice
    ice_robot = np.array([[[0.16, 0.01]]])  # 40 steps through a water cell, 4.7 up each snow cell
    here = np.array([[[-0.6, -0.8]]])  # row 0, column 2, next to the water
    aware, _ = task._targets(state, here, ice_robot, np.ones((1, 1), bool))
    blind, _ = task._targets(state, here, np.full((1, 1, 2), 0.1), np.ones((1, 1), bool))
    assert aware[0, 0, 1] > here[0, 0, 1] and blind[0, 0, 0] > here[0, 0, 0]  # up toward the gap / straight on


def test_composition_matters_the_blind_reference_arrives_less():
    out = headroom("arctic", "train")
    assert out["heuristic"] >= 0.95 and out["blind"] <= out["heuristic"] - 0.1, out


def test_layout_round_trips_and_the_ground_is_drawn():
    env = make_env("arctic_v0", tier="unicycle", render_mode="rgb_array")
    env.reset(seed=4)
    core = env.core
    fresh = core.task.new_state(1, core.N)
    core.task.set_layout(fresh, 0, core.task.layout(core.state, 0))
    np.testing.assert_array_equal(fresh["ground"], core.state["ground"])
    n = env.team.size
    marks = core.task.marks(core.state, 0, core.caps[0, :n], core.type_ids[0, :n])
    assert len(marks.areas) == 1 + int((core.state["ground"][0] != SNOW).sum())
    assert env.render().shape == (448, 640, 3)
