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
from collections.abc import Sequence

import numpy as np

from comat import constants as C
from comat.calibration.experiments import load_log
from comat.calibration.schedule import TOP_TURN_RATE_RADPS
from comat.measure.stats import t_interval
from comat.reality.config import LEVELS

__all__ = [
    "FIT_RANGES",
    "fit_logs",
    "fit_ramp",
    "fit_spin",
    "fit_steps",
    "fit_still",
    "loop_timing",
    "profile_fields",
    "truth_of",
    "unidentified_fields",
]

FIT_RANGES = {
    "delay_ticks": range(9),
    "tau_s": np.round(np.arange(0.0, 0.2001, 0.0025), 6),
    "cap_fraction": np.round(np.arange(0.70, 1.0001, 0.01), 4),
    "accel_radps2": (0.0, 200.0),
}
"""The grids of the ``steps`` fit; the slew limit is either none (0) or the firmware's 200 rad/s²."""
PROFILE_BASE = "nominal"
"""The level a fitted profile starts from: a field the logs cannot identify (faults, freezes, start
error, command loss, the wheel disturbance, ...) keeps this level's value rather than becoming the
ideal world's, and the profile says so field by field (:func:`unidentified_fields`)."""
CAP_MARGIN = 0.02
"""How far below the fastest commanded wheel speed (a fraction of the top) a fitted cap must lie to
count as a derate: two steps of the cap grid, as the pose noise moves the best cap by about one."""
DEAD_ZONE_GRID = np.round(np.arange(0.0, 4.5001, 0.05), 4)
"""Dead zones (rad/s) the ``ramp`` fit tries: up to 4.5 of the ramp's 5 rad/s."""


def _observed_distance(log: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(K, N) distance along each robot's start heading, heading change, and fresh-sample mask."""
    x, y, th = log[..., 3], log[..., 4], log[..., 5]
    c, s = np.cos(th[0]), np.sin(th[0])
    dist = (x - x[0]) * c + (y - y[0]) * s
    fresh = np.ones(x.shape, dtype=bool)
    fresh[1:] = (np.diff(log[..., 3:], axis=0) != 0).any(axis=2)
    dth = np.unwrap(th, axis=0) - th[0]
    return dist, dth, fresh


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


def _fit_response(dist: np.ndarray, fresh: np.ndarray, v_cmd: np.ndarray) -> list[dict]:
    """Per robot: the delay, lag, gain and cap that best turn the commanded speed v_cmd (K, N) into
    the observed distance dist (K, N) (fresh samples only); see :func:`fit_steps`."""
    K, N = dist.shape
    taus = FIT_RANGES["tau_s"]
    delays = list(FIT_RANGES["delay_ticks"])
    shapes = [(cap, accel) for accel in FIT_RANGES["accel_radps2"] for cap in FIT_RANGES["cap_fraction"]]
    res = np.empty((N, len(shapes), len(delays), taus.size))
    gains = np.empty_like(res)
    for i in range(N):
        m = fresh[:, i]
        b = dist[m, i][:, None]
        for ci, (cap, accel) in enumerate(shapes):
            model_v = _model_speed(v_cmd[:, i], taus, cap, accel)  # (K, T)
            travelled = np.vstack([np.zeros((1, taus.size)), np.cumsum(model_v, 0)[:-1] * C.CONTROL_DT_S])
            for di, d in enumerate(delays):
                a = np.vstack([np.zeros((d, taus.size)), travelled[: K - d]])[m]  # pose at k: true pose at k-d
                # least squares b = g a + c: the offset c absorbs the noise of the first pose (the origin)
                n, sa, sb = a.shape[0], a.sum(0), b.sum()
                saa, sab = (a * a).sum(0), (a * b).sum(0)
                det = np.maximum(n * saa - sa * sa, 1e-12)
                g = (n * sab - sa * sb) / det
                c = (sb - g * sa) / n
                gains[i, ci, di] = g
                res[i, ci, di] = ((b - g * a - c) ** 2).mean(0)
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
                "rms_m": math.sqrt(float(res[i, ci, di, t_shared])),
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
    dist, dth, fresh = _observed_distance(log)
    out = _fit_response(dist, fresh, log[:, :, 1])
    for i, row in enumerate(out):
        m = fresh[:, i]
        ds = dist[m, i]
        kappa = float(np.polyfit(ds, dth[m, i], 1)[0]) if np.ptp(ds) > 0.05 else float("nan")
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
    _, dth, fresh = _observed_distance(log)
    half = C.GRITSBOT.base_length_m / 2.0
    out = _fit_response(dth * half, fresh, log[:, :, 2] * half)
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
    dist, _, fresh = _observed_distance(log)
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
    _, _, fresh = _observed_distance(log)
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


def _interval(values: Sequence[float]) -> tuple[float, float, float]:
    v = [x for x in values if np.isfinite(x)]
    if not v:
        return float("nan"), float("nan"), float("nan")
    t = t_interval(v)
    return t["mean"], t["lo"], t["hi"]


def _spread_interval(diffs: Sequence[float], draws: int = 2000) -> tuple[float | None, float | None]:
    """95 % percentile bootstrap over robots of sqrt(6) · SD of the half gain differences (a spread
    is estimated from all robots at once, so no t-interval over robots exists); None with < 3 robots.
    The resampling stream is seeded: the same logs give the same interval."""
    d = np.asarray(diffs, dtype=float)
    if d.size < 3:
        return None, None
    rng = np.random.default_rng(0)
    samples = d[rng.integers(0, d.size, size=(draws, d.size))]
    spreads = math.sqrt(6.0) * samples.std(axis=1, ddof=1)
    return float(np.percentile(spreads, 2.5)), float(np.percentile(spreads, 97.5))


def fit_logs(paths: Sequence[str]) -> dict:
    """Fit every log (one or many runs of each experiment) and return
    ``{"parameters": [{name, estimate, lo, hi, interval, robots, runs, note}], "per_robot": {...}, "timing": [...]}``;
    ``interval`` says what [lo, hi] is: ``"t95"`` the 95 % t-interval over robots (``"t95_runs"``: over
    runs, the loop's tick), ``"bootstrap95"`` a 95 % bootstrap over robots (the wheels' gain spread),
    ``"range"`` the
    per-robot range (the delay, whose spread the profile keeps), None no interval (one robot, or a
    spread estimated from all robots at once; lo and hi None).
    ``steps`` and ``spin`` measure the same wheels: the delay and the lag come from ``steps`` (from
    ``spin`` without it), the gain difference from ``spin`` (from ``steps`` without it), the reachable
    speed from both."""
    if not paths:
        raise ValueError(
            "LOGS: give at least one calibration log (calib_steps.npy, calib_still.npy, calib_ramp.npy, calib_spin.npy)"
        )
    fits = {"steps": fit_steps, "still": fit_still, "ramp": fit_ramp, "spin": fit_spin}
    per: dict[str, list[dict]] = {e: [] for e in fits}
    runs: dict[str, int] = {e: 0 for e in fits}
    timing = []
    for p in paths:
        experiment, log = load_log(p)
        per[experiment] += fits[experiment](log)
        runs[experiment] += 1
        timing.append(loop_timing(log))
    params = []

    def add(name, values, n_runs, note="", robots=None, over="t95"):
        est, lo, hi = _interval(values)
        kind = over if np.isfinite(lo) and np.isfinite(hi) else None  # one value: no interval, not [nan, nan]
        params.append(
            {
                "name": name,
                "estimate": est,
                "lo": lo if kind else None,
                "hi": hi if kind else None,
                "interval": kind,
                "robots": len(values) if robots is None else robots,
                "runs": n_runs,
                "note": note,
            }
        )

    # The delay and the lag from ``steps`` (the experiment built for them; with wheels of unequal lag
    # a spin can read one tick more and a shorter lag), from ``spin`` only without it; the gain
    # difference from ``spin`` (at half rate no wheel is capped, which hides it in ``steps``) when
    # given; the reachable speed from both.
    timed, timed_runs = (per["steps"], runs["steps"]) if per["steps"] else (per["spin"], runs["spin"])
    paired, paired_runs = (per["spin"], runs["spin"]) if per["spin"] else (per["steps"], runs["steps"])
    moving = per["steps"] + per["spin"]
    if moving:
        delays = [r["delay_ticks"] for r in timed]
        params.append(
            {
                "name": "pose_delay_ticks",
                "estimate": int(min(delays)),
                "lo": int(min(delays)),
                "hi": int(max(delays)),
                "interval": "range",
                "robots": len(delays),
                "runs": timed_runs,
                "note": "pose + command delay (not separable); the profile's minimum and spread",
            }
        )
        add("motor_tau_s", [r["tau_s"] for r in timed], timed_runs, "per-robot mean")
        if per["steps"]:
            add(
                "speed_gain",
                [r["gain"] for r in per["steps"]],
                runs["steps"],
                "forward speed gain (mean of the wheels)",
            )
        if per["spin"]:
            add(
                "turn_gain",
                [r["gain"] for r in per["spin"]],
                runs["spin"],
                "turn rate / commanded; the layer's equals the speed gain (a difference: the wheelbase, not modelled)",
            )
            add(
                "tracked_ahead_m",
                [r["tracked_ahead_m"] for r in per["spin"]],
                runs["spin"],
                "tracked point ahead of the wheel axle (reported, not in the layer)",
            )
        add(
            "top_speed_fraction",
            [r["cap_fraction"] * r["gain"] for r in moving],
            runs["steps"] + runs["spin"],
            "reachable / 12.5 rad/s",
        )
        diffs = [r["half_gain_diff"] for r in paired if np.isfinite(r["half_gain_diff"])]
        spread = math.sqrt(6.0) * float(np.std(diffs, ddof=1)) if len(diffs) > 1 else float("nan")
        lo, hi = _spread_interval(diffs)
        params.append(
            {
                "name": "wheel_gain_spread",
                "estimate": spread,
                "lo": lo,
                "hi": hi,
                "interval": None if lo is None else "bootstrap95",
                "robots": len(diffs),
                "runs": paired_runs,
                "note": "sqrt(6) x SD over robots of the half gain difference (triangular)"
                + (", from spin" if per["spin"] else ", from steps"),
            }
        )
    if per["still"]:
        still = per["still"]
        add("pose_noise_xy_m", [r["noise_xy_m"] for r in still], runs["still"])
        add("pose_noise_theta_rad", [r["noise_theta_rad"] for r in still], runs["still"])
        add(
            "pose_hold_prob",
            [r["repeat_share"] for r in still],
            runs["still"],
            "share of repeated poses (nan: the poses never changed, no noise to tell a hold by)",
        )
    if per["ramp"]:
        add(
            "motor_dead_zone_radps",
            [r["dead_zone_radps"] for r in per["ramp"]],
            runs["ramp"],
            "wheel speed below which a robot does not move (0.05 rad/s grid)",
        )
    add(
        "loop_tick_s",
        [t["tick_s"] for t in timing],
        len(paths),
        "median iteration (s), over runs; not in the layer: a longer tick moves the robots further per tick, "
        "which the gains hold",
        robots=0,
        over="t95_runs",
    )
    unknown = (
        "pose_bias_xy_m",
        "command_delay_ticks",
        "command_loss_prob",
        *(() if per["ramp"] else ("motor_dead_zone_radps",)),
        "wheel_disturbance_radps",
        "fault_prob",
    )
    for name in unknown:
        params.append(
            {
                "name": name,
                "estimate": None,
                "lo": None,
                "hi": None,
                "interval": None,
                "robots": 0,
                "runs": 0,
                "note": "not identified by these experiments",
            }
        )
    return {"parameters": params, "per_robot": per, "timing": timing}


def profile_fields(fit: dict) -> dict:
    """The RealityConfig fields a fit writes into a profile file (:func:`comat.reality.config.read_profile`
    reads them back): level :data:`PROFILE_BASE` (``nominal``: what the logs cannot show keeps nominal's
    value, not the ideal world's, :func:`unidentified_fields`) and the fields the logs identified."""
    est = {p["name"]: p for p in fit["parameters"] if p["estimate"] is not None and np.isfinite(p["estimate"])}
    fields: dict = {"level": PROFILE_BASE}
    if "pose_delay_ticks" in est:
        p = est["pose_delay_ticks"]
        fields["pose_delay_ticks"] = int(p["lo"])
        fields["pose_delay_spread_ticks"] = int(p["hi"] - p["lo"])
        # the fitted delay is pose + command together (not separable): all of it on the pose path
        fields["command_delay_ticks"], fields["command_delay_spread_ticks"] = 0, 0
    steps, spin = fit["per_robot"]["steps"], fit["per_robot"].get("spin", [])
    moving, timed = steps + spin, steps or spin  # the lag from steps when given (see fit_logs)
    if moving:
        own = [r["tau_own_s"] for r in timed]
        shared = [r["tau_s"] for r in timed]  # each log's shared lag; the robots' own ones widen the range
        fields["motor_tau_min_s"], fields["motor_tau_max_s"] = float(min(*shared, *own)), float(max(*shared, *own))
        fields["motor_accel_limit_radps2"] = float(np.median([r["accel_radps2"] for r in timed]))
        # a cap at or above the fastest commanded wheel speed (steps: 95 % of the top; spin: 91 %) is not seen
        # a cap counts only clearly below the fastest speed sent (CAP_MARGIN)
        seen = [
            r["cap_fraction"] * r["gain"]
            for r in moving
            if r["cap_fraction"] * r["gain"] < r["full_fraction"] - CAP_MARGIN
        ]
        fields["top_speed_derate_min"] = float(min(1.0, min(seen))) if seen else 1.0
    if "wheel_gain_spread" in est:
        fields["wheel_gain_spread"] = float(min(0.99, max(0.0, est["wheel_gain_spread"]["estimate"])))
    for name in ("pose_noise_xy_m", "pose_noise_theta_rad", "pose_hold_prob", "motor_dead_zone_radps"):
        if name in est:
            fields[name] = float(max(0.0, est[name]["estimate"]))
    return fields


def truth_of(config) -> dict[str, str]:
    """What each fitted parameter should come out as for logs simulated at the known layer ``config``
    (a :class:`~comat.reality.RealityConfig`), as text: a value, or ``lo..hi`` where the layer draws it
    per robot (``comat calibrate --truth``)."""
    c = config
    delay = c.pose_delay_ticks + c.command_delay_ticks
    spread = c.pose_delay_spread_ticks + c.command_delay_spread_ticks
    return {
        "pose_delay_ticks": f"{delay}..{delay + spread}" if spread else f"{delay}",
        "motor_tau_s": f"{c.motor_tau_min_s:.4g}..{c.motor_tau_max_s:.4g}"
        if c.motor_tau_max_s != c.motor_tau_min_s
        else f"{c.motor_tau_min_s:.4g}",
        "speed_gain": "1",
        "turn_gain": "1",
        "tracked_ahead_m": "0",
        "top_speed_fraction": f"{c.top_speed_derate_min:.4g}..1" if c.top_speed_derate_min < 1 else "1",
        "wheel_gain_spread": f"{c.wheel_gain_spread:.4g}",
        "pose_noise_xy_m": f"{c.pose_noise_xy_m:.4g}",
        "pose_noise_theta_rad": f"{c.pose_noise_theta_rad:.4g}",
        "pose_hold_prob": f"{c.pose_hold_prob:.4g}",
        "motor_dead_zone_radps": f"{c.motor_dead_zone_radps:.4g}",
        "loop_tick_s": "0.033",
        "pose_bias_xy_m": f"{c.pose_bias_xy_m:.4g}",
        "command_delay_ticks": f"{c.command_delay_ticks}",
        "command_loss_prob": f"{c.command_loss_prob:.4g}",
        "wheel_disturbance_radps": f"{c.wheel_disturbance_radps:.4g}",
        "fault_prob": f"{c.fault_prob:.4g}",
    }


def unidentified_fields(fields: dict) -> dict[str, str]:
    """Each :class:`~comat.reality.RealityConfig` field a profile does not set from the logs: the
    value it keeps (:data:`PROFILE_BASE`'s) and why, field by field, for the profile file."""
    base = LEVELS[PROFILE_BASE]
    return {
        name: f"{PROFILE_BASE}'s {base[name]!r}: not identified by the calibration experiments"
        for name in base
        if name not in fields
    }
