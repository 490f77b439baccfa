"""The paper's evaluation metrics over episodes, each with a 95 % confidence interval.

Per episode (``EPISODE_METRICS`` of the env): return, steps, progress (the task's share of its
work done, its ``progress``: PCP the prey captured, HMT the material delivered; 1 when the task
is done), finished (1 if the task was done within the horizon, its ``done``: the paper's Table I
"completion"), MuJoCo robot–robot collisions, Robotarium-style violations
(``robotarium_collisions`` + ``boundary_exits`` + ``actuator_errors``: what the real testbed
would flag) and safety-filter interventions; the task's coordination metric (``coordination``,
the mean over the episode's env steps of its ``coordination`` hook: how well the team shares its
work out; only for a task that has one); from the progress curve (:func:`curve_endpoints`)
the area under it (``progress_auc``) and the env steps to 90 % progress (``time_to_90``),
continuous endpoints that still separate policies when progress itself saturates near 100 %.

Intervals are Student-t intervals over *coalitions*: with K episodes per coalition (K start
states), each coalition's K episodes are averaged first and the interval is taken over the
coalition means, so K episodes never count as K independent units. All episodes here come
from one policy (one seed); intervals over seeds are ``comat report``'s.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from comat.files import read_json_detail

__all__ = [
    "PROGRESS_MARK",
    "REPORTED",
    "RETIRED_NAMES",
    "SHARES",
    "current_names",
    "curve_endpoints",
    "interval_text",
    "mean_ci",
    "read_results",
    "summarize_ci",
    "violations",
]

SHARES = ("progress", "finished", "progress_auc")
"""Metrics that are shares in [0, 1]: their intervals are cut to that range (the true value lies
in it, so the cut loses no coverage) instead of printing ``0.33 ± 4.24``."""


def interval_text(
    mean: float, half: float, share: bool = False, scale: float = 1.0, digits: int = 2, unit: str | None = "seed"
) -> str:
    """``mean ± half`` as a table shows it: a share's interval cut to [0, 1] and then written
    ``mean [lo, hi]``; no interval (one ``unit``: nothing to estimate a spread from) said in words
    (``unit=None``: a value that has none, e.g. a published figure)."""
    if math.isnan(mean):
        return "—"
    text = f"{scale * mean:.{digits}f}"
    if math.isnan(half):
        return text if unit is None else f"{text} (1 {unit}, no interval)"
    if share and (mean - half < 0 or mean + half > 1):
        lo, hi = max(0.0, mean - half), min(1.0, mean + half)
        return f"{text} [{scale * lo:.{digits}f}, {scale * hi:.{digits}f}]"
    return f"{text} ± {scale * half:.{digits}f}"


RETIRED_NAMES = {
    "completion": "progress",
    "success": "finished",
    "episode_completion": "episode_progress",
    "episode_success": "episode_finished",
    "completion_points": "progress_points",
    "brakes": "fallbacks",
}
"""Metric names of files written before the vocabulary was made one (issue 32): ``completion``
meant progress (fraction done) in the evaluation files and the finished share in some tables;
``success`` the finished share. Readers of stored files rename them with :func:`current_names`."""


def current_names(data):
    """``data`` (a JSON value, a CSV row or header) with the retired metric names replaced, at every
    depth; values are kept. Files written now pass through unchanged."""
    if isinstance(data, dict):
        return {RETIRED_NAMES.get(k, k): current_names(v) for k, v in data.items()}
    if isinstance(data, list):
        return [current_names(v) for v in data]
    if isinstance(data, str):
        return RETIRED_NAMES.get(data, data)
    return data


def read_results(path, detail: bool = True):
    """A stored result file as every reader takes it: an evaluation (``evaluation_<tier>.json``) or
    sweep file with its per-episode detail put back from the gzipped side file
    (:func:`comat.files.read_json_detail`; ``detail=False``: the summary alone, no ``per_episode``),
    an older plain JSON file as it is, metric names today's (:func:`current_names`)."""
    return current_names(read_json_detail(path, detail=detail))


REPORTED = (
    "return",
    "steps",
    "progress",
    "finished",
    "progress_auc",
    "time_to_90",
    "coordination",
    "collisions",
    "violations",
    "interventions",
    "fallbacks",
    "recoveries",
)
"""Metrics in evaluation tables, in order. ``coordination`` is the task's own (a task without one,
and rows of files written before it, leave it out: the table prints "n/a"); it is not one of
:data:`SHARES`, since a task's metric need not be a share."""

PROGRESS_MARK = 0.9
"""Progress whose first crossing ``time_to_90`` times (reached when progress >= 0.9 - 1e-9: the
slack absorbs the rounding of a sum of float payloads, as the tasks' own ``done`` does)."""


def curve_endpoints(curve: Sequence[float], horizon: int) -> dict[str, float]:
    """Continuous endpoints of one episode's progress curve (progress after each env step).

    ``progress_auc``: the mean over the ``horizon`` env steps of the progress after each step,
    the last value held after an episode that finished early (finishing sooner scores higher);
    ``time_to_90``: env steps until progress first reached :data:`PROGRESS_MARK`, the horizon
    when it never did (censored); ``reached_90``: 1.0 if it did, else 0.0.
    """
    if isinstance(horizon, bool) or not isinstance(horizon, (int, np.integer)) or horizon < 1:
        raise ValueError(f"horizon must be a positive integer, got {horizon!r}")
    c = np.asarray(curve, dtype=float)
    if c.ndim != 1 or not 1 <= c.size <= horizon:
        raise ValueError(f"curve must be a 1-D sequence of 1 to horizon={horizon} values, got shape {c.shape}")
    hit = np.flatnonzero(c >= PROGRESS_MARK - 1e-9)
    return {
        "progress_auc": float((c.sum() + (horizon - c.size) * c[-1]) / horizon),
        "time_to_90": float(hit[0] + 1) if hit.size else float(horizon),
        "reached_90": float(hit.size > 0),
    }


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


def _value(episode: dict, name: str) -> float | None:
    """Metric ``name`` of an episode; None where the row predates it (older result files)."""
    if name == "violations":
        return (
            violations(episode)
            if all(k in episode for k in ("robotarium_collisions", "boundary_exits", "actuator_errors"))
            else None
        )
    return float(episode[name]) if name in episode else None


def summarize_ci(
    episodes: Sequence[dict], confidence: float = 0.95, n_coalitions: int | None = None
) -> dict[str, dict[str, float]]:
    """``{metric: {"mean", "ci95", "n"}}`` for every metric of :data:`REPORTED` the episodes carry.

    The interval is over coalitions: episodes of one coalition are averaged first, then
    :func:`mean_ci` runs over the coalition means; ``n`` is the number of coalitions. An
    episode's coalition is its ``"coalition"``; rows without it (older result files) are
    coalition ``i % n_coalitions`` (episode i of a set evaluated with K episodes per coalition),
    or each its own coalition when ``n_coalitions`` is None. A metric that some episode lacks
    (an older file) is left out.
    """
    if not episodes:
        raise ValueError("summarize_ci needs at least one episode")
    if n_coalitions is not None and (
        isinstance(n_coalitions, bool) or not isinstance(n_coalitions, int) or n_coalitions < 1
    ):
        raise ValueError(f"n_coalitions must be a positive integer or None, got {n_coalitions!r}")
    units = np.array(
        [
            int(e["coalition"]) if "coalition" in e else i % n_coalitions if n_coalitions else i
            for i, e in enumerate(episodes)
        ]
    )
    keys, which = np.unique(units, return_inverse=True)
    out = {}
    for name in REPORTED:
        values = [_value(e, name) for e in episodes]
        if any(v is None for v in values):
            continue
        means = np.bincount(which, weights=values, minlength=keys.size) / np.bincount(which, minlength=keys.size)
        mean, half = mean_ci(means, confidence)
        out[name] = {"mean": mean, "ci95": half, "n": int(keys.size)}
    return out
