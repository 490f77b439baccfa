"""The must-hold of issue 66: comat's filter at ``stress`` costs no more than 1.3x its ``nominal``
tick. Times ``comat bench sim``'s loop (comat.bench.sim_bench.bench_ours: teams driven at random
goals, the controller on measured points) at both levels, interleaved (REPS rounds of 300 ticks
each), and prints the median and the mean tick (the mean carries the rare ticks a robot on probation
makes dear), by the wall clock and by the process's CPU clock (which a busy or noisy VM disturbs
less: repeated wall-clock runs on this 2-core VM moved the 8 × 64 ratio between 0.96 and 1.33),
and each round's wall-clock median ratio.

    .venv/bin/python results/safety_live/tick_cost.py > results/safety_live/tick_cost.txt
"""

from __future__ import annotations

import time

import numpy as np

from comat.bench.sim_bench import _goals, _spread
from comat.config import SimConfig
from comat.control import SafeTeams, go_to_goal
from comat.reality import resolve_reality


def ticks(n: int, batch: int, level: str, count: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    teams = SafeTeams((n,) * batch, SimConfig(tier="unicycle"), reality=resolve_reality(level), reality_seed=seed)
    teams.reset(
        np.concatenate([np.column_stack([_spread(rng, n), rng.uniform(-np.pi, np.pi, n)]) for _ in range(batch)])
    )
    goals = _goals(rng, n * batch)
    out = []
    for k in range(count + 10):
        if k % 50 == 49:
            goals = _goals(rng, n * batch)
        t0, c0 = time.perf_counter(), time.process_time()
        teams.tick(go_to_goal(teams.measured_points, goals, max_speed=0.15))
        if k >= 10:
            out.append((time.perf_counter() - t0, time.process_time() - c0))
    return np.array(out) * 1e3, int(teams.fallbacks.sum()), teams.subset_solves


REPS = 4


if __name__ == "__main__":
    print(
        f"{'N':>3} {'B':>3} {'level':8s} {'median ms':>9s} {'mean ms':>8s} {'CPU median':>10s} {'brakes':>6s} {'subset':>6s}"
    )
    for n, b in ((8, 64), (16, 8), (20, 4)):
        res = {}
        for rep in range(REPS):  # interleaved, so a busy machine weighs on both levels alike
            for level in ("nominal", "stress"):
                res.setdefault(level, []).append(ticks(n, b, level, 300, seed=rep))
        t = {lv: np.concatenate([r[0] for r in runs]) for lv, runs in res.items()}
        for level, runs in res.items():
            print(f"{n:>3} {b:>3} {level:8s} {np.median(t[level][:, 0]):>9.2f} {t[level][:, 0].mean():>8.2f} "
                  f"{np.median(t[level][:, 1]):>10.2f} {sum(r[1] for r in runs):>6d} {sum(r[2] for r in runs):>6d}")  # fmt: skip
        wall, cpu = (np.median(t["stress"][:, k]) / np.median(t["nominal"][:, k]) for k in (0, 1))
        rounds = [np.median(s[0][:, 0]) / np.median(o[0][:, 0]) for s, o in zip(res["stress"], res["nominal"])]
        print(
            f"    stress / nominal: median {wall:.2f}x, mean {t['stress'][:, 0].mean() / t['nominal'][:, 0].mean():.2f}x, "
            f"CPU median {cpu:.2f}x; per round (wall median) {', '.join(f'{r:.2f}' for r in rounds)}"
        )
