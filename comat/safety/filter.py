"""OSQP control-barrier-function filter for one or many teams, called once per control tick.

Per tick and team: ``min ½‖u - û‖²`` over the projected-point velocities u, subject to the
rows of :mod:`comat.safety.constraints` (pairwise barrier, arena boundary, exact wheel limits).
Three exact stages, cheapest first, decided per team:

1. the nominal command already meets every row: it is returned bit for bit;
2. else each robot's command is projected onto its wheel-limit rhombus (the QP restricted to
   the wheel rows, solved in closed form); if that meets every other row it is the optimum;
3. else the remaining teams go to one block-diagonal OSQP problem, set up once per tuple of
   team sizes and then only updated in place (``update(Ax=...)``) and warm-started. Teams of
   ``sparse_from`` robots or more (default 9) get pair rows only for the pairs closer than
   :func:`~comat.safety.constraints.binding_distance` (0.244 m): the others hold for any
   command the wheels allow, so the answer is the all-pairs QP's, while the rows grow with the
   robots' neighbours instead of N² (496 pairs at N = 32). Its pattern follows the neighbours:
   kept over ticks while it still holds every row that can bind (:class:`CouplingPattern`),
   set up anew when not. Teams below ``sparse_from`` keep the cached all-pairs problem, bit
   for bit.

The answer is never trusted blindly: a team passes only if OSQP reports *solved* and its
answer meets its rows within ``feasibility_tol`` (after a repair of eps-sized misses). Failing
teams are re-solved alone with a 1000× tighter tolerance. A team that still fails is outside the
safe set (no command meets its hard rows): it takes the answer of the softened problem of
:mod:`comat.safety.recovery` (barrier and boundary rows relaxed by heavily penalized slacks,
wheel rows hard), which moves it back toward the safe set as fast as the wheels allow — a
*recovery* tick. Only if that solver fails too does the team brake (zero velocity), a
*fallback* tick; both are counted in :class:`SafetyInfo`. With ``strict=True`` anything but a
feasible hard problem raises :class:`InfeasibleError`.
"""

from __future__ import annotations

import dataclasses
import functools
from collections import OrderedDict
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from comat import constants as C
from comat import kernels
from comat._validate import as_float_array
from comat.config import SafetyConfig
from comat.safety import kernels as safety_kernels
from comat.safety.constraints import RowValues, binding_distance, edge_binding_distance, row_constants
from comat.safety.qp import BarrierQP
from comat.safety.recovery import recovery_command
from comat.safety.sparse import CoupledRows, CouplingPattern
from comat.sim.kinematics import limit_to_wheels, si_to_uni, uni_to_si

__all__ = ["InfeasibleError", "SafetyFilter", "SafetyInfo"]

_MAX_CACHED_QPS = 256
_QP_TEAM_BLOCK = 4
"""Teams of a QP are padded up to a multiple of this (see :meth:`SafetyFilter._qp_teams`)."""
SPARSE_FROM_ROBOTS = 9
"""Teams of at least this many robots get only the pair rows that can bind (module docstring).
9 keeps every team of the paper's sets (at most 8 robots, 28 pairs) on the cached all-pairs
problem, bit for bit; at N = 16 (120 pairs, unicycle, batch 64) the reduced problem measured
about 4x cheaper (2.2 vs 8.5 ms of OSQP per tick, one loaded run)."""


class InfeasibleError(RuntimeError):
    """Raised in strict mode when no safe command exists for a team (or the solver failed)."""


class SafetyInfo:
    """What the filter did in one tick.

    Attributes:
        intervention: (B,) ‖u - û‖ per team (m/s), 0 where the nominal command was kept.
        robot_intervened: (R,) bool, the robot's command was changed.
        fallback: (B,) bool, team braked: no trusted solution, not even of the softened problem.
        recovery: (B,) bool, team outside the safe set (its hard QP infeasible) took the answer
            of the softened problem (:mod:`comat.safety.recovery`): moving back toward it.
        status: OSQP status text of the tick's QP (``"skipped"`` if none was needed).
        solve_time_s: OSQP's own time (update + solve + polish), 0 if skipped.
        active_pairs, active_boundary, active_wheels: (B,) rows of each kind that the final
            command meets with equality (the constraints holding the team back); computed on
            first access.
        min_pair_distance: (B,) smallest projected-point distance in the team (inf if N=1);
            computed on first access.
    """

    def __init__(
        self, filt: SafetyFilter, vals, Au, intervention, robot_intervened, fallback, status, solve_time_s, recovery
    ):
        self.intervention = intervention
        self.robot_intervened = robot_intervened
        self.fallback = fallback
        self.recovery = recovery
        self.status = status
        self.solve_time_s = solve_time_s
        self._filt, self._vals, self._Au = filt, vals, Au

    @functools.cached_property
    def _active(self) -> np.ndarray:
        lay, vals, Au = self._filt.layout, self._vals, self._Au
        n = lay.teams.n_teams
        changed = (self.intervention > 0) & ~self.fallback
        if not changed.any():
            return np.zeros((3, n), np.int64)
        tight = (np.abs(Au - vals.upper) <= 1e-7) | (np.abs(Au - vals.lower) <= 1e-7)
        tight &= changed[lay.row_team]
        return np.bincount(self._filt._row_kind_team[tight], minlength=3 * n).reshape(3, n)

    @property
    def active_pairs(self) -> np.ndarray:
        return self._active[0]

    @property
    def active_boundary(self) -> np.ndarray:
        return self._active[1]

    @property
    def active_wheels(self) -> np.ndarray:
        return self._active[2]

    @functools.cached_property
    def min_pair_distance(self) -> np.ndarray:
        f, e = self._filt, self._vals.e
        min_d = np.full(f.layout.teams.n_teams, np.inf)
        if e.shape[0]:
            min_d[f._teams_with_pairs] = np.sqrt(np.minimum.reduceat(e[:, 0] ** 2 + e[:, 1] ** 2, f._pair_starts))
        return min_d

    def __repr__(self) -> str:
        return (
            f"SafetyInfo(intervention={self.intervention}, fallback={self.fallback}, status={self.status!r}, "
            f"active_pairs={self.active_pairs}, active_boundary={self.active_boundary}, "
            f"active_wheels={self.active_wheels}, min_pair_distance={self.min_pair_distance})"
        )


@dataclass
class _Bounds:
    """Row bounds of a sub-problem (what BarrierQP.solve needs besides A)."""

    lower: np.ndarray
    upper: np.ndarray
    layout: object


class SafetyFilter:
    """Barrier filter for teams of fixed sizes; ``filter`` is called once per control tick.

    Args:
        team_sizes: robots per team (an int for a single team).
        config: barrier geometry, gains and solver tolerances.
        profile: robot profile (wheel limits, axle length).
        qp_cache: a dict to keep OSQP problems in, shared with other filters (same config and
            profile) so that a new layout reuses the problems already set up.
        sparse_from: teams of at least this many robots get pair rows only for the pairs that
            can bind (same answer within solver tolerance; see the module docstring).

    Attributes:
        last_solver_s: wall time of the last tick's OSQP update/solve calls (0 if none).
        last_solver_c_s: OSQP's own reported time for them (update + solve + polish).
    """

    def __init__(
        self,
        team_sizes: int | Sequence[int],
        config: SafetyConfig | None = None,
        profile: C.RobotProfile = C.DEFAULT_PROFILE,
        qp_cache: OrderedDict | None = None,
        sparse_from: int = SPARSE_FROM_ROBOTS,
    ) -> None:
        sizes = (team_sizes,) if isinstance(team_sizes, (int, np.integer)) else tuple(team_sizes)
        if not sizes or any(isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1 for n in sizes):
            raise ValueError(f"team_sizes must be positive integers, got {team_sizes!r}")
        self.config = config or SafetyConfig()
        self.profile = profile
        self._full = BarrierQP(tuple(int(n) for n in sizes), self.config, profile)
        self.layout = self._full.layout
        self._precise = dataclasses.replace(self.config, strict=False, eps=self.config.eps * 1e-3)
        # OSQP problems by (team sizes, tolerance); shareable between filters whose teams change.
        self._qps: OrderedDict[tuple, BarrierQP] = OrderedDict() if qp_cache is None else qp_cache
        self._duals = np.zeros(self.layout.n_rows)  # last QP duals per row: warm starts
        self._all_rows = np.arange(self.layout.n_rows)
        self._all_cols = np.arange(2 * self.layout.teams.n_robots)
        lay = self.layout
        t = lay.teams
        self._sizes = np.array(t.team_sizes, np.int64)
        kind = np.concatenate(
            [np.zeros(t.n_pairs, np.int64), np.ones(2 * t.n_robots, np.int64), np.full(2 * t.n_robots, 2)]
        )
        self._row_kind_team = kind * t.n_teams + lay.row_team  # (n_rows,) for counting per kind and team
        self._nnz_kind_team = self._row_kind_team[lay.rows]
        self._teams_with_pairs = np.flatnonzero(np.array(t.team_sizes) > 1)
        self._pair_starts = np.searchsorted(t.pair_team, self._teams_with_pairs)
        self._row_constants = row_constants(self.config, profile)
        self._sparse_team = self._sizes >= sparse_from  # (B,)
        _, _, lo, hi = self._row_constants
        self._pattern = CouplingPattern(
            t,
            self._sparse_team,
            binding_distance(self.config, profile),
            edge_binding_distance(self.config, profile),
            lo,
            hi,
        )
        self._pattern_qp: tuple[CoupledRows, BarrierQP] | None = None
        self.last_solver_s = 0.0
        self.last_solver_c_s = 0.0

    # -- public ---------------------------------------------------------------------------------
    @property
    def team_sizes(self) -> tuple[int, ...]:
        return self.layout.teams.team_sizes

    def filter(self, poses: np.ndarray, dxi: np.ndarray) -> tuple[np.ndarray, SafetyInfo]:
        """Safe projected-point velocities closest to the nominal ones.

        Args:
            poses: (R, 3) [x, y, θ] of all robots, teams concatenated in order.
            dxi: (R, 2) nominal velocities of the projected points (m/s).

        Returns:
            (R, 2) filtered velocities and the :class:`SafetyInfo` of this tick.
        """
        R = self.layout.teams.n_robots
        poses = as_float_array("poses", poses, (R, 3))
        dxi = as_float_array("dxi", dxi, (R, 2))
        return self._filter(poses, dxi)

    def filter_unicycle(self, poses: np.ndarray, dxu: np.ndarray) -> tuple[np.ndarray, SafetyInfo]:
        """As :meth:`filter`, for unicycle commands (R, 2) [v, ω] in and out."""
        R = self.layout.teams.n_robots
        poses = as_float_array("poses", poses, (R, 3))
        dxu = as_float_array("dxu", dxu, (R, 2))
        d = self.config.projection_distance_m
        safe, info = self._filter(poses, uni_to_si(dxu, poses, d))
        out = si_to_uni(safe, poses, d)
        # Robots the filter left alone get their exact input back (no round-trip rounding).
        keep = ~info.robot_intervened
        out[keep] = dxu[keep]
        return out, info

    # -- internals ------------------------------------------------------------------------------
    def _filter(self, poses: np.ndarray, dxi: np.ndarray, cos_sin=None) -> tuple[np.ndarray, SafetyInfo]:
        lay, cfg, full = self.layout, self.config, self._full
        t = lay.teams
        self.last_solver_s = self.last_solver_c_s = 0.0
        c, s = cos_sin if cos_sin is not None else (np.cos(poses[:, 2]), np.sin(poses[:, 2]))
        self._data = None  # nonzeros of A, built only if a QP is solved
        u_nom = dxi.ravel()
        status = "skipped"
        fallback = np.zeros(t.n_teams, dtype=bool)
        recovery = np.zeros(t.n_teams, dtype=bool)
        if kernels.enabled():
            points, vals, out, Au, need, u_wheel, left = self._stages_compiled(poses, u_nom, c, s)
        else:
            points = poses[:, :2] + cfg.projection_distance_m * np.stack([c, s], axis=1)
            vals = full.rows(points, poses[:, 2], (c, s))
            out = u_nom.copy()
            Au = vals.products(u_nom)  # A @ out, kept current through the stages (for SafetyInfo)
            # Stage 1: the nominal command as it is.
            need = ~full.feasible(vals, u_nom, Au=Au)
            if need.any():  # Stage 2: per-robot projection onto the wheel-limit rhombus.
                u_wheel = self._project_wheels(u_nom, c, s)
                Au_wheel = vals.products(u_wheel)
                ok = need & full.feasible(vals, u_wheel, Au=Au_wheel)
                self._take(ok, out, u_wheel, Au, Au_wheel)
                need &= ~ok
            left = need.any()
        if left:  # Stage 3: the QP for the teams still left.
            sparse = need & self._sparse_team
            dense = need & ~sparse
            retry = []  # (teams, reduced problem or None) to re-solve precisely
            if dense.any():
                teams = self._qp_teams(dense)
                x, Ax, good, rows, cols, status, sub = self._solve(teams, vals, u_nom, self.config, u_wheel)
                self._scatter(dense, teams, good, sub, rows, cols, x, Ax, out, Au)
                retry += [(np.array([b]), None) for b in teams[dense[teams] & ~good]]  # rare: each alone
            if sparse.any():
                # Robots outside the reduced problem keep their stage-2 command (its optimum).
                robots_c = np.repeat(sparse[t.robot_team], 2)
                out[robots_c] = u_wheel[robots_c]
                red = self._pattern.rows(vals.e, points, np.flatnonzero(sparse))
                x, Ax, good, rows, cols, status, sub = self._solve(red.teams, vals, u_nom, self.config, u_wheel, red)
                self._scatter(sparse, red.teams, good, sub, rows, cols, x, Ax, out, Au)
                failed = red.teams[sparse[red.teams] & ~good]
                if failed.size:  # together: a large problem's polish sometimes misses a few teams
                    retry.append((failed, self._pattern.subset(failed)))
            everyone = np.ones(t.n_teams, dtype=bool)
            while retry:  # re-solve precisely, else recover, else brake
                teams, red = retry.pop()
                x, Ax, good, rows, cols, _, sub = self._solve(teams, vals, u_nom, self._precise, u_wheel, red)
                self._scatter(everyone, teams, good, sub, rows, cols, x, Ax, out, Au)
                if teams.size > 1:  # one team outside the safe set makes the whole problem infeasible
                    retry += [(np.array([b]), self._pattern.subset(np.array([b]))) for b in teams[~good]]
                    continue
                for b in teams[~good]:
                    self._recover_or_brake(b, points, poses, u_nom, out, Au, recovery, fallback)
            if fallback.any() and cfg.strict:
                raise InfeasibleError(self._explain(np.flatnonzero(fallback), points, status))
            if sparse.any():
                Au = vals.products(out)  # the reduced problem left the products of the rows it dropped stale
            elif recovery.any():
                rows_r = recovery[lay.row_team]
                Au[rows_r] = vals.products(out)[rows_r]
        return out.reshape(-1, 2), self._info(vals, out, u_nom, Au, fallback, status, recovery)

    def _scatter(self, need, teams, good, sub, rows, cols, x, Ax, out, Au) -> None:
        """Teams that needed the QP take its answer (padding teams keep their stage-2 answer)."""
        if kernels.enabled():
            safety_kernels.sub_problem_scatter(
                need, teams, good, sub.teams.robot_team, sub.row_team, rows, cols, x, Ax, out, Au
            )
            return
        take = need[teams] & good
        take_c = np.repeat(take[sub.teams.robot_team], 2)
        out[cols[take_c]] = x[take_c]
        take_r = take[sub.row_team]
        Au[rows[take_r]] = Ax[take_r]

    def _recover_or_brake(self, b: int, points, poses, u_nom, out, Au, recovery, fallback) -> None:
        """Team b, for which no command meets the hard rows (outside the safe set): the answer of
        the softened problem (:mod:`comat.safety.recovery`), or a brake if that fails too."""
        t = self.layout.teams
        lo, hi = t.offsets[b], t.offsets[b + 1]
        cols = slice(2 * lo, 2 * hi)
        u_b = None
        if not self.config.strict:
            u_b = recovery_command(points[lo:hi], poses[lo:hi, 2], u_nom[cols], self.config, self.profile)
        if u_b is not None:
            recovery[b] = True
            out[cols] = u_b
        else:
            fallback[b] = True
            out[cols] = 0.0
            Au[self.layout.row_team == b] = 0.0

    def _stages_compiled(self, poses: np.ndarray, u_nom: np.ndarray, c: np.ndarray, s: np.ndarray):
        """Rows and stages 1–2 of :meth:`_filter` in one kernel call (the numpy branch there is
        its reference): points, rows, answer so far, its row products, teams left (mask and
        count), u_wheel."""
        lay, cfg = self.layout, self.config
        t = lay.teams
        R, n_rows = t.n_robots, lay.n_rows
        k, speed, lo, hi = self._row_constants
        points, e = np.empty((R, 2)), np.empty((t.n_pairs, 2))
        lower, upper, Au, Au_wheel = np.empty(n_rows), np.empty(n_rows), np.empty(n_rows), np.empty(n_rows)
        out, u_wheel, need = np.empty(2 * R), np.empty(2 * R), np.empty(t.n_teams, dtype=bool)
        left = safety_kernels.filter_stages(
            poses, c, s, u_nom, cfg.projection_distance_m, t.pair_i, t.pair_j, cfg.safety_distance_m**2,
            cfg.barrier_gain, -cfg.boundary_gain, cfg.boundary_gain, lo, hi, speed, k, cfg.feasibility_tol,
            self._full.wheel_factor, lay.row_team, t.robot_team, points, e, lower, upper, out, Au, u_wheel, Au_wheel,
            need,
        )  # fmt: skip
        return points, RowValues(lay, e, c, s, k, lower, upper), out, Au, need, u_wheel, left

    def _take(self, teams: np.ndarray, out, u, Au, Au_new) -> None:
        """Adopt ``u`` (and its row products) for the flagged teams."""
        lay = self.layout
        if kernels.enabled():
            safety_kernels.take_teams(teams, lay.teams.robot_team, lay.row_team, out, u, Au, Au_new)
            return
        robots = teams[lay.teams.robot_team]
        out[np.repeat(robots, 2)] = u[np.repeat(robots, 2)]
        rows = teams[lay.row_team]
        Au[rows] = Au_new[rows]

    def _qp(self, sizes: tuple[int, ...], config: SafetyConfig) -> BarrierQP:
        key = (sizes, config.eps)
        qp = self._qps.get(key)
        if qp is None:
            qp = BarrierQP(sizes, config, self.profile)
            self._qps[key] = qp
            if len(self._qps) > _MAX_CACHED_QPS:
                self._qps.popitem(last=False)
        else:
            self._qps.move_to_end(key)
        return qp

    def _qp_teams(self, need: np.ndarray) -> np.ndarray:
        """Teams that go into this tick's QP: those that need it, padded with others.

        Each distinct tuple of team sizes is its own OSQP problem (set up once, ~1 ms), so the
        count is rounded up to a multiple of 4 teams, or to all teams once more than half need
        it; padding teams solve to the answer they already have. (Measured with 16 PCP
        environments: padding to 8 made OSQP ~30 % slower per tick than 1, 2 or 4, which
        differ by less than the noise; 4 needs the fewest set-ups of those.)
        """
        if kernels.enabled():
            return safety_kernels.qp_teams(need, self._sizes, _QP_TEAM_BLOCK)
        t = self.layout.teams
        teams = np.flatnonzero(need)
        k = teams.size
        if k <= 1:
            return teams
        target = t.n_teams if 2 * k > t.n_teams else min(t.n_teams, -(-k // _QP_TEAM_BLOCK) * _QP_TEAM_BLOCK)
        if target == t.n_teams:
            return np.arange(t.n_teams)
        if target > k:
            teams = np.sort(np.concatenate([teams, np.flatnonzero(~need)[: target - k]]))
        # Teams ordered by size: the problem depends only on how many teams of each size it
        # holds (a few dozen problems to set up instead of hundreds).
        return teams[np.argsort(self._sizes[teams], kind="stable")]

    def _sub_indices(self, order: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The full problem's rows, columns and nonzeros of a sub-problem of teams ``order``."""
        t = self.layout.teams
        if kernels.enabled():
            return safety_kernels.sub_problem_indices(order, self._sizes, t.offsets, t.n_pairs, t.n_robots)
        n = t.n_teams
        rows = [np.flatnonzero(self._row_kind_team == kind * n + b) for kind in range(3) for b in order]
        nnz = [np.flatnonzero(self._nnz_kind_team == kind * n + b) for kind in range(3) for b in order]
        cols = [np.arange(2 * t.offsets[b], 2 * t.offsets[b + 1]) for b in order]
        return np.concatenate(rows), np.concatenate(cols), np.concatenate(nnz)

    def _solve(self, teams: np.ndarray, vals, u_nom, config, x0, reduced: CoupledRows | None = None):
        """Solve the QP of the given teams only.

        The rows are those of the full problem restricted to the teams, in the teams' order; with
        ``reduced`` (teams of ``sparse_from`` robots or more) only its rows and robots
        (:mod:`comat.safety.sparse`; the caller gives the others their stage-2 command). Warm
        start: primal from the wheel projection, duals from each row's last solve (the set of
        teams in a problem changes from tick to tick, so the solver's own memory is not theirs).

        Returns:
            x (2R_sub,), A_sub @ x, per-team trust (k,) in the order of ``teams``, the full-layout rows and the columns
            of ``u`` that the sub-problem covers, OSQP's status and the sub-problem's layout.
        """
        lay = self.layout
        t = lay.teams
        if self._data is None:
            self._data = vals.data()
        if reduced is None and teams.size == t.n_teams:  # the whole batch: no slicing
            qp = self._qp(t.team_sizes, config)
            res = qp.solve(qp.matrix(self._data), vals, u_nom, x0=x0, y0=self._duals)
            self._duals = res.y
            rows, cols = self._all_rows, self._all_cols
        else:
            if reduced is None:
                rows, cols, nnz = self._sub_indices(teams)
                qp = self._qp(tuple(self._sizes[teams].tolist()), config)
            else:
                rows, cols, nnz = reduced.rows, reduced.cols, reduced.nnz
                qp = self._reduced_qp(reduced, config)
            if kernels.enabled():
                A, sub, u_sub, x0_sub, y0_sub = self._gather_compiled(qp, rows, cols, nnz, vals, u_nom, x0)
            else:
                A, sub = qp.matrix(self._data[nnz]), _Bounds(vals.lower[rows], vals.upper[rows], qp.layout)
                u_sub, x0_sub, y0_sub = u_nom[cols], x0[cols], self._duals[rows]
            res = qp.solve(A, sub, u_sub, x0=x0_sub, y0=y0_sub)
            self._duals[rows] = res.y
        self.last_solver_s += res.solver_wall_s
        self.last_solver_c_s += res.solver_c_s
        return res.x, res.Ax, res.good, rows, cols, res.status, qp.layout

    def _reduced_qp(self, red: CoupledRows, config: SafetyConfig) -> BarrierQP:
        """The OSQP problem of a reduced problem: the kept pattern's own while it lasts (set up
        once, then updated in place like the cached ones), a fresh one for the rare others."""
        if config is self.config and self._pattern_qp is not None and self._pattern_qp[0] is red:
            return self._pattern_qp[1]
        qp = BarrierQP(tuple(red.sizes.tolist()), config, self.profile, (red.pair_i, red.pair_j))
        if config is self.config and red is self._pattern.current:
            self._pattern_qp = (red, qp)
        return qp

    def _gather_compiled(self, qp: BarrierQP, rows, cols, nnz, vals, u_nom, x0):
        """The sub-problem's matrix, bounds, nominal and warm start, gathered in one kernel call
        (the numpy branch in :meth:`_solve` is its reference)."""
        m, n = rows.size, cols.size
        lower, upper, y0, u_sub, x0_sub = np.empty(m), np.empty(m), np.empty(m), np.empty(n), np.empty(n)
        A = qp.pattern
        safety_kernels.sub_problem_gather(
            rows, cols, nnz, qp.perm, self._data, vals.lower, vals.upper, u_nom, x0, self._duals, A.data,
            lower, upper, u_sub, x0_sub, y0,
        )  # fmt: skip
        return A, _Bounds(lower, upper, qp.layout), u_sub, x0_sub, y0

    def _project_wheels(self, u: np.ndarray, c: np.ndarray, s: np.ndarray) -> np.ndarray:
        """Closest velocities (2R,) inside each robot's reduced wheel-limit rhombus."""
        cfg = self.config
        return limit_to_wheels(
            u.reshape(-1, 2), None, cfg.projection_distance_m, self.profile, cfg.wheel_speed_fraction, (c, s)
        ).ravel()

    def _info(self, vals, out, u_nom, Au, fallback, status, recovery) -> SafetyInfo:
        t = self.layout.teams
        if kernels.enabled():
            robot_norm2, intervention = np.empty(t.n_robots), np.empty(t.n_teams)
            safety_kernels.interventions(out, u_nom, t.robot_team, t.n_teams, robot_norm2, intervention)
        else:
            diff = out - u_nom
            robot_norm2 = diff[0::2] ** 2 + diff[1::2] ** 2
            intervention = np.sqrt(np.bincount(t.robot_team, weights=robot_norm2, minlength=t.n_teams))
        return SafetyInfo(
            self, vals, Au, intervention, robot_norm2 > 0.0, fallback, status, self.last_solver_c_s, recovery
        )

    def _explain(self, teams: np.ndarray, points: np.ndarray, status: str) -> str:
        t, cfg = self.layout.teams, self.config
        parts = []
        for b in teams[:5]:
            p = points[t.offsets[b] : t.offsets[b + 1]]
            d = np.linalg.norm(p[:, None] - p[None], axis=-1) + np.eye(len(p)) * 1e9
            i, j = np.unravel_index(np.argmin(d), d.shape)
            parts.append(
                f"team {b}: closest projected points robots {i} and {j} at {d[i, j]:.3f} m "
                f"(safety distance {cfg.safety_distance_m} m)"
            )
        return (
            f"safety filter found no safe command (solver status {status!r}) for {len(teams)} team(s): "
            + "; ".join(parts)
            + ". Start robots at least the safety distance apart and inside the arena margin, "
            "or use strict=False to brake instead."
        )
