"""Navigation (issue 49): claiming a goal by stopping on it, one goal per robot, layouts the right
plan can finish, the least-cost assignment, and the capability-blind reference's cost."""

import itertools

import numpy as np
import pytest
from reference_runs import headroom

from comat.envs import make_env, make_vec_env
from comat.task_logic import min_cost_assignment
from comat.tasks.navigation import Navigation
from comat.team import generate_coalitions


def _state(goals, starts):
    task = Navigation()
    state = task.new_state(1, len(starts))
    task.set_layout(state, 0, {"goals": goals})
    task.set_starts(state, 0, np.column_stack([starts, np.zeros(len(starts))]))
    return task, state


def test_a_robot_claims_one_goal_by_stopping_on_it():
    task, state = _state([[0.0, 0.0], [0.2, 0.0]], [[-1.0, 0.0], [-1.0, 0.5]])
    caps, mask, types = np.array([[[0.15], [0.05]]]), np.ones((1, 2), bool), np.array([[0, 1]])
    poses = np.array([[[0.05, 0.0, 0.0], [-1.0, 0.5, 0.0]]])
    assert task.update(state, poses, types, caps, mask)["claimed"][0] == 0  # drove 1.05 m: passing through
    assert task.update(state, poses, types, caps, mask)["claimed"][0] == 1  # stopped within 0.16 m: claims
    assert state["claimed"][0, :2].tolist() == [True, False] and state["done_robot"][0].tolist() == [True, False]
    poses[0, 0, :2] = (0.2, 0.0)  # a robot that claimed claims nothing more
    task.update(state, poses, types, caps, mask)
    task.update(state, poses, types, caps, mask)
    assert not state["claimed"][0, 1] and task.progress(state)[0] == pytest.approx(0.5)


def test_the_assignment_is_least_cost():
    rng = np.random.default_rng(0)
    for _ in range(100):
        r, c = (int(x) for x in rng.integers(1, 6, 2))
        cost = rng.uniform(0, 10, (r, c))
        rows, cols = min_cost_assignment(cost)
        assert len(set(rows.tolist())) == len(set(cols.tolist())) == min(r, c)
        if r <= c:
            best = min(sum(cost[i, p[i]] for i in range(r)) for p in itertools.permutations(range(c), r))
        else:
            best = min(sum(cost[p[j], j] for j in range(c)) for p in itertools.permutations(range(r), c))
        assert cost[rows, cols].sum() == pytest.approx(best)


def test_slow_robots_get_near_goals_and_the_blind_plan_does_not_know_which_are_slow():
    """Two goals: one near, one far. The slow robot starts ahead of the fast one; the scripted plan
    still sends the fast one far, the blind one (distance alone) the slow one, which cannot make it."""
    task, state = _state([[-0.4, 0.0], [1.3, 0.0]], [[-1.2, -0.1], [-1.0, 0.1]])
    mask = np.ones((1, 2), bool)
    aware, _ = task._plan(state, None, np.array([[0.16, 0.04]]), mask)
    blind, _ = task._plan(state, None, np.ones((1, 2)), mask)
    assert aware[0, 0].tolist() == [1.3, 0.0] and blind[0, 1].tolist() == [1.3, 0.0]


def test_every_layout_leaves_the_scripted_plan_its_slack():
    env = make_vec_env("navigation_v0", 20, coalitions="train", tier="unicycle", seed=2)
    env.reset(teams=generate_coalitions("navigation", "train"))
    core, task = env.core, env.core.task
    for b in range(20):
        n = core.teams[b].size
        assert task._plan_steps(core.state, b, core.caps[b, :n, 0]) <= task.slack * task.horizon
        np.testing.assert_allclose(core.state["start"][b, :n], core.poses()[b, :n, :2], atol=1e-9)


def test_composition_matters_the_blind_reference_claims_fewer_goals():
    out = headroom("navigation", "train")
    assert out["heuristic"] >= 0.95 and out["blind"] <= out["heuristic"] - 0.1, out


def test_layout_round_trips_and_the_task_draws_itself():
    env = make_env("navigation_v0", tier="unicycle", render_mode="rgb_array")
    env.reset(seed=4)
    core = env.core
    fresh = core.task.new_state(1, core.N)
    core.task.set_layout(fresh, 0, core.task.layout(core.state, 0))
    for key in ("goals", "active", "claimed"):
        np.testing.assert_array_equal(fresh[key], core.state[key])
    assert "goals claimed 0/" in env.render_caption or env.render().shape == (448, 640, 3)
