"""The deployed loop's gap over the U_scale teams, per team size (issue 45).

For each task (HMT, PCP) and each of its 20 U_scale teams (10-20 robots), the shipped COMAT policy
(``pretrained:comat-<task>``) is exported twice — with comat's filter (``--filter comat``, the
default) and with the Robotarium's own barrier (``--filter robotarium``) — and played:

* under the Robotarium's V2 simulator (``--rps``: a checkout of robotarium/robotarium_python_simulator,
  b23069e), one run per folder (V2 drives the robots from random charger places first);
* in comat's MuJoCo world (unicycle tier) with comat's own loop, and with each exported loop run in
  comat's tick (``SafetyConfig.loop`` ``shipped_v2`` / ``robotarium_v2``), from the exported start poses.

So the rps − MuJoCo gap splits into what the deployed loop costs (MuJoCo, deployed loop − comat's
loop) and what is left to the simulators (rps − MuJoCo with the same loop).

    python results/deployed/scale_gap.py --rps <V2 checkout> [--tasks hmt pcp] [--teams 0 1 ...]

writes ``scale_gap.csv`` (a row per task, team and filter) and ``scale_gap.md`` (means per task and
team size) beside this file; rows already in the CSV are kept (an interrupted run resumes).
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
from rows import keep_row, load_rows  # this folder's (run as a script, the folder is on the path)

from comat.cli.args import parse_team, resolve_policy_arg
from comat.config import SafetyConfig
from comat.envs import make_env
from comat.files import write_atomic
from comat.team import TeamSpec
from sim2real.check import run_mujoco, run_rps
from sim2real.export import export_submission, load_config
from sim2real.runtime import ComatRuntime

HERE = Path(__file__).resolve().parent
FIELDS = (
    "task",
    "team",
    "robots",
    "filter",
    "rps_progress",
    "rps_steps",
    "rps_errors",
    "mujoco_comat_progress",
    "mujoco_comat_steps",
    "mujoco_deployed_progress",
    "mujoco_deployed_steps",
)
LOOP = {"comat": "shipped_v2", "robotarium": "robotarium_v2"}


def deployed_in_mujoco(folder: Path, loop: str) -> dict:
    """The folder's policy, team and start poses in comat's unicycle world with ``loop`` in its tick."""
    cfg = load_config(folder)
    team = TeamSpec.from_dict(
        {
            "task": cfg["task"],
            "robots": [{"type": t, "capabilities": c} for t, c in zip(cfg["types"], cfg["capabilities"])],
        }
    )
    env = make_env(
        f"{cfg['task']}_v0",
        team=team,
        tier="unicycle",
        ticks_per_step=cfg["ticks_per_step"],
        safety=SafetyConfig(loop=loop),
    )
    env.reset(seed=cfg["seed"])
    core = env.core
    core.safe.reset(np.array(cfg["start_poses"], dtype=float).T)
    if cfg["task"] == "pcp":
        core.state["prey"][0] = np.array(cfg["prey"], dtype=float)
    policy = ComatRuntime.from_file(folder / "weights.npy")
    while True:
        act = np.zeros((1, core.N), dtype=np.int64)
        act[0, : team.size] = policy.action_probs(core.observe()[0, : team.size])[0]
        res = core.step(act)
        if res.terminated[0] or res.truncated[0]:
            return core.episode_metrics(0)


def measure(task: str, k: int, filter_name: str, rps: str, scratch: Path) -> dict:
    team = parse_team(f"scale:{k}", task)
    policy = resolve_policy_arg(f"pretrained:comat-{task}", task, references=(), algos=("comat",))
    folder = export_submission(
        str(policy.checkpoint), task, team, scratch / f"{task}_{k}_{filter_name}", filter_name=filter_name
    )
    r = run_rps(folder, rps_path=rps)
    mine = run_mujoco(folder, tier="unicycle")
    theirs = deployed_in_mujoco(folder, LOOP[filter_name])
    return {
        "task": task,
        "team": k,
        "robots": team.size,
        "filter": filter_name,
        "rps_progress": r["progress"],
        "rps_steps": r["steps"],
        "rps_errors": sum(r["rps_errors"].values()),
        "mujoco_comat_progress": mine["progress"],
        "mujoco_comat_steps": mine["steps"],
        "mujoco_deployed_progress": theirs["progress"],
        "mujoco_deployed_steps": theirs["steps"],
    }


def table(rows: list[dict]) -> str:
    out = [
        (
            "| task | robots | teams | filter | progress %: V2 rps | MuJoCo, deployed loop | MuJoCo, comat's loop | "
            "rps − comat's loop | of which the loop | steps: V2 rps | deployed | comat's | rps errors |"
        ),
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for task in ("hmt", "pcp"):
        for n in sorted({r["robots"] for r in rows if r["task"] == task}):
            for f in ("robotarium", "comat"):
                sel = [r for r in rows if r["task"] == task and r["robots"] == n and r["filter"] == f]
                if not sel:
                    continue
                rps, dep, com = (
                    100 * np.mean([float(r[k]) for r in sel])
                    for k in ("rps_progress", "mujoco_deployed_progress", "mujoco_comat_progress")
                )
                s_rps, s_dep, s_com = (
                    np.mean([float(r[k]) for r in sel])
                    for k in ("rps_steps", "mujoco_deployed_steps", "mujoco_comat_steps")
                )
                errors = sum(int(r["rps_errors"]) for r in sel)
                out.append(
                    f"| {task.upper()} | {n} | {len(sel)} | {f} | {rps:.1f} | {dep:.1f} | {com:.1f} | "
                    f"{rps - com:+.1f} | {dep - com:+.1f} | {s_rps:.1f} | {s_dep:.1f} | {s_com:.1f} | {errors} |"
                )
    return "\n".join(out) + "\n"


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rps", required=True, help="a V2 checkout (robotarium/robotarium_python_simulator)")
    p.add_argument("--tasks", nargs="+", default=["hmt", "pcp"])
    p.add_argument("--teams", nargs="+", type=int, default=list(range(20)))
    a = p.parse_args()
    path = HERE / "scale_gap.csv"
    rows = load_rows(path)
    done = {(r["task"], r["team"], r["filter"]) for r in rows}
    with tempfile.TemporaryDirectory() as tmp:
        for task in a.tasks:
            for k in a.teams:
                for f in ("robotarium", "comat"):
                    if (task, k, f) in done:
                        continue
                    keep_row(path, rows, measure(task, k, f, a.rps, Path(tmp)), FIELDS)
    write_atomic(HERE / "scale_gap.md", table(rows))


if __name__ == "__main__":
    main()
