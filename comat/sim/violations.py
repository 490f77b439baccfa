"""Robotarium-style error checks and counters, vectorized over all robots of all teams.

The Robotarium's ``_validate`` (rps legacy) flags, every iteration: a *collision* when two
robots' centres, each moved 0.025 m forward along its heading, are <= 0.135 m apart; a
*boundary* error when a centre is outside the arena; an *actuator* error when a requested wheel
speed exceeds 12.5 rad/s. We check the same on the pose after each tick (rps checks the pose
before integrating, which differs only at the last iteration), and add MuJoCo's own
robot–robot and robot–wall contacts.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from comat import constants as C
from comat import kernels
from comat.sim.kinematics import projected_points

__all__ = ["TickEvents", "Violations", "check_tick"]

_BOUNDS = np.array(C.ARENA_BOUNDS_M, dtype=np.float64)  # x0, x1, y0, y1


@dataclass
class TickEvents:
    """Events of one control tick, per robot (R,) unless stated.

    Attributes:
        collision: robot is in a Robotarium collision with some other robot.
        collision_pairs: (B,) number of colliding pairs per team.
        boundary: robot centre outside the arena.
        actuator: requested command exceeded a wheel limit (before clipping).
        robot_contact: chassis touched another robot in MuJoCo during the tick.
        wall_contact: chassis touched a wall in MuJoCo during the tick.
    """

    collision: np.ndarray
    collision_pairs: np.ndarray
    boundary: np.ndarray
    actuator: np.ndarray
    robot_contact: np.ndarray
    wall_contact: np.ndarray


def check_tick(
    poses: np.ndarray,
    pair_i: np.ndarray,
    pair_j: np.ndarray,
    pair_team: np.ndarray,
    n_teams: int,
    actuator: np.ndarray,
    robot_contact: np.ndarray,
    wall_contact: np.ndarray,
    cos_sin: tuple[np.ndarray, np.ndarray] | None = None,
) -> TickEvents:
    """Robotarium checks on poses (R, 3) for the given same-team pairs (P,).

    ``cos_sin`` may pass the headings' cosines and sines when the caller has them already.
    """
    if kernels.enabled():
        c, s = cos_sin if cos_sin is not None else (np.cos(poses[:, 2]), np.sin(poses[:, 2]))
        R = poses.shape[0]
        collision, boundary, pairs = np.empty(R, dtype=bool), np.empty(R, dtype=bool), np.empty(n_teams, np.int64)
        d2 = C.COLLISION_DIAMETER_M**2
        kernels.check_tick_into(
            poses, c, s, C.COLLISION_OFFSET_M, d2, pair_i, pair_j, pair_team, _BOUNDS, collision, pairs, boundary
        )
        return TickEvents(collision, pairs, boundary, actuator, robot_contact, wall_contact)
    pts = projected_points(poses, C.COLLISION_OFFSET_M)
    d = np.take(pts, pair_i, axis=0) - np.take(pts, pair_j, axis=0)
    close = d[:, 0] ** 2 + d[:, 1] ** 2 <= C.COLLISION_DIAMETER_M**2
    collision = np.zeros(poses.shape[0], dtype=bool)
    collision[pair_i[close]] = True
    collision[pair_j[close]] = True
    x0, x1, y0, y1 = C.ARENA_BOUNDS_M
    x, y = poses[:, 0], poses[:, 1]
    boundary = (x < x0) | (x > x1) | (y < y0) | (y > y1)
    return TickEvents(
        collision=collision,
        collision_pairs=np.bincount(pair_team[close], minlength=n_teams),
        boundary=boundary,
        actuator=actuator,
        robot_contact=robot_contact,
        wall_contact=wall_contact,
    )


@dataclass
class Violations:
    """Running counts since the last reset, per team (B,) or per robot (R,).

    Attributes:
        collision_pairs: (B,) Σ over ticks of colliding pairs (rps V2 ``robots_too_close``).
        collision_ticks: (R,) ticks each robot was in a collision (rps legacy per-robot count).
        boundary_ticks: (R,) ticks each robot was outside the arena.
        actuator_ticks: (B,) ticks with any actuator error in the team.
        contact_ticks: (R,) ticks each robot touched another robot in MuJoCo.
        contact_onsets: (R,) times a robot–robot contact began (collision events).
        wall_ticks: (R,) ticks each robot touched a wall in MuJoCo.
    """

    robot_team: np.ndarray
    n_teams: int
    collision_pairs: np.ndarray = field(init=False)
    collision_ticks: np.ndarray = field(init=False)
    boundary_ticks: np.ndarray = field(init=False)
    actuator_ticks: np.ndarray = field(init=False)
    contact_ticks: np.ndarray = field(init=False)
    contact_onsets: np.ndarray = field(init=False)
    wall_ticks: np.ndarray = field(init=False)
    _last_contact: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        R, B = self.robot_team.size, self.n_teams
        self.collision_pairs = np.zeros(B, np.int64)
        self.actuator_ticks = np.zeros(B, np.int64)
        for name in ("collision_ticks", "boundary_ticks", "contact_ticks", "contact_onsets", "wall_ticks"):
            setattr(self, name, np.zeros(R, np.int64))
        self._last_contact = np.zeros(R, dtype=bool)

    def add(self, ev: TickEvents) -> None:
        self.collision_pairs += ev.collision_pairs
        if kernels.enabled():
            kernels.violations_add(
                self.robot_team, ev.collision, ev.boundary, ev.actuator, ev.robot_contact, ev.wall_contact,
                self._last_contact, self.collision_ticks, self.boundary_ticks, self.actuator_ticks,
                self.contact_ticks, self.contact_onsets, self.wall_ticks,
            )  # fmt: skip
            return
        self.collision_ticks += ev.collision
        self.boundary_ticks += ev.boundary
        self.actuator_ticks += np.bincount(self.robot_team[ev.actuator], minlength=self.n_teams) > 0
        self.contact_ticks += ev.robot_contact
        self.contact_onsets += ev.robot_contact & ~self._last_contact
        self._last_contact = ev.robot_contact.copy()
        self.wall_ticks += ev.wall_contact

    def check_and_add(
        self, poses, pair_i, pair_j, pair_team, actuator, robot_contact, wall_contact, cos_sin
    ) -> TickEvents:
        """:func:`check_tick` then :meth:`add`, compiled into one call (kernels on only)."""
        c, s = cos_sin
        R, B = poses.shape[0], self.n_teams
        collision, boundary, pairs = np.empty(R, dtype=bool), np.empty(R, dtype=bool), np.empty(B, np.int64)
        kernels.check_and_count(
            poses, c, s, C.COLLISION_OFFSET_M, C.COLLISION_DIAMETER_M**2, pair_i, pair_j, pair_team, _BOUNDS,
            self.robot_team, actuator, robot_contact, wall_contact, collision, pairs, boundary, self._last_contact,
            self.collision_pairs, self.collision_ticks, self.boundary_ticks, self.actuator_ticks, self.contact_ticks,
            self.contact_onsets, self.wall_ticks,
        )  # fmt: skip
        return TickEvents(collision, pairs, boundary, actuator, robot_contact, wall_contact)

    def reset(self, teams: np.ndarray | None = None) -> None:
        """Zero the counts of the given teams (all if None)."""
        if teams is None:
            self.__post_init__()
            return
        sel = np.isin(self.robot_team, teams)
        for name in ("collision_ticks", "boundary_ticks", "contact_ticks", "contact_onsets", "wall_ticks"):
            getattr(self, name)[sel] = 0
        self._last_contact[sel] = False
        self.collision_pairs[teams] = 0
        self.actuator_ticks[teams] = 0

    def per_team(self, name: str) -> np.ndarray:
        """(B,) sum of a per-robot count over each team."""
        values = getattr(self, name)
        if values.shape[0] == self.n_teams and name in ("collision_pairs", "actuator_ticks"):
            return values.copy()
        return np.bincount(self.robot_team, weights=values, minlength=self.n_teams).astype(np.int64)
