"""The Robotarium arena as an ``mujoco.MjSpec``: floor, four walls, named zone sites.

The walls' inner faces lie on the arena boundary (:data:`comat.constants.ARENA_BOUNDS_M`), so
a robot centre can only leave the arena through a wall contact. Zones are sites (no collision):
they mark task areas for the viewer and for task logic that looks them up by name.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import mujoco

from comat import constants as C

__all__ = ["TASK_ZONES", "Zone", "arena_spec"]


@dataclass(frozen=True)
class Zone:
    """A named task area on the floor.

    Attributes:
        name: site name (``zone/<name>`` in the model).
        centre_m: (x, y) centre.
        half_size_m: (hx, hy) half extents for a box, or (radius, 0) for a circle.
        shape: ``"box"`` or ``"circle"``.
        rgba: display colour.
    """

    name: str
    centre_m: tuple[float, float]
    half_size_m: tuple[float, float]
    shape: str = "box"
    rgba: tuple[float, float, float, float] = (0.9, 0.8, 0.2, 0.35)

    def __post_init__(self) -> None:
        if self.shape not in ("box", "circle"):
            raise ValueError(f"Zone.shape must be 'box' or 'circle', got {self.shape!r}")
        if min(self.half_size_m[0], self.half_size_m[1] if self.shape == "box" else 1.0) <= 0:
            raise ValueError(f"Zone.half_size_m must be positive, got {self.half_size_m}")


_X0, _X1, _Y0, _Y1 = C.ARENA_BOUNDS_M
TASK_ZONES: tuple[Zone, ...] = (
    # Heterogeneous Material Transport (MARBLER MaterialTransport layout).
    Zone("hmt_material_1", (0.0, 0.0), (0.35, 0.0), "circle", (0.95, 0.75, 0.1, 0.35)),
    Zone("hmt_material_2", (1.3, 0.0), (0.3, 1.0), "box", (0.95, 0.75, 0.1, 0.35)),
    Zone("hmt_dropoff", (-1.3, 0.0), (0.3, 1.0), "box", (0.2, 0.7, 0.3, 0.35)),
    # Predator Capture Prey (MARBLER PredatorCapturePrey spawn areas).
    Zone("pcp_robot_spawn", (-0.95, 0.0), (0.45, 0.9), "box", (0.5, 0.5, 0.5, 0.25)),
    Zone("pcp_prey_area", (0.95, 0.0), (0.45, 0.9), "box", (0.3, 0.8, 0.3, 0.25)),
)
"""Zones drawn in the canonical arena; tasks may pass their own."""


def arena_spec(zones: Sequence[Zone] = TASK_ZONES) -> mujoco.MjSpec:
    """Return an MjSpec with the floor, a static ``walls`` body and one site per zone."""
    spec = mujoco.MjSpec()
    spec.modelname = "robotarium_arena"
    spec.compiler.degree = False
    world = spec.worldbody
    world.add_geom(
        name="floor",
        type=mujoco.mjtGeom.mjGEOM_PLANE,
        size=[_X1 + 0.5, _Y1 + 0.5, 0.05],
        contype=1,
        conaffinity=0,
        condim=3,
        friction=[1.0, 0.005, 0.0001],
        rgba=[0.92, 0.92, 0.92, 1.0],
    )
    world.add_light(name="top", pos=[0.0, 0.0, 3.0], dir=[0.0, 0.0, -1.0], type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL)
    walls = world.add_body(name="walls")
    t, h = C.WALL_THICKNESS_M, C.WALL_HEIGHT_M
    half_x, half_y = (_X1 - _X0) / 2.0, (_Y1 - _Y0) / 2.0
    cx, cy = (_X0 + _X1) / 2.0, (_Y0 + _Y1) / 2.0
    for name, pos, size in (
        ("wall_east", [_X1 + t, cy, h], [t, half_y + 2 * t, h]),
        ("wall_west", [_X0 - t, cy, h], [t, half_y + 2 * t, h]),
        ("wall_north", [cx, _Y1 + t, h], [half_x, t, h]),
        ("wall_south", [cx, _Y0 - t, h], [half_x, t, h]),
    ):
        walls.add_geom(
            name=name,
            type=mujoco.mjtGeom.mjGEOM_BOX,
            pos=pos,
            size=size,
            contype=2,
            conaffinity=2,
            condim=3,
            friction=[0.3, 0.005, 0.0001],
            rgba=[0.35, 0.35, 0.4, 1.0],
        )
    for zone in zones:
        if zone.shape == "circle":
            kind, size = mujoco.mjtGeom.mjGEOM_CYLINDER, [zone.half_size_m[0], 0.0005, 0.0]
        else:
            kind, size = mujoco.mjtGeom.mjGEOM_BOX, [zone.half_size_m[0], zone.half_size_m[1], 0.0005]
        world.add_site(
            name=f"zone/{zone.name}",
            type=kind,
            size=size,
            pos=[zone.centre_m[0], zone.centre_m[1], 0.0005],
            rgba=list(zone.rgba),
        )
    return spec
