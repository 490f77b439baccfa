"""Physical constants of the Robotarium and its robots: one source, with units and provenance.

Everything that models the real testbed (MJCF, simulator, safety filter, metrics, export)
imports its numbers from here. Suffixes carry the unit: ``_m``, ``_s``, ``_mps`` (m/s),
``_radps`` (rad/s), ``_kg``, ``_nm`` (N·m).

Provenance (the Robotarium's public simulator code, read at the commits below):

* Robotarium values are those of the legacy GRITSBot-era simulator
  ``robotarium/robotarium_python_simulator`` ``rps/robotarium_abc.py`` at commit ``5ec16db``
  (2025-04-25, the last legacy commit); the 2026 "V2" rewrite (commit ``b23069e``, GTernal
  robots) differs only in the axle length, kept as the :data:`GTERNAL` profile.
* Values marked *model choice* are ours: the Robotarium publishes no mass, motor torque or
  chassis height, so these are plausible figures for a ~0.1 kg, 11 cm micro robot, chosen so
  that the MuJoCo robot tracks the Robotarium's unicycle model (docs/physics.md).
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = [
    "ARENA_BOUNDS_M",
    "ARENA_X_MAX_M",
    "ARENA_X_MIN_M",
    "ARENA_Y_MAX_M",
    "ARENA_Y_MIN_M",
    "BOUNDARY_MARGIN_M",
    "COLLISION_DIAMETER_M",
    "COLLISION_OFFSET_M",
    "CONTROL_DT_S",
    "DEFAULT_PROFILE",
    "DURATION_MARGIN",
    "DURATION_STEP_S",
    "DURATION_WARN_SHARE",
    "GRITSBOT",
    "GTERNAL",
    "MAX_EXPERIMENT_S",
    "MAX_ROBOTS_HARDWARE",
    "PROFILES",
    "PROJECTION_DISTANCE_M",
    "RPS_COMMIT",
    "SAFETY_DISTANCE_M",
    "STARTUP_DRIVE_PER_ROBOT_S",
    "STARTUP_DRIVE_S",
    "RobotProfile",
]

RPS_COMMIT = "5ec16db"
"""robotarium_python_simulator commit whose constants this module mirrors (legacy API)."""

# --- Arena (rps: boundaries = [-1.6, -1, 3.2, 2], lower-left corner + width/height) ----------
ARENA_X_MIN_M = -1.6
ARENA_X_MAX_M = 1.6
ARENA_Y_MIN_M = -1.0
ARENA_Y_MAX_M = 1.0
ARENA_BOUNDS_M = (ARENA_X_MIN_M, ARENA_X_MAX_M, ARENA_Y_MIN_M, ARENA_Y_MAX_M)
"""(x_min, x_max, y_min, y_max): a robot centre outside this box is a boundary error."""

# --- Time -------------------------------------------------------------------------------------
CONTROL_DT_S = 0.033
"""One Robotarium iteration (``step()``) on hardware; our control tick."""

# --- Robotarium error model (rps ``_validate``) ------------------------------------------------
COLLISION_OFFSET_M = 0.025
"""The collision test moves each robot centre this far forward along its heading first."""
COLLISION_DIAMETER_M = 0.135
"""Two offset centres closer than this (<=) are a collision error."""

MAX_ROBOTS_HARDWARE = 20
"""Largest team the Robotarium testbed runs (user guide §2.7)."""

# --- Experiment duration (what a submission declares on the Robotarium's form) -----------------
MAX_EXPERIMENT_S = 900.0
"""An experiment "may take up to 15 minutes" (user guide §2.7.10), start-up drive included."""
STARTUP_DRIVE_S = 60.0
"""Time allowed for the robots' drive from their chargers to the start poses before the loop starts,
for up to 4 robots in lanes (a calibration run): V2's start-up (``Robotarium.initialize``, which
its docstring says is the testbed's own) took 21-29 s for 4 robots in three draws (measured,
2026-12-06); twice the longest. The legacy simulator has no drive (``robotarium_abc.py`` starts
at ``initial_conditions``: derived), but the testbed drove legacy-API scripts too in 2025
(CASH-MARBLER's server logs print V2's "BARRIER DEADLOCK DURING INITIALIZATION"), its length not
logged: assumed the same, so one duration serves both generations."""
STARTUP_DRIVE_PER_ROBOT_S = 9.0
"""Added to STARTUP_DRIVE_S per robot for a policy export, whose start poses lie anywhere in the
task's spawn area: the bound ``60 + 9 N`` s (78 s for 2 robots, 96 for 4, 132 for 8, 240 for 20)
is above every V2 start-up drive measured to exported start poses (measured, 2026-12-07: V2
``b23069e``, PCP and HMT ``size:K`` teams of 2-20 robots, 148 draws of start poses and charger
places; longest 44 s for 2 robots, 36 for 4, 130 for 8, 125 for 12, 122 for 16, 183 for 20;
medians 21-92 s). One 12-robot draw never arrived: two robots 2-3 cm from their poses kept
oscillating for 27,000 iterations (15 minutes); no duration covers that (docs/export.md)."""
DURATION_MARGIN = 0.15
"""Share added to horizon + start-up bound in the declared duration (then rounded up to
DURATION_STEP_S): a run that uses its whole horizon and the whole bound ends at 1 / 1.15 = 87 %
of it, outside the band ``export --check`` warns in (DURATION_WARN_SHARE)."""
DURATION_STEP_S = 10
"""Declared durations are rounded up to a multiple of this many seconds."""
DURATION_WARN_SHARE = 0.9
"""``comat export --check`` warns when a run took at least this share of the declared duration."""


@dataclass(frozen=True)
class RobotProfile:
    """Geometry and limits of one robot generation; derived limits are properties.

    Attributes:
        name: profile id used in configs (``"gritsbot"`` or ``"gternal"``).
        diameter_m: body diameter; also the MuJoCo chassis collision cylinder.
        wheel_radius_m: drive-wheel radius r.
        base_length_m: axle length l (distance between the wheel contact points).
        max_linear_velocity_mps: |v| limit of the Robotarium API.
        rps_source: where the numbers come from.
    """

    name: str
    diameter_m: float
    wheel_radius_m: float
    base_length_m: float
    max_linear_velocity_mps: float
    rps_source: str

    @property
    def radius_m(self) -> float:
        """Body radius (m)."""
        return self.diameter_m / 2.0

    @property
    def max_wheel_velocity_radps(self) -> float:
        """Per-wheel limit v_max / r = 12.5 rad/s; rps clips each wheel to it in ``step()``."""
        return self.max_linear_velocity_mps / self.wheel_radius_m

    @property
    def max_angular_velocity_radps(self) -> float:
        """rps's ω limit, 2·v_max/diameter ≈ 3.64 rad/s (rps uses the diameter, not l)."""
        return 2.0 * self.max_linear_velocity_mps / self.diameter_m

    @property
    def max_turn_rate_radps(self) -> float:
        """Fastest turn on the spot the wheels allow, 2·r·φ̇_max / l (rad/s)."""
        return 2.0 * self.wheel_radius_m * self.max_wheel_velocity_radps / self.base_length_m


GRITSBOT = RobotProfile(
    name="gritsbot",
    diameter_m=0.11,
    wheel_radius_m=0.016,
    base_length_m=0.105,
    max_linear_velocity_mps=0.2,
    rps_source=f"rps/robotarium_abc.py @ {RPS_COMMIT} (legacy, GRITSBot)",
)
GTERNAL = RobotProfile(
    name="gternal",
    diameter_m=0.11,
    wheel_radius_m=0.016,
    base_length_m=0.11,
    max_linear_velocity_mps=0.2,
    rps_source="rps/robotarium_abc.py @ b23069e (V2.0, GTernal)",
)
PROFILES = {p.name: p for p in (GRITSBOT, GTERNAL)}
DEFAULT_PROFILE = GRITSBOT

# --- Safety-filter geometry (our choice, derived from the numbers above) -----------------------
PROJECTION_DISTANCE_M = COLLISION_OFFSET_M
"""The barrier acts on the point this far ahead of the axle centre.

Equal to the Robotarium's collision offset on purpose: the points our barrier keeps apart are
exactly the points the Robotarium's collision test measures.
"""
SAFETY_DISTANCE_M = 0.20
"""Barrier distance d_s between projected points.

Offset-centre distance >= d_s = 0.20 > 0.135 (Robotarium collision test never fires, 6.5 cm
margin); axle centres >= d_s - 2·PROJECTION_DISTANCE_M = 0.15 > 0.11 (bodies never touch,
4 cm margin for the actuator lag of the wheeled tier).
"""
BOUNDARY_MARGIN_M = 0.10
"""Projected points stay this far inside the arena: body edge <= 0.025 + 0.055 = 0.08 m from
the projected point, so the chassis keeps >= 2 cm off the walls whatever its heading."""


# --- Robot body and drive (model choices: the Robotarium publishes none of these) -------------
CHASSIS_HALF_HEIGHT_M = 0.02
"""Half of the 4 cm chassis cylinder height."""
CHASSIS_CLEARANCE_M = 0.006
"""Gap between the floor and the chassis underside."""
CHASSIS_MASS_KG = 0.10
WHEEL_MASS_KG = 0.005
CASTER_RADIUS_M = 0.005
CASTER_OFFSET_M = 0.04
"""Front and rear casters sit this far ahead of / behind the axle."""
CASTER_SPRING_TIMECONST_S = 0.2
"""Contact time constant of the spring-loaded casters: soft enough that they carry ~1 % of the
weight at rest (the wheels carry the rest, so traction is not caster-limited) and stiff enough
to stop the chassis pitching over."""
WHEEL_FRICTION = 1.5
"""Sliding friction coefficient of the wheel-floor contact (silicone tyre on the arena floor).
With the weight on the wheels it allows ~15 m/s², so a full wheel reversal never slips."""
MOTOR_ARMATURE_KGM2 = 5e-5
"""Rotor inertia reflected through the gearbox (~5e-9 kg·m² rotor × 100² ratio)."""
MOTOR_KV_NMS = 0.004
"""Wheel speed-servo gain (N·m per rad/s): with the armature, a ~16 ms first-order response."""
MOTOR_TORQUE_LIMIT_NM = 0.1
"""Stall torque of each gear motor; above kv × 25 rad/s, so the servo never saturates and the
wheel response stays linear (no slip, no bang-bang)."""
WALL_HEIGHT_M = 0.10
WALL_THICKNESS_M = 0.05
