"""``comat bench soak``: many episodes of the reference policies, checking that nothing drifts.

Episodes of the scripted and the random policy on U_train and U_test of every task, in the
unicycle tier with a share in the wheels tier, run in vector environments of 32 (one process).
Counted over all of them: MuJoCo robot–robot contacts, Robotarium-style collisions, boundary
exits, actuator errors, NaN in observations (env steps) or returns (episodes), filter recovery
and fallback ticks; and
the process's resident memory, sampled after every batch (one vector env's pass over a set's
20 coalitions, which ends by dropping that env's OSQP problems and handing free heap pages back
to the OS: :meth:`comat.envs.VectorEnv.release_solvers`), and its peak during every batch.
Growth is measured from the first to the last thousand episodes on the median and on the peak of
the after-batch samples in each, and on the median of the batch peaks (target < 5 % for all
three): a single sample depends on the batch that ran last. The after-batch samples at each
thousand are kept too (``rss_bytes``).
Episodes start inside the safe set (the envs' spawn), so the safety targets are zero contacts,
zero collisions and zero fallbacks.
"""

from __future__ import annotations

import os
import platform
import time

import numpy as np

from comat.bench.sim_bench import finish
from comat.envs import make_vec_env
from comat.envs.base import resolve_coalitions
from comat.envs.heuristics import heuristic_actions, random_actions
from comat.measure.episodes import run_episodes
from comat.tasks import env_id, task_names
from comat.team import COALITION_SETS

__all__ = ["MEMORY_GROWTH_TARGET", "run_soak"]

MEMORY_GROWTH_TARGET = 0.05
"""Largest accepted growth of resident memory from the first to the last thousand episodes."""
_ENVS = 32


def _rss_bytes() -> int:
    """Resident set size of this process (Linux /proc; 0 where unavailable)."""
    try:
        with open("/proc/self/statm") as fh:
            return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        return 0


def _peak_rss_bytes() -> int:
    """Highest resident set size since the last :func:`_reset_peak_rss` (Linux VmHWM; 0 where unavailable)."""
    try:
        with open("/proc/self/status") as fh:
            return next(int(line.split()[1]) * 1024 for line in fh if line.startswith("VmHWM:"))
    except (OSError, ValueError, IndexError, StopIteration):
        return 0


def _reset_peak_rss() -> None:
    """Start a new peak: VmHWM falls to the current RSS (Linux >= 4.0; no-op where unavailable)."""
    try:
        with open("/proc/self/clear_refs", "w") as fh:
            fh.write("5")
    except OSError:
        pass


def _first_and_last_thousand(samples: list[tuple[int, int]], window: int) -> tuple[dict, dict]:
    """Median and peak of the (episodes done, RSS) samples taken within the first ``window``
    episodes and within the last ``window`` (the same samples when the run is that short)."""
    total = samples[-1][0]
    first = [rss for done, rss in samples if done <= window] or [samples[0][1]]
    last = [rss for done, rss in samples if done > total - window] or [samples[-1][1]]
    return tuple({"median": float(np.median(w)), "peak": float(max(w)), "samples": len(w)} for w in (first, last))


def _growth(first: float, last: float) -> float:
    return (last - first) / first if first else 0.0


def _episodes(env, policy: str, teams, seed: int, rng: np.random.Generator) -> tuple[list[dict], int]:
    """One episode per team (``comat.measure.episodes.run_episodes``) and the number of env steps
    whose observations held NaN or inf (seen by the policy wrapper)."""

    bad_steps = 0

    def act(obs, mask, state):
        nonlocal bad_steps
        bad_steps += int(not np.isfinite(obs).all())
        return heuristic_actions(env.core) if policy == "heuristic" else random_actions(rng, mask)

    return run_episodes(env, act, teams, seed), bad_steps


def run_soak(
    episodes: int = 10_000,
    wheels_share: float = 0.1,
    seed: int = 0,
    out: str | None = None,
    progress=print,
    sets=("train", "test"),
) -> dict:
    # long: one soak: checks, the episode loop with its memory samples, then the table
    """At least ``episodes`` episodes (a multiple of 20 coalitions × 2 policies × len(sets) × tasks);
    resident memory is sampled after every batch and compared over the first and the last thousand
    episodes (tenth of a shorter run)."""

    sets = tuple(sets)
    if not sets or any(s not in COALITION_SETS for s in sets) or len(set(sets)) < len(sets):
        raise ValueError(f"sets must be distinct names of {list(COALITION_SETS)}, got {list(sets)!r}")
    per_round = 20 * 2 * 2 * len(sets)
    if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < per_round:
        raise ValueError(
            f"episodes must be an integer >= {per_round} (one round of every task, set and policy), got {episodes!r}"
        )
    if not 0 <= wheels_share <= 1:
        raise ValueError(f"wheels_share must be in [0, 1], got {wheels_share!r}")
    rng = np.random.default_rng(seed)
    combos = [(task, split, policy) for task in task_names() for split in sets for policy in ("heuristic", "random")]
    envs = {
        (task, split, tier): make_vec_env(env_id(task), _ENVS, seed=seed, tier=tier, coalitions=split)
        for task in task_names()
        for split in sets
        for tier in ("unicycle", "wheels")
    }
    # Warm-up, not counted: a few steps in every environment, so that what is allocated on first
    # use (MuJoCo data, filters, compiled kernels) is in place before the first memory sample; the
    # wheels environments are otherwise first used at random moments. Their OSQP problems are
    # dropped again, as after every batch (held, they would inflate the first samples).

    for env in envs.values():
        _, info = env.reset(seed=seed)
        for _ in range(3):
            _, _, _, _, info = env.step(random_actions(rng, info["agent_mask"]))
        env.release_solvers()
    totals = {
        k: 0.0
        for k in (
            "episodes",
            "collisions",
            "robotarium_collisions",
            "boundary_exits",
            "actuator_errors",
            "nan_obs_steps",
            "nan_returns",
            "recoveries",
            "fallbacks",
            "interventions",
            "finished",
        )
    }
    by_tier = {"unicycle": 0, "wheels": 0}
    memory: list[tuple[int, int]] = []
    batches: list[tuple[int, int]] = []
    batch_peaks: list[tuple[int, int]] = []
    done, rounds, t0 = 0, 0, time.perf_counter()
    mark_every = max(per_round, min(1000, episodes // 10))
    next_mark = mark_every
    while done < episodes:
        for task, split, policy in combos:
            tier = "wheels" if rng.random() < wheels_share else "unicycle"
            teams = resolve_coalitions(split, task)
            _reset_peak_rss()
            # run_episodes ends by dropping the env's OSQP problems and trimming the heap
            eps, bad_obs_steps = _episodes(envs[task, split, tier], policy, teams, seed + 1000 * rounds, rng)
            done += len(eps)
            batch_peaks.append((done, _peak_rss_bytes()))
            batches.append((done, _rss_bytes()))
            by_tier[tier] += len(eps)
            totals["nan_obs_steps"] += bad_obs_steps
            for e in eps:
                totals["episodes"] += 1
                totals["nan_returns"] += not np.isfinite(e["return"])
                for key in (
                    "collisions",
                    "robotarium_collisions",
                    "boundary_exits",
                    "actuator_errors",
                    "recoveries",
                    "fallbacks",
                    "interventions",
                ):
                    totals[key] += e[key]
                totals["finished"] += e["finished"] if policy == "heuristic" else 0.0
            if done >= next_mark:
                memory.append(batches[-1])
                next_mark += mark_every
                rate = done / (time.perf_counter() - t0)
                recent = np.median([rss for d, rss in batches if d > done - mark_every]) / 2**20
                progress(
                    f"  {done:,} / {episodes:,} episodes, {rate:.1f} episodes/s, RSS {memory[-1][1] / 2**20:.0f} MiB "
                    f"(median of the last {mark_every:,}: {recent:.0f} MiB)"
                )
        rounds += 1
    for env in envs.values():
        env.close()
    windows = _first_and_last_thousand(batches, mark_every)
    growth = {stat: _growth(windows[0][stat], windows[1][stat]) for stat in ("median", "peak")}
    peak_windows = _first_and_last_thousand(batch_peaks, mark_every)
    growth["batch_peak_median"] = _growth(peak_windows[0]["median"], peak_windows[1]["median"])
    first, last = (memory[0][1], memory[-1][1]) if memory else (0, 0)
    checks = {
        name: {"value": totals[key], "target": "== 0", "pass": totals[key] == 0}
        for name, key in (
            ("mujoco_contacts", "collisions"),
            ("robotarium_collisions", "robotarium_collisions"),
            ("boundary_exits", "boundary_exits"),
            ("actuator_errors", "actuator_errors"),
            ("nan_observation_steps", "nan_obs_steps"),
            ("nan_returns", "nan_returns"),
            ("fallback_ticks", "fallbacks"),
        )
    }
    for name, stat in (
        ("batch_peak_rss_growth_first_to_last_thousand_median", "batch_peak_median"),
        ("rss_growth_first_to_last_thousand_median", "median"),
        ("rss_growth_first_to_last_thousand_peak", "peak"),
    ):
        checks[name] = {
            "value": growth[stat],
            "target": f"< {MEMORY_GROWTH_TARGET}",
            "pass": growth[stat] < MEMORY_GROWTH_TARGET,
        }
    result = {
        "benchmark": "soak",
        "machine": {"platform": platform.platform(), "cpus": os.cpu_count()},
        "sets": list(sets),
        "episodes": int(totals["episodes"]),
        "episodes_by_tier": by_tier,
        "totals": totals,
        "scripted_finished_share": totals["finished"] / max(1.0, totals["episodes"] / 2),
        "rss_windows": {"first": windows[0], "last": windows[1]},
        "batch_peak_rss_windows": {"first": peak_windows[0], "last": peak_windows[1]},
        "rss_peak_bytes_per_batch": batch_peaks,
        "rss_growth_first_to_last_mark": _growth(first, last),
        "rss_bytes_per_batch": batches,
        "rss_bytes": memory,
        "wall_s": time.perf_counter() - t0,
        "checks": checks,
    }
    progress(f"{'metric':<28}{'total':>14}")
    for key, value in totals.items():
        progress(f"{key:<28}{value:>14,.0f}")
    for stat in ("median", "peak"):
        mib = f"{windows[0][stat] / 2**20:.0f} → {windows[1][stat] / 2**20:.0f} MiB"
        progress(f"{f'RSS {stat}, first → last {mark_every}':<28}{100 * growth[stat]:>13.2f}%  ({mib})")
    mib = f"{peak_windows[0]['median'] / 2**20:.0f} → {peak_windows[1]['median'] / 2**20:.0f} MiB"
    progress(f"{'batch peak RSS, median':<28}{100 * growth['batch_peak_median']:>13.2f}%  ({mib})")
    return finish(result, checks, out, progress)
