"""From fitted logs to the table ``comat calibrate`` prints and the profile it writes.

:func:`fit_logs` fits every log given — the four experiments' ``calib_<experiment>.npy``
(:mod:`comat.calibration.fit`) and any policy run's ``comat_run.npy``
(:mod:`comat.calibration.from_runs`) — and combines them into one row per parameter, each with an
interval that says what kind it is; :func:`profile_fields` turns the rows into the
:class:`~comat.reality.RealityConfig` fields of a profile, :func:`unidentified_fields` says field by
field what the rest keeps, and :func:`truth_of` what a fit should find at a known layer.

Which log gives what, when several measure the same wheels: the delay, the pose jitter and the lag
from ``steps`` (from ``spin`` without it, from the runs without either), the gain difference from
``spin`` (from ``steps`` without it), the derate from ``steps`` (from ``spin`` without it), the speed
gain from ``steps`` (from the runs without it), the turn gain from ``spin`` (from the runs without
it), the holds from ``still`` (from the runs' ticks while driving without it).

Each interval is of the kind its parameter's replicates call for (:mod:`comat.calibration.intervals`):
over robots for what each robot has on its own, over blocks of ticks for what the team shares (the
holds and the jitter of the one pose message per tick).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from comat.calibration.experiments import load_log
from comat.calibration.fit import fit_ramp, fit_spin_team, fit_steps_team, fit_still, loop_timing, team_holds
from comat.calibration.from_runs import MIN_TRAVEL_M, fit_run_team
from comat.calibration.intervals import derate_interval, spread_interval
from comat.measure.stats import block_bootstrap_mean, t_interval
from comat.reality.config import LEVELS
from comat.runlog import LOG_FILE, read_run_log

__all__ = [
    "PROFILE_BASE",
    "fit_logs",
    "is_run_log",
    "profile_fields",
    "truth_of",
    "unidentified_fields",
]

PROFILE_BASE = "nominal"
"""The level a fitted profile starts from: a field the logs cannot identify (faults, freezes, start
error, command loss, the wheel disturbance, ...) keeps this level's value rather than becoming the
ideal world's, and the profile says so field by field (:func:`unidentified_fields`)."""
_MISS = float(LEVELS[PROFILE_BASE]["script_miss_prob"])
"""The script's missed ticks a profile keeps (not identified): each repeats every pose once, as a
hold does, so the holds written leave them out (else they would count twice)."""
ALWAYS_UNIDENTIFIED = {
    "pose_bias_xy_m": "no ground truth on the Robotarium",
    "command_delay_ticks": "the delay is pose + command together: all of it goes to pose_delay_ticks",
    "command_loss_prob": "a lost command looks like a late one",
    "wheel_disturbance_radps": "not separated from the lag and the pose noise",
    "fault_prob": "no fault experiment",
    "motor_accel_limit_radps2": "a slew limit and the lag look alike under the wheels' disturbance "
    "(nominal's 200 rad/s², the firmware's PWM slew, is kept)",
}
"""Parameters no log identifies, and why (a row of the table each)."""


def is_run_log(path: str | Path) -> bool:
    """Whether ``path`` names a policy run's log — its ``comat_run.npy`` or the folder holding it and
    its metadata (:func:`comat.runlog.read_run_log`) — rather than a calibration experiment's
    ``calib_<experiment>.npy``."""
    p = Path(path)
    return p.name == LOG_FILE or p.is_dir()


def _row(name, estimate, lo=None, hi=None, kind=None, robots=0, runs=0, note="") -> dict:
    return {
        "name": name,
        "estimate": estimate,
        "lo": lo,
        "hi": hi,
        "interval": kind,
        "robots": robots,
        "runs": runs,
        "note": note,
    }


def _t_row(name, values, runs, note="", estimate=None, robots=None, kind="t95") -> dict:
    """A row with the 95 % t-interval over ``values`` (robots, or runs); no interval from one value."""
    v = [x for x in values if x is not None and np.isfinite(x)]
    t = t_interval(v) if v else {"mean": float("nan"), "lo": float("nan"), "hi": float("nan")}
    ok = np.isfinite(t["lo"]) and np.isfinite(t["hi"])
    est = t["mean"] if estimate is None else estimate
    return _row(
        name,
        est,
        t["lo"] if ok else None,
        t["hi"] if ok else None,
        kind if ok else None,
        len(v) if robots is None else robots,
        runs,
        note,
    )


def _block_row(name, series: list, runs: int, note: str, transform=None) -> dict:
    """A row for a quantity common to the team: the pooled mean of per-tick ``series`` (one per
    run) with its 95 % block bootstrap interval over ticks (:func:`block_bootstrap_mean`), each end
    mapped by the monotone ``transform``; no row value without a tick."""
    series = [x for x in series if len(x)]
    if not series:
        return _row(name, None, note=f"not identified: {note}")
    b = block_bootstrap_mean(series)
    f = transform or (lambda v: v)
    note += f"; blocks of {'/'.join(str(k) for k in b['blocks'])} ticks"
    return _row(name, f(b["mean"]), f(b["lo"]), f(b["hi"]), "block95", 0, runs, note)


def _read(paths: Sequence[str]) -> tuple[dict[str, list[dict]], dict[str, int], list[dict], dict[str, list]]:
    """Every log fitted: per experiment (and ``run``) the robots' rows, the runs, the loop timings
    and the team's series (``jitter_<source>``: the posterior of a late pose at the ticks that tell;
    ``holds_<source>``: 1 where every robot repeated its pose), one entry per log."""
    per: dict[str, list[dict]] = {e: [] for e in ("steps", "still", "ramp", "spin", "run")}
    runs: dict[str, int] = {e: 0 for e in per}
    team: dict[str, list] = {k: [] for k in ("jitter_steps", "jitter_spin", "jitter_run", "holds_still", "holds_run")}
    timing = []
    for p in paths:
        if is_run_log(p):
            run = read_run_log(str(p))
            rows, series = fit_run_team(run)
            per["run"] += rows
            team["jitter_run"].append(series["jitter"])
            team["holds_run"].append(series["holds"])
            runs["run"] += 1
            timing.append(loop_timing(run.t.astype(np.float64)[:, None, None]))
            continue
        experiment, log = load_log(p)
        if experiment in ("steps", "spin"):
            rows, told = (fit_steps_team if experiment == "steps" else fit_spin_team)(log)
            team[f"jitter_{experiment}"].append(told)
        elif experiment == "still":
            rows = fit_still(log)
            noisy = np.flatnonzero([np.isfinite(r["repeat_share"]) for r in rows])  # a repeat tells only with noise
            team["holds_still"].append(team_holds(log[..., 3:], noisy) if noisy.size else np.zeros(0))
        else:
            rows = fit_ramp(log)
        per[experiment] += rows
        runs[experiment] += 1
        timing.append(loop_timing(log))
    return per, runs, timing, team


def _derate(rows: list[dict]) -> tuple[float, float, float, int]:
    """The profile's ``top_speed_derate_min``, its 95 % interval (:func:`derate_interval`) and how
    many robots' caps were seen (:func:`comat.calibration.fit.reach_test`: binding beyond the
    phases' scatter). A robot whose cap was not seen holds at least what it reached. With no cap
    seen the derate is not identified: :data:`PROFILE_BASE`'s value is kept, within the interval."""
    ok = [r for r in rows if np.isfinite(r["reach_fraction"])]
    seen = [r for r in ok if r["cap_seen"]]
    z = 1.96  # an unseen cap is at least what the robot reached, at the lower 97.5 % bound of that
    above = [r["reach_fraction"] - z * np.nan_to_num(r["reach_se"]) for r in ok if not r["cap_seen"]]
    estimate, lo, hi = derate_interval([r["reach_fraction"] for r in seen], above, [r["reach_se"] for r in seen])
    if not seen:
        estimate = float(min(max(LEVELS[PROFILE_BASE]["top_speed_derate_min"], lo), 1.0))
    return estimate, lo, hi, len(seen)


def fit_logs(paths: Sequence[str]) -> dict:
    """Fit every log (one or many runs of each experiment, and policy runs' logs) and return
    ``{"parameters": [{name, estimate, lo, hi, interval, robots, runs, note}], "per_robot": {...}, "timing": [...]}``;
    ``interval`` names the kind of [lo, hi] (:data:`comat.calibration.intervals.KINDS`, the kind of
    each parameter :data:`~comat.calibration.intervals.PARAMETER_KINDS`); None: no interval (too few
    robots or runs; lo and hi None). An estimate None: not identified (the note says why)."""
    if not paths:
        raise ValueError(
            "LOGS: give at least one calibration log (calib_steps.npy, calib_still.npy, calib_ramp.npy, "
            "calib_spin.npy) or a run's comat_run.npy"
        )
    per, runs, timing, team = _read(paths)
    driven = [r for r in per["run"] if r["used"]]
    source, params = _timing_rows(per, runs, team, driven)
    params += _gain_rows(per, runs, driven)
    moving = per["steps"] + per["spin"]
    if moving:
        params += _cap_rows(per, runs)
    params += _rest_rows(per, runs, team, driven)
    params.append(
        _t_row(
            "loop_tick_s",
            [t["tick_s"] for t in timing],
            len(paths),
            "median iteration (s), over runs; not in the layer: a longer tick moves the robots further "
            "per tick, which the gains hold",
            robots=0,
            kind="t95_runs",
        )
    )
    skipped = sum(not r["used"] for r in per["run"])
    if skipped and source == "run":
        params[0]["note"] += f"; {skipped} robot(s) that drove less than {MIN_TRAVEL_M} m left out"
    for name, why in _unidentified(per, moving).items():
        params.append(_row(name, None, note=f"not identified: {why}"))
    return {"parameters": params, "per_robot": per, "timing": timing}


def _timing_rows(per: dict, runs: dict, team: dict, driven: list[dict]) -> tuple[str, list[dict]]:
    """The delay, its jitter and the motor lag, from the first of steps, spin and the policy runs'
    driven robots that has logs; ``(that source, rows)`` (no rows where none has)."""
    for source in ("steps", "spin", "run"):
        timed = driven if source == "run" else per[source]
        if timed:
            break
    if not timed:
        return source, []
    delays = [r["delay_ticks"] for r in timed]
    return source, [
        _row(
            "pose_delay_ticks",
            int(min(delays)),
            int(min(delays)),
            int(max(delays)),
            "range",
            len(delays),
            runs[source],
            f"pose + command delay (not separable), from {source}; the profile's minimum and spread",
        ),
        _block_row(
            "pose_delay_jitter_prob",
            team[f"jitter_{source}"],
            runs[source],
            f"share of ticks whose pose message is one tick older, from {source} (common to the team)",
        ),
        # the estimate is the lag the robots share (one per log); the interval is over each robot's own best lag
        _t_row(
            "motor_tau_s",
            [r["tau_own_s"] for r in timed],
            runs[source],
            f"shared lag, from {source}; interval over the robots' own",
            float(np.mean([r["tau_s"] for r in timed])),
        ),
    ]


def _gain_rows(per: dict, runs: dict, driven: list[dict]) -> list[dict]:
    """The speed and turn gains and the tracked point: from the steps and spin logs, else the runs."""
    rows = []
    gains, gains_from = (per["steps"], "steps") if per["steps"] else (driven, "run")
    if gains:
        rows.append(
            _t_row(
                "speed_gain",
                [r["gain"] for r in gains],
                runs[gains_from],
                f"forward speed gain (the wheels' mean), from {gains_from}: the profile's wheel_gain_mean",
            )
        )
    turns = [r["gain"] for r in per["spin"]] or [r["turn_gain"] for r in driven]
    if turns:
        rows.append(
            _t_row(
                "turn_gain",
                turns,
                runs["spin"] or runs["run"],
                "turn rate / commanded; the layer's equals the speed gain (a difference: the wheelbase, not modelled)",
            )
        )
    if per["spin"]:
        rows.append(
            _t_row(
                "tracked_ahead_m",
                [r["tracked_ahead_m"] for r in per["spin"]],
                runs["spin"],
                "tracked point ahead of the wheel axle (reported, not in the layer)",
            )
        )
    return rows


def _cap_rows(per: dict, runs: dict) -> list[dict]:
    """The top speed reached, the fleet's smallest cap and the wheels' gain spread: from the logs
    that drive fast or turn (steps, spin)."""
    rows = []
    capped, capped_from = (per["steps"], "steps") if per["steps"] else (per["spin"], "spin")
    reach = [r["reach_fraction"] for r in capped if np.isfinite(r["reach_fraction"])]
    if reach:
        rows.append(
            _row(
                "top_speed_fraction",
                float(np.mean(reach)),
                float(min(reach)),
                float(max(reach)),
                "range",
                len(reach),
                runs[capped_from],
                f"speed held at the fastest command / 12.5 rad/s, from {capped_from} (a robot whose cap "
                "never binds shows its gain times what it was sent)",
            )
        )
        derate, lo, hi, seen = _derate(capped)
        rows.append(
            _row(
                "top_speed_derate_min",
                derate,
                lo,
                hi,
                "order95",
                len(reach),
                runs[capped_from],
                f"the fleet's smallest cap, from {capped_from}: "
                + (
                    f"{seen} of {len(reach)} robots' caps seen binding"
                    if seen
                    else f"no cap seen binding, {PROFILE_BASE}'s kept within the interval"
                ),
            )
        )
    paired, paired_from = (per["spin"], "spin") if per["spin"] else (per["steps"], "steps")
    ok = [r for r in paired if np.isfinite(r["half_gain_diff"])]
    spread, lo, hi = spread_interval([r["half_gain_diff"] for r in ok], [r["half_gain_diff_se"] for r in ok])
    rows.append(
        _row(
            "wheel_gain_spread",
            spread,
            lo,
            hi,
            None if lo is None else "chi2_95",
            len(ok),
            runs[paired_from],
            f"sqrt(6) x SD over robots of the half gain difference (triangular), each robot's own error "
            f"taken out, from {paired_from}",
        )
    )
    return rows


def _rest_rows(per: dict, runs: dict, team: dict, driven: list[dict]) -> list[dict]:
    """What shows at rest or barely moving: the pose noise (still), the held ticks (still, else the
    runs) and the motors' dead zone (ramp)."""
    rows = []
    if per["still"]:
        still = per["still"]
        rows.append(_t_row("pose_noise_xy_m", [r["noise_xy_m"] for r in still], runs["still"]))
        rows.append(_t_row("pose_noise_theta_rad", [r["noise_theta_rad"] for r in still], runs["still"]))
    holds_from = "still" if per["still"] else "run"
    if per["still"] or driven:
        rows.append(
            _block_row(
                "pose_hold_prob",
                team[f"holds_{holds_from}"],
                runs[holds_from],
                f"share of ticks at which every robot's pose repeated, from {holds_from}, less the script's "
                f"missed ticks the profile keeps ({PROFILE_BASE}'s {_MISS})",
                lambda share: max(0.0, 1.0 - (1.0 - share) / (1.0 - _MISS)),
            )
        )
    if per["ramp"]:
        rows.append(
            _t_row(
                "motor_dead_zone_radps",
                [r["dead_zone_radps"] for r in per["ramp"]],
                runs["ramp"],
                "wheel speed below which a robot does not move (0.05 rad/s grid)",
            )
        )
    return rows


def _unidentified(per: dict, moving: list[dict]) -> dict[str, str]:
    """Parameter -> why these logs cannot identify it."""
    unknown = dict(ALWAYS_UNIDENTIFIED)
    if not per["ramp"]:
        unknown["motor_dead_zone_radps"] = "needs a ramp log"
    if not moving:
        unknown["top_speed_derate_min"] = "needs a steps or spin log (a task run seldom asks for the top speed)"
        unknown["wheel_gain_spread"] = "needs a spin or steps log (a task's turns hide the drift)"
    if not per["still"]:
        unknown["pose_noise_xy_m"] = unknown["pose_noise_theta_rad"] = "needs a still log"
    return unknown


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
        # the jitter fitted beside it (0 where no tick could tell: the delay fitted alone then holds it),
        # never nominal's on top of a delay that already holds the logs' own
        jitter = est.get("pose_delay_jitter_prob")
        fields["pose_delay_jitter_prob"] = float(min(max(jitter["estimate"], 0.0), 1.0)) if jitter else 0.0
    per = fit["per_robot"]
    timed = per["steps"] or per["spin"] or [r for r in per.get("run", []) if r["used"]]
    if timed:
        own = [r["tau_own_s"] for r in timed]
        shared = [r["tau_s"] for r in timed]  # each log's shared lag; the robots' own ones widen the range
        fields["motor_tau_min_s"], fields["motor_tau_max_s"] = float(min(*shared, *own)), float(max(*shared, *own))
    if "top_speed_derate_min" in est:
        fields["top_speed_derate_min"] = float(est["top_speed_derate_min"]["estimate"])
    if "speed_gain" in est:
        fields["wheel_gain_mean"] = float(est["speed_gain"]["estimate"])
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
        "pose_delay_jitter_prob": f"{c.pose_delay_jitter_prob:.4g}",
        "motor_tau_s": f"{c.motor_tau_min_s:.4g}..{c.motor_tau_max_s:.4g}"
        if c.motor_tau_max_s != c.motor_tau_min_s
        else f"{c.motor_tau_min_s:.4g}",
        "speed_gain": f"{c.wheel_gain_mean:.4g}",
        "turn_gain": f"{c.wheel_gain_mean:.4g}",
        "tracked_ahead_m": "0",
        "top_speed_fraction": f"{c.top_speed_derate_min:.4g}..1" if c.top_speed_derate_min < 1 else "1",
        "top_speed_derate_min": f"{c.top_speed_derate_min:.4g}",
        "wheel_gain_spread": f"{c.wheel_gain_spread:.4g}",
        "pose_noise_xy_m": f"{c.pose_noise_xy_m:.4g}",
        "pose_noise_theta_rad": f"{c.pose_noise_theta_rad:.4g}",
        "pose_hold_prob": f"{c.pose_hold_prob:.4g}",
        "motor_dead_zone_radps": f"{c.motor_dead_zone_radps:.4g}",
        "motor_accel_limit_radps2": f"{c.motor_accel_limit_radps2:.4g}",
        "loop_tick_s": "0.033",
        "pose_bias_xy_m": f"{c.pose_bias_xy_m:.4g}",
        "command_delay_ticks": f"{c.command_delay_ticks}",
        "command_loss_prob": f"{c.command_loss_prob:.4g}",
        "wheel_disturbance_radps": f"{c.wheel_disturbance_radps:.4g}",
        "fault_prob": f"{c.fault_prob:.4g}",
    }


def unidentified_fields(fields: dict, reasons: dict[str, str] | None = None) -> dict[str, str]:
    """Each :class:`~comat.reality.RealityConfig` field a profile does not set from the logs: the
    value it keeps (:data:`PROFILE_BASE`'s) and why, field by field, for the profile file
    (``reasons``: the table's notes by parameter, e.g. :func:`fit_logs`'s)."""
    base, reasons = LEVELS[PROFILE_BASE], reasons or {}
    why = {name: reasons[name].removeprefix("not identified: ") for name in reasons if name in base}
    return {
        name: f"{PROFILE_BASE}'s {base[name]!r}: not identified "
        + (f"({why[name]})" if name in why else "by the logs given")
        for name in base
        if name not in fields
    }
