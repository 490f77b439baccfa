"""The deployed loop: what an exported ``main.py`` does every Robotarium iteration (numpy + cvxopt).

This file is shipped verbatim in every export (as ``deployed_loop.py``) and run by comat itself
(``SafetyConfig.deployed``, ``comat bench safety --loops deployed``), so the loop comat measures
under the reality layer is the loop it deploys. It imports numpy, cvxopt (both on the
Robotarium's server, ``libraries.txt``) and the standard library only.

One iteration, on the measured poses x (3, N) and the waypoints of the env step (2, N):

1. point velocities ``dxi = gain·(waypoint − point)`` of the points ``projection`` ahead of the
   axles, norm-clipped to ``max_speed`` (the Robotarium's ``si_position_controller``);
2. unicycle commands by the installed rps's ``create_si_to_uni_mapping`` (legacy rps clips
   |ω| to π rad/s there, V2 does not), scaled down (v and ω together) to the wheel limit;
3. the barrier: the Robotarium's own (:func:`robotarium_barrier`, either generation) or the
   filter the export ships, on the measured poses;
4. the wheel scaling again.

The Robotarium's barrier, reimplemented from the rps sources' maths (row for row, same solver
and options) so that comat can run it in its tick; ``tests/test_deployed.py`` checks it against
the real rps functions (legacy from PyPI always, V2 with ``COMAT_RPS_V2``):

==========================  =====================================  ==========================================
                            legacy (PyPI 0.0.0, 2020–2025)         V2 (2026)
==========================  =====================================  ==========================================
function                    ``create_unicycle_barrier_certifi-     ``create_uni_barrier_certificate_with_
                            cate_with_boundary``                   boundary``
projection d                0.05 m                                 0.03 m
points kept apart           0.12 + d = 0.17 m                      0.12 + 2d = 0.18 m
pair rows                   ḣ ≥ −100·h³, h = ‖Δp‖² − r²            ḣ ≥ −150·h³
wall rows                   ẋ·n ≤ 0.4·100·(wall − r/2 − x)³        0.4·150·(…)³
speed                       input norm-clipped to 0.2 m/s          8 rows per robot: |v·n| ≤ 0.2·cos(π/8)
                                                                   = 0.185 m/s (an inscribed octagon)
QP                          cvxopt, reltol = feastol = 1e-2,       the same
                            50 iterations
solver failure              its last iterate is used as is         zero commands for the whole team
one robot                   QP with the wall rows                  the command passes unchanged
si→uni afterwards           |ω| clipped to π rad/s                 no clip
==========================  =====================================  ==========================================
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "GENERATIONS",
    "DeadlockTieBreak",
    "DeployedLoop",
    "PortableBarrier",
    "RobotWatch",
    "ShippedFilter",
    "cvxopt_qp",
    "keep_right",
    "robotarium_barrier",
    "robotarium_loop",
    "si_to_uni",
    "uni_to_si",
    "wheel_projected",
    "wheel_scaled",
]

GENERATIONS = ("v2", "legacy")
"""The rps generations whose barrier this module runs."""
ARENA = (-1.6, 1.6, -1.0, 1.0)
"""(x_min, x_max, y_min, y_max) m: the boundary both generations' barriers use."""
QP_OPTIONS = {"show_progress": False, "reltol": 1e-2, "feastol": 1e-2, "maxiters": 50}
"""cvxopt's settings as both rps generations set them (module-wide there; passed per call here)."""
AXLE_M = {"v2": 0.11, "legacy": 0.105}
"""The simulator's axle length (``BASE_LENGTH`` / ``base_length``) that main.py's wheel scaling reads."""
WHEEL_RADIUS_M = 0.016
"""Both generations' wheel radius."""


HOLD_TICKS = 30
"""Ticks (1 s) a robot may be held still against its command before the deadlock tie-break
(comat's loop, :meth:`comat.control.SafeTeams.tick`, and :class:`ShippedFilter`)."""
HOLD_FRACTION = 0.2
"""A robot is held still when its filtered speed is below this fraction of its nominal speed."""
DETOUR_TICKS = 30
"""Ticks (1 s) the tie-break lasts once triggered."""
DETOUR_ANGLE_RAD = -np.pi / 6
"""The tie-break: a held robot's nominal command rotated clockwise by 30° ("keep right"). Two
robots that block each other head-on on one line both turn to their right and pass; measured
with the scripted PCP policy on every 2-robot U_test team from the env's starts (seeds 0–4,
MuJoCo wheels tier): 33 of 35 episodes finished without it, 35 of 35 with it."""


class DeadlockTieBreak:
    """The deadlock tie-break of comat's loops (its own and :class:`ShippedFilter`), per robot: a
    robot the filter holds still against its command (filtered speed under ``HOLD_FRACTION`` of the
    nominal) for ``HOLD_TICKS`` ticks has its nominal command turned by ``DETOUR_ANGLE_RAD``
    ("keep right") for ``DETOUR_TICKS`` ticks."""

    def __init__(self, n: int) -> None:
        self.held = np.zeros(n, np.int64)
        """(N,) consecutive ticks each robot has been held still."""
        self.detour = np.zeros(n, np.int64)
        """(N,) tie-break ticks each robot has left."""

    def restart(self, rows) -> None:
        """Robots ``rows`` (indices or a mask) begin anew."""
        self.held[rows] = 0
        self.detour[rows] = 0

    def steer(self, nominal: np.ndarray) -> np.ndarray:
        """The point velocities (N, 2) to filter: ``nominal`` itself, or a copy turned where a robot
        is on its detour (one tick of it used up)."""
        if not self.detour.any():
            return nominal
        turn = self.detour > 0
        c, s = np.cos(DETOUR_ANGLE_RAD), np.sin(DETOUR_ANGLE_RAD)
        out = nominal.copy()
        out[turn] = nominal[turn] @ np.array([[c, s], [-s, c]])
        self.detour[turn] -= 1
        return out

    def update(self, nominal: np.ndarray, safe: np.ndarray) -> None:
        """After the filter: count the robots it held still (nominal and filtered (N, 2)) and start
        the detours that are due."""
        want = nominal[:, 0] ** 2 + nominal[:, 1] ** 2
        still = (want > 1e-6) & (safe[:, 0] ** 2 + safe[:, 1] ** 2 < HOLD_FRACTION**2 * want)
        self.held = np.where(still, self.held + 1, 0)
        start = self.held >= HOLD_TICKS
        if start.any():
            self.detour[start] = DETOUR_TICKS
            self.held[start] = 0


KEEP_RIGHT_REACH_M = 0.6
"""Distance (m) between projected points within which a robot ahead turns a robot's nominal
command to the right (:func:`keep_right`)."""
KEEP_RIGHT_ANGLE_RAD = np.pi / 4
"""Largest turn (rad) :func:`keep_right` gives a nominal command (a robot right ahead, touching)."""


def keep_right(points: np.ndarray, nominal: np.ndarray, pair_i: np.ndarray, pair_j: np.ndarray) -> np.ndarray:
    """Nominal point velocities (N, 2) turned clockwise where other robots are ahead: robot i's
    command turns by ``KEEP_RIGHT_ANGLE_RAD · w_i``, w_i the largest over the robots j ahead of it
    (pairs ``pair_i``, ``pair_j``, indices into ``points`` (N, 2)) of
    ``(1 − r_ij / KEEP_RIGHT_REACH_M)⁺ · cos⁺(angle between i's command and the direction to j)``.

    A crowd that crosses then circulates one way round (a roundabout) instead of meeting head-on
    at the centre, where symmetric barrier rows hold everyone still. Only the NOMINAL command
    changes: the barrier still filters every command, so every safety row holds as before (the
    proof is untouched); a turn under 90° keeps a component toward the goal."""
    n = nominal.shape[0]
    speed = np.hypot(nominal[:, 0], nominal[:, 1])
    d = nominal / np.maximum(speed, 1e-12)[:, None]
    e = points[pair_j] - points[pair_i]
    r = np.maximum(np.hypot(e[:, 0], e[:, 1]), 1e-12)
    near = np.clip(1.0 - r / KEEP_RIGHT_REACH_M, 0.0, 1.0)
    w = np.zeros(n)
    np.maximum.at(w, pair_i, near * np.clip((e * d[pair_i]).sum(axis=1) / r, 0.0, 1.0))
    np.maximum.at(w, pair_j, near * np.clip(-(e * d[pair_j]).sum(axis=1) / r, 0.0, 1.0))
    a = -KEEP_RIGHT_ANGLE_RAD * w
    c, s = np.cos(a), np.sin(a)
    return np.column_stack([c * nominal[:, 0] - s * nominal[:, 1], s * nominal[:, 0] + c * nominal[:, 1]])


# -- maps between points and unicycles (row 0 x / v, row 1 y / ω; one column per robot) ----------
def si_to_uni(dxi: np.ndarray, x: np.ndarray, d: float, angular_limit: float | None = None) -> np.ndarray:
    """Unicycle commands (2, N) moving the points ``d`` ahead of poses x (3, N) at dxi (2, N);
    ``angular_limit`` clips |ω| (legacy rps: π; V2: None)."""
    c, s = np.cos(x[2]), np.sin(x[2])
    dxu = np.vstack([c * dxi[0] + s * dxi[1], (-s * dxi[0] + c * dxi[1]) / d])
    if angular_limit is not None:
        dxu[1] = np.clip(dxu[1], -angular_limit, angular_limit)
    return dxu


def uni_to_si(dxu: np.ndarray, x: np.ndarray, d: float) -> np.ndarray:
    """Velocities (2, N) of the points ``d`` ahead of poses x (3, N) under unicycle commands (2, N)."""
    c, s = np.cos(x[2]), np.sin(x[2])
    return np.vstack([c * dxu[0] - d * s * dxu[1], s * dxu[0] + d * c * dxu[1]])


def wheel_scaled(dxu: np.ndarray, radius: float, axle: float, limit: float) -> np.ndarray:
    """Unicycle commands (2, N) scaled down (v and ω together) so no wheel exceeds ``limit`` rad/s."""
    left, right = (2 * dxu[0] - axle * dxu[1]) / (2 * radius), (2 * dxu[0] + axle * dxu[1]) / (2 * radius)
    fastest = np.maximum(np.abs(left), np.abs(right))
    return dxu * np.minimum(1.0, limit / np.maximum(fastest, 1e-12))


def wheel_projected(dxi: np.ndarray, x: np.ndarray, d: float, radius: float, axle: float, limit: float) -> np.ndarray:
    """Closest point velocities (2, N) to dxi (2, N) that the wheels can drive (comat's waypoint
    controller saturation): the per-wheel limit is the rhombus |a| + k|b| <= v in the components
    along (a) and across (b) the heading, k = axle / 2d, v = radius·limit; points outside are
    projected onto it in closed form (comat.sim.kinematics.limit_to_wheels, tested equal)."""
    k, v = axle / (2.0 * d), radius * limit
    c, s = np.cos(x[2]), np.sin(x[2])
    a, b = c * dxi[0] + s * dxi[1], c * dxi[1] - s * dxi[0]
    pa, pb = np.abs(a), np.abs(b)
    outside = pa + k * pb > v
    t = np.clip(((v - pa) * v + pb * v / k) / (v * v * (1.0 + 1.0 / (k * k))), 0.0, 1.0)
    pa, pb = np.where(outside, v - t * v, pa), np.where(outside, t * v / k, pb)
    a, b = np.copysign(pa, a), np.copysign(pb, b)
    return np.vstack([c * a - s * b, s * a + c * b])


def points_apart_and_inside(points: np.ndarray, distance: float, margin: float) -> bool:
    """Points (2, N) pairwise >= ``distance`` apart and >= ``margin`` inside the arena."""
    x0, x1, y0, y1 = ARENA
    p = points
    if (
        (p[0] < x0 + margin).any()
        or (p[0] > x1 - margin).any()
        or (p[1] < y0 + margin).any()
        or (p[1] > y1 - margin).any()
    ):
        return False
    i, j = np.triu_indices(p.shape[1], 1)
    return bool((np.hypot(*(p[:, i] - p[:, j])) >= distance).all())


# -- the Robotarium's barrier ----------------------------------------------------------------------
_OCTAGON = np.array([[1, 0], [1, 1], [0, 1], [-1, 1], [-1, 0], [-1, -1], [0, -1], [1, -1]], dtype=float)
_OCTAGON[1::2] /= np.sqrt(2)


def _rows(points: np.ndarray, radius: float, gain: float, arena) -> tuple[np.ndarray, np.ndarray]:
    """The pair and wall rows ``A v <= b`` (v stacked per robot: x0, y0, x1, ...) of points (2, N),
    in rps's order: pairs (i < j) row by row, then +y, −y, +x, −x walls per robot."""
    n = points.shape[1]
    i, j = np.triu_indices(n, 1)
    diff = points[:, i] - points[:, j]  # (2, P)
    h = diff[0] * diff[0] + diff[1] * diff[1] - radius**2
    pairs = np.zeros((i.size, 2 * n))
    rows = np.arange(i.size)
    for axis in (0, 1):
        pairs[rows, 2 * i + axis] = -2 * diff[axis]
        pairs[rows, 2 * j + axis] = 2 * diff[axis]
    walls = np.zeros((4 * n, 2 * n))
    k = np.arange(n)
    walls[4 * k, 2 * k + 1] = 1
    walls[4 * k + 1, 2 * k + 1] = -1
    walls[4 * k + 2, 2 * k] = 1
    walls[4 * k + 3, 2 * k] = -1
    x0, x1, y0, y1 = arena
    margin = radius / 2
    wall_b = (
        0.4
        * gain
        * np.stack(
            [y1 - margin - points[1], points[1] - y0 - margin, x1 - margin - points[0], points[0] - x0 - margin], 1
        ).ravel()
        ** 3
    )
    return np.vstack([pairs, walls]), np.concatenate([gain * h**3, wall_b])


def _solve(vhat: np.ndarray, A: np.ndarray, b: np.ndarray, sparse_cost: bool):
    """min ‖v − v̂‖² s.t. A v <= b with cvxopt at rps's settings: (v (2, N) or None, status)."""
    from cvxopt import matrix, solvers, sparse

    n = vhat.shape[1]
    H = sparse(matrix(2.0 * np.eye(2 * n))) if sparse_cost else matrix(2.0 * np.eye(2 * n))
    f = matrix(-2.0 * vhat.reshape(-1, order="F"))
    try:
        sol = solvers.qp(H, f, matrix(A), matrix(b), options=dict(QP_OPTIONS))
    except (ValueError, ArithmeticError):  # a singular KKT system: rps's own call raises too
        return None, "error"
    x = None if sol["x"] is None else np.reshape(np.array(sol["x"]), (2, n), order="F")
    return x, sol["status"]


class RobotariumBarrier:
    """``barrier(dxu (2, N), x (3, N)) -> dxu (2, N)``: the Robotarium's unicycle barrier with
    boundary of one rps generation (module docstring). ``failures`` counts the calls whose QP
    did not end *optimal* (V2 then commands zeros; legacy uses the last iterate, or zeros where
    cvxopt returned none, where rps itself would stop with an exception)."""

    def __init__(self, generation: str = "v2") -> None:
        if generation not in GENERATIONS:
            raise ValueError(f"generation must be one of {list(GENERATIONS)}, got {generation!r}")
        self.generation = generation
        v2 = generation == "v2"
        self.projection = 0.03 if v2 else 0.05
        self.radius = 0.12 + (2 if v2 else 1) * self.projection
        self.gain = 150.0 if v2 else 100.0
        self.angular_limit = None if v2 else math.pi
        self.failures = 0

    def points(self, x: np.ndarray) -> np.ndarray:
        """(2, N) the points ``projection`` ahead of poses x (3, N) that this barrier keeps apart."""
        return x[:2] + self.projection * np.vstack([np.cos(x[2]), np.sin(x[2])])

    def in_safe_set(self, x: np.ndarray) -> bool:
        """Poses x (3, N) inside this barrier's safe set: every pair of points >= ``radius`` apart
        and every point >= ``radius``/2 inside the arena (all its rows' h >= 0)."""
        return points_apart_and_inside(self.points(x), self.radius, self.radius / 2)

    def __call__(self, dxu: np.ndarray, x: np.ndarray) -> np.ndarray:
        n = dxu.shape[1]
        v2 = self.generation == "v2"
        if v2 and n < 2:
            return dxu
        d = self.projection
        points = self.points(x)
        dxi = uni_to_si(dxu, x, d)
        A, b = _rows(points, self.radius, self.gain, ARENA)
        if v2:
            octagon = np.zeros((8 * n, 2 * n))
            for k in range(8):
                octagon[8 * np.arange(n) + k, 2 * np.arange(n)] = _OCTAGON[k, 0]
                octagon[8 * np.arange(n) + k, 2 * np.arange(n) + 1] = _OCTAGON[k, 1]
            A = np.vstack([A, octagon])
            b = np.concatenate([b, np.full(8 * n, 0.2 * np.cos(np.pi / 8))])
        else:
            norms = np.linalg.norm(dxi, axis=0)
            over = norms > 0.2
            dxi[:, over] *= 0.2 / norms[over]
        safe, status = _solve(dxi, A, b, sparse_cost=v2)
        if status != "optimal":
            self.failures += 1
            if v2 or safe is None:
                return np.zeros((2, n))
        return si_to_uni(safe, x, d, self.angular_limit)


def robotarium_barrier(generation: str = "v2") -> RobotariumBarrier:
    """The Robotarium's unicycle barrier with boundary of ``generation`` ("v2" or "legacy")."""
    return RobotariumBarrier(generation)


# -- comat's filter, as an export ships it -------------------------------------------------------
class RobotWatch:
    """What the script can tell about each robot from its poses and its own commands (N robots).

    * **Stale poses dead-reckoned.** A measured pose that repeats the previous one bit for bit is
      stale (a tracker hold or freeze): the estimate moves on by the unicycle command sent in the
      tick before, integrated over the tick. A fresh measurement replaces it.
    * **Probation.** A robot is on probation when it does not respond — over the last ``window``
      ticks its fresh measurements moved its point, ALONG the displacement its commands predicted
      (sent up to ``lag`` ticks earlier, the best-fitting lag), less than ``ratio`` of that
      prediction (at least ``min_path_m``: a dead motor, a robot braked after a Wi-Fi loss, one at
      a fraction of its speed, one driving the wrong way or sideways: direction and magnitude, not
      distance alone) — or when its pose has been stale for ``stale_limit`` ticks while it was told
      to move (a dead robot and a frozen tracker look alike then). A robot on probation is an
      obstacle to the others (:class:`PortableBarrier`), placed between its last fresh pose and its
      dead-reckoned one with the half-distance as extra radius. It leaves probation when fresh
      measurements show it making good ``release_ratio`` of its predicted displacement again.

    Call :meth:`observe` with each tick's measured poses (N, 3) before deciding, :meth:`sent` with
    the unicycle commands (N, 2) sent after.
    """

    def __init__(
        self,
        n: int,
        projection: float,
        lag: int,
        window: int = 15,
        stale_limit: int = 8,
        min_path_m: float = 0.03,
        ratio: float = 0.25,
        release_ratio: float = 0.5,
        dt: float = 0.033,
        dead_reckon: bool = True,
    ) -> None:
        self.n, self.d, self.lag, self.window = n, float(projection), int(lag), int(window)
        self.stale_limit, self.min_path = int(stale_limit), min_path_m
        self.ratio, self.release_ratio = ratio, release_ratio
        self.dt, self.dead_reckon = dt, dead_reckon
        self.tick = 0
        self.estimate = np.zeros((n, 3))
        """(N, 3) the script's best pose of each robot (dead-reckoned while stale)."""
        self.anchor = np.zeros((n, 3))
        """(N, 3) each robot's last fresh measurement."""
        self.stale = np.zeros(n, np.int64)
        """(N,) ticks each robot's measurement has repeated."""
        self.probation = np.zeros(n, dtype=bool)
        """(N,) robots the others must treat as obstacles: :attr:`unresponsive` or :attr:`unsure`."""
        self.unresponsive = np.zeros(n, dtype=bool)
        """(N,) robots whose fresh poses showed them ignoring their commands (until they follow them again)."""
        self.unsure = np.zeros(n, dtype=bool)
        """(N,) robots stale for ``stale_limit`` ticks while told to move (until a fresh pose)."""
        self._last = np.full((n, 3), np.nan)
        self._sent = np.zeros((n, 2))
        span = self.window + self.lag + 1
        self._ask = np.zeros((n, span, 2))  # point displacement (m) the command sent at tick t asked for, slot t % span
        self._points = np.zeros((n, self.window + 1, 2))  # measured points, slot t % (window + 1)
        self._stale_path = np.zeros(n)  # path asked for while stale
        self._born = np.zeros(n, np.int64)  # tick each robot's episode began

    def observe(self, measured: np.ndarray) -> None:
        """This tick's measured poses (N, 3), before the script decides."""
        stale = (measured == self._last).all(axis=1)  # NaN (a new episode) never equals
        est = self.estimate
        if self.dead_reckon and stale.any():
            th = est[stale, 2]
            v, w = self._sent[stale, 0], self._sent[stale, 1]
            est[stale, 0] += v * np.cos(th) * self.dt
            est[stale, 1] += v * np.sin(th) * self.dt
            est[stale, 2] = np.pi - np.remainder(np.pi - (th + w * self.dt), 2.0 * np.pi)
        np.copyto(est, measured, where=~stale[:, None])
        np.copyto(self.anchor, measured, where=~stale[:, None])
        self.stale = np.where(stale, self.stale + 1, 0)
        last_ask = self._ask[:, self.tick % self._ask.shape[1]]  # the command sent in the tick before
        self._stale_path = np.where(stale, self._stale_path + np.hypot(last_ask[:, 0], last_ask[:, 1]), 0.0)
        np.copyto(self._last, measured)
        k = self.tick % (self.window + 1)
        a = self.anchor
        self._points[:, k] = a[:, :2] + self.d * np.column_stack([np.cos(a[:, 2]), np.sin(a[:, 2])])
        old = self.tick - self._born > self.window + self.lag
        if old.any():
            self._judge(old, stale, k)
        self.unsure = (self.stale >= self.stale_limit) & (self._stale_path >= self.min_path / 3)
        self.probation = self.unresponsive | self.unsure
        self.tick += 1

    def _judge(self, old: np.ndarray, stale: np.ndarray, k: int) -> None:
        """Put on probation, or release, the robots ``old`` (N,) enough to judge, by what their
        points did against what their commands asked (points slot ``k`` is this tick's). comat's
        simulator runs a compiled twin of this (``comat.safety.kernels.watch_judgement``)."""
        then = (self.tick - self.window) % (self.window + 1)
        span = self._ask.shape[1]
        # Net displacement asked for over the window, for every response lag 0..lag (the
        # prediction from the commands sent), against the measured displacement: the share of
        # each prediction made good ALONG it (the signed projection, so a robot driving the
        # wrong way scores below 0, a slow one its speed fraction, a stopped one 0). The robot
        # is judged by the lag that fits best, and only when every lag asks for min_path at
        # least (a command that reversed asks for little at some lag): only a robot that does
        # not follow its commands whatever the lag is put on probation.
        recent = self._ask[:, (self.tick - np.arange(self.window + self.lag)) % span]  # newest first
        sums = np.cumsum(recent, axis=1)
        before = np.concatenate([np.zeros((self.n, 1, 2)), sums[:, : -self.window]], axis=1)
        windows = sums[:, self.window - 1 :] - before  # (N, lag + 1, 2)
        asked = np.hypot(windows[..., 0], windows[..., 1]).min(axis=1)
        moved = self._points[:, k] - self._points[:, then]  # (N, 2)
        along = windows[..., 0] * moved[:, None, 0] + windows[..., 1] * moved[:, None, 1]
        square = windows[..., 0] * windows[..., 0] + windows[..., 1] * windows[..., 1]
        made_good = (along / np.maximum(square, 1e-30)).max(axis=1)
        judged = old & ~stale & (asked >= self.min_path)
        self.unresponsive |= judged & (made_good < self.ratio)
        self.unresponsive &= ~(judged & (made_good >= self.release_ratio))

    def restart(self, rows: np.ndarray) -> None:
        """Robots ``rows`` begin a new episode: nothing is known about them yet."""
        self._last[rows] = np.nan
        self.stale[rows] = 0
        self.probation[rows] = False
        self._sent[rows] = 0.0
        self._ask[rows] = 0.0
        self.unresponsive[rows] = False
        self.unsure[rows] = False
        self._stale_path[rows] = 0.0
        self._born[rows] = self.tick

    def sent(self, dxu: np.ndarray) -> None:
        """The unicycle commands (N, 2) the script sent this tick."""
        self._sent = np.array(dxu, dtype=float)
        velocity = uni_to_si(self._sent.T, self.estimate.T, self.d).T
        self._ask[:, self.tick % self._ask.shape[1]] = velocity * self.dt

    def obstacles(self) -> tuple[np.ndarray, np.ndarray]:
        """(poses (N, 3), extra radius (N,)): where the barrier places each robot. A stale robot on
        probation sits midway between its last fresh pose and its dead-reckoned one, the
        half-distance added to its radius; every other robot at its estimate, radius 0."""
        poses = self.estimate.copy()
        extra = np.zeros(self.n)
        unsure = self.unsure
        if unsure.any():
            mid = 0.5 * (self.anchor[unsure, :2] + self.estimate[unsure, :2])
            extra[unsure] = 0.5 * np.hypot(*(self.estimate[unsure, :2] - self.anchor[unsure, :2]).T)
            poses[unsure, :2] = mid
        return poses, extra


def cvxopt_qp(vhat: np.ndarray, A: np.ndarray, b: np.ndarray, weights: np.ndarray | None = None):
    """min ½·Σ w_k (v_k − v̂_k)² (w = 1 by default) s.t. A v <= b with cvxopt at tight tolerances
    (the export): (v or None, status)."""
    from cvxopt import matrix, solvers

    w = np.ones(vhat.size) if weights is None else weights
    try:
        sol = solvers.qp(
            matrix(np.diag(w)),
            matrix(-w * vhat),
            matrix(A),
            matrix(b),
            options={"show_progress": False, "abstol": 1e-9, "reltol": 1e-9, "feastol": 1e-9, "maxiters": 100},
        )
    except (ValueError, ArithmeticError):
        return None, "error"
    if sol["status"] != "optimal":
        return None, sol["status"]
    return np.array(sol["x"]).ravel(), "optimal"


SLACK_WEIGHT = 1e4
"""Weight of the squared slacks of :class:`PortableBarrier`'s softened problem against the squared
deviation from the nominal command (as comat.safety.recovery's)."""


class PortableBarrier:
    """comat's barrier filter for one team, in numpy, for the export and for teams with a robot on
    probation: ``min ½‖u − û‖²`` over the projected points' velocities u (N, 2) subject to

    * pair rows ``ḣ >= −γ·h``, h = ‖p_i − p_j‖² − (d_s + ρ_i + ρ_j)²; a pair with one robot on
      probation is split: the other robot alone keeps ``ḣ >= −γh`` and the one on probation may
      not close in at all (``ḣ >= 0`` from its own velocity), so the row holds whether or not it
      executes its command; both on probation: neither may close in;
    * wall rows ``−γ_b·(p − lo) <= u <= γ_b·(hi − p)``, [lo, hi] the arena shrunk by the margin
      (+ ρ);
    * wheel rows ``|u·(ê ± k·n̂)| <= v``: the wheel limit at the projected point.

    ``settings``: safety_distance_m, projection_distance_m, boundary_margin_m, barrier_gain,
    boundary_gain, axle_m, wheel_radius_m, wheel_limit_radps (the comat filter's robust values,
    written into the export's config). ``solve``: :func:`cvxopt_qp` (the export) or
    :func:`comat.safety.qp.dense_qp` (DAQP, comat's own runs).

    A team outside the safe set (no command meets the hard rows, e.g. after a robot's extra radius
    grew) takes the answer of the softened problem — pair and wall rows relaxed by slacks of
    weight :data:`SLACK_WEIGHT`, wheel rows hard — which moves it back as fast as the wheels allow
    (``recoveries`` counts those ticks); only if that fails too does it brake (``failures``).
    """

    def __init__(self, settings: dict, solve=cvxopt_qp) -> None:
        self.s = dict(settings)
        self.solve = solve
        self.failures = 0
        self.recoveries = 0

    def __call__(
        self,
        poses: np.ndarray,
        u_nom: np.ndarray,
        probation: np.ndarray | None = None,
        extra: np.ndarray | None = None,
        candidate: np.ndarray | None = None,
        tol: float = 0.0,
    ) -> np.ndarray:
        """Filtered point velocities (N, 2) for poses (N, 3) and nominal ones (N, 2).

        ``candidate`` (N, 2), e.g. the answer of a filter that trusted every robot: returned as it
        is when it meets every row (within ``tol``), so no QP is solved. It is then a command this
        problem admits — safe by the same rows — and, where the problem's set lies inside the
        candidate's own problem's (the split pair rows imply the cooperative ones), its optimum."""
        n = poses.shape[0]
        A, b = self.problem(poses, probation, extra)
        u0 = u_nom.ravel().astype(float)
        if np.all(A @ u0 <= b):  # the nominal command meets every row: it is the optimum
            return u_nom.reshape(n, 2).astype(float)
        if candidate is not None and np.all(A @ candidate.ravel() <= b + tol):
            return candidate.reshape(n, 2).astype(float)
        u, _ = self.solve(u0, A, b)
        if u is None:  # outside the safe set: relax the pair and wall rows (the last 4n rows are the wheels')
            soft = A.shape[0] - 4 * n
            m = A.shape[0]
            relaxed = np.hstack([A, np.vstack([-np.eye(soft), np.zeros((m - soft, soft))])])
            positive = np.hstack([np.zeros((soft, 2 * n)), -np.eye(soft)])
            z, _ = self.solve(
                np.concatenate([u0, np.zeros(soft)]),
                np.vstack([relaxed, positive]),
                np.concatenate([b, np.zeros(soft)]),
                np.concatenate([np.ones(2 * n), np.full(soft, SLACK_WEIGHT)]),
            )
            if z is None:
                self.failures += 1
                return np.zeros((n, 2))
            self.recoveries += 1
            u = z[: 2 * n]
        return u.reshape(n, 2)

    def problem(
        self, poses: np.ndarray, probation: np.ndarray | None = None, extra: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """The rows ``A u <= b`` (u stacked per robot: x0, y0, x1, ...) for poses (N, 3): pair rows,
        wall rows, then the 4N wheel rows last."""
        s, n = self.s, poses.shape[0]
        probation = np.zeros(n, dtype=bool) if probation is None else probation
        extra = np.zeros(n) if extra is None else extra
        c, sn = np.cos(poses[:, 2]), np.sin(poses[:, 2])
        p = poses[:, :2] + s["projection_distance_m"] * np.column_stack([c, sn])
        i, j = np.triu_indices(n, 1)
        e = p[i] - p[j]
        h = (e * e).sum(axis=1) - (s["safety_distance_m"] + extra[i] + extra[j]) ** 2
        g = s["barrier_gain"]
        rows, bounds = [], []
        pi, pj = probation[i], probation[j]
        trusted = ~pi & ~pj
        for sel, use_i, use_j, bound in (
            (trusted, True, True, g * h),
            (pj & ~pi, True, False, g * h),
            (pi & ~pj, False, True, g * h),
            (pi, True, False, 0.0 * h),
            (pj, False, True, 0.0 * h),
        ):
            k = np.flatnonzero(sel)
            if k.size == 0:
                continue
            A = np.zeros((k.size, 2 * n))
            r = np.arange(k.size)
            if use_i:
                A[r, 2 * i[k]], A[r, 2 * i[k] + 1] = -2 * e[k, 0], -2 * e[k, 1]
            if use_j:
                A[r, 2 * j[k]], A[r, 2 * j[k] + 1] = 2 * e[k, 0], 2 * e[k, 1]
            rows.append(A)
            bounds.append(bound[k])
        x0, x1, y0, y1 = ARENA
        m = s["boundary_margin_m"] + extra
        gb = s["boundary_gain"]
        eye = np.eye(2 * n)
        rows += [eye, -eye]
        hi = np.column_stack([x1 - m - p[:, 0], y1 - m - p[:, 1]]).ravel()
        lo = np.column_stack([p[:, 0] - x0 - m, p[:, 1] - y0 - m]).ravel()
        bounds += [gb * hi, gb * lo]
        k_w = s["axle_m"] / (2 * s["projection_distance_m"])
        v_w = s["wheel_radius_m"] * s["wheel_limit_radps"]
        wheel = np.zeros((4 * n, 2 * n))
        rr = np.arange(n)
        for q, (a, b) in enumerate(((c - k_w * sn, sn + k_w * c), (c + k_w * sn, sn - k_w * c))):
            for sign in (1.0, -1.0):
                row = 4 * rr + 2 * q + (0 if sign > 0 else 1)
                wheel[row, 2 * rr], wheel[row, 2 * rr + 1] = sign * a, sign * b
        rows.append(wheel)
        bounds.append(np.full(4 * n, v_w))
        return np.vstack(rows), np.concatenate(bounds)


class ShippedFilter:
    """``filter(dxu (2, N), x (3, N)) -> dxu (2, N)``: comat's filter as an export ships it, in the
    barrier's place of main.py — :class:`RobotWatch` on the measured poses, :class:`PortableBarrier`
    on the projected points (cvxopt on the Robotarium), back to unicycle commands.

    Args:
        n: robots.
        settings: :class:`PortableBarrier`'s (the robust filter's values for the reality level
            the export was made for).
        lag: ticks from a command to its effect on a measured pose, at most (:class:`RobotWatch`).
        keep_right: turn nominal commands right near robots ahead (:func:`keep_right`).
    """

    def __init__(self, n: int, settings: dict, lag: int, solve=cvxopt_qp, keep_right: bool = True) -> None:
        self.projection = float(settings["projection_distance_m"])
        self.watch = RobotWatch(n, self.projection, lag)
        self.barrier = PortableBarrier(settings, solve)
        self.tie_break = DeadlockTieBreak(n)
        self.keep_right = keep_right
        """Turn nominal commands right near robots ahead (:func:`keep_right`; the filter is unchanged)."""
        self._pairs = np.triu_indices(n, 1)

    @property
    def failures(self) -> int:
        """Ticks with no feasible command (the team braked)."""
        return self.barrier.failures

    @property
    def recoveries(self) -> int:
        """Ticks the team was outside the safe set and took the softened problem's answer."""
        return self.barrier.recoveries

    def in_safe_set(self, x: np.ndarray) -> bool:
        """Poses x (3, N) inside the filter's safe set (its pair and wall rows' h >= 0)."""
        s = self.barrier.s
        p = x[:2] + self.projection * np.vstack([np.cos(x[2]), np.sin(x[2])])
        return points_apart_and_inside(p, s["safety_distance_m"], s["boundary_margin_m"])

    def command(self, x: np.ndarray, nominal: np.ndarray) -> np.ndarray:
        """Unicycle commands (2, N) for measured poses x (3, N) and the waypoint controller's
        point velocities (2, N) (already within the wheels' rhombus)."""
        watch, d = self.watch, self.projection
        watch.observe(x.T)
        poses, extra = watch.obstacles()
        nominal = nominal.T
        steered = self.tie_break.steer(nominal)
        if self.keep_right:
            c, s = np.cos(poses[:, 2]), np.sin(poses[:, 2])
            points = np.column_stack([poses[:, 0] + d * c, poses[:, 1] + d * s])
            steered = keep_right(points, steered, *self._pairs)
        u = self.barrier(poses, steered, watch.probation, extra)
        self.tie_break.update(nominal, u)
        out = si_to_uni(u.T, poses.T, d)
        watch.sent(out.T)
        return out


# -- one iteration of main.py ----------------------------------------------------------------------
class DeployedLoop:
    """``command(x (3, N), waypoints (2, N)) -> dxu (2, N)``: one iteration of an exported main.py.

    Args:
        barrier: ``(dxu (2, N), x (3, N)) -> dxu (2, N)`` (the installed rps's, or a shipped filter).
        si_to_uni_map: ``(dxi (2, N), x (3, N)) -> dxu (2, N)`` at ``projection`` (rps's mapping).
        wheel_radius, axle: the simulator's wheel constants (m) the scaling reads.
        wheel_limit: largest wheel speed commanded (rad/s).
        gain: the waypoint controller's gain (1/s).
        max_speed: the points' speed limit (m/s).
        projection: how far ahead of the axles the controlled points sit (m).
    """

    def __init__(
        self,
        barrier,
        si_to_uni_map,
        wheel_radius: float,
        axle: float,
        wheel_limit: float,
        gain: float,
        max_speed: float,
        projection: float,
    ) -> None:
        self.barrier, self.si_to_uni = barrier, si_to_uni_map
        self.shipped = isinstance(barrier, ShippedFilter)
        """comat's pipeline (wheel projection, :class:`ShippedFilter` on the points, si→uni)
        instead of the Robotarium's (si→uni, wheel scaling, the Robotarium's barrier)."""
        self.wheel = (float(wheel_radius), float(axle), float(wheel_limit))
        self.gain, self.max_speed, self.projection = float(gain), float(max_speed), float(projection)

    def points(self, x: np.ndarray) -> np.ndarray:
        """(2, N) the controlled points of poses x (3, N)."""
        return x[:2] + self.projection * np.vstack([np.cos(x[2]), np.sin(x[2])])

    def controller(self, x: np.ndarray, waypoints: np.ndarray) -> np.ndarray:
        """(2, N) the points' velocities toward their waypoints (2, N), norm-clipped to max_speed."""
        dxi = self.gain * (waypoints - self.points(x))
        norm = np.linalg.norm(dxi, axis=0)
        return dxi * np.minimum(1.0, self.max_speed / np.maximum(norm, 1e-12))

    def commands(self, x: np.ndarray, dxi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(nominal, sent): unicycle commands (2, N) for the points' velocities dxi (2, N), before
        the barrier and as sent. The Robotarium's pipeline: si→uni, wheel scaling, its barrier,
        scaling again. comat's (a :class:`ShippedFilter`): the velocities projected onto the
        wheels' rhombus, the filter on the points, si→uni, scaling as a safety net."""
        if self.shipped:
            nominal = wheel_projected(dxi, x, self.projection, *self.wheel)
            sent = self.barrier.command(x, nominal)
            return si_to_uni(nominal, x, self.projection), wheel_scaled(sent, *self.wheel)
        nominal = wheel_scaled(self.si_to_uni(dxi, x), *self.wheel)
        return nominal, wheel_scaled(self.barrier(nominal, x), *self.wheel)

    def command(self, x: np.ndarray, waypoints: np.ndarray) -> np.ndarray:
        """(2, N) the commands main.py sends this iteration."""
        return self.commands(x, self.controller(x, waypoints))[1]


def robotarium_loop(
    generation: str = "v2",
    gain: float = 4.0,
    projection: float = 0.025,
    wheel_limit: float = 0.999 * 12.5,
    max_speed: float = 0.2,
    barrier=None,
) -> DeployedLoop:
    """The exported loop as it runs under rps ``generation``: with the Robotarium's own barrier,
    or with ``barrier`` (e.g. a :class:`ShippedFilter`) in its place."""
    limit = None if generation == "v2" else math.pi
    return DeployedLoop(
        robotarium_barrier(generation) if barrier is None else barrier,
        lambda dxi, x: si_to_uni(dxi, x, projection, limit),
        WHEEL_RADIUS_M,
        AXLE_M[generation],
        wheel_limit,
        gain,
        max_speed,
        projection,
    )
