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
    "csc_matvec",
    "enabled",
    "episode_stats_add",
    "filter_stages",
    "group_ctrl",
    "group_read",
    "interventions",
    "limit_to_wheels",
    "qp_teams",
    "reference_path",
    "row_bounds_into",
    "row_data",
    "row_products",
    "si_to_uni",
    "si_to_wheels",
    "sub_problem_gather",
    "sub_problem_indices",
    "sub_problem_scatter",
    "take_teams",
    "team_violations",
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


# -- safety filter rows --------------------------------------------------------------------------
@_jit
def row_bounds_into(
    points, pair_i, pair_j, safety_d2, barrier_gain, neg_boundary_gain, boundary_gain, lo, hi, speed, e, lower, upper
):
    """:func:`comat.safety.constraints.row_values`: pair differences e (P, 2) and bounds (rows,)."""
    P, R = pair_i.size, points.shape[0]
    for p in range(P):
        e0 = points[pair_i[p], 0] - points[pair_j[p], 0]
        e1 = points[pair_i[p], 1] - points[pair_j[p], 1]
        e[p, 0], e[p, 1] = e0, e1
        lower[p] = -1e30
        upper[p] = barrier_gain * (e0 * e0 + e1 * e1 - safety_d2)
    for r in range(R):
        for axis in range(2):
            lower[P + 2 * r + axis] = neg_boundary_gain * (points[r, axis] - lo[axis])
            upper[P + 2 * r + axis] = boundary_gain * (hi[axis] - points[r, axis])
    for q in range(P + 2 * R, P + 4 * R):
        lower[q] = -speed
        upper[q] = speed


@_jit
def row_products(e, c, s, k, pair_i, pair_j, u, out):
    """:meth:`comat.safety.constraints.RowValues.products`: A @ u (rows,) for u (2R,)."""
    P, R = pair_i.size, c.size
    for p in range(P):
        i, j = pair_i[p], pair_j[p]
        du0 = u[2 * i] - u[2 * j]
        du1 = u[2 * i + 1] - u[2 * j + 1]
        out[p] = -2.0 * (e[p, 0] * du0 + e[p, 1] * du1)
    for q in range(2 * R):
        out[P + q] = u[q]
    for r in range(R):
        ux, uy = u[2 * r], u[2 * r + 1]
        along = c[r] * ux + s[r] * uy
        across = -s[r] * ux + c[r] * uy
        out[P + 2 * R + 2 * r] = along + k * across
        out[P + 2 * R + 2 * r + 1] = along - k * across


@_jit
def team_violations(Au, lower, upper, tol, wheel_start, wheel_factor, row_team, n_teams):
    """:meth:`comat.safety.qp.BarrierQP.feasible`: (B,) True where the team meets every row."""
    ok = np.ones(n_teams, dtype=np.bool_)
    for q in range(Au.size):
        if q < wheel_start:
            bad = Au[q] > upper[q] + tol or Au[q] < lower[q] - tol
        else:
            bad = abs(Au[q]) > upper[q] * wheel_factor
        if bad:
            ok[row_team[q]] = False
    return ok


@_jit
def interventions(out, u_nom, robot_team, n_teams, robot_norm2, per_team):
    """:meth:`comat.safety.filter.SafetyFilter._info`'s norms: per robot (R,) squared, per team (B,)."""
    per_team[:] = 0.0
    for r in range(robot_team.size):
        dx = out[2 * r] - u_nom[2 * r]
        dy = out[2 * r + 1] - u_nom[2 * r + 1]
        robot_norm2[r] = dx * dx + dy * dy
        per_team[robot_team[r]] += robot_norm2[r]
    for b in range(n_teams):
        per_team[b] = math.sqrt(per_team[b])


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


# -- safety filter QP stage ----------------------------------------------------------------------
@_jit
def row_data(e, c, s, k, out):
    """:meth:`comat.safety.constraints.RowValues.data`: A's nonzeros in layout order into out."""
    P, R = e.shape[0], c.size
    for p in range(P):
        out[4 * p] = -2.0 * e[p, 0]
        out[4 * p + 1] = -2.0 * e[p, 1]
        out[4 * p + 2] = 2.0 * e[p, 0]
        out[4 * p + 3] = 2.0 * e[p, 1]
    for q in range(4 * P, 4 * P + 2 * R):
        out[q] = 1.0
    w = 4 * P + 2 * R
    for r in range(R):
        out[w + 4 * r] = c[r] - k * s[r]
        out[w + 4 * r + 1] = s[r] + k * c[r]
        out[w + 4 * r + 2] = c[r] + k * s[r]
        out[w + 4 * r + 3] = s[r] - k * c[r]


@_jit
def csc_matvec(indptr, indices, data, x, n_rows):
    """A @ x for a CSC matrix, summed in scipy's order (column by column)."""
    y = np.zeros(n_rows)
    for j in range(indptr.size - 1):
        for q in range(indptr[j], indptr[j + 1]):
            y[indices[q]] += data[q] * x[j]
    return y


@_jit
def take_teams(teams, robot_team, row_team, out, u, Au, Au_new):
    """Adopt velocities u (2R,) and row products Au_new (rows,) for the teams flagged (B,)."""
    for r in range(robot_team.size):
        if teams[robot_team[r]]:
            out[2 * r] = u[2 * r]
            out[2 * r + 1] = u[2 * r + 1]
    for q in range(row_team.size):
        if teams[row_team[q]]:
            Au[q] = Au_new[q]


@_jit
def filter_stages(
    poses,
    c,
    s,
    u_nom,
    distance,
    pair_i,
    pair_j,
    safety_d2,
    barrier_gain,
    neg_boundary_gain,
    boundary_gain,
    lo,
    hi,
    speed,
    k,
    tol,
    wheel_factor,
    row_team,
    robot_team,
    points,
    e,
    lower,
    upper,
    out,
    Au,
    u_wheel,
    Au_wheel,
    need,
):
    """:meth:`comat.safety.filter.SafetyFilter._filter`'s rows and stages 1–2 in one call.

    Projected points (R, 2), rows (e, lower, upper), ``out`` (2R,) = the stage-1/2 answer with
    its row products ``Au``; ``need`` (B,) the teams left for the QP. Returns how many are left;
    ``u_wheel`` (2R,) and ``Au_wheel`` are filled only if stage 2 ran, as in the reference.
    """
    R, P, B = poses.shape[0], pair_i.size, need.size
    for r in range(R):
        points[r, 0] = poses[r, 0] + distance * c[r]
        points[r, 1] = poses[r, 1] + distance * s[r]
    row_bounds_into(
        points,
        pair_i,
        pair_j,
        safety_d2,
        barrier_gain,
        neg_boundary_gain,
        boundary_gain,
        lo,
        hi,
        speed,
        e,
        lower,
        upper,
    )
    out[:] = u_nom
    row_products(e, c, s, k, pair_i, pair_j, u_nom, Au)
    ok = team_violations(Au, lower, upper, tol, P + 2 * R, wheel_factor, row_team, B)
    any_need = False
    for b in range(B):
        need[b] = not ok[b]
        any_need |= need[b]
    if not any_need:
        return 0
    limit_to_wheels(u_nom.reshape(R, 2), c, s, k, speed, u_wheel.reshape(R, 2))
    row_products(e, c, s, k, pair_i, pair_j, u_wheel, Au_wheel)
    ok = team_violations(Au_wheel, lower, upper, tol, P + 2 * R, wheel_factor, row_team, B)
    left = 0
    for b in range(B):
        ok[b] &= need[b]
        need[b] &= not ok[b]
        left += need[b]
    take_teams(ok, robot_team, row_team, out, u_wheel, Au, Au_wheel)
    return left


@_jit
def sub_problem_indices(order, sizes, offsets, n_pairs, n_robots):
    """Rows, columns and nonzeros of the full barrier QP that the teams ``order`` (k,) cover, in
    the order of the sub-problem's own layout (teams in the given order).

    Returns rows (n_rows_sub,), cols (2·R_sub,), nnz (nnz_sub,) as indices into the full
    problem's rows, velocities and :meth:`RowValues.data` (see :mod:`comat.safety.constraints`).
    """
    P, R = n_pairs, n_robots
    pair_start = np.zeros(sizes.size + 1, np.int64)
    for b in range(sizes.size):
        pair_start[b + 1] = pair_start[b] + sizes[b] * (sizes[b] - 1) // 2
    sub_pairs = 0
    sub_robots = 0
    for b in order:
        sub_pairs += sizes[b] * (sizes[b] - 1) // 2
        sub_robots += sizes[b]
    rows = np.empty(sub_pairs + 4 * sub_robots, np.int64)
    cols = np.empty(2 * sub_robots, np.int64)
    nnz = np.empty(4 * sub_pairs + 6 * sub_robots, np.int64)
    p = 0
    c = 0
    for b in order:
        for q in range(pair_start[b], pair_start[b + 1]):
            rows[p] = q
            for z in range(4):
                nnz[4 * p + z] = 4 * q + z
            p += 1
        for q in range(2 * offsets[b], 2 * offsets[b + 1]):
            cols[c] = q
            c += 1
    for m in range(2 * sub_robots):
        q = cols[m]
        rows[sub_pairs + m] = P + q  # boundary row of this velocity component
        nnz[4 * sub_pairs + m] = 4 * P + q
        rows[sub_pairs + 2 * sub_robots + m] = P + 2 * R + q  # wheel row
        for z in range(2):
            nnz[4 * sub_pairs + 2 * sub_robots + 2 * m + z] = 4 * P + 2 * R + 2 * q + z
    return rows, cols, nnz


@_jit
def qp_teams(need, sizes, block):
    """:meth:`comat.safety.filter.SafetyFilter._qp_teams`: the teams (k,) of this tick's QP."""
    B = need.size
    teams = np.flatnonzero(need)
    k = teams.size
    if k <= 1:
        return teams
    target = B if 2 * k > B else min(B, -(-k // block) * block)
    if target == B:
        return np.arange(B)
    if target > k:
        chosen = need.copy()
        extra = target - k
        for b in range(B):
            if extra == 0:
                break
            if not chosen[b]:
                chosen[b] = True
                extra -= 1
        teams = np.flatnonzero(chosen)
    return teams[np.argsort(sizes[teams], kind="mergesort")]


@_jit
def sub_problem_gather(
    rows, cols, nnz, perm, data, lower, upper, u_nom, x0, duals, A_data, lower_s, upper_s, u_s, x0_s, y0_s
):
    """A sub-problem's inputs from the full problem's: its matrix's nonzeros in CSC order
    (A_data[i] = data[nnz[perm[i]]]), row bounds and duals at ``rows``, velocities at ``cols``."""
    for i in range(perm.size):
        A_data[i] = data[nnz[perm[i]]]
    for m in range(rows.size):
        q = rows[m]
        lower_s[m], upper_s[m], y0_s[m] = lower[q], upper[q], duals[q]
    for m in range(cols.size):
        q = cols[m]
        u_s[m], x0_s[m] = u_nom[q], x0[q]


@_jit
def sub_problem_scatter(need, teams, good, robot_team_s, row_team_s, rows, cols, x, Ax, out, Au):
    """A sub-problem's answer back into the full problem's velocities ``out`` and row products
    ``Au``, for its teams (k,) that needed the QP (``need`` (B,)) and whose answer is ``good`` (k,)."""
    take = np.empty(teams.size, dtype=np.bool_)
    for m in range(teams.size):
        take[m] = need[teams[m]] and good[m]
    for r in range(robot_team_s.size):
        if take[robot_team_s[r]]:
            out[cols[2 * r]] = x[2 * r]
            out[cols[2 * r + 1]] = x[2 * r + 1]
    for m in range(rows.size):
        if take[row_team_s[m]]:
            Au[rows[m]] = Ax[m]
