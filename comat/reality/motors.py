"""The robots' wheels as the reality layer models them: what a wheel asked for a speed actually does.

Per tick and wheel (left, right), in order:

1. dead zone: a wheel asked for less than ``motor_dead_zone_radps`` does not turn;
2. gain: the request times the wheel's episode gain (radius, calibration mismatch), times the
   robot's fault fraction once its fault has begun;
3. top speed: clipped to 12.5 rad/s × the robot's episode derate;
4. lag: a first-order step toward that target with the wheel's time constant, its change per
   tick clipped by the acceleration limit;
5. disturbance: a per-wheel Ornstein–Uhlenbeck speed error, clipped to its bound, added while
   the wheel is driven (a wheel at rest does not creep), the sum clipped to the top speed again.

All state is row-per-robot (R, 2) and advanced for every robot at once.
"""

from __future__ import annotations

import numpy as np

from comat import constants as C
from comat import kernels
from comat.reality import kernels as rk
from comat.reality.config import RealityConfig
from comat.sim.kinematics import diff_to_uni, uni_to_diff

__all__ = ["Motors"]


class Motors:
    """Wheel-speed dynamics, calibration errors and faults of R robots."""

    ROW_STATE = ("speed", "alpha", "gain", "cap", "noise", "fault_tick", "dead_zone")

    def __init__(self, config: RealityConfig, profile: C.RobotProfile, n_robots: int) -> None:
        self.c = config
        self.profile = profile
        self.speed = np.zeros((n_robots, 2))
        """(R, 2) current wheel speeds [left, right] (rad/s)."""
        self.alpha = np.zeros((n_robots, 2))
        """(R, 2) per-tick decay exp(-dt/τ) of the lag (0: no lag)."""
        self.gain = np.ones((n_robots, 2))
        """(R, 2) per-wheel speed gain of this episode."""
        self.cap = np.full(n_robots, profile.max_wheel_velocity_radps)
        """(R,) reachable wheel speed of this episode (rad/s)."""
        self.noise = np.zeros((n_robots, 2))
        """(R, 2) the wheels' disturbance state (rad/s)."""
        self.fault_tick = np.full(n_robots, np.iinfo(np.int64).max)
        """(R,) tick from which the robot runs at ``fault_speed_fraction`` (int64 max: never)."""
        self.dead_zone = np.full(n_robots, float(config.motor_dead_zone_radps))
        """(R,) wheel speed below which this episode's wheels do not turn (rad/s): the config's,
        or a calibrated draw (:mod:`comat.reality.randomize`)."""
        dt, tc = C.CONTROL_DT_S, config.wheel_disturbance_corr_s
        self._rho = float(np.exp(-dt / tc))
        self._kick = config.wheel_disturbance_radps * float(np.sqrt(1.0 - self._rho**2))
        self._step = config.motor_accel_limit_radps2 * dt

    def begin(
        self,
        rows: np.ndarray,
        u: np.ndarray,
        n: np.ndarray,
        fault_ticks: np.ndarray,
        drawn: dict[str, np.ndarray] | None = None,
    ) -> None:
        """New episodes for robots ``rows``: per-episode uniforms (r, 5) (time constants 2, gains 2,
        derate 1), normals (r, 2) (the disturbance's stationary start) and fault ticks (r,).
        ``drawn``: this episode's calibrated draws per robot, name -> (r,) (:mod:`comat.reality.randomize`;
        None or a name left out: the config's value)."""
        c = self.c
        tau_min, tau_max, mean, spread, derate = (
            c.motor_tau_min_s,
            c.motor_tau_max_s,
            c.wheel_gain_mean,
            c.wheel_gain_spread,
            c.top_speed_derate_min,
        )
        if drawn:
            point = c.point  # the profile's own values (the config's fields are the draws' envelope)
            shift = drawn.get("motor_tau_shift_s")
            if shift is not None:
                tau_min = np.maximum(point.motor_tau_min_s + shift, 0.0)[:, None]
                tau_max = np.maximum(point.motor_tau_max_s + shift, 0.0)[:, None]
            else:
                tau_min, tau_max = point.motor_tau_min_s, point.motor_tau_max_s
            mean = drawn["wheel_gain_mean"][:, None] if "wheel_gain_mean" in drawn else point.wheel_gain_mean
            spread = drawn["wheel_gain_spread"][:, None] if "wheel_gain_spread" in drawn else point.wheel_gain_spread
            derate = drawn.get("top_speed_derate_min", point.top_speed_derate_min)
            self.dead_zone[rows] = drawn.get("motor_dead_zone_radps", point.motor_dead_zone_radps)
        tau = tau_min + (tau_max - tau_min) * u[:, 0:2]
        self.alpha[rows] = np.exp(-C.CONTROL_DT_S / np.maximum(tau, 1e-300)) * (tau > 0)
        self.gain[rows] = mean + spread * (2.0 * u[:, 2:4] - 1.0)
        self.cap[rows] = self.profile.max_wheel_velocity_radps * (derate + (1.0 - derate) * u[:, 4])
        bound = c.wheel_disturbance_bound_radps
        self.noise[rows] = np.clip(c.wheel_disturbance_radps * n, -bound, bound)
        self.speed[rows] = 0.0
        self.fault_tick[rows] = fault_ticks

    def faulty(self, ticks: np.ndarray) -> np.ndarray:
        """(R,) True where a robot's fault has begun at its tick."""
        return ticks >= self.fault_tick

    def update(self, wheels: np.ndarray, ticks: np.ndarray, noise_n: np.ndarray) -> np.ndarray:
        """Wheel speeds (R, 2) this tick for requested ones (R, 2) at the robots' ticks (R,);
        ``noise_n`` (R, 2) standard normals for the disturbance (None when it is off)."""
        c = self.c
        target = np.where(np.abs(wheels) < self.dead_zone[:, None], 0.0, wheels) * self.gain
        if c.fault_prob > 0:
            target = target * np.where(self.faulty(ticks), c.fault_speed_fraction, 1.0)[:, None]
        cap = self.cap[:, None]
        target = np.clip(target, -cap, cap)
        new = target + (self.speed - target) * self.alpha
        if self._step > 0:
            new = self.speed + np.clip(new - self.speed, -self._step, self._step)
        self.speed = new
        if c.wheel_disturbance_radps <= 0:
            return new
        bound = c.wheel_disturbance_bound_radps
        self.noise = np.clip(self.noise * self._rho + self._kick * noise_n, -bound, bound)
        return np.clip(new + np.where(target != 0.0, self.noise, 0.0), -cap, cap)

    def update_unicycle(self, dxu: np.ndarray, ticks: np.ndarray, noise_n: np.ndarray) -> np.ndarray:
        """Unicycle commands (R, 2) executed for requested ones (R, 2): :meth:`update` between
        the wheel conversions (one compiled pass, no temporaries, when the kernels are on)."""
        p = self.profile
        if not kernels.enabled():
            return diff_to_uni(self.update(uni_to_diff(dxu, p), ticks, noise_n), p)
        c = self.c
        fault = np.where(self.faulty(ticks), c.fault_speed_fraction, 1.0) if c.fault_prob > 0 else None
        out = np.empty_like(dxu)
        rk.motors_step(
            dxu, p.wheel_radius_m, p.base_length_m / 2.0, p.base_length_m, self.dead_zone, self.gain, fault,
            self.cap, self.alpha, self._step, self.speed, self.noise, self._rho, self._kick,
            c.wheel_disturbance_bound_radps, noise_n if c.wheel_disturbance_radps > 0 else None, out,
        )  # fmt: skip
        return out
