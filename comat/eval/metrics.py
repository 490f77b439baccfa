"""The paper's evaluation metrics over episodes, each with a 95 % confidence interval.

Per episode (``EPISODE_METRICS`` of the env): return, steps, completion (1 if every prey was
captured / all material delivered within the horizon, as in the paper's Table I; partial
progress in between), success, MuJoCo robot–robot collisions, Robotarium-style violations
(``robotarium_collisions`` + ``boundary_exits`` + ``actuator_errors``: what the real testbed
would flag) and safety-filter interventions.

Intervals are Student-t intervals of the mean over episodes (episodes are the independent
units; a seed's episodes are not pooled with another seed's here — see ``comat report``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

__all__ = ["REPORTED", "mean_ci", "summarize_ci", "violations"]

REPORTED = ("return", "steps", "completion", "success", "collisions", "violations", "interventions", "fallbacks", "recoveries")
"""Metrics in evaluation tables, in order."""


def violations(episode: dict) -> float:
    """Robotarium-style violations of one episode: collisions by its offset-centre check,
    boundary exits and actuator-limit errors, summed."""
    return float(episode["robotarium_collisions"] + episode["boundary_exits"] + episode["actuator_errors"])


def mean_ci(values: Sequence[float], confidence: float = 0.95) -> tuple[float, float]:
    """Mean and half-width of its two-sided Student-t ``confidence`` interval.

    One value: half-width nan (no spread to estimate). Identical values: half-width 0.
    """
    from scipy import stats

    x = np.asarray(values, dtype=float)
    if x.ndim != 1 or x.size == 0:
        raise ValueError(f"values must be a non-empty 1-D sequence, got shape {x.shape}")
    if not 0 < confidence < 1:
        raise ValueError(f"confidence must be in (0, 1), got {confidence!r}")
    mean = float(x.mean())
    if x.size == 1:
        return mean, math.nan
    sem = float(x.std(ddof=1)) / math.sqrt(x.size)
    return mean, float(stats.t.ppf(0.5 + confidence / 2, x.size - 1) * sem)


def summarize_ci(episodes: Sequence[dict], confidence: float = 0.95) -> dict[str, dict[str, float]]:
    """``{metric: {"mean", "ci95", "n"}}`` over episodes for every metric in :data:`REPORTED`."""
    if not episodes:
        raise ValueError("summarize_ci needs at least one episode")
    out = {}
    for name in REPORTED:
        values = [violations(e) if name == "violations" else float(e[name]) for e in episodes]
        mean, half = mean_ci(values, confidence)
        out[name] = {"mean": mean, "ci95": half, "n": len(values)}
    return out
