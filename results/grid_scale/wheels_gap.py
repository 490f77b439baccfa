"""The transfer gap of the grid's COMAT runs: trained in `unicycle`, evaluated in both tiers.

    .venv/bin/python results/grid_scale/wheels_gap.py [RUN ...]

Without RUN: every COMAT run of the grid (runs/comat_*_s* here, or its retrain in
comat_wheels/runs/ where one is kept: see retrain_wheels.sh), written to comat_wheels/gap.md;
with RUN folders: those, printed only. Reads each run's evaluation_unicycle.json and
evaluation_wheels.json (`comat eval --teams all`, same coalitions and seeds in both tiers) and
gives per run and set the progress in each tier, the difference (wheels − unicycle, points), the
finished shares and collisions, then per task and set the mean difference over seeds with its
95 % Student-t half-width.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from comat.measure.metrics import (
    current_names,  # files written before issue 32: today's names
    mean_ci,
    read_results,  # an evaluation with its per-episode detail
)

HERE = Path(__file__).resolve().parent
SETS = ("train", "test", "scale")


def _rows(run: Path, tier: str) -> dict[str, dict]:
    data = read_results(run / f"evaluation_{tier}.json")
    return {r["set"]: r["metrics"] for r in data["rows"] if r["policy"] == data["algo"]}


def main(runs: list[Path]) -> str:
    head = (
        "| run | set | unicycle progress (%) | wheels progress (%) | gap (points) "
        "| finished unicycle / wheels (%) | collisions unicycle / wheels |"
    )
    lines = [head, "|---|---|---|---|---|---|---|"]
    gaps: dict[tuple[str, str], list[float]] = {}
    for run in runs:
        uni, whe = _rows(run, "unicycle"), _rows(run, "wheels")
        task = current_names(json.loads((run / "summary.json").read_text()))["task"]
        for split in SETS:
            if split not in uni or split not in whe:
                continue
            u, w = 100 * uni[split]["progress"]["mean"], 100 * whe[split]["progress"]["mean"]
            gaps.setdefault((task, split), []).append(w - u)
            done = f"{100 * uni[split]['finished']['mean']:.0f} / {100 * whe[split]['finished']['mean']:.0f}"
            hits = f"{uni[split]['collisions']['mean']:g} / {whe[split]['collisions']['mean']:g}"
            lines.append(f"| {run.name} | U_{split} | {u:.1f} | {w:.1f} | {w - u:+.1f} | {done} | {hits} |")
    lines += ["", "| task | set | seeds | gap over seeds (points, 95 % interval) |", "|---|---|---|---|"]
    for (task, split), values in sorted(gaps.items(), key=lambda kv: (kv[0][0], SETS.index(kv[0][1]))):
        mean, half = mean_ci(values)
        spread = f" ± {half:.1f}" if len(values) > 1 else ""
        lines.append(f"| {task.upper()} | U_{split} | {len(values)} | {mean:+.1f}{spread} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    grid = [
        HERE / "comat_wheels" / "runs" / r.name if (HERE / "comat_wheels" / "runs" / r.name).is_dir() else r
        for r in sorted(HERE.glob("runs/comat_*_s*"))
    ]
    folders = [Path(a) for a in sys.argv[1:]] or grid
    both = [f for f in folders if all((f / f"evaluation_{t}.json").is_file() for t in ("unicycle", "wheels"))]
    for f in sorted(set(folders) - set(both)):
        print(
            f"wheels_gap: {f} left out: it needs evaluation_unicycle.json and evaluation_wheels.json", file=sys.stderr
        )
    folders = both
    if not folders:
        sys.exit(
            "wheels_gap: no run folder has both evaluations (run `comat eval --policy RUN --teams all --tier wheels`)"
        )
    text = main(folders)
    if not sys.argv[1:]:
        (HERE / "comat_wheels" / "gap.md").write_text(text)
    print(text, end="")
