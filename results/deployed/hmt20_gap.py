"""The 20-robot HMT export under V2 rps against comat's own loop, run for run (issue 66).

The shipped ``pretrained:comat-hmt`` is exported for each team asked (``size:19``, the 20-robot
team of issue 45, by default; ``scale:K`` the U_scale teams) with ``comat export``'s seed, with
comat's filter made for ``--filter-reality`` (the export's default ``nominal``), and its exact
``main.py`` is run ``--runs`` times under the
Robotarium's V2 simulator (``--rps``: a checkout of robotarium/robotarium_python_simulator,
b23069e). V2 first drives the robots from random charger places to the start poses
(``random.sample`` and ``numpy.random``, unseeded in rps): run k seeds both with k before main.py
starts, so a run is reproducible and every export of a team starts run k from the same poses.

Beside each run, comat's own loop (MuJoCo, unicycle tier, reality ``off``) plays the same policy,
team and task layout from the poses that run really started from (the first poses its log
holds, within V2's 0.05 m / 0.2 rad of the requested ones), and once from the requested poses
(the export's own ``--check`` twin).

    python results/deployed/hmt20_gap.py --rps <V2 checkout> [--runs 6] [--teams size:19 ...]
        [--filter-reality nominal] [--keep-right on|off] [--label NAME] [--out hmt20_gap.csv]

``--keep-right on|off`` is a diagnosis, not an export option: it turns the exported CONFIG's
``filter_keep_right`` (an export keeps right when its filter is made for a reality layer, as comat's
loop does; rows before that rule, 2026-12-08 morning, edited main.py's filter line to the same effect).

writes a row per team and run to ``--out`` (beside this file; rows already there with the same
label, team and run are kept, so an interrupted sitting resumes) and prints the means.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from rows import keep_row  # this folder's (run as a script, the folder is on the path)

from comat.cli.args import DEFAULT_SEED, parse_team, resolve_policy_arg
from comat.runlog import read_run_log
from sim2real.check import mujoco_twin
from sim2real.export import export_submission, load_config

HERE = Path(__file__).resolve().parent
FIELDS = (
    "label",
    "filter_reality",
    "keep_right",
    "seed",
    "team",
    "robots",
    "run",
    "rps_progress",
    "rps_steps",
    "rps_errors",
    "filter_failures",
    "start_error_m",
    "comat_progress",
    "comat_steps",
    "comat_requested_progress",
    "comat_requested_steps",
)
SEEDED_MAIN = (
    "import random, runpy, sys\n"
    "import numpy\n"
    "random.seed({seed}); numpy.random.seed({seed})\n"
    "sys.argv = ['main.py', '--no-figure']\n"
    "runpy.run_path('main.py', run_name='__main__')\n"
)
"""main.py under rps with the start-up drive's two random generators seeded (run k: seed k)."""


def run_seeded(folder: Path, rps: str, seed: int, log_dir: Path) -> dict:
    """``folder/main.py`` under the rps in ``rps`` with seed ``seed``; its COMAT_RESULT dict."""
    env = {**os.environ, "PYTHONPATH": str(Path(rps).resolve()), "COMAT_SHOW_FIGURE": "0", "MPLBACKEND": "Agg"}
    env["COMAT_LOG_DIR"] = str(log_dir)
    code = SEEDED_MAIN.format(seed=int(seed))
    proc = subprocess.run(
        [sys.executable, "-c", code], cwd=folder, env=env, capture_output=True, text=True, check=False
    )
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("COMAT_RESULT ")]
    if proc.returncode != 0 or not lines:
        raise RuntimeError(f"{folder}/main.py failed under rps (seed {seed}): {proc.stderr.strip()[-300:]}")
    return json.loads(lines[-1][len("COMAT_RESULT ") :])


def measure_team(
    spec: str, runs: list[int], rps: str, filter_reality: str, keep: str, seed: int, label: str, scratch: Path
):
    """Rows (one per run) of team ``spec`` (``size:K``, ``scale:K``): the export under V2 and comat's
    loop beside it."""
    team = parse_team(spec, "hmt")
    policy = resolve_policy_arg("pretrained:comat-hmt", "hmt", references=(), algos=("comat",))
    folder = export_submission(
        str(policy.checkpoint),
        "hmt",
        team,
        scratch / f"hmt_{spec.replace(':', '_')}_{filter_reality}",
        seed=seed,
        filter_reality=filter_reality,
    )
    config_py = folder / "submission_config.py"
    exported = "on" if load_config(folder).get("filter_keep_right", True) else "off"
    if keep not in (None, exported):  # a diagnosis: the exported CONFIG's keep right turned over
        want = keep == "on"
        text = config_py.read_text()
        config_py.write_text(text.replace(f"'filter_keep_right': {not want},", f"'filter_keep_right': {want},"))
        assert load_config(folder)["filter_keep_right"] is (keep == "on"), config_py
    keep = keep or exported
    requested = mujoco_twin(folder, tier="unicycle")["metrics"]
    wanted = np.array(load_config(folder)["start_poses"], dtype=float).T  # (N, 3)
    for run in runs:
        log_dir = scratch / f"log_{spec.replace(':', '_')}_{run}"
        res = run_seeded(folder, rps, run, log_dir)
        start = read_run_log(str(log_dir)).poses[0].astype(float)  # (N, 3), where the loop began
        mine = mujoco_twin(folder, tier="unicycle", start_poses=start)["metrics"]
        yield {
            "label": label,
            "filter_reality": filter_reality,
            "keep_right": keep,
            "seed": seed,
            "team": spec,
            "robots": team.size,
            "run": run,
            "rps_progress": round(res["progress"], 4),
            "rps_steps": res["steps"],
            "rps_errors": sum(res["rps_errors"].values()),
            "filter_failures": res["filter_failures"],
            "start_error_m": round(float(np.hypot(*(start[:, :2] - wanted[:, :2]).T).max()), 3),
            "comat_progress": round(mine["progress"], 4),
            "comat_steps": int(mine["steps"]),
            "comat_requested_progress": round(requested["progress"], 4),
            "comat_requested_steps": int(requested["steps"]),
        }


def summary(rows: list[dict]) -> str:
    """Per label and team: runs, mean progress under V2 and in comat's loop (same starts), the gap."""
    out = []
    keys = sorted({(r["label"], r["filter_reality"], r["keep_right"], int(r["seed"]), r["team"]) for r in rows})
    for key in keys:
        sel = [r for r in rows if (r["label"], r["filter_reality"], r["keep_right"], int(r["seed"]), r["team"]) == key]
        rps = 100 * np.mean([float(r["rps_progress"]) for r in sel])
        mine = 100 * np.mean([float(r["comat_progress"]) for r in sel])
        per_run = " ".join(f"{100 * float(r['rps_progress']):.1f}" for r in sel)
        out.append(
            f"{key[0]} (filter for {key[1]}, keep right {key[2]}, seed {key[3]}) {key[4]}: {len(sel)} runs, "
            f"V2 {rps:.1f} % [{per_run}], comat's loop "
            f"{mine:.1f} % (same starts), requested starts {100 * float(sel[0]['comat_requested_progress']):.1f} %: "
            f"gap {rps - mine:+.1f} points"
        )
    return "\n".join(out)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rps", required=True, help="a V2 checkout (robotarium/robotarium_python_simulator)")
    p.add_argument("--runs", type=int, default=6, help="V2 runs per team, seeds 0..runs-1")
    p.add_argument("--teams", nargs="+", default=["size:19"], help="teams: size:K (U_size), scale:K (U_scale)")
    p.add_argument("--filter-reality", default="nominal", help="the level comat's exported filter is made for")
    p.add_argument(
        "--keep-right",
        choices=("on", "off"),
        default=None,
        help="turn the export's filter_keep_right (default: as exported)",
    )
    p.add_argument("--seed", type=int, default=DEFAULT_SEED, help="the export's seed: start poses, layout")
    p.add_argument("--label", default="shipped", help="names this sitting's code in the CSV")
    p.add_argument("--out", default="hmt20_gap.csv", help="the CSV, beside this file")
    a = p.parse_args()
    path = HERE / a.out
    rows = list(csv.DictReader(path.open())) if path.exists() else []
    done = {(r["label"], r["filter_reality"], r["keep_right"], int(r["seed"]), r["team"], int(r["run"])) for r in rows}
    with tempfile.TemporaryDirectory() as tmp:
        for spec in a.teams:
            todo = [s for s in range(a.runs) if (a.label, a.filter_reality, a.keep_right, a.seed, spec, s) not in done]
            if todo:
                for row in measure_team(spec, todo, a.rps, a.filter_reality, a.keep_right, a.seed, a.label, Path(tmp)):
                    keep_row(path, rows, row, FIELDS)
    print(summary(rows))


if __name__ == "__main__":
    main()
