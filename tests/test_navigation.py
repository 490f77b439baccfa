"""Navigation v1: claiming a goal by stopping on it, one goal per robot, goals drawn within their own
robot's reach (never redrawn toward a plan), a planner that reads speeds through ``caps`` only, the
observation its spec sheet states, the coordination metric, and the reference ladder's order where
the type says nothing of a robot's speed."""

import itertools
import re

import numpy as np
import pytest
from reference_runs import mean_progress

import comat.tasks.navigation as navigation_module
from comat.envs import make_env, make_vec_env
from comat.envs.heuristics import blind_actions, heuristic_actions, type_mean_capabilities, type_only_actions
from comat.task_logic import min_cost_assignment
from comat.tasks import COALITION_SETS
from comat.tasks.navigation import Navigation
from comat.team import generate_coalitions


def _state(goals, starts, task=None):
    task = task or Navigation()
    task.fit_teams(len(goals))  # a goal slot for each goal, as for a team that large
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


def test_the_faster_of_two_same_type_robots_gets_the_far_goal_and_only_caps_say_which():
    """Two fast-type robots side by side, a near goal and a far one. The plan reads the speeds from
    ``caps``: swapping the two robots' speeds swaps their goals. Believing them equally fast (the
    type_only rung: one type, one mean) or reading no speed at all (the blind twin), the plan is the
    same whatever the speeds are."""
    near, far = [-0.5, 0.0], [1.0, 0.0]
    task, state = _state([near, far], [[-1.2, 0.1], [-1.2, -0.1]])
    mask, types = np.ones((1, 2), bool), np.zeros((1, 2), np.int64)
    poses = np.array([[[-1.2, 0.1, 0.0], [-1.2, -0.1, 0.0]]])
    for caps, far_robot in (([0.06, 0.15], 1), ([0.15, 0.06], 0)):
        goals, ok = task._plan(state, np.array([caps]), mask)
        assert ok.all() and goals[0, far_robot].tolist() == far and goals[0, 1 - far_robot].tolist() == near
    believed = task._plan(state, np.full((1, 2), 0.115), mask)[0]
    blind_a = task.blind_scripted_actions(state, poses, types, np.array([[[0.06], [0.15]]]), mask)
    blind_b = task.blind_scripted_actions(state, poses, types, np.array([[[0.15], [0.06]]]), mask)
    np.testing.assert_array_equal(blind_a, blind_b)
    np.testing.assert_array_equal(believed, task._plan(state, np.ones((1, 2)), mask)[0])


def test_the_state_holds_no_speed_the_planner_could_read():
    env = make_vec_env("navigation_v1", 2, coalitions="capability", tier="unicycle", seed=3)
    env.reset(teams=generate_coalitions("navigation", "capability", 2))
    speeds = set(np.round(env.core.caps[env.core.mask][:, 0], 6).tolist())
    for key, value in env.core.state.items():
        assert not speeds & set(np.round(np.asarray(value, dtype=float).ravel(), 6).tolist()), key


@pytest.mark.parametrize("split", COALITION_SETS)
def test_every_goal_is_within_its_robots_reach_and_no_layout_consults_the_planner(split, monkeypatch):
    """A right assignment exists by construction: one that gives every robot a goal it reaches in
    ``reach_steps_for(n)`` steps of travel; goals keep apart from each other and from every start."""
    task = Navigation()
    task.fit_teams(20)

    def no_planning(*args, **kwargs):
        raise AssertionError("a layout was drawn against the planner")

    monkeypatch.setattr(task, "_plan", no_planning)
    rng = np.random.default_rng(4)
    spacing = []
    for team in generate_coalitions("navigation", split):
        n, caps = team.size, team.capability_array()
        state, starts = task.new_state(1, n), task.spawn(rng, n)
        task.reset_env(state, 0, rng, caps, starts)
        _, steps = task._steps_to(state, state["start"], caps[None, :, 0])
        late = steps[0][:, :n] > task.reach_steps_for(n) + 1e-9
        rows, cols = min_cost_assignment(late.astype(float))
        assert late[rows, cols].sum() == 0, (split, n)
        goals = state["goals"][0, :n]
        gaps = np.hypot(*(goals[:, None] - goals[None]).transpose(2, 0, 1)) + 9 * np.eye(n)
        to_starts = np.hypot(*(goals[:, None] - starts[None, :, :2]).transpose(2, 0, 1))
        assert to_starts.min() > task.goal_radius_m
        spacing.append(gaps.min(1))
    spacing = np.concatenate(spacing)
    assert spacing.min() >= 0.28 and np.mean(spacing >= task.goal_spacing - 1e-9) >= 0.97


def test_the_same_seed_gives_the_same_episode():
    runs = []
    for _ in range(2):
        env = make_vec_env("navigation_v1", 3, coalitions="train", tier="unicycle", seed=11)
        obs, _ = env.reset(seed=11)
        for _ in range(4):
            obs = env.step(heuristic_actions(env.core))[0]
        runs.append((env.core.state["goals"].copy(), obs.copy()))
    np.testing.assert_array_equal(runs[0][0], runs[1][0])
    np.testing.assert_array_equal(runs[0][1], runs[1][1])


def test_the_observation_is_what_the_spec_sheet_says():
    doc = navigation_module.__doc__
    size = int(re.search(r"\| Observation \| Box\((\d+),\)", doc).group(1))
    last = max(int(m) for m in re.findall(r"^\| \d+–(\d+) \|", doc, re.MULTILINE))
    task = Navigation()
    assert task.obs_size() == size == last + 1
    # one robot at the origin, speed 0.1 m, 2 steps gone (20 left); four open goals and one claimed
    goals = [[0.5, 0.0], [0.0, 0.8], [1.5, 0.5], [2.4, 0.0], [0.3, 0.3]]
    task, state = _state(goals, [[0.0, 0.0], [-1.0, 0.0]], task)
    state["claimed"][0, 4] = True
    state["steps"][:] = 2
    caps = np.array([[[0.1], [0.05]]])
    obs = task.observe(state, np.zeros((1, 2, 3)), np.array([[0, 1]]), caps, np.ones((1, 2), bool))[0, 0]
    assert obs.shape == (size,) and obs[6] == pytest.approx(0.5) and obs[7] == 0.0
    assert obs[8] == pytest.approx(1 / 5) and obs[9] == pytest.approx(20 / 22)

    def view(x, y):  # offset and steps to go / horizon of a goal seen from the origin at 0.1 m a step
        return [x, y, (abs(x) + abs(y) - 0.1) / 0.1 / 22]

    np.testing.assert_allclose(obs[10:16], view(0.5, 0.0) + view(0.0, 0.8))  # the two nearest open goals
    # the farthest it can still reach in 20 steps: (1.5, 0.5) at 19 steps, then (0, 0.8), (0.5, 0);
    # (2.4, 0) needs 23 steps, and the claimed (0.3, 0.3) is no longer shown
    np.testing.assert_allclose(obs[16:25], view(1.5, 0.5) + view(0.0, 0.8) + view(0.5, 0.0))


def test_coordination_counts_goals_no_free_robot_can_still_reach():
    goals = [[0.5, 0.0], [1.1, 0.0], [2.0, 0.6], [0.0, 0.5]]
    task, state = _state(goals, [[0.0, 0.0], [0.0, -0.2]])
    state["steps"][:] = 10  # 12 steps left
    caps, mask, types = np.array([[[0.1], [0.05]]]), np.ones((1, 2), bool), np.zeros((1, 2), np.int64)
    poses = np.array([[[0.0, 0.0, 0.0], [0.0, -0.2, 0.0]]])
    # robot 0 reaches 1.2 m (+0.16 claim radius), robot 1 0.6 m: goal 2 (2.6 m) is out of everyone's
    # reach; goal 1 (1.1 m) only robot 0's
    assert task.coordination(state, poses, types, caps, mask)[0] == pytest.approx(1 / 4)
    state["done_robot"][0, 0] = True  # robot 0 claimed another goal: goal 1 is stranded too
    state["claimed"][0, 3] = True
    assert task.coordination(state, poses, types, caps, mask)[0] == pytest.approx(2 / 4)
    state["claimed"][0, 2] = True  # a claimed goal is never stranded
    assert task.coordination(state, poses, types, caps, mask)[0] == pytest.approx(1 / 4)
    assert task.coordination_name and "lower is better" in task.coordination_doc


def test_no_goal_is_stranded_at_the_start():
    env = make_vec_env("navigation_v1", 20, coalitions="scale", tier="unicycle", seed=2)
    env.reset(teams=generate_coalitions("navigation", "scale"))
    core = env.core
    assert core.task.coordination(core.state, core.poses(), core.type_ids, core.caps, core.mask).max() == 0.0


def test_where_the_type_says_nothing_of_the_speed_the_ladder_is_ordered():
    """U_cap: scripted well above type_only (each robot believed at its type's mean speed) and above
    the blind twin (one episode per stored coalition, unicycle tier)."""
    means = type_mean_capabilities("navigation", "capability")
    scripted = mean_progress("navigation", "capability", heuristic_actions)
    type_only = mean_progress("navigation", "capability", lambda core: type_only_actions(core, means))
    blind = mean_progress("navigation", "capability", blind_actions)
    assert scripted >= 0.9 and type_only <= scripted - 0.08 and blind <= scripted - 0.08, (scripted, type_only, blind)


def _team_view_actions(core):
    """A planner that reads only the team's observations (positions, speeds, goal views): the goals
    any robot sees, shared out with the least summed squared steps to go from where the robots are
    now (late and hopeless travel weighed as the scripted planner does)."""
    task, obs, mask = core.task, core.observe(), core.mask
    targets, has = np.zeros((*mask.shape, 2)), np.zeros(mask.shape, bool)
    views = obs[..., 10:].reshape(*mask.shape, -1, 3)
    for b in range(mask.shape[0]):
        seen = (np.abs(views[b]).sum(-1) > 0) & mask[b][:, None]
        goals = np.unique(np.round((obs[b, :, None, :2] + views[b, ..., :2])[seen], 9), axis=0)
        robots = np.flatnonzero(mask[b] & (obs[b, :, 7] < 0.5))
        if not (goals.size and robots.size):
            continue
        speed = obs[b, robots, 6] * task.capability_scale[0]
        t = np.maximum(np.abs(goals[None] - obs[b, robots, None, :2]).sum(-1) - task.arrive_m, 0) / speed[:, None]
        left = task.horizon * obs[b, robots, 9][:, None]
        late = np.maximum(t - task.plan_budget_steps, 0)
        rows, cols = min_cost_assignment(t**2 + task.late_weight * late**2 + task.hopeless_cost * (t > left))
        targets[b, robots[rows]], has[b, robots[rows]] = goals[cols], True
    return task.drive(core.state, core.poses(), core.caps, mask, targets, has)


def test_the_team_observations_hold_what_a_speed_aware_plan_needs():
    """What a learner's communication can carry suffices to beat the blind reference, which reads
    every goal and start: the views of the team together show the goals, with each robot's speed."""
    shared = mean_progress("navigation", "train", _team_view_actions)
    blind = mean_progress("navigation", "train", blind_actions)
    assert shared >= blind + 0.05, (shared, blind)


def test_layout_round_trips_and_the_task_draws_itself():
    env = make_env("navigation_v1", tier="unicycle", render_mode="rgb_array")
    env.reset(seed=4)
    core = env.core
    fresh = core.task.new_state(1, core.N)
    core.task.set_layout(fresh, 0, core.task.layout(core.state, 0))
    for key in ("goals", "active", "claimed"):
        np.testing.assert_array_equal(fresh[key], core.state[key])
    assert "goals claimed 0/" in env.render_caption or env.render().shape == (448, 640, 3)
