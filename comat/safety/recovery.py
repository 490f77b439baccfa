"""Recovery outside the safe set: the barrier QP with its barrier and boundary rows softened.

Inside the safe set (every projected-point pair at least the safety distance apart, every point
inside the arena margin) the hard QP of :mod:`comat.safety.constraints` is feasible: u = 0 meets
every row. Outside it — a team that starts inside the safety distance, or is pushed there — a
row ḣ >= −γ·h with h < 0 demands a recovery rate γ·|h| that the wheel limits may not deliver,
the hard QP is infeasible, and braking would hold the team there forever. For such a team the
filter solves instead::

    min ½‖u − û‖² + ½·ρ·‖s‖²
    s.t.  pair rows      a·u − s_k <= b_k                 (s_k >= 0)
          boundary rows  l_k − s_k <= u_k <= h_k + s_k     (s_k >= 0)
          wheel rows     |a_w·u| <= v                       hard

which is always feasible (u = 0 with large slacks). With ρ ≫ 1 the slacks come first: every
violated barrier value is driven back toward the safe set at the best rate the wheels allow;
then, in the directions that leaves free, the answer stays as close to the nominal command as it
can. The wheel rows are never relaxed, so the answer is always realizable by the motors.
"""

from __future__ import annotations

import numpy as np
import osqp
import scipy.sparse as sp

from comat import constants as C
from comat.config import SafetyConfig
from comat.safety.constraints import OSQP_INFINITY, make_layout, row_values
from comat.safety.qp import new_osqp
from comat.sim.kinematics import WHEEL_LIMIT_TOLERANCE

__all__ = ["SLACK_WEIGHT", "recovery_command"]

SLACK_WEIGHT = 1e4
"""ρ: weight of the squared slacks against the squared deviation from the nominal command.
Row values are O(0.01–0.1) (m²/s, m/s) and commands O(0.1 m/s): ρ = 1e4 makes a 1e-3 slack
cost as much as a 0.1 m/s deviation."""


def recovery_command(
    points: np.ndarray,
    headings: np.ndarray,
    u_nom: np.ndarray,
    config: SafetyConfig,
    profile: C.RobotProfile = C.DEFAULT_PROFILE,
) -> np.ndarray | None:
    """The softened problem above for one team of n robots.

    Args:
        points: (n, 2) projected points; headings: (n,) rad; u_nom: (2n,) nominal velocities.

    Returns:
        u (2n,), meeting every wheel row at the true wheel limit; None when the solver failed
        (the caller brakes).
    """
    n = points.shape[0]
    layout = make_layout((n,))
    vals = row_values(layout, points, headings, config, profile)
    A = sp.csr_matrix((vals.data(), (layout.rows, layout.cols)), shape=(layout.n_rows, 2 * n))
    P, R2 = layout.teams.n_pairs, 2 * n
    m = P + R2  # soft rows: pairs and boundary
    pair, bound, wheel = A[:P], A[P : P + R2], A[P + R2 :]
    I_s = sp.identity(m, format="csr")
    zero_ws = sp.csr_matrix((R2, m))
    rows = sp.vstack(
        [
            sp.hstack([pair, -I_s[:P]]),  # a·u − s <= b
            sp.hstack([bound, I_s[P:]]),  # u + s >= l
            sp.hstack([bound, -I_s[P:]]),  # u − s <= h
            sp.hstack([wheel, zero_ws]),  # hard
            sp.hstack([sp.csr_matrix((m, R2)), I_s]),  # s >= 0
        ],
        format="csc",
    )
    inf = OSQP_INFINITY
    lo, up = vals.lower, vals.upper
    lower = np.concatenate([np.full(P, -inf), lo[P : P + R2], np.full(R2, -inf), lo[P + R2 :], np.zeros(m)])
    upper = np.concatenate([up[:P], np.full(R2, inf), up[P : P + R2], up[P + R2 :], np.full(m, inf)])
    cost = sp.diags(np.concatenate([np.ones(R2), np.full(m, SLACK_WEIGHT)]), format="csc")
    solver = new_osqp()
    solver.setup(
        cost,
        np.concatenate([-u_nom, np.zeros(m)]),
        rows,
        lower,
        upper,
        verbose=False,
        eps_abs=config.eps * 1e-2,
        eps_rel=config.eps * 1e-2,
        max_iter=10 * config.max_iter,
        polishing=True,
    )
    result = solver.solve(raise_error=False)  # failures are handled below (the caller brakes)
    if result.info.status_val != osqp.SolverStatus.OSQP_SOLVED or not np.all(np.isfinite(result.x)):
        return None
    u = np.array(result.x[:R2])
    # Unpolished answers may exceed a wheel row by ~eps: scale each robot's command into its
    # rhombus (u = 0 is always inside), so the motors never see more than the limit.
    speed = vals.upper[P + R2 :] * WHEEL_LIMIT_TOLERANCE
    over = np.abs(wheel @ u) / speed  # (2n,) rows 2r, 2r+1 belong to robot r
    scale = 1.0 / np.maximum(1.0, over.reshape(n, 2).max(1))
    return u * np.repeat(scale, 2)
