import numpy as np
import pytest

from comat import constants as C
from comat.sim import kinematics as K


def test_uni_diff_round_trip(rng):
    dxu = rng.uniform(-1, 1, (5, 7, 2))
    np.testing.assert_allclose(K.diff_to_uni(K.uni_to_diff(dxu)), dxu, atol=1e-12)


def test_wheel_mapping_matches_rps_formula():
    v, w = 0.1, 1.5
    left, right = K.uni_to_diff(np.array([v, w]))
    l, r = C.GRITSBOT.base_length_m, C.GRITSBOT.wheel_radius_m
    assert left == pytest.approx((2 * v - l * w) / (2 * r))
    assert right == pytest.approx((2 * v + l * w) / (2 * r))


def test_threshold_clips_each_wheel_and_flags_overrun():
    dxu = np.array([[0.2, 0.0], [0.2, 1.0], [0.05, 0.5], [0.0, -10.0]])
    out, over = K.threshold_wheels(dxu)
    wheels = K.uni_to_diff(out)
    assert np.all(np.abs(wheels) <= 12.5 + 1e-9)
    np.testing.assert_array_equal(over, [False, True, False, True])
    np.testing.assert_allclose(out[[0, 2]], dxu[[0, 2]])
    # Per-wheel clipping (current rps), not arc-preserving scaling: the turn is partly erased.
    assert out[1, 1] < 1.0 and out[1, 0] < 0.2


def test_si_uni_maps_are_inverse(rng):
    poses = rng.uniform(-1, 1, (9, 3))
    dxi = rng.uniform(-0.2, 0.2, (9, 2))
    dxu = K.si_to_uni(dxi, poses, 0.025)
    np.testing.assert_allclose(K.uni_to_si(dxu, poses, 0.025), dxi, atol=1e-12)


def test_si_to_uni_is_the_projection_point_map():
    pose = np.array([[0.0, 0.0, np.pi / 2]])
    # Moving the point sideways (to -x, i.e. to the robot's left) is pure rotation.
    dxu = K.si_to_uni(np.array([[-0.05, 0.0]]), pose, 0.025)
    np.testing.assert_allclose(dxu, [[0.0, 2.0]], atol=1e-12)


def test_euler_step_is_the_robotarium_integration():
    pose = np.array([0.1, -0.2, 3.1])
    nxt = K.euler_unicycle_step(pose, np.array([0.2, 2.0]))
    assert nxt[0] == pytest.approx(0.1 + 0.033 * 0.2 * np.cos(3.1))
    assert nxt[1] == pytest.approx(-0.2 + 0.033 * 0.2 * np.sin(3.1))
    assert nxt[2] == pytest.approx(np.arctan2(np.sin(3.1 + 0.066), np.cos(3.1 + 0.066)))
