import math

from comat import constants as C


def test_derived_limits_match_the_robotarium():
    p = C.GRITSBOT
    assert math.isclose(p.max_wheel_velocity_radps, 12.5)
    assert math.isclose(p.max_angular_velocity_radps, 2 * 0.2 / 0.11)
    assert math.isclose(p.max_turn_rate_radps, 2 * 0.016 * 12.5 / 0.105)
    assert C.GTERNAL.base_length_m == 0.11 and C.GRITSBOT.base_length_m == 0.105
    assert C.ARENA_BOUNDS_M == (-1.6, 1.6, -1.0, 1.0)


def test_safety_geometry_keeps_the_robotarium_test_and_the_bodies_apart():
    # The barrier's points are the Robotarium's offset centres...
    assert C.PROJECTION_DISTANCE_M == C.COLLISION_OFFSET_M
    assert C.SAFETY_DISTANCE_M > C.COLLISION_DIAMETER_M
    # ...and whatever the headings, axle centres stay more than a body diameter apart.
    assert C.SAFETY_DISTANCE_M - 2 * C.PROJECTION_DISTANCE_M > C.GRITSBOT.diameter_m
    # The chassis edge never reaches a wall while the projected point respects the margin.
    assert C.BOUNDARY_MARGIN_M > C.PROJECTION_DISTANCE_M + C.GRITSBOT.radius_m


def test_motor_never_saturates_inside_the_wheel_range():
    assert C.MOTOR_KV_NMS * 2 * C.GRITSBOT.max_wheel_velocity_radps <= C.MOTOR_TORQUE_LIMIT_NM
