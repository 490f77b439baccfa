"""Issue 50's first look (descriptive): IPPO and CASH beside the grid's COMAT, MAT and MAPPO.

Writes README.md's table between its markers from the kept runs' evaluation files: IPPO and CASH
from ``runs/`` here, COMAT, MAT and MAPPO from ``results/grid_v3/runs/`` (the same protocol: sweep
preset, 300 k env steps, trained at reality off, seeds 100-102, 5 episodes per coalition). Each
cell is the mean progress % over the seeds kept so far, with the seeds' SD and their count; no
number is typed by hand. A second table says which robot type delivers HMT's material on U_train
(the per-episode ``by_type`` counts of the evaluation's detail file). Descriptive only: no test, no
selection.
"""

from pathlib import Path

import numpy as np

from comat.eval import SET_NAMES
from comat.files import replace_block
from comat.measure.metrics import read_results

HERE = Path(__file__).resolve().parent
GRID = HERE.parent / "grid_v3" / "runs"
SETS = ("train", "val", "test", "scale", "size", "capability")
SEEDS = (100, 101, 102)
LEARNERS = (("ippo", HERE / "runs"), ("cash", HERE / "runs"), ("comat", GRID), ("mat", GRID), ("mappo", GRID))
LEVELS = (("off", "evaluation_unicycle.json"), ("nominal", "evaluation_unicycle_nominal.json"))


def progress_by_seed(folder: Path, algo: str, task: str, file: str) -> dict[str, list[float]]:
    """set -> progress % of each kept seed (trained at off, 300 k)."""
    out: dict[str, list[float]] = {}
    for seed in SEEDS:
        path = folder / f"{algo}_{task}_off_s{seed}" / file
        if not path.is_file():
            continue
        for row in read_results(path, detail=False)["rows"]:
            if row["policy"] == algo:
                out.setdefault(row["set"], []).append(100 * row["metrics"]["progress"]["mean"])
    return out


def deliveries_by_seed(folder: Path, algo: str) -> dict[str, list[float]]:
    """HMT U_train at off, per kept seed: the mean material delivered per episode by the fast and
    by the slow robots, and the slow robots' share of it (%)."""
    out: dict[str, list[float]] = {}
    for seed in SEEDS:
        path = folder / f"{algo}_hmt_off_s{seed}" / "evaluation_unicycle.json"
        if not path.is_file():
            continue
        row = next(r for r in read_results(path)["rows"] if r["policy"] == algo and r["set"] == "train")
        fast = [ep["by_type"]["fast"]["delivered_sum"] for ep in row["per_episode"]]
        slow = [ep["by_type"]["slow"]["delivered_sum"] for ep in row["per_episode"]]
        out.setdefault("fast", []).append(float(np.mean(fast)))
        out.setdefault("slow", []).append(float(np.mean(slow)))
        out.setdefault("share", []).append(100 * float(np.sum(slow) / max(np.sum(fast) + np.sum(slow), 1e-9)))
    return out


def cell(values: list[float] | None) -> str:
    if not values:
        return "—"
    sd = f" ± {np.std(values, ddof=1):.1f}" if len(values) > 1 else ""
    return f"{np.mean(values):.1f}{sd} ({len(values)})"


def main() -> None:
    lines = [
        "Progress %: mean over seeds ± seed SD (number of seeds kept); trained at reality off, evaluated at the",
        "level named. COMAT, MAT and MAPPO are the grid's runs (`results/grid_v3/`). — : not run yet.",
        "",
    ]
    for task in ("pcp", "hmt"):
        for level, file in LEVELS:
            lines += [f"### {task.upper()}, evaluated at {level}", ""]
            lines.append("| learner | " + " | ".join(SET_NAMES[s] for s in SETS) + " |")
            lines.append("|---|" + "---:|" * len(SETS))
            for algo, folder in LEARNERS:
                got = progress_by_seed(folder, algo, task, file)
                lines.append(f"| {algo} | " + " | ".join(cell(got.get(s)) for s in SETS) + " |")
            lines.append("")
    lines += [
        "### HMT, who delivers (U_train, evaluated at off)",
        "",
        "Material delivered per episode by each type's robots together (mean over episodes, then over seeds),",
        "and the slow robots' share of all delivered.",
        "",
        "| learner | fast robots | slow robots | slow share % |",
        "|---|---:|---:|---:|",
    ]
    for algo, folder in LEARNERS:
        got = deliveries_by_seed(folder, algo)
        lines.append(f"| {algo} | " + " | ".join(cell(got.get(k)) for k in ("fast", "slow", "share")) + " |")
    lines.append("")
    replace_block(HERE / "README.md", "table", "\n".join(lines))
    print(f"wrote {HERE / 'README.md'}")


if __name__ == "__main__":
    main()
