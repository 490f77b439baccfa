"""Liveness beside safety: do the robots of a battery episode get where they were sent, and when?

A filter that stops every robot is perfectly safe. The battery therefore measures, for the
scenarios whose goals can all be held at once (:func:`live_goals`), three things per episode:

=====================  ==========================================================================
measure                definition
=====================  ==========================================================================
arrival tick (R,)      the first tick a robot's true projected point is within
                       :data:`GOAL_TOLERANCE_M` of its goal (−1: never); robots that start there
                       (``movers`` False) are left out of every share
liveness at k×         share of movers at their goal (arrived) by ``k · T_off`` of their episode,
                       k = 1 and 2; ``T_off`` is the tick by which the same episode (same teams,
                       requested starts, seed and loop) at reality ``off`` had every mover that
                       ever arrived there arrived (its horizon if none did)
team freeze            a team whose movers not at their goals all moved their true projected
                       points less than :data:`FREEZE_MOVE_M` over the last
                       :data:`FREEZE_TICKS` ticks (3 s), while not every mover is at its goal;
                       counted once per onset
=====================  ==========================================================================

Why 3 s: comat's deadlock tie-break turns a robot held still for 1 s to its right for 1 s
(:data:`comat.safety.deployed.HOLD_TICKS`, :data:`~comat.safety.deployed.DETOUR_TICKS`); a team
still for 3 s is one the tie-break fired in and did not set moving, not a pause of the rule
itself, a Wi-Fi brake (0.5 s) or a script stall (0.26 s on average at ``stress``). 2 cm in 3 s
is under 4 % of the 0.2 m/s top speed, above the true wobble of a robot held still.

Why 0.1 m: at ``stress`` the wheels' dead zone (3 rad/s, 0.048 m/s at the point) stops the gain-1
waypoint controller about 5 cm short of its goal, plus the tracker's bias and noise; the goals of
a live scenario are at least :data:`LIVE_GOAL_SPACING_M` apart, so 0.1 m still names one goal.
"""

from __future__ import annotations

import numpy as np

from comat import constants as C

__all__ = [
    "FREEZE_MOVE_M",
    "FREEZE_TICKS",
    "GOAL_TOLERANCE_M",
    "LIVE_GOAL_SPACING_M",
    "LivenessTracker",
    "arrival_lists",
    "live_goals",
    "liveness_shares",
    "off_times",
    "row_liveness",
]

GOAL_TOLERANCE_M = 0.1
"""A robot is at its goal when its true projected point is this close (m)."""
FREEZE_TICKS = 91
"""Ticks (3 s at 0.033 s) a team must stand still to count as frozen."""
FREEZE_MOVE_M = 0.02
"""Net displacement (m) over :data:`FREEZE_TICKS` under which a robot stands still."""
LIVE_GOAL_SPACING_M = 0.31
"""Goals of a team at least this far apart (m; above ``stress``'s robust safety distance 0.303 m)
and inside the arena by the ``stress`` boundary margin: every robot can be at its goal at once."""
_LIVE_MARGIN_M = 0.16


def live_goals(goals: np.ndarray, team_sizes: tuple[int, ...]) -> bool:
    """Every team's goals (R, 2) can be held at once (pairwise spacing and boundary margin)."""
    x0, x1, y0, y1 = C.ARENA_BOUNDS_M
    m = _LIVE_MARGIN_M
    inside = (goals[:, 0] >= x0 + m) & (goals[:, 0] <= x1 - m) & (goals[:, 1] >= y0 + m) & (goals[:, 1] <= y1 - m)
    if not inside.all():
        return False
    start = 0
    for n in team_sizes:
        g = goals[start : start + n]
        start += n
        i, j = np.triu_indices(n, 1)
        if i.size and np.hypot(*(g[i] - g[j]).T).min() < LIVE_GOAL_SPACING_M:
            return False
    return True


class LivenessTracker:
    """Per tick, from the true projected points (R, 2): first arrivals and team freezes.

    Args:
        goals: (R, 2) the projected points' goals.
        robot_team: (R,) team index of each robot.
        n_teams: B.
        start_points: (R, 2) the true projected points at the start (movers: those not at goal).
    """

    def __init__(self, goals: np.ndarray, robot_team: np.ndarray, n_teams: int, start_points: np.ndarray) -> None:
        self.goals = goals
        self.team = robot_team
        self.n_teams = n_teams
        self.movers = np.hypot(*(start_points - goals).T) > GOAL_TOLERANCE_M
        """(R,) robots that start away from their goals (the only ones counted)."""
        self.arrival = np.full(goals.shape[0], -1, np.int64)
        """(R,) first tick at the goal, −1 never."""
        self.freezes = np.zeros(n_teams, np.int64)
        """(B,) onsets of a team freeze."""
        self.frozen_ticks = np.zeros(n_teams, np.int64)
        """(B,) ticks spent frozen."""
        self._ring = np.repeat(start_points[:, None], FREEZE_TICKS, axis=1)
        self._frozen = np.zeros(n_teams, dtype=bool)
        self._tick = 0

    def update(self, points: np.ndarray) -> None:
        """This tick's true projected points (R, 2)."""
        t = self._tick
        at = np.hypot(*(points - self.goals).T) <= GOAL_TOLERANCE_M
        self.arrival[(self.arrival < 0) & at] = t
        slot = t % FREEZE_TICKS
        if t >= FREEZE_TICKS:
            moved = np.hypot(*(points - self._ring[:, slot]).T) >= FREEZE_MOVE_M
            pending = self.movers & ~at
            # a team is frozen when none of its pending movers moved and some mover is pending
            moving = np.bincount(self.team, weights=pending & moved, minlength=self.n_teams) > 0
            waiting = np.bincount(self.team, weights=pending, minlength=self.n_teams) > 0
            frozen = waiting & ~moving
            self.freezes += frozen & ~self._frozen
            self.frozen_ticks += frozen
            self._frozen = frozen
        self._ring[:, slot] = points
        self._tick += 1


def off_times(
    arrival: np.ndarray, movers: np.ndarray, robot_team: np.ndarray, n_teams: int, horizon: int
) -> np.ndarray:
    """(B,) ``T_off`` per episode from the ``off`` run's arrival ticks (R,): the last arrival of a
    mover that arrived, ``horizon`` where none did."""
    t = np.full(n_teams, -1, np.int64)
    ok = movers & (arrival >= 0)
    np.maximum.at(t, robot_team[ok], arrival[ok])
    return np.where(t < 0, horizon, t)


def liveness_shares(
    arrival: np.ndarray, movers: np.ndarray, robot_team: np.ndarray, t_off: np.ndarray, multiples=(1, 2)
) -> dict:
    """Share of movers arrived by ``k · T_off`` of their episode, per k in ``multiples``."""
    n = int(movers.sum())
    out = {}
    for k in multiples:
        by = k * t_off[robot_team]
        out[f"{k}x"] = float(((arrival >= 0) & (arrival <= by) & movers).sum() / n) if n else float("nan")
    return out


def row_liveness(arrival: list, off_arrival: list, horizon_off: int, ticks: int) -> dict:
    """A battery row's liveness against its ``off`` row: ``arrival`` and ``off_arrival`` are per
    episode the arrival ticks of the movers (None for a robot that starts at its goal), as
    :func:`arrival_lists` writes them. Returns the shares at 1× and 2× ``T_off``, the share that
    arrived by the row's own horizon ``ticks``, and the episodes whose 2 × ``T_off`` passed
    ``ticks`` (counted at ``ticks``: ``capped``)."""
    sizes = [len(a) for a in arrival]
    team = np.repeat(np.arange(len(sizes)), sizes)
    flat = np.array([-1 if t is None else t for a in arrival for t in a], np.int64)
    movers = np.array([t is not None for a in arrival for t in a])
    off = np.array([-1 if t is None else t for a in off_arrival for t in a], np.int64)
    t_off = off_times(off, movers, team, len(sizes), horizon_off)
    out = liveness_shares(flat, movers, team, t_off)
    out["by_horizon"] = float(((flat >= 0) & movers).sum() / max(int(movers.sum()), 1))
    out["capped"] = int((2 * t_off > ticks).sum())
    out["t_off_median_s"] = float(np.median(t_off) * C.CONTROL_DT_S)
    return out


def arrival_lists(arrival: np.ndarray, movers: np.ndarray, team_sizes: tuple[int, ...]) -> list:
    """Per episode, the arrival ticks (R,) of its robots as a JSON-ready list (None: not a mover)."""
    out, start = [], 0
    for n in team_sizes:
        out.append([int(a) if m else None for a, m in zip(arrival[start : start + n], movers[start : start + n])])
        start += n
    return out
