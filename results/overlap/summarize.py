"""Issue 48's overlap study: PLAN.md's endpoints from the kept runs (``runs/``), per arm and seed,
and overlap − sequential with its Welch interval over seeds. Reads U_train (the periodic,
deterministic evaluations of ``eval.csv``) and U_val (``evaluation_unicycle.json``) only:

    python results/overlap/summarize.py > results/overlap/overlap.md
"""

from __future__ import annotations

import csv
import json
import re
import sys
from pathlib import Path

import numpy as np

from comat.measure.metrics import read_results
from comat.measure.stats import t_interval, welch

RUNS = Path(__file__).resolve().parent / "runs"
NAME = re.compile(r"^(?P<arm>sequential|overlap)_(?P<task>pcp|hmt)_s(?P<seed>\d+)$")
ARMS = ("sequential", "overlap")
MARGIN_POINTS = 5.0
"""PLAN.md: no worse where the interval's lower end is above −5 points of progress ..."""
MARGIN_RETURN = 0.05
"""... or −5 % of the sequential mean return."""


def one_run(folder: Path) -> dict:
    with open(folder / "eval.csv") as f:
        periodic = [float(r["progress"]) for r in csv.DictReader(f)]
    if len(periodic) != 12:
        raise ValueError(f"{folder}: {len(periodic)} periodic evaluations in eval.csv, PLAN.md's endpoint needs 12")
    data = read_results(folder / "evaluation_unicycle.json")
    val = next(r for r in data["rows"] if r["set"] == "val" and r["policy"] not in ("heuristic", "constant", "random"))
    eps = val["per_episode"]
    summary = json.loads((folder / "summary.json").read_text())
    return {
        "auc": 100 * float(np.mean(periodic)),
        "val_progress": 100 * float(np.mean([e["progress"] for e in eps])),
        "val_finished": 100 * float(np.mean([e["finished"] for e in eps])),
        "val_return": float(np.mean([e["return"] for e in eps])),
        "wall_min": summary["wall_s"] / 60,
    }


ENDPOINTS = (
    ("auc", "U_train progress, mean of the 12 periodic evaluations (%)", "points"),
    ("val_progress", "U_val progress at 300 k (%)", "points"),
    ("val_finished", "U_val finished share at 300 k (%)", None),
    ("val_return", "U_val return at 300 k", "return"),
    ("wall_min", "training wall time, 2-core VM (min)", None),
)


def main() -> None:
    runs: dict[str, dict[int, dict]] = {arm: {} for arm in ARMS}
    for folder in sorted(RUNS.iterdir()) if RUNS.is_dir() else []:
        m = NAME.match(folder.name)
        if m and (folder / "summary.json").is_file():
            runs[m["arm"]][int(m["seed"])] = one_run(folder)
    print("# Issue 48's overlap study: results (`python results/overlap/summarize.py`)\n")
    print(f"Runs kept: sequential seeds {sorted(runs['sequential'])}, overlap seeds {sorted(runs['overlap'])}.\n")
    print(
        "| endpoint | sequential, per seed | overlap, per seed | sequential mean [95 % t] | overlap mean [95 % t] "
        "| overlap − sequential [95 % Welch], p | no worse (PLAN.md margin) |"
    )
    print("|---|---|---|---|---|---|---|")
    for key, label, margin in ENDPOINTS:
        cols = []
        values = {arm: [runs[arm][s][key] for s in sorted(runs[arm])] for arm in ARMS}
        for arm in ARMS:
            cols.append(", ".join(f"{v:.1f}" for v in values[arm]) or "-")
        for arm in ARMS:
            t = t_interval(values[arm]) if values[arm] else None
            cols.append("-" if t is None else f"{t['mean']:.1f} [{t['lo']:.1f}, {t['hi']:.1f}]")
        if all(len(values[arm]) >= 2 for arm in ARMS):
            w = welch(values["overlap"], values["sequential"])
            cols.append(f"{w['diff']:+.1f} [{w['lo']:+.1f}, {w['hi']:+.1f}], p = {w['p']:.2f}")
            if margin is None:
                cols.append("(descriptive)")
            else:
                bound = -MARGIN_POINTS if margin == "points" else -MARGIN_RETURN * abs(np.mean(values["sequential"]))
                verdict = "yes" if w["lo"] > bound else "not shown"
                cols.append(f"{verdict} (lower end vs {bound:+.1f})")
        else:
            cols += ["-", "-"]
        print(f"| {label} | " + " | ".join(cols) + " |")


if __name__ == "__main__":
    sys.exit(main())
