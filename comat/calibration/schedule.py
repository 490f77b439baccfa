"""The calibration experiments' command schedules (numpy only: shipped verbatim in every
Robotarium calibration folder by ``comat export --calibration``, and used by comat's simulator
runs, so both drive the robots alike). See :mod:`comat.calibration.experiments`."""

import numpy as np

TOP_SPEED_MPS = 0.2
"""The Robotarium's linear-speed limit (m/s), the schedules' full speed."""
TOP_TURN_RATE_RADPS = 2.0 * TOP_SPEED_MPS / 0.11
"""The Robotarium's turn-rate limit (rad/s; 3.64, both rps generations: 2 (r / d) (v_max / r) with
the robot's diameter d = 0.11 m), the ``spin`` experiment's full turn rate."""
CONTROL_DT_S = 0.033
"""One Robotarium iteration (s)."""
LANE_SPACING_M = 0.4
"""Lanes this far apart: the export's minimum start spacing (the Robotarium's start-up drive)."""
MAX_ROBOTS = 4
"""Four lanes 0.4 m apart (y within ±0.6 m): far enough from the walls that the Robotarium's boundary
barrier never steers a robot (at ±0.8 m it turned the outer robots measurably)."""

LOG_COLUMNS = ("t_s", "v_cmd_mps", "w_cmd_radps", "x_m", "y_m", "theta_rad")
"""Columns of a calibration log's last axis."""

EXPERIMENTS = {"steps": 1600, "still": 1800, "ramp": 1400, "spin": 1000}
"""Experiment -> iterations (at 0.033 s: 53 s, 59 s, 46 s and 33 s)."""

FULL_FRACTION = 0.95
_STEP_PHASES = ((10, 0.0), (15, 0.5), (15, FULL_FRACTION), (15, 0.0), (15, -0.5), (15, -FULL_FRACTION), (15, 0.0))
"""(iterations, fraction of the top speed 0.2 m/s) of one ``steps`` cycle (100 iterations); "full" is 95 %
of the top speed, so that the Robotarium's barrier never pushes a wheel past its limit (an actuator error)."""

_SPIN_PHASES = ((10, 0.0), (60, 0.5), (20, FULL_FRACTION), (10, 0.0), (60, -0.5), (20, -FULL_FRACTION), (20, 0.0))
"""(iterations, fraction of the top turn rate 3.64 rad/s) of one ``spin`` cycle (200 iterations): at half
the rate each way the robot turns 3.6 rad, more than half round, with no wheel near a speed limit (a
capped wheel would hide the gain difference), so the circle its centre draws is seen; then 20
iterations at 95 % show the reachable speed."""


RAMP_TOP_FRACTION = 0.4
_RAMP_PHASES = ((150, 1.0), (25, 0.0), (150, -1.0), (25, 0.0))
"""(iterations, direction) of one ``ramp`` cycle (350 iterations): the forward speed rises linearly
from standstill to 40 % of the top speed (5 s; 0 -> 5 rad/s at the wheels, past any dead zone the
GTernal's 0.03 m/s minimum implies), stops, then the same backwards, so a cycle ends where it began."""


def schedule(experiment: str, k: int, n: int) -> np.ndarray:
    """(n, 2) unicycle commands (v m/s, ω rad/s) of iteration ``k`` of ``experiment``."""
    out = np.zeros((n, 2))
    if experiment in ("steps", "spin"):
        column, top, phases = (
            (0, TOP_SPEED_MPS, _STEP_PHASES) if experiment == "steps" else (1, TOP_TURN_RATE_RADPS, _SPIN_PHASES)
        )
        k = k % sum(p for p, _ in phases)
        for length, fraction in phases:
            if k < length:
                out[:, column] = fraction * top
                break
            k -= length
    elif experiment == "ramp":
        k = k % sum(p for p, _ in _RAMP_PHASES)
        for length, direction in _RAMP_PHASES:
            if k < length:
                out[:, 0] = direction * RAMP_TOP_FRACTION * TOP_SPEED_MPS * (k + 1) / length if direction else 0.0
                break
            k -= length
    elif experiment != "still":
        raise ValueError(f"experiment must be one of {sorted(EXPERIMENTS)}, got {experiment!r}")
    return out


def lane_poses(n: int) -> np.ndarray:
    """(n, 3) start poses: lanes 0.4 m apart across the arena, facing +x, at x = -0.4 m (a
    ``steps`` cycle drives 0.23 m forward and back)."""
    if not 1 <= n <= MAX_ROBOTS:
        raise ValueError(f"a calibration run has 1 to {MAX_ROBOTS} robots (lanes {LANE_SPACING_M} m apart), got {n}")
    y = LANE_SPACING_M * (np.arange(n) - (n - 1) / 2)
    return np.column_stack([np.full(n, -0.4), y, np.zeros(n)])
