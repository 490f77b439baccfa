"""Robotarium submission folder from a COMAT policy (or the scripted one): ``export_submission``
(checked offline by :mod:`sim2real.check`).

=====================  ========================================================================
Folder (flat)          ``main.py`` and ``rps_compat.py`` (``sim2real/templates/``, verbatim: the
                       second lets legacy ``rps`` draw under matplotlib >= 3.10), ``runtime.py``
                       (``sim2real/runtime.py``, verbatim) and ``comat_schema.py``
                       (``comat/models/comat_schema.py``, verbatim: the description of COMAT's
                       arrays the runtime reads), ``task_logic.py``
                       (``comat/task_logic.py``, verbatim: numpy only, so the very file the
                       MuJoCo envs run is shipped) and ``task_<name>.py`` (the task's own logic,
                       ``comat/tasks/<name>.py``, verbatim but for its import of ``task_logic``),
                       ``deployed_loop.py``
                       (``comat/safety/deployed.py``, verbatim: the per-iteration loop and
                       comat's filter, numpy + cvxopt), ``weights.npy`` (pickle-free weights),
                       ``submission_config.py`` (``CONFIG = {...}``: policy, task (its module,
                       class and options), team, start poses, the task's layout (PCP: prey),
                       ticks per step, controller constants, the filter and its
                       settings, and what to declare on the Robotarium's form:
                       ``duration_s`` (:func:`declared_duration_s`) and ``robots``); the scripted
                       policy's folder has no ``runtime.py``, ``comat_schema.py`` and
                       ``weights.npy``
File types             ``.py`` and ``.npy`` only (the Robotarium accepts .m .jpg .jpeg .png .gif
                       .tiff .bmp .py .mat .npy .mexa64 and no folders; JSON is not accepted,
                       hence the config as a Python literal)
Policy                 a COMAT checkpoint or policy file (``checkpoint.pt`` / ``policy.pt`` of
                       ``comat train --algo comat``), a ``comat.models.comat.Comat`` module,
                       or ``"heuristic"``: the scripted reference policy of ``task_logic`` (it
                       reads the task state, which the script keeps anyway; for checking a
                       deployment end to end); other
                       algorithms raise ValueError
Start poses            (3, N) float, default: the MuJoCo env's own spawn (and task layout) for
                       ``seed``; must be >= WALL_MARGIN_M inside the arena, >= MIN_SPACING_M apart
Team                   TeamSpec or mapping, 1..20 robots (the Robotarium's hardware limit)
Duration               ``duration_s`` = (horizon ``horizon_s``: the task's steps × ticks per
                       step × 0.033 s, + the start-up drive's bound ``startup_drive_s``:
                       STARTUP_DRIVE_S + STARTUP_DRIVE_PER_ROBOT_S × robots) × 1.15, rounded
                       up to 10 s; ``comat export`` prints ``declare N s and K robots``; more
                       than 900 s (15 min) is an error
Atomicity              written into ``<out>.tmp-*`` next to ``out`` and renamed at the end; on any
                       error nothing is left; an existing ``out`` is an error
=====================  ========================================================================

:func:`sim2real.check.check_submission` runs a folder's ``main.py`` under ``rps`` and the same
episode in MuJoCo, and compares them.
"""

from __future__ import annotations

import hashlib
import math
import os
import pprint
import re
import shutil
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

import comat.runlog as runlog_module
import comat.safety.deployed as deployed_module
import comat.task_logic as task_logic_module
from comat import constants as C
from comat._version import __version__ as comat_version
from comat.config import SafetyConfig
from comat.control import portable_settings
from comat.envs import make_env
from comat.envs.core import WAYPOINT_GAIN
from comat.models import Comat, comat_schema
from comat.reality import resolve_reality
from comat.reality.margin import response_lag_ticks, robust_safety
from comat.rl import POLICY_FORMAT, load_trained, policy_modules
from comat.tasks import task_entry
from comat.team import TeamSpec
from sim2real.weights import export_weights

__all__ = [
    "ACCEPTED_EXTENSIONS",
    "ALLOWED_IMPORTS",
    "EXPORT_SPACING_M",
    "FILTERS",
    "HEURISTIC_FILES",
    "MIN_SPACING_M",
    "SHIPPED_FILES",
    "WALL_MARGIN_M",
    "declared_duration_s",
    "export_submission",
    "filter_config",
    "layout_of",
    "load_config",
    "shipped_code",
    "shipped_task_module",
    "startup_drive_s",
    "submission_files",
    "task_module_name",
]

HERE = Path(__file__).resolve().parent
ACCEPTED_EXTENSIONS = (".m", ".jpg", ".jpeg", ".png", ".gif", ".tiff", ".bmp", ".py", ".mat", ".npy", ".mexa64")
"""File types the Robotarium's upload form accepts (reference §3.2)."""
ALLOWED_IMPORTS = frozenset({"numpy", "scipy", "matplotlib", "rps", "cvxopt"})
"""Third-party top-level packages shipped code may import (besides the standard library and the
folder's own modules)."""
SHIPPED_FILES = (
    "main.py",
    "rps_compat.py",
    "runtime.py",
    "comat_schema.py",
    "task_logic.py",
    "deployed_loop.py",
    "run_log.py",
    "submission_config.py",
    "weights.npy",
)
"""The folder of a COMAT policy."""
HEURISTIC_FILES = (
    "main.py",
    "rps_compat.py",
    "task_logic.py",
    "deployed_loop.py",
    "run_log.py",
    "submission_config.py",
)
"""The folder of the scripted policy."""
FILTERS = ("comat", "robotarium")
"""What an export's main.py filters its commands with: comat's filter (the default: it meets the
safety battery at ``nominal`` with faults, docs/safety.md) or the installed rps's own barrier."""


def submission_files(policy: str, task_module: str | None = None) -> tuple[str, ...]:
    """The files of a folder whose CONFIG["policy"] is ``policy`` ("comat" or "heuristic") and whose
    task logic is the module ``task_module`` (None: a folder exported before tasks had modules of
    their own, whose task_logic.py held every task)."""
    files = HEURISTIC_FILES if policy == "heuristic" else SHIPPED_FILES
    return files if task_module is None else (*files, f"{task_module}.py")


def shipped_code(task: str, policy: str = "comat") -> dict[str, bytes]:
    """Every ``.py`` file an export of ``task`` for ``policy`` ("comat" or "heuristic") ships but the
    generated ``submission_config.py``, by name: the bytes :func:`export_submission` writes (verbatim
    copies; the task's module with its import of ``comat.task_logic`` made local)."""
    if policy not in ("comat", "heuristic"):
        raise ValueError(f"policy must be 'comat' or 'heuristic', got {policy!r}")
    sources = {
        "main.py": HERE / "templates" / "main.py",
        "rps_compat.py": HERE / "templates" / "rps_compat.py",
        "runtime.py": HERE / "runtime.py",
        "comat_schema.py": Path(comat_schema.__file__),
        "task_logic.py": Path(task_logic_module.__file__),
        "deployed_loop.py": Path(deployed_module.__file__),
        "run_log.py": Path(runlog_module.__file__),
    }
    module = task_module_name(task)
    code = {name: sources[name].read_bytes() for name in submission_files(policy, module) if name in sources}
    code[f"{module}.py"] = shipped_task_module(type(_task(task))).encode()
    return code


def task_module_name(task: str) -> str:
    """The file name (no ``.py``) a task's logic ships under: ``task_<name>``."""
    return f"task_{task}"


def shipped_task_module(logic: type) -> str:
    """The source of ``logic``'s module as an export ships it: verbatim but for its import of
    ``comat.task_logic``, which becomes ``task_logic`` (the copy beside it)."""
    import sys

    source = Path(sys.modules[logic.__module__].__file__).read_text()
    shipped = source.replace("from comat.task_logic import", "from task_logic import")
    if re.search(r"^\s*(from|import)\s+(comat|sim2real)\b", shipped, re.MULTILINE):
        raise ValueError(
            f"task {logic.name!r}: its module {logic.__module__} imports comat beyond comat.task_logic "
            "(an export ships it alone: numpy and task_logic only)"
        )
    return shipped


def layout_of(config: Mapping) -> dict:
    """The task layout an export's CONFIG holds (before task modules: PCP's ``prey`` alone)."""
    if "layout" in config:
        return dict(config["layout"])
    return {"prey": config["prey"]} if config.get("prey") else {}


MIN_SPACING_M = 0.40
"""Start-pose centres at least this far apart. The V2 simulator (and the Robotarium) first drives
the robots from their chargers to the start poses under ``create_uni_barrier_certificate``: points
0.05 m ahead of the axles kept >= 0.25 m apart (safety radius 0.15 + 2 × 0.05), i.e. centres
>= 0.35 m for any headings; closer poses are never reached. 0.05 m more as margin."""
EXPORT_SPACING_M = 0.45
"""Spacing of the export's own start poses, used where the env's spawn (0.3 m) is closer than
MIN_SPACING_M: dense teams (12+ robots) and the occasional close pair of a smaller team."""
SPACING_TOL_M = 1e-6
"""Spacing checks accept this much rounding (a 0.3 m grid gives 0.29999999999999993)."""
WALL_MARGIN_M = 0.1
"""Start poses must be this far inside the arena."""
MAX_ROBOTS = C.MAX_ROBOTS_HARDWARE
MAX_EPISODE_S = 600.0
"""Longest episode exported (s of Robotarium time): well inside the 15-minute experiment limit."""


def startup_drive_s(robots: int) -> float:
    """Bound on the start-up drive of ``robots`` robots to an export's start poses (s):
    ``STARTUP_DRIVE_S + STARTUP_DRIVE_PER_ROBOT_S · robots`` (see :mod:`comat.constants`)."""
    return C.STARTUP_DRIVE_S + C.STARTUP_DRIVE_PER_ROBOT_S * robots


def declared_duration_s(horizon_s: float, robots: int) -> int:
    """The duration to declare for an episode of at most ``horizon_s`` seconds of loop with ``robots``
    robots: (horizon + start-up drive bound) × (1 + DURATION_MARGIN), rounded up to DURATION_STEP_S."""
    step = C.DURATION_STEP_S
    return int(math.ceil((horizon_s + startup_drive_s(robots)) * (1 + C.DURATION_MARGIN) / step - 1e-9) * step)


# -- inputs ----------------------------------------------------------------------------------------
def _comat_model(checkpoint_or_policy, task: str):
    """The torch Comat module of a checkpoint or policy file (``policy.pt``) path or of a Comat instance."""
    if isinstance(checkpoint_or_policy, (str, Path)):
        data = load_trained(checkpoint_or_policy)
        noun = "policy file" if data["format"] == POLICY_FORMAT else "checkpoint"
        if data["algo"] != "comat":
            raise ValueError(
                f"export supports COMAT checkpoints and policy files (and the scripted 'heuristic') only: "
                f"{str(checkpoint_or_policy)!r} is a {data['algo']!r} {noun} (expected algo 'comat')"
            )
        if data["task"] != task:
            raise ValueError(f"{noun} {str(checkpoint_or_policy)!r} is for task {data['task']!r}, expected {task!r}")
        modules, _config = policy_modules(data, checkpoint_or_policy)
        return modules["policy"]

    if isinstance(checkpoint_or_policy, Comat):
        return checkpoint_or_policy.eval()
    raise TypeError(
        f"checkpoint_or_policy must be a COMAT checkpoint path, a Comat model or 'heuristic', "
        f"got {type(checkpoint_or_policy).__name__} (export supports COMAT and the scripted policy only)"
    )


def _team(team: Any, task: str) -> TeamSpec:
    if isinstance(team, Mapping):
        team = TeamSpec.from_dict({"task": task, **team})
    if not isinstance(team, TeamSpec):
        raise TypeError(f"team must be a TeamSpec or a mapping with 'robots', got {type(team).__name__}")
    if team.task != task:
        raise ValueError(f"team is a {team.task!r} team, expected a {task!r} team")
    if team.size > MAX_ROBOTS:
        raise ValueError(f"team must have at most {MAX_ROBOTS} robots (Robotarium hardware limit), got {team.size}")
    return team


def _task(task: str):
    return task_entry(task).logic()


def check_start_poses(poses: Any, n: int) -> np.ndarray:
    """Start poses as float (3, n), inside the arena by WALL_MARGIN_M, >= MIN_SPACING_M apart."""
    try:
        p = np.array(poses, dtype=float)
    except (TypeError, ValueError) as err:
        raise ValueError(f"start_poses must be a numeric (3, {n}) array, got {poses!r}") from err
    if p.shape != (3, n) or not np.isfinite(p).all():
        raise ValueError(
            f"start_poses must be a finite (3, {n}) array (x, y, θ rows, one column per robot), got shape {p.shape}"
        )
    x0, x1, y0, y1 = C.ARENA_BOUNDS_M
    m = WALL_MARGIN_M
    outside = (p[0] < x0 + m) | (p[0] > x1 - m) | (p[1] < y0 + m) | (p[1] > y1 - m)
    if outside.any():
        i = int(np.flatnonzero(outside)[0])
        raise ValueError(
            f"start_poses: robot {i} at ({p[0, i]:.3f}, {p[1, i]:.3f}) must be >= {m} m inside the "
            f"arena x [{x0}, {x1}], y [{y0}, {y1}]"
        )
    if n > 1:
        d = np.hypot(p[0][:, None] - p[0][None], p[1][:, None] - p[1][None]) + np.eye(n) * 1e9
        i, j = np.unravel_index(np.argmin(d), d.shape)
        if d[i, j] < MIN_SPACING_M - SPACING_TOL_M:
            raise ValueError(
                f"start_poses: robots {min(i, j)} and {max(i, j)} are {d[i, j]:.3f} m apart, "
                f"expected >= {MIN_SPACING_M} m"
            )
    p[2] = np.arctan2(np.sin(p[2]), np.cos(p[2]))
    return p


def mujoco_start(task: str, team: TeamSpec, seed: int, tier: str = "unicycle") -> tuple[np.ndarray, dict]:
    """The MuJoCo env's spawn for ``seed``: start poses (3, N) and the task's layout (PCP: its
    prey; :meth:`comat.task_logic.TaskLogic.layout`).

    Where two of the env's robots start closer than MIN_SPACING_M (the Robotarium's start-up
    drive could not reach them), the robots are placed again in the task's spawn area
    EXPORT_SPACING_M apart (seeded by ``seed``; the layout stays)."""

    env = make_env(task_entry(task).env_id, team=team, tier=tier)
    env.reset(seed=seed)
    poses = env.core.poses()[0, : team.size].T.copy()
    prey = env.core.task.layout(env.core.state, 0)
    if _min_spacing(poses) < MIN_SPACING_M - SPACING_TOL_M:
        rng = np.random.default_rng([seed, team.size, 2026])
        poses = env.core.task.spawn(rng, team.size, spacing=EXPORT_SPACING_M).T.copy()
    return poses, prey


def _min_spacing(poses: np.ndarray) -> float:
    """Smallest centre distance of start poses (3, N) (inf for one robot)."""
    n = poses.shape[1]
    if n < 2:
        return float("inf")
    d = np.hypot(poses[0][:, None] - poses[0][None], poses[1][:, None] - poses[1][None]) + np.eye(n) * 1e9
    return float(d.min())


# -- export ----------------------------------------------------------------------------------------
def filter_config(filter_name: str, filter_reality: Any) -> dict:
    """The CONFIG entries of an export's filter: ``filter``, and for comat's its settings, robust
    to the reality level (or profile) ``filter_reality`` as comat's own filter is (the simulator's
    wheel constants replace the profile's at run time), its response lag (ticks) and whether it keeps
    right (as comat's own loop does: under a reality layer, not at ``off``)."""
    if filter_name not in FILTERS:
        raise ValueError(f"--filter must be one of {list(FILTERS)}, got {filter_name!r}")
    if filter_name == "robotarium":
        return {"filter": "robotarium"}

    reality = resolve_reality(filter_reality, "filter_reality")
    profile = C.DEFAULT_PROFILE
    cfg = robust_safety(SafetyConfig(), reality, profile)
    lag = response_lag_ticks(reality, profile)
    level = filter_reality if isinstance(filter_reality, str) else reality.level
    return {
        "filter": "comat",
        "filter_reality": level,
        "filter_lag_ticks": lag,
        "filter_keep_right": not reality.is_off,
        "filter_settings": {k: float(v) for k, v in portable_settings(cfg, profile).items()},
    }


def _config(
    policy: str, task: str, team: TeamSpec, poses: np.ndarray, layout: dict, ticks: int, seed: int, filters: dict
) -> dict:
    logic = task_entry(task).logic
    return {
        "policy": policy,
        "task": task,
        "env_id": task_entry(task).env_id,
        "task_module": task_module_name(task),
        "task_class": logic.__name__,
        "task_options": logic.layout_options(layout),
        "seed": int(seed),
        "types": [r.type for r in team.robots],
        "capabilities": [[float(c) for c in r.capabilities] for r in team.robots],
        "start_poses": [[float(v) for v in row] for row in poses],
        "layout": layout,
        "ticks_per_step": int(ticks),
        "projection_distance_m": float(C.PROJECTION_DISTANCE_M),
        "waypoint_gain": float(WAYPOINT_GAIN),
        "max_speed_mps": 0.2,
        "wheel_radius_m": float(C.DEFAULT_PROFILE.wheel_radius_m),
        "base_length_m": float(C.DEFAULT_PROFILE.base_length_m),
        "max_wheel_radps": 0.999 * float(C.DEFAULT_PROFILE.max_wheel_velocity_radps),
        "collision_offset_m": float(C.COLLISION_OFFSET_M),
        "collision_distance_m": 0.135,
        "min_spacing_m": MIN_SPACING_M - SPACING_TOL_M,
        "wall_margin_m": WALL_MARGIN_M - 1e-9,
        **filters,
    }


def _robotarium_timing(task_obj, ticks_per_step: int | None, robots: int) -> tuple[int, float, int]:
    """``(ticks per step, episode seconds, declared seconds)`` on the Robotarium for ``robots`` robots;
    ValueError where the episode or the whole experiment would not fit the Robotarium's limits."""
    ticks = task_obj.ticks_per_step if ticks_per_step is None else ticks_per_step
    if isinstance(ticks, bool) or not isinstance(ticks, int) or ticks < 1:
        raise ValueError(f"ticks_per_step must be a positive integer, got {ticks!r}")
    episode_s = task_obj.horizon * ticks * C.CONTROL_DT_S
    if episode_s > MAX_EPISODE_S:
        raise ValueError(
            f"ticks_per_step={ticks}: a {task_obj.horizon}-step episode would take {episode_s:.0f} s on "
            f"the Robotarium, expected <= {MAX_EPISODE_S:.0f} s (experiments may take up to 15 min, "
            f"with the drive to the start poses)"
        )
    duration = declared_duration_s(episode_s, robots)
    if duration > C.MAX_EXPERIMENT_S:
        raise ValueError(
            f"ticks_per_step={ticks}: {robots} robots and a {episode_s:.0f} s episode would declare "
            f"{duration} s, expected <= {C.MAX_EXPERIMENT_S:.0f} s (the Robotarium's 15 minutes, start-up drive "
            "included)"
        )
    return ticks, episode_s, duration


def export_submission(
    checkpoint_or_policy,
    task: str,
    team: Any,
    out_dir,
    start_poses: Any = None,
    seed: int = 0,
    ticks_per_step: int | None = None,
    filter_name: str = "comat",
    filter_reality: Any = "nominal",
) -> Path:
    """Write a flat Robotarium submission folder ``out_dir`` (see the module docstring).

    Args:
        checkpoint_or_policy: COMAT checkpoint or policy file path, a ``Comat`` model, or ``"heuristic"`` (the
            scripted policy).
        task: a registered task's name (``comat tasks``).
        team: TeamSpec or ``{"robots": [...]}``, 1..20 robots.
        out_dir: folder to create (must not exist).
        start_poses: (3, N) x, y, θ; default the MuJoCo env's spawn for ``seed``.
        seed: seed of the default spawn and the task's layout (PCP: prey).
        ticks_per_step: Robotarium iterations per env step (default the task's: PCP 29, HMT 74).
        filter_name: "comat" (comat's filter, shipped in deployed_loop.py) or "robotarium" (the
            installed rps's own barrier).
        filter_reality: the reality level or profile comat's filter is made robust to.

    Returns:
        The folder's path.
    """

    task_obj = _task(task)
    team = _team(team, task)
    filters = filter_config(filter_name, filter_reality)
    out = Path(out_dir)
    if out.exists():
        raise FileExistsError(f"out_dir {str(out)!r} already exists; choose a new folder")
    ticks, episode_s, duration = _robotarium_timing(task_obj, ticks_per_step, team.size)
    policy = "heuristic" if isinstance(checkpoint_or_policy, str) and checkpoint_or_policy == "heuristic" else "comat"
    model = None if policy == "heuristic" else _comat_model(checkpoint_or_policy, task)
    want_dim = task_obj.obs_size()
    if model is not None and model.layout.obs_dim != want_dim:
        raise ValueError(f"policy observes {model.layout.obs_dim} features, task {task!r} has {want_dim}")
    default_poses, prey = mujoco_start(task, team, seed)
    poses = check_start_poses(default_poses if start_poses is None else start_poses, team.size)

    out.parent.mkdir(parents=True, exist_ok=True)
    for stale in out.parent.glob(f".{out.name}.tmp-*"):  # left by an export killed mid-write
        shutil.rmtree(stale, ignore_errors=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.tmp-", dir=out.parent))
    try:
        for name, code in shipped_code(task, policy).items():
            (tmp / name).write_bytes(code)
        sha = "heuristic"
        if model is not None:
            export_weights(model, tmp / "weights.npy")
            sha = hashlib.sha256((tmp / "weights.npy").read_bytes()).hexdigest()
        config = {
            **_config(policy, task, team, poses, prey, ticks, seed, filters),
            "robots": team.size,
            "horizon_s": round(episode_s, 3),
            "startup_drive_s": startup_drive_s(team.size),
            "duration_s": duration,
            "policy_sha256": sha,
            "comat_version": comat_version,
        }
        text = (
            '"""Exported by comat (sim2real/export.py): the submission\'s settings."""\n\n'
            f"CONFIG = {pprint.pformat(config, sort_dicts=False, width=110)}\n"
        )
        (tmp / "submission_config.py").write_text(text)
        names = sorted(p.name for p in tmp.iterdir())
        assert names == sorted(submission_files(policy, task_module_name(task))), names
        os.chmod(tmp, 0o755)
        tmp.rename(out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return out


# -- reading a folder back ------------------------------------------------------------------------
def load_config(folder: Path) -> dict:
    import ast

    path = folder / "submission_config.py"
    try:
        tree = ast.parse(path.read_bytes().decode("utf-8"))
        for node in tree.body:
            if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "CONFIG" for t in node.targets):
                config = ast.literal_eval(node.value)
                if not isinstance(config, dict):
                    raise ValueError(f"CONFIG must be a dict, got {type(config).__name__}")
                return config
    except (SyntaxError, UnicodeDecodeError, ValueError) as err:
        where = f" (line {err.lineno})" if getattr(err, "lineno", None) else ""
        raise ValueError(
            f"{path} is not an exported submission config{where}: "
            f"{getattr(err, 'msg', None) or err}; export the folder again"
        ) from err
    raise ValueError(f"{path} has no CONFIG literal; export the folder again")
