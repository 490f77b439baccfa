"""Scenes: the arena with N robots attached under the prefix ``robot_{i}/``, and the golden files.

All robots are attached at the origin with yaw 0 (so the XML round-trips bit for bit) and
placed through ``qpos`` at reset; the ``home`` keyframe holds a non-overlapping line-up so the
files open sensibly in a viewer. Per robot, two contact sensors report how many contacts its
chassis has in total and with the walls (their difference: robot–robot contacts), so contact
events are read from ``sensordata`` in the batched path as well.
"""

from __future__ import annotations

import functools
import math
from pathlib import Path

import mujoco
import numpy as np

from comat import constants as C
from comat.mjcf.arena import TASK_ZONES, arena_spec
from comat.mjcf.robot import TIERS, robot_spec

__all__ = [
    "DEFAULT_SUBSTEPS",
    "GOLDEN_TEAM_SIZES",
    "compiled_scene",
    "home_poses",
    "physics_timestep",
    "scene_spec",
    "write_assets",
]

DEFAULT_SUBSTEPS = {"wheels": 4, "unicycle": 3}
"""Physics substeps per 0.033 s control tick, per tier (docs/physics.md, says why)."""
GOLDEN_TEAM_SIZES = (2, 4, 8)


def physics_timestep(substeps: int) -> float:
    """MuJoCo timestep (s) for ``substeps`` physics steps per control tick."""
    if not isinstance(substeps, (int, np.integer)) or isinstance(substeps, bool) or substeps < 1:
        raise ValueError(f"substeps must be a positive integer, got {substeps!r}")
    return C.CONTROL_DT_S / int(substeps)


def home_poses(n_robots: int) -> np.ndarray:
    """A non-overlapping line-up, (N, 3) [x, y, θ]: rows of robots 0.3 m apart, heading +x."""
    per_row = 10
    idx = np.arange(n_robots)
    rows = math.ceil(n_robots / per_row)
    x = -1.35 + 0.3 * (idx % per_row)
    y = 0.3 * (idx // per_row) - 0.15 * (rows - 1)
    return np.stack([x, y, np.zeros(n_robots)], axis=1)


def scene_spec(
    n_robots: int,
    tier: str = "wheels",
    profile: C.RobotProfile = C.DEFAULT_PROFILE,
    substeps: int | None = None,
) -> mujoco.MjSpec:
    """Return the MjSpec of the arena with ``n_robots`` robots of one tier.

    Args:
        n_robots: team size, >= 1 (no maximum; > 30 robots do not fit the home line-up rows
            but still compile).
        tier: ``"wheels"`` or ``"unicycle"``.
        profile: robot geometry and limits.
        substeps: physics steps per control tick; default :data:`DEFAULT_SUBSTEPS`.
    """
    if not isinstance(n_robots, (int, np.integer)) or isinstance(n_robots, bool) or n_robots < 1:
        raise ValueError(f"n_robots must be a positive integer, got {n_robots!r}")
    if tier not in TIERS:
        raise ValueError(f"tier must be one of {TIERS}, got {tier!r}")
    substeps = DEFAULT_SUBSTEPS[tier] if substeps is None else substeps
    spec = arena_spec(TASK_ZONES)
    spec.modelname = f"robotarium_{tier}_n{n_robots}"
    opt = spec.option
    opt.timestep = physics_timestep(substeps)
    opt.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    opt.solver = mujoco.mjtSolver.mjSOL_NEWTON
    # Elliptic cones with a high friction-to-normal impedance ratio: less creep in turns.
    opt.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    opt.impratio = 100.0
    for i in range(int(n_robots)):
        frame = spec.worldbody.add_frame(pos=[0.0, 0.0, 0.0])
        frame.attach_body(robot_spec(tier, profile, opt.timestep).body("chassis"), f"robot_{i}/", "")
    for i in range(int(n_robots)):
        for name, ref in (("contacts", None), ("wall_contacts", "walls")):
            sensor = spec.add_sensor(
                name=f"robot_{i}/{name}",
                type=mujoco.mjtSensor.mjSENS_CONTACT,
                objtype=mujoco.mjtObj.mjOBJ_GEOM,
                objname=f"robot_{i}/chassis",
                intprm=[1, 0, 1],  # data="found", unsorted, one slot: the number of contacts
            )
            if ref is not None:
                sensor.reftype = mujoco.mjtObj.mjOBJ_BODY
                sensor.refname = ref
    model = spec.compile()
    qpos = model.qpos0.copy()
    poses = home_poses(int(n_robots))
    for i, (x, y, _) in enumerate(poses):
        adr = model.jnt_qposadr[model.joint(f"robot_{i}/{'root' if tier == 'wheels' else 'x'}").id]
        qpos[adr : adr + 2] = (x, y)
    spec.add_key(name="home", qpos=qpos.tolist())
    return spec


@functools.lru_cache(maxsize=64)
def compiled_scene(n_robots: int, tier: str, profile_name: str, substeps: int) -> mujoco.MjModel:
    """Compiled scene, cached per (team size, tier, profile, substeps).

    The model is shared: callers must treat it as read-only.
    """
    if profile_name not in C.PROFILES:
        raise ValueError(f"profile must be one of {sorted(C.PROFILES)}, got {profile_name!r}")
    return scene_spec(n_robots, tier, C.PROFILES[profile_name], substeps).compile()


def write_assets(out_dir: str | Path) -> list[Path]:
    """Write the golden MJCF files (robot and scenes per tier, arena) into ``out_dir``.

    Returns the written paths. These files are never edited by hand: regenerate them with
    ``comat mjcf --out assets/mjcf``.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files: dict[str, str] = {"arena.xml": arena_spec().to_xml()}
    for tier in TIERS:
        files[f"robot_{tier}.xml"] = robot_spec(tier).to_xml()
        for n in GOLDEN_TEAM_SIZES:
            files[f"scene_{tier}_n{n}.xml"] = scene_spec(n, tier).to_xml()
    written = []
    for name, text in files.items():
        path = out / name
        tmp = path.with_suffix(".xml.tmp")
        tmp.write_text(text)
        tmp.replace(path)
        written.append(path)
    return written
