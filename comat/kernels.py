"""Compiled twins (numba) of the per-tick numpy functions, equal to them bit for bit.

Why: a control tick of 16–32 teams costs ~300 small numpy calls whose fixed cost (1–5 µs each)
outweighs their arithmetic. Each kernel here repeats its numpy reference's arithmetic in the
same order, without fast-math (so no reassociation or fused multiply-adds): results are
identical, not merely close (``tests/test_kernels.py`` checks every twin against its
reference on random inputs, and whole env rollouts with and without kernels). Cosines, sines
and arctangents stay in numpy, whose SIMD versions may round differently from libm.

The numpy functions remain the reference and the general path (any leading batch
dimensions); the kernels take the flat (R, ·) arrays of the per-tick code. Set
``COMAT_KERNELS=0`` in the environment, or use :func:`reference_path`, to run numpy only.
The barrier filter's twins stand beside it, in :mod:`comat.safety.kernels`; the reality layer's in
:mod:`comat.reality.kernels`.

Shapes: R robots, P same-team pairs, B teams, S simulations of one group of n robots each.
"""

from __future__ import annotations

import contextlib
import math
import os
from collections.abc import Iterator

import numpy as np
from numba import njit

__all__ = [
    "check_and_count",
    "check_tick_into",
    "enabled",
    "episode_stats_add",
    "group_ctrl",
    "group_read",
    "limit_to_wheels",
    "reference_path",
    "si_to_uni",
    "si_to_wheels",
    "threshold_wheels",
    "violations_add",
    "waypoint_nominal",
]

_enabled = os.environ.get("COMAT_KERNELS", "1") != "0"


def enabled() -> bool:
    """True when the per-tick code uses the compiled kernels."""
    return _enabled


@contextlib.contextmanager
def reference_path() -> Iterator[None]:
    """Run the numpy reference functions inside the block (tests, debugging)."""
    global _enabled
    before, _enabled = _enabled, False
    try:
        yield
    finally:
        _enabled = before


_jit = njit(cache=True, nogil=True)


# -- kinematics ----------------------------------------------------------------------------------
@_jit
def _limit_one(ux, uy, c, s, k, v):
    a = c * ux + s * uy
    b = c * uy - s * ux
    pa, pb = abs(a), abs(b)
    if pa + k * pb > v:
        t = ((v - pa) * v + pb * v / k) / (v * v * (1.0 + 1.0 / (k * k)))
        t = min(max(t, 0.0), 1.0)
        pa = v - t * v
        pb = t * v / k
    a = math.copysign(pa, a)
    b = math.copysign(pb, b)
    return c * a - s * b, s * a + c * b


@_jit
def limit_to_wheels(u, c, s, k, v, out):
    """:func:`comat.sim.kinematics.limit_to_wheels` for u (R, 2) into out (R, 2)."""
    for r in range(u.shape[0]):
        out[r, 0], out[r, 1] = _limit_one(u[r, 0], u[r, 1], c[r], s[r], k, v)


@_jit
def waypoint_nominal(points, poses, c, s, goals, gain, distance, max_speed, k, v, out):
    """:func:`comat.control.waypoint_controller` (go-to-goal, then the wheel limit) into out (R, 2).

    points (R, 2), or None for the points ``distance`` ahead of poses (R, 3).
    """
    for r in range(poses.shape[0]):
        if points is None:
            px = poses[r, 0] + distance * c[r]
            py = poses[r, 1] + distance * s[r]
        else:
            px, py = points[r, 0], points[r, 1]
        dx = gain * (goals[r, 0] - px)
        dy = gain * (goals[r, 1] - py)
        f = min(1.0, max_speed / max(math.sqrt(dx * dx + dy * dy), 1e-12))
        out[r, 0], out[r, 1] = _limit_one(dx * f, dy * f, c[r], s[r], k, v)


@_jit
def si_to_uni(dxi, c, s, distance, out):
    """:func:`comat.sim.kinematics.si_to_uni` for dxi (R, 2) into out (R, 2)."""
    for r in range(dxi.shape[0]):
        dx, dy = dxi[r, 0], dxi[r, 1]
        out[r, 0] = c[r] * dx + s[r] * dy
        out[r, 1] = (-s[r] * dx + c[r] * dy) / distance


@_jit
def threshold_wheels(dxu, wheel_radius, half_length, length, limit, tolerance, out, overrun):
    """:func:`comat.sim.kinematics.threshold_wheels`; returns True if any wheel overran."""
    any_over = False
    bound = limit * tolerance
    for r in range(dxu.shape[0]):
        v, w = dxu[r, 0], dxu[r, 1]
        left = (v - half_length * w) / wheel_radius
        right = (v + half_length * w) / wheel_radius
        over = abs(left) > bound or abs(right) > bound
        overrun[r] = over
        if over:
            any_over = True
            left = min(max(left, -limit), limit)
            right = min(max(right, -limit), limit)
            out[r, 0] = wheel_radius * (left + right) / 2.0
            out[r, 1] = wheel_radius * (right - left) / length
        else:
            out[r, 0], out[r, 1] = v, w
    return any_over


@_jit
def si_to_wheels(dxi, c, s, distance, wheel_radius, half_length, length, limit, tolerance, dxu, clipped, overrun):
    """:func:`si_to_uni` then :func:`threshold_wheels` (the unicycle command dxu (R, 2) and what
    the wheels realize of it, clipped (R, 2)); returns True if any wheel overran."""
    si_to_uni(dxi, c, s, distance, dxu)
    return threshold_wheels(dxu, wheel_radius, half_length, length, limit, tolerance, clipped, overrun)


# -- physics bindings ----------------------------------------------------------------------------
@_jit
def group_ctrl(dxu, rows, sims, unicycle, half_h, lateral_gain, wheel_radius, half_length, ctrl):
    """:meth:`comat.sim.binding.Binding.ctrl` of the robots at ``rows`` (S, n), written into rows
    ``sims`` (S,) of the batch's ctrl (nsim, nu)."""
    for i in range(rows.shape[0]):
        out = ctrl[sims[i]]
        for j in range(rows.shape[1]):
            v, w = dxu[rows[i, j], 0], dxu[rows[i, j], 1]
            if unicycle:
                a = half_h * w
                a2 = a * a
                sinc_a = 1.0 - a2 * (1.0 / 6.0 - a2 * (1.0 / 120.0 - a2 / 5040.0))
                cos_a = 1.0 - a2 * (0.5 - a2 * (1.0 / 24.0 - a2 / 720.0))
                out[3 * j] = v * sinc_a * cos_a
                out[3 * j + 1] = v * sinc_a * sinc_a * a * lateral_gain
                out[3 * j + 2] = w
            else:
                out[2 * j] = (v - half_length * w) / wheel_radius
                out[2 * j + 1] = (v + half_length * w) / wheel_radius


@_jit
def group_read(record, qpos, sims, qadr, sensor_all, sensor_wall, rows, unicycle, poses, robot, wall):
    """Contacts in any substep and poses of one group, scattered to the flat rows (S, n).

    record (S, substeps, nsensordata) of simulations ``sims`` (S,); qpos (nsim, nq). Unicycle
    tier: poses[:, 2] gets the yaw wrapped to (-π, π] as :meth:`Binding.poses`; wheels tier:
    the caller computes the yaw from the quaternion (arctan2 stays in numpy).
    """
    two_pi = 2.0 * math.pi
    for i in range(rows.shape[0]):
        for j in range(rows.shape[1]):
            r = rows[i, j]
            hit_robot = False
            hit_wall = False
            for t in range(record.shape[1]):
                total, w = record[i, t, sensor_all[j]], record[i, t, sensor_wall[j]]
                hit_robot |= total - w > 0.0
                hit_wall |= w > 0.0
            robot[r], wall[r] = hit_robot, hit_wall
            q = qadr[j]
            poses[r, 0] = qpos[sims[i], q]
            poses[r, 1] = qpos[sims[i], q + 1]
            if unicycle:
                # np.remainder(π - θ, 2π), as numpy computes it (fmod, then the sign of 2π)
                mod = np.fmod(math.pi - qpos[sims[i], q + 2], two_pi)  # exact
                if mod != 0.0:
                    if mod < 0.0:
                        mod += two_pi
                else:
                    mod = 0.0
                poses[r, 2] = math.pi - mod


# -- checks and counters -------------------------------------------------------------------------
@_jit
def check_tick_into(
    poses, c, s, offset, diameter2, pair_i, pair_j, pair_team, bounds, collision, collision_pairs, boundary
):
    """:func:`comat.sim.violations.check_tick`'s arrays, written into the given outputs."""
    collision[:] = False
    collision_pairs[:] = 0
    for p in range(pair_i.size):
        i, j = pair_i[p], pair_j[p]
        d0 = (poses[i, 0] + offset * c[i]) - (poses[j, 0] + offset * c[j])
        d1 = (poses[i, 1] + offset * s[i]) - (poses[j, 1] + offset * s[j])
        if d0 * d0 + d1 * d1 <= diameter2:
            collision[i] = True
            collision[j] = True
            collision_pairs[pair_team[p]] += 1
    for r in range(poses.shape[0]):
        x, y = poses[r, 0], poses[r, 1]
        boundary[r] = x < bounds[0] or x > bounds[1] or y < bounds[2] or y > bounds[3]


@_jit
def violations_add(
    robot_team,
    collision,
    boundary,
    actuator,
    robot_contact,
    wall_contact,
    last_contact,
    collision_ticks,
    boundary_ticks,
    actuator_ticks,
    contact_ticks,
    contact_onsets,
    wall_ticks,
):
    """:meth:`comat.sim.violations.Violations.add`'s per-robot and per-team counters."""
    B = actuator_ticks.size
    any_act = np.zeros(B, dtype=np.bool_)
    for r in range(robot_team.size):
        collision_ticks[r] += collision[r]
        boundary_ticks[r] += boundary[r]
        contact_ticks[r] += robot_contact[r]
        contact_onsets[r] += robot_contact[r] and not last_contact[r]
        last_contact[r] = robot_contact[r]
        wall_ticks[r] += wall_contact[r]
        if actuator[r]:
            any_act[robot_team[r]] = True
    for b in range(B):
        actuator_ticks[b] += any_act[b]


@_jit
def check_and_count(
    poses,
    c,
    s,
    offset,
    diameter2,
    pair_i,
    pair_j,
    pair_team,
    bounds,
    robot_team,
    actuator,
    robot_contact,
    wall_contact,
    collision,
    collision_pairs,
    boundary,
    last_contact,
    pair_total,
    collision_ticks,
    boundary_ticks,
    actuator_ticks,
    contact_ticks,
    contact_onsets,
    wall_ticks,
):
    """:func:`check_tick_into` then :func:`violations_add`, and the pair counts added to
    ``pair_total`` (B,): a tick's checks and counters in one call."""
    check_tick_into(
        poses, c, s, offset, diameter2, pair_i, pair_j, pair_team, bounds, collision, collision_pairs, boundary
    )
    violations_add(
        robot_team,
        collision,
        boundary,
        actuator,
        robot_contact,
        wall_contact,
        last_contact,
        collision_ticks,
        boundary_ticks,
        actuator_ticks,
        contact_ticks,
        contact_onsets,
        wall_ticks,
    )
    for b in range(pair_total.size):
        pair_total[b] += collision_pairs[b]


@_jit
def episode_stats_add(
    starts,
    robot_contact,
    last_contact,
    boundary,
    actuator,
    collision_pairs,
    intervention,
    fallback,
    collisions,
    boundary_exits,
    actuator_errors,
    robotarium_collisions,
    interventions,
    fallbacks,
    violations,
):
    """:meth:`comat.envs.core.TaskCore.step`'s per-tick episode counters, per team (B,).

    collisions counts robot-contact onsets, boundary_exits robot-ticks outside, actuator_errors
    ticks with any error; violations (this env step's) adds onsets, exits and Robotarium pairs.
    """
    B = starts.size
    R = robot_contact.size
    for b in range(B):
        end = starts[b + 1] if b + 1 < B else R
        onsets = 0
        exits = 0
        act = 0
        for r in range(starts[b], end):
            onsets += robot_contact[r] and not last_contact[r]
            exits += boundary[r]
            act += actuator[r]
        collisions[b] += onsets
        boundary_exits[b] += exits
        actuator_errors[b] += act > 0
        robotarium_collisions[b] += collision_pairs[b]
        interventions[b] += intervention[b] > 0
        fallbacks[b] += fallback[b]
        violations[b] += onsets + exits + collision_pairs[b]
