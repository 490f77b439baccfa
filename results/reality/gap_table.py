"""The reality gap of kept policies: each policy folder's evaluation at off, nominal and stress on
U_train and U_test (paired episodes: the same teams and requested starts at every level).

    python results/reality/gap_table.py results/policies/*_s0 [runs/gap2/*_s1 ...] > results/reality/gap.md

Per policy, task and set: progress, finished share, episode length (env steps), contact steps per
episode and Robotarium violations per episode at each level, then the change from off (points,
and % of steps: the figure CASH-MARBLER reports for real runs, +2-4 % steps, 0 collisions). The ±
are 95 % t-intervals over coalitions (one policy each: seed spread is not in them).
"""

import json
import sys
from pathlib import Path

LEVELS = ("off", "nominal", "stress")
SETS = {"train": "U_train", "test": "U_test"}


def rows(folder: Path) -> dict:
    out = {}
    for level in LEVELS:
        path = folder / ("evaluation_unicycle.json" if level == "off" else f"evaluation_unicycle_{level}.json")
        if not path.is_file():
            continue
        data = json.loads(path.read_text())
        for r in data["rows"]:
            if r["set"] in SETS and r["policy"] not in ("heuristic", "constant", "random"):
                out[(r["policy"], r["task"], r["set"], level)] = r["metrics"]
    return out


def fmt(m: dict, key: str, scale: float = 1.0, digits: int = 1) -> str:
    return f"{m[key]['mean'] * scale:.{digits}f} ± {m[key]['ci95'] * scale:.{digits}f}"


def main(folders: list[str]) -> None:
    print("| policy | task | set | level | progress % | finished % | steps | Δ steps | contacts/ep | violations/ep | trained at |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for folder in map(Path, folders):
        got = rows(folder)
        trained = json.loads((folder / "evaluation_unicycle.json").read_text()).get("trained_reality", "off") or "off"
        for (policy, task, split, level), m in sorted(got.items(), key=lambda kv: (kv[0][1], kv[0][2], LEVELS.index(kv[0][3]))):
            off = got.get((policy, task, split, "off"))
            delta = "" if off is None or level == "off" else \
                f"{100 * (m['steps']['mean'] / off['steps']['mean'] - 1):+.1f} %"
            print(f"| {folder.name} | {task.upper()} | {SETS[split]} | {level} | {fmt(m, 'completion', 100)} | "
                  f"{fmt(m, 'success', 100)} | {fmt(m, 'steps')} | {delta} | {fmt(m, 'collisions', 1, 2)} | "
                  f"{fmt(m, 'violations', 1, 2)} | {trained} |")


if __name__ == "__main__":
    main(sys.argv[1:])
