"""``comat report RUNS…``: the paper's Table I, Fig. 4, Fig. 5 and team-size figure from run folders.

A run folder (``comat train`` / ``comat sweep``) holds ``config.yaml`` (algo, task, seed, env-step
budget), ``progress.csv`` (training curve) and ``evaluation_<tier>.json`` (``comat eval``: the
deterministic policy on U_train, U_test and, where evaluated, U_scale; reference policies on the
same episodes). Runs are grouped by (algo, task); seeds are the independent units: each seed's
mean over a set's coalitions is one sample, and tables give the mean over seeds ± the 95 %
Student-t interval over seeds (± nan with one seed). Runs without an evaluation are left out
with a warning; when none has one, nothing is written.

Outputs in ``--out`` (:data:`REPORT_FILES`):

* ``table1.md`` / ``table1.csv``: per task and metric, each algorithm's U_train result next to
  the paper's Table I (completion = share of episodes finished, the paper's meaning), with the
  env-step budget next to the paper's 4 M; the reference policies' rows below.
* ``generalization.csv``: per algorithm and task and per composition set (U_scale where a run
  has it), return and progress, and progress retention (progress on the set / progress on
  U_train — a ratio of non-negative fractions, unlike a ratio of returns that change sign).
  ``generalization.md``: the same progress and retention as a table, then the finished share per
  set, and under each, per unseen set whether COMAT's 95 % interval over seeds lies above each
  baseline's (the paper's claim, where it can be decided: two or more seeds each).
* ``aggregates.csv``: over seeds × coalitions (each coalition's mean over its episodes), the
  plain mean and the interquartile mean with 95 % stratified-bootstrap intervals (rliable:
  seeds resampled within each coalition, 2,000 resamples, fixed random state).
* ``fig4_training_return``, ``fig5_generalization``, ``fig6_team_size`` (.png and .pdf):
  :mod:`comat.eval.figures`.
"""

from __future__ import annotations

import csv
import io
import json
import math
import sys
from pathlib import Path

import numpy as np

from comat.eval import figures
from comat.eval.figures import ALGO_LABELS
from comat.eval.metrics import mean_ci
from comat.files import write_atomic

__all__ = ["PAPER_RETENTION", "PAPER_TABLE1", "REPORT_FILES", "aggregate", "load_run", "make_report"]

ALGO_ORDER = ("mappo", "qmix", "mat", "comat")
SETS = ("train", "test", "scale")
REFERENCES = ("heuristic", "constant", "random")
PAPER_BUDGET = 4_000_000
"""Env steps per run in the paper's experiments."""
BOOTSTRAP_REPS = 2000
SET_NAMES = {"train": "U_train", "test": "U_test", "scale": "U_scale"}
"""The composition sets as the paper names them."""


REPORT_FILES = ("table1.md", "table1.csv", "generalization.md", "generalization.csv", "aggregates.csv",
                *(f"{stem}.{fmt}" for stem in ("fig4_training_return", "fig5_generalization", "fig6_team_size")
                  for fmt in figures.FORMATS))
"""Every file ``make_report`` writes (``comat report`` refuses to overwrite them without --force)."""
PAPER_TABLE1 = {
    # Paper Table I ("Detailed metrics for train team compositions"): MAPPO, QMIX, MAT, COMAT.
    ("pcp", "return"): (45.43, 24.10, 70.12, 82.47),
    ("pcp", "steps"): (79.00, 79.70, 70.95, 65.61),
    ("pcp", "success"): (0.879, 0.856, 0.916, 0.928),
    ("pcp", "collisions"): (0.00, 0.00, 0.00, 0.00),
    ("hmt", "return"): (11.70, 11.70, 8.32, 12.41),
    ("hmt", "steps"): (70.00, 70.60, 72.30, 68.75),
    ("hmt", "success"): (0.977, 0.972, 0.911, 0.977),
    ("hmt", "collisions"): (0.00, 0.00, 1.00, 0.00),
}
"""The paper's Table I, keyed by (task, our metric name); values in ``ALGO_ORDER``."""
PAPER_RETENTION = {("pcp", "comat"): 0.88, ("hmt", "comat"): 0.95}
"""COMAT's retention of training return on unseen compositions reported in the paper (§IV-B; a
ratio of returns — ours is of progress, see the module docstring)."""
TABLE_METRICS = (("return", "Mean return"), ("steps", "Episode steps"), ("success", "Completion"),
                 ("collisions", "Collisions"), ("completion", "Progress (fraction done)"),
                 ("violations", "Robotarium violations"), ("interventions", "Filter interventions"))


def load_run(folder: str | Path, tier: str | None = None) -> dict:
    """One run folder: config, training curve and (if present) its evaluation rows."""
    import yaml

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
    evaluation = json.loads(eval_path.read_text()) if eval_path.is_file() else None
    return {"folder": str(folder), "algo": config["algo"], "task": config["task"], "seed": config["seed"],
            "tier": tier, "env_steps": curve["env_steps"][-1] if curve["env_steps"] else 0, "curve": curve,
            "budget": int(config.get("total_env_steps") or 0), "evaluation": evaluation}


def _row(run: dict, split: str, policy: str | None = None) -> dict | None:
    """The evaluation row of ``policy`` (default: the run's own algorithm) on ``split``, or None."""
    if run["evaluation"] is None:
        return None
    for row in run["evaluation"]["rows"]:
        if row["set"] == split and row["policy"] == (policy or run["algo"]):
            return row
    return None


def _eval_mean(run: dict, split: str, metric: str) -> float | None:
    row = _row(run, split)
    return None if row is None else row["metrics"][metric]["mean"]


def _over_seeds(runs: list[dict], split: str, metric: str) -> tuple[float, float, int]:
    values = [v for v in (_eval_mean(r, split, metric) for r in runs) if v is not None]
    if not values:
        return math.nan, math.nan, 0
    mean, half = mean_ci(values)
    return mean, half, len(values)


def _per_coalition(run: dict, row: dict, metric: str) -> np.ndarray:
    """(C,) each coalition's mean over its episodes (``comat eval`` plays coalition c as episodes
    c, c + C, c + 2C, …: the set repeated ``episodes_per_coalition`` times)."""
    per = np.array([e[metric] for e in row["per_episode"]], dtype=float)
    reps = int(run["evaluation"].get("episodes_per_coalition") or 1)
    return per.reshape(reps, -1).mean(axis=0)


def _fmt(mean: float, half: float, metric: str) -> str:
    if math.isnan(mean):
        return "—"
    if metric == "success":
        return f"{100 * mean:.1f}%" + ("" if math.isnan(half) else f" ± {100 * half:.1f}")
    return f"{mean:.2f}" + ("" if math.isnan(half) else f" ± {half:.2f}")


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
    lines = ["| Task | Metric | " + " | ".join(f"{ALGO_LABELS[a]} (ours) | {ALGO_LABELS[a]} (paper)" for a in algos)
             + " |", "|---|---|" + "---|---|" * len(algos)]
    for task in tasks:
        budgets = _budgets(groups, task, algos)
        cells = []
        for algo in algos:
            cells += [_budget_cell(budgets.get(algo, [])), f"{PAPER_BUDGET:,}"]
            writer.writerow([task, "env_step_budget", algo, len(budgets.get(algo, [])),
                             np.mean(budgets[algo]) if budgets.get(algo) else "", "", PAPER_BUDGET])
        lines.append(f"| {task.upper()} | Env-step budget per run | " + " | ".join(cells) + " |")
        for metric, label in TABLE_METRICS:
            cells = []
            for algo in algos:
                mean, half, n = _over_seeds(groups.get((algo, task), []), "train", metric)
                paper = PAPER_TABLE1.get((task, metric))
                paper_v = None if paper is None else paper[ALGO_ORDER.index(algo)]
                cells += [_fmt(mean, half, metric), "—" if paper_v is None else _fmt(paper_v, math.nan, metric)]
                writer.writerow([task, metric, algo, n, mean, half, "" if paper_v is None else paper_v])
            lines.append(f"| {task.upper()} | {label} | " + " | ".join(cells) + " |")
    seeds = {f"{ALGO_LABELS[a]}/{t.upper()}": len([r for r in groups.get((a, t), []) if r["evaluation"]])
             for t in tasks for a in algos}
    lines += ["", "Training coalitions (U_train), deterministic actions; ours: mean over seeds ± 95 % Student-t "
              "interval over seeds (seeds per cell: " + ", ".join(f"{k} {v}" for k, v in seeds.items()) + "), each "
              "seed's value its mean over the 20 coalitions. Completion = share of episodes in which every prey was "
              "captured / all material delivered (the paper's definition). The paper trains 4 M env steps per run."]
    lines += _reference_lines(groups, tasks)
    return "\n".join(lines) + "\n", buf.getvalue()


def _reference_lines(groups: dict, tasks: list[str]) -> list[str]:
    """Reference policies (heuristic, constant, random) on the same episodes, from the first run
    per task whose evaluation has them."""
    out = []
    for task in tasks:
        runs = [r for (a, t), rs in groups.items() if t == task for r in rs if r["evaluation"]]
        for split in SETS:
            found = next(({p: _row(r, split, p) for p in REFERENCES} for r in runs
                          if any(_row(r, split, p) for p in REFERENCES)), None)
            if not found:
                continue
            if not out:
                out += ["", "Reference policies on the same episodes (mean ± 95 % interval over episodes):", "",
                        "| Task | Set | Policy | Return | Progress | Completion |", "|---|---|---|---|---|---|"]
            for policy, row in found.items():
                if row is None:
                    continue
                m = row["metrics"]
                out.append(f"| {task.upper()} | {split} | {policy} | {_fmt(m['return']['mean'], m['return']['ci95'], 'return')}"
                           f" | {_fmt(m['completion']['mean'], m['completion']['ci95'], 'return')} | "
                           f"{_fmt(m['success']['mean'], m['success']['ci95'], 'success')} |")
    return out


def _sets_present(runs: list[dict]) -> list[str]:
    return [s for s in SETS if any(_row(r, s) for r in runs)]


def _generalization(groups: dict, tasks: list[str], algos: list[str], sets: list[str]) -> tuple[list[dict], str]:
    """Per (task, algo): each set's return and progress over seeds and progress retention per
    unseen set (progress on it / progress on U_train, per seed, then over seeds)."""
    rows = []
    for task in tasks:
        for algo in algos:
            runs = groups.get((algo, task), [])
            row = {"task": task, "algo": algo, "seeds": _over_seeds(runs, "train", "return")[2]}
            for split in sets:
                for metric, key in (("return", "return"), ("completion", "progress"), ("success", "completion")):
                    mean, half, _ = _over_seeds(runs, split, metric)
                    row[f"{split}_{key}"], row[f"{split}_{key}_ci95"] = mean, half
            for split in sets:
                if split == "train":
                    continue
                ratios = []
                for r in runs:
                    tr, un = _eval_mean(r, "train", "completion"), _eval_mean(r, split, "completion")
                    if tr is not None and un is not None and tr > 0:
                        ratios.append(un / tr)
                mean, half = mean_ci(ratios) if ratios else (math.nan, math.nan)
                row[f"{split}_retention"], row[f"{split}_retention_ci95"] = mean, half
                row[f"{split}_retention_seeds"] = len(ratios)  # a seed without U_train progress has none
            tr, te = row.get("train_return", math.nan), row.get("test_return", math.nan)
            row["test_return_ratio"] = te / tr if tr > 0 and te >= 0 else math.nan  # the paper's form, where defined
            row["paper_retention_return_ratio"] = PAPER_RETENTION.get((task, algo), math.nan)
            rows.append(row)
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=list(rows[0]))
    writer.writeheader()
    writer.writerows(rows)
    return rows, buf.getvalue()


def _cell(row: dict, key: str) -> str:
    """A fraction ``row[key]`` as percent, ± its ``_ci95`` half-width where there is one."""
    mean, half = row.get(key, math.nan), row.get(f"{key}_ci95", math.nan)
    if math.isnan(mean):
        return "—"
    return f"{100 * mean:.1f}" + ("" if math.isnan(half) else f" ± {100 * half:.1f}")


def _retention_cell(row: dict, split: str) -> str:
    """Retention over seeds, naming how many seeds it covers where some had no U_train progress."""
    cell, n = _cell(row, f"{split}_retention"), row.get(f"{split}_retention_seeds", row["seeds"])
    return cell if n in (0, row["seeds"]) else f"{cell} ({n} of {row['seeds']} seeds)"  # 0: "—", no set or none


def _generalization_md(rows: list[dict], tasks: list[str], algos: list[str], sets: list[str]) -> str:
    """Progress per set and retention per unseen set, then the share of episodes finished per set,
    each mean ± 95 % half-width over seeds; under each table, per task and unseen set, whether
    COMAT's interval lies above (or below) each baseline's."""
    unseen = [s for s in sets if s != "train"]
    head = ["Task", "Algorithm", "Seeds", *(f"{SET_NAMES[s]} progress (%)" for s in sets),
            *(f"{SET_NAMES[s]} retention (%)" for s in unseen)]
    lines = _table(rows, head, lambda row: [*(_cell(row, f"{s}_progress") for s in sets),
                                            *(_retention_cell(row, s) for s in unseen)])
    lines += ["", ("Progress: share of prey captured / material delivered, each seed's mean over the set's "
              "coalitions (deterministic policy); retention: progress on the set / progress on U_train, per seed "
              "(undefined for a seed with no U_train progress, which the cell then names). "
              "± : 95 % Student-t half-width over seeds (none with one seed)."), ""]
    lines += _verdicts(rows, tasks, algos, unseen, "progress",
                       lambda mine, split: f"reaches {_cell(mine, f'{split}_progress')} % progress "
                       f"({_cell(mine, f'{split}_retention')} % of its U_train progress)")
    head = ["Task", "Algorithm", "Seeds", *(f"{SET_NAMES[s]} finished (%)" for s in sets)]
    lines += ["", *_table(rows, head, lambda row: [_cell(row, f"{s}_completion") for s in sets])]
    lines += ["", ("Finished: share of the set's episodes in which every prey was captured / all material "
              "delivered (the paper's completion), each seed's share, then over seeds: the finer measure where "
              "progress is near 100 % for every algorithm (U_scale PCP keeps 6 prey for 10–20 robots)."), ""]
    lines += _verdicts(rows, tasks, algos, unseen, "completion",
                       lambda mine, split: f"finishes {_cell(mine, f'{split}_completion')} % of its episodes")
    return "\n".join(lines) + "\n"


def _table(rows: list[dict], head: list[str], cells) -> list[str]:
    """A markdown table: task, algorithm and seeds, then ``cells(row)``."""
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for row in rows:
        lines.append("| " + " | ".join([row["task"].upper(), ALGO_LABELS.get(row["algo"], row["algo"]),
                                        str(row["seeds"]), *cells(row)]) + " |")
    return lines


def _verdicts(rows: list[dict], tasks: list[str], algos: list[str], unseen: list[str], key: str, lead) -> list[str]:
    """Per task and unseen set, COMAT's 95 % interval of ``<set>_<key>`` against each baseline's:
    above, below, overlapping, or why it cannot be said. The sentence names the measure compared."""
    by = {(r["task"], r["algo"]): r for r in rows}
    noun = {"progress": "progress", "completion": "finished-share"}[key]
    lines = []
    for task in tasks:
        mine = by.get((task, "comat"))
        for split in unseen if mine else ():
            verdicts = []
            lo_c, hi_c = (mine[f"{split}_{key}"] + d * mine[f"{split}_{key}_ci95"] for d in (-1, 1))
            for algo in (a for a in algos if a != "comat"):
                other, label = by[(task, algo)], ALGO_LABELS.get(algo, algo)
                lo_o, hi_o = (other[f"{split}_{key}"] + d * other[f"{split}_{key}_ci95"] for d in (-1, 1))
                if not other["seeds"]:
                    verdicts.append(f"{label}: no runs")
                elif math.isnan(other[f"{split}_{key}"]):
                    verdicts.append(f"{label}: not evaluated on {SET_NAMES[split]}")
                elif any(math.isnan(v) for v in (lo_c, hi_c, lo_o, hi_o)):
                    verdicts.append(f"{label}: not decidable (needs 2+ seeds each)")
                else:
                    verdicts.append(f"{label}: " + ("above" if lo_c > hi_o else "below" if hi_c < lo_o else "overlapping"))
            versus = f"its 95 % {noun} interval vs " + "; ".join(verdicts) if verdicts else "no baseline in these runs"
            lines.append(f"* {task.upper()}, {SET_NAMES[split]}: COMAT {lead(mine, split)}; {versus}.")
    return lines


def aggregate(scores: np.ndarray, reps: int = BOOTSTRAP_REPS, seed: int = 0) -> dict[str, float]:
    """Mean and interquartile mean of ``scores`` (seeds, coalitions) with 95 % stratified-bootstrap
    intervals (rliable: seeds resampled with replacement within each coalition)."""
    from rliable import library as rly
    from rliable import metrics

    scores = np.asarray(scores, dtype=float)
    if scores.ndim != 2 or scores.size == 0:
        raise ValueError(f"scores must be a non-empty (seeds, coalitions) array, got shape {scores.shape}")

    def both(x: np.ndarray) -> np.ndarray:
        return np.array([metrics.aggregate_mean(x), metrics.aggregate_iqm(x)])

    # rliable 1.2 draws its resamples from numpy's global generator (StratifiedBootstrap.update_indices
    # calls np.random.choice; random_state= only reaches arch, which does not draw them): seed it
    # for these calls alone and give the caller's state back.
    saved = np.random.get_state()
    try:
        np.random.seed(seed)
        point, interval = rly.get_interval_estimates({"x": scores}, both, reps=reps)
    finally:
        np.random.set_state(saved)
    (mean, iqm), ci = point["x"], interval["x"]
    return {"mean": float(mean), "mean_lo": float(ci[0, 0]), "mean_hi": float(ci[1, 0]),
            "iqm": float(iqm), "iqm_lo": float(ci[0, 1]), "iqm_hi": float(ci[1, 1])}


def _aggregates(groups: dict, tasks: list[str], algos: list[str], sets: list[str]) -> str:
    buf = io.StringIO()
    writer = csv.writer(buf)
    writer.writerow(["task", "algo", "set", "metric", "seeds", "coalitions", "mean", "mean_ci95_lo", "mean_ci95_hi",
                     "iqm", "iqm_ci95_lo", "iqm_ci95_hi", "mean_over_seeds", "t_ci95_over_seeds"])
    for task in tasks:
        for algo in algos:
            runs = groups.get((algo, task), [])
            for split in sets:
                with_rows = [(r, _row(r, split)) for r in runs if _row(r, split)]
                if not with_rows:
                    continue
                for metric in ("return", "completion", "success"):
                    per = [_per_coalition(r, row, metric) for r, row in with_rows]
                    if len({p.size for p in per}) != 1:
                        print(f"warning: {algo}/{task} {split}: runs evaluated different numbers of coalitions; "
                              "left out of aggregates.csv", file=sys.stderr)
                        continue
                    scores = np.stack(per)
                    agg = aggregate(scores)
                    plain, half = mean_ci(scores.mean(axis=1))
                    writer.writerow([task, algo, split, metric, scores.shape[0], scores.shape[1], agg["mean"],
                                     agg["mean_lo"], agg["mean_hi"], agg["iqm"], agg["iqm_lo"], agg["iqm_hi"],
                                     plain, half])
    return buf.getvalue()


def _by_team_size(groups: dict, sets: list[str]) -> dict:
    """(algo, task) -> team size -> per seed {"return", "completion"} means over its episodes."""
    out: dict = {}
    for key, runs in groups.items():
        sizes: dict[int, list[dict[str, float]]] = {}
        for r in runs:
            eps = [e for split in sets if (row := _row(r, split)) for e in row["per_episode"]]
            for n in sorted({int(e["team_size"]) for e in eps}):
                mine = [e for e in eps if int(e["team_size"]) == n]
                sizes.setdefault(n, []).append({m: float(np.mean([e[m] for e in mine])) for m in ("return", "completion")})
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
        raise ValueError(f"none of the {len(runs)} run folder(s) has an evaluation (evaluation_<tier>.json, tier "
                         f"{runs[0]['tier']!r}): run `comat eval --policy RUN` on each first")
    for folder in missing:
        print(f"warning: {folder} has no evaluation in the {tier or 'training'} tier: left out of the tables and "
              "of Fig. 5 and 6 (its training curve stays in Fig. 4)", file=sys.stderr)
    groups: dict[tuple[str, str], list[dict]] = {}
    for r in runs:
        groups.setdefault((r["algo"], r["task"]), []).append(r)
    tasks = [t for t in ("pcp", "hmt") if any(k[1] == t for k in groups)]
    algos = [a for a in ALGO_ORDER if any(k[0] == a for k in groups)]
    evaluated = {k: [r for r in v if r["evaluation"]] for k, v in groups.items()}
    sets = _sets_present(runs)
    md, table_csv = _table1(evaluated, tasks, algos)
    rows, gen_csv = _generalization(evaluated, tasks, algos, sets)
    files = {"table1.md": md, "table1.csv": table_csv, "generalization.md": _generalization_md(rows, tasks, algos, sets),
             "generalization.csv": gen_csv,
             "aggregates.csv": _aggregates(evaluated, tasks, algos, sets)}
    for name, text in files.items():
        write_atomic(out / name, text)
    budgets = {t: _budgets(groups, t, algos) for t in tasks}
    curves = {k: [(np.asarray(r["curve"]["env_steps"]), np.asarray(r["curve"]["return"])) for r in v]
              for k, v in groups.items()}
    names = list(files)
    names += figures.fig4(curves, tasks, algos, budgets, out / "fig4_training_return")
    names += figures.fig5(rows, tasks, algos, sets, budgets, out / "fig5_generalization")
    names += figures.fig_team_size(_by_team_size(evaluated, sets), tasks, algos, budgets, out / "fig6_team_size")
    assert set(names) == set(REPORT_FILES), names
    return {"runs": len(runs), "groups": {f"{a}/{t}": len(v) for (a, t), v in groups.items()}, "sets": sets,
            "files": names, "generalization": rows}
