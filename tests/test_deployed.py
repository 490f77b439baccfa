"""The deployed loop (comat.safety.deployed): the Robotarium's barrier as comat runs it equals the
real rps functions (legacy from PyPI here; the 2026 V2 simulator with ``COMAT_RPS_V2=<checkout>``),
and the loop's pieces do what main.py does."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from comat.safety.deployed import (
    DeployedLoop,
    robotarium_barrier,
    robotarium_loop,
    wheel_projected,
    wheel_scaled,
)

V2 = os.environ.get("COMAT_RPS_V2")

COMPARE = textwrap.dedent("""
    import sys, numpy as np
    from comat.safety.deployed import robotarium_barrier, si_to_uni
    gen = sys.argv[1]
    from rps.utilities import barrier_certificates as bc
    from rps.utilities.transformations import create_si_to_uni_mapping
    real = (bc.create_uni_barrier_certificate_with_boundary() if gen == "v2"
            else bc.create_unicycle_barrier_certificate_with_boundary())
    mine = robotarium_barrier(gen)
    rng = np.random.default_rng(0)
    worst = worst_map = 0.0
    for trial in range(120):
        n = int(rng.choice([1, 2, 3, 5, 8, 12, 20]))
        pts = rng.uniform([-1.5, -0.9], [1.5, 0.9], (n, 2)) * rng.choice([1.0, 0.3])  # crowded half the time
        x = np.vstack([pts.T, rng.uniform(-np.pi, np.pi, n)])
        dxu = np.vstack([rng.uniform(-0.2, 0.2, n), rng.uniform(-3, 3, n)])
        worst = max(worst, np.abs(real(dxu.copy(), x.copy()) - mine(dxu.copy(), x.copy())).max())
        dxi = rng.uniform(-0.2, 0.2, (2, n))
        mapped = create_si_to_uni_mapping(projection_distance=0.025)[0](dxi, x)
        worst_map = max(worst_map, np.abs(mapped - si_to_uni(dxi, x, 0.025, None if gen == "v2" else np.pi)).max())
    print(worst, worst_map, mine.failures)
""")


def _compare(generation: str, rps_path: str | None) -> tuple[float, float, int]:
    env = {**os.environ, "PYTHONWARNINGS": "ignore"}
    env.pop("PYTHONPATH", None)
    if rps_path:
        env["PYTHONPATH"] = rps_path
    out = subprocess.run(
        [sys.executable, "-c", COMPARE, generation], env=env, capture_output=True, text=True, check=True, timeout=600
    ).stdout.split()
    return float(out[0]), float(out[1]), int(out[2])


def test_legacy_barrier_equals_the_real_rps():
    """120 random teams of 1-20 robots, half of them crowded so that pair rows bind."""
    pytest.importorskip("rps.utilities.barrier_certificates")
    barrier, mapping, _ = _compare("legacy", None)
    assert barrier < 1e-9 and mapping < 1e-12


@pytest.mark.skipif(not V2, reason="set COMAT_RPS_V2 to a robotarium_python_simulator (V2) checkout")
def test_v2_barrier_equals_the_real_rps():
    barrier, mapping, failures = _compare("v2", V2)
    assert barrier < 1e-9 and mapping < 1e-12
    assert failures > 0  # crowded starts: V2's QP fails and it commands zeros, so do we


def test_v2_octagon_caps_the_points_speed_and_one_robot_passes():
    b = robotarium_barrier("v2")
    x = np.array([[0.0], [0.0], [0.3]])
    dxu = np.array([[0.2], [1.0]])
    assert np.array_equal(b(dxu, x), dxu)  # V2 returns a single robot's command unchanged
    rng = np.random.default_rng(1)
    x = np.vstack([np.array([[-1.0, 0.0, 1.0], [0.0, 0.5, -0.5]]), rng.uniform(-np.pi, np.pi, 3)])
    out = b(np.vstack([np.full(3, 0.2), np.zeros(3)]), x)
    points = out[0] ** 2 + (0.03 * out[1]) ** 2
    assert np.all(np.sqrt(points) <= 0.2 + 1e-3)  # inside the octagon (apothem 0.185, vertex 0.2)
    assert np.all(np.sqrt(points) >= 0.185 - 1e-2)


def test_legacy_barrier_clips_the_turn_rate():
    b = robotarium_barrier("legacy")
    x = np.array([[0.0, 1.0], [0.0, 0.0], [0.0, 0.0]])
    out = b(np.array([[0.0, 0.0], [12.0, -12.0]]), x)
    assert np.all(np.abs(out[1]) <= np.pi + 1e-12)


def test_wheel_scaling_keeps_the_direction_and_the_limit():
    dxu = np.array([[0.2, 0.1, 0.0], [0.0, 5.0, 20.0]])
    out = wheel_scaled(dxu, 0.016, 0.105, 12.5)
    wheels = np.abs(np.vstack([2 * out[0] - 0.105 * out[1], 2 * out[0] + 0.105 * out[1]]) / 0.032)
    assert wheels.max() <= 12.5 + 1e-12
    assert np.allclose(out[0] * dxu[1], out[1] * dxu[0])  # v and ω scaled together


def test_the_shipped_wheel_projection_is_comats():
    """deployed.wheel_projected (numpy only, shipped) equals comat's limit_to_wheels (the envs'
    controller saturation, compiled twin included) on random commands and headings."""
    from comat import constants as C
    from comat.sim.kinematics import limit_to_wheels

    rng = np.random.default_rng(3)
    poses = np.column_stack([rng.uniform(-1, 1, (500, 2)), rng.uniform(-np.pi, np.pi, 500)])
    dxi = rng.normal(0.0, 0.3, (500, 2))
    p = C.DEFAULT_PROFILE
    ours = wheel_projected(dxi.T, poses.T, 0.025, p.wheel_radius_m, p.base_length_m, p.max_wheel_velocity_radps).T
    np.testing.assert_allclose(ours, limit_to_wheels(dxi, poses, 0.025, p), rtol=0, atol=1e-14)
    assert (np.abs(ours - dxi) > 1e-9).any(axis=1).sum() > 100  # many were outside the rhombus


def test_the_loop_steers_toward_its_waypoints():
    loop = robotarium_loop("v2")
    assert isinstance(loop, DeployedLoop)
    x = np.array([[-1.0, 1.0], [0.0, 0.0], [0.0, np.pi]])
    u = loop.command(x, np.array([[-0.5, 0.5], [0.0, 0.0]]))
    assert u[0, 0] > 0.1 and u[0, 1] > 0.1 and np.all(np.abs(u[1]) < 1e-6)  # straight ahead, both
    with pytest.raises(ValueError, match=r"generation must be one of \['v2', 'legacy'\], got 'v3'"):
        robotarium_barrier("v3")


def test_envs_and_runs_take_the_deployed_loop():
    """make_env(..., safety=SafetyConfig(loop=...)) steps the exported script's loop in comat's tick;
    a training run takes it as the run key ``loop`` (a bad one is a one-line error)."""
    from comat.config import SafetyConfig
    from comat.envs import make_env
    from comat.envs.heuristics import heuristic_actions
    from comat.rl import apply_overrides, resolve

    for loop in ("robotarium_v2", "shipped_legacy"):
        env = make_env("pcp_v0", coalitions="test", tier="unicycle", ticks_per_step=10, safety=SafetyConfig(loop=loop))
        env.reset(seed=1)
        assert env.core.safe.deployed is not None
        start = env.core.poses().copy()
        for _ in range(4):
            act = heuristic_actions(env.core)[0]
            env.step({a: int(act[i]) for i, a in enumerate(env.agents)})
        assert np.abs(env.core.poses() - start).max() > 0.05
        assert env.core.episode_metrics(0)["robotarium_collisions"] == 0
    config = resolve(apply_overrides({}, ["loop=shipped_v2"]), "comat", "pcp")
    assert config.loop == "shipped_v2" and config.to_dict()["loop"] == "shipped_v2"
    with pytest.raises(ValueError, match=r"loop must be one of .*'robotarium_v2'.*got 'robotarium_v3'"):
        resolve(apply_overrides({}, ["loop=robotarium_v3"]), "comat", "pcp")
    with pytest.raises(ValueError, match=r"SafetyConfig.loop must be one of"):
        SafetyConfig(loop="rps")
