"""A run's logged commands played through a twin's plant: the open-loop row and the k-step score.

The *plant* is everything between a command the robots' script sends and the pose it reads next:
the reality layer's command path and motors (delay, loss, lag, dead zone, gains, disturbance), the
robots in comat's MuJoCo world, and the layer's pose path (delay, noise, bias, holds). It is the
twin without the policy and the filter. A run's log (:mod:`comat.runlog`) holds both ends of it at
every iteration: the pose the script received and the command it sent (after the filter). So a
profile's plant can be judged against the log without the policy's choices in the way:

* :func:`open_loop`: every logged command, from the logged first pose, through the plant (the poses
  it reaches drift: errors add up over the run);
* :func:`kstep_errors`: the **k-step prediction error**. From each logged pose (every ``stride``-th
  iteration), the logged commands of the next k ticks go through the plant; the pose it predicts is
  compared with the pose logged k ticks later (position in m, heading in rad), per robot and in
  total, for k = 1, 5 and 30 ticks (0.033, 0.17 and 1 s) by default.

The plant has state that a pose does not show: commands on their way (the command delay), wheel
speeds (the lag), a measurement still to come (the pose delay). Each k-step rollout therefore starts
``warmup`` ticks earlier, from the logged pose there, and plays the logged commands of those ticks
first. Its prediction is the motion the plant makes between the tick it starts from and k ticks later
(a rigid displacement in the robot's own frame), put on the logged pose it starts from:

    predicted(s + k) = logged(s) ∘ twin(s)⁻¹ ∘ twin(s + k)

so the warm-up's own drift does not count, and at ``off`` the prediction is the logged pose plus the
logged commands of the k ticks, integrated by MuJoCo.

Randomness (a profile's per-episode draws, noise, holds): ``draws`` independent draws per start (one
at ``off``, which has none), fixed by ``seed``; the rollouts of every start and draw are independent
teams of one :class:`comat.sim.BatchWorld` and one :class:`comat.reality.RealityLayer`, stepped
together (robots vectorized; Python loops over ticks only). The error is the mean over draws. Beside
it, the **score** is the energy score over the draws (mean error − half the mean distance between
two draws' predictions; with one draw, the error): a profile whose randomness is right is not
penalized for spreading its predictions, so the score ranks profiles without favouring the noiseless
one; lower is better for both.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from comat import constants as C
from comat.config import SimConfig
from comat.reality import RealityConfig, RealityLayer, resolve_reality
from comat.runlog import RunLog
from comat.sim import BatchWorld
from comat.sim.kinematics import threshold_wheels, wrap_angle
from comat.sim.layout import team_layout

__all__ = [
    "DRAWS",
    "KSTEP_TICKS",
    "MAX_STARTS",
    "WARMUP_TICKS",
    "PlantError",
    "check_horizons",
    "kstep_errors",
    "log_profile",
    "open_loop",
    "plant_config",
]

KSTEP_TICKS = (1, 5, 30)
"""The default prediction horizons (ticks): one iteration, about a sixth of a second, one second."""
WARMUP_TICKS = 30
"""Logged ticks played before each k-step start (1 s): longer than any level's delays (at most 5
ticks at ``stress``) and five of its slowest wheel lags (0.12 s), so the plant's hidden state is the
commands' and not the reset's."""
DRAWS = 8
"""Draws of a profile's randomness per start (one at ``off``)."""
MAX_STARTS = 200
"""At most this many k-step starts, evenly spaced over the log (every iteration of a short log)."""


class PlantError(ValueError):
    """Inputs to the plant's scoring that cannot be used (one line: which, expected, received)."""


def log_profile(log: RunLog) -> C.RobotProfile:
    """The robots a log's run drove: V2's GTernal (axle 0.11 m) or the legacy simulator's GRITSBOT."""
    return C.GTERNAL if log.meta.get("rps") == "v2" else C.GRITSBOT


def plant_config(reality) -> RealityConfig:
    """The reality layer of the plant for ``reality`` (a level, a profile file, a RealityConfig or a
    mapping): the same, without the start error (a rollout starts from a logged pose, which is
    where the robot really was, as measured)."""
    config = resolve_reality(reality, "--reality")
    return dataclasses.replace(config, start_xy_m=0.0, start_theta_rad=0.0)


def check_horizons(ks: Sequence[int], name: str = "--k-steps") -> tuple[int, ...]:
    """The horizons sorted and unique; one-line ValueError unless they are integers >= 1."""
    if isinstance(ks, (int, np.integer)) or len(ks) == 0:
        raise PlantError(f"{name} must be one or more integers >= 1 (ticks), got {ks!r}")
    for k in ks:
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or k < 1:
            raise PlantError(f"{name} must be integers >= 1 (ticks), got {k!r}")
    return tuple(sorted({int(k) for k in ks}))


def _check_count(value, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise PlantError(f"{name} must be an integer >= 1, got {value!r}")
    return int(value)


def _valid_starts(poses: np.ndarray, radius: float) -> np.ndarray:
    """(S,) which teams' poses (S, N, 3) the world can be reset to: every robot inside the arena and
    no two overlapping (a pose logged with a collision or a tracker glitch is skipped)."""
    x0, x1, y0, y1 = C.ARENA_BOUNDS_M
    x, y = poses[..., 0], poses[..., 1]
    inside = ((x >= x0 + radius) & (x <= x1 - radius) & (y >= y0 + radius) & (y <= y1 - radius)).all(axis=1)
    n = poses.shape[1]
    if n < 2:
        return inside
    i, j = np.triu_indices(n, 1)
    gap = np.hypot(poses[:, i, 0] - poses[:, j, 0], poses[:, i, 1] - poses[:, j, 1])
    return inside & (gap >= 2 * radius).all(axis=1)


def _play(
    log: RunLog,
    config: RealityConfig,
    first: np.ndarray,
    length: int,
    draws: int,
    keep: Sequence[int],
    tier: str,
    seed: int,
) -> np.ndarray:
    """The plant's measured poses (J, S, D, N, 3) at the rollout ticks ``keep`` (0: the reset) of
    S × D independent rollouts: rollout (s, d) starts at the logged pose of iteration ``first[s]``
    and plays the logged commands of iterations ``first[s] … first[s] + length - 1`` through the
    plant, with the d-th draw of its randomness (teams keyed from ``seed``)."""
    S, D, n = first.size, draws, log.n
    profile = log_profile(log)
    world = BatchWorld((n,) * (S * D), SimConfig(tier=tier, profile=profile.name))
    layer = RealityLayer(config, profile, team_layout((n,) * (S * D)), seed)
    poses = np.asarray(log.poses, dtype=float)
    sent = np.asarray(log.sent, dtype=float)
    teams = np.arange(S * D)
    start = np.repeat(poses[first], D, axis=0).reshape(-1, 3)
    start = layer.start(start, teams, None)  # the plant's config has no start error: the logged poses
    if layer.physics_on and tier == "wheels":
        world.set_robot_physics(*layer.physics(), teams=teams)
    world.reset(start)
    layer.begin_measuring(world.poses, teams)
    keep = list(keep)
    out = np.empty((len(keep), S, D, n, 3))
    slots = {j: i for i, j in enumerate(keep)}
    if 0 in slots:
        out[slots[0]] = layer.measured.reshape(S, D, n, 3)
    for j in range(length):
        command = np.repeat(sent[first + j], D, axis=0).reshape(-1, 2)
        world.step(layer.actuate(threshold_wheels(command, profile)[0]))  # what set_velocities passes on
        layer.observe(world.poses)
        if j + 1 in slots:
            out[slots[j + 1]] = layer.measured.reshape(S, D, n, 3)
    return out


def open_loop(log: RunLog, reality="off", tier: str = "unicycle", draws: int = DRAWS, seed: int = 0) -> np.ndarray:
    """(D, K, N, 3) the poses the plant at ``reality`` reports at each of the log's K iterations when
    every logged command is played to it from the logged first pose, for each of ``draws`` draws of
    the profile's randomness (one at ``off``)."""
    config = plant_config(reality)
    draws = 1 if config.is_off else _check_count(draws, "--draws")
    K = len(log.t)
    if not _valid_starts(np.asarray(log.poses[:1], dtype=float), log_profile(log).radius_m)[0]:
        raise PlantError("the log's first poses put a robot outside the arena or two robots in one another")
    played = _play(log, config, np.zeros(1, np.int64), K - 1, draws, range(K), tier, seed)
    return played[:, 0].transpose(1, 0, 2, 3)


def _compose(anchor: np.ndarray, start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """``anchor ∘ start⁻¹ ∘ end`` for poses (..., 3): the motion from ``start`` to ``end``, in the
    robot's own frame, made from ``anchor`` instead."""
    c, s = np.cos(start[..., 2]), np.sin(start[..., 2])
    dx, dy = end[..., 0] - start[..., 0], end[..., 1] - start[..., 1]
    fwd, left = c * dx + s * dy, -s * dx + c * dy
    ca, sa = np.cos(anchor[..., 2]), np.sin(anchor[..., 2])
    out = np.empty(np.broadcast_shapes(anchor.shape, start.shape, end.shape))
    out[..., 0] = anchor[..., 0] + ca * fwd - sa * left
    out[..., 1] = anchor[..., 1] + sa * fwd + ca * left
    out[..., 2] = wrap_angle(anchor[..., 2] + end[..., 2] - start[..., 2])
    return out


def kstep_errors(
    log: RunLog,
    reality="off",
    ks: Sequence[int] = KSTEP_TICKS,
    tier: str = "unicycle",
    draws: int = DRAWS,
    seed: int = 0,
    warmup: int = WARMUP_TICKS,
    max_starts: int = MAX_STARTS,
) -> dict:
    """The k-step prediction error of the plant at ``reality`` on ``log`` (module docstring).

    Returns ``{"ks": horizons that fit the log, "starts": S, "skipped": starts left out (a logged
    pose the world cannot take), "draws": D, "warmup": ticks, "stride": iterations between starts,
    "error_m": (len(ks), N) per robot the mean position error (m), "total_m": (len(ks),) over robots
    too, "heading_rad": (len(ks),) the mean heading error, "score_m": (len(ks),) the energy score of
    the positions, "robot_heading_rad" and "robot_score_m": (len(ks), N) both per robot}``. A log
    too short for any horizon (fewer than ``warmup`` + k + 1 iterations) gives empty arrays.
    """
    ks = check_horizons(ks)
    draws = _check_count(draws, "--draws")
    max_starts = _check_count(max_starts, "max_starts")
    if isinstance(warmup, bool) or not isinstance(warmup, (int, np.integer)) or warmup < 0:
        raise PlantError(f"warmup must be an integer >= 0 (ticks), got {warmup!r}")
    config = plant_config(reality)
    draws = 1 if config.is_off else draws
    K, n = len(log.t), log.n
    fit = tuple(k for k in ks if warmup + k <= K - 1)
    if not fit:
        none, per_robot = np.zeros(0), np.zeros((0, n))
        empty = {"ks": (), "starts": 0, "skipped": 0, "draws": draws, "warmup": warmup, "stride": 0}
        empty.update(error_m=per_robot, total_m=none, heading_rad=none, score_m=none)
        return {**empty, "robot_heading_rad": per_robot, "robot_score_m": per_robot}
    last = K - 1 - fit[-1]  # the last start whose longest horizon is logged
    stride = max(1, -(-(last - warmup + 1) // max_starts))
    starts = np.arange(warmup, last + 1, stride)
    poses = np.asarray(log.poses, dtype=float)
    ok = _valid_starts(poses[starts - warmup], log_profile(log).radius_m)
    skipped = int((~ok).sum())
    starts = starts[ok]
    if starts.size == 0:
        raise PlantError("no k-step start: every logged pose puts a robot outside the arena or in another")
    keep = [warmup] + [warmup + k for k in fit]
    played = _play(log, config, starts - warmup, warmup + fit[-1], draws, keep, tier, seed)
    anchor = poses[starts][:, None]  # (S, 1, N, 3): the logged poses the predictions start from
    error, total, heading, score, robot_heading, robot_score = [], [], [], [], [], []
    for i, k in enumerate(fit):
        pred = _compose(anchor, played[0], played[i + 1])  # (S, D, N, 3)
        target = poses[starts + k][:, None]
        dist = np.hypot(pred[..., 0] - target[..., 0], pred[..., 1] - target[..., 1])  # (S, D, N)
        turn = np.abs(wrap_angle(pred[..., 2] - target[..., 2]))
        spread = 0.0
        if draws > 1:  # mean distance between two different draws' predictions, (S, N)
            diff = pred[:, :, None, :, :2] - pred[:, None, :, :, :2]
            spread = np.hypot(diff[..., 0], diff[..., 1]).sum(axis=(1, 2)) / (draws * (draws - 1))
        per_robot = dist.mean(axis=(0, 1))
        energy = (dist.mean(axis=1) - 0.5 * spread).mean(axis=0)  # (N,)
        error.append(per_robot)
        robot_heading.append(turn.mean(axis=(0, 1)))
        robot_score.append(energy)
        total.append(float(per_robot.mean()))
        heading.append(float(turn.mean()))
        score.append(float(energy.mean()))
    return {
        "ks": fit,
        "starts": int(starts.size),
        "skipped": skipped,
        "draws": draws,
        "warmup": warmup,
        "stride": stride,
        "error_m": np.stack(error),
        "total_m": np.array(total),
        "heading_rad": np.array(heading),
        "score_m": np.array(score),
        "robot_heading_rad": np.stack(robot_heading),
        "robot_score_m": np.stack(robot_score),
    }
