"""``comat report --format marl-eval``: run folders as the JSON that marl-eval reads and BenchMARL writes.

marl-eval (instadeepai/marl-eval, Gorsane et al. 2022, the protocol's aggregation and rliable plots)
reads one JSON file of raw results; BenchMARL's ``JsonWriter`` writes the same shape. Written here so
comat's runs can sit in their plots beside theirs:

.. code-block:: text

    {ENV: {TASK: {ALGO: {"seed_S": {"step_0": {"step_count": int, METRIC: [float, ...]},
                                    ...,
                                    "step_K": {...},
                                    "absolute_metrics": {METRIC: [float, ...]}}}}}}

===================  =================================================================================
key                  what comat writes there
===================  =================================================================================
ENV                  ``comat_<tier>``: the tier the evaluations played in (runs of two tiers: two envs)
TASK                 the run's task (``pcp``, ``hmt``, ...)
ALGO                 the run's learner under today's name (``comat``, ``mat``, ``cash-caps``, ...)
``seed_S``           the run's training seed, as BenchMARL names runs
``step_i``           the i-th of training's evaluations (``eval.csv``: deterministic actions on
                     U_train, every ``eval_interval`` env steps), in order; ``step_count`` its env
                     steps; each metric a one-element list, that evaluation's mean over its episodes
                     (comat keeps no per-episode values of them; marl-eval takes one element "for a
                     metric computed over multiple episodes")
``absolute_metrics`` the run's final evaluation (``comat eval``, ``evaluation_<tier>.json``) on one
                     composition set (``--absolute-set``, default U_train), one value per episode
                     (20 coalitions x K episodes). marl-eval's absolute metric is the best policy's
                     score over 10x the episodes; comat keeps the final policy only, so this is the
                     final policy's, on its own episodes
===================  =================================================================================

Metrics (:data:`METRICS`): ``return`` (the team's episode return, the one marl-eval normalizes),
``progress`` (the task's share of its work done) and ``finished`` (1 if the episode finished before
the horizon). marl-eval needs every run of an environment to hold the same metrics, the same number
of steps, and every algorithm of a task the same number of runs; a set of runs that breaks this is
refused with a one-line ValueError naming what differs (marl-eval's own check would only print it).
"""

from __future__ import annotations

import csv
import json
import math
from collections import Counter
from pathlib import Path

from comat.eval.runs import evaluation_row, load_run

__all__ = ["METRICS", "marl_eval_data", "marl_eval_name", "write_marl_eval"]

METRICS = ("return", "progress", "finished")
"""Metrics written per step and in ``absolute_metrics`` (the same in both, as marl-eval requires)."""
ABSOLUTE = "absolute_metrics"


def marl_eval_name(absolute_set: str) -> str:
    """The file ``comat report --format marl-eval`` writes: ``marl_eval_<set>.json``."""
    return f"marl_eval_{absolute_set}.json"


def _steps(folder: Path) -> list[dict]:
    """Training's evaluations (``eval.csv``) as marl-eval steps, in order."""
    path = folder / "eval.csv"
    if not path.is_file():
        raise FileNotFoundError(
            f"{str(folder)!r} has no eval.csv (training's evaluations): marl-eval's steps come from it "
            "(a run trained with eval_interval 0 has none)"
        )
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    if not rows:
        raise ValueError(f"{str(path)!r} must hold at least one evaluation, got none")
    missing = [m for m in ("env_steps", *METRICS) if m not in rows[0]]
    if missing:
        raise ValueError(f"{str(path)!r} must have columns {['env_steps', *METRICS]}, got none for {missing}")
    return [{"step_count": int(float(r["env_steps"])), **{m: [_finite(r[m], path, m)] for m in METRICS}} for r in rows]


def _finite(text: str, path: Path, metric: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise ValueError(f"{str(path)!r}: {metric} must be a finite number, got {text!r}")
    return value


def _absolute(run: dict, absolute_set: str) -> dict[str, list[float]]:
    """The final evaluation's per-episode values on ``absolute_set``."""
    row = evaluation_row(run, absolute_set)
    if row is None or not row.get("per_episode"):
        raise FileNotFoundError(
            f"{run['folder']!r} has no {run['algo']} evaluation on {absolute_set!r} in evaluation_{run['tier']}.json: "
            f"run `comat eval --policy {run['folder']} --teams {absolute_set}` first"
        )
    episodes = row["per_episode"]
    lacking = [m for m in METRICS if any(m not in e for e in episodes)]
    if lacking:
        raise ValueError(f"{run['folder']!r}: the {absolute_set} episodes must carry {list(METRICS)}, lack {lacking}")
    return {m: [float(e[m]) for e in episodes] for m in METRICS}


def marl_eval_data(run_folders: list[str | Path], tier: str | None = None, absolute_set: str = "train") -> dict:
    """The marl-eval dictionary (module docstring) of ``run_folders``; ``tier``: which evaluation to
    read (default: each run's training tier)."""
    data: dict = {}
    for folder in run_folders:
        run = load_run(folder, tier)
        if run["evaluation"] is None:
            raise FileNotFoundError(
                f"{str(folder)!r} has no evaluation_{run['tier']}.json: run `comat eval --policy {folder}` first"
            )
        steps = _steps(Path(folder))
        seeds = data.setdefault(f"comat_{run['tier']}", {}).setdefault(run["task"], {}).setdefault(run["algo"], {})
        key = f"seed_{run['seed']}"
        if key in seeds:
            raise ValueError(
                f"run folders must be one per algorithm, task and seed; {str(folder)!r} repeats "
                f"{run['algo']} {run['task']} {key} of {seeds[key]['_folder']!r}"
            )
        seeds[key] = {
            "_folder": str(folder),
            **{f"step_{i}": step for i, step in enumerate(steps)},
            ABSOLUTE: _absolute(run, absolute_set),  # last: marl-eval takes a run's last key as its absolute one
        }
    _check_shape(data)
    for tasks in data.values():
        for algos in tasks.values():
            for runs in algos.values():
                for run in runs.values():
                    del run["_folder"]
    return data


def _check_shape(data: dict) -> None:
    """What marl-eval's aggregation assumes (its ``DiagnoseData.check_data``): per environment, one
    number of steps in every run and one number of runs for every algorithm of every task."""
    for env, tasks in data.items():
        runs = [run for algos in tasks.values() for seeds in algos.values() for run in seeds.values()]
        steps = Counter(len(run) - 2 for run in runs)  # less _folder and absolute_metrics
        if len(steps) > 1:
            usual, count = steps.most_common(1)[0]
            odd = "; ".join(f"{len(run) - 2} in {run['_folder']!r}" for run in runs if len(run) - 2 != usual)
            raise ValueError(
                f"marl-eval needs the same number of evaluations in every run of {env}: {count} runs have {usual}, "
                f"but {odd}"
            )
        counts = {f"{algo} {task}": len(seeds) for task, algos in tasks.items() for algo, seeds in algos.items()}
        if len(set(counts.values())) > 1:
            raise ValueError(
                f"marl-eval needs the same number of seeds for every algorithm and task of {env}, got {counts}"
            )


def write_marl_eval(
    run_folders: list[str | Path], out: str | Path, tier: str | None = None, absolute_set: str = "train"
) -> tuple[Path, dict]:
    """:func:`marl_eval_data` written as strict JSON (no NaN) to ``out/marl_eval_<set>.json``; the
    path and the data."""
    from comat.files import write_atomic

    data = marl_eval_data(run_folders, tier, absolute_set)
    path = Path(out) / marl_eval_name(absolute_set)
    write_atomic(path, json.dumps(data, indent=1, allow_nan=False) + "\n")
    return path, data
