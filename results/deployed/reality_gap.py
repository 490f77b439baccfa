"""The reality gap of the deployed loop next to comat's loop (issue 45).

For each task and U_test teams 0-4 (2-8 robots), the shipped COMAT policy is exported with each
filter and checked with ``comat export --check --reality L`` (the exact main.py under the legacy rps
from PyPI, the reality layer around ``get_poses`` and ``set_velocities``, robots moved by rps, 3 runs
with layer seeds 0-2) at ``off`` and ``nominal``; beside it comat's own loop in MuJoCo (unicycle) at
the same level on the same team and start poses (one episode, layer seed 0).

    python results/deployed/reality_gap.py [--repeats 3]

writes ``reality_gap.csv`` (a row per task, team, filter and level; rows already there are kept)
and ``reality_gap.md`` (means per task, filter and level) beside this file.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
from rows import keep_row, load_rows  # this folder's (run as a script, the folder is on the path)

from comat.cli.args import parse_team, resolve_policy_arg
from comat.files import write_atomic
from sim2real.check import check_submission
from sim2real.export import export_submission

HERE = Path(__file__).resolve().parent
FIELDS = (
    "task",
    "team",
    "robots",
    "filter",
    "level",
    "deployed_progress",
    "deployed_steps",
    "comat_progress",
    "comat_steps",
    "collision_runs",
    "closest_m",
    "rps_errors",
)


def measure(task: str, k: int, filter_name: str, level: str, repeats: int, scratch: Path) -> dict:
    team = parse_team(f"test:{k}", task)
    folder = scratch / f"{task}_{k}_{filter_name}"
    if not folder.exists():
        policy = resolve_policy_arg(f"pretrained:comat-{task}", task, references=(), algos=("comat",))
        export_submission(str(policy.checkpoint), task, team, folder, filter_name=filter_name)
    report = check_submission(folder, tier="unicycle", repeats=repeats, reality=level)
    rec = report["rps"]["reality"]
    return {
        "task": task,
        "team": k,
        "robots": team.size,
        "filter": filter_name,
        "level": level,
        "deployed_progress": report["rps"]["progress"],
        "deployed_steps": report["rps"]["steps"],
        "comat_progress": report["mujoco"]["progress"],
        "comat_steps": report["mujoco"]["steps"],
        "collision_runs": rec["runs_with_collisions"],
        "closest_m": rec["min_offset_centre_distance_m"],
        "rps_errors": sum(report["rps"]["rps_errors"].values()),
    }


def table(rows: list[dict]) -> str:
    out = [
        (
            "| task | filter | level | teams | progress %: deployed | comat's loop | steps: deployed | comat's loop | "
            "runs with collisions | closest (m) | rps errors |"
        ),
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for task in ("hmt", "pcp"):
        for f in ("robotarium", "comat"):
            for level in ("off", "nominal"):
                sel = [r for r in rows if (r["task"], r["filter"], r["level"]) == (task, f, level)]
                if not sel:
                    continue

                def mean(key: str, sel: list[dict] = sel) -> float:
                    return float(np.mean([float(r[key]) for r in sel]))

                out.append(
                    f"| {task.upper()} | {f} | {level} | {len(sel)} | {100 * mean('deployed_progress'):.1f} | "
                    f"{100 * mean('comat_progress'):.1f} | {mean('deployed_steps'):.1f} | "
                    f"{mean('comat_steps'):.1f} | {sum(int(r['collision_runs']) for r in sel)} | "
                    f"{min(float(r['closest_m']) for r in sel):.3f} | {sum(int(r['rps_errors']) for r in sel)} |"
                )
    return "\n".join(out) + "\n"


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeats", type=int, default=3, help="rps runs per folder and level (default: %(default)s)")
    p.add_argument("--teams", nargs="+", type=int, default=[0, 1, 2, 3, 4])
    a = p.parse_args()
    path = HERE / "reality_gap.csv"
    rows = load_rows(path)
    done = {(r["task"], r["team"], r["filter"], r["level"]) for r in rows}
    with tempfile.TemporaryDirectory() as tmp:
        for task in ("hmt", "pcp"):
            for k in a.teams:
                for f in ("robotarium", "comat"):
                    for level in ("off", "nominal"):
                        if (task, k, f, level) in done:
                            continue
                        keep_row(path, rows, measure(task, k, f, level, a.repeats, Path(tmp)), FIELDS)
    write_atomic(HERE / "reality_gap.md", table(rows))


if __name__ == "__main__":
    main()
