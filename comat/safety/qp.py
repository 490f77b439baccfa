"""One block-diagonal OSQP problem for a fixed tuple of team sizes, set up once, updated per tick."""

from __future__ import annotations

import time
from dataclasses import dataclass

import daqp
import numpy as np
import osqp
import scipy.sparse as sp

from comat import constants as C
from comat import kernels
from comat.config import SafetyConfig
from comat.safety import kernels as safety_kernels
from comat.safety.constraints import Layout, RowValues, make_layout, row_values
from comat.sim.kinematics import WHEEL_LIMIT_TOLERANCE

__all__ = ["BarrierQP", "QPResult", "dense_qp", "matrix_of", "new_osqp"]

_SOLVED = osqp.SolverStatus.OSQP_SOLVED
_DAQP_OPTIMAL, _DAQP_INFEASIBLE = 1, -1  # DAQP's exit flags (its docs' "parameters" page)
_DENSE_FEASIBILITY_TOL = 1e-9  # m/s·(row scale): what dense_qp's answers must meet; DAQP's land at ~1e-15


def new_osqp() -> osqp.OSQP:
    """An OSQP solver on its built-in linear algebra, named rather than looked up: without
    ``algebra`` the solver tries to import the CUDA and MKL backends first, and a failed import is
    not cached, so each set-up searched ``sys.path`` twice (1.3 ms of a 6 ms dense solve, 16 robots
    x 8 teams at ``stress``; results/safety_live/README.md). Naming it also keeps every machine on
    the same algebra, as determinism asks."""
    return osqp.OSQP(algebra="builtin")


_REFINE_MAX_TEAMS = 8


def matrix_of(layout: Layout) -> tuple[sp.csc_matrix, np.ndarray]:
    """CSC pattern of the layout's rows and the permutation from our data order to CSC order."""
    R = layout.teams.n_robots
    nnz = layout.rows.size
    coo = sp.coo_matrix(
        (np.arange(1, nnz + 1, dtype=np.float64), (layout.rows, layout.cols)), shape=(layout.n_rows, 2 * R)
    )
    csc = coo.tocsc()
    return csc, csc.data.astype(np.int64) - 1


@dataclass
class QPResult:
    """Answer for the teams of one problem: velocities (2R,), per-team trust, OSQP's status."""

    x: np.ndarray
    Ax: np.ndarray
    y: np.ndarray
    good: np.ndarray
    status: str
    solver_wall_s: float
    solver_c_s: float


class BarrierQP:
    """The barrier QP of :mod:`comat.safety.constraints` for teams of ``team_sizes`` robots (with
    pair rows for all their pairs, or for the given ``pairs`` only)."""

    def __init__(
        self,
        team_sizes: tuple[int, ...],
        config: SafetyConfig,
        profile: C.RobotProfile,
        pairs: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> None:
        self.layout = make_layout(team_sizes, pairs)
        self.config = config
        self.profile = profile
        self.pattern, self.perm = matrix_of(self.layout)
        """The constraint matrix (its nonzeros rewritten per tick) and the permutation from
        :meth:`RowValues.data` order to its CSC order."""
        self._solver: osqp.OSQP | None = None
        self.wheel_factor = WHEEL_LIMIT_TOLERANCE / config.wheel_speed_fraction
        """Wheel rows are violated beyond ``upper · wheel_factor`` (see :meth:`feasible`)."""

    def matrix(self, data: np.ndarray) -> sp.csc_matrix:
        """The constraint matrix for nonzeros ``data`` given in layout order.

        The returned matrix is this problem's own, rewritten in place by the next call.
        """
        np.take(data, self.perm, out=self.pattern.data)
        return self.pattern

    def rows(self, points: np.ndarray, headings: np.ndarray, cos_sin=None) -> RowValues:
        return row_values(self.layout, points, headings, self.config, self.profile, cos_sin)

    def per_team(self, row_flags: np.ndarray) -> np.ndarray:
        """(B,) number of flagged rows in each team."""
        lay = self.layout
        return np.bincount(lay.row_team[row_flags], minlength=lay.teams.n_teams)

    def feasible(self, vals: RowValues, u: np.ndarray, Au: np.ndarray | None = None) -> np.ndarray:
        """(B,) True where u meets every row of the team.

        Barrier and boundary rows within ``feasibility_tol``; wheel rows against the true wheel
        limit with no tolerance (over it is a Robotarium actuator error), while the QP itself
        answers within ``wheel_speed_fraction`` of it, so solver tolerance never gets there.
        """
        Au = vals.products(u) if Au is None else Au
        tol = self.config.feasibility_tol
        t = self.layout.teams
        wheel_factor = self.wheel_factor
        if kernels.enabled():
            return safety_kernels.team_violations(
                Au,
                vals.lower,
                vals.upper,
                tol,
                self.layout.n_pair_rows + 2 * t.n_robots,
                wheel_factor,
                self.layout.row_team,
                t.n_teams,
            )
        viol = (Au > vals.upper + tol) | (Au < vals.lower - tol)
        w = slice(self.layout.n_pair_rows + 2 * t.n_robots, None)
        limit = vals.upper[w] * wheel_factor
        viol[w] = np.abs(Au[w]) > limit
        return self.per_team(viol) == 0

    def solve(
        self, A: sp.csc_matrix, vals, u_nom: np.ndarray, x0: np.ndarray | None = None, y0: np.ndarray | None = None
    ) -> QPResult:
        """Solve for all teams of this problem, warm-started from (x0, y0) if given, else from
        this problem's previous answer."""
        cfg = self.config
        t0 = time.perf_counter()
        if self._solver is None:
            self._solver = new_osqp()
            self._solver.setup(
                sp.identity(u_nom.size, format="csc"),
                -u_nom,
                A,
                vals.lower,
                vals.upper,
                verbose=False,
                eps_abs=cfg.eps,
                eps_rel=cfg.eps,
                rho=cfg.admm_rho,
                max_iter=cfg.max_iter,
                polishing=True,
                warm_starting=True,
                check_termination=10,
            )
        else:
            # The compiled solver directly: the Python wrapper's per-call bookkeeping (bound
            # clipping, a derivative cache, a SimpleNamespace of results) costs more than a
            # small solve. Our bounds are already within ±OSQP_INFINITY.
            ext = self._solver._solver
            ext.update_data_vec(q=-u_nom, l=vals.lower, u=vals.upper)
            ext.update_data_mat(P_x=None, P_i=None, A_x=A.data, A_i=None)
        ext = self._solver._solver
        if x0 is not None:
            ext.warm_start(x0, y0)
        ext.solve()
        info = ext.info
        c_time = float(info.update_time + info.solve_time + info.polish_time)
        if info.status_val == _SOLVED and info.status_polish != 1 and self.layout.teams.n_teams <= _REFINE_MAX_TEAMS:
            # Polishing missed the active set: continue from this answer to eps/100 (which
            # usually lets the polish find it), so the result is the optimum to ~1e-5 whatever
            # else shares the problem (batched == single); then restore the tolerance. Larger
            # problems (dense pile-ups of many teams) skip this — it costs more than the rest
            # of the tick — and keep the repaired answer, within eps of the optimum.
            self._solver.update_settings(eps_abs=cfg.eps * 1e-2, eps_rel=cfg.eps * 1e-2)
            ext.solve()
            self._solver.update_settings(eps_abs=cfg.eps, eps_rel=cfg.eps)
            info = ext.info
            c_time += float(info.solve_time + info.polish_time)
        wall = time.perf_counter() - t0
        sol = ext.solution
        status, status_val, polished = info.status, info.status_val, info.status_polish == 1
        x, y = np.array(sol.x), np.array(sol.y)
        B = self.layout.teams.n_teams
        if status_val != _SOLVED or not np.all(np.isfinite(x)):
            m = vals.lower.size
            return QPResult(
                np.zeros_like(u_nom), np.zeros(m), np.zeros(m), np.zeros(B, dtype=bool), status, wall, c_time
            )
        # A polished answer is exact; an unpolished one may miss rows by ~eps: repair it.
        if not polished:
            x = self._repair(A, vals, x)
        Ax = self._product(A, x)
        return QPResult(x, Ax, y, self.feasible(vals, x, Au=Ax), status, wall, c_time)

    def _product(self, A: sp.csc_matrix, x: np.ndarray) -> np.ndarray:
        """A @ x (scipy's order of summation, compiled when the kernels are on)."""
        if kernels.enabled():
            return safety_kernels.csc_matvec(A.indptr, A.indices, A.data, x, self.layout.n_rows)
        return A @ x

    def _repair(self, A: sp.csc_matrix, vals, x: np.ndarray) -> np.ndarray:
        """Scale each team's answer toward 0 until it meets every row exactly.

        An unpolished ADMM answer may miss rows by ~eps. Where u = 0 is feasible for the team
        (the state is safe: all barrier values h >= 0 and robots inside the margin), every row
        is a·u <= b with b >= 0 or a·u >= b with b <= 0, so scaling u by the smallest b/(a·u)
        over the missed rows lands inside the polytope; the change is of the order of eps.
        """
        lay = self.layout
        Ax = self._product(A, x)
        over, under = Ax > vals.upper, Ax < vals.lower
        if not (over.any() or under.any()):
            return x
        zero_ok = self.per_team((vals.lower > 0) | (vals.upper < 0)) == 0
        ratio = np.ones(lay.n_rows)
        ratio[over] = vals.upper[over] / Ax[over]
        ratio[under] = vals.lower[under] / Ax[under]
        alpha = np.ones(lay.teams.n_teams)
        np.minimum.at(alpha, lay.row_team, np.clip(ratio, 0.0, 1.0))
        alpha = np.where(zero_ok, alpha * (1.0 - 1e-12), 1.0)
        return x * np.repeat(alpha[lay.teams.robot_team], 2)


def dense_qp(
    vhat: np.ndarray, A: np.ndarray, b: np.ndarray, weights: np.ndarray | None = None
) -> tuple[np.ndarray | None, str]:
    """min ½·Σ w_k (v_k − v̂_k)² (w = 1 by default) s.t. A v <= b for one small dense problem (the
    portable barrier of a team with a robot on probation,
    :class:`comat.safety.deployed.PortableBarrier`, and its re-solves of a few robots):
    (v or None, status: "optimal", "primal infeasible" or DAQP's exit flag).

    DAQP's dual active-set method (Arnström, Bemporad & Axehill 2022), exact up to rounding on
    these problems of 2–40 variables: 0.03 ms where OSQP's set-up alone took 1.6 ms (8 variables,
    30 rows; both optima equal to 1e-14), which made a team with a robot on probation dear at
    ``stress`` (issue 66). The answer is checked against the rows before it is returned."""
    w = np.ones(vhat.size) if weights is None else weights
    A = np.ascontiguousarray(A, dtype=float)
    b = np.ascontiguousarray(b, dtype=float)
    x, _, flag, _ = daqp.solve(np.diag(w), -w * vhat, A, b, np.full(b.size, -1e30), np.zeros(b.size, np.intc))
    if flag == _DAQP_INFEASIBLE:
        return None, "primal infeasible"
    if flag != _DAQP_OPTIMAL or not np.all(np.isfinite(x)) or np.any(A @ x > b + _DENSE_FEASIBILITY_TOL):
        return None, f"daqp exit {flag}"
    return x, "optimal"
