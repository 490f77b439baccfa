"""Compiled twins (numba) of the barrier filter's per-tick numpy code, equal to it bit for bit: the
rows' bounds and products (:mod:`comat.safety.constraints`), the feasibility test and the QP's
sparse products (:mod:`comat.safety.qp`), the filter's exact stages and the sub-problem gather and
scatter (:mod:`comat.safety.filter`). Beside the code they twin, as :mod:`comat.reality.kernels`;
the switch and the rules (same order of arithmetic, no fast-math) are :mod:`comat.kernels`'.

Shapes: R robots, P same-team pairs, B teams.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from comat.kernels import limit_to_wheels

__all__ = [
    "csc_matvec",
    "filter_stages",
    "interventions",
    "portable_pair_rows",
    "portable_problem",
    "qp_teams",
    "row_bounds_into",
    "row_data",
    "row_products",
    "sub_problem_gather",
    "sub_problem_indices",
    "sub_problem_scatter",
    "take_teams",
    "team_violations",
    "watch_judgement",
]

_jit = njit(cache=True, nogil=True)


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


# -- the deployed loop's robot watch -------------------------------------------------------------
@_jit
def watch_judgement(ask, points, tick, born, window, lag, k, stale, min_path, ratio, release_ratio, unresponsive):
    """:meth:`comat.safety.deployed.RobotWatch._judge` (its numpy code is the reference), updating
    ``unresponsive`` (N,) in place: ask (N, window + lag + 1, 2), points (N, window + 1, 2), born
    (N,), stale (N,). The same sums in the same order (a running sum over the newest-first asks,
    as ``np.cumsum``; the share made good along each window as ``along / max(square, 1e-30)``),
    so the same bits."""
    n, span = ask.shape[0], ask.shape[1]
    depth = window + lag
    then = (tick - window) % (window + 1)
    sums = np.empty((depth, 2))
    for r in range(n):
        if tick - born[r] <= depth or stale[r]:
            continue  # not old enough to judge, or no fresh pose: neither judged nor released
        for t in range(depth):
            slot = (tick - t) % span
            for c in range(2):
                sums[t, c] = ask[r, slot, c] if t == 0 else sums[t - 1, c] + ask[r, slot, c]
        asked = np.inf
        nan = False
        best = -np.inf
        mx = points[r, k, 0] - points[r, then, 0]
        my = points[r, k, 1] - points[r, then, 1]
        for t in range(lag + 1):  # the window ending t ticks back, as sums[w - 1 + t] - sums[t - 1]
            x = sums[window - 1 + t, 0] - (0.0 if t == 0 else sums[t - 1, 0])
            y = sums[window - 1 + t, 1] - (0.0 if t == 0 else sums[t - 1, 1])
            h = math.hypot(x, y)
            if math.isnan(h):
                nan = True  # np.min propagates NaN
            elif h < asked:
                asked = h
            g = (x * mx + y * my) / max(x * x + y * y, 1e-30)
            if math.isnan(g):
                nan = True  # np.max propagates NaN: no comparison holds
            elif g > best:
                best = g
        if nan or not asked >= min_path:
            continue
        if best < ratio:
            unresponsive[r] = True
        if best >= release_ratio:
            unresponsive[r] = False


# -- the portable barrier's rows (a team with a robot on probation) -------------------------------
@_jit
def portable_pair_rows(poses, probation, extra, d, safety, gain):
    """The pair rows of :func:`portable_problem`, in its order, and what its other rows need:
    cosines, sines and projected points of poses (N, 3) (each (N,)); per pair row (P_rows,) the
    robots i < j, whether each has a part in it, e = p_i − p_j and the bound."""
    n = poses.shape[0]
    c, s = np.cos(poses[:, 2]), np.sin(poses[:, 2])
    px, py = poses[:, 0] + d * c, poses[:, 1] + d * s
    n_pairs = n * (n - 1) // 2
    pi, pj = np.empty(n_pairs, np.int64), np.empty(n_pairs, np.int64)
    k = 0
    for a in range(n):
        for b in range(a + 1, n):
            pi[k], pj[k] = a, b
            k += 1
    count = 0
    for k in range(n_pairs):
        on_i, on_j = probation[pi[k]], probation[pj[k]]
        count += (1 if not on_i and not on_j else 0) + (1 if on_j and not on_i else 0)
        count += (1 if on_i and not on_j else 0) + (1 if on_i else 0) + (1 if on_j else 0)
    ri, rj = np.empty(count, np.int64), np.empty(count, np.int64)
    use_i, use_j = np.empty(count, np.bool_), np.empty(count, np.bool_)
    ex, ey, bound = np.empty(count), np.empty(count), np.empty(count)
    r = 0
    for group in range(5):
        for k in range(n_pairs):
            i, j = pi[k], pj[k]
            on_i, on_j = probation[i], probation[j]
            if group == 0:
                take, with_i, with_j = not on_i and not on_j, True, True
            elif group == 1:
                take, with_i, with_j = on_j and not on_i, True, False
            elif group == 2:
                take, with_i, with_j = on_i and not on_j, False, True
            elif group == 3:
                take, with_i, with_j = on_i, True, False
            else:
                take, with_i, with_j = on_j, False, True
            if not take:
                continue
            ri[r], rj[r], use_i[r], use_j[r] = i, j, with_i, with_j
            ex[r], ey[r] = px[i] - px[j], py[i] - py[j]
            rad = safety + extra[i] + extra[j]
            h = (ex[r] * ex[r] + ey[r] * ey[r]) - rad * rad  # numpy's ** 2 is a square: the same bits
            bound[r] = gain * h if group < 3 else 0.0 * h
            r += 1
    return c, s, px, py, ri, rj, use_i, use_j, ex, ey, bound


@_jit
def portable_problem(poses, probation, extra, d, safety, margin, gain, boundary_gain, k_w, v_w, x0, x1, y0, y1):
    """:meth:`comat.safety.deployed.PortableBarrier.problem` (its numpy code is the reference):
    the rows ``A u <= b`` for poses (N, 3), probation (N,) bool, extra radii (N,) — pair rows in its
    five groups (trusted pairs, then pairs whose j / i alone is on probation, then every pair with i,
    with j on probation), the 2N upper and 2N lower wall rows, the 4N wheel rows — with the same
    arithmetic in the same order, so the same bits. Returns A (M, 2N), b (M,)."""
    n = poses.shape[0]
    pairs = portable_pair_rows(poses, probation, extra, d, safety, gain)
    c, s, px, py, ri, rj, use_i, use_j, ex, ey, pair_bound = pairs
    rows = ri.size + 8 * n
    A, bound = np.zeros((rows, 2 * n)), np.empty(rows)
    for r in range(ri.size):
        i, j = ri[r], rj[r]
        if use_i[r]:
            A[r, 2 * i], A[r, 2 * i + 1] = -2 * ex[r], -2 * ey[r]
        if use_j[r]:
            A[r, 2 * j], A[r, 2 * j + 1] = 2 * ex[r], 2 * ey[r]
        bound[r] = pair_bound[r]
    r = ri.size
    for q in range(2 * n):  # the upper walls, then the lower ones
        m = margin + extra[q // 2]
        A[r + q, q], A[r + 2 * n + q, q] = 1.0, -1.0
        p, hi, lo = (px[q // 2], x1, x0) if q % 2 == 0 else (py[q // 2], y1, y0)
        bound[r + q], bound[r + 2 * n + q] = boundary_gain * (hi - m - p), boundary_gain * (p - lo - m)
    r += 4 * n
    for t in range(n):
        for q in range(2):
            a = c[t] - k_w * s[t] if q == 0 else c[t] + k_w * s[t]
            b = s[t] + k_w * c[t] if q == 0 else s[t] - k_w * c[t]
            row = r + 4 * t + 2 * q
            A[row, 2 * t], A[row, 2 * t + 1] = a, b
            A[row + 1, 2 * t], A[row + 1, 2 * t + 1] = -1.0 * a, -1.0 * b
    bound[r:] = v_w
    return A, bound
