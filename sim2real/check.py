"""Checking a Robotarium submission offline: ``check_submission`` runs the folder's exact
``main.py`` under ``rps`` (the installed one, or a checkout of the 2026 V2 simulator) and the same
policy, team, start poses and task layout (PCP: prey) in comat's MuJoCo env, and compares them.

* :func:`run_rps`: ``main.py`` in a subprocess (figures off), optionally inside the reality layer
  (:mod:`sim2real.reality_rps`); its COMAT_RESULT, and where the run's log went (beside the folder);
* :func:`run_mujoco` / :func:`mujoco_twin`: the twin in MuJoCo (metrics; poses and actions per step);
* :func:`check_submission`: both, the gap between them, over ``repeats`` runs.
"""

from __future__ import annotations

import dataclasses
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np

from comat import constants as C
from comat.config import SafetyConfig
from comat.envs import make_env
from comat.envs.heuristics import heuristic_actions
from comat.measure.metrics import current_names
from comat.reality import resolve_reality
from comat.tasks import env_id
from comat.team import TeamSpec
from sim2real.export import HEURISTIC_FILES, layout_of, load_config, submission_files
from sim2real.reality_rps import DRIVES
from sim2real.runtime import ComatRuntime

__all__ = ["CheckError", "check_submission", "duration_warning", "mujoco_twin", "run_mujoco", "run_rps", "run_seconds"]


class CheckError(RuntimeError):
    """An exported folder's main.py failed or hung under rps (the message ends with its stderr's last line)."""


def _tail(stderr) -> str:
    """': <last line of stderr>' of a subprocess, '' if it wrote nothing."""
    if isinstance(stderr, bytes):
        stderr = stderr.decode(errors="replace")
    lines = [ln for ln in (stderr or "").strip().splitlines() if ln.strip()]
    return f"; its stderr ends: {lines[-1].strip()[:300]}" if lines else ""


def _main_py_environment(show_figure: bool, rps_path, max_steps: int | None) -> dict[str, str]:
    """The environment variables main.py runs with: figures, no bytecode, only the folder's modules
    and the installed packages (or the rps checkout at ``rps_path``), ``max_steps`` if given."""
    env = {
        **os.environ,
        "COMAT_SHOW_FIGURE": "1" if show_figure else "0",
        "MPLBACKEND": "Agg",
        "PYTHONDONTWRITEBYTECODE": "1",
    }
    env.pop("PYTHONPATH", None)  # only the folder's own modules and the installed packages
    if rps_path is not None:
        rps_path = Path(rps_path).resolve()
        if not (rps_path / "rps" / "__init__.py").is_file():
            raise FileNotFoundError(
                f"rps_path {str(rps_path)!r} must be a folder holding the rps package "
                f"(rps/__init__.py), e.g. a robotarium_python_simulator checkout"
            )
        env["PYTHONPATH"] = str(rps_path)
    if max_steps is not None:
        env["COMAT_MAX_STEPS"] = str(int(max_steps))
    return env


def run_rps(
    folder,
    timeout_s: float = 1800.0,
    rps_path=None,
    show_figure: bool = False,
    max_steps: int | None = None,
    reality: str | None = None,
    seed: int = 0,
    drive: str = "rps",
    python: str | None = None,
) -> dict:
    """Run ``folder/main.py`` under rps (figures off unless ``show_figure``, then on the Agg
    backend); its COMAT_RESULT dict + output.

    ``python``: the interpreter that runs main.py (default comat's own; e.g. a server's Python of
    :mod:`sim2real.server_pythons`, with its own numpy and rps; not with ``reality``, whose wrapper
    is comat's).

    ``rps_path``: a folder holding an ``rps`` package (e.g. a checkout of the 2026 V2 simulator)
    used instead of the installed one. ``max_steps``: stop after that many env steps.
    A folder whose ``main.py`` logs its run writes the log beside it, in
    ``<folder>.rps-log/run<seed>/`` (``result["run_log"]``).
    ``reality`` (a level or profile file): the reality layer around ``get_poses`` and
    ``set_velocities`` (:mod:`sim2real.reality_rps`, seeded by ``seed``; ``drive`` "unicycle" or
    "wheels" moves the robots in comat's MuJoCo world); the dict then has ``reality``, that run's
    true-pose record.
    """
    folder = Path(folder)
    if python is not None and reality is not None:
        raise ValueError("run_rps: python runs main.py alone; the reality layer needs comat's own interpreter")
    env = _main_py_environment(show_figure, rps_path, max_steps)
    env["COMAT_RPS_SEED"] = str(int(seed))  # V2's chargers and start-up drive: run k the same every time
    # The run's log goes beside the folder, never into the folder a user uploads.
    log_dir = folder.parent / f"{folder.name}.rps-log" / f"run{int(seed)}"
    if (folder / "run_log.py").is_file():
        shutil.rmtree(log_dir, ignore_errors=True)
        env["COMAT_LOG_DIR"] = str(log_dir.resolve())
    argv = [python or sys.executable, "main.py"] + ([] if show_figure else ["--no-figure"])
    if reality is not None:
        # main.py runs in the folder: a profile's path must not depend on the cwd
        profile = str(Path(reality).resolve()) if str(reality).endswith((".yaml", ".yml")) else str(reality)
        argv = [
            sys.executable,
            "-m",
            "sim2real.reality_rps",
            "--reality",
            profile,
            "--seed",
            str(int(seed)),
            "--drive",
            drive,
            "main.py",
        ] + argv[2:]
    try:
        proc = subprocess.run(argv, cwd=folder, env=env, capture_output=True, text=True, timeout=timeout_s, check=False)
    except subprocess.TimeoutExpired as err:
        raise CheckError(
            f"{folder / 'main.py'} did not finish under rps within --timeout {timeout_s:g} s" + _tail(err.stderr)
        ) from None
    if proc.returncode != 0:
        raise CheckError(f"{folder / 'main.py'} failed under rps (exit {proc.returncode})" + _tail(proc.stderr))
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("COMAT_RESULT ")]
    if not lines:
        raise CheckError(f"{folder / 'main.py'} printed no COMAT_RESULT line" + _tail(proc.stdout))
    result = current_names(json.loads(lines[-1][len("COMAT_RESULT ") :]))  # folders exported before issue 32
    if reality is not None:
        records = [ln for ln in proc.stdout.splitlines() if ln.startswith("COMAT_REALITY ")]
        if not records:
            raise CheckError(
                f"{folder / 'main.py'} under the reality layer printed no COMAT_REALITY line" + _tail(proc.stderr)
            )
        result["reality"] = json.loads(records[-1][len("COMAT_REALITY ") :])
    result["stdout"] = "\n".join(ln for ln in proc.stdout.splitlines() if not ln.startswith("COMAT_REALITY "))
    if "COMAT_LOG_DIR" in env:
        result["run_log"] = str(log_dir)
    return result


def run_mujoco(folder, tier: str = "wheels", reality: str | None = None, seed: int = 0) -> dict:
    """The same policy (the folder's weights through the numpy runtime, or the scripted policy),
    team, start poses and prey in the MuJoCo env, comat's own loop (at ``reality``, its layer
    seeded by ``seed``); its episode metrics."""
    return mujoco_twin(folder, tier, reality, seed)["metrics"]


def mujoco_twin(
    folder,
    tier: str = "wheels",
    reality: str | None = None,
    seed: int = 0,
    loop: str = "comat",
    start_poses: np.ndarray | None = None,
    max_steps: int | None = None,
) -> dict:
    """:func:`run_mujoco`'s episode with what it did: ``{"metrics", "poses" (S + 1, N, 3) true poses
    at every env step's start and at the end, "measured" (S + 1, N, 3) the poses its script saw then
    (the true ones at reality off), "actions" (S, N)}`` (a real run's simulated twin, ``comat replay``).
    ``loop``: what turns waypoints into wheel commands (:data:`comat.config.LOOPS`): comat's, or the
    one the export runs (``shipped_<rps>``, ``robotarium_<rps>``). ``start_poses`` (N, 3): where the
    robots really start (a run's logged first poses; the layer's start error is then off, as those
    poses hold the real one), instead of the folder's requested poses (which the task logic keeps
    as its starts, as main.py does). ``max_steps``: stop after that many env steps (a run stopped
    by ``COMAT_MAX_STEPS``)."""

    folder = Path(folder)
    cfg = load_config(folder)
    task = cfg["task"]
    made_for = cfg.get("env_id", f"{task}_v0")  # folders exported before versions were stored: v0
    if made_for != env_id(task):
        raise ValueError(
            f"{folder} was exported for {made_for}, but this comat has {env_id(task)} (the task's rules "
            "changed since): export the folder again"
        )
    team = TeamSpec.from_dict(
        {"task": task, "robots": [{"type": t, "capabilities": c} for t, c in zip(cfg["types"], cfg["capabilities"])]}
    )
    requested = np.array(cfg["start_poses"], dtype=float).T
    start = requested if start_poses is None else np.array(start_poses, dtype=float).reshape(requested.shape)
    layer = resolve_reality(reality, "reality")
    if start_poses is not None:  # the logged poses hold the real start error
        layer = dataclasses.replace(layer, start_xy_m=0.0, start_theta_rad=0.0)
    env = make_env(
        env_id(task),
        team=team,
        tier=tier,
        ticks_per_step=cfg["ticks_per_step"],
        reality=layer,
        safety=None if loop == "comat" else SafetyConfig(loop=loop),
    )
    env.reset(seed=cfg["seed"])
    core = env.core
    core.safe.reset(start, reality_keys=None if reality is None else [seed])
    core.task.set_layout(core.state, 0, layout_of(cfg))
    core.task.set_starts(core.state, 0, requested)  # main.py keeps the requested poses as its starts
    if cfg.get("policy", "comat") == "heuristic":

        def act_fn():
            return heuristic_actions(core)
    else:
        policy = ComatRuntime.from_file(folder / "weights.npy")

        def act_fn():
            act = np.zeros((1, core.N), dtype=np.int64)
            act[0, : team.size] = policy.action_probs(core.observe()[0, : team.size])[0]
            return act

    n = team.size
    poses, measured, actions = [core.poses()[0, :n].copy()], [core.measured_poses()[0, :n].copy()], []
    while True:
        act = act_fn()
        res = core.step(act)
        actions.append(act[0, :n].copy())
        # the poses after the step (the episode's last too: the core does not reset by itself)
        poses.append(core.poses()[0, :n].copy())
        measured.append(core.measured_poses()[0, :n].copy())
        if res.terminated[0] or res.truncated[0] or (max_steps is not None and len(actions) >= max_steps):
            return {
                "metrics": core.episode_metrics(0),
                "poses": np.stack(poses),
                "measured": np.stack(measured),
                "actions": np.stack(actions),
            }


def run_seconds(config: dict, result: dict) -> float:
    """How long the run ``result`` (main.py's COMAT_RESULT) would take on the Robotarium (s): its
    start-up drive (V2's, as simulated; the legacy simulator has none, so the folder's bound
    ``startup_drive_s`` stands for the testbed's) + its loop: iterations × 0.033 s, or the loop's
    wall time where that was longer (a loop slower than real time stretches the run; not under the
    reality layer, whose own cost is in that time)."""
    if result.get("rps") == "v2":
        startup = result.get("startup_iterations", 0) * C.CONTROL_DT_S
    else:
        startup = float(config.get("startup_drive_s", 0.0))
    wall = 0.0 if "reality" in result else float(result.get("loop_wall_s", 0.0))  # the layer's own cost aside
    return startup + max(result.get("iterations", 0) * C.CONTROL_DT_S, wall)


def duration_warning(config: dict, result: dict) -> str | None:
    """A one-line warning when the run ``result`` took at least DURATION_WARN_SHARE (90 %) of the
    ``duration_s`` its folder's ``config`` declares (None: it did not, or the folder declares none)."""
    declared = config.get("duration_s")
    if declared is None:
        return None
    took = run_seconds(config, result)
    if took < C.DURATION_WARN_SHARE * declared:
        return None
    drive = ""
    if result.get("rps") == "v2":
        startup = result.get("startup_iterations", 0) * C.CONTROL_DT_S
        drive = f"start-up drive {startup:.0f} s (bound {config.get('startup_drive_s', 0):.0f} s), "
    return (
        f"the run took {took:.0f} s of the {declared} s the folder declares ({100 * took / declared:.0f} %, "
        f"warning from {100 * C.DURATION_WARN_SHARE:.0f} %): "
        + drive
        + f"loop {result.get('iterations', 0)} iterations ({result.get('iterations', 0) * C.CONTROL_DT_S:.0f} s, "
        f"{result.get('loop_wall_s', 0):.0f} s of wall time here); declare more than {declared} s"
    )


def _submission_config(folder: Path) -> dict:
    """The settings of the exported folder ``folder``; FileNotFoundError naming the files it lacks
    among those an export of its vintage ships (older exports lack some by design)."""
    missing = [
        f for f in HEURISTIC_FILES if f not in ("deployed_loop.py", "run_log.py") and not (folder / f).is_file()
    ]  # every folder's
    if not missing:
        config = load_config(folder)
        wanted = submission_files(config.get("policy", "comat"), config.get("task_module"))
        if "filter" not in config:  # exported before issue 45: main.py had the loop inline
            wanted = tuple(f for f in wanted if f != "deployed_loop.py")
        if "run_log" not in (folder / "main.py").read_text(errors="replace"):  # exported before runs logged
            wanted = tuple(f for f in wanted if f != "run_log.py")
        runtime_py = folder / "runtime.py"
        if runtime_py.is_file() and "comat_schema" not in runtime_py.read_text(errors="replace"):
            wanted = tuple(f for f in wanted if f != "comat_schema.py")  # its runtime describes the arrays itself
        missing = [f for f in wanted if not (folder / f).is_file()]
    if missing:
        raise FileNotFoundError(f"{str(folder)!r} is not an exported submission: missing {missing}")
    return config


def _reality_totals(records: list[dict], reality: str, drive: str) -> dict:
    """The runs' true-pose records under the reality layer, summed: collisions, the first of them,
    the closest offset centres, MuJoCo contacts (None with ``drive`` rps) and boundary iterations."""
    hits = [dict(rec["first_collision"], run=k) for k, rec in enumerate(records) if rec["first_collision"]]
    closest = [
        rec["min_offset_centre_distance_m"] for rec in records if rec["min_offset_centre_distance_m"] is not None
    ]
    return {
        "level": reality,
        "drive": drive,
        "runs": len(records),
        "collision_pair_iterations": sum(rec["collision_pair_iterations"] for rec in records),
        "runs_with_collisions": len(hits),
        "first_collision": hits[0] if hits else None,
        "min_offset_centre_distance_m": min(closest) if closest else None,
        "mujoco_contact_ticks": None if drive == "rps" else sum(rec["mujoco_contact_ticks"] for rec in records),
        "boundary_iterations": sum(rec["boundary_iterations"] for rec in records),
    }


def check_submission(
    folder,
    tier: str = "wheels",
    timeout_s: float = 1800.0,
    rps_path=None,
    repeats: int = 1,
    reality: str | None = None,
    drive: str = "rps",
) -> dict:
    """{"rps": ..., "mujoco": ..., "gap": {progress_points, return}} for an exported folder (``rps_path``:
    see :func:`run_rps`).

    ``repeats`` runs main.py under rps that many times: V2 drives the robots from randomly placed
    chargers to the start poses first, so one V2 run is one random sample (the legacy simulator
    starts at the poses and repeats itself). ``rps`` then holds the means of return, steps,
    progress and finished, the worst error counts, and ``runs`` (each run's figures).

    ``reality`` (a level or profile): every run has the reality layer around ``get_poses`` and
    ``set_velocities`` (run k seeded k; ``drive``: see :func:`run_rps`), and ``rps["reality"]``
    sums their true-pose records (closest offset centres, collision pair-iterations, the first
    collision, MuJoCo contacts); the MuJoCo side is comat's own loop at the same level."""
    if isinstance(repeats, bool) or not isinstance(repeats, int) or repeats < 1:
        raise ValueError(f"--repeats must be an integer >= 1, got {repeats!r}")
    folder = Path(folder)
    config = _submission_config(folder)
    if drive not in DRIVES:
        raise ValueError(f"--drive must be one of {list(DRIVES)}, got {drive!r}")
    if reality is not None:
        resolve_reality(reality, "--reality")  # a one-line error before anything runs
    runs = [run_rps(folder, timeout_s, rps_path, reality=reality, seed=k, drive=drive) for k in range(repeats)]
    rps = dict(runs[0])
    keys = ("return", "steps", "progress", "finished")
    for key in keys:
        rps[key] = float(np.mean([r[key] for r in runs]))
    rps["rps_errors"] = {k: max(r["rps_errors"].get(k, 0) for r in runs) for k in runs[0]["rps_errors"]}
    timing = ("startup_iterations", "iterations", "loop_wall_s")  # folders exported before issue 66: none
    rps["runs"] = [
        {
            **{k: r[k] for k in keys},
            **{k: r[k] for k in timing if k in r},
            "rps_errors": r["rps_errors"],
            **({"reality": r["reality"]} if reality else {}),
        }
        for r in runs
    ]
    rps["duration_warnings"] = [w for w in (duration_warning(config, r) for r in runs) if w]
    if reality is not None:
        rps["reality"] = _reality_totals([r["reality"] for r in runs], reality, drive)
    mj = run_mujoco(folder, tier, reality)
    gap = {"progress_points": 100.0 * (rps["progress"] - mj["progress"]), "return": rps["return"] - mj["return"]}
    return {"rps": rps, "mujoco": mj, "gap": gap}
