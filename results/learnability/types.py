"""What each robot type of a kept forage policy does (issue 65's diagnosis): per type, the share of each
action and the mean position while it plays U_val (deterministic, 40 environments, one episode each,
episode seed 2,000,003), and from the run's own evaluation on U_train (``evaluation_unicycle.json``,
5 episodes per coalition) the share of a robot's steps it stayed by choice (``still_idle``), was held
(chose to move, moved < 20 % of its step: the filter, a teammate or a wall stopped it) and the lifts it
helped per robot and episode. A markdown table on stdout.

    .venv/bin/python results/learnability/types.py results/tasks/runs/comat_forage_s100 ... > types.md

Descriptive: one policy per folder; episodes are not independent seeds.
"""

import sys
from pathlib import Path

import numpy as np

import comat
from comat.measure.metrics import read_results

TYPES = ("heavy", "light")
ACTIONS = ("stay", "+x", "−x", "+y", "−y")


def action_shares(folder: str, envs: int = 40, seed: int = 2_000_003) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """{type id: ((5,) action shares, (2,) mean x, y)} over U_val episodes, live robots only."""
    policy = comat.load_policy(folder, deterministic=True)
    vec = comat.make_vec_env("forage_v0", envs, seed=seed, coalitions="val", tier="unicycle")
    obs, info = vec.reset()
    core, live = vec.core, np.ones(envs, dtype=bool)
    counts = {t: np.zeros(5) for t in range(len(TYPES))}
    where = {t: [] for t in range(len(TYPES))}
    for _ in range(core.task.horizon):
        mask = info["agent_mask"]
        actions = policy.act(obs, mask)
        for t in counts:
            sel = mask & (core.type_ids == t) & live[:, None]
            counts[t] += np.bincount(actions[sel], minlength=5)
            where[t].append(obs[sel][:, :2])
        obs, _, term, trunc, info = vec.step(actions)
        live &= ~(term | trunc)
    return {t: (counts[t] / counts[t].sum(), np.concatenate(where[t]).mean(0)) for t in counts}


def behaviour(folder: str, split: str = "train") -> dict[str, tuple[float, float, float]]:
    """{type: (idle share, held share, lifts per robot and episode)} from the run's own evaluation."""
    rows = read_results(Path(folder) / "evaluation_unicycle.json")["rows"]
    eps = next(r["per_episode"] for r in rows if r["set"] == split and r["policy"] not in comat_references())
    out = {}
    for t in TYPES:
        by = [(e["by_type"][t], e["steps"]) for e in eps if t in e["by_type"]]
        out[t] = (
            float(np.mean([b["still_idle"] / s for b, s in by])),
            float(np.mean([b["still_held"] / s for b, s in by])),
            float(np.mean([b["lifting"] / b["robots"] for b, _ in by])),
        )
    return out


def comat_references() -> tuple[str, ...]:
    from comat.tasks import LADDER

    return LADDER


def main(folders: list[str]) -> None:
    print("| run | type | " + " | ".join(ACTIONS) + " | mean x, y (m) | idle | held | lifts / robot |")
    print("|---|---|" + "---:|" * (len(ACTIONS) + 4))
    for folder in folders:
        shares, acts = behaviour(folder), action_shares(folder)
        for t, name in enumerate(TYPES):
            share, xy = acts[t]
            idle, held, lifts = shares[name]
            print(
                f"| {Path(folder).name} | {name} | "
                + " | ".join(f"{100 * s:.0f} %" for s in share)
                + f" | {xy[0]:+.2f}, {xy[1]:+.2f} | {100 * idle:.0f} % | {100 * held:.0f} % | {lifts:.2f} |"
            )


if __name__ == "__main__":
    main(sys.argv[1:])
