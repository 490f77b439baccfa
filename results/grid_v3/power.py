"""Issue 33's seed counts, recomputed from the stability confirmation's seed spread (the plan's
"Seeds" section quotes this script's output):

    python results/grid_v3/power.py > results/grid_v3/power.md

Planning SD per learner and task: max(2.5 × its per-seed SD of U_val progress in
results/stability/confirm/runs/, 3 points). Why 2.5: the unseen sets spread seeds more than U_val
does; for the old COMAT default its seeds' SD was 4.5 points on U_val (the stability screen's
control, seeds 0-2) and 11.2 on the first grid's U_scale (science-turn3.md §1), a ratio of 2.5.
Why a floor of 3: 5 seeds pin an SD down poorly (its 95 % upper bound is 2.9 × the estimate), and
the issue's stability target counts 3 points as small. Power of Welch's two-sided test at
α = 0.05 by simulation (normal per-seed means, 20,000 draws, seeded): no closed form is exact for
Welch's df.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy import stats

from comat.measure.metrics import read_results  # an evaluation with its per-episode detail

ROOT = Path(__file__).resolve().parents[2]
CONFIRM = ROOT / "results" / "stability" / "confirm" / "runs"
INFLATION, FLOOR = 2.5, 3.0
DRAWS = 20_000


def confirmation_sd(task: str, learner: str) -> tuple[float, int]:
    """Per-seed SD of U_val progress (points) and the number of seeds, from the kept runs."""
    values = []
    for folder in sorted(CONFIRM.glob(f"{'mat_control' if learner == 'mat' else 'adapters'}_{task}_s*")):
        data = read_results(folder / "evaluation_unicycle.json")
        row = next(
            r for r in data["rows"] if r["set"] == "val" and r["policy"] not in ("heuristic", "constant", "random")
        )
        values.append(100 * np.mean([e["progress"] for e in row["per_episode"]]))
    return float(np.std(values, ddof=1)), len(values)


def welch_power(n1: int, n2: int, sd1: float, sd2: float, delta: float, seed: int = 0) -> float:
    """Share of simulated grids in which Welch's test (two-sided, α = 0.05) finds a true ``delta``."""
    rng = np.random.default_rng(seed)
    a = rng.normal(delta, sd1, (DRAWS, n1))
    b = rng.normal(0.0, sd2, (DRAWS, n2))
    return float(np.mean(stats.ttest_ind(a, b, axis=1, equal_var=False).pvalue < 0.05))


def main() -> None:
    print("# Issue 33: seed counts from the stability confirmation\n")
    print(f"Planning SD = max({INFLATION} × confirmation SD on U_val, {FLOOR} points); MAPPO was not in the")
    print("confirmation and gets MAT's. Power of Welch's test (α = 0.05, two-sided), COMAT vs each baseline.\n")
    plan_sd = {}
    print("| task | learner | confirmation SD (seeds) | planning SD |")
    print("|---|---|---|---|")
    for task in ("hmt", "pcp"):
        for learner in ("comat", "mat"):
            sd, n = confirmation_sd(task, learner)
            plan_sd[task, learner] = max(INFLATION * sd, FLOOR)
            print(f"| {task} | {learner} | {sd:.2f} ({n}) | {plan_sd[task, learner]:.1f} |")
        plan_sd[task, "mappo"] = plan_sd[task, "mat"]
    print(
        "\n| task | COMAT seeds | baseline seeds | planning SDs | power Δ = 10 | power Δ = 5 | "
        "power Δ = 10 at twice COMAT's SD |"
    )
    print("|---|---|---|---|---|---|---|")
    for task in ("hmt", "pcp"):
        sc, sb = plan_sd[task, "comat"], plan_sd[task, "mat"]
        for nc, nb in ((3, 3), (4, 4), (5, 5), (6, 4), (6, 6), (8, 6), (8, 8), (12, 6)):
            print(
                f"| {task} | {nc} | {nb} | {sc:.1f} / {sb:.1f} | {welch_power(nc, nb, sc, sb, 10):.2f} | "
                f"{welch_power(nc, nb, sc, sb, 5):.2f} | {welch_power(nc, nb, 2 * sc, sb, 10):.2f} |"
            )


if __name__ == "__main__":
    main()
