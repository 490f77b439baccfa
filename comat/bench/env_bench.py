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

from comat.bench.sim_bench import bench_rps, finish, rps_available
from comat.envs import make_vec_env
from comat.envs.heuristics import random_actions
from comat.envs.sharded import shard_slices
from comat.tasks import env_id, task_entry, task_names
from comat.team import random_team

__all__ = ["EnvBenchRow", "bench_env", "bench_rollout_split", "run_env_bench", "run_rollout_bench"]

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

    team = random_team(np.random.default_rng(seed), task, "train", n)
    env = make_vec_env(env_id(task), batch, seed=seed, team=team, tier=tier)
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

    if not rps_available():
        return None
    ticks = task_entry(task).logic.ticks_per_step
    row = bench_rps(n, iterations)
    return EnvBenchRow("robotarium-rps loop", task, "euler", n, 1, 1e6 / (row.tick_us * ticks), iterations)


def run_env_bench(
    tasks=None,
    tiers=("wheels", "unicycle"),
    sizes=(2, 5, 8, 12, 16, 20),
    batches=(1, 64),
    steps: int = 20,
    out=None,
    progress=print,
) -> dict:
    """Every task (``tasks``, default all registered) by size, tier and batch, a table on ``progress``
    and JSON at ``out``."""
    tasks = task_names() if tasks is None else tuple(tasks)
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

    return finish(result, checks, out, progress)


def _checks(rows: list[EnvBenchRow]) -> dict:
    checks = {}
    for tier, factor in (("unicycle", 20), ("wheels", 5)):
        r = next(
            (
                r
                for r in rows
                if r.system == "comat" and r.task == "pcp" and r.tier == tier and r.batch == 64 and r.n_robots == 4
            ),
            None,
        )
        if r:
            ratio = r.env_steps_per_s / MARBLER_PCP4_REPORTED
            checks[f"pcp4_{tier}_B64_vs_marbler"] = {"value": ratio, "target": f">= {factor}", "pass": ratio >= factor}
    return checks


def _timed_shard(task: str, tier: str, first: int, count: int, total: int, steps: int, seed: int) -> dict:
    """ms per vector step of environments first..first+count-1 of ``total`` (training coalitions,
    random actions), split into physics, OSQP, the rest of the ticks and the rest of the step."""

    env = make_vec_env(env_id(task), count, seed=seed, tier=tier, shard=(first, total))
    rng = np.random.default_rng(seed + first)
    env.reset()
    for _ in range(2):  # first-call set-ups out of the timing
        env.step(random_actions(rng, env.agent_mask))
    split = np.zeros(3)

    def observe(*_):
        t = env.core.safe.timing
        split[:] += (t.total, t.physics, t.solver)

    env.core.safe.tick_observers.append(observe)
    robots = 0
    t0 = time.perf_counter()
    for _ in range(steps):
        robots += int(env.agent_mask.sum())
        env.step(random_actions(rng, env.agent_mask))
    step_ms = (time.perf_counter() - t0) / steps * 1e3
    ticks, physics, osqp = split / steps * 1e3
    return {
        "envs": [first, first + count - 1],
        "robots": robots / steps,
        "step_ms": step_ms,
        "physics_ms": physics,
        "osqp_ms": osqp,
        "tick_rest_ms": ticks - physics - osqp,
        "outside_ticks_ms": step_ms - ticks,
    }


def bench_rollout_split(
    task: str = "pcp", tier: str = "unicycle", batch: int = 32, workers: int = 2, steps: int = 8, seed: int = 0
) -> dict:
    """Where a rollout step's time goes: the whole batch in one process, then each of the
    ``workers`` shards an env process would hold, timed one after the other (their maximum is
    what a step with that many processes costs at best), plus a single environment (the fixed
    part)."""

    whole = _timed_shard(task, tier, 0, batch, batch, steps, seed)
    shards = [
        _timed_shard(task, tier, sl.start, sl.stop - sl.start, batch, steps, seed)
        for sl in shard_slices(batch, workers)
    ]
    single = _timed_shard(task, tier, 0, 1, batch, steps, seed)
    best = max(r["step_ms"] for r in shards)
    return {
        "task": task,
        "tier": tier,
        "batch": batch,
        "workers": workers,
        "steps": steps,
        "whole": whole,
        "shards": shards,
        "single_env": single,
        "sharded_step_ms_lower_bound": best,
        "sharding_speedup_upper_bound": whole["step_ms"] / best,
    }


def run_rollout_bench(
    task: str = "pcp",
    tier: str = "unicycle",
    batch: int = 32,
    workers: int = 2,
    steps: int = 8,
    out=None,
    progress=print,
) -> dict:
    """``comat bench env --rollout``: :func:`bench_rollout_split` as a table and JSON."""
    r = bench_rollout_split(task, tier, batch, workers, steps)
    head = f"{'environments':<16}{'robots':>8}{'step ms':>9}{'physics':>9}{'OSQP':>7}{'tick rest':>11}{'outside':>9}"
    progress(
        f"comat bench env --rollout: {task}, {tier}, training coalitions, random actions, {steps} steps\n"
        + head
        + "\n"
        + "-" * len(head)
    )
    for label, row in (
        [("all", r["whole"])] + [(f"shard {i}", x) for i, x in enumerate(r["shards"])] + [("one env", r["single_env"])]
    ):
        progress(
            f"{label + ' ' + str(row['envs'][0]) + '-' + str(row['envs'][1]):<16}{row['robots']:>8.0f}"
            f"{row['step_ms']:>9.1f}{row['physics_ms']:>9.1f}{row['osqp_ms']:>7.1f}{row['tick_rest_ms']:>11.1f}"
            f"{row['outside_ticks_ms']:>9.1f}"
        )
    progress(
        f"{workers} env processes: a step costs at least {r['sharded_step_ms_lower_bound']:.1f} ms (the slowest "
        f"shard), at most {r['sharding_speedup_upper_bound']:.2f}x faster than one process"
    )

    result = {
        "benchmark": "env-rollout",
        "machine": {"platform": platform.platform(), "python": platform.python_version(), "cpus": os.cpu_count()},
        **r,
    }
    return finish(result, {}, out, progress)
