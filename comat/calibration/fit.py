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
    "fit_ramp",
    "fit_response",
    "fit_spin",
    "fit_steps",
    "fit_still",
    "loop_timing",
    "observed_distance",
]

FIT_RANGES = {
    "delay_ticks": range(9),
    "tau_s": np.round(np.arange(0.0, 0.2001, 0.0025), 6),
    "cap_fraction": np.round(np.arange(0.70, 1.0001, 0.01), 4),
    "accel_radps2": (0.0, 200.0),
}
"""The grids of the ``steps`` fit; the slew limit is either none (0) or the firmware's 200 rad/s²."""
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


def fit_response(dist: np.ndarray, fresh: np.ndarray, v_cmd: np.ndarray, shapes=None) -> list[dict]:
    """Per robot: the delay, lag, gain and cap that best turn the commanded speed v_cmd (K, N) into
    the observed distance dist (K, N) (fresh samples only); see :func:`fit_steps`. ``shapes``: the
    (cap, slew) pairs to try (default: the grids of :data:`FIT_RANGES`).

    The fit compares the distance travelled between consecutive fresh samples, not the distance
    since the start: the wheels' disturbance makes the error of a cumulative distance a random walk,
    which least squares on it weighs wrongly (one slow stretch moves every later residual), while
    the increments' errors are nearly independent."""
    K, N = dist.shape
    taus = FIT_RANGES["tau_s"]
    delays = list(FIT_RANGES["delay_ticks"])
    if shapes is None:
        shapes = [(cap, accel) for accel in FIT_RANGES["accel_radps2"] for cap in FIT_RANGES["cap_fraction"]]
    res = np.empty((N, len(shapes), len(delays), taus.size))
    gains = np.empty_like(res)
    for i in range(N):
        f = np.flatnonzero(fresh[:, i])
        b = np.diff(dist[f, i])[:, None]
        for ci, (cap, accel) in enumerate(shapes):
            model_v = _model_speed(v_cmd[:, i], taus, cap, accel)  # (K, T)
            travelled = np.vstack([np.zeros((1, taus.size)), np.cumsum(model_v, 0)[:-1] * C.CONTROL_DT_S])
            for di, d in enumerate(delays):
                # the pose at k is the true pose at k - d; b = g a by least squares (no offset: increments)
                a = np.diff(np.vstack([np.zeros((d, taus.size)), travelled[: K - d]])[f], axis=0)
                g = (a * b).sum(0) / np.maximum((a * a).sum(0), 1e-12)
                gains[i, ci, di] = g
                res[i, ci, di] = ((b - g * a) ** 2).mean(0)
    best_per_tau = res.min(axis=(1, 2))  # (N, T): each robot at its best cap and delay
    t_shared = int(np.argmin(best_per_tau.sum(0)))
    out = []
    for i in range(N):
        ci, di = np.unravel_index(np.argmin(res[i, :, :, t_shared]), res[i, :, :, 0].shape)
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
            }
        )
    return out


def fit_steps(log: np.ndarray) -> list[dict]:
    """Per robot of a ``steps`` log (K, N, 6): delay d (ticks), lag τ (s), speed gain, cap
    fraction of the top speed, the wheels' half gain difference, and the fit's RMS residual (m).

    A lag and one more tick of delay look alike in a noisy step response (a first-order lag
    delays slow signals by τ); the robots share the lag's scale, so τ is chosen first by the
    residual summed over robots (each at its own best d and cap), then each robot's d, cap
    and gain at that τ, and finally each robot's own τ at its d (reported as its spread)."""
    dist, dth, fresh = observed_distance(log[..., 3:])
    out = fit_response(dist, fresh, log[:, :, 1])
    for i, row in enumerate(out):
        f = np.flatnonzero(fresh[:, i])
        ds, dh = np.diff(dist[f, i]), np.diff(dth[f, i])  # increments, as in the response fit
        kappa = float((ds * dh).sum() / (ds * ds).sum()) if np.abs(ds).sum() > 0.05 else float("nan")
        row["half_gain_diff"] = kappa * C.GRITSBOT.base_length_m / 2.0  # kappa = (g_r - g_l) / l
        # the fastest wheel speed the robot was sent, as a fraction of the top: the schedule asks for
        # FULL_FRACTION, but a barrier may have cut it (V2's does, to ~0.93): a cap is only seen below it
        row["full_fraction"] = float(np.abs(log[:, i, 1]).max()) / C.GRITSBOT.max_linear_velocity_mps
    return out


def fit_spin(log: np.ndarray) -> list[dict]:
    """Per robot of a ``spin`` log (K, N, 6): the fit of :func:`fit_steps` on the wheels' rim
    distance l/2 · Δθ against the commanded rim speed l/2 · ω (a turn in place drives the wheels
    at ∓ω l/2), so ``gain`` is the turn-rate gain and ``cap_fraction`` the reachable wheel speed;
    then the circle the tracked point draws: x = c_x + R sin θ + e cos θ, y = c_y − R cos θ + e sin θ
    by least squares, where R = v/ω = l (g_r − g_l) / (2 (g_r + g_l)) gives the half gain difference
    and e is how far ahead of the wheel axle the tracked point sits (a point beside the axle line
    would add to R: the ``steps`` heading drift is the estimate that cannot see it)."""
    _, dth, fresh = observed_distance(log[..., 3:])
    half = C.GRITSBOT.base_length_m / 2.0
    out = fit_response(dth * half, fresh, log[:, :, 2] * half)
    full = float(np.abs(log[:, :, 2]).max()) * half / C.GRITSBOT.max_linear_velocity_mps
    for i, row in enumerate(out):
        coef = _spin_circle(log[:, i], fresh[:, i], row["delay_ticks"])
        row["half_gain_diff"] = float(2.0 * coef[0] * row["gain"] / C.GRITSBOT.base_length_m)
        row["tracked_ahead_m"] = float(coef[1])
        row["full_fraction"] = full
    return out


def _spin_circle(log: np.ndarray, fresh: np.ndarray, delay: int, settle: int = 6) -> np.ndarray:
    """(R, e) of one robot's ``spin`` log (K, 6) by least squares over the poses of the half-rate
    phases (the command steady for ``settle`` ticks, ``delay`` ticks earlier), each phase with a
    centre of its own; nan where the heading does not turn more than half round in them."""
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
        return np.full(2, np.nan)
    n, S = th.size, ids.size
    design = np.zeros((2 * n, 2 * S + 2))
    col = np.searchsorted(ids, segment)
    design[np.arange(n), 2 * col] = 1.0  # each phase's centre x
    design[n + np.arange(n), 2 * col + 1] = 1.0  # and y
    design[:n, -2], design[n:, -2] = np.sin(th), -np.cos(th)
    design[:n, -1], design[n:, -1] = np.cos(th), np.sin(th)
    return np.linalg.lstsq(design, np.concatenate([x, y]), rcond=None)[0][-2:]


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
    share of repeated samples."""
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
