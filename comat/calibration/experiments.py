"""Calibration experiments: short system-identification runs whose logs fit the reality layer.

Each experiment is a command schedule for robots standing in lanes, well apart: every iteration
a robot gets a unicycle command (v, ω) that depends only on the iteration and the robot. A run
logs, per iteration, the time, the commanded (v, ω) and the pose the robot's script received, as
one float64 array (K, N, 6) with the columns :data:`LOG_COLUMNS`, saved as
``calib_<experiment>.npy`` — the same format whether the run happened on the Robotarium (its
``main.py`` saves it) or in comat's simulator with the reality layer at known values
(:func:`simulate`), which is how the fit (:mod:`comat.calibration.fit`) is proven on known truth.

Experiments (:data:`EXPERIMENTS`):

* ``steps`` — forward-speed steps 0 → ½ → full → 0, then the same backwards, 16 cycles
  (53 s): the delay from command to observed motion (pose + command delay: the two shift the
  response alike and are not told apart), the wheels' lag, the reachable speed, and from the
  heading's drift over the distance the two wheels' gain difference;
* ``still`` — the robots stand for 60 s: pose noise, and the share of repeated poses (holds);
* ``ramp`` — the forward speed rises slowly from standstill to 40 % of the top speed, stops, then
  the same backwards, 4 cycles (46 s): the dead zone, the wheel speed below which a robot does
  not move (the GTernal's 0.03 m/s minimum would be 1.9 rad/s);
* ``spin`` — turn-rate steps 0 → ½ → 95 % of the Robotarium's 3.64 rad/s → 0 and back, the robots
  turning in place more than once round each way, 5 cycles (33 s): the delay and the lag again, the turn-rate gain
  and the
  reachable turn rate, and from the circle the robot's centre draws while it turns the wheels' gain
  difference (and how far ahead of the wheel axle the tracked point sits).

Every log also times the loop (``time.time()`` each iteration on the Robotarium): the fit reports
the tick's length. There is no timing experiment of its own: every run measures it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from comat import constants as C
from comat.calibration.schedule import EXPERIMENTS, LOG_COLUMNS, lane_poses, schedule
from comat.config import SimConfig
from comat.control import SafeTeams
from comat.reality import RealityLayer, resolve_reality
from comat.sim.layout import team_layout

__all__ = ["EXPERIMENTS", "LOG_COLUMNS", "lane_poses", "load_log", "run_under_rps", "schedule", "simulate"]


def simulate(experiment: str, reality, n: int = 4, seed: int = 0, tier: str | None = None) -> np.ndarray:
    """Run ``experiment`` with the reality layer ``reality`` (a level, a RealityConfig or a mapping
    of fields) and return its log (K, n, 6), as the Robotarium's ``main.py`` records it: the
    measured pose read first, then the command sent.

    ``tier`` None: the robots move as the Robotarium simulator moves them (Euler steps of the
    unicycle model, what ``rps`` does), so the log shows the layer and nothing else: the known
    truth a fit must recover. ``"unicycle"`` or ``"wheels"``: comat's MuJoCo tiers, whose own
    actuator response (the unicycle tier's ~12 ms servo) then adds to the layer's."""
    if experiment not in EXPERIMENTS:
        raise ValueError(f"experiment must be one of {sorted(EXPERIMENTS)}, got {experiment!r}")
    config = resolve_reality(reality)
    K = EXPERIMENTS[experiment]
    log = np.zeros((K, n, 6))
    if tier is not None:
        return _simulate_tier(experiment, config, n, seed, tier, log)
    layer = RealityLayer(config, C.GRITSBOT, team_layout((n,)), seed)
    true = layer.start(lane_poses(n), np.array([0]), None)
    layer.begin_measuring(true, np.array([0]))
    for k in range(K):
        dxu = schedule(experiment, k, n)
        log[k, :, 0] = k * C.CONTROL_DT_S
        log[k, :, 1:3] = dxu
        log[k, :, 3:] = layer.measured
        v, w = layer.actuate(dxu).T
        true = true.copy()
        true[:, 0] += v * np.cos(true[:, 2]) * C.CONTROL_DT_S
        true[:, 1] += v * np.sin(true[:, 2]) * C.CONTROL_DT_S
        true[:, 2] = np.pi - np.remainder(np.pi - (true[:, 2] + w * C.CONTROL_DT_S), 2.0 * np.pi)
        layer.observe(true)
    return log


def _simulate_tier(experiment: str, config, n: int, seed: int, tier: str, log: np.ndarray) -> np.ndarray:
    teams = SafeTeams((n,), SimConfig(tier=tier), reality=config, reality_seed=seed)
    teams.reset(lane_poses(n))
    overrun = np.zeros(n, dtype=bool)
    for k in range(log.shape[0]):
        dxu = schedule(experiment, k, n)
        log[k, :, 0] = k * C.CONTROL_DT_S
        log[k, :, 1:3] = dxu
        log[k, :, 3:] = teams.measured_poses
        teams.execute(dxu, overrun)  # open loop: the schedule's commands, no filter
    return log


def load_log(path: str | Path) -> tuple[str, np.ndarray]:
    """(experiment, log (K, N, 6)) of a ``calib_<experiment>.npy`` file; one-line errors for a file
    that is not a calibration log or is cut short."""
    path = Path(path)
    name = path.stem
    if not (path.suffix == ".npy" and name.startswith("calib_") and name[6:].split(".")[0] in EXPERIMENTS):
        raise ValueError(
            f"LOGS must be calibration logs calib_<{'|'.join(sorted(EXPERIMENTS))}>[.<run>].npy, got {str(path)!r}"
        )
    experiment = name[6:].split(".")[0]
    if not path.is_file():
        raise FileNotFoundError(f"LOGS: {str(path)!r} does not exist")
    try:
        log = np.load(path, allow_pickle=False)
    except ValueError as exc:
        raise ValueError(f"LOGS: {str(path)!r} is not a numeric .npy array ({exc})") from None
    if log.ndim != 3 or log.shape[2] != len(LOG_COLUMNS) or not np.issubdtype(log.dtype, np.floating):
        raise ValueError(
            f"LOGS: {str(path)!r} must be a float array (iterations, robots, {len(LOG_COLUMNS)}) with "
            f"columns {list(LOG_COLUMNS)}, got shape {log.shape} {log.dtype}"
        )
    need = EXPERIMENTS[experiment] // 2
    if log.shape[0] < need:
        raise ValueError(
            f"LOGS: {str(path)!r} holds {log.shape[0]} iterations of {experiment!r}, fewer than the "
            f"{need} a fit needs (a truncated run?)"
        )
    if not np.isfinite(log).all():
        raise ValueError(f"LOGS: {str(path)!r} holds non-finite values")
    return experiment, log


def run_under_rps(experiment: str, n: int = 4) -> np.ndarray:
    """Run ``experiment`` under the Robotarium simulator (the installed ``rps``: the legacy PyPI
    package here) and return its log, as a Robotarium run's ``main.py`` records it. The
    simulator has no delay, noise or motor model: a fit of this log must find none."""
    from rps import robotarium

    if experiment not in EXPERIMENTS:
        raise ValueError(f"experiment must be one of {sorted(EXPERIMENTS)}, got {experiment!r}")
    r = robotarium.Robotarium(
        number_of_robots=n, show_figure=False, sim_in_real_time=False, initial_conditions=lane_poses(n).T.copy()
    )
    K = EXPERIMENTS[experiment]
    log = np.zeros((K, n, 6))
    for k in range(K):
        x = r.get_poses()  # (3, n)
        dxu = schedule(experiment, k, n)
        log[k, :, 0] = k * C.CONTROL_DT_S
        log[k, :, 1:3] = dxu
        log[k, :, 3:] = np.asarray(x).T
        r.set_velocities(np.arange(n), dxu.T.copy())
        r.step()
    return log
