"""``comat report RUNS…``: the paper's Table I, Fig. 4 and Fig. 5 from run folders.

A run folder (``comat train`` / ``comat sweep``) holds ``config.yaml`` (algo, task, seed),
``progress.csv`` (training curve) and ``evaluation_<tier>.json`` (``comat eval``: the
deterministic policy on U_train and U_test). Runs are grouped by (algo, task); seeds are the
independent units: each seed's episode mean is one sample, and tables give the mean over seeds
± the 95 % Student-t interval over seeds (± nan with one seed).

Outputs in ``--out``:

* ``table1.md`` / ``table1.csv``: per task and metric, each algorithm's training-set result
  next to the paper's Table I (completion = share of episodes finished, the paper's meaning).
* ``generalization.csv``: train vs unseen return per algorithm and task, and retention
  (test / train return, the paper's Fig. 5 comparison; undefined when the train return ≤ 0).
* ``fig4_training_return.png``: mean training return vs env steps, shaded ± one standard
  deviation over seeds, one panel per task.
* ``fig5_generalization.png``: train vs unseen return bars with retention labels.
"""

from __future__ import annotations

import csv
import io
import json
import math
import sys
from pathlib import Path

import numpy as np

from comat.eval.metrics import mean_ci
from comat.files import write_atomic

__all__ = ["PAPER_RETENTION", "PAPER_TABLE1", "REPORT_FILES", "load_run", "make_report"]

REPORT_FILES = ("table1.md", "table1.csv", "generalization.csv", "fig4_training_return.png", "fig5_generalization.png")
"""Every file ``make_report`` writes (``comat report`` refuses to overwrite them without --force)."""

ALGO_ORDER = ("mappo", "qmix", "mat", "comat")
ALGO_LABELS = {"mappo": "MAPPO", "qmix": "QMIX", "mat": "MAT", "comat": "COMAT"}
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
"""COMAT's retention of training return on unseen compositions reported in the paper (§IV-B)."""
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
            "evaluation": evaluation}


def _eval_mean(run: dict, split: str, metric: str) -> float | None:
    if run["evaluation"] is None:
        return None
    for row in run["evaluation"]["rows"]:
        if row["set"] == split and row["policy"] == run["algo"]:
            return row["metrics"][metric]["mean"]
    return None


def _over_seeds(runs: list[dict], split: str, metric: str) -> tuple[float, float, int]:
    values = [v for v in (_eval_mean(r, split, metric) for r in runs) if v is not None]
    if not values:
        return math.nan, math.nan, 0
    mean, half = mean_ci(values)
    return mean, half, len(values)


def _fmt(mean: float, half: float, metric: str) -> str:
    if math.isnan(mean):
        return "—"
    if metric == "success":
        return f"{100 * mean:.1f}%" + ("" if math.isnan(half) else f" ± {100 * half:.1f}")
    return f"{mean:.2f}" + ("" if math.isnan(half) else f" ± {half:.2f}")


def _save(fig, path: Path) -> None:
    import matplotlib.pyplot as plt

    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    write_atomic(path, buf.getvalue())


def _table1(groups: dict, tasks: list[str], algos: list[str]) -> tuple[str, str]:
    buf = io.StringIO()
    writer = csv.writer(buf)
    writer.writerow(["task", "metric", "algo", "seeds", "mean", "ci95_over_seeds", "paper"])
    lines = ["| Task | Metric | " + " | ".join(f"{ALGO_LABELS[a]} (ours) | {ALGO_LABELS[a]} (paper)" for a in algos)
             + " |", "|---|---|" + "---|---|" * len(algos)]
    for task in tasks:
        for metric, label in TABLE_METRICS:
            cells = []
            for algo in algos:
                mean, half, n = _over_seeds(groups.get((algo, task), []), "train", metric)
                paper = PAPER_TABLE1.get((task, metric))
                paper_v = None if paper is None else paper[ALGO_ORDER.index(algo)]
                cells += [_fmt(mean, half, metric), "—" if paper_v is None else _fmt(paper_v, math.nan, metric)]
                writer.writerow([task, metric, algo, n, mean, half, "" if paper_v is None else paper_v])
            lines.append(f"| {task.upper()} | {label} | " + " | ".join(cells) + " |")
    seeds = {f"{ALGO_LABELS[a]}/{t.upper()}": len(groups.get((a, t), [])) for t in tasks for a in algos}
    lines += ["", "Training coalitions (U_train), deterministic actions; ours: mean over seeds ± 95 % interval over "
              "seeds (runs per cell: " + ", ".join(f"{k} {v}" for k, v in seeds.items()) + "). Completion = share of "
              "episodes in which every prey was captured / all material delivered (the paper's definition)."]
    return "\n".join(lines) + "\n", buf.getvalue()


def _generalization(groups: dict, tasks: list[str], algos: list[str]) -> tuple[list[dict], str]:
    rows = []
    for task in tasks:
        for algo in algos:
            runs = groups.get((algo, task), [])
            train, train_ci, n = _over_seeds(runs, "train", "return")
            test, test_ci, _ = _over_seeds(runs, "test", "return")
            retention = test / train if train > 0 and not math.isnan(test) else math.nan
            rows.append({"task": task, "algo": algo, "seeds": n, "train_return": train, "train_ci95": train_ci,
                         "test_return": test, "test_ci95": test_ci, "retention": retention,
                         "paper_retention": PAPER_RETENTION.get((task, algo), math.nan)})
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=list(rows[0]))
    writer.writeheader()
    writer.writerows(rows)
    return rows, buf.getvalue()


def _fig4(groups: dict, tasks: list[str], algos: list[str], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(tasks), 1, figsize=(7, 3.2 * len(tasks)), squeeze=False)
    for ax, task in zip(axes[:, 0], tasks):
        for algo in algos:
            runs = [r for r in groups.get((algo, task), []) if len(r["curve"]["env_steps"]) > 1]
            if not runs:
                continue
            end = min(r["curve"]["env_steps"][-1] for r in runs)
            grid = np.linspace(min(r["curve"]["env_steps"][0] for r in runs), end, 100)
            ys = []
            for r in runs:
                x, y = np.asarray(r["curve"]["env_steps"]), np.asarray(r["curve"]["return"])
                k = max(1, len(y) // 20)  # trailing mean over ~5 % of the run (no padding at the ends)
                y = np.convolve(y, np.ones(k))[: len(y)] / np.minimum(np.arange(1, len(y) + 1), k)
                ys.append(np.interp(grid, x, y))
            ys = np.asarray(ys)
            mean, std = ys.mean(0), ys.std(0)
            ax.plot(grid, mean, label=f"{ALGO_LABELS[algo]} ({len(runs)} seed{'s' if len(runs) > 1 else ''})")
            ax.fill_between(grid, mean - std, mean + std, alpha=0.2)
        ax.set_title(f"{task.upper()}: mean training episode return (U_train)")
        ax.set_xlabel("env steps")
        ax.set_ylabel("return")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    _save(fig, path)


def _fig5(rows: list[dict], tasks: list[str], algos: list[str], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(tasks), figsize=(4.5 * len(tasks), 3.6), squeeze=False)
    for ax, task in zip(axes[0], tasks):
        sel = [r for r in rows if r["task"] == task]
        x = np.arange(len(sel))
        train = [r["train_return"] for r in sel]
        test = [r["test_return"] for r in sel]
        ax.bar(x - 0.2, train, 0.4, yerr=[0 if math.isnan(v) else v for v in (r["train_ci95"] for r in sel)],
               label="train (U_train)", color="tab:red")
        ax.bar(x + 0.2, test, 0.4, yerr=[0 if math.isnan(v) else v for v in (r["test_ci95"] for r in sel)],
               label="unseen (U_test)", color="tab:orange")
        for i, r in enumerate(sel):
            if not math.isnan(r["retention"]):
                top = np.nanmax([r["train_return"], r["test_return"], 0.0])
                ax.annotate(f"{100 * r['retention']:.0f}%", (i, top), ha="center", va="bottom", fontsize=8)
        ax.set_xticks(x, [ALGO_LABELS[r["algo"]] for r in sel])
        ax.set_title(f"{task.upper()}: return, train vs unseen (retention %)")
        ax.axhline(0, color="k", lw=0.5)
        ax.legend(fontsize=8)
    _save(fig, path)


def make_report(run_folders: list[str | Path], out: str | Path, tier: str | None = None) -> dict:
    """Write Table I, the generalization table and Fig. 4/5 for ``run_folders`` into ``out``."""
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
        print(f"warning: {folder} has no evaluation in the {tier or 'training'} tier: left out of the tables",
              file=sys.stderr)
    groups: dict[tuple[str, str], list[dict]] = {}
    for r in runs:
        groups.setdefault((r["algo"], r["task"]), []).append(r)
    tasks = [t for t in ("pcp", "hmt") if any(k[1] == t for k in groups)]
    algos = [a for a in ALGO_ORDER if any(k[0] == a for k in groups)]
    md, table_csv = _table1(groups, tasks, algos)
    rows, gen_csv = _generalization(groups, tasks, algos)
    files = {"table1.md": md, "table1.csv": table_csv, "generalization.csv": gen_csv}
    for name, text in files.items():
        write_atomic(out / name, text)
    _fig4(groups, tasks, algos, out / "fig4_training_return.png")
    _fig5(rows, tasks, algos, out / "fig5_generalization.png")
    return {"runs": len(runs), "groups": {f"{a}/{t}": len(v) for (a, t), v in groups.items()},
            "files": [*files, "fig4_training_return.png", "fig5_generalization.png"], "generalization": rows}
