"""The diagnosis runs' curves side by side (issue 65): per arm, the training progress (stochastic
policy, mean over the updates in each 20 k-step bin) with the policy's entropy, and the periodic
deterministic evaluation on U_train (``eval.csv``: one episode per coalition, every 50 k steps).
A markdown table on stdout.

    .venv/bin/python results/learnability/diag_curves.py results/learnability/diag/mat_navigation_s0_bootstrap ...

Exploratory: one seed per arm; it says where to look, not what holds over seeds.
"""

import csv
import sys
from pathlib import Path

import numpy as np

BIN = 20_000


def curves(folder: Path) -> tuple[dict[int, tuple[float, float]], dict[int, float]]:
    """({bin start: (training progress, entropy)}, {env steps: deterministic U_train progress})."""
    rows = list(csv.DictReader((folder / "progress.csv").read_text().splitlines()))
    train = {}
    for lo in range(0, max(int(r["env_steps"]) for r in rows) + 1, BIN):
        sel = [r for r in rows if lo <= int(r["env_steps"]) < lo + BIN]
        if sel:
            train[lo] = (
                float(np.mean([float(r["episode_progress"]) for r in sel])),
                float(np.mean([float(r["entropy"]) for r in sel])),
            )
    evals = {
        int(r["env_steps"]): float(r["progress"])
        for r in csv.DictReader((folder / "eval.csv").read_text().splitlines())
    }
    return train, evals


def main(folders: list[str], upto: int = 300_000) -> None:
    arms = {Path(f).name: curves(Path(f)) for f in folders}
    print("Training progress % / entropy (nats), mean over each 20 k-step bin:\n")
    print("| env steps | " + " | ".join(arms) + " |")
    print("|---:|" + "---:|" * len(arms))
    for lo in range(0, upto, BIN):
        cells = [f"{100 * a[0][lo][0]:.1f} / {a[0][lo][1]:.2f}" if lo in a[0] else "—" for a in arms.values()]
        print(f"| {lo // 1000}–{(lo + BIN) // 1000} k | " + " | ".join(cells) + " |")
    steps = sorted({s for a in arms.values() for s in a[1]})
    print("\nDeterministic progress % on U_train (one episode per coalition):\n")
    print("| env steps | " + " | ".join(arms) + " |")
    print("|---:|" + "---:|" * len(arms))
    for s in steps:
        cells = [f"{100 * a[1][s]:.1f}" if s in a[1] else "—" for a in arms.values()]
        print(f"| {s:,} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main(sys.argv[1:])
