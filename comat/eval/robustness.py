"""Robustness to one reality component: ``comat eval --reality-sweep COMPONENT`` and the curves
``comat report`` draws from it.

A sweep plays a policy (and, unless told not to, the scripted heuristic) at three or more values
of one field of :class:`~comat.reality.RealityConfig`, every other field at the base level
(``--reality``, default ``off``: the component alone), on the same teams and starts at every
value (paired episodes). The file ``evaluation_<tier>_sweep_<component>.json`` holds, per value,
each policy's metrics per set (means over the set's episodes); the per-episode table for the
coalition-first averaging of :mod:`comat.measure.stats` is in ``<that stem>.episodes.json.gz``
(:func:`comat.measure.metrics.read_results` reads both).

``comat report`` also reads a run's evaluations at the named levels (``evaluation_<tier>.json`` at
``off``, ``evaluation_<tier>_nominal.json``, ``evaluation_<tier>_stress.json``: ``comat eval
--reality LEVEL``) as one more component, ``level``, with the values off, nominal, stress, where a
run has at least two of them: the gap a grid measures at every level, drawn the same way.

``comat report`` reads the sweep files of its runs: per task, component and algorithm, each
endpoint at each value as the mean over seeds (one value per run: its episodes averaged per
coalition, then over coalitions) with the Student-t interval over those per-seed means
(``robustness.csv``), and one panel per (task, component) and endpoint in ``fig7_robustness``:
progress, finished share, episode length (steps) and collisions against the component's value,
one line per algorithm.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from comat.eval.evaluate import evaluate_policies
from comat.eval.figures import _plt, algo_label, clipped_err, empty_figure, save
from comat.files import detail_name, write_atomic, write_json_detail
from comat.measure.metrics import read_results
from comat.measure.stats import per_seed_means, t_interval
from comat.reality.config import LEVELS, RealityConfig

__all__ = [
    "LEVEL_COMPONENT",
    "LEVEL_ORDER",
    "ROBUSTNESS_ENDPOINTS",
    "ROBUSTNESS_FILES",
    "SWEEP_VALUES",
    "load_levels",
    "load_sweeps",
    "print_sweep",
    "robustness_csv",
    "robustness_figure",
    "robustness_rows",
    "run_reality_sweep",
    "sweep_files",
    "sweep_values",
    "write_sweep",
]

ROBUSTNESS_FILES = ("robustness.csv", "fig7_robustness.png", "fig7_robustness.pdf")
"""What ``comat report`` adds when its runs hold reality sweeps."""

SWEEP_VALUES: dict[str, tuple] = {
    "pose_delay_ticks": (0, 1, 2, 3, 4),
    "pose_hold_prob": (0.0, 0.3, 0.6),
    "pose_noise_xy_m": (0.0, 0.001, 0.005, 0.01),
    "pose_noise_theta_rad": (0.0, 0.01, 0.05, 0.1),
    "pose_bias_xy_m": (0.0, 0.0005, 0.0025, 0.01),
    "pose_freeze_prob": (0.0, 0.002, 0.02, 0.05),
    "command_delay_ticks": (0, 1, 2, 3),
    "command_loss_prob": (0.0, 0.01, 0.05, 0.1),
    "motor_tau_max_s": (0.0, 0.08, 0.12, 0.2),
    "motor_accel_limit_radps2": (0.0, 400.0, 200.0, 100.0),
    "motor_dead_zone_radps": (0.0, 1.9, 3.0, 5.0),
    "wheel_gain_spread": (0.0, 0.03, 0.07, 0.15),
    "top_speed_derate_min": (1.0, 0.9, 0.75, 0.5),
    "wheel_disturbance_radps": (0.0, 0.5, 2.0, 4.0),
    "fault_prob": (0.0, 0.5, 1.0),
    "start_xy_m": (0.0, 0.05, 0.1),
    "start_theta_rad": (0.0, 0.2, 0.5),
}
"""Default values of each component's sweep: off, nominal, stress and beyond (for the motors'
acceleration limit, 0 means none, so the sweep runs from no limit to a tighter one)."""

ROBUSTNESS_ENDPOINTS = (
    ("progress", "progress (%)"),
    ("finished", "finished share (%)"),
    ("steps", "episode length (env steps)"),
    ("collisions", "contact steps per episode"),
)
"""(metric, axis label) drawn against the component's value."""

_NUMERIC = sorted(k for k, v in LEVELS["off"].items() if not isinstance(v, bool))


def sweep_values(component: str, values: Sequence[float] | None, base: str = "off") -> list:
    """The values a sweep of ``component`` runs at (the others at level ``base``): ``values`` or
    :data:`SWEEP_VALUES`; one-line errors for an unknown component, fewer than three values, or a
    value the config refuses, all before the first episode."""
    if component not in _NUMERIC:
        raise ValueError(
            f"--reality-sweep must be one of the reality layer's numeric fields {_NUMERIC}, got {component!r}"
        )
    if values is None:
        if component not in SWEEP_VALUES:
            raise ValueError(
                f"--reality-sweep {component} has no default values: give three or more with --sweep-values"
            )
        values = SWEEP_VALUES[component]
    values = list(values)
    if len(values) < 3:
        raise ValueError(f"--sweep-values must give three or more values, got {values}")
    if isinstance(LEVELS["off"][component], int):
        if any(float(v) != int(v) for v in values):
            raise ValueError(f"--sweep-values of {component} must be whole ticks, got {values}")
        values = [int(v) for v in values]
    for value in values:
        _config(component, value, base)
    return values


def _config(component: str, value, base: str) -> RealityConfig:
    fields = {"level": base, component: value}
    if component == "motor_tau_max_s":  # a lag from 0 up to the value
        fields["motor_tau_min_s"] = min(LEVELS[base]["motor_tau_min_s"], value)
    if component == "fault_start_max_s":
        fields["fault_start_min_s"] = min(LEVELS[base]["fault_start_min_s"], value)
    try:
        return RealityConfig(**fields)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"--sweep-values: {exc}") from None


def run_reality_sweep(
    checkpoint,
    task: str,
    sets,
    episodes: int,
    tier: str,
    seed: int,
    component: str,
    values: Sequence[float] | None = None,
    base: str = "off",
    references=(),
    progress: Callable[[str], None] = print,
) -> dict:
    """Evaluate at each value of ``component`` (module docstring); returns the sweep file's dict."""

    values = sweep_values(component, values, base)
    configs = [_config(component, v, base) for v in values]
    points = []
    for value, cfg in zip(values, configs):
        progress(f"{component} = {value}")
        result = evaluate_policies(
            checkpoint, task, sets, episodes, tier, seed, references=references, progress=progress, reality=cfg
        )
        points.append({"value": value, "rows": result["rows"]})
    return {
        "component": component,
        "base": base,
        "values": values,
        "task": task,
        "tier": tier,
        "episodes_per_coalition": episodes,
        "points": points,
    }


def load_sweeps(folder: str | Path, tier: str) -> list[dict]:
    """The sweep files of a run folder in ``tier`` (none: [])."""
    return [read_results(p) for p in sorted(Path(folder).glob(f"evaluation_{tier}_sweep_*.json"))]


LEVEL_COMPONENT = "level"
"""The component under which the level evaluations appear (values: :data:`LEVEL_ORDER`)."""
LEVEL_ORDER = ("off", "nominal", "stress")


def load_levels(folder: str | Path, tier: str) -> list[dict]:
    """A run's evaluations at the named reality levels as one sweep-like record (``component``
    ``level``, one point per level present, in :data:`LEVEL_ORDER`); [] with fewer than two."""
    points = []
    for level in LEVEL_ORDER:
        path = Path(folder) / (f"evaluation_{tier}.json" if level == "off" else f"evaluation_{tier}_{level}.json")
        if path.is_file():
            points.append({"value": level, "rows": read_results(path)["rows"]})
    return [{"component": LEVEL_COMPONENT, "points": points}] if len(points) >= 2 else []


def _x(component: str, value):
    """Where a value sits on its axis: a level's place in :data:`LEVEL_ORDER`, else the value."""
    return LEVEL_ORDER.index(value) if component == LEVEL_COMPONENT else value


def _run_value(row: dict, metric: str) -> float | None:
    """A run's score on one set: its episodes averaged per coalition first, then over coalitions."""

    eps = row.get("per_episode") or []
    vals = [(e.get("coalition", i), e.get(metric)) for i, e in enumerate(eps) if e.get(metric) is not None]
    if not vals:
        return None
    coalitions, v = zip(*vals)
    _, means = per_seed_means([0] * len(v), list(coalitions), [float(x) for x in v])
    return float(means[0])


def robustness_rows(runs: list[dict]) -> list[dict]:
    """Per (task, component, set, algorithm, value, endpoint): mean over seeds, t-interval, seeds."""

    cells: dict[tuple, list[float]] = {}
    for run in runs:
        for sweep in [*load_sweeps(run["folder"], run["tier"]), *load_levels(run["folder"], run["tier"])]:
            for point in sweep["points"]:
                for row in point["rows"]:
                    if row["policy"] != run["algo"]:
                        continue  # the references' rows: the same for every seed
                    for metric, _ in ROBUSTNESS_ENDPOINTS:
                        v = _run_value(row, metric)
                        if v is not None:
                            key = (run["task"], sweep["component"], row["set"], run["algo"], point["value"], metric)
                            cells.setdefault(key, []).append(v)
    out = []

    def order(item):
        task, comp, split, algo, value, metric = item[0]
        return task, comp, split, algo, _x(comp, value), metric

    for (task, comp, split, algo, value, metric), vals in sorted(cells.items(), key=order):
        t = t_interval(vals)
        out.append(
            {
                "task": task,
                "component": comp,
                "set": split,
                "algo": algo,
                "value": value,
                "metric": metric,
                "mean": t["mean"],
                "ci95": t["half"],
                "seeds": t["n"],
            }
        )
    return out


def robustness_csv(rows: list[dict]) -> str:
    buf = io.StringIO()
    w = csv.DictWriter(buf, ["task", "component", "set", "algo", "value", "metric", "mean", "ci95", "seeds"])
    w.writeheader()
    for r in rows:
        w.writerow(r)
    return buf.getvalue()


def robustness_figure(rows: list[dict], stem: Path) -> list[str]:
    """One panel row per (task, component, set), one column per endpoint; lines per algorithm with
    t-intervals over seeds (bars; none with one seed, said in the title)."""

    plt = _plt()
    keys = sorted({(r["task"], r["component"], r["set"]) for r in rows})
    if not keys:
        return empty_figure(
            "no reality sweeps or level evaluations in these runs (comat eval --reality-sweep "
            "COMPONENT, or --reality nominal next to off)",
            stem,
        )
    fig, axes = plt.subplots(
        len(keys), len(ROBUSTNESS_ENDPOINTS), figsize=(4 * len(ROBUSTNESS_ENDPOINTS), 3 * len(keys)), squeeze=False
    )
    for i, (task, comp, split) in enumerate(keys):
        for j, (metric, label) in enumerate(ROBUSTNESS_ENDPOINTS):
            ax = axes[i][j]
            sel = [r for r in rows if (r["task"], r["component"], r["set"], r["metric"]) == (task, comp, split, metric)]
            for algo in sorted({r["algo"] for r in sel}):
                pts = sorted((r for r in sel if r["algo"] == algo), key=lambda r: _x(comp, r["value"]))
                scale = 100.0 if metric in ("progress", "finished") else 1.0
                x = [_x(comp, r["value"]) for r in pts]
                y = np.array([r["mean"] for r in pts]) * scale
                err = np.nan_to_num(np.array([r["ci95"] for r in pts]) * scale)
                if metric in ("progress", "finished"):
                    err = clipped_err(y, err)
                seeds = min(r["seeds"] for r in pts)
                ax.errorbar(
                    x,
                    y,
                    yerr=err,
                    marker="o",
                    capsize=3,
                    label=f"{algo_label(algo)} ({seeds} seed{'s' if seeds > 1 else ''})",
                )
            ax.set_xlabel(comp)
            if comp == LEVEL_COMPONENT:
                ax.set_xticks(range(len(LEVEL_ORDER)), LEVEL_ORDER)
            ax.set_ylabel(label)
            if metric in ("progress", "finished"):
                ax.set_ylim(0, 105)
            else:
                ax.set_ylim(bottom=0)
            ax.set_title(f"{task.upper()} {split}", fontsize=9)
            ax.legend(fontsize=7)
    fig.suptitle(
        "Robustness to one reality component (mean over seeds, 95 % t-interval over per-seed means; "
        "no bar with one seed)",
        fontsize=9,
    )
    fig.tight_layout()
    return save(fig, stem)


_EPISODE_KEYS = (
    "coalition",
    "team_size",
    "return",
    "progress",
    "finished",
    "steps",
    "collisions",
    "robotarium_collisions",
    "interventions",
    "recoveries",
    "fallbacks",
)
"""What a sweep file keeps of each episode (not the progress curve or the per-robot tables)."""


def sweep_files(stem: str) -> list[str]:
    """The files :func:`write_sweep` writes for ``stem``."""
    return [f"{stem}.json", detail_name(f"{stem}.json"), f"{stem}.csv"]


def write_sweep(sweep: dict, out_dir: Path, stem: str) -> list[Path]:
    """:func:`sweep_files`: ``<stem>.json`` (the sweep; its episodes in ``<stem>.episodes.json.gz``,
    :func:`comat.files.write_json_detail`) and ``<stem>.csv`` (value, policy, set, metric, mean, ci95)."""

    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow([sweep["component"], "policy", "set", "metric", "mean", "ci95"])
    for point in sweep["points"]:
        for row in point["rows"]:
            for metric, _ in ROBUSTNESS_ENDPOINTS:
                m = row["metrics"].get(metric)
                if m is not None:
                    w.writerow([point["value"], row["policy"], row["set"], metric, m["mean"], m["ci95"]])
    points = [
        {
            "value": p["value"],
            "rows": [
                {**r, "per_episode": [{k: e[k] for k in _EPISODE_KEYS if k in e} for e in r.get("per_episode", [])]}
                for r in p["rows"]
            ],
        }
        for p in sweep["points"]
    ]
    paths = write_json_detail(out_dir / f"{stem}.json", {**sweep, "points": points})
    write_atomic(out_dir / f"{stem}.csv", buf.getvalue())
    return [*paths, out_dir / f"{stem}.csv"]


def print_sweep(sweep: dict, out=print) -> None:
    """value × policy × set: progress, finished share, steps, contact steps (means over episodes)."""
    out(
        f"{sweep['component']:>24} {'policy':<10} {'set':<11} {'progress':>9} {'finished':>9} {'steps':>7} "
        f"{'contacts':>9}"
    )
    for point in sweep["points"]:
        for row in point["rows"]:
            m = row["metrics"]
            out(
                f"{point['value']!s:>24} {row['policy']:<10} {row['set']:<11} {100 * m['progress']['mean']:>8.1f}% "
                f"{100 * m['finished']['mean']:>8.1f}% {m['steps']['mean']:>7.1f} {m['collisions']['mean']:>9.2f}"
            )
