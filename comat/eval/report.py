"""``comat report RUNS…``: the paper's Table I, Fig. 4, Fig. 5 and team-size figure from run folders.

A run folder (``comat train`` / ``comat sweep``) holds ``config.yaml`` (algo, task, seed, env-step
budget), ``progress.csv`` (training curve) and ``evaluation_<tier>.json`` (``comat eval``: the
deterministic policy on the composition sets, K episodes (start states) per coalition; reference
policies on the same episodes). Runs are grouped by (algo, task); runs without an evaluation are
left out with a warning; when none has one, nothing is written.

Intervals (:mod:`comat.measure.stats`, which says why and gives their measured coverage). The seed
is the replicated unit: every coalition of a run is played by the same policy. Each seed's score
on a set first averages its K episodes per coalition, then its coalitions (so K episodes never
count as K seeds); tables give the mean over seeds ± the 95 % Student-t interval over those
per-seed means (nan with one seed). COMAT is compared with each baseline by Welch's t-test over
per-seed means; the test, not a look at two intervals, decides. The hierarchical bootstrap
(seeds, then coalitions within a seed) is in ``aggregates.csv`` only, as a descriptive interval:
it undercovers with 3–5 seeds. An episode's coalition is its row's ``coalition``; rows of older
files lack it and are coalition ``i % C`` (C = episodes / ``episodes_per_coalition``).

Outputs in ``--out`` (:data:`REPORT_FILES`):

* ``table1.md`` / ``table1.csv``: per task and metric, each algorithm's U_train result next to
  the paper's Table I (the finished share is the paper's "completion"), with the
  env-step budget next to the paper's 4 M; the reference policies' rows below.
* ``generalization.csv``: per algorithm and task and per composition set present (:data:`SETS`
  order), return, progress, the finished share and, where the evaluations carry them,
  ``progress_auc`` and ``time_to_90``, each with its t half-width and seed count; progress
  retention per set (progress on it / on U_train, per seed); COMAT − this algorithm on progress,
  finished share and ``progress_auc`` with Welch's interval, t, df and p.
  ``generalization.md``: the same as tables, and the Welch comparisons.
* ``aggregates.csv``: per task, algorithm, set and metric, the mean over seeds with the t-interval
  over per-seed means, and the mean and interquartile mean of the seed x coalition cells with
  hierarchical-bootstrap intervals (2,000 resamples, generator seed 0).
* ``fig4_training_return``, ``fig5_generalization``, ``fig6_team_size`` (.png and .pdf):
  :mod:`comat.eval.figures`.
* Only when runs hold reality sweeps (``comat eval --reality-sweep``) or evaluations at two or more
  levels (``comat eval --reality nominal`` next to ``off``): ``robustness.csv`` and
  ``fig7_robustness`` (.png and .pdf), :mod:`comat.eval.robustness`.
"""

from __future__ import annotations

import csv
import io
import math
import sys
from pathlib import Path

import numpy as np

from comat.eval import figures
from comat.eval.figures import algo_label
from comat.eval.generalization import generalization_csv, generalization_md, generalization_rows
from comat.eval.robustness import robustness_csv, robustness_figure, robustness_rows
from comat.eval.runs import (
    ENDPOINTS,
    PAPER_BUDGET,
    REFERENCES,
    SET_NAMES,
    SETS,
    evaluation_row,
    k_text,
    load_run,
    method_text,
    over_seeds,
    run_cells,
    seed_means,
)
from comat.files import write_atomic
from comat.learners import learner_names, not_registered
from comat.measure.metrics import SHARES, interval_text, mean_ci
from comat.measure.stats import hierarchical_bootstrap
from comat.tasks import task_names

__all__ = ["PAPER_TABLE1", "REPORT_FILES", "make_report"]

REPORT_FILES = (
    "table1.md",
    "table1.csv",
    "generalization.md",
    "generalization.csv",
    "aggregates.csv",
    *(
        f"{stem}.{fmt}"
        for stem in ("fig4_training_return", "fig5_generalization", "fig6_team_size")
        for fmt in figures.FORMATS
    ),
)
"""Every file ``make_report`` writes (``comat report`` refuses to overwrite them without --force)."""
_PAPER_COLUMNS = ("mappo", "qmix", "mat", "comat")
PAPER_TABLE1 = {
    key: dict(zip(_PAPER_COLUMNS, values))
    for key, values in {
        # Paper Table I ("Detailed metrics for train team compositions"): MAPPO, QMIX, MAT, COMAT.
        ("pcp", "return"): (45.43, 24.10, 70.12, 82.47),
        ("pcp", "steps"): (79.00, 79.70, 70.95, 65.61),
        ("pcp", "finished"): (0.879, 0.856, 0.916, 0.928),
        ("pcp", "collisions"): (0.00, 0.00, 0.00, 0.00),
        ("hmt", "return"): (11.70, 11.70, 8.32, 12.41),
        ("hmt", "steps"): (70.00, 70.60, 72.30, 68.75),
        ("hmt", "finished"): (0.977, 0.972, 0.911, 0.977),
        ("hmt", "collisions"): (0.00, 0.00, 1.00, 0.00),
    }.items()
}
"""The paper's Table I, keyed by (task, our metric name): learner -> value. The paper ran MAPPO,
QMIX, MAT and COMAT; another learner's cells show —."""
TABLE_METRICS = (
    ("return", "Mean return"),
    ("steps", "Episode steps"),
    ("finished", "Finished (paper: completion)"),
    ("collisions", "Collisions"),
    ("progress", "Progress (fraction done)"),
    ("violations", "Robotarium violations"),
    ("interventions", "Filter interventions"),
)


def _fmt(mean: float, half: float, metric: str, unit: str | None = "seed") -> str:
    """A table cell: shares in % with their interval cut to [0, 100] %, one ``unit`` said in words."""
    if metric == "finished":
        head, _, rest = interval_text(mean, half, share=True, scale=100.0, digits=1, unit=unit).partition(" ")
        return head if head == "—" else f"{head}%" + (f" {rest}" if rest else "")
    return interval_text(mean, half, share=metric in SHARES, unit=unit)


def _budgets(groups: dict, task: str, algos: list[str]) -> dict[str, list[int]]:
    return {a: [r["budget"] for r in groups[(a, task)]] for a in algos if groups.get((a, task))}


def _budget_cell(budgets: list[int]) -> str:
    if not budgets:
        return "—"
    lo, hi = min(budgets), max(budgets)
    return f"{lo:,}" if lo == hi else f"{lo:,}–{hi:,}"


def _table1(groups: dict, tasks: list[str], algos: list[str]) -> tuple[str, str]:
    buf = io.StringIO()
    writer = csv.writer(buf)
    writer.writerow(["task", "metric", "algo", "seeds", "mean", "ci95_over_seeds", "paper"])
    lines = [
        "| Task | Metric | " + " | ".join(f"{algo_label(a)} (ours) | {algo_label(a)} (paper)" for a in algos) + " |",
        "|---|---|" + "---|---|" * len(algos),
    ]
    for task in tasks:
        budgets = _budgets(groups, task, algos)
        cells = []
        for algo in algos:
            cells += [_budget_cell(budgets.get(algo, [])), f"{PAPER_BUDGET:,}"]
            writer.writerow(
                [
                    task,
                    "env_step_budget",
                    algo,
                    len(budgets.get(algo, [])),
                    np.mean(budgets[algo]) if budgets.get(algo) else "",
                    "",
                    PAPER_BUDGET,
                ]
            )
        lines.append(f"| {task.upper()} | Env-step budget per run | " + " | ".join(cells) + " |")
        for metric, label in TABLE_METRICS:
            cells = []
            for algo in algos:
                mean, half, n = over_seeds(groups.get((algo, task), []), "train", metric)
                # Returns are not comparable: the paper's reward scale is not ours (see the caption).
                paper = None if metric == "return" else PAPER_TABLE1.get((task, metric))
                paper_v = None if paper is None else paper.get(algo)
                cells += [
                    _fmt(mean, half, metric),
                    "—" if paper_v is None else _fmt(paper_v, math.nan, metric, unit=None),
                ]
                writer.writerow([task, metric, algo, n, mean, half, "" if paper_v is None else paper_v])
            lines.append(f"| {task.upper()} | {label} | " + " | ".join(cells) + " |")
    seeds = {
        f"{algo_label(a)}/{t.upper()}": len(seed_means(groups.get((a, t), []), "train", "return"))
        for t in tasks
        for a in algos
    }
    every = [r for rs in groups.values() for r in rs]
    lines += [
        "",
        "Training coalitions (U_train), deterministic actions; ours: "
        + method_text("seeds per cell: " + ", ".join(f"{k} {v}" for k, v in seeds.items()), k_text(every))
        + ". Finished = share of episodes in which the task was done before the horizon (PCP: every prey "
        'captured; HMT: all material delivered; the paper\'s "completion"). The paper trains 4 M env steps per '
        "run. The paper's "
        "columns hold only what compares: the finished share, episode steps and collisions. Its returns are "
        "left out: they are on another reward scale (our scripted policy, which finishes every episode, scores "
        "35 on PCP; the paper's COMAT 82.5), so a return next to a return would mislead. Shares' intervals are "
        "cut to [0, 100] % (written [low, high] where cut); one seed has no interval and says so.",
    ]
    lines += _reference_lines(groups, tasks)
    return "\n".join(lines) + "\n", buf.getvalue()


def _reference_lines(groups: dict, tasks: list[str]) -> list[str]:
    """Reference policies (heuristic, constant, random) on the same episodes, from the first run
    per task whose evaluation has them; one policy each, so the interval is over coalitions."""
    out = []
    for task in tasks:
        runs = [r for (a, t), rs in groups.items() if t == task for r in rs if r["evaluation"]]
        for split in SETS:
            found = next(
                (
                    (r, {p: evaluation_row(r, split, p) for p in REFERENCES})
                    for r in runs
                    if any(evaluation_row(r, split, p) for p in REFERENCES)
                ),
                None,
            )
            if not found:
                continue
            if not out:
                out += [
                    "",
                    (
                        "Reference policies on the same episodes (one policy each: mean ± 95 % t-interval over "
                        "the set's coalitions, each coalition's episodes averaged first; no seed spread):"
                    ),
                    "",
                    "| Task | Set | Policy | Return | Progress | Finished |",
                    "|---|---|---|---|---|---|",
                ]
            run, rows = found
            for policy, row in rows.items():
                if row is None:
                    continue
                cells = []
                for metric, kind in (("return", "return"), ("progress", "return"), ("finished", "finished")):
                    got = run_cells(run, split, metric, policy)
                    cells.append("—" if got is None else _fmt(*mean_ci(got[1]), kind, unit="coalition"))
                out.append(f"| {task.upper()} | {SET_NAMES[split]} | {policy} | " + " | ".join(cells) + " |")
    return out


def _sets_present(runs: list[dict]) -> list[str]:
    return [s for s in SETS if any(evaluation_row(r, s) for r in runs)]


def _endpoints_present(runs: list[dict], sets: list[str]) -> list[tuple[str, str]]:
    """ENDPOINTS that some run's own row carries on some set (older files lack the new ones)."""
    return [
        (m, k)
        for m, k in ENDPOINTS
        if any(run_cells(r, s, m) is not None for r in runs if r["evaluation"] for s in sets)
    ]


def _aggregates(groups: dict, tasks: list[str], algos: list[str], sets: list[str], endpoints) -> str:
    """Per task, algorithm, set and metric: the t-interval over per-seed means and, over the
    seed x coalition cells, the mean and IQM with hierarchical-bootstrap intervals."""
    buf = io.StringIO()
    writer = csv.writer(buf)
    writer.writerow(
        [
            "task",
            "algo",
            "set",
            "metric",
            "seeds",
            "coalitions",
            "episodes_per_coalition",
            "mean_over_seeds",
            "sd_over_seeds",
            "t_ci95_lo_over_seeds",
            "t_ci95_hi_over_seeds",
            "t_df",
            "hier_boot_mean_ci95_lo",
            "hier_boot_mean_ci95_hi",
            "iqm_of_cells",
            "hier_boot_iqm_ci95_lo",
            "hier_boot_iqm_ci95_hi",
        ]
    )
    for task in tasks:
        for algo in algos:
            runs = groups.get((algo, task), [])
            for split in sets:
                for metric, _ in endpoints:
                    got = [(r, c) for r in runs if (c := run_cells(r, split, metric)) is not None]
                    if not got:
                        continue
                    per_seed = np.array([c[1].mean() for _, c in got])
                    mean, half = mean_ci(per_seed)
                    sd = float(per_seed.std(ddof=1)) if per_seed.size > 1 else math.nan
                    same = len({tuple(c[0]) for _, c in got}) == 1
                    if same:
                        boot = hierarchical_bootstrap(np.stack([c[1] for _, c in got]))
                    else:
                        print(
                            f"warning: {algo}/{task} {split}: runs evaluated different coalitions; no "
                            "hierarchical bootstrap in aggregates.csv",
                            file=sys.stderr,
                        )
                        boot = dict.fromkeys(("mean_lo", "mean_hi", "iqm", "iqm_lo", "iqm_hi"), math.nan)
                    writer.writerow(
                        [
                            task,
                            algo,
                            split,
                            metric,
                            per_seed.size,
                            len(got[0][1][0]) if same else "",
                            k_text([r for r, _ in got]),
                            mean,
                            sd,
                            mean - half,
                            mean + half,
                            per_seed.size - 1,
                            boot["mean_lo"],
                            boot["mean_hi"],
                            boot["iqm"],
                            boot["iqm_lo"],
                            boot["iqm_hi"],
                        ]
                    )
    return buf.getvalue()


def _by_team_size(groups: dict, sets: list[str]) -> dict:
    """(algo, task) -> team size -> per seed ``{"return", "progress", "coalitions"}``: the mean
    over that seed's coalitions of that size (each its episodes' mean) in ``sets``, and how many."""
    out: dict = {}
    for key, runs in groups.items():
        sizes: dict[int, list[dict[str, float]]] = {}
        for r in runs:
            cells: dict[int, dict[str, list[float]]] = {}
            for split in sets:
                size = run_cells(r, split, "team_size")
                if size is None:
                    continue
                metrics = {m: run_cells(r, split, m)[1] for m in ("return", "progress")}
                for c, n in enumerate(size[1]):
                    mine = cells.setdefault(int(n), {"return": [], "progress": []})
                    for m, v in metrics.items():
                        mine[m].append(float(v[c]))
            for n in sorted(cells):
                sizes.setdefault(n, []).append(
                    {m: float(np.mean(v)) for m, v in cells[n].items()} | {"coalitions": len(cells[n]["return"])}
                )
        if sizes:
            out[key] = sizes
    return out


def make_report(run_folders: list[str | Path], out: str | Path, tier: str | None = None) -> dict:
    """Write :data:`REPORT_FILES` for ``run_folders`` into the folder ``out`` (which must exist)."""

    if not run_folders:
        raise ValueError("make_report needs at least one run folder")
    out = Path(out)
    if not out.is_dir():
        raise FileNotFoundError(f"output folder {str(out)!r} does not exist (create it first)")
    runs = [load_run(f, tier) for f in run_folders]
    missing = [r["folder"] for r in runs if r["evaluation"] is None]
    if len(missing) == len(runs):
        raise ValueError(
            f"none of the {len(runs)} run folder(s) has an evaluation (evaluation_<tier>.json, tier "
            f"{runs[0]['tier']!r}): run `comat eval --policy RUN` on each first"
        )
    for folder in missing:
        print(
            f"warning: {folder} has no evaluation in the {tier or 'training'} tier: left out of the tables and "
            "of Fig. 5 and 6 (its training curve stays in Fig. 4)",
            file=sys.stderr,
        )
    groups: dict[tuple[str, str], list[dict]] = {}
    for r in runs:
        groups.setdefault((r["algo"], r["task"]), []).append(r)
    tasks = [t for t in task_names() if any(k[1] == t for k in groups)]
    algos = [a for a in learner_names() if any(k[0] == a for k in groups)]
    for stray in sorted({k[0] for k in groups} - set(algos)):
        print(f"warning: runs of {stray!r} left out of the report: {not_registered(stray)}", file=sys.stderr)
    evaluated = {k: [r for r in v if r["evaluation"]] for k, v in groups.items()}
    sets = _sets_present(runs)
    endpoints = _endpoints_present(runs, sets)
    episodes_text = k_text(runs)
    md, table_csv = _table1(evaluated, tasks, algos)
    rows = generalization_rows(evaluated, tasks, algos, sets, endpoints)
    files = {
        "table1.md": md,
        "table1.csv": table_csv,
        "generalization.md": generalization_md(rows, tasks, algos, sets, endpoints, episodes_text),
        "generalization.csv": generalization_csv(rows),
        "aggregates.csv": _aggregates(evaluated, tasks, algos, sets, endpoints),
    }
    for name, text in files.items():
        write_atomic(out / name, text)
    budgets = {t: _budgets(groups, t, algos) for t in tasks}
    curves = {
        k: [(np.asarray(r["curve"]["env_steps"]), np.asarray(r["curve"]["return"])) for r in v]
        for k, v in groups.items()
    }
    size_sets = [s for s in sets if s in figures.SIZE_SETS]
    names = list(files)
    names += figures.fig4(curves, tasks, algos, budgets, out / "fig4_training_return")
    names += figures.fig5(rows, tasks, algos, sets, budgets, out / "fig5_generalization", episodes_text)
    names += figures.fig_team_size(
        _by_team_size(evaluated, size_sets), tasks, algos, budgets, out / "fig6_team_size", size_sets, episodes_text
    )
    assert set(names) == set(REPORT_FILES), names
    robust = robustness_rows(runs)
    if robust:  # runs with `comat eval --reality-sweep` files
        write_atomic(out / "robustness.csv", robustness_csv(robust))
        names += ["robustness.csv", *robustness_figure(robust, out / "fig7_robustness")]
    return {
        "runs": len(runs),
        "groups": {f"{a}/{t}": len(v) for (a, t), v in groups.items()},
        "sets": sets,
        "files": names,
        "generalization": rows,
    }
