"""Capabilities outside the training ranges, without training (issue 30): the kept HMT policies on
U_cap and U_scale with every robot's capability features clipped, in its observations only, to its
type's U_train range (fast: speed 0.19-0.45 m, payload 5-12; slow: 0.10-0.15 m, 16-22). The robots
keep their true capabilities (task logic, physics, rewards): only what the policy reads changes. The
same teams and starts as `comat eval`'s (seed 2,000,003, 5 episodes per coalition), both conditions
run here; the difference per coalition, then its 95 % t-interval over the 20 coalitions.

    python results/stability/caps/clip.py results/policies/comat_hmt_s0 ... > results/stability/caps/clip.md
"""

import sys
from pathlib import Path

import numpy as np

from comat.envs import make_vec_env
from comat.envs.base import resolve_coalitions
from comat.eval import EVAL_SEED
from comat.measure.episodes import run_episodes
from comat.measure.metrics import mean_ci
from comat.rl import BASELINE_ROBOTS, load_policy, robot_slots
from comat.team import CAPABILITY_RANGES

EPISODES = 5
CAPS = slice(6, 8)  # HMT observation: capabilities (speed / 0.5 m, payload / 20)
SCALE = np.array([0.5, 20.0])
TYPES = slice(4, 6)  # type one-hot (fast, slow)


def training_box() -> np.ndarray:
    """(2 types, 2 caps, lo/hi) of U_train in observation units."""
    ranges = CAPABILITY_RANGES[("hmt", "train")]
    box = np.array([[[band[0][0], band[0][1]] for band in ranges[kind]] for kind in ("fast", "slow")])
    return box / SCALE[None, :, None]


def clipped(act, box):
    def wrapped(obs, mask, state):
        obs = obs.copy()
        kind = obs[..., TYPES].argmax(-1)  # (B, N): 0 fast, 1 slow
        lo, hi = box[kind, :, 0], box[kind, :, 1]
        obs[..., CAPS] = np.clip(obs[..., CAPS], lo, hi)
        return act(obs, mask, state)

    return wrapped


def per_coalition(episodes, n):
    prog = np.zeros(n)
    fin = np.zeros(n)
    for e in episodes:
        prog[e["coalition"]] += e["progress"] / EPISODES
        fin[e["coalition"]] += e["finished"] / EPISODES
    return prog, fin


def main(folders):
    box = training_box()
    print(
        "| policy | set | progress % (own) | clipped | Δ progress (points) | finished % (own) | clipped | Δ finished (points) |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for folder in map(Path, folders):
        act, config = load_policy(folder / "policy.pt", task="hmt")
        slots = robot_slots(config)
        for split in ("capability", "scale"):
            coalitions = resolve_coalitions(split, "hmt")
            teams = coalitions * EPISODES
            out = {}
            for name, policy in (("own", act), ("clipped", clipped(act, box))):
                env = make_vec_env(
                    "hmt_v0",
                    min(len(teams), 32),
                    seed=EVAL_SEED,
                    tier="unicycle",
                    coalitions=coalitions,
                    max_robots=slots,
                    state_robots=slots or BASELINE_ROBOTS,
                )
                out[name] = per_coalition(
                    run_episodes(env, policy, teams, EVAL_SEED, n_coalitions=len(coalitions)), len(coalitions)
                )
                env.close()
            cells = []
            for k in (0, 1):
                own, clip = 100 * out["own"][k], 100 * out["clipped"][k]
                d, h = mean_ci(clip - own)
                cells += [f"{own.mean():.1f}", f"{clip.mean():.1f}", f"{d:+.1f} [{d - h:+.1f}, {d + h:+.1f}]"]
            print(f"| {folder.name} | {split} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
