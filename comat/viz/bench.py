"""``comat bench viz``: what recording a rollout costs, in time and in bytes.

For each task, the same episodes (same policy, teams and seeds, hence the same steps) run
``repeats`` times without a recorder and ``repeats`` times recorded to a temporary ``.rrd``,
alternating so that background load hits both alike, after one warm-up of each (imports,
MuJoCo models, OSQP set-up, Rerun's first-use initialization). Each rollout is timed in wall
seconds and in CPU seconds of this process (all its threads, Rerun's encoder and writer
included); CPU time is the robust figure on a shared machine, where wall time also counts
other processes. Reported per task:

| key | meaning |
|---|---|
| ``plain_cpu_s``, ``recorded_cpu_s`` | median CPU time of a rollout (recorded: writing and closing the file included) |
| ``overhead_cpu`` | median over the repeats of (recorded / plain run just before it) - 1 (budget: <= 0.10) |
| ``recorder_cpu_s``, ``background_cpu_s`` | median CPU time the recording itself took, on the rollout's thread (timed inside the recorder) and on Rerun's threads |
| ``attributed_overhead_cpu`` | ``(recorder_cpu_s + background_cpu_s) / plain_cpu_s``: the overhead measured where it is spent, so other processes' load barely moves it; the best figure on a busy machine |
| ``overhead_cpu_min`` | fastest recorded / fastest plain run - 1: on a loaded machine noise only adds time, so the minima are the least disturbed pair |
| ``plain_wall_s``, ``recorded_wall_s``, ``overhead_wall``, ``overhead_wall_min`` | the same in wall-clock time |
| ``bytes``, ``robot_steps`` | file size; Σ over episodes of steps × team size |
| ``bytes_per_robot_step`` | ``bytes / robot_steps``, everything in the file included |
| ``payload_bytes_per_robot_step`` | Arrow bytes of the per-step chunks / robot_steps: the part that grows with the rollout (no per-chunk framing, static scene or blueprint) |
| ``steps``, ``episodes``, ``team_sizes`` | what ran |

The JSON also holds the settings, every single run, and the machine (CPUs, load average).
"""

from __future__ import annotations

import json
import os
import platform
import statistics
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

from comat.tasks import task_names
from comat.viz.rollout import RolloutResult, record_episodes

__all__ = ["format_table", "run_viz_bench"]


def _timed(path: Path | None, task: str, policy: str, kwargs: dict) -> tuple[RolloutResult, float, float]:
    w0, c0 = time.perf_counter(), time.process_time()
    result = record_episodes(path, task, policy, **kwargs)
    return result, time.perf_counter() - w0, time.process_time() - c0


def run_viz_bench(
    tasks: Sequence[str] | None = None,
    *,
    tier: str = "unicycle",
    policy: str = "heuristic",
    episodes: int = 3,
    coalitions: str = "test",
    repeats: int = 5,
    seed: int = 0,
    ticks_per_step: int | None = None,
    out: str | Path | None = "benchmarks/results/viz.json",
    quiet: bool = False,
) -> dict:
    """Time rollouts with and without recording; write JSON to ``out`` (None: don't) and print a table.

    Returns the result document (``{"settings": …, "machine": …, "results": [one per task]}``).
    """
    tasks = task_names() if tasks is None else tuple(tasks)
    if isinstance(repeats, bool) or not isinstance(repeats, int) or repeats < 1:
        raise ValueError(f"repeats must be a positive integer, got {repeats!r}")
    out_path = Path(out) if out is not None else None
    if out_path is not None and not out_path.parent.is_dir():
        raise ValueError(f"out: folder {str(out_path.parent)!r} does not exist, got {str(out_path)!r}")
    kwargs = {
        "episodes": episodes,
        "coalitions": coalitions,
        "seed": seed,
        "tier": tier,
        "ticks_per_step": ticks_per_step,
    }
    settings = {"tasks": list(tasks), "policy": policy, "repeats": repeats, **kwargs}
    machine = {
        "cpus": os.cpu_count(),
        "load_avg_1min": os.getloadavg()[0],
        "python": platform.python_version(),
        "platform": platform.platform(),
    }
    results = []
    with tempfile.TemporaryDirectory(prefix="comat-viz-bench-") as tmp:
        for task in tasks:
            results.append(_task_row(task, policy, kwargs, repeats, Path(tmp)))
    doc = {"benchmark": "viz", "settings": settings, "machine": machine, "results": results}
    if out_path is not None:
        out_path.write_text(json.dumps(doc, indent=2) + "\n")
    if not quiet:
        print(format_table(results))
        if out_path is not None:
            print(f"wrote {out_path}")
    return doc


def _task_row(task: str, policy: str, kwargs: dict, repeats: int, tmp: Path) -> dict:
    """One task's row: after a warm-up of each, ``repeats`` pairs of a plain and a recorded rollout
    (recordings in ``tmp``), their medians, paired overheads and what the recording weighs."""
    _timed(None, task, policy, kwargs)
    _timed(tmp / f"{task}_warmup.rrd", task, policy, kwargs)
    runs: dict[str, list[dict[str, float]]] = {"plain": [], "recorded": []}
    last = None
    for r in range(repeats):
        base, wall, cpu = _timed(None, task, policy, kwargs)
        runs["plain"].append({"wall_s": wall, "cpu_s": cpu})
        last, wall, cpu = _timed(tmp / f"{task}_{r}.rrd", task, policy, kwargs)
        runs["recorded"].append(
            {
                "wall_s": wall,
                "cpu_s": cpu,
                "recorder_cpu_s": last.recorder_cpu_s,
                "background_cpu_s": last.background_cpu_s,
            }
        )
        if last.episodes != base.episodes:  # recording must not change what happens
            raise RuntimeError(f"{task}: the recorded rollout differs from the plain one")
    row = {"task": task}
    for clock in ("wall", "cpu"):
        plain = [t[f"{clock}_s"] for t in runs["plain"]]
        recorded = [t[f"{clock}_s"] for t in runs["recorded"]]
        # Paired ratios (each recorded run against the plain run just before it) cancel
        # slow drifts of the machine's load; their median discards the odd disturbed pair.
        ratio = statistics.median(q / p for p, q in zip(plain, recorded))
        row.update(
            {
                f"plain_{clock}_s": statistics.median(plain),
                f"recorded_{clock}_s": statistics.median(recorded),
                f"overhead_{clock}": ratio - 1.0,
                f"overhead_{clock}_min": min(recorded) / min(plain) - 1.0,
            }
        )
    recorder_cpu = statistics.median(t["recorder_cpu_s"] for t in runs["recorded"])
    background_cpu = statistics.median(t["background_cpu_s"] for t in runs["recorded"])
    row.update(
        {
            "recorder_cpu_s": recorder_cpu,
            "background_cpu_s": background_cpu,
            "attributed_overhead_cpu": (recorder_cpu + background_cpu) / row["plain_cpu_s"],
            "bytes": last.bytes,
            "robot_steps": last.robot_steps,
            "bytes_per_robot_step": last.bytes_per_robot_step,
            "payload_bytes_per_robot_step": _payload_bytes(last.path) / max(last.robot_steps, 1),
            "steps": last.steps,
            "episodes": len(last.episodes),
            "team_sizes": [int(e["team_size"]) for e in last.episodes],
            "runs": runs,
        }
    )
    return row


def format_table(results: list[dict]) -> str:
    """The results as a fixed-width text table (overheads: median paired ratio, and minima)."""
    head = (
        f"{'task':<5} {'steps':>5} {'robot-steps':>11} {'cpu plain/rec s':>15} {'overhead':>8} {'(min)':>6} "
        f"{'attributed':>10} "
        f"{'wall plain/rec s':>16} {'overhead':>8} {'(min)':>6} {'file KiB':>8} {'B/robot-step':>12} {'payload':>7}"
    )
    rows = [
        f"{r['task']:<5} {r['steps']:>5} {r['robot_steps']:>11} "
        f"{r['plain_cpu_s']:>7.2f}/{r['recorded_cpu_s']:<7.2f} {r['overhead_cpu']:>8.1%} {r['overhead_cpu_min']:>6.1%} "
        f"{r['attributed_overhead_cpu']:>10.1%} "
        f"{r['plain_wall_s']:>8.2f}/{r['recorded_wall_s']:<7.2f} {r['overhead_wall']:>8.1%} "
        f"{r['overhead_wall_min']:>6.1%} {r['bytes'] / 1024:>8.0f} {r['bytes_per_robot_step']:>12.0f} "
        f"{r['payload_bytes_per_robot_step']:>7.0f}"
        for r in results
    ]
    return "\n".join([head, *rows])


def _payload_bytes(path: Path) -> int:
    """Arrow bytes of the temporal chunks of a recording (what scales with steps and robots)."""
    from rerun.chunk import RrdReader

    return sum(ch.to_record_batch().nbytes for ch in RrdReader(path).stream() if not ch.is_static)
