"""MJCF generation with ``mujoco.MjSpec``: the robot (two dynamics tiers), the arena, scenes."""

from comat.mjcf.arena import TASK_ZONES, Zone, arena_spec
from comat.mjcf.robot import TIERS, robot_spec
from comat.mjcf.scene import DEFAULT_SUBSTEPS, compiled_scene, home_poses, scene_spec, write_assets

__all__ = [
    "DEFAULT_SUBSTEPS",
    "TASK_ZONES",
    "TIERS",
    "Zone",
    "arena_spec",
    "compiled_scene",
    "home_poses",
    "robot_spec",
    "scene_spec",
    "write_assets",
]
