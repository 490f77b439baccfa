"""OSQP control-barrier-function filter for one or many teams (one block-diagonal QP per tick).

Per tick and team: ``min ½‖u - û‖²`` over the projected-point velocities u, subject to the
rows of :mod:`comat.safety.constraints` (pairwise barrier, arena boundary, exact wheel limits).

* Set up once per tuple of team sizes (fixed sparsity); each tick only updates ``q``, the
  bounds and the nonzeros in place (``update(Ax=...)``) and warm-starts from the last answer.
* A team whose nominal command already satisfies every row gets it back bit for bit, and if
  every team does, no QP is solved at all.
* The answer is never trusted blindly: a team passes only if OSQP reports *solved* and its
  solution satisfies its rows within ``feasibility_tol``. Otherwise the whole batch is re-solved
  team by team, and a team that still fails brakes (zero velocity) — counted in
  :class:`SafetyInfo` — or, with ``strict=True``, raises :class:`InfeasibleError`.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import osqp
import scipy.sparse as sp

from comat import constants as C
from comat._validate import as_float_array
from comat.config import SafetyConfig
from comat.safety.constraints import Layout, make_layout, row_values
from comat.sim.kinematics import projected_points, si_to_uni, uni_to_si

__all__ = ["InfeasibleError", "SafetyFilter", "SafetyInfo"]

_SOLVED = osqp.SolverStatus.OSQP_SOLVED


class InfeasibleError(RuntimeError):
    """Raised in strict mode when no safe command exists for a team (or the solver failed)."""


@dataclass
class SafetyInfo:
    """What the filter did in one tick.

    Attributes:
        intervention: (B,) ‖u - û‖ per team (m/s), 0 where the nominal command was kept.
        robot_intervened: (R,) bool, robot's command changed by more than 1e-9 m/s.
        active_pairs: (B,) pair rows active (barrier holding the team apart).
        active_boundary: (B,) boundary rows active.
        active_wheels: (B,) wheel-limit rows active.
        fallback: (B,) bool, team braked because its QP had no trusted solution.
        status: OSQP status text of the batch solve (``"skipped"`` if none was needed).
        solve_time_s: OSQP's own time (update + solve + polish), 0 if skipped.
        min_pair_distance: (B,) smallest projected-point distance in the team (inf if N=1).
    """

    intervention: np.ndarray
    robot_intervened: np.ndarray
    active_pairs: np.ndarray
    active_boundary: np.ndarray
    active_wheels: np.ndarray
    fallback: np.ndarray
    status: str
    solve_time_s: float
    min_pair_distance: np.ndarray


class SafetyFilter:
    """Barrier filter for teams of fixed sizes; ``filter`` is called once per control tick.

    Args:
        team_sizes: robots per team (an int for a single team).
        config: barrier geometry, gains and solver tolerances.
        profile: robot profile (wheel limits, axle length).
    """

    def __init__(
        self,
        team_sizes: int | Sequence[int],
        config: SafetyConfig | None = None,
        profile: C.RobotProfile = C.DEFAULT_PROFILE,
    ) -> None:
        sizes = (team_sizes,) if isinstance(team_sizes, (int, np.integer)) else tuple(team_sizes)
        if not sizes or any(isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1 for n in sizes):
            raise ValueError(f"team_sizes must be positive integers, got {team_sizes!r}")
        self.config = config or SafetyConfig()
        self.profile = profile
        self.layout: Layout = make_layout(sizes)
        lay = self.layout
        R = lay.teams.n_robots
        # CSC order of our nonzeros: build once with data = 1..nnz, read the permutation back.
        coo = sp.coo_matrix(
            (np.arange(1, lay.rows.size + 1, dtype=np.float64), (lay.rows, lay.cols)), shape=(lay.n_rows, 2 * R)
        )
        csc = coo.tocsc()
        self._perm = csc.data.astype(np.int64) - 1
        self._A_pattern = csc
        self._P = sp.identity(2 * R, format="csc")
        self._solver: osqp.OSQP | None = None
        self.last_solver_s = 0.0
        """Wall time of the last tick's OSQP setup/update/solve calls (0 if none was needed)."""
        self._single: dict[int, SafetyFilter] = {}
        self._is_retry = False

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
    def _filter(self, poses: np.ndarray, dxi: np.ndarray) -> tuple[np.ndarray, SafetyInfo]:
        lay, cfg = self.layout, self.config
        self.last_solver_s = 0.0
        points = projected_points(poses, cfg.projection_distance_m)
        vals = row_values(lay, points, poses[:, 2], cfg, self.profile)
        A = self._matrix(vals.data)
        u_nom = dxi.ravel()
        B = lay.teams.n_teams
        # The nominal command is kept if it respects the true wheel limit; only the QP's own
        # answer is held to the reduced limit (wheel_speed_fraction) that absorbs solver tolerance.
        wheel_rows = slice(lay.teams.n_pairs + 2 * lay.teams.n_robots, None)
        lo_nom, up_nom = vals.lower.copy(), vals.upper.copy()
        lo_nom[wheel_rows] /= cfg.wheel_speed_fraction
        up_nom[wheel_rows] /= cfg.wheel_speed_fraction
        team_ok = self._teams_feasible(A @ u_nom, lo_nom, up_nom)
        out = u_nom.copy()
        fallback = np.zeros(B, dtype=bool)
        status, solve_time = "skipped", 0.0
        y = np.zeros(lay.n_rows)
        if not team_ok.all():
            x, y, status, solve_time, good = self._solve(A, vals, u_nom)
            redo = ~good & ~team_ok
            if redo.any() and not self._is_retry:
                x, y, fallback, extra = self._solve_per_team(poses, dxi, x, y, redo)
                solve_time += extra
            else:
                fallback = redo
            solved = ~team_ok & ~fallback
            mask = solved[self.layout.teams.robot_team].repeat(2)
            out[mask] = x[mask]
            fb_mask = fallback[lay.teams.robot_team].repeat(2)
            out[fb_mask] = 0.0
            if fallback.any() and cfg.strict:
                raise InfeasibleError(self._explain(np.flatnonzero(fallback), points, status))
        return out.reshape(-1, 2), self._info(out, u_nom, y, fallback, status, solve_time, points, team_ok)

    def _matrix(self, data: np.ndarray) -> sp.csc_matrix:
        A = self._A_pattern.copy()
        A.data = data[self._perm]
        return A

    def _teams_feasible(self, Au: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
        """(B,) True where every row of the team holds within feasibility_tol."""
        viol = np.maximum(Au - upper, lower - Au) > self.config.feasibility_tol
        return self._per_team(viol) == 0

    def _per_team(self, row_flags: np.ndarray, rows: slice = slice(None)) -> np.ndarray:
        """(B,) number of flagged rows per team, over the row range ``rows``."""
        team = self.layout.row_team[rows]
        return np.bincount(team, weights=row_flags[rows], minlength=self.layout.teams.n_teams).astype(np.int64)

    def _solve(self, A: sp.csc_matrix, vals, u_nom: np.ndarray):
        cfg = self.config
        q = -u_nom
        t0 = time.perf_counter()
        if self._solver is None:
            self._solver = osqp.OSQP()
            self._solver.setup(
                self._P,
                q,
                A,
                vals.lower,
                vals.upper,
                verbose=False,
                eps_abs=cfg.eps,
                eps_rel=cfg.eps,
                max_iter=cfg.max_iter,
                polishing=True,
                warm_starting=True,
                check_termination=10,
            )
        else:
            self._solver.update(q=q, l=vals.lower, u=vals.upper, Ax=A.data)
        res = self._solver.solve(raise_error=False)
        self.last_solver_s += time.perf_counter() - t0
        info = res.info
        t = float(info.update_time + info.solve_time + info.polish_time)
        if info.status_val != _SOLVED or res.x is None or not np.all(np.isfinite(res.x)):
            good = np.zeros(self.layout.teams.n_teams, dtype=bool)
            return np.zeros_like(u_nom), np.zeros(self.layout.n_rows), info.status, t, good
        x = self._repair(A, vals, res.x)
        good = self._teams_feasible(A @ x, vals.lower, vals.upper)
        return x, res.y, info.status, t, good

    def _repair(self, A: sp.csc_matrix, vals, x: np.ndarray) -> np.ndarray:
        """Scale each team's answer toward 0 until it meets every row exactly.

        An unpolished ADMM answer may miss rows by ~eps. Where u = 0 is feasible for the team
        (the state is safe: all barrier values h >= 0 and robots inside the margin), every row
        is a·u <= b with b >= 0 or a·u >= b with b <= 0, so scaling u by the smallest b/(a·u)
        over the missed rows lands inside the polytope; the change is of the order of eps.
        """
        lay = self.layout
        Ax = A @ x
        over, under = Ax > vals.upper, Ax < vals.lower
        if not (over.any() or under.any()):
            return x
        zero_ok = self._per_team((vals.lower > 0) | (vals.upper < 0)) == 0
        ratio = np.ones(lay.n_rows)
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio[over] = vals.upper[over] / Ax[over]
            ratio[under] = vals.lower[under] / Ax[under]
        alpha = np.ones(lay.teams.n_teams)
        np.minimum.at(alpha, lay.row_team, np.clip(ratio, 0.0, 1.0))
        alpha = np.where(zero_ok, alpha * (1.0 - 1e-12), 1.0)
        return x * np.repeat(alpha[lay.teams.robot_team], 2)

    def _solve_per_team(self, poses, dxi, x, y, redo):
        """Re-solve the teams whose batch answer was not trusted, each on its own, more precisely."""
        lay = self.layout
        fallback = np.zeros(lay.teams.n_teams, dtype=bool)
        x, y = x.copy(), y.copy()
        extra = 0.0
        for b in np.flatnonzero(redo):
            n = lay.teams.team_sizes[b]
            sl = slice(lay.teams.offsets[b], lay.teams.offsets[b + 1])
            single = self._single.get(n)
            if single is None:
                # Retry with a 1000x tighter tolerance: a team whose state is just outside the
                # safe set (h slightly < 0 after a tick) needs an accurate answer, not a repair.
                precise = dataclasses.replace(self.config, strict=False, eps=self.config.eps * 1e-3)
                single = self._single[n] = SafetyFilter(n, precise, self.profile)
                single._is_retry = True
            safe, info = single._filter(poses[sl], dxi[sl])
            self.last_solver_s += single.last_solver_s
            extra += info.solve_time_s
            fallback[b] = bool(info.fallback[0])
            x[2 * sl.start : 2 * sl.stop] = safe.ravel()
        return x, y, fallback, extra

    def _info(self, out, u_nom, y, fallback, status, solve_time, points, team_ok) -> SafetyInfo:
        lay = self.layout
        diff = (out - u_nom).reshape(-1, 2)
        robot_norm2 = np.einsum("rk,rk->r", diff, diff)
        B = lay.teams.n_teams
        intervention = np.sqrt(np.bincount(lay.teams.robot_team, weights=robot_norm2, minlength=B))
        # Rows of teams that kept their command or braked are not "active" whatever y says.
        active = (np.abs(y) > 1e-9) & ~(team_ok | fallback)[lay.row_team]
        P, R = lay.teams.n_pairs, lay.teams.n_robots
        pairs = self._per_team(active, slice(0, P))
        bnd = self._per_team(active, slice(P, P + 2 * R))
        whl = self._per_team(active, slice(P + 2 * R, None))
        e = points[lay.teams.pair_i] - points[lay.teams.pair_j]
        dist = np.sqrt(np.einsum("pk,pk->p", e, e))
        min_d = np.full(B, np.inf)
        np.minimum.at(min_d, lay.teams.pair_team, dist)
        return SafetyInfo(
            intervention=intervention,
            robot_intervened=robot_norm2 > 1e-18,
            active_pairs=pairs,
            active_boundary=bnd,
            active_wheels=whl,
            fallback=fallback,
            status=status,
            solve_time_s=solve_time,
            min_pair_distance=min_d,
        )

    def _explain(self, teams: np.ndarray, points: np.ndarray, status: str) -> str:
        lay, cfg = self.layout, self.config
        parts = []
        for b in teams[:5]:
            sl = slice(lay.teams.offsets[b], lay.teams.offsets[b + 1])
            p = points[sl]
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
