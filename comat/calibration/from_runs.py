"""Calibration from a policy's run: every real run's log (``comat_run.npy``, :mod:`comat.runlog`)
is also a calibration log.

A task run drives the robots along curves at speeds the policy chose, not the experiments' lanes
and steps, so it identifies less, and says so:

* **identified** — the delay from command to observed motion (pose + command, as from ``steps``),
  the wheels' lag τ, the forward speed gain and the turn-rate gain: the same response fit as the
  experiments' (:func:`comat.calibration.fit.fit_response`, on increments), fed with each robot's
  forward distance along its own heading (the increment between two fresh poses projected on their
  mean heading) against the forward command the barrier sent, and its heading against the turn
  command; the team's pose jitter (:func:`comat.calibration.fit.jitter_posterior`); and the team's
  holds: the ticks at which every driving robot repeated its pose (a moving robot's pose never
  repeats by itself; one robot's repeat alone is its own tracking freeze);
* **not identified** — the top-speed derate (a policy seldom asks for the top speed: the cap is
  held at none), the slew limit, the pose noise (the robots are moving), the dead zone, the wheels'
  gain difference (a task's turns hide the drift), the pose bias, command loss, the disturbance and
  faults.

A robot that drove less than :data:`MIN_TRAVEL_M` tells too little and is left out (its row says
so); the response fits are per robot, as the experiments' are, so their intervals are over robots;
the jitter and the holds are the team's, one series of ticks per run (intervals over time blocks).
"""

from __future__ import annotations

import numpy as np

from comat import constants as C
from comat.calibration.fit import fit_response, fit_timed, observed_distance
from comat.runlog import RunLog

__all__ = ["MIN_TRAVEL_M", "RUN_SHAPES", "fit_run", "fit_run_team"]

MIN_TRAVEL_M = 0.3
"""Least forward distance (m) a robot must drive in a run for its response to be fitted."""
RUN_SHAPES = [(1.0, 0.0), (1.0, 200.0)]
"""The (cap, slew) pairs the run fit tries: no cap below the top speed (a task run rarely asks for
it, and a cap it never reached fits every value alike), the slew none or the firmware's."""
MOVING_MPS = 0.02
"""A robot counts as driving where the forward command sent the tick before was above this (m/s)."""


def fit_run(run: RunLog) -> list[dict]:
    """Per robot of a run's log: ``delay_ticks``, ``tau_s`` (shared by the run's robots), ``tau_own_s``,
    ``gain`` (forward speed), ``turn_gain``, ``repeat_share`` (repeated poses while driving),
    ``travel_m``, ``jitter_share`` (the team's), and ``used`` (False: it drove less than
    :data:`MIN_TRAVEL_M`; its numbers are nan); see :func:`fit_run_team`."""
    return fit_run_team(run)[0]


def fit_run_team(run: RunLog) -> tuple[list[dict], dict[str, np.ndarray]]:
    """:func:`fit_run`'s rows and the team's series: ``jitter`` (T,) the posterior of a late pose at
    each tick that can tell, ``holds`` (H,) 1 where every robot driving at a tick repeated its pose
    (ticks with no robot driving left out)."""
    poses, sent = run.poses, run.sent.astype(np.float64)
    dist, dth, fresh = observed_distance(poses)
    travel = np.abs(np.diff(dist, axis=0) * fresh[1:]).sum(0)
    used = np.flatnonzero(travel >= MIN_TRAVEL_M)
    unused = {"used": False, "delay_ticks": None, "tau_s": np.nan, "tau_own_s": np.nan, "accel_radps2": np.nan}
    unused |= {"gain": np.nan, "turn_gain": np.nan, "repeat_share": np.nan, "jitter_share": np.nan}
    out = [{**unused, "travel_m": float(travel[i])} for i in range(run.n)]
    team = {"jitter": np.zeros(0), "holds": np.zeros(0)}
    if used.size == 0:
        return out, team
    forward, team["jitter"] = fit_timed(dist[:, used], fresh[:, used], sent[:, used, 0], RUN_SHAPES)
    share = forward[0]["jitter_share"]
    half = C.GRITSBOT.base_length_m / 2.0
    turn = fit_response(dth[:, used] * half, fresh[:, used], sent[:, used, 1] * half, RUN_SHAPES, jitter=share)
    driving = np.zeros_like(fresh)
    driving[1:] = np.abs(sent[:-1, :, 0]) > MOVING_MPS
    drive = driving[1:, used]  # (K - 1, U)
    some = drive.any(axis=1)
    team["holds"] = (~(fresh[1:, used] & drive).any(axis=1))[some].astype(np.float64)
    for j, i in enumerate(used):
        m = driving[1:, i]
        out[i] = {
            "used": True,
            "travel_m": float(travel[i]),
            "delay_ticks": forward[j]["delay_ticks"],
            "tau_s": forward[j]["tau_s"],
            "tau_own_s": forward[j]["tau_own_s"],
            "accel_radps2": forward[j]["accel_radps2"],
            "gain": forward[j]["gain"],
            "turn_gain": turn[j]["gain"],
            "repeat_share": float(1.0 - fresh[1:, i][m].mean()) if m.any() else np.nan,
            "jitter_share": share,
        }
    return out, team
