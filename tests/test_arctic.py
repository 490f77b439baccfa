"""Arctic Transport v2 (issue 64): the cells' needs and the crawl, arriving, what the team sees, the
field drawn against the team, the planners (capabilities only through ``caps``), the ladder's order
on a few design teams, the blind rung against the constant action, the coordination metric, the
observation layout against the spec sheet, drawing and export."""

import re

import numpy as np
import pytest

from comat.envs import make_env, make_vec_env
from comat.envs.heuristics import (
    blind_actions,
    heuristic_actions,
    type_mean_capabilities,
    type_only_actions,
)
from comat.tasks import arctic, env_id
from comat.tasks.arctic import CRAWL_M, ICE, SNOW, WATER, ArcticTransport
from comat.team import RobotSpec, TeamSpec, generate_coalitions, random_team

ONE = np.ones((1, 1), bool)


def field(task, B=1, N=1, ground=SNOW, need=0.0, seen=True):
    """A state whose field (every field cell) is ``ground`` with ``need``, seen or not."""
    state = task.new_state(B, N)
    cols = list(task.field_cols)
    state["ground"][:, :, cols] = ground
    state["need"][:, :, cols] = need
    state["seen"][:] = seen
    return state


def at(col, row):
    """The centre (x, y) of cell (row, col)."""
    return [-1.6 + 0.4 * (col + 0.5), -1.0 + 0.4 * (row + 0.5)]


def test_a_robot_crosses_a_cell_at_its_speed_on_that_ground_if_it_meets_the_need_else_it_crawls():
    task = ArcticTransport()
    state = field(task, N=4)
    state["ground"][0, :, 2], state["ground"][0, :, 3] = ICE, WATER
    state["need"][0, :, 2], state["need"][0, :, 3] = 0.15, 0.05
    caps = np.array([[[0.16, 0.03, 0.3], [0.14, 0.06, 0.3], [0.16, 0.03, 0.3], [0.14, 0.06, 0.3]]])
    poses = np.array([[[*at(2, 2), 0.0], [*at(2, 2), 0.0], [*at(3, 2), 0.0], [*at(0, 2), 0.0]]])
    # ice robot meets the ridge (0.16 >= 0.15); the other does not; the first misses the current
    # (0.03 < 0.05); on snow (column 0) the step is the mean of the two speeds
    np.testing.assert_allclose(task.step_lengths_at(caps, poses, state)[0], [0.16, CRAWL_M, CRAWL_M, 0.10])
    state["need"][0] = 0.0
    np.testing.assert_allclose(task.step_lengths_at(caps, poses, state)[0], [0.16, 0.14, 0.03, 0.10])


def test_only_crossers_must_arrive_and_the_goal_is_the_last_two_columns():
    task = ArcticTransport()
    state = task.new_state(1, 4)
    caps = np.array([[[0.16, 0.03, 0.3]] * 3 + [[0.07, 0.07, 0.9]]])
    types, mask = np.array([[0, 1, 0, 2]]), np.ones((1, 4), bool)
    ends = np.array([[[0.85, 0.0, 0.0], [0.75, 0.0, 0.0], [1.4, 0.5, 0.0], [1.3, -0.5, 0.0]]])  # the scout arrives too
    assert task.update(state, ends, types, caps, mask)["arrived"][0] == 2
    assert task.progress(state)[0] == pytest.approx(2 / 3) and not task.done(state)[0]
    assert task.end_counts(state)["not_arrived"][0] == 1
    task.update(state, ends + np.array([0.1, 0.0, 0.0]), types, caps, mask)  # x = 0.85: in
    assert task.done(state)[0] and task.progress(state)[0] == 1.0
    task.update(state, ends - np.array([1.0, 0.0, 0.0]), types, caps, mask)  # arrived stays arrived
    assert task.progress(state)[0] == 1.0


def test_the_team_sees_what_any_robot_sees_for_good_and_observes_only_that():
    task = ArcticTransport()
    state = task.new_state(1, 2)
    caps = np.array([[[0.16, 0.03, 0.1], [0.07, 0.07, 0.85]]])
    starts = np.array([[-0.7, -0.7, 0.0], [-1.0, 0.2, 0.0]])  # column 2, row 0; column 1, row 2
    task.reset_env(state, 0, np.random.default_rng(0), caps[0], starts)
    seen = state["seen"][0]
    d = np.hypot(-1.6 + 0.4 * (np.arange(8) + 0.5)[None, :] + 1.0, -1.0 + 0.4 * (np.arange(5) + 0.5)[:, None] - 0.2)
    expect = d <= 0.85
    expect[0, 2] = expect[2, 1] = True  # the cells they stand in
    np.testing.assert_array_equal(seen, expect)
    task.update(state, np.array([[[1.4, 0.8, 0.0], [1.4, 0.8, 0.0]]]), np.array([[0, 2]]), caps, np.ones((1, 2), bool))
    assert (state["seen"][0] >= expect).all()  # nothing is forgotten
    g = task.global_features(state)[0]
    np.testing.assert_array_equal(g[:40].reshape(5, 8), np.where(state["seen"][0], state["ground"][0], SNOW))
    np.testing.assert_allclose(g[40:80].reshape(5, 8), np.where(state["seen"][0], state["need"][0], 0.0) / 0.2)
    np.testing.assert_array_equal(g[80:120].reshape(5, 8), state["seen"][0])


def test_the_field_is_drawn_against_the_team_and_every_crosser_has_a_good_way():
    task = ArcticTransport()
    team = generate_coalitions("arctic", "train", 20, seed=1)[3]
    caps, rng = team.capability_array(), np.random.default_rng(7)
    starts = task.spawn(rng, team.size)
    ground, need = task.draw_field(np.random.default_rng(3), caps, starts)
    again = task.draw_field(np.random.default_rng(3), caps, starts)
    np.testing.assert_array_equal(again[0], ground)
    np.testing.assert_array_equal(again[1], need)
    outside = np.setdiff1d(np.arange(8), task.field_cols)
    assert (ground[:, outside] == SNOW).all() and (need[:, outside] == 0).all() and (need[ground == SNOW] == 0).all()
    # each need is U(0.8, 1.1) × some robot's speed on that cell's ground
    for kind, k in ((ICE, 0), (WATER, 1)):
        for value in need[(ground == kind) & (need > 0)]:
            ratio = value / caps[:, k]
            assert ((ratio >= 0.8 - 1e-12) & (ratio <= 1.1 + 1e-12)).any(), (kind, value, caps[:, k])
    crossers = caps[:, :2].max(axis=1) > task.crosser_speed_m
    assert crossers.sum() == sum(r.type != "scout" for r in team.robots)
    assert (task.route_ratios(ground, need, caps[crossers], starts[crossers]) <= task.route_slack).all()


def test_whether_a_detour_pays_depends_on_the_robot_s_actual_speeds():
    """Water straight ahead, ice one row up: a robot slow enough in water goes round over the ice,
    one fast enough in water goes straight; a ridge needing 0.12 m stops one robot and not another."""
    task = ArcticTransport()
    state = field(task, ground=ICE)
    state["ground"][0, 2, 2:6] = WATER  # the robot's row: water across the field
    here = np.array([[[-0.85, 0.0, 0.0]]])  # column 1, row 2, at the field's edge
    slow_swimmer = np.array([[[0.15, 0.03, 0.3]]])
    fair_swimmer = np.array([[[0.15, 0.12, 0.3]]])
    up = task.scripted_actions(state, here, np.zeros((1, 1), int), slow_swimmer, ONE)
    on = task.scripted_actions(state, here, np.zeros((1, 1), int), fair_swimmer, ONE)
    assert up[0, 0] in (3, 4) and on[0, 0] == 1  # ±y round the water / +x through it
    state = field(task, ground=ICE, need=0.12)
    state["ground"][0, [0, 4], 2:6] = SNOW  # ridges needing 0.12 m everywhere but on the edges' snow
    state["need"][0, [0, 4], 2:6] = 0.0
    strong, weak = np.array([[[0.15, 0.03, 0.3]]]), np.array([[[0.11, 0.03, 0.3]]])
    assert task.scripted_actions(state, here, np.zeros((1, 1), int), strong, ONE)[0, 0] == 1
    assert task.scripted_actions(state, here, np.zeros((1, 1), int), weak, ONE)[0, 0] in (3, 4)


def test_the_planners_read_capabilities_only_through_caps():
    """The state keeps each robot's sight for the rules; changing it changes no plan, and the
    type-only plan is the scripted plan given other caps."""
    env = make_vec_env(env_id("arctic"), 4, coalitions="capability", tier="unicycle", seed=11)
    env.reset(teams=generate_coalitions("arctic", "capability", 20, seed=1)[:4])
    core = env.core
    for _ in range(6):
        before = heuristic_actions(core), blind_actions(core)
        core.state["sight"] = core.state["sight"][:, ::-1].copy() + 0.3
        assert np.array_equal(before[0], heuristic_actions(core)) and np.array_equal(before[1], blind_actions(core))
        env.step(before[0])
    believed = type_mean_capabilities("arctic", "capability")
    mine = core.task.scripted_actions(core.state, core.poses(), core.type_ids, believed[core.type_ids], core.mask)
    np.testing.assert_array_equal(np.where(core.mask, mine, 0), type_only_actions(core, believed))


def run_episodes(split, teams, act, seed):
    """Final progress (B,) of one episode of each team under ``act(core)`` (unicycle)."""
    env = make_vec_env(env_id("arctic"), len(teams), coalitions=split, tier="unicycle", seed=seed)
    env.reset(teams=teams)
    done, out = np.zeros(len(teams), bool), np.zeros(len(teams))
    while not done.all():
        info = env.step(act(env.core))[-1]
        if "episode" in info:
            new = info["_episode"] & ~done
            out[new], done = info["episode"]["progress"][new], done | info["_episode"]
    return out


def test_the_ladder_keeps_its_order_on_a_few_design_teams():
    """Design teams (coalition seed 1), an episode seed below the held-out ones: scripted arrives
    with nearly everyone, the type-only plan loses crossers on U_cap, the blind one on U_size."""
    cap = generate_coalitions("arctic", "capability", 20, seed=1)[:6]
    believed = type_mean_capabilities("arctic", "capability")
    scripted = run_episodes("capability", cap, heuristic_actions, seed=21)
    type_only = run_episodes("capability", cap, lambda core: type_only_actions(core, believed), seed=21)
    assert scripted.mean() >= 0.75 and scripted.mean() - type_only.mean() >= 0.1, (scripted, type_only)
    size = generate_coalitions("arctic", "size", 20, seed=1)[4:10]
    scripted, blind = (run_episodes("size", size, act, seed=22) for act in (heuristic_actions, blind_actions))
    assert scripted.mean() >= 0.9 and scripted.mean() - blind.mean() >= 0.1, (scripted, blind)


def test_the_blind_plan_goes_round_what_it_believes_it_cannot_cross_unlike_the_constant_action():
    task = ArcticTransport()
    state = field(task, ground=ICE)
    state["need"][0, 2, 2] = 0.15  # a ridge right ahead that 0.1 m does not meet
    here = np.array([[[-0.85, 0.0, 0.0]]])
    assert task.blind_scripted_actions(state, here, np.zeros((1, 1), int), np.array([[[0.16, 0.03, 0.3]]]), ONE)[
        0, 0
    ] in (3, 4)
    assert task.best_constant_action == 1
    env = make_vec_env(env_id("arctic"), 3, coalitions="size", tier="unicycle", seed=23)
    env.reset(teams=generate_coalitions("arctic", "size", 20, seed=1)[6:9])
    differ = 0
    for _ in range(10):
        actions = blind_actions(env.core)
        differ += int(((actions != 1) & env.core.mask & ~env.core.state["arrived"]).sum())
        env.step(actions)
    assert differ > 0


def test_the_coordination_metric_is_the_speed_the_crossers_lose_to_the_ground():
    task = ArcticTransport()
    state = field(task, N=4, ground=WATER)
    state["ground"][0, :, 3] = ICE
    state["need"][0, 4, 3] = 0.2  # a ridge nobody meets
    caps = np.array([[[0.16, 0.04, 0.3], [0.04, 0.16, 0.3], [0.16, 0.04, 0.3], [0.07, 0.07, 0.9]]])
    types, mask = np.array([[0, 1, 0, 2]]), np.ones((1, 4), bool)
    poses = np.array([[[*at(2, 2), 0], [*at(2, 1), 0], [*at(3, 2), 0], [*at(2, 3), 0]]], float)
    task.update(state, poses, types, caps, mask)  # crossers: robots 0–2; the scout does not count
    # robot 0 in water at 0.04 of its 0.16; robot 1 at its best; robot 2 on ice at its best
    assert task.coordination(state, poses, types, caps, mask)[0] == pytest.approx((0.75 + 0 + 0) / 3)
    poses[0, 2] = [*at(3, 4), 0]  # robot 2 on the ridge: crawling
    assert task.coordination(state, poses, types, caps, mask)[0] == pytest.approx((0.75 + 1 - CRAWL_M / 0.16) / 3)
    poses[0, :3, 0] = -1.3  # all back on the snow outside the field: nobody counted
    assert task.coordination(state, poses, types, caps, mask)[0] == 0.0
    assert task.coordination_name and "lower is better" in task.coordination_doc


def test_the_observation_layout_is_the_spec_sheet_s():
    task = ArcticTransport()
    rows = re.findall(r"^\| (\d+)(?:–(\d+))? \| (.+?) \|$", arctic.__doc__, flags=re.MULTILINE)
    covered = [i for lo, hi, _ in rows for i in range(int(lo), int(hi or lo) + 1)]
    assert covered == list(range(task.obs_size())) == list(range(40)), covered
    assert f"Box({task.obs_size()},)" in arctic.__doc__
    state = field(task, N=1, ground=ICE, seen=False)
    state["ground"][0, 3, 3], state["need"][0, 3, 3], state["seen"][0, 3, 3] = WATER, 0.1, True
    pose = np.array([[[*at(2, 2), 0.0]]])  # the seen water cell is one row up, one column ahead
    obs = task.observe(state, pose, np.zeros((1, 1), int), np.array([[[0.16, 0.04, 0.3]]]), ONE)[0, 0]
    k = 3 * (1 + 1) + 1
    assert obs[10 + k] == WATER and obs[19 + k] == pytest.approx(0.5) and obs[28 + k] == 1
    assert obs[10:19].sum() == WATER and obs[28:37].sum() == 1  # the rest unseen
    np.testing.assert_allclose(obs[7:10], [0.8, 0.2, 0.3])
    assert obs[37] == pytest.approx(0.8 - at(2, 2)[0]) and obs[38] == 0 and obs[39] == pytest.approx(1 / 20)
    edge = task.observe(state, np.array([[[*at(2, 0), 0.0]]]), np.zeros((1, 1), int), np.ones((1, 1, 3)), ONE)[0, 0]
    np.testing.assert_array_equal(edge[19:22], 1.0)  # the row below the bottom row: a wall
    np.testing.assert_array_equal(edge[28:31], 1.0)


def test_same_seed_same_episode():
    teams = generate_coalitions("arctic", "scale", 20, seed=1)[:2]
    runs = []
    for _ in range(2):
        env = make_vec_env(env_id("arctic"), 2, coalitions="scale", tier="unicycle", seed=31)
        env.reset(teams=teams)
        fields = env.core.state["ground"].copy(), env.core.state["need"].copy()
        for _ in range(8):
            env.step(heuristic_actions(env.core))
        runs.append((*fields, env.core.poses().copy(), env.core.state["seen"].copy()))
    for a, b in zip(*runs):
        np.testing.assert_array_equal(a, b)


def test_layout_round_trips_and_the_ground_is_drawn_and_named_in_the_legend():
    env = make_env(env_id("arctic"), tier="unicycle", render_mode="rgb_array")
    env.reset(seed=4)
    core, task = env.core, env.core.task
    fresh = task.new_state(1, core.N)
    task.reset_env(fresh, 0, np.random.default_rng(1), core.caps[0, : env.team.size])  # an export's first reset
    task.set_layout(fresh, 0, task.layout(core.state, 0))
    for key in ("ground", "need"):
        np.testing.assert_array_equal(fresh[key], core.state[key])
    n = env.team.size
    marks = task.marks(core.state, 0, core.caps[0, :n], core.type_ids[0, :n])
    assert len(marks.areas) == 1 + 5 * len(task.field_cols)
    hidden = [a for a in marks.areas if a.label == "?"]
    assert len(hidden) == int((~core.state["seen"][0][:, list(task.field_cols)]).sum())
    legend = dict(marks.legend)
    assert {"ground: ice", "ground: water", "ground: snow"} <= set(legend)
    assert legend["ground: ice"] != legend["ground: water"]
    assert env.render().shape == (448, 640, 3)
    # the video's legend and the recording's list them beside the robot types "ice" and "water"
    from comat.viz.scene import legend_items

    labels = [label for label, _ in legend_items(task, [r.type for r in env.team.robots], False, marks)]
    assert {"ice", "water", "ground: ice", "ground: water", "ground: snow"} <= set(labels)


def test_a_team_needs_ice_and_water_robots_and_may_lack_a_scout():
    two = TeamSpec("arctic", (RobotSpec("ice", (0.16, 0.04, 0.3)), RobotSpec("water", (0.04, 0.16, 0.3))))
    assert two.size == 2
    with pytest.raises(
        ValueError, match=r"needs at least one robot of each type \('ice', 'water'\); missing \['water'\]"
    ):
        TeamSpec("arctic", (RobotSpec("ice", (0.16, 0.04, 0.3)), RobotSpec("scout", (0.07, 0.07, 0.9))))
    drawn = {n: random_team(np.random.default_rng(n), "arctic", "train", n) for n in (2, 3, 5, 20)}
    assert sorted(r.type for r in drawn[2].robots) == ["ice", "water"]
    assert all({"ice", "water", "scout"} <= {r.type for r in t.robots} for n, t in drawn.items() if n >= 3)


def test_the_old_rules_are_refused_by_name():
    for old in ("arctic_v0", "arctic_v1"):
        with pytest.raises(ValueError, match=rf"got '{old}' \(arctic's rules changed: it is arctic_v2 now\)"):
            make_env(old)
    assert env_id("arctic") == "arctic_v2"
