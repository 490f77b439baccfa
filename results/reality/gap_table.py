"""The reality gap of kept policies: each policy folder's evaluation at off, nominal and stress on
U_train and U_test (paired episodes: the same teams and requested starts at every level).

    python results/reality/gap_table.py results/policies/*_s0 [runs/gap2/*_s1 ...] > results/reality/gap.md
    python results/reality/gap_table.py --by-arm results/policies/{comat,mat}_{pcp,hmt}{,_nominal}_s[01] > results/reality/gap_arms.md

Per policy, task and set: progress, finished share, episode length (env steps), contact steps per
episode and Robotarium violations per episode at each level, then the change from off (points,
and % of steps: the figure CASH-MARBLER reports for real runs, +2-4 % steps, 0 collisions). The ±
are 95 % t-intervals over coalitions (one policy each: seed spread is not in them).

``--by-arm`` groups the folders by arm (the folder name without its ``_s<seed>``: learner, task,
training level) and prints, per set and level, the mean over seeds of each policy's mean with every
seed's own value beside it: the seed is the replicated unit, and with two seeds no interval is
drawn (a t-interval on 1 degree of freedom is 12.7 half-spreads wide).
"""

import re
import sys
from collections import defaultdict
from pathlib import Path

from comat.measure.metrics import read_results  # per-episode detail included; today's names

LEVELS = ("off", "nominal", "stress")
SETS = {"train": "U_train", "test": "U_test"}


def rows(folder: Path) -> dict:
    out = {}
    for level in LEVELS:
        path = folder / ("evaluation_unicycle.json" if level == "off" else f"evaluation_unicycle_{level}.json")
        if not path.is_file():
            continue
        data = read_results(path)
        for r in data["rows"]:
            if r["set"] in SETS and r["policy"] not in ("heuristic", "constant", "random"):
                out[(r["policy"], r["task"], r["set"], level)] = r["metrics"]
    return out


def fmt(m: dict, key: str, scale: float = 1.0, digits: int = 1) -> str:
    return f"{m[key]['mean'] * scale:.{digits}f} ± {m[key]['ci95'] * scale:.{digits}f}"


def main(folders: list[str]) -> None:
    print(
        "| policy | task | set | level | progress % | finished % | steps | Δ steps | contacts/ep | violations/ep | trained at |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for folder in map(Path, folders):
        got = rows(folder)
        trained = read_results(folder / "evaluation_unicycle.json", detail=False).get("trained_reality", "off") or "off"
        for (policy, task, split, level), m in sorted(
            got.items(), key=lambda kv: (kv[0][1], kv[0][2], LEVELS.index(kv[0][3]))
        ):
            off = got.get((policy, task, split, "off"))
            delta = (
                ""
                if off is None or level == "off"
                else f"{100 * (m['steps']['mean'] / off['steps']['mean'] - 1):+.1f} %"
            )
            print(
                f"| {folder.name} | {task.upper()} | {SETS[split]} | {level} | {fmt(m, 'progress', 100)} | "
                f"{fmt(m, 'finished', 100)} | {fmt(m, 'steps')} | {delta} | {fmt(m, 'collisions', 1, 2)} | "
                f"{fmt(m, 'violations', 1, 2)} | {trained} |"
            )


def by_arm(folders: list[str]) -> None:
    cells: dict = defaultdict(list)  # (arm, task, set, level) -> [(seed, metrics, off metrics)]
    for folder in map(Path, folders):
        match = re.fullmatch(r"(.+)_s(\d+)", folder.name)
        if match is None:
            raise SystemExit(f"gap_table.py --by-arm: folder names must end in _s<seed>, got {folder.name!r}")
        arm, seed = match.group(1), int(match.group(2))
        got = rows(folder)
        for (_, task, split, level), m in got.items():
            cells[(arm, task, split, level)].append((seed, m, got.get((_, task, split, "off"))))
    print("| arm | set | level | seeds | progress % | finished % | Δ steps vs off | contacts/ep | violations/ep |")
    print("|---|---|---|---|---|---|---|---|---|")
    for (arm, task, split, level), got in sorted(
        cells.items(), key=lambda kv: (kv[0][0], kv[0][2], LEVELS.index(kv[0][3]))
    ):
        got.sort(key=lambda g: g[0])

        def cell(values: list[float], digits: int = 1, unit: str = "") -> str:
            each = " / ".join(f"{v:+.{digits}f}{unit}" if unit else f"{v:.{digits}f}" for v in values)
            mean = sum(values) / len(values)
            return f"{mean:+.{digits}f}{unit} ({each})" if unit else f"{mean:.{digits}f} ({each})"

        prog = [100 * m["progress"]["mean"] for _, m, _ in got]
        fin = [100 * m["finished"]["mean"] for _, m, _ in got]
        delta = (
            [100 * (m["steps"]["mean"] / off["steps"]["mean"] - 1) for _, m, off in got]
            if level != "off" and all(off is not None for *_, off in got)
            else None
        )
        coll = sum(m["collisions"]["mean"] for _, m, _ in got) / len(got)
        viol = sum(m["violations"]["mean"] for _, m, _ in got) / len(got)
        print(
            f"| {arm} | {SETS[split]} | {level} | {', '.join(str(s) for s, *_ in got)} | {cell(prog)} | "
            f"{cell(fin, 0)} | {cell(delta, 1, ' %') if delta else ''} | {coll:.2f} | {viol:.2f} |"
        )


if __name__ == "__main__":
    if sys.argv[1:2] == ["--by-arm"]:
        by_arm(sys.argv[2:])
    else:
        main(sys.argv[1:])
