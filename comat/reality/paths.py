"""The two information paths of the reality layer: poses to the robots' script, commands to the robots.

:class:`PosePath` turns true poses into measured ones (per-robot delay, Gaussian noise, an
episode bias, holds and tracking freezes that repeat the last measured pose); :class:`CommandPath`
turns the script's commands into those the robots execute (per-robot delay, lost commands that
leave the last one in force, a brake once the firmware's timeout expires). Both hold per-robot
state in row-per-robot arrays (R, ...) and are advanced for all robots at once.
"""

from __future__ import annotations

import numpy as np

from comat import kernels
from comat.reality import kernels as rk
from comat.reality.config import RealityConfig

__all__ = ["CommandPath", "PosePath", "binomial_half", "run_lengths"]


def binomial_half(u: np.ndarray) -> np.ndarray:
    """Binomial(n, 1/2) counts (R,) from uniforms (R, n)."""
    return (u < 0.5).sum(axis=1).astype(np.int64)


def run_lengths(u: np.ndarray, mean: float, longest: int) -> np.ndarray:
    """Geometric run lengths >= 1 with the given mean, at most ``longest``, from uniforms (R,)."""
    if mean <= 1.0:
        return np.ones(u.shape, np.int64)
    n = np.ceil(np.log(u) / np.log1p(-1.0 / mean))
    return np.clip(n, 1, longest).astype(np.int64)


class PosePath:
    """True poses (R, 3) -> measured poses (R, 3), robot by robot (row-per-robot state).

    Per tick: the true pose of ``delay`` ticks ago, plus the episode's bias and fresh Gaussian
    noise, unless the measurement is held (probability ``pose_hold_prob``) or the tracker is
    frozen (a run of ticks started with probability ``pose_freeze_prob``): then the last
    measured pose repeats exactly, as the Robotarium's tracker repeats a lost marker's pose.
    """

    ROW_STATE = ("history", "delay", "bias", "measured", "freeze_left", "scale")

    def __init__(self, config: RealityConfig, n_robots: int) -> None:
        self.c = config
        self.length = config.pose_delay_max_ticks + 1
        self.history = np.zeros((n_robots, self.length, 3))
        """(R, L, 3) ring buffer of true poses, slot = tick mod L."""
        self.delay = np.zeros(n_robots, np.int64)
        """(R,) this episode's measurement delay (ticks)."""
        self.bias = np.zeros((n_robots, 2))
        """(R, 2) this episode's position offset (m)."""
        self.measured = np.zeros((n_robots, 3))
        """(R, 3) the latest measured poses."""
        self.freeze_left = np.zeros(n_robots, np.int64)
        """(R,) ticks of the current freeze still to come (0: tracking)."""
        self.rows = np.arange(n_robots)
        self.noisy = config.pose_noise_xy_m > 0 or config.pose_noise_theta_rad > 0
        self.scale = np.tile(
            [config.pose_noise_xy_m, config.pose_noise_xy_m, config.pose_noise_theta_rad], (n_robots, 1)
        )
        """(R, 3) this episode's noise SDs (x, y in m, θ in rad): the config's, or a calibrated draw
        (:meth:`begin`, :mod:`comat.reality.randomize`)."""

    def begin(
        self,
        rows: np.ndarray,
        true: np.ndarray,
        delay_u: np.ndarray,
        bias_n: np.ndarray,
        drawn: dict[str, np.ndarray] | None = None,
    ) -> None:
        """New episodes for robots ``rows`` at true poses (r, 3); per-episode uniforms (r, spread)
        for the delay and normals (r, 2) for the bias. The first measurement is fresh. ``drawn``:
        this episode's calibrated noise SDs per robot, name -> (r,) (None or a name left out: the
        profile's value)."""
        c = self.c
        if drawn:
            xy = drawn.get("pose_noise_xy_m", c.point.pose_noise_xy_m)
            theta = drawn.get("pose_noise_theta_rad", c.point.pose_noise_theta_rad)
            self.scale[rows, 0], self.scale[rows, 1], self.scale[rows, 2] = xy, xy, theta
        self.history[rows] = true[:, None, :]
        self.delay[rows] = c.pose_delay_ticks + binomial_half(delay_u)
        self.bias[rows] = c.pose_bias_xy_m * bias_n
        self.freeze_left[rows] = 0

    def first(self, rows: np.ndarray, true: np.ndarray, noise: np.ndarray) -> None:
        """The episode's first measurement of robots ``rows`` (true (r, 3), normals (r, 3))."""
        self.measured[rows] = self._corrupt(true, self.bias[rows], noise, self.scale[rows])

    def _corrupt(self, poses: np.ndarray, bias: np.ndarray, noise: np.ndarray | None, scale: np.ndarray) -> np.ndarray:
        out = poses + noise[:, :3] * scale if noise is not None else poses.copy()
        out[:, :2] += bias
        if noise is not None:  # wrapped to (-π, π], as the tiers report
            out[:, 2] = np.pi - np.remainder(np.pi - out[:, 2], 2.0 * np.pi)
        return out

    def update(
        self,
        true: np.ndarray,
        ticks: np.ndarray,
        noise: np.ndarray,
        u: np.ndarray,
        hold: np.ndarray | None = None,
        extra_delay: np.ndarray | None = None,
    ) -> None:
        """After a tick: record true poses (R, 3) at the robots' ticks (R,) (already advanced)
        and measure; ``noise`` (R, >= 3) normals (None: no noise), ``u`` (R, 3) uniforms (hold,
        freeze start, length). ``hold`` (R,) bool: the robots whose measurement is held this
        tick, decided by the caller (team-common holds, a script that missed the tick) instead
        of ``u[:, 0]``; ``extra_delay`` (R,) ticks added to the episode's delay this tick (jitter)."""
        c, L = self.c, self.length
        hold_prob = c.pose_hold_prob
        if hold is not None:  # the caller's decision, through the same test: u < 0.5 exactly where held
            u = u.copy()
            u[:, 0] = np.where(hold, 0.0, 1.0)
            hold_prob = 0.5
        delay = self.delay if extra_delay is None else self.delay + extra_delay
        if kernels.enabled():
            starts = np.empty(true.shape[0], np.int64)
            k = rk.pose_step(
                true,
                ticks,
                self.history,
                delay,
                self.bias,
                self.scale,
                noise,
                self.measured,
                self.freeze_left,
                c.pose_freeze_prob,
                hold_prob,
                u,
                starts,
            )
            if k:  # a started freeze repeats the pose it holds now, so its length is only needed from the next tick
                rows = starts[:k]
                self.freeze_left[rows] = run_lengths(u[rows, 2], c.pose_freeze_mean_ticks, c.pose_freeze_max_ticks) - 1
            return
        if L > 1:
            slot = ticks % L
            self.history[self.rows, slot] = true
            delayed = np.take(self.history.reshape(-1, 3), self.rows * L + (slot - delay) % L, axis=0)
        else:
            delayed = true
        fresh = self._corrupt(delayed, self.bias, noise, self.scale)
        frozen = self.freeze_left > 0
        self.freeze_left -= frozen
        if c.pose_freeze_prob > 0:
            start = ~frozen & (u[:, 1] < c.pose_freeze_prob)
            if start.any():
                self.freeze_left[start] = (
                    run_lengths(u[start, 2], c.pose_freeze_mean_ticks, c.pose_freeze_max_ticks) - 1
                )
                frozen |= start
        if hold_prob > 0:
            frozen |= u[:, 0] < hold_prob
        np.copyto(self.measured, fresh, where=~frozen[:, None])


class CommandPath:
    """Commands the script sends (R, 2) -> commands the robots execute (R, 2).

    A robot's command arrives ``delay`` ticks after it was sent (before the first one arrives,
    the robot is at rest). A lost command (a run of ticks started with probability
    ``command_loss_prob``) leaves the last received one in force; once no command has arrived
    for ``command_brake_after_s`` the robot brakes (zero command), as the GTernal firmware does.
    """

    ROW_STATE = ("sent", "delay", "last", "lost_run", "lost_left")

    def __init__(self, config: RealityConfig, n_robots: int) -> None:
        self.c = config
        self.length = config.command_delay_max_ticks + 1
        self.brake_after = config.command_brake_after_ticks
        self.sent = np.zeros((n_robots, self.length, 2))
        """(R, L, 2) ring buffer of sent commands, slot = tick mod L."""
        self.delay = np.zeros(n_robots, np.int64)
        """(R,) this episode's command delay (ticks)."""
        self.last = np.zeros((n_robots, 2))
        """(R, 2) the last command received."""
        self.lost_run = np.zeros(n_robots, np.int64)
        """(R,) consecutive ticks without a command (0: the last one arrived)."""
        self.lost_left = np.zeros(n_robots, np.int64)
        """(R,) ticks of the current run of losses still to come."""
        self.rows = np.arange(n_robots)

    def begin(self, rows: np.ndarray, delay_u: np.ndarray) -> None:
        """New episodes for robots ``rows``; per-episode uniforms (r, spread) for the delay."""
        self.sent[rows] = 0.0
        self.delay[rows] = self.c.command_delay_ticks + binomial_half(delay_u)
        self.last[rows] = 0.0
        self.lost_run[rows] = 0
        self.lost_left[rows] = 0

    def update(
        self, sent: np.ndarray, ticks: np.ndarray, u: np.ndarray, missed: np.ndarray | None = None
    ) -> np.ndarray:
        """Commands (R, 2) the robots execute this tick, given those sent now (R, 2) at the robots'
        ticks (R,) and uniforms (R, 2) (loss start, run length). ``missed`` (R,) bool: robots to
        which the script sent nothing this tick (its iteration overran or stalled): as a lost
        command, the last one stays in force and the brake's clock runs."""
        c, L = self.c, self.length
        forced = missed is not None and bool(missed.any())
        if kernels.enabled() and not forced:
            starts, out = np.empty(sent.shape[0], np.int64), np.empty_like(sent)
            k = rk.command_step(
                sent,
                ticks,
                self.delay,
                self.sent,
                self.last,
                self.lost_run,
                self.lost_left,
                c.command_loss_prob,
                self.brake_after,
                u,
                starts,
                out,
            )
            if k:  # a started run's length only matters from the next tick on
                rows = starts[:k]
                self.lost_left[rows] = run_lengths(u[rows, 1], c.command_loss_mean_ticks, np.iinfo(np.int32).max) - 1
            return out
        if L > 1:
            self.sent[self.rows, ticks % L] = sent
            arrived = np.where((ticks >= self.delay)[:, None], self.sent[self.rows, (ticks - self.delay) % L], 0.0)
        else:
            arrived = sent
        if c.command_loss_prob <= 0 and not forced:
            np.copyto(self.last, arrived)  # a copy: ``arrived`` may be the caller's array
            self.lost_run[:] = 0
            return arrived
        lost = self.lost_left > 0
        self.lost_left -= lost
        start = ~lost & (u[:, 0] < c.command_loss_prob)
        if start.any():
            self.lost_left[start] = run_lengths(u[start, 1], c.command_loss_mean_ticks, np.iinfo(np.int32).max) - 1
            lost |= start
        if forced:
            lost = lost | missed
        self.lost_run = np.where(lost, self.lost_run + 1, 0)
        self.last = np.where(lost[:, None], self.last, arrived)
        return np.where((self.lost_run >= self.brake_after)[:, None], 0.0, self.last)
