"""Decoding order without training (issue 30): progress and finished share of the kept HMT
policies with each team's robots in their own order, reversed, and slow robots first.

    python results/stability/orders/compare.py > results/stability/orders/orders.md

Per policy and set, mean over coalitions (each coalition's 5 episodes averaged first) and the
paired difference from the original order with its 95 % t-interval over coalitions (the same
coalitions in every order; the robots' start positions follow their slots, so they move with
the order too). One policy per learner: this says what the order does to these two policies.
"""

from pathlib import Path

import numpy as np

from comat.measure.metrics import read_results  # per-episode detail included; today's names
from comat.measure.stats import t_interval

ROOT = Path(__file__).resolve().parents[3]


def per_coalition(path: Path, split: str, policy: str, metric: str) -> np.ndarray:
    rows = read_results(path)["rows"]
    row = next(r for r in rows if r["set"] == split and r["policy"] == policy)
    by: dict[int, list[float]] = {}
    for e in row["per_episode"]:
        by.setdefault(int(e["coalition"]), []).append(float(e[metric]))
    return np.array([np.mean(by[k]) for k in sorted(by)])


def main() -> None:
    print("| policy | set | order | progress % | Δ progress (points) | finished % | Δ finished (points) |")
    print("|---|---|---|---|---|---|---|")
    for pol in ("comat_hmt_s0", "mat_hmt_s0"):
        algo = pol.split("_")[0]
        for split in ("train", "capability"):
            base = {
                m: per_coalition(ROOT / "results/policies" / pol / "evaluation_unicycle.json", split, algo, m)
                for m in ("progress", "finished")
            }
            print(
                f"| {pol} | {split} | own | {100 * base['progress'].mean():.1f} | | {100 * base['finished'].mean():.1f} | |"
            )
            for order in ("reversed", "slow_first"):
                name = f"hmt_{split}_{order}"
                path = ROOT / "results/stability/orders" / pol / name / "evaluation_unicycle.json"
                got = {m: per_coalition(path, f"results/stability/orders/{name}.yaml", algo, m) for m in base}
                cells = []
                for m in ("progress", "finished"):
                    t = t_interval(100 * (got[m] - base[m]))
                    cells += [f"{100 * got[m].mean():.1f}", f"{t['mean']:+.1f} [{t['lo']:+.1f}, {t['hi']:+.1f}]"]
                print(f"| {pol} | {split} | {order} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
