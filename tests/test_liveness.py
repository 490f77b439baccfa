"""Liveness beside safety (issue 66): arrivals, team freezes, the dense crossings, the battery's columns."""

from __future__ import annotations

import json
import sys

import numpy as np
import pytest

from comat.bench import CROSSINGS, make_scenario
from comat.bench.liveness import (
    FREEZE_TICKS,
    GOAL_TOLERANCE_M,
    LivenessTracker,
    live_goals,
    row_liveness,
)
from comat.bench.safety_bench import CROSSING_NAMES, liveness_table, run_safety_bench
from comat.config import SafetyConfig
from comat.control import SafeTeams
from comat.reality import RealityConfig


def test_crossings_are_named_and_live_and_start_in_every_levels_safe_set():
    assert set(CROSSING_NAMES) == set(CROSSINGS)
    for name in CROSSING_NAMES:
        scn = make_scenario(name, 6, seed=0)
        assert scn.live, name
        for level in ("nominal", "stress"):
            cfg = SafeTeams((1,), reality=RealityConfig(level=level)).filter_config
            lay_start = 0
            for n in scn.team_sizes:
                p = scn.poses[lay_start : lay_start + n]
                q = p[:, :2] + cfg.projection_distance_m * np.column_stack([np.cos(p[:, 2]), np.sin(p[:, 2])])
                i, j = np.triu_indices(n, 1)
                assert np.hypot(*(q[i] - q[j]).T).min() >= cfg.safety_distance_m, (name, level)
                lay_start += n
    assert not make_scenario("converge16", 2, seed=0).live  # one goal for 16 robots
    assert not make_scenario("walls", 2, seed=0).live  # goals beyond the walls
    assert not make_scenario("bangbang16", 2, seed=0).live


def test_live_goals_needs_spacing_and_margin():
    assert live_goals(np.array([[0.0, 0.0], [0.4, 0.0]]), (2,))
    assert not live_goals(np.array([[0.0, 0.0], [0.2, 0.0]]), (2,))
    assert not live_goals(np.array([[0.0, 0.0], [1.55, 0.0]]), (2,))
    assert live_goals(np.array([[0.0, 0.0], [0.0, 0.0]]), (1, 1))  # one robot per team


def test_tracker_counts_arrivals_and_one_freeze_per_onset():
    goals = np.array([[1.0, 0.0], [-1.0, 0.0], [0.5, 0.5]])
    start = np.array([[0.0, 0.0], [-0.5, 0.0], [0.5, 0.5]])  # robot 2 starts at its goal
    t = LivenessTracker(goals, np.zeros(3, np.int64), 1, start)
    assert t.movers.tolist() == [True, True, False]
    p = start.copy()
    for tick in range(2 * FREEZE_TICKS):  # robot 0 drives to its goal; robot 1 never moves
        p[0, 0] = min(1.0, 0.01 * tick)
        t.update(p)
    assert t.arrival[0] == int(np.ceil((1.0 - GOAL_TOLERANCE_M) / 0.01)) and t.arrival[1] == -1
    # robot 0 stopped at its goal at tick 100; robot 1 still for the whole run: frozen since
    # the window was first full (tick 91), one onset
    assert t.freezes[0] == 1 and t.frozen_ticks[0] == 2 * FREEZE_TICKS - FREEZE_TICKS
    for _ in range(5):  # robot 1 moves: the freeze ends; then stands still again: a second onset
        p[1, 0] += 0.05
        t.update(p)
    for _ in range(FREEZE_TICKS + 2):
        t.update(p)
    assert t.freezes[0] == 2


def test_a_team_whose_movers_all_arrived_is_not_frozen():
    goals = np.array([[0.5, 0.0], [-0.5, 0.0]])
    t = LivenessTracker(goals, np.zeros(2, np.int64), 1, np.zeros((2, 2)) + [[0.0, 0.3], [0.0, -0.3]])
    for _ in range(3 * FREEZE_TICKS):
        t.update(goals)
    assert t.freezes[0] == 0 and (t.arrival == 0).all()


def test_row_liveness_against_off():
    off = [[10, 20, None], [30, -1, 5]]  # episode 0: T_off 20; episode 1: T_off 30 (robot 1 never)
    level = [[15, 39, None], [61, 45, 70]]
    x = row_liveness(level, off, horizon_off=100, ticks=100)
    assert x["1x"] == pytest.approx(1 / 5) and x["2x"] == pytest.approx(3 / 5)
    assert x["by_horizon"] == 1.0 and x["capped"] == 0
    assert row_liveness(level, off, 100, ticks=50)["capped"] == 1


def test_battery_reports_liveness_beside_safety(tmp_path):
    out = tmp_path / "s.json"
    res = run_safety_bench(("nominal", "off"), ("unicycle",), 2, 0, str(out), scenarios=("swap4", "converge16"))
    assert res["levels"] == ["off", "nominal"]  # off first: the reference
    rows = {(r["reality"], r["scenario"]): r for r in res["rows"]}
    assert rows[("off", "converge16")]["live"] is False and "liveness" not in rows[("off", "converge16")]
    off, nom = rows[("off", "swap4")], rows[("nominal", "swap4")]
    # per episode the last arrival at off (its horizon, 300, if none arrived)
    t_off = max(max((t for t in ep if t is not None and t >= 0), default=300) for ep in off["arrival"])
    assert nom["ticks"] == max(2 * t_off + 1, 300)  # the level runs long enough to see 2x
    assert off["liveness"]["1x"] == off["liveness"]["by_horizon"]
    assert 0.0 < nom["liveness"]["2x"] <= 1.0 and nom["freezes"] >= 0
    assert "live_nominal_2x_at_least_90pct_of_off" in res["liveness_targets"]
    assert json.loads(out.read_text())["rows"][0]["arrival"] == off["arrival"]
    assert "`swap4`" in liveness_table(res)


def test_keep_right_turns_only_the_nominal_and_only_clockwise():
    from comat.safety.deployed import KEEP_RIGHT_ANGLE_RAD, KEEP_RIGHT_REACH_M, keep_right

    rng = np.random.default_rng(3)
    i, j = np.triu_indices(2, 1)
    alone = keep_right(np.array([[0.0, 0.0], [KEEP_RIGHT_REACH_M + 0.01, 0.0]]), np.array([[0.2, 0.0], [0.2, 0]]), i, j)
    np.testing.assert_array_equal(alone, [[0.2, 0.0], [0.2, 0.0]])  # out of reach: unchanged
    head_on = keep_right(np.array([[0.0, 0.0], [0.3, 0.0]]), np.array([[0.2, 0.0], [-0.2, 0.0]]), i, j)
    turn = (1 - 0.3 / KEEP_RIGHT_REACH_M) * KEEP_RIGHT_ANGLE_RAD
    np.testing.assert_allclose(head_on[0], 0.2 * np.array([np.cos(turn), -np.sin(turn)]))  # to its right
    np.testing.assert_allclose(head_on[1], -head_on[0])  # both keep right: they pass
    for _ in range(20):  # a crowd: speeds kept, turns clockwise and at most the largest angle
        n = 12
        p, u = rng.uniform(-1, 1, (n, 2)), rng.uniform(-0.2, 0.2, (n, 2))
        a, b = np.triu_indices(n, 1)
        out = keep_right(p, u, a, b)
        np.testing.assert_allclose(np.hypot(*out.T), np.hypot(*u.T))
        cross = u[:, 0] * out[:, 1] - u[:, 1] * out[:, 0]
        assert (cross <= 1e-15).all()
        cos = (u * out).sum(1) / np.maximum(np.hypot(*u.T) ** 2, 1e-30)
        assert (cos >= np.cos(KEEP_RIGHT_ANGLE_RAD) - 1e-12).all()


def test_the_shipped_filter_with_keep_right_still_meets_every_barrier_row():
    """The rule changes the nominal only: what the shipped filter sends meets the portable
    barrier's rows (the same proof), on crowded random teams with robots on probation."""
    from comat.safety.deployed import PortableBarrier, ShippedFilter, si_to_uni, uni_to_si

    settings = SafeTeams((1,), reality=RealityConfig(level="nominal"))._portable.s
    rng = np.random.default_rng(0)
    checked = 0
    for _ in range(30):
        n = 8
        pts = []
        while len(pts) < n:
            q = rng.uniform([-1.3, -0.75], [1.3, 0.75])
            if all(np.hypot(*(q - r)) > 0.26 for r in pts):
                pts.append(q)
        x = np.column_stack([pts, rng.uniform(-np.pi, np.pi, n)]).T
        f = ShippedFilter(n, settings, lag=4)
        f.watch.unresponsive[rng.integers(n)] = True  # a false alarm: an obstacle to the others
        nominal = rng.uniform(-0.15, 0.15, (2, n))
        out = f.command(x, nominal)
        u = uni_to_si(out, x, f.projection).T
        assert f.watch.probation.sum() == 1
        A, b = PortableBarrier(settings).problem(x.T, f.watch.probation, np.zeros(n))
        assert np.all(A @ u.ravel() <= b + 1e-6)
        checked += not np.allclose(si_to_uni(nominal, x, f.projection), out)
    assert checked > 5  # the barrier was active in many of them


def test_a_filter_built_for_one_reality_runs_in_another():
    from comat.reality.margin import response_lag_ticks

    nominal, stress = RealityConfig(level="nominal"), RealityConfig(level="stress")
    built = SafeTeams((3,), reality=stress, filter_reality=nominal)
    matched = SafeTeams((3,), reality=nominal)
    assert built.filter_config == matched.filter_config  # margins and gain of nominal's filter
    assert built.reality.config == stress  # in stress's world
    assert (
        built.watch.lag
        == response_lag_ticks(nominal, built.world.profile)
        < response_lag_ticks(stress, built.world.profile)
    )
    shipped = SafeTeams((3,), safety=SafetyConfig(loop="shipped_v2"), reality=stress, filter_reality=nominal)
    assert shipped.deployed[0].barrier.watch.lag == built.watch.lag


def test_the_wrong_way_robot_executes_its_speed_negated():
    from comat.bench.scenarios import _drive_wrong_way

    teams = SafeTeams((2, 2), reality=RealityConfig(level="nominal", command_loss_prob=0.0))
    seen = []
    teams.reality.actuate = lambda dxu: seen.append(dxu.copy()) or dxu
    _drive_wrong_way(teams, 1)
    cmd = np.full((4, 2), 0.1)
    teams.reality.actuate(cmd)
    teams.reality.actuate(cmd)
    np.testing.assert_array_equal(seen[0], cmd)
    np.testing.assert_array_equal(seen[1][:, 0], [-0.1, 0.1, -0.1, 0.1])  # each team's first robot
    np.testing.assert_array_equal(seen[1][:, 1], 0.1)


def test_mismatch_battery_reports_every_case(tmp_path):
    from comat.bench.safety_bench import MISMATCHES, mismatch_table, run_mismatch

    res = run_mismatch(1, 0, str(tmp_path / "m.json"), scenarios=("swap4",))
    cases = [r["case"] for r in res["rows"]]
    assert cases == ["off", *MISMATCHES]
    assert all(r["liveness"]["2x"] >= 0 for r in res["rows"])
    assert mismatch_table(res).count("`swap4`") == len(MISMATCHES)


def test_a_robot_on_probation_is_handled_by_re_solving_only_the_robots_it_concerns():
    """comat's loop with a false alarm: the fast answer is kept where it meets the portable rows,
    else only the robots in broken rows are re-solved; either way the team's command meets every
    portable row, and a far-away part of the team keeps its fast answer bit for bit."""
    from comat.control import _portable_qp, _resolve_subset
    from comat.safety.deployed import PortableBarrier

    settings = SafeTeams((1,), reality=RealityConfig(level="nominal"))._portable.s
    barrier = PortableBarrier(settings)
    # robots 0 and 1 head-on 0.3 m apart (1 on probation), robots 2 and 3 far away, driving apart
    poses = np.array([[-0.15, 0.0, 0.0], [0.15, 0.0, np.pi], [-1.2, 0.6, 0.0], [1.2, -0.6, np.pi]])
    probation = np.array([False, True, False, False])
    u_fast = np.array([[0.1, 0.0], [-0.1, 0.0], [0.05, 0.0], [-0.05, 0.0]])  # cooperative: each closes in
    A, b = barrier.problem(poses, probation, np.zeros(4))
    broken = A @ u_fast.ravel() > b + 1e-4
    assert broken.any()
    out = _resolve_subset(_portable_qp, A, b, u_fast.ravel(), u_fast.ravel(), broken, 1e-4)
    assert out is not None and np.all(A @ out <= b + 1e-4)
    np.testing.assert_array_equal(out[4:], u_fast.ravel()[4:])  # robots 2 and 3 untouched
    assert out[2] <= 1e-6  # the robot on probation may not close in


def test_the_exported_filter_keeps_right_as_comats_own_loop_does(tmp_path, monkeypatch):
    """An export's filter keeps right only where comat's loop does, under a reality layer: made for
    ``off`` it does not (issue 66: the 20-robot HMT export made for ``off`` then plays as comat's
    loop at ``off``, results/deployed/README.md); a folder from before the key keeps right."""
    import runpy
    from types import SimpleNamespace

    from comat.cli.args import parse_team
    from sim2real.export import export_submission

    for level, right in (("off", False), ("nominal", True), (None, True)):
        folder = tmp_path / str(level)
        team = parse_team("test:3", "pcp")
        export_submission(
            "heuristic", "pcp", team, folder, seed=1, filter_name="comat", filter_reality=level or "stress"
        )
        if level is None:  # a folder exported before filter_keep_right existed
            config = folder / "submission_config.py"
            config.write_text(config.read_text().replace("'filter_keep_right': True,", ""))
            assert "filter_keep_right" not in config.read_text()
        monkeypatch.syspath_prepend(str(folder))
        main = runpy.run_path(str(folder / "main.py"), run_name="exported_main")
        assert main["CONFIG"].get("filter_keep_right", True) is right
        loop = main["make_loop"](SimpleNamespace(si_to_uni=None, barrier=None, generation="legacy"), 4, (0.016, 0.105))
        assert loop.barrier.keep_right is right, level
        for name in ("submission_config", "deployed_loop", "main"):
            sys.modules.pop(name, None)
