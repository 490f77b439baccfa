"""MuJoCo worlds (single team and batched), kinematics and Robotarium-style checks."""

from comat.sim.batch import BatchWorld
from comat.sim.kinematics import (
    diff_to_uni,
    euler_unicycle_step,
    projected_points,
    si_to_uni,
    threshold_wheels,
    uni_to_diff,
    uni_to_si,
    wrap_angle,
)
from comat.sim.violations import TickEvents, Violations
from comat.sim.world import World, points_to_wheels

__all__ = [
    "BatchWorld",
    "TickEvents",
    "Violations",
    "World",
    "diff_to_uni",
    "euler_unicycle_step",
    "points_to_wheels",
    "projected_points",
    "si_to_uni",
    "threshold_wheels",
    "uni_to_diff",
    "uni_to_si",
    "wrap_angle",
]
