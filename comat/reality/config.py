"""The reality layer's settings: one frozen :class:`RealityConfig`, three levels, per-field overrides.

``RealityConfig(level="nominal", pose_delay_ticks=2)`` is the nominal level with one component
changed; every field left at None takes the level's value in ``__post_init__`` (so a resolved
config, as written next to results, holds concrete numbers and loads back to itself).
``resolve_reality`` accepts what the env option ``reality=`` accepts.

Each field is declared once, with its value at each level and its provenance: :data:`LEVELS`,
:data:`SOURCES` and the levels table of docs/reality.md (:func:`levels_markdown`) are made from
those declarations. A provenance is a mark, **measured** (a number read from Robotarium code or
firmware), **derived** (arithmetic or a toy model on such numbers) or **assumed** (a proposed
magnitude with no public measurement behind it), and a source. The primary sources are the
Robotarium's public code: the GTernal robot firmware (``robotarium/GTernal``), the Vicon pose
publisher (``robotarium/vicon_tracker``), the Python simulator and its user guide
(``robotarium/robotarium_python_simulator``), and CASH-MARBLER's Robotarium runs
(``shalin-jain/CASH-MARBLER``); the assumed physics ranges scale those of MuJoCo Playground,
legged_gym and Isaac Lab. The § numbers ("§1.2", "§6 #3") name sections of
docs/reality-sources.md, which states the facts each value rests on with its public source.
"""

from __future__ import annotations

import ast
import dataclasses
import inspect
import itertools
import math
import textwrap
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from comat import constants as C
from comat.config import load

__all__ = [
    "KINDS",
    "LEVELS",
    "MARKS",
    "PARAMETER_KINDS",
    "PROFILE_FORMAT",
    "REALITY_LEVELS",
    "SOURCES",
    "RealityConfig",
    "field_docs",
    "levels_markdown",
    "read_profile",
    "resolve_reality",
]

REALITY_LEVELS = ("off", "nominal", "stress")
"""The named levels, in order of severity."""

MARKS = ("measured", "derived", "assumed")
"""How a value is known: read from Robotarium code or firmware, worked out from such numbers, or
proposed without a public measurement."""


def _field(off: Any, nominal: Any, stress: Any, mark: str, source: str) -> Any:
    """A :class:`RealityConfig` field: None by default (``__post_init__`` puts in the level's
    value), with its value at each level and its provenance in the field's metadata, which
    :data:`LEVELS`, :data:`SOURCES` and :func:`levels_markdown` read."""
    if mark not in MARKS:
        raise ValueError(f"mark must be one of {MARKS}, got {mark!r}")
    levels = dict(zip(REALITY_LEVELS, (off, nominal, stress)))
    return dataclasses.field(default=None, metadata={"levels": levels, "mark": mark, "source": source})


@dataclass(frozen=True)
class RealityConfig:
    """What separates the simulated robots from the Robotarium's, component by component.

    ``level`` names the base values (:data:`LEVELS`); any other field given overrides its
    level's value. All times are at the 0.033 s control tick. Per-robot quantities are drawn
    once per episode from the episode's seed (same seed, same draws); per-tick noise likewise.
    """

    level: str = "off"
    """Base level: ``"off"`` (the ideal world, bit for bit), ``"nominal"`` or ``"stress"``."""

    # Each field below is declared by _field(off, nominal, stress, mark, source): its value at each
    # level and its provenance, stated here alone (LEVELS, SOURCES and docs/reality.md's table are
    # made from these declarations). Its docstring says what it is and why it has those values.

    # -- pose path (true poses -> what controller, filter and policy see) -------------------------
    pose_delay_ticks: int | None = _field(
        0, 0, 1, "derived", "Vicon->MQTT every 33 ms, no timestamps (§1.1-1.2, §6 #1)"
    )
    """Minimum measurement delay (ticks): the tracker publishes every 33 ms over MQTT, without
    timestamps (§1.2, §6 #1)."""
    pose_delay_spread_ticks: int | None = _field(0, 2, 2, "derived", "{0,1,2} ticks P .25/.5/.25 (§6 #1)")
    """Extra delay per episode ~ Binomial(spread, 1/2) ticks on top of the minimum: spread 2 gives
    {0, 1, 2} with P .25/.5/.25 (§6 #1), common to the team (one message carries every pose) unless
    ``pose_per_robot``."""
    pose_delay_jitter_prob: float | None = _field(
        0.0, 0.2, 0.4, "assumed", "two unsynchronised 33 ms clocks, no timestamps (§1.1)"
    )
    """Per tick, probability that this tick's message is one tick older than the episode's delay
    (two unsynchronised 33 ms clocks, the tracker's and the script's, beat between k and k + 1
    ticks; no timestamps to tell). Common to the team (§1.1)."""
    pose_hold_prob: float | None = _field(0.0, 0.3, 0.3, "assumed", "mjlab-style hold (§6 #1)")
    """Per tick probability that the measurement is not refreshed (the last measured pose repeats;
    mjlab-style hold): common to the team (a message that did not come repeats every pose) unless
    ``pose_per_robot`` (§6 #1)."""
    pose_per_robot: bool | None = _field(
        False, False, False, "measured", "structure: one MQTT message with every pose (§1.1)"
    )
    """True: each robot's pose delay, jitter and holds are its own (the structure of the results
    committed before 2026-12-06). False (every level): common to the team, as the testbed's one
    message per tick with every pose. Structure only: it switches nothing on."""
    pose_noise_xy_m: float | None = _field(0.0, 0.001, 0.005, "assumed", "Vicon class (§1.4, §6 #8)")
    """SD of Gaussian position noise per axis per tick (m); nominal is of the Vicon class (§1.4,
    §6 #8)."""
    pose_noise_theta_rad: float | None = _field(0.0, 0.01, 0.05, "assumed", "§6 #8; V2 orientation 0.31° measured")
    """SD of Gaussian heading noise per tick (rad) (§6 #8; the V2 simulator's onboard orientation
    noise is 0.31° = 0.0054 rad, measured)."""
    pose_bias_xy_m: float | None = _field(
        0.0, 0.0005, 0.0025, "assumed", "nominal §6 #8; stress = camera 2.5 mm/px, derived (§1.4)"
    )
    """SD of a per-robot, per-episode position offset per axis (m): nominal assumed (§6 #8);
    stress derived, the older camera tracker's 2.5 mm per pixel (§1.4)."""
    pose_freeze_prob: float | None = _field(0.0, 0.002, 0.02, "assumed", "§6 #9")
    """Per robot-tick probability that tracking freezes (the last measured pose repeats for a
    run of ticks) (§6 #9)."""
    pose_freeze_mean_ticks: float | None = _field(3.0, 3.0, 10.0, "assumed", "§6 #9")
    """Mean length of a freeze (geometric, ticks >= 1) (§6 #9)."""
    pose_freeze_max_ticks: int | None = _field(
        150, 150, 30, "measured", "tracker timeout 5000 ms (§1.1); stress 30 assumed (§6 #9)"
    )
    """Longest freeze (ticks): nominal the tracker's, which drops a marker after 5000 ms
    (vicon_tracker ``timeout_millis``, §1.1); stress the proposal's "bursts up to 30" (§6 #9)."""

    # -- command path (filtered command -> what reaches the robot) --------------------------------
    command_delay_ticks: int | None = _field(0, 0, 1, "derived", "Pi poll + ISR + execute-then-sense (§1.2, §6 #2)")
    """Minimum command delay (ticks): the Pi's 16 ms poll + the ISR's 10 ms + execute-then-sense
    10 ms (§1.2, §6 #2)."""
    command_delay_spread_ticks: int | None = _field(0, 1, 1, "derived", "{0,1} / {1,2} ticks (§6 #2)")
    """Extra command delay per robot and episode ~ Binomial(spread, 1/2): spread 1 gives {0, 1}
    (nominal) or {1, 2} (stress) with equal odds (§6 #2)."""
    command_loss_prob: float | None = _field(0.0, 0.01, 0.05, "assumed", "§6 #10")
    """Per robot-tick probability that a run of lost commands starts: the robot keeps its last
    received command (§6 #10)."""
    command_loss_mean_ticks: float | None = _field(1.0, 1.0, 5.0, "assumed", "§6 #10 (stress: bursts)")
    """Mean length of a run of losses (geometric, ticks >= 1); stress has bursts (§6 #10)."""
    script_miss_prob: float | None = _field(
        0.0, 0.002, 0.02, "derived", "the deployed loop's measured compute time (§6 #11); server speed assumed"
    )
    """Per tick probability that the script's iteration overruns the 0.033 s tick (a long QP, the
    policy's inference at a step boundary): that tick no command goes out to any robot of the team
    (each keeps its last; it counts toward the brake) and the pose it reads next is one tick
    staler (a hold). Derived from the deployed loop's measured compute time (docs/reality.md)
    with the server's speed assumed."""
    script_stall_prob: float | None = _field(
        0.0, 0.0, 0.001, "assumed", "stalls and interrupts of the user's script (§1.1, §6 #11)"
    )
    """Per tick probability that the script stalls (garbage collection, I/O, the server's load):
    no command to any robot of the team for a run of ticks; a run past the brake time stops every
    robot (§1.1; CASH's server logs end in interrupts)."""
    script_stall_mean_ticks: float | None = _field(10.0, 10.0, 10.0, "assumed", "shorter than the brake (§6 #11)")
    """Mean length of a stall (geometric, ticks >= 1; 10 ticks = 0.33 s)."""
    command_brake_after_s: float | None = _field(0.5, 0.5, 0.5, "measured", "GTernal communicationCheck(500) (§1.1)")
    """A robot without a command for this long brakes (v = ω = 0) until one arrives: it brakes
    from the tick during which the timeout expires (15 lost ticks at 0.5 s). The GTernal firmware's
    ``communicationCheck(500)`` (§1.1)."""

    # -- motors (wheel speeds the robot asks for -> wheel speeds it gets) -------------------------
    motor_tau_min_s: float | None = _field(0.0, 0.04, 0.08, "derived", "firmware PI + slew toy model (§1.2, §6 #3)")
    """First-order wheel-speed lag: time constant per wheel and episode ~ U(min, max) (s); 0 =
    no lag. Derived from the firmware's PI loop and slew (a toy model: 60–80 ms to 63 %, §1.2,
    §6 #3)."""
    motor_tau_max_s: float | None = _field(0.0, 0.08, 0.12, "derived", "firmware PI + slew toy model (§1.2, §6 #3)")
    """Upper end of the lag's time constant (s); see ``motor_tau_min_s``."""
    motor_accel_limit_radps2: float | None = _field(
        0.0, 200.0, 200.0, "derived", "PWM slew 50/255 per 10 ms (§1.1, §6 #3)"
    )
    """Largest change of a wheel's speed (rad/s per s); 0 = no limit. The firmware's PWM slew of
    50/255 per 10 ms: 12.5 rad/s in ~60 ms (§1.1, §6 #3)."""
    motor_dead_zone_radps: float | None = _field(
        0.0, 1.9, 3.0, "derived", "guide minimum speed 0.03 m/s (§1.1, §6 #4); stress assumed"
    )
    """A wheel asked for less than this speed (rad/s) does not turn. Nominal: 0.03 m/s at the
    rim, the user guide's minimum speed (§1.1, §6 #4); stress assumed."""
    wheel_gain_mean: float | None = _field(1.0, 1.0, 1.0, "assumed", "calibrated wheel radius; a profile measures it")
    """Every wheel's mean speed gain (reached / asked for): a fleet uniformly slow or fast (worn
    tyres, a wheel radius unlike the firmware's). 1 at every level: the firmware's radius is taken as
    calibrated; a calibration profile writes the speed gain it measured (``comat calibrate``)."""
    wheel_gain_spread: float | None = _field(0.0, 0.03, 0.07, "assumed", "guide Fig. 13 curved open-loop path (§6 #5)")
    """Per wheel and episode, speed gain ~ U(1 - spread, 1 + spread) (radius, calibration):
    a straight command drives a curve, as in the user guide's Fig. 13 (§6 #5)."""
    top_speed_derate_min: float | None = _field(
        1.0, 0.9, 0.75, "assumed", "battery thresholds, PID saturation (§1.1, §6 #6)"
    )
    """Per robot and episode, the reachable wheel speed is 12.5 rad/s × U(min, 1) (battery,
    wear); 1 = none (the firmware's battery thresholds, PID saturation: §1.1, §6 #6)."""
    wheel_disturbance_radps: float | None = _field(0.0, 0.5, 2.0, "assumed", "§6 #7")
    """Stationary SD of a per-wheel Ornstein–Uhlenbeck speed disturbance on a turning wheel
    (rad/s) (§6 #7)."""
    wheel_disturbance_corr_s: float | None = _field(0.2, 0.2, 0.2, "assumed", "§6 #7")
    """Correlation time of that disturbance (s) (§6 #7)."""
    wheel_disturbance_bound_radps: float | None = _field(
        5.0, 5.0, 5.0, "measured", "robust barrier disturbance=5 rad/s, a design bound (§1.1)"
    )
    """The disturbance is clipped to ± this (rad/s): measured as a design bound (the Robotarium's
    robust barrier, ``disturbance=5``, §1.1, §6 #7)."""

    # -- faults -----------------------------------------------------------------------------------
    fault_prob: float | None = _field(0.0, 0.0, 0.0, "assumed", "opt-in; CASH-MARBLER motor_failure (§2.3, §6 #6)")
    """Probability that an episode has one faulty robot (drawn uniformly from the team). 0 at
    every level: faults change the team under the policy, an experiment of its own (set it to
    1 to run CASH-MARBLER's ``motor_failure``, §2.3)."""
    fault_speed_fraction: float | None = _field(
        0.25, 0.25, 0.25, "measured", "CASH-MARBLER motor_failure setting (§2.3)"
    )
    """The faulty robot's wheels turn at this fraction of their speed from the fault on (0 =
    the motors fail): CASH-MARBLER's ``motor_failure`` setting (§2.3)."""
    fault_start_min_s: float | None = _field(0.0, 0.0, 0.0, "assumed", "comat's choice (§6 #6)")
    """The fault begins at a time ~ U(min, max) after the episode's start (s)."""
    fault_start_max_s: float | None = _field(60.0, 60.0, 60.0, "assumed", "within the first minute (§6 #6)")
    """Upper end of the fault's start time (s): within the first minute (both tasks' horizons are
    longer, PCP 77 s, HMT 171 s)."""
    fault_known: bool | None = _field(False, False, False, "assumed", "comat's choice (§6 #6)")
    """Whether the faulty robot's capability vector reports its new speed (known) or not
    (hidden). The layer only carries the flag (:attr:`RealityLayer.speed_fraction` holds the
    factor); the env decides what a capability vector says."""

    # -- start ------------------------------------------------------------------------------------
    start_xy_m: float | None = _field(
        0.0, 0.05, 0.05, "measured", "V2 initializer at_pose radial tolerance (§1.3, §6 #12)"
    )
    """A robot starts up to this far from its requested position (uniform in the disc of this
    radius, m: the start-up drive's radial tolerance, the V2 initializer's ``at_pose``, a norm,
    §1.3, §6 #12)."""
    start_theta_rad: float | None = _field(0.0, 0.2, 0.2, "measured", "V2 initializer at_pose tolerance (§1.3, §6 #12)")
    """Heading start error, uniform ± this (rad): the V2 initializer's ``at_pose`` tolerance (§1.3)."""

    # -- physics (wheels tier only: the unicycle tier has no contacts or masses to vary) ----------
    floor_friction_min: float | None = _field(
        0.0, 0.6, 0.4, "assumed", "peers' ranges scaled to a 0.1 kg robot (§3.8, §6 #13)"
    )
    """Per robot and episode, the friction between its wheels and the floor ~ U(min, max) (the
    model's own is 1.5); max 0 = unchanged. MuJoCo Playground's, legged_gym's and Isaac Lab's
    ranges scaled to a 0.1 kg robot (§3.8, §6 #13)."""
    floor_friction_max: float | None = _field(
        0.0, 1.5, 1.5, "assumed", "peers' ranges scaled to a 0.1 kg robot (§3.8, §6 #13)"
    )
    """Upper end of the floor friction (see ``floor_friction_min``)."""
    chassis_mass_spread: float | None = _field(0.0, 0.1, 0.1, "assumed", "peers' ×U(0.9, 1.1) (§3.8, §6 #13)")
    """Per robot and episode, the chassis mass × U(1 - spread, 1 + spread) (§6 #13)."""
    com_offset_m: float | None = _field(0.0, 0.005, 0.005, "assumed", "peers' ±5 cm scaled to a 0.11 m robot (§6 #13)")
    """Per robot and episode, the chassis centre of mass moves U(-c, c) along x and y (m) (§6 #13)."""

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
        """True when every component is neutral: the world is the ideal one (the identity layer)."""
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


_INT_FIELDS = (
    "pose_delay_ticks",
    "pose_delay_spread_ticks",
    "pose_freeze_max_ticks",
    "command_delay_ticks",
    "command_delay_spread_ticks",
)
_PROB_FIELDS = (
    "pose_hold_prob",
    "pose_delay_jitter_prob",
    "pose_freeze_prob",
    "command_loss_prob",
    "script_miss_prob",
    "script_stall_prob",
    "fault_prob",
    "fault_speed_fraction",
)
_NONNEG_FIELDS = (
    "pose_noise_xy_m",
    "pose_noise_theta_rad",
    "pose_bias_xy_m",
    "motor_tau_min_s",
    "motor_tau_max_s",
    "motor_accel_limit_radps2",
    "motor_dead_zone_radps",
    "wheel_disturbance_radps",
    "wheel_disturbance_bound_radps",
    "fault_start_min_s",
    "fault_start_max_s",
    "start_xy_m",
    "start_theta_rad",
    "floor_friction_min",
    "floor_friction_max",
    "com_offset_m",
)
_POSITIVE_FIELDS = ("command_brake_after_s", "wheel_disturbance_corr_s")
_INERT = (
    "fault_speed_fraction",
    "fault_start_min_s",
    "fault_start_max_s",
    "fault_known",
    "pose_freeze_mean_ticks",
    "pose_freeze_max_ticks",
    "command_loss_mean_ticks",
    "command_brake_after_s",
    "wheel_disturbance_corr_s",
    "wheel_disturbance_bound_radps",
    "pose_per_robot",
    "script_stall_mean_ticks",
)
"""Fields that shape a component without switching it on (a component is on through its
probability, SD, delay or range). The upper ends of ranges are not among them: a lag drawn from
[0, motor_tau_max_s] or a delay from [0, spread] ticks is on with its lower end at 0 (were they
inert, such a setting would run the ideal world while the layer's own switches said it was on)."""


def _check(c: RealityConfig) -> None:
    """One-line ValueError/TypeError naming ``RealityConfig.<field>``, the expectation and the value."""

    def fail(name: str, expected: str) -> None:
        raise ValueError(f"RealityConfig.{name} must be {expected}, got {getattr(c, name)!r}")

    for name in _INT_FIELDS:
        v = getattr(c, name)
        if isinstance(v, bool) or not isinstance(v, int) or v < 0:
            fail(name, "an integer >= 0 (ticks)")
    for name in (
        _PROB_FIELDS
        + _NONNEG_FIELDS
        + _POSITIVE_FIELDS
        + (
            "pose_freeze_mean_ticks",
            "command_loss_mean_ticks",
            "wheel_gain_mean",
            "wheel_gain_spread",
            "top_speed_derate_min",
            "chassis_mass_spread",
            "script_stall_mean_ticks",
        )
    ):
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
    if not 0.0 < c.wheel_gain_mean <= 2.0:
        fail("wheel_gain_mean", "a number in (0, 2]")
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


_FIELDS = tuple(f for f in dataclasses.fields(RealityConfig) if f.name != "level")

LEVELS: dict[str, dict[str, Any]] = {
    level: {f.name: f.metadata["levels"][level] for f in _FIELDS} for level in REALITY_LEVELS
}
"""Each level's value of every field, in the fields' order (the ``off`` values switch every
component off); made from the fields' declarations."""

SOURCES: dict[str, tuple[str, str]] = {f.name: (f.metadata["mark"], f.metadata["source"]) for f in _FIELDS}
"""Per field: (mark, source) for the documentation and the levels table of docs/reality.md; made
from the fields' declarations."""


def levels_markdown() -> str:
    """The levels table of docs/reality.md (field, nominal, stress, mark, source), made from the
    fields' declarations (:data:`LEVELS`, :data:`SOURCES`): a test keeps the page equal to it."""
    rows = ["| field | nominal | stress | mark | source |", "|---|---|---|---|---|"]
    for name in LEVELS["off"]:
        mark, source = SOURCES[name]
        rows.append(f"| `{name}` | {LEVELS['nominal'][name]} | {LEVELS['stress'][name]} | {mark} | {source} |")
    return "\n".join(rows) + "\n"


PROFILE_FORMAT = 2
"""The format ``comat calibrate`` writes a fitted profile in (its ``format`` key). 2: the intervals
of :mod:`comat.calibration.intervals` (team-wide quantities over blocks of ticks) and the pose jitter
fitted, not kept at nominal's on top of a fitted delay. A fitted profile of another format is refused
with the command that regenerates it."""

KINDS = {
    "t95": "95 % t, robots",
    "t95_runs": "95 % t, runs",
    "block95": "95 % block bootstrap, ticks",
    "chi2_95": "95 % chi-square, robots",
    "order95": "95 % smallest of robots",
    "range": "robots' range",
}
"""Each kind of interval a fitted profile states (:mod:`comat.calibration.intervals`) and how
``comat calibrate``'s table names it; part of the profile format (here, below the calibration that
writes them, so the reality layer can read a profile's intervals: :mod:`comat.reality.randomize`)."""
PARAMETER_KINDS = {
    "pose_delay_ticks": "range",
    "pose_delay_jitter_prob": "block95",
    "motor_tau_s": "t95",
    "speed_gain": "t95",
    "turn_gain": "t95",
    "tracked_ahead_m": "t95",
    "top_speed_fraction": "range",
    "top_speed_derate_min": "order95",
    "wheel_gain_spread": "chi2_95",
    "pose_noise_xy_m": "t95",
    "pose_noise_theta_rad": "t95",
    "pose_hold_prob": "block95",
    "motor_dead_zone_radps": "t95",
    "loop_tick_s": "t95_runs",
}
"""The kind each fitted parameter's interval must be (or none: too few robots or runs for one)."""


def read_profile(path: str, name: str = "reality") -> dict[str, Any]:
    """The RealityConfig fields a profile file holds (``comat calibrate --out PROFILE.yaml``: a
    mapping with a ``reality`` mapping of fields); one-line errors for a missing or foreign file.
    (:func:`comat.calibration.fit.profile_fields` makes those fields from a fit.)"""
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
            "as comat calibrate writes)"
        )
    if "fit" in data and data.get("format") != PROFILE_FORMAT:  # fitted by an earlier comat calibrate
        logs = " ".join(str(x) for x in data.get("logs") or ["LOGS..."])
        raise ValueError(
            f"{name}: profile {path!r} was fitted by an earlier comat calibrate (format "
            f"{data.get('format', 1)!r}, now {PROFILE_FORMAT}: team-wide holds had intervals over robots and "
            f"nominal's pose jitter sat on top of the fitted delay); regenerate it: comat calibrate {logs} "
            f"--out {path} --force"
        )
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
        return load(RealityConfig, read_profile(value, name), prefix=name)
    if isinstance(value, str):
        if value not in LEVELS:
            raise ValueError(
                f"{name} must be one of {list(REALITY_LEVELS)}, a RealityConfig or a mapping of its "
                f"fields, got {value!r}"
            )
        return RealityConfig(level=value)
    if isinstance(value, Mapping):
        fields = dict(value)
        return load(RealityConfig, fields, prefix=name)
    raise TypeError(
        f"{name} must be one of {list(REALITY_LEVELS)}, a RealityConfig or a mapping of its fields, "
        f"got {type(value).__name__}"
    )


def field_docs() -> dict[str, str]:
    """Each :class:`RealityConfig` field's docstring, on one line (what a profile file's header says
    of the fields it sets)."""
    tree = ast.parse(textwrap.dedent(inspect.getsource(RealityConfig)))
    body = tree.body[0].body
    docs = {}
    for node, after in itertools.pairwise(body):
        if (
            isinstance(node, ast.AnnAssign)
            and isinstance(node.target, ast.Name)
            and isinstance(after, ast.Expr)
            and isinstance(after.value, ast.Constant)
            and isinstance(after.value.value, str)
        ):
            docs[node.target.id] = " ".join(after.value.value.split())
    return docs
