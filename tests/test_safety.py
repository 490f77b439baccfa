import dataclasses

import numpy as np
import pytest
import scipy.sparse as sp

from comat import constants as C
from comat.bench.scenarios import SCENARIOS, make_scenario, run_scenario
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


def test_infeasible_start_falls_back_to_braking_and_is_counted():
    teams = SafeTeams((2, 2), SimConfig(tier="unicycle"))
    # Team 0: face to face with the projected points 0.07 m apart (inside d_s = 0.2), driving
    # in; no velocity within the wheel limits can satisfy the barrier. Team 1 is fine.
    poses = np.array([[-0.06, 0, 0], [0.06, 0, np.pi], [-0.5, 0.6, 0], [0.5, 0.6, np.pi]])
    teams.reset(poses)
    _ev, info = teams.tick(np.array([[0.1, 0], [-0.1, 0], [0.1, 0], [-0.1, 0]]))
    assert info.fallback.tolist() == [True, False]
    assert teams.fallbacks.tolist() == [1, 0]
    np.testing.assert_allclose(teams.poses[:2], poses[:2], atol=1e-9)  # braked: did not move
    assert teams.poses[2, 0] > -0.5


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


@pytest.mark.parametrize("tier", ["unicycle", "wheels"])
@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_scenarios_are_safe_quick(name, tier):
    episodes = 4 if name == "converge32" else 12
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
