"""Liveness beside safety (issue 66): arrivals, team freezes, the dense crossings, the battery's columns."""

from __future__ import annotations

import json

import numpy as np
import pytest

from comat.bench.liveness import (
    FREEZE_TICKS,
    GOAL_TOLERANCE_M,
    LivenessTracker,
    live_goals,
    row_liveness,
)
from comat.bench.safety_bench import CROSSING_NAMES, liveness_table, run_safety_bench
from comat.bench.scenarios import CROSSINGS, make_scenario
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
