"""The reality layer's settings: one frozen :class:`RealityConfig`, three levels, per-field overrides.

``RealityConfig(level="nominal", pose_delay_ticks=2)`` is the nominal level with one component
changed; every field left at None takes the level's value in ``__post_init__`` (so a resolved
config, as written next to results, holds concrete numbers and loads back to itself).
``resolve_reality`` accepts what the env option ``reality=`` accepts.

Every default carries its provenance (:data:`SOURCES`), in the marks of
``shared/reference/sim2real-anchors.md``: **measured** (a number read from Robotarium code or
firmware), **derived** (arithmetic or a toy model on such numbers) or **assumed** (a proposed
magnitude with no public measurement behind it).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from comat import constants as C
from comat.config import load

__all__ = ["LEVELS", "REALITY_LEVELS", "SOURCES", "RealityConfig", "levels_markdown", "profile_fields",
           "resolve_reality"]

REALITY_LEVELS = ("off", "nominal", "stress")
"""The named levels, in order of severity."""


@dataclass(frozen=True)
class RealityConfig:
    """What separates the simulated robots from the Robotarium's, component by component.

    ``level`` names the base values (:data:`LEVELS`); any other field given overrides its
    level's value. All times are at the 0.033 s control tick. Per-robot quantities are drawn
    once per episode from the episode's seed (same seed, same draws); per-tick noise likewise.
    """

    level: str = "off"
    """Base level: ``"off"`` (the ideal world, bit for bit), ``"nominal"`` or ``"stress"``."""

    # -- pose path (true poses -> what controller, filter and policy see) -------------------------
    pose_delay_ticks: int | None = None
    """Minimum measurement delay (ticks). nominal 0, stress 1: derived (Vicon->MQTT every 33 ms,
    no timestamps; sim2real-anchors §1.2, §6 #1)."""
    pose_delay_spread_ticks: int | None = None
    """Extra delay per episode ~ Binomial(spread, 1/2) ticks on top of the minimum: spread 2 gives
    {0, 1, 2} with P .25/.5/.25 (§6 #1), common to the team (one message carries every pose) unless
    ``pose_per_robot``. nominal 2, stress 2: derived."""
    pose_delay_jitter_prob: float | None = None
    """Per tick, probability that this tick's message is one tick older than the episode's delay
    (two unsynchronised 33 ms clocks, the tracker's and the script's, beat between k and k + 1
    ticks; no timestamps to tell). Common to the team. nominal 0.2, stress 0.4: assumed (§1.1)."""
    pose_hold_prob: float | None = None
    """Per tick probability that the measurement is not refreshed (the last measured pose repeats;
    mjlab-style hold): common to the team (a message that did not come repeats every pose) unless
    ``pose_per_robot``. nominal 0.3, stress 0.3: assumed (§6 #1)."""
    pose_per_robot: bool | None = None
    """True: each robot's pose delay, jitter and holds are its own (comat's structure before issue
    45; the results committed before 2026-12-06 used it). False (every level): common to the team,
    as the testbed's one message per tick with every pose. Structure only: it switches nothing on."""
    pose_noise_xy_m: float | None = None
    """SD of Gaussian position noise per axis per tick (m). nominal 0.001 (Vicon class), stress
    0.005: assumed (§1.4, §6 #8)."""
    pose_noise_theta_rad: float | None = None
    """SD of Gaussian heading noise per tick (rad). nominal 0.01, stress 0.05: assumed (§6 #8;
    V2's onboard orientation noise is 0.31° = 0.0054 rad, measured)."""
    pose_bias_xy_m: float | None = None
    """SD of a per-robot, per-episode position offset per axis (m). nominal 0.0005: assumed
    (§6 #8); stress 0.0025: derived (the older camera tracker's 2.5 mm per pixel, §1.4)."""
    pose_freeze_prob: float | None = None
    """Per robot-tick probability that tracking freezes (the last measured pose repeats for a
    run of ticks). nominal 0.002, stress 0.02: assumed (§6 #9)."""
    pose_freeze_mean_ticks: float | None = None
    """Mean length of a freeze (geometric, ticks >= 1). nominal 3, stress 10: assumed (§6 #9)."""
    pose_freeze_max_ticks: int | None = None
    """Longest freeze (ticks). nominal 150: measured (the tracker drops a marker after 5000 ms,
    vicon_tracker ``timeout_millis``, §1.1); stress 30: assumed (§6 #9 "bursts up to 30")."""

    # -- command path (filtered command -> what reaches the robot) --------------------------------
    command_delay_ticks: int | None = None
    """Minimum command delay (ticks). nominal 0, stress 1: derived (Pi 16 ms poll + ISR 10 ms +
    execute-then-sense 10 ms, §1.2, §6 #2)."""
    command_delay_spread_ticks: int | None = None
    """Extra command delay per robot and episode ~ Binomial(spread, 1/2): spread 1 gives {0, 1}
    (nominal) or {1, 2} (stress) with equal odds (§6 #2). nominal 1, stress 1: derived."""
    command_loss_prob: float | None = None
    """Per robot-tick probability that a run of lost commands starts: the robot keeps its last
    received command. nominal 0.01, stress 0.05: assumed (§6 #10)."""
    command_loss_mean_ticks: float | None = None
    """Mean length of a run of losses (geometric, ticks >= 1). nominal 1, stress 5 (bursts):
    assumed (§6 #10)."""
    script_miss_prob: float | None = None
    """Per tick probability that the script's iteration overruns the 0.033 s tick (a long QP, the
    policy's inference at a step boundary): that tick no command goes out to any robot of the team
    (each keeps its last; it counts toward the brake) and the pose it reads next is one tick
    staler (a hold). nominal 0.002, stress 0.02: derived from the deployed loop's measured
    compute time (docs/reality.md) with the server's speed assumed."""
    script_stall_prob: float | None = None
    """Per tick probability that the script stalls (garbage collection, I/O, the server's load):
    no command to any robot of the team for a run of ticks; a run past the brake time stops every
    robot. nominal 0, stress 0.001: assumed (§1.1; CASH's server logs end in interrupts)."""
    script_stall_mean_ticks: float | None = None
    """Mean length of a stall (geometric, ticks >= 1). 10 (0.33 s) at both levels: assumed."""
    command_brake_after_s: float | None = None
    """A robot without a command for this long brakes (v = ω = 0) until one arrives: it brakes
    from the tick during which the timeout expires (15 lost ticks at 0.033 s). 0.5 s at both
    levels: measured (GTernal ``communicationCheck(500)``, §1.1)."""

    # -- motors (wheel speeds the robot asks for -> wheel speeds it gets) -------------------------
    motor_tau_min_s: float | None = None
    """First-order wheel-speed lag: time constant per wheel and episode ~ U(min, max) (s); 0 =
    no lag. nominal 0.04–0.08, stress 0.08–0.12: derived (firmware PI + slew, toy model 60–80
    ms to 63 %, §1.2, §6 #3)."""
    motor_tau_max_s: float | None = None
    """Upper end of the lag's time constant (s); see ``motor_tau_min_s``."""
    motor_accel_limit_radps2: float | None = None
    """Largest change of a wheel's speed (rad/s per s); 0 = no limit. 200 at both levels:
    derived (PWM slew 50/255 per 10 ms: 12.5 rad/s in ~60 ms, §1.1, §6 #3)."""
    motor_dead_zone_radps: float | None = None
    """A wheel asked for less than this speed (rad/s) does not turn. nominal 1.9 (0.03 m/s at
    the rim): derived (guide minimum speed 0.03 m/s, §1.1, §6 #4); stress 3.0: assumed."""
    wheel_gain_spread: float | None = None
    """Per wheel and episode, speed gain ~ U(1 - spread, 1 + spread) (radius, calibration):
    a straight command drives a curve. nominal 0.03, stress 0.07: assumed (guide Fig. 13, §6 #5)."""
    top_speed_derate_min: float | None = None
    """Per robot and episode, the reachable wheel speed is 12.5 rad/s × U(min, 1) (battery,
    wear); 1 = none. nominal 0.9, stress 0.75: assumed (battery thresholds, PID saturation,
    §1.1, §6 #6)."""
    wheel_disturbance_radps: float | None = None
    """Stationary SD of a per-wheel Ornstein–Uhlenbeck speed disturbance on a turning wheel
    (rad/s). nominal 0.5, stress 2.0: assumed (§6 #7)."""
    wheel_disturbance_corr_s: float | None = None
    """Correlation time of that disturbance (s). 0.2 at both levels: assumed (§6 #7)."""
    wheel_disturbance_bound_radps: float | None = None
    """The disturbance is clipped to ± this (rad/s). 5.0 at both levels: measured as a design
    bound (the Robotarium's robust barrier, ``disturbance=5``, §1.1, §6 #7)."""

    # -- faults -----------------------------------------------------------------------------------
    fault_prob: float | None = None
    """Probability that an episode has one faulty robot (drawn uniformly from the team). 0 at
    both levels: faults change the team under the policy, an experiment of its own (set it to
    1 to run CASH-MARBLER's ``motor_failure``, §2.3)."""
    fault_speed_fraction: float | None = None
    """The faulty robot's wheels turn at this fraction of their speed from the fault on (0 =
    the motors fail). 0.25 at both levels: measured setting (CASH-MARBLER ``motor_failure``, §2.3)."""
    fault_start_min_s: float | None = None
    """The fault begins at a time ~ U(min, max) after the episode's start (s). 0: assumed."""
    fault_start_max_s: float | None = None
    """Upper end of the fault's start time (s). 60 (within the first minute: both tasks'
    horizons are longer, PCP 77 s, HMT 171 s): assumed."""
    fault_known: bool | None = None
    """Whether the faulty robot's capability vector reports its new speed (known) or not
    (hidden). The layer only carries the flag (:attr:`RealityLayer.speed_fraction` holds the
    factor); the env decides what a capability vector says. False at both levels: assumed."""

    # -- start ------------------------------------------------------------------------------------
    start_xy_m: float | None = None
    """A robot starts up to this far from its requested position (uniform in the disc of this
    radius, m: the start-up drive's radial tolerance). 0.05 at both levels: measured (V2
    initializer ``at_pose`` tolerance, a norm, §1.3, §6 #12)."""
    start_theta_rad: float | None = None
    """Heading start error, uniform ± this (rad). 0.2 at both levels: measured (§1.3)."""

    # -- physics (wheels tier only: the unicycle tier has no contacts or masses to vary) ----------
    floor_friction_min: float | None = None
    """Per robot and episode, the friction between its wheels and the floor ~ U(min, max) (the
    model's own is 1.5); max 0 = unchanged. nominal 0.6–1.5, stress 0.4–1.5: assumed (§6 #13:
    Playground, legged_gym and Isaac ranges scaled to a 0.1 kg robot)."""
    floor_friction_max: float | None = None
    """Upper end of the floor friction (see ``floor_friction_min``)."""
    chassis_mass_spread: float | None = None
    """Per robot and episode, the chassis mass × U(1 - spread, 1 + spread). 0.1 at both levels:
    assumed (§6 #13)."""
    com_offset_m: float | None = None
    """Per robot and episode, the chassis centre of mass moves U(-c, c) along x and y (m). 0.005
    at both levels: assumed (§6 #13)."""

    def __post_init__(self) -> None:
        if not isinstance(self.level, str) or self.level not in LEVELS:
            raise ValueError(f"RealityConfig.level must be one of {list(REALITY_LEVELS)}, got {self.level!r}")
        base = LEVELS[self.level]
        for f in dataclasses.fields(self):
            if f.name != "level" and getattr(self, f.name) is None:
                object.__setattr__(self, f.name, base[f.name])
        _check(self)

    @property
    def is_off(self) -> bool:
        """True when every component is neutral: the world is the ideal one (no layer runs)."""
        off = LEVELS["off"]
        return all(getattr(self, k) == v for k, v in off.items() if k not in _INERT)

    @property
    def command_brake_after_ticks(self) -> int:
        """Consecutive lost ticks after which the robot brakes: the tick during which
        ``command_brake_after_s`` expires (15 at 0.5 s)."""
        return max(1, math.floor(self.command_brake_after_s / C.CONTROL_DT_S + 1e-9))

    @property
    def pose_delay_max_ticks(self) -> int:
        """The longest pose delay any robot can get (ticks; a jittered tick included)."""
        return self.pose_delay_ticks + self.pose_delay_spread_ticks + (1 if self.pose_delay_jitter_prob > 0 else 0)

    @property
    def command_delay_max_ticks(self) -> int:
        """The longest command delay any robot can get (ticks)."""
        return self.command_delay_ticks + self.command_delay_spread_ticks

    def overrides(self) -> dict[str, Any]:
        """The fields that differ from the level's values (what a run's label should list)."""
        base = LEVELS[self.level]
        return {k: getattr(self, k) for k in base if getattr(self, k) != base[k]}

    @property
    def label(self) -> str:
        """What a row says about its reality layer: the level's name, or ``"custom"`` when any field
        differs from the level's value."""
        return "custom" if self.overrides() else self.level


_INT_FIELDS = ("pose_delay_ticks", "pose_delay_spread_ticks", "pose_freeze_max_ticks", "command_delay_ticks",
               "command_delay_spread_ticks")
_PROB_FIELDS = ("pose_hold_prob", "pose_delay_jitter_prob", "pose_freeze_prob", "command_loss_prob", "script_miss_prob",
                "script_stall_prob", "fault_prob", "fault_speed_fraction")
_NONNEG_FIELDS = ("pose_noise_xy_m", "pose_noise_theta_rad", "pose_bias_xy_m", "motor_tau_min_s", "motor_tau_max_s",
                  "motor_accel_limit_radps2", "motor_dead_zone_radps", "wheel_disturbance_radps",
                  "wheel_disturbance_bound_radps", "fault_start_min_s", "fault_start_max_s", "start_xy_m",
                  "start_theta_rad", "floor_friction_min", "floor_friction_max", "com_offset_m")
_POSITIVE_FIELDS = ("command_brake_after_s", "wheel_disturbance_corr_s")
_INERT = ("fault_speed_fraction", "fault_start_min_s", "fault_start_max_s", "fault_known", "pose_freeze_mean_ticks",
          "pose_freeze_max_ticks", "command_loss_mean_ticks", "command_brake_after_s", "wheel_disturbance_corr_s",
          "wheel_disturbance_bound_radps", "pose_per_robot", "script_stall_mean_ticks")
"""Fields that shape a component without switching it on (a component is on through its
probability, SD, delay or range). The upper ends of ranges are not among them: a lag drawn from
[0, motor_tau_max_s] or a delay from [0, spread] ticks is on with its lower end at 0 (they were,
until 2026-12-04, and such a setting ran the ideal world: the layer's own switches disagreed)."""


def _check(c: RealityConfig) -> None:
    """One-line ValueError/TypeError naming ``RealityConfig.<field>``, the expectation and the value."""

    def fail(name: str, expected: str) -> None:
        raise ValueError(f"RealityConfig.{name} must be {expected}, got {getattr(c, name)!r}")

    for name in _INT_FIELDS:
        v = getattr(c, name)
        if isinstance(v, bool) or not isinstance(v, int) or v < 0:
            fail(name, "an integer >= 0 (ticks)")
    for name in _PROB_FIELDS + _NONNEG_FIELDS + _POSITIVE_FIELDS + ("pose_freeze_mean_ticks", "command_loss_mean_ticks",
                                                                      "wheel_gain_spread", "top_speed_derate_min",
                                                                      "chassis_mass_spread", "script_stall_mean_ticks"):
        v = getattr(c, name)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            fail(name, "a finite number")
    for name in _PROB_FIELDS:
        if not 0.0 <= getattr(c, name) <= 1.0:
            fail(name, "a probability in [0, 1]")
    for name in _NONNEG_FIELDS:
        if getattr(c, name) < 0:
            fail(name, "a number >= 0")
    for name in _POSITIVE_FIELDS:
        if getattr(c, name) <= 0:
            fail(name, "a number > 0")
    for name in ("pose_freeze_mean_ticks", "command_loss_mean_ticks", "script_stall_mean_ticks"):
        if getattr(c, name) < 1:
            fail(name, "a mean run length >= 1 tick")
    if c.pose_freeze_max_ticks < 1:
        fail("pose_freeze_max_ticks", "an integer >= 1 (ticks)")
    if not 0.0 <= c.wheel_gain_spread < 1.0:
        fail("wheel_gain_spread", "a number in [0, 1)")
    if not 0.0 < c.top_speed_derate_min <= 1.0:
        fail("top_speed_derate_min", "a number in (0, 1]")
    if c.motor_tau_max_s < c.motor_tau_min_s:
        fail("motor_tau_max_s", f"a number >= motor_tau_min_s ({c.motor_tau_min_s})")
    if not 0.0 <= c.chassis_mass_spread < 1.0:
        fail("chassis_mass_spread", "a number in [0, 1)")
    if c.floor_friction_max > 0 and not 0 < c.floor_friction_min <= c.floor_friction_max:
        fail("floor_friction_min", f"a number in (0, floor_friction_max = {c.floor_friction_max}] (max 0: unchanged)")
    if c.fault_start_max_s < c.fault_start_min_s:
        fail("fault_start_max_s", f"a number >= fault_start_min_s ({c.fault_start_min_s})")
    for name in ("fault_known", "pose_per_robot"):
        if not isinstance(getattr(c, name), bool):
            raise TypeError(f"RealityConfig.{name} must be a bool, got {getattr(c, name)!r}")


_OFF = {
    "pose_delay_ticks": 0, "pose_delay_spread_ticks": 0, "pose_hold_prob": 0.0, "pose_noise_xy_m": 0.0, "pose_noise_theta_rad": 0.0,
    "pose_bias_xy_m": 0.0, "pose_freeze_prob": 0.0, "pose_freeze_mean_ticks": 3.0, "pose_freeze_max_ticks": 150,
    "pose_delay_jitter_prob": 0.0, "pose_per_robot": False, "script_miss_prob": 0.0, "script_stall_prob": 0.0,
    "script_stall_mean_ticks": 10.0, "command_delay_ticks": 0, "command_delay_spread_ticks": 0, "command_loss_prob": 0.0, "command_loss_mean_ticks": 1.0,
    "command_brake_after_s": 0.5, "motor_tau_min_s": 0.0, "motor_tau_max_s": 0.0, "motor_accel_limit_radps2": 0.0,
    "motor_dead_zone_radps": 0.0, "wheel_gain_spread": 0.0, "top_speed_derate_min": 1.0, "wheel_disturbance_radps": 0.0,
    "wheel_disturbance_corr_s": 0.2, "wheel_disturbance_bound_radps": 5.0, "fault_prob": 0.0, "fault_speed_fraction": 0.25,
    "fault_start_min_s": 0.0, "fault_start_max_s": 60.0, "fault_known": False, "start_xy_m": 0.0, "start_theta_rad": 0.0,
    "floor_friction_min": 0.0, "floor_friction_max": 0.0, "chassis_mass_spread": 0.0, "com_offset_m": 0.0,
}
LEVELS: dict[str, dict[str, Any]] = {
    "off": _OFF,
    "nominal": {**_OFF, 
        "pose_delay_ticks": 0, "pose_delay_spread_ticks": 2, "pose_hold_prob": 0.3, "pose_noise_xy_m": 0.001,
        "pose_noise_theta_rad": 0.01, "pose_bias_xy_m": 0.0005, "pose_freeze_prob": 0.002, "pose_freeze_mean_ticks": 3.0,
        "pose_freeze_max_ticks": 150, "command_delay_ticks": 0, "command_delay_spread_ticks": 1, "command_loss_prob": 0.01,
        "command_loss_mean_ticks": 1.0, "motor_tau_min_s": 0.04, "motor_tau_max_s": 0.08, "motor_accel_limit_radps2": 200.0,
        "motor_dead_zone_radps": 1.9, "wheel_gain_spread": 0.03, "top_speed_derate_min": 0.9, "wheel_disturbance_radps": 0.5,
        "start_xy_m": 0.05, "start_theta_rad": 0.2, "floor_friction_min": 0.6, "floor_friction_max": 1.5,
        "chassis_mass_spread": 0.1, "com_offset_m": 0.005, "pose_delay_jitter_prob": 0.2, "script_miss_prob": 0.002,
    },
    "stress": {**_OFF, 
        "pose_delay_ticks": 1, "pose_delay_spread_ticks": 2, "pose_hold_prob": 0.3, "pose_noise_xy_m": 0.005,
        "pose_noise_theta_rad": 0.05, "pose_bias_xy_m": 0.0025, "pose_freeze_prob": 0.02, "pose_freeze_mean_ticks": 10.0,
        "pose_freeze_max_ticks": 30, "command_delay_ticks": 1, "command_delay_spread_ticks": 1, "command_loss_prob": 0.05,
        "command_loss_mean_ticks": 5.0, "motor_tau_min_s": 0.08, "motor_tau_max_s": 0.12, "motor_accel_limit_radps2": 200.0,
        "motor_dead_zone_radps": 3.0, "wheel_gain_spread": 0.07, "top_speed_derate_min": 0.75, "wheel_disturbance_radps": 2.0,
        "start_xy_m": 0.05, "start_theta_rad": 0.2, "floor_friction_min": 0.4, "floor_friction_max": 1.5,
        "chassis_mass_spread": 0.1, "com_offset_m": 0.005, "pose_delay_jitter_prob": 0.4, "script_miss_prob": 0.02,
        "script_stall_prob": 0.001,
    },
}
"""Each level's value of every field (the ``off`` values switch every component off)."""

SOURCES: dict[str, tuple[str, str]] = {
    "pose_delay_ticks": ("derived", "Vicon->MQTT every 33 ms, no timestamps (§1.1-1.2, §6 #1)"),
    "pose_delay_spread_ticks": ("derived", "{0,1,2} ticks P .25/.5/.25 (§6 #1)"),
    "pose_hold_prob": ("assumed", "mjlab-style hold (§6 #1)"),
    "pose_noise_xy_m": ("assumed", "Vicon class (§1.4, §6 #8)"),
    "pose_noise_theta_rad": ("assumed", "§6 #8; V2 orientation 0.31° measured"),
    "pose_bias_xy_m": ("assumed", "nominal §6 #8; stress = camera 2.5 mm/px, derived (§1.4)"),
    "pose_freeze_prob": ("assumed", "§6 #9"),
    "pose_freeze_mean_ticks": ("assumed", "§6 #9"),
    "pose_freeze_max_ticks": ("measured", "tracker timeout 5000 ms (§1.1); stress 30 assumed (§6 #9)"),
    "pose_delay_jitter_prob": ("assumed", "two unsynchronised 33 ms clocks, no timestamps (§1.1)"),
    "pose_per_robot": ("measured", "structure: one MQTT message with every pose (§1.1)"),
    "script_miss_prob": ("derived", "the deployed loop's measured compute time; server speed assumed"),
    "script_stall_prob": ("assumed", "stalls and interrupts of the user's script (§1.1)"),
    "script_stall_mean_ticks": ("assumed", "—"),
    "command_delay_ticks": ("derived", "Pi poll + ISR + execute-then-sense (§1.2, §6 #2)"),
    "command_delay_spread_ticks": ("derived", "{0,1} / {1,2} ticks (§6 #2)"),
    "command_loss_prob": ("assumed", "§6 #10"),
    "command_loss_mean_ticks": ("assumed", "§6 #10 (stress: bursts)"),
    "command_brake_after_s": ("measured", "GTernal communicationCheck(500) (§1.1)"),
    "motor_tau_min_s": ("derived", "firmware PI + slew toy model (§1.2, §6 #3)"),
    "motor_tau_max_s": ("derived", "firmware PI + slew toy model (§1.2, §6 #3)"),
    "motor_accel_limit_radps2": ("derived", "PWM slew 50/255 per 10 ms (§1.1, §6 #3)"),
    "motor_dead_zone_radps": ("derived", "guide minimum speed 0.03 m/s (§1.1, §6 #4); stress assumed"),
    "wheel_gain_spread": ("assumed", "guide Fig. 13 curved open-loop path (§6 #5)"),
    "top_speed_derate_min": ("assumed", "battery thresholds, PID saturation (§1.1, §6 #6)"),
    "wheel_disturbance_radps": ("assumed", "§6 #7"),
    "wheel_disturbance_corr_s": ("assumed", "§6 #7"),
    "wheel_disturbance_bound_radps": ("measured", "robust barrier disturbance=5 rad/s, a design bound (§1.1)"),
    "fault_prob": ("assumed", "opt-in; CASH-MARBLER motor_failure (§2.3)"),
    "fault_speed_fraction": ("measured", "CASH-MARBLER motor_failure setting (§2.3)"),
    "fault_start_min_s": ("assumed", "—"),
    "fault_start_max_s": ("assumed", "within the first minute"),
    "fault_known": ("assumed", "—"),
    "start_xy_m": ("measured", "V2 initializer at_pose radial tolerance (§1.3, §6 #12)"),
    "start_theta_rad": ("measured", "V2 initializer at_pose tolerance (§1.3, §6 #12)"),
    "floor_friction_min": ("assumed", "peers' ranges scaled to a 0.1 kg robot (§3.8, §6 #13)"),
    "floor_friction_max": ("assumed", "peers' ranges scaled to a 0.1 kg robot (§3.8, §6 #13)"),
    "chassis_mass_spread": ("assumed", "peers' ×U(0.9, 1.1) (§3.8, §6 #13)"),
    "com_offset_m": ("assumed", "peers' ±5 cm scaled to a 0.11 m robot (§6 #13)"),
}
"""Per field: (mark, source) for the documentation and the levels table of docs/reality.md."""


def levels_markdown() -> str:
    """The levels table of docs/reality.md (field, nominal, stress, mark, source), made from
    :data:`LEVELS` and :data:`SOURCES`: a test keeps the page equal to it."""
    rows = ["| field | nominal | stress | mark | source |", "|---|---|---|---|---|"]
    for name in LEVELS["off"]:
        mark, source = SOURCES[name]
        rows.append(f"| `{name}` | {LEVELS['nominal'][name]} | {LEVELS['stress'][name]} | {mark} | {source} |")
    return "\n".join(rows) + "\n"


def profile_fields(path: str, name: str = "reality") -> dict[str, Any]:
    """The RealityConfig fields of a profile file (``comat calibrate --out PROFILE.yaml``: a
    mapping with a ``reality`` mapping of fields); one-line errors for a missing or foreign file."""
    from pathlib import Path

    import yaml

    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"{name}: profile {path!r} does not exist (write one with comat calibrate)")
    try:
        data = yaml.safe_load(p.read_text())
    except yaml.YAMLError as exc:
        raise ValueError(f"{name}: profile {path!r} is not YAML ({str(exc).splitlines()[0]})") from None
    if not isinstance(data, dict) or not isinstance(data.get("reality"), dict):
        raise ValueError(  # noqa: TRY004 (a file of the wrong kind: a value error to the user)
            f"{name}: {path!r} is not a reality profile (a mapping with a 'reality' mapping of fields, "
            "as comat calibrate writes)")
    return dict(data["reality"])


def resolve_reality(value: Any, name: str = "reality") -> RealityConfig:
    """A RealityConfig from ``"off" | "nominal" | "stress"``, a profile file (``*.yaml``, from
    ``comat calibrate``), a RealityConfig, None (off), or a
    mapping of fields (``{"level": "nominal", "pose_delay_ticks": 2}``; without ``level`` the
    fields change the ``off`` level, so ``{"pose_delay_ticks": 2}`` is that one component alone)."""

    if value is None:
        return RealityConfig()
    if isinstance(value, RealityConfig):
        return value
    if isinstance(value, str) and value.endswith((".yaml", ".yml")):
        return load(RealityConfig, profile_fields(value, name), prefix=name)
    if isinstance(value, str):
        if value not in LEVELS:
            raise ValueError(f"{name} must be one of {list(REALITY_LEVELS)}, a RealityConfig or a mapping of its "
                             f"fields, got {value!r}")
        return RealityConfig(level=value)
    if isinstance(value, Mapping):
        fields = dict(value)
        return load(RealityConfig, fields, prefix=name)
    raise TypeError(f"{name} must be one of {list(REALITY_LEVELS)}, a RealityConfig or a mapping of its fields, "
                    f"got {type(value).__name__}")
