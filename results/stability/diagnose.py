"""What COMAT's and MAT's robots do in HMT episodes (issue 30, diagnosis without training).

    python results/stability/diagnose.py results/policies/comat_hmt_s0 results/policies/mat_hmt_s0 [...]

Reads each folder's ``evaluation_unicycle.json`` (``comat eval --teams all --episodes 5``: every
episode's per-robot diagnostics, comat.envs.diagnostics) and prints, per policy, set and robot type,
the share of a robot's steps spent

* idle by choice (``still_idle``: it chose ``stay``),
* held (``still_held``: it chose to move but its point moved < 20 % of its step: the filter, a
  teammate or a wall stopped it),
* carrying material (``carrying``),
* the rest: moving empty (wandering or travelling to load),

and the share of the team's delivered material each type delivered, over all episodes and over
the unfinished ones (where the time-out came first). Then, per policy and set, progress against the
share of the team's payload held by slow robots (the issue's slow-heavy axis): the slope per SD of
that share (least squares over the set's episodes), as in ``science-turn3.md`` §5. Descriptive: one
policy per folder, episodes are not independent seeds.
"""

import sys
from pathlib import Path

import numpy as np

from comat.envs.base import resolve_coalitions
from comat.measure.metrics import read_results  # per-episode detail included; today's names

SETS = ("train", "val", "test", "scale", "size", "capability")


def _team_slow_payload(task: str, split: str, coalition: int) -> float:
    team = resolve_coalitions(split, task)[coalition]
    pay = np.array([r.capabilities[1] for r in team.robots], float)  # (speed_m, payload)
    slow = np.array([r.type == "slow" for r in team.robots])
    return float(pay[slow].sum() / pay.sum())


def shares(episodes: list[dict]) -> dict:
    """type -> (idle, held, carrying, empty-moving shares of steps; delivered share of the team's)."""
    acc: dict = {}
    for e in episodes:
        total = sum(r["delivered"] for r in e["robots"]) or 1.0
        for r in e["robots"]:
            a = acc.setdefault(r["type"], [[], [], [], [], []])
            steps = e["steps"]
            idle, held, carry = r["still_idle"] / steps, r["still_held"] / steps, r["carrying"] / steps
            a[0].append(idle)
            a[1].append(held)
            a[2].append(carry)
            a[3].append(max(0.0, 1.0 - idle - held - carry))
            a[4].append(r["delivered"] / total)
    return {k: [100 * float(np.mean(v)) for v in a] for k, a in acc.items()}


def main(folders: list[str]) -> None:
    print(
        "| policy | set | episodes | type | idle % | held % | carrying % | moving empty % | delivered % "
        "| unfinished: idle % | held % | carrying % | moving empty % |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    slopes = []
    for folder in map(Path, folders):
        data = read_results(folder / "evaluation_unicycle.json")
        for row in data["rows"]:
            if row["task"] != "hmt" or row["policy"] in ("heuristic", "constant", "random"):
                continue
            eps = row["per_episode"]
            if not eps or "robots" not in eps[0]:
                continue
            allv, fail = shares(eps), shares([e for e in eps if e["finished"] < 1])
            for t in sorted(allv):
                f = fail.get(t, [float("nan")] * 5)
                print(
                    f"| {folder.name} | {row['set']} | {len(eps)} | {t} | "
                    + " | ".join(f"{v:.1f}" for v in allv[t])
                    + " | "
                    + " | ".join(f"{v:.1f}" for v in f[:4])
                    + " |"
                )
            x = np.array([_team_slow_payload("hmt", row["set"], e["coalition"]) for e in eps])
            y = np.array([100 * e["progress"] for e in eps])
            if x.std() > 0:
                slope = np.polyfit((x - x.mean()) / x.std(), y, 1)[0]
                slopes.append((folder.name, row["set"], slope, float(y.mean())))
    print("\n| policy | set | progress % | progress points per SD of the slow robots' payload share |")
    print("|---|---|---|---|")
    for name, split, slope, mean in slopes:
        print(f"| {name} | {split} | {mean:.1f} | {slope:+.1f} |")


if __name__ == "__main__":
    main(sys.argv[1:])
