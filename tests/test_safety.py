import dataclasses

import numpy as np
import pytest
import scipy.sparse as sp

from comat import constants as C
from comat.bench import SCENARIOS, make_scenario, run_scenario
from comat.config import SafetyConfig, SimConfig
from comat.control import SafeTeams
from comat.safety import InfeasibleError, SafetyFilter
from comat.safety.constraints import make_layout, reference_rows, row_values
from comat.sim.kinematics import projected_points, uni_to_diff


def test_vectorized_rows_equal_the_loop_reference(rng):
    sizes = (3, 1, 5, 2)
    R = sum(sizes)
    pts, hd = rng.uniform(-1, 1, (R, 2)), rng.uniform(-3, 3, R)
    cfg = SafetyConfig()
    lay = make_layout(sizes)
    vals = row_values(lay, pts, hd, cfg, C.GRITSBOT)
    A = sp.coo_matrix((vals.data(), (lay.rows, lay.cols)), shape=(lay.n_rows, 2 * R)).toarray()
    A_ref, lo_ref, up_ref = reference_rows(sizes, pts, hd, cfg, C.GRITSBOT)
    np.testing.assert_allclose(A, A_ref, atol=1e-15)
    u = rng.uniform(-0.2, 0.2, 2 * R)
    np.testing.assert_allclose(vals.products(u), A_ref @ u, atol=1e-14)
    np.testing.assert_array_equal(vals.lower, lo_ref)
    np.testing.assert_allclose(vals.upper, up_ref, atol=1e-15)


def test_safe_command_comes_back_unchanged(rng):
    f = SafetyFilter(3)
    poses = np.array([[-0.8, 0.0, 0.0], [0.0, 0.5, 1.0], [0.7, -0.3, 2.0]])
    dxu = np.array([[0.1, 0.5], [-0.05, 1.0], [0.15, -0.2]])
    out, info = f.filter_unicycle(poses, dxu)
    assert np.max(np.abs(out - dxu)) < 1e-4  # the requirement; in fact exactly equal:
    np.testing.assert_array_equal(out, dxu)
    assert info.status == "skipped" and info.intervention[0] == 0.0


def test_filter_output_respects_every_row_and_wheel_limits(rng):
    f = SafetyFilter((4, 4))
    poses = np.array([[-0.17, 0, 0], [0.17, 0, np.pi], [0, 0.17, -np.pi / 2], [0, -0.17, np.pi / 2]] * 2)
    poses[4:, 0] += 0.9
    dxu = np.tile([[0.2, 0.0]], (8, 1))
    out, info = f.filter_unicycle(poses, dxu)
    assert (info.active_pairs > 0).all() and not info.fallback.any()
    assert np.all(np.abs(uni_to_diff(out)) <= 12.5 + 1e-9)
    # Barrier rows hold: ḣ >= -γh for every pair of the filtered velocities.
    d = f.config.projection_distance_m
    pts = projected_points(poses, d)
    from comat.sim.kinematics import uni_to_si

    u = uni_to_si(out, poses, d)
    for b in range(2):
        for i in range(4 * b, 4 * b + 4):
            for j in range(i + 1, 4 * b + 4):
                e = pts[i] - pts[j]
                h = e @ e - f.config.safety_distance_m**2
                assert 2 * e @ (u[i] - u[j]) >= -f.config.barrier_gain * h - 1e-6


def test_infeasible_start_recovers_and_only_a_failed_solver_brakes():
    """Team 0 starts face to face with the projected points 0.07 m apart (inside d_s = 0.2),
    driving in: no command meets its hard rows. It takes the softened problem's answer (a
    recovery tick, counted) and moves apart; team 1 is untouched. Only when that solver fails
    too does the team brake (a fallback tick)."""
    from unittest import mock

    from comat.safety import filter as filter_module

    poses = np.array([[-0.06, 0, 0], [0.06, 0, np.pi], [-0.5, 0.6, 0], [0.5, 0.6, np.pi]])
    dxi = np.array([[0.1, 0], [-0.1, 0], [0.1, 0], [-0.1, 0]])
    teams = SafeTeams((2, 2), SimConfig(tier="unicycle"))
    teams.reset(poses)
    _ev, info = teams.tick(dxi)
    assert info.recovery.tolist() == [True, False] and not info.fallback.any()
    assert teams.recoveries.tolist() == [1, 0] and teams.fallbacks.tolist() == [0, 0]

    def gap(p):
        return np.linalg.norm(projected_points(p[:2], 0.05)[0] - projected_points(p[:2], 0.05)[1])

    assert gap(teams.poses) > gap(poses)  # moved apart, against the nominal command
    assert teams.poses[2, 0] > -0.5
    teams.reset(poses)
    with mock.patch.object(filter_module, "recovery_command", return_value=None):
        _ev, info = teams.tick(dxi)
    assert info.fallback.tolist() == [True, False] and not info.recovery.any()
    assert teams.fallbacks.tolist() == [1, 0]
    np.testing.assert_allclose(teams.poses[:2], poses[:2], atol=1e-9)  # braked: did not move


def _run(teams, dxi_of, seconds):
    """Ticks of nominal velocities ``dxi_of(teams)`` for ``seconds``; minimum projected-point
    distance of the team's pairs at the end and MuJoCo robot-robot contact ticks."""
    for _ in range(round(seconds / C.CONTROL_DT_S)):
        teams.tick(dxi_of(teams))
    lay = teams.world.layout
    p = teams.points
    d = np.linalg.norm(p[lay.pair_i] - p[lay.pair_j], axis=1)
    return d.min(), int(teams.world.violations.per_team("contact_ticks").sum())


@pytest.mark.parametrize("tier", ["unicycle", "wheels"])
@pytest.mark.parametrize("direction", ["apart", "toward"])
def test_pair_started_inside_the_safety_distance_separates(tier, direction):
    """Centres 0.2 m apart, facing each other: projected points 0.1 m apart, inside d_s. Commanded
    apart or toward each other, they reach d_s within 2 s, never touching."""
    teams = SafeTeams([2], SimConfig(tier=tier))
    teams.reset(np.array([[-0.1, 0, 0.0], [0.1, 0, np.pi]]))
    sign = 1.0 if direction == "apart" else -1.0
    d, contacts = _run(teams, lambda t: np.array([[-0.2 * sign, 0.0], [0.2 * sign, 0.0]]), 2.0)
    assert d >= teams.safety_config.safety_distance_m - 1e-3 and contacts == 0
    assert teams.recoveries[0] > 0 and teams.fallbacks[0] == 0


def test_ring_of_20_started_inside_the_safety_distance_separates():
    """20 robots on a ring 0.15 m apart (inside d_s), all driven through the centre."""
    n = 20
    radius = 0.15 / (2 * np.sin(np.pi / n))
    a = np.linspace(0, 2 * np.pi, n, endpoint=False)
    teams = SafeTeams([n], SimConfig(tier="unicycle"))
    teams.reset(np.stack([radius * np.cos(a), radius * np.sin(a), a + np.pi], axis=1))
    d, contacts = _run(teams, lambda t: 0.2 * (-t.points / np.linalg.norm(t.points, axis=1, keepdims=True)), 3.0)
    assert contacts == 0 and teams.fallbacks[0] == 0 and teams.recoveries[0] > 0
    assert d >= teams.safety_config.safety_distance_m - 1e-3


def test_robot_inside_the_boundary_margin_moves_inward():
    """A projected point 0.05 m from the wall (inside the 0.1 m margin), commanded inward."""
    x1 = C.ARENA_BOUNDS_M[1]
    teams = SafeTeams([1], SimConfig(tier="unicycle"))
    teams.reset(np.array([[x1 - 0.05 - teams.safety_config.projection_distance_m, 0.0, 0.0]]))
    x0 = teams.points[0, 0]
    for _ in range(15):
        teams.tick(np.array([[-0.2, 0.0]]))
    assert teams.points[0, 0] < x0 - 0.02 and teams.fallbacks[0] == 0


@pytest.mark.parametrize("size", [1e3, 1e15, 1e150, 1e300])
def test_huge_commands_never_brake(size):
    """A ring of 20 robots 0.25 m apart with random commands of this size, redrawn every 10 ticks
    (commands far beyond the wheels are saturated to them before the filter)."""
    n = 20
    radius = 0.25 / (2 * np.sin(np.pi / n))
    a = np.linspace(0, 2 * np.pi, n, endpoint=False)
    for seed in range(2):
        rng = np.random.default_rng(seed)
        teams = SafeTeams([n], SimConfig(tier="unicycle"))
        teams.reset(np.stack([radius * np.cos(a), radius * np.sin(a), a + np.pi], axis=1))
        for k in range(40):
            if k % 10 == 0:
                direction = rng.standard_normal((n, 2))
            teams.tick(size * direction)
        assert teams.fallbacks[0] == 0 and teams.recoveries[0] == 0
        assert int(teams.world.violations.per_team("contact_ticks").sum()) == 0


def test_strict_mode_raises_a_clear_error():
    f = SafetyFilter(2, SafetyConfig(strict=True))
    poses = np.array([[-0.06, 0, 0], [0.06, 0, np.pi]])
    with pytest.raises(InfeasibleError, match=r"team 0: closest projected points robots 0 and 1 at 0.070 m"):
        f.filter_unicycle(poses, np.array([[0.1, 0.0], [0.1, 0.0]]))


def test_bad_filter_inputs():
    f = SafetyFilter(2)
    with pytest.raises(ValueError, match=r"poses must have shape \(2, 3\), got shape \(3, 3\)"):
        f.filter(np.zeros((3, 3)), np.zeros((2, 2)))
    with pytest.raises(ValueError, match=r"dxi must be finite, got nan at index \(0, 1\)"):
        f.filter(np.array([[0, 0, 0], [1, 0, 0]]), np.array([[0, np.nan], [0, 0]]))
    with pytest.raises(ValueError, match=r"team_sizes must be positive integers, got \(2, 0\)"):
        SafetyFilter((2, 0))
    with pytest.raises(ValueError, match=r"SafetyConfig.barrier_gain must be a positive finite number, got -1"):
        SafetyConfig(barrier_gain=-1)
    with pytest.raises(ValueError, match=r"gains must satisfy gain \* 0.033 s < 1"):
        SafetyConfig(barrier_gain=40.0)


def _check(result, name):
    assert result.robot_contacts.sum() == 0, f"{name}: MuJoCo robot-robot contacts"
    assert result.robotarium_collisions.sum() == 0, f"{name}: Robotarium-style collisions"
    assert result.boundary_exits.sum() == 0, f"{name}: boundary exits"
    assert result.wall_contacts.sum() == 0, f"{name}: wall contacts"
    assert result.actuator_errors.sum() == 0, f"{name}: actuator errors"
    assert (result.interventions > 0).all(), f"{name}: the filter never intervened in some episode"
    assert result.min_centre_distance.min() > C.GRITSBOT.diameter_m
    # Started inside the safe set, teams stay in it: never a recovery tick, never a brake.
    ticks = result.interventions.size * make_scenario(name, 1, seed=0).ticks
    print(
        f"{name}: brake share {result.fallbacks.sum() / ticks:.2e}, "
        f"recovery share {result.recoveries.sum() / ticks:.2e} "
        f"of {ticks} team-ticks"
    )
    assert result.fallbacks.sum() == 0 and result.recoveries.sum() == 0, f"{name}: brakes or recoveries"


@pytest.mark.parametrize("tier", ["unicycle", "wheels"])
@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_scenarios_are_safe_quick(name, tier):
    # about 100-200 robot-episodes each (the slow suite below plays 200 episodes of every scenario)
    episodes = {"converge32": 4, "ring20": 6}.get(name, 12)
    _check(run_scenario(make_scenario(name, episodes, seed=1), SimConfig(tier=tier)), name)


@pytest.mark.slow
@pytest.mark.parametrize("tier", ["unicycle", "wheels"])
@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_scenarios_are_safe_200_episodes(name, tier):
    _check(run_scenario(make_scenario(name, 200, seed=2), SimConfig(tier=tier)), name)


def test_safety_config_is_replaceable():
    cfg = dataclasses.replace(SafetyConfig(), safety_distance_m=0.25)
    assert cfg.safety_distance_m == 0.25


def test_wheel_projection_is_the_qp_optimum_when_only_wheel_rows_bind(rng):
    """Stage 2 (closed-form projection) against OSQP on the same problem (the slow reference)."""
    from comat.safety.qp import BarrierQP

    f = SafetyFilter(3)
    poses = np.array([[-1.0, 0.0, 0.3], [0.0, 0.5, -2.0], [1.0, -0.4, 2.5]])  # far apart
    for _ in range(20):
        dxi = rng.uniform(-0.5, 0.5, (3, 2))
        fast = f._project_wheels(dxi.ravel(), np.cos(poses[:, 2]), np.sin(poses[:, 2]))
        qp = BarrierQP((3,), SafetyConfig(eps=1e-9), C.GRITSBOT)
        vals = qp.rows(projected_points(poses, 0.025), poses[:, 2])
        res = qp.solve(qp.matrix(vals.data()), vals, dxi.ravel())
        np.testing.assert_allclose(fast, res.x, atol=1e-7)
        out, info = f.filter(poses, dxi)
        np.testing.assert_allclose(out.ravel(), fast, atol=1e-12)
        assert info.status == "skipped"


@pytest.mark.parametrize("tie_break", [True, False])
def test_head_on_deadlock_is_broken_by_keeping_right(tie_break):
    """U_test coalition 1 (a sensing and a capture robot), scripted policy, the env's start for
    seed 1, MuJoCo wheels tier: the two meet head-on on one line and the barrier holds both still
    for the rest of the episode (4 of 6 prey) unless the tie-break turns them to their right."""
    from unittest import mock

    from comat.envs import make_env
    from comat.envs.base import resolve_coalitions
    from comat.envs.heuristics import heuristic_actions
    from comat.safety import deployed

    env = make_env("pcp_v0", team=resolve_coalitions("test", "pcp")[1], tier="wheels")
    with mock.patch.object(deployed, "HOLD_TICKS", deployed.HOLD_TICKS if tie_break else 10**9):
        env.reset(seed=1)
        while True:
            res = env.core.step(heuristic_actions(env.core))
            if res.terminated[0] or res.truncated[0]:
                break
    metrics = env.core.episode_metrics(0)
    assert metrics["collisions"] == 0 and metrics["fallbacks"] == 0
    assert metrics["finished"] == (1.0 if tie_break else 0.0)
    assert metrics["progress"] == (1.0 if tie_break else pytest.approx(4 / 6))


@pytest.mark.slow
def test_soak_bench_one_round_is_clean(tmp_path):
    """``comat bench soak`` for one round (160 episodes, some in the wheels tier): every safety
    count zero, no NaN, the JSON written."""
    from comat.bench import run_soak

    result = run_soak(160, wheels_share=0.5, seed=1, out=str(tmp_path / "soak.json"), progress=lambda m: None)
    assert result["episodes"] == 160 and all(c["pass"] for c in result["checks"].values()), result["checks"]
    assert (tmp_path / "soak.json").is_file() and result["scripted_finished_share"] > 0.8
    # one sample per batch of 20 coalitions after it, one of its peak; a batch peaks above where it ends
    assert [d for d, _ in result["rss_bytes_per_batch"]] == list(range(20, 161, 20))
    peaks = result["rss_peak_bytes_per_batch"]
    assert [d for d, _ in peaks] == list(range(20, 161, 20))
    assert all(after <= peak for (_, after), (_, peak) in zip(result["rss_bytes_per_batch"], peaks))
    # a one-round run's first and last windows are the same
    assert set(result["rss_bytes"]) <= set(result["rss_bytes_per_batch"])
    assert result["rss_windows"]["first"] == result["rss_windows"]["last"]


def test_soak_memory_windows_see_drift_not_swings():
    """The soak's memory check compares the median and peak of the first and last thousand
    episodes' samples: a run whose samples swing between two levels does not grow, one whose
    floor and ceiling creep up by 10 % does."""
    from comat.bench.soak import _first_and_last_thousand, _growth

    mib = 2**20
    swings = [(20 * i, (300 if i % 3 else 330) * mib) for i in range(1, 501)]
    first, last = _first_and_last_thousand(swings, 1000)
    assert first["samples"] == last["samples"] == 50
    assert abs(_growth(first["median"], last["median"])) < 0.01 and _growth(first["peak"], last["peak"]) == 0
    creep = [(d, rss * (1 + 0.1 * d / 10_000)) for d, rss in swings]
    first, last = _first_and_last_thousand(creep, 1000)
    assert _growth(first["median"], last["median"]) > 0.08 and _growth(first["peak"], last["peak"]) > 0.08
