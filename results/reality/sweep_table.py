"""Each reality component alone, from its smallest to its largest swept value, per arm (issue 29).

    python results/reality/sweep_table.py results/policies/{comat,mat}_{pcp,hmt}{,_nominal}_s[01] > results/reality/sweeps.md

Reads every ``evaluation_unicycle_sweep_<component>.json`` of the policy folders (``comat eval
--reality-sweep``: that component alone at its values, every other one off; U_test, the same
episodes at every value). An arm is a folder name without its ``_s<seed>`` (learner, task, the level
it trained at). Per task, component and arm: progress and episode steps at the first value (off) and
at the last, the change in steps, and contact steps and Robotarium violations per episode summed
over the values; the mean over seeds with each seed's own value in brackets (two seeds: no interval).
"""

import re
import sys
from collections import defaultdict
from pathlib import Path

from comat.measure.metrics import read_results  # per-episode detail included; today's names


def _seed_rows(folder: Path) -> dict:
    """(task, component) -> {"values", "progress", "steps", "collisions", "violations"} of one policy."""
    out = {}
    for path in sorted(folder.glob("evaluation_unicycle_sweep_*.json")):
        sweep = read_results(path)
        points = [(p["value"], p["rows"][0]["metrics"]) for p in sweep["points"]]
        out[(sweep["task"], sweep["component"])] = {
            "values": [v for v, _ in points],
            "progress": [100 * m["progress"]["mean"] for _, m in points],
            "steps": [m["steps"]["mean"] for _, m in points],
            "collisions": sum(m["collisions"]["mean"] for _, m in points),
            "violations": sum(m["violations"]["mean"] for _, m in points),
        }
    return out


def _cell(values: list[float], fmt: str) -> str:
    mean = sum(values) / len(values)
    return f"{mean:{fmt}}" + (f" ({' / '.join(f'{v:{fmt}}' for v in values)})" if len(values) > 1 else "")


def main(folders: list[str]) -> None:
    cells: dict = defaultdict(list)  # (task, component, arm) -> [(seed, rows)]
    for folder in map(Path, folders):
        if not folder.is_dir():  # an unmatched shell pattern (e.g. no nominal-trained MAT)
            continue
        match = re.fullmatch(r"(.+)_s(\d+)", folder.name)
        if match is None:
            raise SystemExit(f"sweep_table.py: folder names must end in _s<seed>, got {folder.name!r}")
        for key, rows in _seed_rows(folder).items():
            cells[(*key, match.group(1))].append((int(match.group(2)), rows))
    print(
        "| task | component | values | arm | seeds | progress % at first | at last | steps at first | at last "
        "| Δ steps | contacts, violations (all values) |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for (task, component, arm), got in sorted(cells.items()):
        got.sort(key=lambda g: g[0])
        rows = [r for _, r in got]
        values = rows[0]["values"]
        delta = [100 * (r["steps"][-1] / r["steps"][0] - 1) for r in rows]
        print(
            f"| {task.upper()} | {component} | {values[0]:g} → {values[-1]:g} | {arm} | "
            f"{', '.join(str(s) for s, _ in got)} | {_cell([r['progress'][0] for r in rows], '.1f')} | "
            f"{_cell([r['progress'][-1] for r in rows], '.1f')} | {_cell([r['steps'][0] for r in rows], '.1f')} | "
            f"{_cell([r['steps'][-1] for r in rows], '.1f')} | {_cell(delta, '+.0f')} % | "
            f"{sum(r['collisions'] for r in rows):.2f}, {sum(r['violations'] for r in rows):.2f} |"
        )


if __name__ == "__main__":
    main(sys.argv[1:])
