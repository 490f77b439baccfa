"""Known-truth recovery: the calibration experiments simulated at a known reality layer, fitted
back, and checked against the truth within the fit's tolerances.

:func:`setting` draws a random known layer, :func:`recover` simulates the four experiments under
it and fits them, :func:`check` says which quantity came back within its tolerance: the total delay
(pose + command) exactly for the median robot and the minimum, from ``steps`` and from ``spin``; the
lag τ, the pose noise (x, y and θ) and the hold probability within 20 %; the dead zone within
0.4 rad/s; each robot's half gain difference (g_r − g_l)/2 from ``spin`` within 0.01 of the layer's
own draw (:func:`true_half_gain_diff`). ``results/calibration/recovery.py`` writes the table of six
settings; the tests check two.
"""

from __future__ import annotations

import numpy as np

from comat import constants as C
from comat.calibration.experiments import lane_poses, simulate
from comat.calibration.fit import fit_ramp, fit_spin, fit_steps, fit_still
from comat.reality import RealityLayer, resolve_reality
from comat.sim.layout import team_layout

__all__ = ["check", "recover", "setting", "true_half_gain_diff"]


def setting(rng: np.random.Generator) -> dict:
    tau = float(np.round(rng.uniform(0.02, 0.12), 3))
    return {
        "pose_delay_ticks": int(rng.integers(0, 4)),
        "command_delay_ticks": int(rng.integers(0, 2)),
        "motor_tau_min_s": tau,
        "motor_tau_max_s": tau,
        "motor_accel_limit_radps2": 200.0,
        "pose_noise_xy_m": float(np.round(rng.uniform(0.0005, 0.003), 4)),
        "pose_noise_theta_rad": float(np.round(rng.uniform(0.005, 0.03), 3)),
        "pose_hold_prob": float(np.round(rng.uniform(0.05, 0.4), 2)),
        "top_speed_derate_min": float(np.round(rng.uniform(0.8, 1.0), 2)),
        "wheel_gain_spread": float(np.round(rng.uniform(0.0, 0.05), 3)),
        "motor_dead_zone_radps": float(np.round(rng.uniform(0.0, 3.0), 1)),
    }


def true_half_gain_diff(truth: dict, seed: int, n: int = 4) -> np.ndarray:
    """(n,) (g_r - g_l) / 2 the layer drew for a simulated run's robots (the same draw simulate makes)."""
    layer = RealityLayer(resolve_reality(truth), C.GRITSBOT, team_layout((n,)), seed)
    layer.start(lane_poses(n), np.array([0]), None)
    return (layer.motors.gain[:, 1] - layer.motors.gain[:, 0]) / 2


def recover(truth: dict, seed: int) -> dict:
    steps = fit_steps(simulate("steps", truth, n=4, seed=seed))
    still = fit_still(simulate("still", truth, n=4, seed=seed))
    spin = fit_spin(simulate("spin", truth, n=4, seed=seed))
    ramp = fit_ramp(simulate("ramp", truth, n=4, seed=seed))
    delays = [r["delay_ticks"] for r in steps]
    spin_delays = [r["delay_ticks"] for r in spin]
    return {
        "delay_median": int(np.median(delays)),
        "delay_min": min(delays),
        "tau": steps[0]["tau_s"],
        "spin_delay_median": int(np.median(spin_delays)),
        "spin_delay_min": min(spin_delays),
        "gain_diff_error": float(
            np.abs(np.array([r["half_gain_diff"] for r in spin]) - true_half_gain_diff(truth, seed)).max()
        ),
        "dead_zone": float(np.median([r["dead_zone_radps"] for r in ramp])),
        "noise_xy": float(np.mean([r["noise_xy_m"] for r in still])),
        "noise_theta": float(np.mean([r["noise_theta_rad"] for r in still])),
        "hold": float(np.mean([r["repeat_share"] for r in still])),
    }


def check(truth: dict, got: dict) -> dict:
    total = truth["pose_delay_ticks"] + truth["command_delay_ticks"]

    def close(a, b):
        return abs(a - b) <= 0.2 * b

    return {
        "delay": got["delay_median"] == total and got["delay_min"] == total,
        "spin delay": got["spin_delay_median"] == total and got["spin_delay_min"] == total,
        "tau": close(got["tau"], truth["motor_tau_min_s"]),
        "gain diff": got["gain_diff_error"] <= 0.01,
        "dead zone": abs(got["dead_zone"] - truth["motor_dead_zone_radps"]) <= 0.4,
        "noise_xy": close(got["noise_xy"], truth["pose_noise_xy_m"]),
        "noise_theta": close(got["noise_theta"], truth["pose_noise_theta_rad"]),
        "hold": close(got["hold"], truth["pose_hold_prob"]),
    }
