"""Run folders as the reports read them: a run's config, training curve and evaluation rows, and
the per-seed values every table and test is built from (the seed is the replicated unit).

:func:`load_run` reads one folder; :func:`run_cells` gives a run's per-coalition means of a metric on a
set, :func:`seed_means` one value per seed; :func:`method_text` states the interval method in captions.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import yaml

from comat.measure.metrics import mean_ci, read_results, violations
from comat.measure.stats import cell_means
from comat.team import COALITION_SETS, SET_LABELS

__all__ = [
    "ALPHA",
    "COMPARED",
    "ENDPOINTS",
    "PAPER_BUDGET",
    "PAPER_RETENTION",
    "REFERENCES",
    "SETS",
    "SET_NAMES",
    "episodes_per_coalition",
    "evaluation_row",
    "k_text",
    "load_run",
    "method_text",
    "over_seeds",
    "run_cells",
    "seed_means",
]

SETS = COALITION_SETS
"""Composition sets in table order (``comat.team.COALITION_SETS``); only those present appear."""
SET_NAMES = SET_LABELS
"""The composition sets as the reports name them (``comat.team.SET_LABELS``)."""
ENDPOINTS = (
    ("return", "return"),
    ("progress", "progress"),
    ("finished", "finished"),
    ("progress_auc", "progress_auc"),
    ("time_to_90", "time_to_90"),
)
"""(evaluation metric, report key): the per-set endpoints of the generalization table. The last two
appear only where the evaluation rows carry them (files written before issue 28 do not)."""
COMPARED = ("progress", "finished", "progress_auc")
"""Endpoints on which COMAT is compared with each baseline (Welch's t-test over seeds)."""
REFERENCES = ("heuristic", "constant", "random")
PAPER_BUDGET = 4_000_000
"""Env steps per run in the paper's experiments."""
ALPHA = 0.05
"""Two-sided level of the Welch tests."""

PAPER_RETENTION = {("pcp", "comat"): 0.88, ("hmt", "comat"): 0.95}
"""COMAT's retention of training return on unseen compositions reported in the paper (§IV-B; a
ratio of returns — ours is of progress, see the module docstring)."""


def load_run(folder: str | Path, tier: str | None = None) -> dict:
    """One run folder: config, training curve and (if present) its evaluation rows."""
    folder = Path(folder)
    cfg_path = folder / "config.yaml"
    if not cfg_path.is_file():
        raise FileNotFoundError(f"{str(folder)!r} is not a run folder (no config.yaml)")
    config = yaml.safe_load(cfg_path.read_text())["config"]
    curve: dict[str, list[float]] = {"env_steps": [], "return": []}
    progress = folder / "progress.csv"
    if progress.is_file():
        with open(progress) as fh:
            for row in csv.DictReader(fh):
                if row["episode_return"] not in ("", "nan"):
                    curve["env_steps"].append(float(row["env_steps"]))
                    curve["return"].append(float(row["episode_return"]))
    tier = tier or config["tier"]
    eval_path = folder / f"evaluation_{tier}.json"
    # The summary with its per-episode detail; files written before issue 32: today's metric names.
    evaluation = read_results(eval_path) if eval_path.is_file() else None
    # Imported here: the rest of this module runs without torch.
    from comat.rl import current_name

    algo = current_name(config["algo"], config.get("model"))
    if algo != config["algo"] and evaluation is not None:  # a learner renamed since: its rows under today's name
        for row in evaluation["rows"]:
            if row.get("policy") == config["algo"]:
                row["policy"] = algo
    return {
        "folder": str(folder),
        "algo": algo,
        "task": config["task"],
        "seed": config["seed"],
        "tier": tier,
        "env_steps": curve["env_steps"][-1] if curve["env_steps"] else 0,
        "curve": curve,
        "budget": int(config.get("total_env_steps") or 0),
        "evaluation": evaluation,
    }


def evaluation_row(run: dict, split: str, policy: str | None = None) -> dict | None:
    """The evaluation row of ``policy`` (default: the run's own algorithm) on ``split``, or None."""
    if run["evaluation"] is None:
        return None
    for row in run["evaluation"]["rows"]:
        if row["set"] == split and row["policy"] == (policy or run["algo"]):
            return row
    return None


def episodes_per_coalition(run: dict) -> int:
    return int(run["evaluation"].get("episodes_per_coalition") or 1)


def _value(episode: dict, metric: str) -> float | None:
    if metric == "violations":
        keys = ("robotarium_collisions", "boundary_exits", "actuator_errors")
        return violations(episode) if all(k in episode for k in keys) else None
    return float(episode[metric]) if metric in episode else None


def run_cells(run: dict, split: str, metric: str, policy: str | None = None) -> tuple[list, np.ndarray] | None:
    """``(coalitions, means (C,))``: each coalition's mean of ``metric`` over its episodes in the
    run's evaluation row of ``policy`` on ``split``; None where there is no such row or an
    episode lacks the metric (a file written before it existed)."""
    row = evaluation_row(run, split, policy)
    if row is None or not row.get("per_episode"):
        return None
    eps = row["per_episode"]
    values = [_value(e, metric) for e in eps]
    if any(v is None for v in values):
        return None
    if all("coalition" in e for e in eps):
        coalition = [int(e["coalition"]) for e in eps]
    else:  # older files: episode i is coalition i % C (the set repeated K times)
        k = episodes_per_coalition(run)
        if len(eps) % k:
            raise ValueError(
                f"{run['folder']}: {split} has {len(eps)} episodes, not a multiple of its episodes_per_coalition {k}"
            )
        coalition = [i % (len(eps) // k) for i in range(len(eps))]
    table, _, coals = cell_means(np.zeros(len(eps)), coalition, values)
    return coals, table[0]


def seed_means(runs: list[dict], split: str, metric: str) -> list[float]:
    """Each run's (seed's) mean over coalitions of its coalition means; runs without it left out."""
    return [float(c[1].mean()) for c in (run_cells(r, split, metric) for r in runs) if c is not None]


def over_seeds(runs: list[dict], split: str, metric: str) -> tuple[float, float, int]:
    values = seed_means(runs, split, metric)
    if not values:
        return math.nan, math.nan, 0
    mean, half = mean_ci(values)
    return mean, half, len(values)


def method_text(seeds: str, k: str) -> str:
    """The interval method, as every caption states it."""
    return (
        f"mean over seeds ± 95 % t-interval over per-seed means ({seeds}); each seed's mean first averages "
        f"its {k} episode(s) per coalition, then its coalitions"
    )


def k_text(runs: list[dict]) -> str:
    ks = sorted({episodes_per_coalition(r) for r in runs if r["evaluation"]})
    return "/".join(map(str, ks)) if ks else "1"
