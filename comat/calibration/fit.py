"""Fit the reality layer's parameters to calibration logs (:mod:`comat.calibration.experiments`).

Per robot, then over robots (the robots are the replicated unit: the interval is the 95 %
Student-t interval over the per-robot estimates; with one robot it is nan):

* ``steps`` logs — the forward distance along the start heading is simulated by the layer's own
  motor model (the forward-speed request through the top-speed cap, a first-order lag of time
  constant τ with the slew limit, a speed gain), integrated and shifted by d whole ticks, and
  fitted to the observed distance by least squares: d and the cap on grids, τ on a grid (vectorized),
  the gain in closed form. Repeated poses (a held or frozen measurement) are left out. d is the
  pose delay plus the command delay (they shift the response alike; the profile puts it all in
  ``pose_delay_ticks``). The heading's drift per metre driven gives the wheels' gain difference.
* ``still`` logs — the pose noise SD (x, y, θ) over the fresh measurements, and the share of
  repeated measurements (``pose_hold_prob``).
* ``ramp`` logs — the dead zone δ: the forward distance is modelled as the integral of the
  commanded wheel speed with every speed below δ set to 0 (the layer's own dead zone), shifted by
  d whole ticks, with a gain and an offset by least squares; δ on a 0.05 rad/s grid and d on a grid.
  The ramp is slow (1 rad/s per second at the wheels), so the lag (τ ≲ 0.1 s) moves δ by ≲ 0.1 rad/s.
* ``spin`` logs — the ``steps`` fit on the heading (the wheels' rim distance l/2 · Δθ against the
  commanded l/2 · ω): delay, lag, turn-rate gain, reachable wheel speed; the circle the robot's
  centre draws while turning gives the wheels' gain difference (:func:`fit_spin`).
* every log — the loop's tick (median, 95th percentile, share late) from its clock column.

What the logs cannot show is reported as not identified, never guessed: the pose bias (no
ground truth on the Robotarium), the split of the delay between poses and commands, command
loss, faults (no fault experiment), the wheel disturbance; the dead zone without a ``ramp`` log.
"""

from __future__ import annotations

import math

import numpy as np

from comat import constants as C
from comat.calibration.schedule import TOP_TURN_RATE_RADPS

__all__ = [
    "FIT_RANGES",
    "JITTER_SEPARATION",
    "fit_ramp",
    "fit_response",
    "fit_spin",
    "fit_spin_team",
    "fit_steps",
    "fit_steps_team",
    "fit_still",
    "fit_timed",
    "jitter_posterior",
    "loop_timing",
    "observed_distance",
    "team_holds",
]

FIT_RANGES = {
    "delay_ticks": range(9),
    "tau_s": np.round(np.arange(0.0, 0.2001, 0.0025), 6),
    "cap_fraction": np.round(np.arange(0.70, 1.0001, 0.01), 4),
    "accel_radps2": (0.0, 200.0),
}
"""The grids of the ``steps`` fit; the slew limit is either none (0) or the firmware's 200 rad/s²."""
SECOND_FIT_CAPS = 0.03
"""The fit at the jitter found tries caps from this below the first fit's lowest (fraction of the top speed)."""
JACKKNIFE_BLOCKS = 16
"""Stretches of a ``steps`` log (one cycle each, 3.3 s) the gain difference's jackknife leaves out in turn."""
DEAD_ZONE_GRID = np.round(np.arange(0.0, 4.5001, 0.05), 4)
"""Dead zones (rad/s) the ``ramp`` fit tries: up to 4.5 of the ramp's 5 rad/s."""


def observed_distance(poses: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(K, N) forward distance each robot drove along its own heading, the unwrapped heading change
    and the fresh-sample mask, from measured poses (K, N, 3): the sum of the increments between
    fresh poses, each projected on the mean of its two headings. (Along the start heading instead, a
    robot whose wheels differ, and so drives a curve, would seem slower: cos of its drift.) A
    repeated pose (held or frozen) is not fresh; the distance at it is the last fresh one's."""
    x, y, th = (poses[..., j].astype(np.float64) for j in range(3))
    fresh = np.ones(x.shape, dtype=bool)
    fresh[1:] = (np.diff(poses, axis=0) != 0).any(axis=2)
    heading = np.unwrap(th, axis=0)
    dist = np.zeros(x.shape)
    for i in range(x.shape[1]):
        f = np.flatnonzero(fresh[:, i])
        mid = 0.5 * (heading[f[1:], i] + heading[f[:-1], i])
        step = np.diff(x[f, i]) * np.cos(mid) + np.diff(y[f, i]) * np.sin(mid)
        travelled = np.zeros(x.shape[0])
        travelled[f[1:]] = step
        dist[:, i] = np.cumsum(travelled)
    return dist, heading - heading[0], fresh


def _model_speed(v_cmd: np.ndarray, taus: np.ndarray, cap: float, accel: float) -> np.ndarray:
    """(K, T) forward speed (m/s) for the commanded speed (K,) through the layer's wheel model
    (equal wheels, gain 1): cap at ``cap`` of the top wheel speed, slew ``accel`` rad/s², then
    a first-order lag per τ (T,); 0 = no lag."""
    r, top = C.GRITSBOT.wheel_radius_m, C.GRITSBOT.max_wheel_velocity_radps
    target = np.clip(v_cmd / r, -cap * top, cap * top)
    alpha = np.where(taus > 0, np.exp(-C.CONTROL_DT_S / np.maximum(taus, 1e-9)), 0.0)
    step = accel * C.CONTROL_DT_S if accel > 0 else np.inf
    speed = np.zeros(taus.shape)
    out = np.empty((v_cmd.size, taus.size))
    for k, want in enumerate(target):
        new = alpha * speed + (1 - alpha) * want
        speed = speed + np.clip(new - speed, -step, step)
        out[k] = speed
    return out * r


def _default_shapes() -> list[tuple[float, float]]:
    """Every (cap, slew) pair of :data:`FIT_RANGES`."""
    return [(cap, accel) for accel in FIT_RANGES["accel_radps2"] for cap in FIT_RANGES["cap_fraction"]]


def _shift(travelled: np.ndarray, d: int) -> np.ndarray:
    """(K, ...) ``travelled`` seen ``d`` ticks late: row k holds row k - d (0 before the first)."""
    K = travelled.shape[0]
    return np.concatenate([np.zeros((min(d, K), *travelled.shape[1:])), travelled[: max(K - d, 0)]])


def _robot_travel(v_cmd: np.ndarray, row: dict) -> np.ndarray:
    """(K,) the distance one robot's fitted wheel model (its lag, cap, slew and gain, ``row``)
    travels for its commanded speed (K,), by the start of each tick."""
    v = _model_speed(v_cmd, np.array([row["tau_s"]]), row["cap_fraction"], row["accel_radps2"])[:, 0]
    return row["gain"] * np.concatenate([[0.0], np.cumsum(v)[:-1] * C.CONTROL_DT_S])


JITTER_SEPARATION = 16.0
"""A tick tells whether its pose is one tick late where the two predictions, on time and one tick
late, differ by at least this many noise variances summed over the robots seen (4 SD): a robot at
half speed moves 3 mm a tick against 1 mm of pose noise. Slower ticks are left out of the share."""


def jitter_posterior(
    dist: np.ndarray, fresh: np.ndarray, v_cmd: np.ndarray, rows: list[dict]
) -> tuple[np.ndarray, np.ndarray]:
    """(K,) for each tick, the probability that the team's pose message was one tick older than each
    robot's delay (the layer's ``pose_delay_jitter_prob``, common to the team: one message carries
    every pose), and (K,) which ticks can tell (:data:`JITTER_SEPARATION`; elsewhere the
    probability is about the share's own).

    The ticks with a fresh pose form a chain; between two of them each robot seen at both moved
    ``dist`` (K, N) by its fitted model's travel (``rows``, :func:`fit_response` at no jitter) from
    the earlier tick's state (on time or late) to the later one's, plus Gaussian noise. The
    forward-backward pass gives each tick's posterior; the share late (the prior) and the noise
    variance are refitted by expectation-maximization (ten rounds). All 0 where no tick can tell."""
    travel = np.stack([_robot_travel(v_cmd[:, i], r) for i, r in enumerate(rows)], axis=1)  # (K, N)
    delay = [r["delay_ticks"] for r in rows]
    late = [np.stack([_shift(travel[:, i], d + j) for i, d in enumerate(delay)], axis=1) for j in (0, 1)]
    nodes = np.flatnonzero(fresh.any(axis=1))
    prev, cur = nodes[:-1], nodes[1:]
    seen = fresh[prev] & fresh[cur]  # (M, N): robots fresh at both ends of a link
    step = dist[cur] - dist[prev]
    # sq[a, c, m]: squared residuals summed over robots with the earlier tick in state a, the later in c
    sq = np.stack(
        [np.stack([((step - late[c][cur] + late[a][prev]) ** 2 * seen).sum(1) for c in (0, 1)]) for a in (0, 1)]
    )
    count = max(int(seen.sum()), 1)
    apart = ((late[0][cur] - late[1][cur]) ** 2 * seen).sum(1)  # (M,)
    sigma2 = max(float(np.median(sq.min(axis=(0, 1)) / np.maximum(seen.sum(1), 1))) / 0.455, 1e-12)
    K = dist.shape[0]
    share, gamma = 0.2, np.zeros((nodes.size, 2))
    for _ in range(10):
        tells = apart >= JITTER_SEPARATION * sigma2
        if not tells.any():
            return np.zeros(K), np.zeros(K, dtype=bool)
        psi = -sq / (2.0 * sigma2) + np.log([1.0 - share, share])[None, :, None]
        psi = np.exp(psi - psi.max(axis=(0, 1), keepdims=True))  # (2, 2, M), scaled per link
        M = psi.shape[2]
        alpha, beta = np.empty((M + 1, 2)), np.ones((M + 1, 2))
        alpha[0] = (1.0 - share, share)
        for m in range(M):  # a chain of two states: a loop over links, each a 2 x 2 product
            a = alpha[m] @ psi[:, :, m]
            alpha[m + 1] = a / a.sum()
        for m in range(M - 1, -1, -1):
            b = psi[:, :, m] @ beta[m + 1]
            beta[m] = b / b.sum()
        gamma = alpha * beta
        gamma /= gamma.sum(1, keepdims=True)
        xi = alpha[:-1, :, None] * psi.transpose(2, 0, 1) * beta[1:, None, :]  # (M, 2, 2)
        xi /= xi.sum(axis=(1, 2), keepdims=True)
        share = float(np.clip(gamma[1:, 1][tells].mean(), 1e-6, 1 - 1e-6))
        sigma2 = max(float((xi.transpose(1, 2, 0) * sq).sum()) / count, 1e-12)
    late_p, told = np.full(K, share), np.zeros(K, dtype=bool)
    late_p[nodes] = gamma[:, 1]
    told[cur[tells]] = True
    return late_p, told


def fit_timed(dist: np.ndarray, fresh: np.ndarray, v_cmd: np.ndarray, shapes=None) -> tuple[list[dict], np.ndarray]:
    """:func:`fit_response` with the team's pose jitter found and then modelled: a first fit at no
    jitter, each tick's posterior of a late pose (:func:`jitter_posterior`), and the fit again with
    each tick's pose expected from its posterior (where a tick tells, nearly on time or late: the
    jitter's own scatter, which grows with the speed and hides the cap, leaves the increments).
    Returns (rows, the posterior at the ticks that tell (T,)); each row's ``jitter_share`` is the
    team's, their mean (0 where no tick tells)."""
    rows = fit_response(dist, fresh, v_cmd, shapes)
    late_p, tells = jitter_posterior(dist, fresh, v_cmd, rows)
    told = late_p[tells]
    share = float(told.mean()) if told.size else 0.0
    if share > 0:  # the second fit near the first one's delays, and at caps from a little below its lowest up:
        # the jitter's scatter pulls the first fit's caps down (it trades a cap for gain), never up
        near = [d for d in FIT_RANGES["delay_ticks"] if any(abs(d - r["delay_ticks"]) <= 1 for r in rows)]
        low = min(r["cap_fraction"] for r in rows) - SECOND_FIT_CAPS
        shapes = [(cap, accel) for cap, accel in (shapes or _default_shapes()) if cap >= low]
        rows = fit_response(dist, fresh, v_cmd, shapes, jitter=late_p, delays=near)
    for row in rows:
        row["jitter_share"] = share
    return rows, told


def fit_response(
    dist: np.ndarray, fresh: np.ndarray, v_cmd: np.ndarray, shapes=None, jitter=0.0, delays=None
) -> list[dict]:
    """Per robot: the delay, lag, gain and cap that best turn the commanded speed v_cmd (K, N) into
    the observed distance dist (K, N) (fresh samples only); see :func:`fit_steps`. ``shapes``: the
    (cap, slew) pairs to try, ``delays`` the delays (default: the grids of :data:`FIT_RANGES`).
    ``jitter``: the probability that a tick's pose is one tick older than the delay, one for all
    ticks or (K,) one per tick (the model is then the expected position, (1 - jitter) of the pose d
    ticks old and jitter of the one d + 1 ticks old; unmodelled, a jitter of 0.2 reads as 0.01 s
    more lag).

    The fit compares the distance travelled between consecutive fresh samples, not the distance
    since the start: the wheels' disturbance makes the error of a cumulative distance a random walk,
    which least squares on it weighs wrongly (one slow stretch moves every later residual), while
    the increments' errors are nearly independent."""
    K, N = dist.shape
    taus = FIT_RANGES["tau_s"]
    delays = list(FIT_RANGES["delay_ticks"] if delays is None else delays)
    if shapes is None:
        shapes = _default_shapes()
    res = np.empty((N, len(shapes), len(delays), taus.size))
    gains = np.empty_like(res)
    late = None if np.all(np.asarray(jitter) == 0) else np.broadcast_to(np.asarray(jitter, float), (K,))[:, None]
    commands, which = np.unique(v_cmd, axis=1, return_inverse=True)  # the experiments send every robot the same
    for ci, (cap, accel) in enumerate(shapes):
        model_v = [_model_speed(commands[:, u], taus, cap, accel) for u in range(commands.shape[1])]  # (K, T) each
        for i in range(N):
            f = np.flatnonzero(fresh[:, i])
            b = np.diff(dist[f, i])[:, None]
            travelled = np.vstack([np.zeros((1, taus.size)), np.cumsum(model_v[which[i]], 0)[:-1] * C.CONTROL_DT_S])
            for di, d in enumerate(delays):
                # the pose at k is the true pose at k - d; b = g a by least squares (no offset: increments)
                at = _shift(travelled, d)
                if late is not None:
                    at = (1.0 - late) * at + late * _shift(travelled, d + 1)
                a = np.diff(at[f], axis=0)
                g = (a * b).sum(0) / np.maximum((a * a).sum(0), 1e-12)
                gains[i, ci, di] = g
                res[i, ci, di] = ((b - g * a) ** 2).mean(0)
    best_per_tau = res.min(axis=(1, 2))  # (N, T): each robot at its best cap and delay
    t_shared = int(np.argmin(best_per_tau.sum(0)))
    caps = np.array([cap for cap, _ in shapes])
    out = []
    for i in range(N):
        at_tau = res[i, :, :, t_shared]
        ci, di = np.unravel_index(np.argmin(at_tau), at_tau.shape)
        # the best fit with a cap at or above the fastest speed sent, which never binds: the robot without one
        free = np.flatnonzero(caps >= np.abs(v_cmd[:, i]).max() / C.GRITSBOT.max_linear_velocity_mps - 1e-9)
        fi, fd = np.unravel_index(np.argmin(at_tau[free]), at_tau[free].shape) if free.size else (ci, di)
        fi = free[fi] if free.size else ci
        own_t = int(np.argmin(res[i, ci, di]))
        out.append(
            {
                "delay_ticks": delays[di],
                "tau_s": float(taus[t_shared]),
                "tau_own_s": float(taus[own_t]),
                "gain": float(gains[i, ci, di, t_shared]),
                "cap_fraction": float(shapes[ci][0]),
                "accel_radps2": float(shapes[ci][1]),
                "rms_m": math.sqrt(float(res[i, ci, di, t_shared])),  # of the increments
                "free_gain": float(gains[i, fi, fd, t_shared]),
                "free_delay_ticks": delays[fd],
                "free_accel_radps2": float(shapes[fi][1]),
            }
        )
    return out


def _uncapped_unless_seen(row: dict) -> None:
    """A robot whose cap :func:`reach_test` did not see binding takes the fit without a cap (the
    noise, from above, can only pull a fitted cap down, trading it for gain)."""
    if not row["cap_seen"]:
        row["gain"], row["delay_ticks"], row["accel_radps2"] = (
            row["free_gain"],
            row["free_delay_ticks"],
            row["free_accel_radps2"],
        )
        row["cap_fraction"] = 1.0


CAP_CONFIDENCE = 0.995
"""One-sided confidence that a robot's cap binds before it counts as seen: 2.5 % shared by four robots,
so that a team of free robots shows a false cap in about 2.5 % of logs."""
SETTLE_TICKS = 8
"""Ticks a command must have held (at the robot, after its delay) before a phase's speed counts:
the lag's transient is then mostly over (the rest is in the model the speed is compared with)."""


def steady_speeds(
    dist: np.ndarray, fresh: np.ndarray, v_cmd: np.ndarray, row: dict
) -> list[tuple[float, float, float]]:
    """One robot's (commanded, reached, modelled) speed in each phase of held command: the slopes, by
    least squares over the fresh ticks whose command, ``row["delay_ticks"]`` ticks earlier, had held
    for :data:`SETTLE_TICKS` (at least 4 ticks), of its distance (K,) and of the distance its fitted
    model (``row``: lag, slew, delay and the team's jitter) drives with no cap and gain 1. Their ratio
    is the robot's gain in that phase, free of the lag's transient; each phase is a stretch of time of
    its own (the wheels' disturbance decorrelates within 0.2 s), so phases are its replicates."""
    K, d = dist.shape[0], row["delay_ticks"]
    sent = _shift(v_cmd, d)
    held = np.zeros(K, dtype=bool)
    held[SETTLE_TICKS:] = True
    for j in range(1, SETTLE_TICKS + 1):  # the command unchanged over the last SETTLE_TICKS ticks
        held[j:] &= np.abs(sent[j:] - sent[:-j]) <= 0.01 * np.abs(sent[j:]) + 1e-9
    held &= np.abs(sent) > 0
    travel = _robot_travel(v_cmd, {**row, "cap_fraction": 1.0, "gain": 1.0})
    share = row.get("jitter_share", 0.0)
    model = (1.0 - share) * _shift(travel, d) + share * _shift(travel, d + 1)
    phase = np.cumsum(np.r_[True, np.diff(held.astype(int)) != 0])
    out = []
    for label in np.unique(phase[held]):
        ticks = np.flatnonzero(held & fresh & (phase == label))
        if ticks.size >= 4:
            t = ticks * C.CONTROL_DT_S
            out.append(
                (
                    float(sent[ticks].mean()),
                    float(np.polyfit(t, dist[ticks], 1)[0]),
                    float(np.polyfit(t, model[ticks], 1)[0]),
                )
            )
    return out


def reach_test(phases: list[tuple[float, float, float]]) -> dict:
    """Whether a robot's cap binds at its fastest commands, from :func:`steady_speeds`:
    ``reach_fraction``, the speed it holds at the fastest level (a fraction of the top speed: the
    speed sent times reached / modelled, in the mean over those phases) and ``reach_se`` its standard
    error over them;
    ``speed_ratio``, each fastest phase's gain (reached / modelled) over the preceding slower phase's,
    in the mean (1 for a robot whose cap never binds), with its one-sided upper t-bound over the phase
    pairs (:data:`CAP_CONFIDENCE`); ``cap_seen``, that bound below 1: the cap binds beyond the phases'
    own scatter. A
    cap that binds by less is not seen, but the robot's reach then lies close to it. nan and False
    without two pairs."""
    from scipy import stats

    levels = np.array([abs(c) for c, _, _ in phases])
    out = {"reach_fraction": float("nan"), "reach_se": float("nan"), "speed_ratio": float("nan")}
    out |= {"speed_ratio_hi": float("nan"), "cap_seen": False}
    if levels.size < 2 or np.ptp(levels) < 0.05 * levels.max():
        return out
    fast = levels > levels.min() + 0.5 * np.ptp(levels)
    # reached over modelled, times the speed sent: what the robot holds there, the lag's transient taken out
    held = np.array([abs(c) * v / m for (c, v, m), f in zip(phases, fast) if f]) / C.GRITSBOT.max_linear_velocity_mps
    out["reach_fraction"] = float(held.mean())
    out["reach_se"] = float(held.std(ddof=1) / math.sqrt(held.size)) if held.size > 1 else float("nan")
    q = np.array(
        [
            (phases[k][1] / phases[k][2]) / (phases[k - 1][1] / phases[k - 1][2])
            for k in range(1, len(phases))
            if fast[k] and not fast[k - 1] and np.sign(phases[k][0]) == np.sign(phases[k - 1][0])
        ]
    )
    out["slow_gain"] = float(np.mean([v / m for (_, v, m), f in zip(phases, fast) if not f]))
    if q.size >= 2:
        hi = float(q.mean() + stats.t.ppf(CAP_CONFIDENCE, q.size - 1) * q.std(ddof=1) / math.sqrt(q.size))
        out |= {"speed_ratio": float(q.mean()), "speed_ratio_hi": hi, "cap_seen": hi < 1.0}
    return out


def fit_steps(log: np.ndarray) -> list[dict]:
    """Per robot of a ``steps`` log (K, N, 6): delay d (ticks), lag τ (s), speed gain, cap
    fraction of the top speed, the wheels' half gain difference with its standard error (a
    jackknife over :data:`JACKKNIFE_BLOCKS` stretches of the log), the team's jitter share, what
    the robot reaches at the fastest command (:func:`reach_test`) and the fit's RMS residual (m);
    see :func:`fit_steps_team`."""
    return fit_steps_team(log)[0]


def fit_steps_team(log: np.ndarray) -> tuple[list[dict], np.ndarray]:
    """:func:`fit_steps`'s rows and the team's per-tick posterior of a late pose (T,)
    (:func:`jitter_posterior`).

    A lag and one more tick of delay look alike in a noisy step response (a first-order lag
    delays slow signals by τ); the robots share the lag's scale, so τ is chosen first by the
    residual summed over robots (each at its own best d and cap), then each robot's d, cap
    and gain at that τ, and finally each robot's own τ at its d (reported as its spread)."""
    dist, dth, fresh = observed_distance(log[..., 3:])
    out, told = fit_timed(dist, fresh, log[:, :, 1])
    for i, row in enumerate(out):
        f = np.flatnonzero(fresh[:, i])
        ds, dh = np.diff(dist[f, i]), np.diff(dth[f, i])  # increments, as in the response fit
        block = f[1:] * JACKKNIFE_BLOCKS // len(log)
        kappa, se = _ratio_jackknife(ds * dh, ds * ds, block) if np.abs(ds).sum() > 0.05 else (np.nan, np.nan)
        half = C.GRITSBOT.base_length_m / 2.0  # kappa = (g_r - g_l) / l
        row["half_gain_diff"], row["half_gain_diff_se"] = kappa * half, se * half
        # the fastest wheel speed the robot was sent, as a fraction of the top: the schedule asks for
        # FULL_FRACTION, but a barrier may have cut it (V2's does, to ~0.93): a cap is only seen below it
        row["full_fraction"] = float(np.abs(log[:, i, 1]).max()) / C.GRITSBOT.max_linear_velocity_mps
        row |= reach_test(steady_speeds(dist[:, i], fresh[:, i], log[:, i, 1], row))
        _uncapped_unless_seen(row)
    return out, told


def _ratio_jackknife(num: np.ndarray, den: np.ndarray, block: np.ndarray) -> tuple[float, float]:
    """sum(num) / sum(den) and its delete-one-block jackknife standard error over the blocks
    ``block`` (one label per term): the blocks are stretches of time, long next to the wheels'
    0.2 s disturbance, so their errors are close to independent."""
    ratio = float(num.sum() / den.sum())
    labels = np.unique(block)
    if labels.size < 2:
        return ratio, float("nan")
    n_b = np.array([num[block == b].sum() for b in labels])
    d_b = np.array([den[block == b].sum() for b in labels])
    left = (num.sum() - n_b) / (den.sum() - d_b)
    return ratio, float(np.sqrt((labels.size - 1) / labels.size * ((left - left.mean()) ** 2).sum()))


def fit_spin(log: np.ndarray) -> list[dict]:
    """Per robot of a ``spin`` log (K, N, 6); see :func:`fit_spin_team`."""
    return fit_spin_team(log)[0]


def fit_spin_team(log: np.ndarray) -> tuple[list[dict], np.ndarray]:
    """Per robot of a ``spin`` log (K, N, 6) and the team's per-tick posterior of a late pose: the
    fit of :func:`fit_steps_team` on the wheels' rim distance l/2 · Δθ against the commanded rim
    speed l/2 · ω (a turn in place drives the wheels at ∓ω l/2), so ``gain`` is the turn-rate gain
    and ``cap_fraction`` the reachable wheel speed; then the circle the tracked point draws:
    x = c_x + R sin θ + e cos θ, y = c_y − R cos θ + e sin θ by least squares, where
    R = v/ω = l (g_r − g_l) / (2 (g_r + g_l)) gives the half gain difference (its standard error a
    jackknife over the half-rate phases) and e is how far ahead of the wheel axle the tracked point
    sits (a point beside the axle line would add to R: the ``steps`` heading drift is the estimate
    that cannot see it)."""
    _, dth, fresh = observed_distance(log[..., 3:])
    half = C.GRITSBOT.base_length_m / 2.0
    out, told = fit_timed(dth * half, fresh, log[:, :, 2] * half)
    full = float(np.abs(log[:, :, 2]).max()) * half / C.GRITSBOT.max_linear_velocity_mps
    for i, row in enumerate(out):
        row["full_fraction"] = full
        row |= reach_test(steady_speeds(dth[:, i] * half, fresh[:, i], log[:, i, 2] * half, row))
        _uncapped_unless_seen(row)
        coef, se = _spin_circle(log[:, i], fresh[:, i], row["delay_ticks"])
        scale = 2.0 * row["gain"] / C.GRITSBOT.base_length_m
        row["half_gain_diff"], row["half_gain_diff_se"] = float(coef[0] * scale), float(se * scale)
        row["tracked_ahead_m"] = float(coef[1])
    return out, told


def _spin_circle(log: np.ndarray, fresh: np.ndarray, delay: int, settle: int = 6) -> tuple[np.ndarray, float]:
    """(R, e) of one robot's ``spin`` log (K, 6) by least squares over the poses of the half-rate
    phases (the command steady for ``settle`` ticks, ``delay`` ticks earlier), each phase with a
    centre of its own, and R's delete-one-phase jackknife standard error; nan where the heading
    does not turn more than half round in them."""
    w = log[:, 2]
    level = 0.5 * TOP_TURN_RATE_RADPS
    at_level = np.abs(np.abs(w) - level) < 0.02 * level
    steady = np.convolve(at_level, np.ones(settle), "full")[: len(w)] >= settle  # the last `settle` ticks at it
    use = np.zeros_like(steady)
    use[delay:] = steady[: len(steady) - delay]
    segment = np.cumsum(np.r_[True, np.diff(use.astype(int)) != 0])  # one id per phase
    use &= fresh  # (a held pose is left out, not a new phase)
    segment = segment[use]
    ids = np.unique(segment)
    th, x, y = log[use, 5], log[use, 3], log[use, 4]
    if ids.size == 0 or max(np.ptp(np.unwrap(th[segment == s])) for s in ids) < np.pi / 2:
        return np.full(2, np.nan), float("nan")
    n, S = th.size, ids.size
    design = np.zeros((2 * n, 2 * S + 2))
    col = np.searchsorted(ids, segment)
    design[np.arange(n), 2 * col] = 1.0  # each phase's centre x
    design[n + np.arange(n), 2 * col + 1] = 1.0  # and y
    design[:n, -2], design[n:, -2] = np.sin(th), -np.cos(th)
    design[:n, -1], design[n:, -1] = np.cos(th), np.sin(th)
    target = np.concatenate([x, y])
    coef = np.linalg.lstsq(design, target, rcond=None)[0][-2:]
    if S < 2:
        return coef, float("nan")
    left = np.empty(S)
    for s in range(S):  # a phase left out: its rows and its centre's two columns
        keep_rows = np.tile(col != s, 2)
        keep_cols = np.ones(2 * S + 2, dtype=bool)
        keep_cols[2 * s : 2 * s + 2] = False
        left[s] = np.linalg.lstsq(design[keep_rows][:, keep_cols], target[keep_rows], rcond=None)[0][-2]
    return coef, float(np.sqrt((S - 1) / S * ((left - left.mean()) ** 2).sum()))


def loop_timing(log: np.ndarray) -> dict:
    """The loop's own timing from a log's clock column: median and 95th percentile of the tick (s),
    and the share of ticks longer than 1.5 × 0.033 s."""
    dt = np.diff(log[:, 0, 0])
    return {
        "tick_s": float(np.median(dt)),
        "tick_p95_s": float(np.percentile(dt, 95)),
        "late_share": float((dt > 1.5 * C.CONTROL_DT_S).mean()),
    }


def fit_ramp(log: np.ndarray) -> list[dict]:
    """Per robot of a ``ramp`` log (K, N, 6): the dead zone (rad/s of wheel speed), the delay d
    (ticks), the speed gain and the RMS residual (m) of the best fit (see the module docstring)."""
    dist, _, fresh = observed_distance(log[..., 3:])
    K, N = dist.shape
    wheel = log[:, :, 1] / C.GRITSBOT.wheel_radius_m  # (K, N) commanded wheel speed, rad/s
    out = []
    for i in range(N):
        m = fresh[:, i]
        b = dist[m, i][:, None]
        w = wheel[:, i][:, None]
        moving = np.where(np.abs(w) < DEAD_ZONE_GRID[None, :], 0.0, w) * C.GRITSBOT.wheel_radius_m  # (K, D) m/s
        travelled = np.vstack([np.zeros((1, DEAD_ZONE_GRID.size)), np.cumsum(moving, 0)[:-1] * C.CONTROL_DT_S])
        best = None
        for d in FIT_RANGES["delay_ticks"]:
            a = np.vstack([np.zeros((d, DEAD_ZONE_GRID.size)), travelled[: K - d]])[m]
            n, sa, sb = a.shape[0], a.sum(0), b.sum()
            saa, sab = (a * a).sum(0), (a * b).sum(0)
            g = (n * sab - sa * sb) / np.maximum(n * saa - sa * sa, 1e-12)
            c = (sb - g * sa) / n
            res = ((b - g * a - c) ** 2).mean(0)
            j = int(np.argmin(res))
            if best is None or res[j] < best[0]:
                best = (float(res[j]), j, d, float(g[j]))
        res, j, d, g = best
        out.append({"dead_zone_radps": float(DEAD_ZONE_GRID[j]), "delay_ticks": d, "gain": g, "rms_m": math.sqrt(res)})
    return out


def fit_still(log: np.ndarray) -> list[dict]:
    """Per robot of a ``still`` log: pose noise SD (x, y in m, θ in rad) over fresh samples and the
    share of repeated samples (holds and the robot's own freezes together)."""
    _, _, fresh = observed_distance(log[..., 3:])
    out = []
    for i in range(log.shape[1]):
        m = fresh[:, i]
        if m[1:].sum() < 2:  # the pose never changed: no noise, and then a repeat is not a sign of a hold
            out.append({"noise_xy_m": 0.0, "noise_theta_rad": 0.0, "repeat_share": float("nan")})
            continue
        xy = log[m, i, 3:5]
        th = np.unwrap(log[m, i, 5])
        out.append(
            {
                "noise_xy_m": float(xy.std(0, ddof=1).mean()),
                "noise_theta_rad": float(th.std(ddof=1)),
                "repeat_share": float(1.0 - m[1:].mean()),
            }
        )
    return out


def team_holds(poses: np.ndarray, robots: np.ndarray | None = None) -> np.ndarray:
    """(K - 1,) 1 where every robot of ``robots`` (default: all) repeated its pose at a tick, else 0,
    from measured poses (K, N, 3): the team's holds (one message carries every pose, so a message
    that did not come repeats all of them), told apart from one robot's tracking freeze. Use it
    where a fresh pose always differs from the last (pose noise, or a robot that drives)."""
    _, _, fresh = observed_distance(poses)
    rows = slice(None) if robots is None else robots
    return (~fresh[1:, rows].any(axis=1)).astype(np.float64)
