"""One GRITSBot-like differential-drive robot as an ``mujoco.MjSpec``, in either dynamics tier.

Body frame: origin on the floor-parallel plane through the wheel axles (z = wheel radius), x
forward, y to the left, so the robot's pose (x, y, θ) is the body's planar position and yaw.

* ``wheels`` tier: a free-floating chassis on two hinged wheels (sphere colliders, friction
  contact with the floor, velocity-servo motors with a torque limit) and two frictionless
  casters. The robot moves only through wheel–floor friction.
* ``unicycle`` tier: the same chassis on planar joints (slide x, slide y, hinge yaw), driven by
  velocity servos acting in the body frame: forward speed v and yaw rate ω (from the same wheel
  speeds), lateral speed held at 0. Wheels are drawn but do not collide.

Collision bits (both tiers): floor ``contype=1``; wheels and casters collide with the floor
only; chassis and walls ``contype=conaffinity=2`` (robot–robot and robot–wall contacts).
"""

from __future__ import annotations

import mujoco
import numpy as np

from comat import constants as C

__all__ = ["TIERS", "planar_yaw_inertia", "robot_spec"]

TIERS = ("wheels", "unicycle")

PLANAR_RESPONSE_S = 0.011
"""Time constant of the unicycle tier's body-frame velocity servos (gain = mass / this)."""
WHEEL_SOLIMP = [0.99, 0.999, 0.001, 0.5, 2.0]
"""Wheel–floor impedance close to 1: little penetration, so the rolling radius is r (to 0.1 %)."""

_BODY_RGBA = (0.15, 0.35, 0.75, 1.0)
_WHEEL_RGBA = (0.1, 0.1, 0.1, 1.0)
_CYL = mujoco.mjtGeom.mjGEOM_CYLINDER
_SPHERE = mujoco.mjtGeom.mjGEOM_SPHERE


def _chassis_geoms(body: mujoco.MjsBody, profile: C.RobotProfile) -> None:
    r_wheel = profile.wheel_radius_m
    z_centre = C.CHASSIS_CLEARANCE_M + C.CHASSIS_HALF_HEIGHT_M - r_wheel
    body.add_geom(
        name="chassis",
        type=_CYL,
        size=[profile.radius_m, C.CHASSIS_HALF_HEIGHT_M, 0.0],
        pos=[0.0, 0.0, z_centre],
        mass=C.CHASSIS_MASS_KG,
        contype=2,
        conaffinity=2,
        condim=3,
        friction=[0.3, 0.005, 0.0001],
        rgba=list(_BODY_RGBA),
    )
    top = z_centre + C.CHASSIS_HALF_HEIGHT_M
    # Heading marker, visual only.
    body.add_geom(
        name="heading",
        type=mujoco.mjtGeom.mjGEOM_BOX,
        size=[0.02, 0.004, 0.001],
        pos=[0.03, 0.0, top + 0.001],
        contype=0,
        conaffinity=0,
        mass=0.0,
        group=1,
        rgba=[1.0, 1.0, 1.0, 1.0],
    )
    for name, x in (
        ("centre", 0.0),
        ("collision_point", C.COLLISION_OFFSET_M),
        ("projection_point", C.PROJECTION_DISTANCE_M),
    ):
        body.add_site(name=name, pos=[x, 0.0, top], size=[0.005, 0.0, 0.0], group=3)


def _wheeled_robot(spec: mujoco.MjSpec, profile: C.RobotProfile, timestep: float) -> None:
    r = profile.wheel_radius_m
    body = spec.worldbody.add_body(name="chassis", pos=[0.0, 0.0, r])
    body.add_freejoint(name="root")
    _chassis_geoms(body, profile)
    for name, x in (("front_caster", C.CASTER_OFFSET_M), ("rear_caster", -C.CASTER_OFFSET_M)):
        # condim 1 + priority 1: the caster's frictionless contact wins over the floor's condim 3.
        body.add_geom(
            name=name,
            type=_SPHERE,
            size=[C.CASTER_RADIUS_M, 0.0, 0.0],
            pos=[x, 0.0, C.CASTER_RADIUS_M - r],
            mass=0.0,
            contype=0,
            conaffinity=1,
            condim=1,
            priority=1,
            solref=[C.CASTER_SPRING_TIMECONST_S, 1.0],
            rgba=[0.6, 0.6, 0.6, 1.0],
        )
    for side, y in (("left", profile.base_length_m / 2.0), ("right", -profile.base_length_m / 2.0)):
        wheel = body.add_body(name=f"{side}_wheel", pos=[0.0, y, 0.0])
        wheel.add_joint(
            name=f"{side}_wheel",
            type=mujoco.mjtJoint.mjJNT_HINGE,
            axis=[0.0, 1.0, 0.0],
            armature=C.MOTOR_ARMATURE_KGM2,
        )
        wheel.add_geom(
            name=f"{side}_wheel",
            type=_SPHERE,
            size=[r, 0.0, 0.0],
            mass=C.WHEEL_MASS_KG,
            contype=0,
            conaffinity=1,
            condim=3,
            priority=1,
            friction=[C.WHEEL_FRICTION, 0.005, 0.0001],
            # The stiffest contact MuJoCo integrates stably at this timestep (2·dt); softer
            # contacts creep sideways in turns (lateral slip grows with the time constant).
            solref=[2.0 * timestep, 1.0],
            solimp=list(WHEEL_SOLIMP),
            rgba=list(_WHEEL_RGBA),
        )
        act = spec.add_actuator(
            name=f"{side}_motor",
            target=f"{side}_wheel",
            trntype=mujoco.mjtTrn.mjTRN_JOINT,
        )
        act.set_to_velocity(kv=C.MOTOR_KV_NMS)
        act.ctrllimited = 1
        act.ctrlrange = [-profile.max_wheel_velocity_radps, profile.max_wheel_velocity_radps]
        act.forcelimited = 1
        act.forcerange = [-C.MOTOR_TORQUE_LIMIT_NM, C.MOTOR_TORQUE_LIMIT_NM]


def _planar_robot(spec: mujoco.MjSpec, profile: C.RobotProfile) -> None:
    r = profile.wheel_radius_m
    body = spec.worldbody.add_body(name="chassis", pos=[0.0, 0.0, r])
    body.add_joint(name="x", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[1.0, 0.0, 0.0])
    body.add_joint(name="y", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[0.0, 1.0, 0.0])
    body.add_joint(name="yaw", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0.0, 0.0, 1.0])
    _chassis_geoms(body, profile)
    for side, y in (("left", profile.base_length_m / 2.0), ("right", -profile.base_length_m / 2.0)):
        body.add_geom(
            name=f"{side}_wheel",
            type=_CYL,
            size=[r, 0.004, 0.0],
            pos=[0.0, y, 0.0],
            quat=[np.sqrt(0.5), np.sqrt(0.5), 0.0, 0.0],
            mass=C.WHEEL_MASS_KG,  # same total mass as the wheeled tier
            contype=0,
            conaffinity=0,
            group=1,
            rgba=list(_WHEEL_RGBA),
        )
    # Velocity servos in the body frame, through the centre site (gear acts in the site frame).
    # No force limit: a saturated servo is integrated explicitly and would chatter; the gains
    # give a response time of PLANAR_RESPONSE_S on the robot's mass and yaw inertia.
    mass = C.CHASSIS_MASS_KG + 2 * C.WHEEL_MASS_KG
    for name, gear in (("forward", [1, 0, 0, 0, 0, 0]), ("lateral", [0, 1, 0, 0, 0, 0])):
        act = spec.add_actuator(name=name, target="centre", trntype=mujoco.mjtTrn.mjTRN_SITE, gear=gear)
        act.set_to_velocity(kv=mass / PLANAR_RESPONSE_S)
    act = spec.add_actuator(name="yaw", target="yaw", trntype=mujoco.mjtTrn.mjTRN_JOINT)
    act.set_to_velocity(kv=planar_yaw_inertia(profile) / PLANAR_RESPONSE_S)


def planar_yaw_inertia(profile: C.RobotProfile) -> float:
    """Yaw inertia (kg·m²) of the unicycle-tier body: chassis cylinder plus the two wheels."""
    return 0.5 * C.CHASSIS_MASS_KG * profile.radius_m**2 + 2 * C.WHEEL_MASS_KG * (profile.base_length_m / 2) ** 2


def robot_spec(
    tier: str = "wheels", profile: C.RobotProfile = C.DEFAULT_PROFILE, timestep: float = C.CONTROL_DT_S / 4
) -> mujoco.MjSpec:
    """Return a fresh MjSpec holding one robot (root body ``chassis``) of the given tier.

    Args:
        tier: ``"wheels"`` (free chassis on friction-driven wheels) or ``"unicycle"`` (planar
            joints, velocity-driven).
        profile: robot geometry and limits (:data:`comat.constants.PROFILES`).
        timestep: physics timestep the robot will run at (sets the wheel contact stiffness).
    """
    if tier not in TIERS:
        raise ValueError(f"tier must be one of {TIERS}, got {tier!r}")
    spec = mujoco.MjSpec()
    spec.modelname = f"{profile.name}_{tier}"
    spec.compiler.degree = False
    if tier == "wheels":
        _wheeled_robot(spec, profile, timestep)
    else:
        _planar_robot(spec, profile)
    return spec
