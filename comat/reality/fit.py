"""Fit the reality layer's parameters to calibration logs (:mod:`comat.reality.calibration`).

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

What the logs cannot show is reported as not identified, never guessed: the pose bias (no
ground truth on the Robotarium), the split of the delay between poses and commands, command
loss, faults (no fault experiment), the wheel disturbance; the dead zone without a ``ramp`` log.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from comat import constants as C
from comat.reality.calibration import load_log
from comat.reality.calibration_schedule import FULL_FRACTION

FULL_STEP = FULL_FRACTION
"""The ``steps`` experiment's full speed, as a fraction of the top speed."""

__all__ = ["FIT_RANGES", "fit_logs", "fit_ramp", "fit_steps", "fit_still", "profile_fields"]

FIT_RANGES = {"delay_ticks": range(9), "tau_s": np.round(np.arange(0.0, 0.2001, 0.0025), 6),
              "cap_fraction": np.round(np.arange(0.70, 1.0001, 0.01), 4), "accel_radps2": (0.0, 200.0)}
"""The grids of the ``steps`` fit; the slew limit is either none (0) or the firmware's 200 rad/s²."""
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


def fit_steps(log: np.ndarray) -> list[dict]:
    """Per robot of a ``steps`` log (K, N, 6): delay d (ticks), lag τ (s), speed gain, cap
    fraction of the top speed, the wheels' half gain difference, and the fit's RMS residual (m).

    A lag and one more tick of delay look alike in a noisy step response (a first-order lag
    delays slow signals by τ); the robots share the lag's scale, so τ is chosen first by the
    residual summed over robots (each at its own best d and cap), then each robot's d, cap
    and gain at that τ, and finally each robot's own τ at its d (reported as its spread)."""
    dist, dth, fresh = _observed_distance(log)
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
            model_v = _model_speed(log[:, i, 1], taus, cap, accel)  # (K, T)
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
        m = fresh[:, i]
        ds = dist[m, i]
        kappa = float(np.polyfit(ds, dth[m, i], 1)[0]) if np.ptp(ds) > 0.05 else float("nan")
        out.append({"delay_ticks": delays[di], "tau_s": float(taus[t_shared]), "tau_own_s": float(taus[own_t]),
                    "gain": float(gains[i, ci, di, t_shared]), "cap_fraction": float(shapes[ci][0]),
                    "accel_radps2": float(shapes[ci][1]),
                    "half_gain_diff": kappa * C.GRITSBOT.base_length_m / 2.0,  # kappa = (g_r - g_l) / l
                    "rms_m": math.sqrt(float(res[i, ci, di, t_shared]))})
    return out


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
        out.append({"noise_xy_m": float(xy.std(0, ddof=1).mean()), "noise_theta_rad": float(th.std(ddof=1)),
                    "repeat_share": float(1.0 - m[1:].mean())})
    return out


def _interval(values: Sequence[float]) -> tuple[float, float, float]:
    from comat.eval.stats import t_interval

    v = [x for x in values if np.isfinite(x)]
    if not v:
        return float("nan"), float("nan"), float("nan")
    t = t_interval(v)
    return t["mean"], t["lo"], t["hi"]


def fit_logs(paths: Sequence[str]) -> dict:
    """Fit every log (one or many runs of each experiment) and return
    ``{"parameters": [{name, estimate, lo, hi, robots, runs, note}], "per_robot": {...}}``."""
    if not paths:
        raise ValueError("LOGS: give at least one calibration log (calib_steps.npy, calib_still.npy)")
    fits = {"steps": fit_steps, "still": fit_still, "ramp": fit_ramp}
    per: dict[str, list[dict]] = {e: [] for e in fits}
    runs: dict[str, int] = {e: 0 for e in fits}
    for p in paths:
        experiment, log = load_log(p)
        per[experiment] += fits[experiment](log)
        runs[experiment] += 1
    params = []

    def add(name, values, experiment, note="", integer=False):
        est, lo, hi = _interval(values)
        if integer and np.isfinite(est):
            est = round(est)
        params.append({"name": name, "estimate": est, "lo": lo, "hi": hi, "robots": len(values),
                       "runs": runs[experiment], "note": note})

    steps, still = per["steps"], per["still"]
    if steps:
        delays = [r["delay_ticks"] for r in steps]
        params.append({"name": "pose_delay_ticks", "estimate": int(min(delays)), "lo": int(min(delays)),
                       "hi": int(max(delays)), "robots": len(delays), "runs": runs["steps"],
                       "note": "pose + command delay (not separable); lo-hi: per-robot range"})
        add("motor_tau_s", [r["tau_s"] for r in steps], "steps", "per-robot mean")
        add("speed_gain", [r["gain"] for r in steps], "steps", "forward speed gain (mean of the wheels)")
        add("top_speed_fraction", [r["cap_fraction"] * r["gain"] for r in steps], "steps", "reachable / 12.5 rad/s")
        diffs = [r["half_gain_diff"] for r in steps]
        spread = math.sqrt(6.0) * float(np.std(diffs, ddof=1)) if len(diffs) > 1 else float("nan")
        params.append({"name": "wheel_gain_spread", "estimate": spread, "lo": float("nan"), "hi": float("nan"),
                       "robots": len(diffs), "runs": runs["steps"],
                       "note": "sqrt(6) x SD over robots of the half gain difference (triangular)"})
    if still:
        add("pose_noise_xy_m", [r["noise_xy_m"] for r in still], "still")
        add("pose_noise_theta_rad", [r["noise_theta_rad"] for r in still], "still")
        add("pose_hold_prob", [r["repeat_share"] for r in still], "still",
            "share of repeated poses (nan: the poses never changed, no noise to tell a hold by)")
    if per["ramp"]:
        add("motor_dead_zone_radps", [r["dead_zone_radps"] for r in per["ramp"]], "ramp",
            "wheel speed below which a robot does not move (0.05 rad/s grid)")
    unknown = ("pose_bias_xy_m", "command_delay_ticks", "command_loss_prob",
               *(() if per["ramp"] else ("motor_dead_zone_radps",)), "wheel_disturbance_radps", "fault_prob")
    for name in unknown:
        params.append({"name": name, "estimate": None, "lo": None, "hi": None, "robots": 0, "runs": 0,
                       "note": "not identified by these experiments"})
    return {"parameters": params, "per_robot": per}


def profile_fields(fit: dict) -> dict:
    """The RealityConfig fields (level ``off`` plus what the logs identified) a fit writes."""
    est = {p["name"]: p for p in fit["parameters"] if p["estimate"] is not None and np.isfinite(p["estimate"])}
    fields: dict = {"level": "off"}
    if "pose_delay_ticks" in est:
        p = est["pose_delay_ticks"]
        fields["pose_delay_ticks"] = int(p["lo"])
        fields["pose_delay_spread_ticks"] = int(p["hi"] - p["lo"])
    steps = fit["per_robot"]["steps"]
    if steps:
        own = [r["tau_own_s"] for r in steps]
        tau = steps[0]["tau_s"]  # the robots' shared lag; their own ones widen the range
        fields["motor_tau_min_s"], fields["motor_tau_max_s"] = float(min(tau, *own)), float(max(tau, *own))
        fields["motor_accel_limit_radps2"] = float(np.median([r["accel_radps2"] for r in steps]))
        reach = min(r["cap_fraction"] * r["gain"] for r in steps)
        # the steps command 95 % of the top speed: a cap at or above that is not seen (no derate)
        fields["top_speed_derate_min"] = float(min(1.0, reach)) if reach < FULL_STEP - 0.01 else 1.0
    if "wheel_gain_spread" in est:
        fields["wheel_gain_spread"] = float(min(0.99, max(0.0, est["wheel_gain_spread"]["estimate"])))
    for name in ("pose_noise_xy_m", "pose_noise_theta_rad", "pose_hold_prob", "motor_dead_zone_radps"):
        if name in est:
            fields[name] = float(max(0.0, est[name]["estimate"]))
    return fields
