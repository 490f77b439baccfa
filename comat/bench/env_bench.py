"""``comat bench env``: env-steps per second with random actions, per task, tier, batch and team size.

Each configuration runs a :class:`comat.envs.VectorEnv` of B environments with one fixed team
of N robots (types and capabilities drawn like the training set), random actions, safety filter
at every control tick, autoreset included. Next to it, the Robotarium simulator's own loop with
its unicycle barrier at every iteration, timed here for the same team size and turned into
env-steps/s with the task's ticks per step — the cost floor of MARBLER's "Robotarium mode"
(MARBLER adds its own Python on top; it measured 15 env-steps/s for 4-robot PCP on this machine
class, reference/robotarium-marbler.md §5.2).
"""

from __future__ import annotations

import os
import platform
import time
from dataclasses import asdict, dataclass

import numpy as np

__all__ = ["EnvBenchRow", "bench_env", "run_env_bench"]

MARBLER_PCP4_REPORTED = 15.0
"""MARBLER PCP, 4 robots, barrier every iteration: env-steps/s measured on this machine class."""


@dataclass
class EnvBenchRow:
    system: str
    task: str
    tier: str
    n_robots: int
    batch: int
    env_steps_per_s: float
    steps: int


def bench_env(task: str, tier: str, n: int, batch: int, steps: int, seed: int = 0) -> EnvBenchRow:
    """Time ``steps`` vector steps of B environments with a fixed random team of n robots."""
    from comat.envs import make_vec_env
    from comat.envs.heuristics import random_actions
    from comat.team import random_team

    team = random_team(np.random.default_rng(seed), task, "train", n)
    env = make_vec_env(f"{task}_v0", batch, seed=seed, team=team, tier=tier)
    rng = np.random.default_rng(seed)
    env.reset()
    env.step(random_actions(rng, env.agent_mask))  # first-call set-ups out of the timing
    t0 = time.perf_counter()
    for _ in range(steps):
        env.step(random_actions(rng, env.agent_mask))
    dt = time.perf_counter() - t0
    return EnvBenchRow("comat", task, tier, n, batch, steps * batch / dt, steps)


def bench_rps_env(task: str, n: int, iterations: int = 150) -> EnvBenchRow | None:
    """The Robotarium loop with its barrier every iteration, per env step of ``task``."""
    from comat.bench.sim_bench import bench_rps, rps_available
    from comat.task_logic import HMT, PCP

    if not rps_available():
        return None
    ticks = {"pcp": PCP, "hmt": HMT}[task].ticks_per_step
    row = bench_rps(n, iterations)
    return EnvBenchRow("robotarium-rps loop", task, "euler", n, 1, 1e6 / (row.tick_us * ticks), iterations)


def run_env_bench(
    tasks=("pcp", "hmt"), tiers=("wheels", "unicycle"), sizes=(2, 5, 8, 16), batches=(1, 64), steps: int = 20, out=None, progress=print
) -> dict:
    rows: list[EnvBenchRow] = []
    for task in tasks:
        for n in sizes:
            for tier in tiers:
                for b in batches:
                    progress(f"  {task} {tier:<8} N={n:<3} B={b:<3} ...")
                    # Fewer steps for the big batches: each already covers B env steps.
                    rows.append(bench_env(task, tier, n, b, steps if b == 1 else max(3, steps // 4)))
        if task == "pcp":  # the speed target: PCP with 4 robots, batch 64
            for tier in tiers:
                progress(f"  {task} {tier:<8} N=4   B=64  ...")
                rows.append(bench_env(task, tier, 4, 64, max(3, steps // 4)))
        rps = bench_rps_env(task, 4)
        if rps:
            rows.append(rps)
    checks = _checks(rows)
    result = {
        "benchmark": "env",
        "machine": {"platform": platform.platform(), "python": platform.python_version(), "cpus": os.cpu_count()},
        "actions": "uniformly random",
        "marbler_pcp4_reported_env_steps_per_s": MARBLER_PCP4_REPORTED,
        "rows": [asdict(r) for r in rows],
        "checks": checks,
    }
    head = f"{'system':<20}{'task':<6}{'tier':<10}{'N':>4}{'B':>5}{'env-steps/s':>14}"
    progress(head + "\n" + "-" * len(head))
    for r in rows:
        progress(f"{r.system:<20}{r.task:<6}{r.tier:<10}{r.n_robots:>4}{r.batch:>5}{r.env_steps_per_s:>14.1f}")
    from comat.bench.sim_bench import finish

    return finish(result, checks, out, progress)


def _checks(rows: list[EnvBenchRow]) -> dict:
    checks = {}
    for tier, factor in (("unicycle", 20), ("wheels", 5)):
        r = next((r for r in rows if r.system == "comat" and r.task == "pcp" and r.tier == tier and r.batch == 64 and r.n_robots == 4), None)
        if r:
            ratio = r.env_steps_per_s / MARBLER_PCP4_REPORTED
            checks[f"pcp4_{tier}_B64_vs_marbler"] = {"value": ratio, "target": f">= {factor}", "pass": ratio >= factor}
    return checks
