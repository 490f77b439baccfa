"""Do the written intervals cover? Known truth, many seeds, every interval a profile states checked.

A truth profile (:data:`COVERAGE_TRUTH`: ``nominal`` with every nuisance on, and the identified
parameters moved away from nominal's values so that a fit which returned nominal's would fail) is
simulated seed by seed as the four experiments (:func:`comat.calibration.experiments.simulate`, four
robots), fitted and written as ``comat calibrate`` writes a profile; each 95 % interval read back from
the profile (:func:`comat.calibration.intervals.read_fit`) is checked against the truth it is for:

* a parameter each robot has on its own (its gains, lag, noise, dead zone) has an interval over robots
  for the **fleet's** value, the layer's parameter (the mean of the range it draws a robot's from);
* a parameter the team shares (the holds, the pose jitter) has an interval over blocks of ticks for
  the layer's probability;
* the spread and the derate have intervals for the layer's ``wheel_gain_spread`` and
  ``top_speed_derate_min``, from the robots' own draws;
* the robots' ranges (the delay, the reachable speeds) are no 95 % intervals: the delay's written range
  is checked against the range of the robots' draws, exactly (:func:`judge`).

``results/calibration/coverage.py`` runs twenty seeds and writes ``coverage.md``; a nominal 95 %
interval covers in at least 17 of 20 with probability 0.98.
"""

from __future__ import annotations

import numpy as np

from comat.calibration.intervals import PARAMETER_KINDS
from comat.calibration.recovery import level_truth
from comat.reality import resolve_reality

__all__ = ["COVERAGE_TRUTH", "JUDGED", "fleet_truth", "judge", "summarize"]

COVERAGE_TRUTH = {
    "level": "nominal",
    "pose_delay_ticks": 1,
    "pose_delay_spread_ticks": 1,
    "pose_delay_jitter_prob": 0.25,
    "pose_hold_prob": 0.2,
    "pose_noise_xy_m": 0.0015,
    "pose_noise_theta_rad": 0.015,
    "motor_tau_min_s": 0.05,
    "motor_tau_max_s": 0.09,
    "wheel_gain_mean": 0.95,
    "wheel_gain_spread": 0.04,
    "top_speed_derate_min": 0.85,
    "motor_dead_zone_radps": 1.5,
}
"""The study's known truth: ``nominal`` (per-robot command delays, per-wheel lags, the wheels'
Ornstein–Uhlenbeck disturbance, command loss, tracking freezes, pose bias, missed script ticks, the
slew) with the fitted parameters set away from nominal's."""
JUDGED = [name for name, kind in PARAMETER_KINDS.items() if kind != "range"]
"""The parameters whose written interval claims 95 % (every kind but the robots' range)."""


def fleet_truth(reality) -> dict[str, float]:
    """The value each judged parameter's interval is for, at the layer ``reality`` (a level, mapping
    or :class:`~comat.reality.RealityConfig`): the layer's own parameter, a per-robot range's mean."""
    c = resolve_reality(reality)
    return {
        "pose_delay_jitter_prob": c.pose_delay_jitter_prob,
        "motor_tau_s": (c.motor_tau_min_s + c.motor_tau_max_s) / 2.0,
        "speed_gain": c.wheel_gain_mean,
        "turn_gain": c.wheel_gain_mean,
        "tracked_ahead_m": 0.0,
        "top_speed_derate_min": c.top_speed_derate_min,
        "wheel_gain_spread": c.wheel_gain_spread,
        "pose_noise_xy_m": c.pose_noise_xy_m,
        "pose_noise_theta_rad": c.pose_noise_theta_rad,
        "pose_hold_prob": c.pose_hold_prob,
        "motor_dead_zone_radps": c.motor_dead_zone_radps,
        "loop_tick_s": 0.033,
    }


def judge(rows: list[dict], reality, seed: int, robots: int = 4) -> dict[str, dict]:
    """Per judged parameter of one seed's written fit ``rows``: ``{"estimate", "lo", "hi", "kind",
    "truth", "covered"}`` (covered: lo <= truth <= hi; False where no interval was written); and
    ``pose_delay_ticks``: the written robots' range of delays against the range of the layer's draws
    at ``seed`` (:func:`comat.calibration.recovery.level_truth`), exactly."""
    truth = fleet_truth(reality)
    by_name = {r["name"]: r for r in rows}
    out = {}
    for name in JUDGED:
        r = by_name.get(name, {})
        lo, hi, t = r.get("lo"), r.get("hi"), truth[name]
        covered = lo is not None and hi is not None and lo - 1e-12 <= t <= hi + 1e-12
        out[name] = {"estimate": r.get("estimate"), "lo": lo, "hi": hi, "kind": r.get("interval"), "truth": t}
        out[name]["covered"] = bool(covered)
    drawn = level_truth(resolve_reality(reality), seed, robots)["delay"]
    delay = by_name.get("pose_delay_ticks", {})
    written = [delay.get("lo"), delay.get("hi")]
    out["pose_delay_ticks"] = {"written": written, "truth": [int(drawn.min()), int(drawn.max())]}
    out["pose_delay_ticks"]["covered"] = written == out["pose_delay_ticks"]["truth"]
    return out


def summarize(results: list[dict[str, dict]]) -> list[dict]:
    """One row per parameter over the seeds' :func:`judge` results: ``{"name", "kind", "truth",
    "covered", "seeds", "mean_estimate", "mean_width"}`` (the delay: robots' delays exact)."""
    table = []
    for name in [*JUDGED, "pose_delay_ticks"]:
        got = [r[name] for r in results]
        row = {"name": name, "covered": sum(g["covered"] for g in got), "seeds": len(got)}
        if name == "pose_delay_ticks":
            row |= {"kind": "range", "truth": "the robots' draws", "mean_estimate": None, "mean_width": None}
        else:
            est = [g["estimate"] for g in got if g["estimate"] is not None]
            width = [g["hi"] - g["lo"] for g in got if g["lo"] is not None]
            row |= {
                "kind": got[0]["kind"],
                "truth": got[0]["truth"],
                "mean_estimate": float(np.mean(est)) if est else None,
                "mean_width": float(np.mean(width)) if width else None,
            }
        table.append(row)
    return table
