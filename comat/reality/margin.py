"""The barrier filter made robust to what the reality layer hides: gains, distances, stale poses.

With the layer on, the filter decides on *measured* poses (late, noisy, sometimes repeated) and
its commands reach the ground late, through lagging motors. Three changes keep it safe on the
*true* poses (docs/safety.md and docs/reality.md derive them):

* **Gain from the loop delay.** Near the barrier's edge the filtered closing motion obeys
  ``ḣ(t) = -γ h(t - T)``: the filter sees ``h`` late by the loop delay T (pose delay, command
  delay, the zero-order hold, lost commands, the wheels' lag and slew). That equation decays
  without overshoot (h never crosses 0) exactly when ``γ·T <= 1/e``; larger gains overshoot
  into the safety distance, as measured at ``nominal`` with γ = 10 (true projected points 0.12
  m apart, Robotarium collisions). :func:`loop_delay_s` bounds T from the layer's settings; the
  filter uses ``min(γ, 1/(e·T))`` for its pair and boundary rows.
* **Distance from the measurement bound.** Every measured position is within
  :func:`measurement_bound_m` of the true one (the noise and the bias are drawn from a table
  that bounds them at 4.33 SD): the filter keeps measured points ``d_s + 2·e`` apart and ``e``
  further inside the boundary margin, so the true ones keep ``d_s``.
* **Stale poses dead-reckoned.** A tracker that holds or freezes repeats the last pose exactly,
  which a noisy measurement never does; the filter then moves its estimate of that robot by the
  commands it sent since (:class:`StalePoses`), instead of steering around a pose that is
  seconds old. Without pose noise a repeat cannot be told from a robot standing still, so
  nothing is dead-reckoned (the gain and distance still apply).

At ``off`` none of this runs (the layer is the identity): the filter is the ideal world's, bit for bit.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from comat import constants as C
from comat.config import SafetyConfig
from comat.reality.config import RealityConfig
from comat.reality.random import NORMAL_BOUND

__all__ = [
    "ROBUST_ADMM_RHO",
    "StalePoses",
    "loop_delay_s",
    "measurement_bound_m",
    "response_lag_ticks",
    "robust_safety",
]


def loop_delay_s(reality: RealityConfig, profile: C.RobotProfile) -> float:
    """Upper bound T (s) on the delay from a true pose to the wheels' response to it.

    Ticks: the longest pose delay (a jittered message included) + the longest command delay + 1
    (the zero-order hold of a tick) + the longest run of lost commands the level draws at its mean
    (a lost command repeats the previous one: one more tick of delay each) + 1 if the script
    misses ticks; then the motors' slowest lag τ_max and half the time the slew limit needs for a
    full wheel-speed change (the mean delay of a ramp). Holds and freezes are not in T: the dead
    reckoning of :class:`StalePoses` covers them. Script stalls are not either: past 0.5 s the
    robots brake; shorter ones are a scenario of the battery (``stall_converge16``).
    """
    ticks = reality.pose_delay_max_ticks + reality.command_delay_max_ticks + 1
    if reality.command_loss_prob > 0:
        ticks += math.ceil(reality.command_loss_mean_ticks)
    if reality.script_miss_prob > 0:  # a missed tick: the command before stays in force one tick longer
        ticks += 1
    slew = 0.0
    if reality.motor_accel_limit_radps2 > 0:
        slew = 2.0 * profile.max_wheel_velocity_radps / reality.motor_accel_limit_radps2 / 2.0
    return ticks * C.CONTROL_DT_S + reality.motor_tau_max_s + slew


def response_lag_ticks(reality: RealityConfig, profile: C.RobotProfile) -> int:
    """Ticks from a command to its effect on a measured pose, at most: :func:`loop_delay_s` in
    whole ticks (1 at ``off``), the lags a robot watch tries before it calls a robot
    unresponsive (:class:`comat.safety.deployed.RobotWatch`)."""
    if reality.is_off:
        return 1
    return math.ceil(loop_delay_s(reality, profile) / C.CONTROL_DT_S)


def measurement_bound_m(reality: RealityConfig, projection_m: float) -> float:
    """Largest distance (m) between a robot's measured and true projected point from noise and
    bias: 4.33 SD of each (the draws' hard bound) on both axes, plus the heading noise's
    4.33 SD swinging the point ``projection_m`` ahead of the axle. Delay is not in it (that is
    the gain's part)."""
    xy = math.sqrt(2.0) * NORMAL_BOUND * (reality.pose_noise_xy_m + reality.pose_bias_xy_m)
    return xy + projection_m * NORMAL_BOUND * reality.pose_noise_theta_rad


ROBUST_ADMM_RHO = 0.3
"""OSQP's initial ADMM step size for the robust filter (:attr:`SafetyConfig.admm_rho`). Its gains
are ~10× lower than ``off``'s (0.98 at ``nominal``, 0.60 at ``stress``, from 10) and its distances
wider, so more rows are active: with OSQP's default 0.1 the batched QP took 28 ADMM iterations a
solve at ``nominal`` and 53–60 at ``stress`` (teams driven at random goals, 16 × 8 and 20 × 4,
``results/safety_live/tick_cost.py``'s streams), with 0.3 20 and 26–29; 0.2 took 19–20 and 30–33,
0.5 27–28 and 34–38, 1.0 34 and 53 (16 × 8). Polished answers are the same optimum; no brake
appeared with either (issue 66: the stress tick within 1.3× nominal's). ``off`` keeps OSQP's
default, bit for bit (there 0.3 cut 29 iterations to 14–20 too)."""


def robust_safety(safety: SafetyConfig, reality: RealityConfig, profile: C.RobotProfile) -> SafetyConfig:
    """The filter's settings under ``reality``: gains at most 1/(e·T), safety distance + 2e,
    boundary margin + e (module docstring), OSQP's step size :data:`ROBUST_ADMM_RHO` (unless
    ``safety.admm_rho`` was set). ``safety.robust=False`` returns ``safety`` as is."""
    if not safety.robust or reality.is_off:
        return safety
    gain_max = 1.0 / (math.e * loop_delay_s(reality, profile))
    e = measurement_bound_m(reality, safety.projection_distance_m)
    return dataclasses.replace(
        safety,
        barrier_gain=min(safety.barrier_gain, gain_max),
        boundary_gain=min(safety.boundary_gain, gain_max),
        safety_distance_m=safety.safety_distance_m + 2.0 * e,
        boundary_margin_m=min(safety.boundary_margin_m + e, 0.89),
        admm_rho=ROBUST_ADMM_RHO if safety.admm_rho == SafetyConfig.admm_rho else safety.admm_rho,
    )


class StalePoses:
    """The filter's pose estimate (R, 3): measured, or dead-reckoned while a measurement repeats.

    A robot's measured pose that equals the previous tick's bit for bit is stale (held or
    frozen; a noisy tracker never repeats itself): its estimate then moves by the unicycle
    command the script sent last tick, integrated over the tick on the estimate's heading. A
    fresh measurement replaces the estimate. Off (the estimate is the measurement) when the
    layer has no pose noise, where a repeat cannot be told from a robot standing still.
    """

    def __init__(self, n_robots: int, enabled: bool) -> None:
        self.enabled = enabled
        self.estimate = np.zeros((n_robots, 3))
        self._last = np.full((n_robots, 3), np.nan)
        self.stale_ticks = np.zeros(n_robots, np.int64)
        """(R,) consecutive ticks each robot's measurement has repeated."""

    def start(self, rows: np.ndarray, measured: np.ndarray) -> None:
        """Robots ``rows`` begin an episode with the measurement ``measured`` (R, 3)."""
        self.estimate[rows] = measured[rows]
        self._last[rows] = measured[rows]
        self.stale_ticks[rows] = 0

    def update(self, measured: np.ndarray, sent: np.ndarray) -> None:
        """After a tick: the new measurements (R, 3) and the unicycle commands (R, 2) the script
        sent in that tick."""
        if not self.enabled:
            return
        stale = (measured == self._last).all(axis=1)
        self.stale_ticks = np.where(stale, self.stale_ticks + 1, 0)
        est = self.estimate
        if stale.any():
            th = est[stale, 2]
            v, w = sent[stale, 0], sent[stale, 1]
            est[stale, 0] += v * np.cos(th) * C.CONTROL_DT_S
            est[stale, 1] += v * np.sin(th) * C.CONTROL_DT_S
            est[stale, 2] = np.pi - np.remainder(np.pi - (th + w * C.CONTROL_DT_S), 2.0 * np.pi)
        np.copyto(est, measured, where=~stale[:, None])
        np.copyto(self._last, measured)

    def remap(self, new_rows: slice, old: StalePoses, old_rows: slice) -> None:
        """Carry a team's state over a relayout."""
        self.estimate[new_rows] = old.estimate[old_rows]
        self._last[new_rows] = old._last[old_rows]
        self.stale_ticks[new_rows] = old.stale_ticks[old_rows]
