"""Compiled pass over the teams with a robot on probation (:class:`comat.safety.deployed.RobotWatch`):
the cheap cases of :meth:`comat.control.SafeTeams._watch_teams` for every team in one call.

Per team with a robot on probation, as the reference loop in ``_watch_teams`` does:

1. the portable filter's rows ``A u <= b`` (:func:`portable_rows`, the same bits as
   :meth:`~comat.safety.deployed.PortableBarrier.problem`, in CSR);
2. the fast answer meets every row within ``tol``: kept;
3. else only the robots in the rows it breaks are re-solved, the others held at the fast
   answer, by :func:`nearest_in_polytope` (below), and the result is taken if it meets every row
   of the team within ``tol``;
4. else (the held robots left the subset no room) the whole team's hard problem, from the
   nominal commands: the portable filter's own answer (:meth:`PortableBarrier.__call__` returns
   the nominal commands where they meet every row, else this optimum);
5. else (no command meets the hard rows) the team is left to the reference loop, which ends in
   the portable filter's softened problem or its brake.

Why: at ``stress`` 36 of 64 teams of 8 robots had a robot on probation every tick, and each broke a
row (a robot on probation may not close in on any teammate), so the Python loop re-solved ~36
sub-problems a tick at ~80 µs each, most of it numpy calls around a 10 µs DAQP solve (issue 66:
stress/nominal 1.73× where ≤ 1.3× must hold).

:func:`nearest_in_polytope` is the dual active-set method of Goldfarb & Idnani (1983) for a unit
Hessian, ``min ½‖x − v‖² s.t. A x <= b``: exact up to rounding, as DAQP (a dual active-set method
too) is. The optimum is unique (strictly convex), so both land on the same point up to rounding:
``tests/test_probation.py`` checks it against DAQP to 1e-9 m/s, and this pass against the
reference loop to the same tolerance (not bit for bit: the solver and the order of the sums
differ). The pass then cost 0.13–0.22 ms a tick at ``stress`` for 20 × 4, 16 × 8 and 8 × 64
(CPU time on captured ticks, busy machine) where the loop had cost 3.2 ms at 8 × 64 (quiet).

Shapes: R robots, B teams, M rows, n variables.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from comat.safety.kernels import portable_pair_rows

__all__ = [
    "GAVE_UP", "INFEASIBLE", "KEPT", "NO_PROBATION", "REFERENCE", "SOLVED", "SUBSET", "TEAM",
    "nearest_in_polytope", "portable_rows", "probation_pass",
]  # fmt: skip

_jit = njit(cache=True, nogil=True)

SOLVED, INFEASIBLE, GAVE_UP = 0, 1, 2
""":func:`nearest_in_polytope`'s results."""
NO_PROBATION, KEPT, SUBSET, TEAM, REFERENCE = 0, 1, 2, 3, 4
""":func:`probation_pass`'s verdict per team: no robot on probation; the fast answer meets every
row; the re-solved subset does; the whole team's hard problem was solved (the portable filter's
answer); left to the reference loop."""

_VIOLATION_TOL = 1e-12  # m/s·(row scale): rows met to this count as met (DAQP's answers land at ~1e-15)
_DEPENDENT = 1e-18  # ‖z‖² / ‖a‖² below this: the row lies in the span of the active ones (sin ~1e-9)
_MAX_STEPS_PER_ROW = 10  # active-set changes allowed per row and variable before giving up


@_jit
def _sparse(A):
    """A (M, n)'s nonzeros by row (CSR: row k's are ``cols[start[k]:start[k + 1]]`` and ``vals``
    there) and its rows' squared norms (M,). A barrier row has at most 4 of a team's 2N columns,
    so every later pass over the rows costs their nonzeros, not M·n (20 robots: 387 × 40)."""
    m, n = A.shape
    start, cols, vals, norm2 = np.zeros(m + 1, np.int64), np.empty(m * n, np.int64), np.empty(m * n), np.empty(m)
    e = 0
    for k in range(m):
        s = 0.0
        for j in range(n):
            if A[k, j] != 0.0:
                cols[e], vals[e] = j, A[k, j]
                s += A[k, j] * A[k, j]
                e += 1
        start[k + 1], norm2[k] = e, s
    return start, cols, vals, norm2


@njit(cache=True, nogil=True, inline="always")  # a call per row cost as much as the solve (2x at 20 robots)
def _row_times(start, cols, vals, k, x):
    """Row k of a CSR matrix times x."""
    s = 0.0
    for e in range(start[k], start[k + 1]):
        s += vals[e] * x[cols[e]]
    return s


@_jit
def _orthogonalize(start, cols, vals, row, Q, q, z, w):
    """z = row ``row`` of a CSR matrix less its part in the span of Q[:q] (orthonormal rows),
    w (q,) = Q[:q] · (the row); returns ‖z‖². Classical Gram–Schmidt, the first products on the
    row's few nonzeros, repeated once where it cancelled more than half the row (‖z‖² < ½‖a‖²:
    the 1/√2 test of Daniel, Gragg, Kaufman & Stewart 1976), so z ⟂ Q to rounding."""
    n = z.size
    z[:] = 0.0
    for e in range(start[row], start[row + 1]):
        z[cols[e]] = vals[e]
    for i in range(q):
        d = 0.0
        for e in range(start[row], start[row + 1]):
            d += Q[i, cols[e]] * vals[e]
        w[i] = d
    for i in range(q):
        for j in range(n):
            z[j] -= w[i] * Q[i, j]
    aa, zz = 0.0, 0.0
    for e in range(start[row], start[row + 1]):
        aa += vals[e] * vals[e]
    for j in range(n):
        zz += z[j] * z[j]
    if q > 0 and zz < 0.5 * aa:
        for i in range(q):
            d = 0.0
            for j in range(n):
                d += Q[i, j] * z[j]
            w[i] += d
            for j in range(n):
                z[j] -= d * Q[i, j]
        zz = 0.0
        for j in range(n):
            zz += z[j] * z[j]
    return zz


@_jit
def _set_column(Q, R, i, z, w, zz):
    """Column i of the active rows' factors N = Qᵀ R (Q's rows orthonormal): Q[i] = z / ‖z‖,
    R[:i, i] = w, R[i, i] = ‖z‖ (z, w and ‖z‖² = zz from :func:`_orthogonalize`)."""
    nz = math.sqrt(zz)
    for j in range(z.size):
        Q[i, j] = z[j] / nz
    for k in range(i):
        R[k, i] = w[k]
    R[i, i] = nz


@_jit
def nearest_in_polytope(v, A, b, x):
    """The point x (n,) of ``{x : A x <= b}`` (A (M, n), b (M,)) nearest to v (n,): Goldfarb &
    Idnani's dual active-set method with a unit Hessian. Starts at v with no row active; adds the
    most violated row (by distance) with a step along its normal projected off the active rows'
    span, dropping an active row whose multiplier reaches 0 on the way. Returns :data:`SOLVED`
    (every row met within 1e-12), :data:`INFEASIBLE` (a violated row no step can mend: the
    rows have no common point) or :data:`GAVE_UP` (step limit; the caller falls back)."""
    start, cols, vals, norm2 = _sparse(A)
    return _nearest(v, start, cols, vals, norm2, b, x)


@_jit
def _nearest(v, start, cols, vals, norm2, b, x):
    """:func:`nearest_in_polytope` on the rows in CSR (:func:`_sparse`)."""
    m, n = b.size, v.size
    x[:] = v
    Q, R = np.zeros((n, n)), np.zeros((n, n))  # active rows' normals N (n, q) = Q[:q]ᵀ R
    active = np.empty(n, np.int64)
    u = np.zeros(n)  # active rows' multipliers
    z, w, r = np.empty(n), np.empty(n), np.empty(n)
    q = 0
    steps = 0
    while True:
        p, worst = -1, 0.0
        for k in range(m):
            s = _row_times(start, cols, vals, k, x) - b[k]
            if s > _VIOLATION_TOL and norm2[k] == 0.0:
                return INFEASIBLE  # 0 <= b < 0
            if s > _VIOLATION_TOL and s * s / norm2[k] > worst:
                p, worst = k, s * s / norm2[k]
        if p < 0:
            return SOLVED
        up = 0.0  # multiplier of row p
        while True:
            steps += 1
            if steps > _MAX_STEPS_PER_ROW * (m + n):
                return GAVE_UP
            zz = _orthogonalize(start, cols, vals, p, Q, q, z, w)
            for i in range(q - 1, -1, -1):  # r = R⁻¹ w: how the active multipliers trade for row p's
                acc = w[i]
                for k in range(i + 1, q):
                    acc -= R[i, k] * r[k]
                r[i] = acc / R[i, i]
            full = math.inf
            if q < n and zz > _DEPENDENT * norm2[p]:  # n active rows span everything: z is rounding
                full = (_row_times(start, cols, vals, p, x) - b[p]) / zz  # the step that meets row p exactly
            partial, drop = math.inf, -1
            for i in range(q):
                if r[i] > 0.0 and u[i] / r[i] < partial:
                    partial, drop = u[i] / r[i], i
            if full == math.inf and partial == math.inf:
                return INFEASIBLE  # row p's normal is a non-negative mix of the active ones
            t = min(full, partial)
            if full < math.inf:
                for j in range(n):
                    x[j] -= t * z[j]
            for i in range(q):
                u[i] -= t * r[i]
            up += t
            if full <= partial:  # row p joins the active set
                _set_column(Q, R, q, z, w, zz)
                active[q], u[q] = p, up
                q += 1
                break
            for i in range(drop, q - 1):  # row `drop`'s multiplier reached 0: it leaves
                active[i], u[i] = active[i + 1], u[i + 1]
            q -= 1
            for i in range(drop, q):  # the factors anew from the dropped row on (the columns before it stay)
                _set_column(Q, R, i, z, w, _orthogonalize(start, cols, vals, active[i], Q, i, z, w))


@_jit
def _meets(start, cols, vals, bound, u, tol):
    """Every row of a CSR matrix times u (n,) within ``bound`` + tol."""
    for k in range(bound.size):
        if _row_times(start, cols, vals, k, u) > bound[k] + tol:
            return False
    return True


@_jit
def _subset(start, cols, vals, bound, u, u_nom, broken, tol, out):
    """:func:`comat.control._resolve_subset` with :func:`nearest_in_polytope` on a team's rows in
    CSR: the robots in the ``broken`` (M,) rows re-solved, the others held at ``u`` (2N,); True
    with ``out`` (2N,) when the result meets every row within ``tol``."""
    M, n2 = bound.size, u.size
    free = np.zeros(n2, np.bool_)
    for k in range(M):
        if broken[k]:
            for e in range(start[k], start[k + 1]):
                free[2 * (cols[e] // 2)] = True
                free[2 * (cols[e] // 2) + 1] = True
    index = np.cumsum(free) - 1  # column of each free velocity in the sub-problem
    n_free = index[-1] + 1
    # The rows that involve a free robot, on the free columns; the held robots' part moves to the bound.
    sub_start, sub_cols, sub_vals = np.zeros(M + 1, np.int64), np.empty(start[M], np.int64), np.empty(start[M])
    sub_bound, sub_norm2 = np.empty(M), np.empty(M)
    m = 0
    e_sub = 0
    for k in range(M):
        involved = False
        for e in range(start[k], start[k + 1]):
            involved |= free[cols[e]]
        if not involved:
            continue
        held, norm2 = 0.0, 0.0
        for e in range(start[k], start[k + 1]):
            j = cols[e]
            if free[j]:
                sub_cols[e_sub], sub_vals[e_sub] = index[j], vals[e]
                norm2 += vals[e] * vals[e]
                e_sub += 1
            else:
                held += vals[e] * u[j]
        sub_bound[m], sub_norm2[m] = bound[k] - held, norm2
        m += 1
        sub_start[m] = e_sub
    x = np.empty(n_free)
    if _nearest(u_nom[free], sub_start[: m + 1], sub_cols, sub_vals, sub_norm2[:m], sub_bound[:m], x) != SOLVED:
        return False
    out[:] = u
    out[free] = x
    return _meets(start, cols, vals, bound, out, tol)


@_jit
def _put(cols, vals, e, j, value, norm2):
    """Store a nonzero (column j) at slot e as :func:`_sparse` would; returns the next slot and the
    row's squared norm so far."""
    if value != 0.0:
        cols[e], vals[e] = j, value
        return e + 1, norm2 + value * value
    return e, norm2


@_jit
def portable_rows(poses, probation, extra, d, safety, margin, gain, boundary_gain, k_w, v_w, x0, x1, y0, y1):
    """:func:`comat.safety.kernels.portable_problem`'s rows straight into CSR, as :func:`_sparse`
    stores them (start, cols, vals, norm2) with the bounds (M,): the same arithmetic in the same
    order, so the same bits (``tests/test_probation.py``), without the dense (M, 2N) matrix whose
    zeros cost more than the rows (a barrier row has at most 4 nonzeros)."""
    n = poses.shape[0]
    pairs = portable_pair_rows(poses, probation, extra, d, safety, gain)
    c, s, px, py, ri, rj, use_i, use_j, ex, ey, pair_bound = pairs
    count = ri.size
    rows, nnz = count + 8 * n, 4 * count + 12 * n  # nnz: at most
    start, cols, vals = np.zeros(rows + 1, np.int64), np.empty(nnz, np.int64), np.empty(nnz)
    norm2, bound = np.empty(rows), np.empty(rows)
    e = 0
    for r in range(count):
        i, j = ri[r], rj[r]
        sq = 0.0
        if use_i[r]:
            e, sq = _put(cols, vals, e, 2 * i, -2 * ex[r], sq)
            e, sq = _put(cols, vals, e, 2 * i + 1, -2 * ey[r], sq)
        if use_j[r]:
            e, sq = _put(cols, vals, e, 2 * j, 2 * ex[r], sq)
            e, sq = _put(cols, vals, e, 2 * j + 1, 2 * ey[r], sq)
        bound[r], norm2[r] = pair_bound[r], sq
        start[r + 1] = e
    r = count
    for side in range(2):  # the upper walls, then the lower ones
        for q in range(2 * n):
            m = margin + extra[q // 2]
            p, hi, lo = (px[q // 2], x1, x0) if q % 2 == 0 else (py[q // 2], y1, y0)
            e, sq = _put(cols, vals, e, q, 1.0 if side == 0 else -1.0, 0.0)
            bound[r] = boundary_gain * (hi - m - p) if side == 0 else boundary_gain * (p - lo - m)
            norm2[r] = sq
            r += 1
            start[r] = e
    for t in range(n):
        for q in range(2):
            a = c[t] - k_w * s[t] if q == 0 else c[t] + k_w * s[t]
            b = s[t] + k_w * c[t] if q == 0 else s[t] - k_w * c[t]
            for sign in (1.0, -1.0):
                e, sq = _put(cols, vals, e, 2 * t, a if sign > 0 else -1.0 * a, 0.0)
                e, sq = _put(cols, vals, e, 2 * t + 1, b if sign > 0 else -1.0 * b, sq)
                bound[r], norm2[r] = v_w, sq
                r += 1
                start[r] = e
    return start, cols, vals, norm2, bound


@_jit
def probation_pass(poses, probation, extra, offsets, safe, dxi, tol, constants, verdict, intervention):
    """Steps 1–4 of the module docstring for every team: poses (R, 3) and extra radii (R,) as
    :meth:`RobotWatch.obstacles` places them, probation (R,) bool, team offsets (B + 1,),
    ``safe`` (R, 2) the fast filter's answer (changed in place for :data:`SUBSET` and
    :data:`TEAM` teams), ``dxi`` (R, 2) the nominal commands, ``constants`` the portable rows'
    scalars as :attr:`comat.control.CompiledPortableBarrier.constants` holds them. Fills
    ``verdict`` (B,) and, for :data:`SUBSET` and :data:`TEAM` teams, ``intervention`` (B,)
    ‖safe − dxi‖ over the team."""
    B = offsets.size - 1
    for b in range(B):
        lo, hi = offsets[b], offsets[b + 1]
        verdict[b] = NO_PROBATION
        if not probation[lo:hi].any():
            continue
        start, cols, vals, norm2, bound = portable_rows(poses[lo:hi], probation[lo:hi], extra[lo:hi], *constants)
        u = safe[lo:hi].copy().reshape(-1)
        broken = np.empty(bound.size, np.bool_)
        for k in range(bound.size):
            broken[k] = _row_times(start, cols, vals, k, u) > bound[k] + tol
        if not broken.any():
            verdict[b] = KEPT
            continue
        out = np.empty(u.size)
        u_nom = dxi[lo:hi].copy().reshape(-1)
        if _subset(start, cols, vals, bound, u, u_nom, broken, tol, out):
            verdict[b] = SUBSET
        elif _nearest(u_nom, start, cols, vals, norm2, bound, out) == SOLVED:  # the held robots left no room
            verdict[b] = TEAM
        else:
            verdict[b] = REFERENCE
            continue
        square = 0.0
        for r in range(hi - lo):
            for c in range(2):
                safe[lo + r, c] = out[2 * r + c]
                square += (out[2 * r + c] - dxi[lo + r, c]) ** 2
        intervention[b] = math.sqrt(square)
