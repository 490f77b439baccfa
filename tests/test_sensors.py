"""Heterogeneous Sensor Network (issue 49): watching targets at once, clusters only the right radius
covers from their centre, the scripted plan and its capability-blind twin, the export layout."""

import numpy as np
import pytest
from reference_runs import headroom

from comat.envs import make_env, make_vec_env
from comat.tasks.sensors import SensorNetwork


def test_progress_is_the_most_targets_watched_at_once():
    task = SensorNetwork()
    state = task.new_state(1, 2)
    task.set_layout(
        state, 0, {"targets": [[0.0, 0.0], [1.0, 0.0]], "centres": [[0.0, 0.0], [1.0, 0.0]], "need": [0.0, 0.0]}
    )
    caps, mask, types = np.array([[[0.3], [0.2]]]), np.ones((1, 2), bool), np.array([[0, 1]])
    watch_one = np.array([[[0.1, 0.0, 0.0], [-1.0, 0.5, 0.0]]])
    assert task.update(state, watch_one, types, caps, mask)["coverage"][0] == 1.0
    assert task.update(state, watch_one, types, caps, mask)["coverage"][0] == 0.0  # no new best, no reward
    watch_none = np.array([[[-1.0, -0.5, 0.0], [-1.0, 0.5, 0.0]]])
    task.update(state, watch_none, types, caps, mask)
    assert task.progress(state)[0] == pytest.approx(0.5) and not state["watched"][0].any()
    watch_both = np.array([[[0.1, 0.0, 0.0], [1.15, 0.0, 0.0]]])
    assert task.update(state, watch_both, types, caps, mask)["coverage"][0] == 1.0 and task.done(state)[0]


@pytest.mark.parametrize("split", ["train", "capability"])
def test_each_cluster_is_covered_from_its_centre_by_the_robot_it_was_sized_for(split):
    env = make_vec_env("sensors_v1", 8, coalitions=split, tier="unicycle", seed=3)
    env.reset()
    core = env.core
    for b in range(8):
        n = core.teams[b].size
        need, radii = np.sort(core.state["need"][b, :n]), np.sort(core.caps[b, :n, 0])
        # one cluster per robot, each sized U(0.5, 0.62) x its robot's radius: sorted, they pair up
        assert (need <= 0.62 * radii + 1e-9).all() and (need >= 0.5 * radii - 0.1).all()


def test_composition_matters_the_blind_reference_watches_fewer():
    out = headroom("sensors", "train")
    assert out["heuristic"] >= 0.95 and out["blind"] <= out["heuristic"] - 0.1, out


def test_layout_round_trips_and_the_task_draws_itself():
    env = make_env("sensors_v1", tier="unicycle", render_mode="rgb_array")
    env.reset(seed=4)
    core = env.core
    fresh = core.task.new_state(1, core.N)
    core.task.set_layout(fresh, 0, core.task.layout(core.state, 0))
    for key in ("targets", "active", "centres", "need", "clusters"):
        np.testing.assert_array_equal(fresh[key], core.state[key])
    assert env.render().shape == (448, 640, 3)
