"""The encoder ablation's tables and curves from its run folders (issue 17).

    .venv/bin/python results/ablations/summarize.py      # from the repository root

Reads ``results/ablations/runs/<variant>_<task>_s<seed>_<steps>/`` (``run.sh``) and, as
references trained with the same preset at 300 k steps, ``results/sweep/{comat,mat}_<task>_s*``
(today's COMAT = variant a, and MAT). Writes into ``results/ablations/``:

* ``screen.md``: per task and variant, the training-rollout progress (share of prey captured /
  material delivered by the stochastic policy, mean of the 3 updates ending at the step) at
  25 / 50 / 100 k env steps, the share of training episodes finished at 100 k, and the
  deterministic evaluation on U_train at 100 k (progress, finished);
* ``confirm.md`` / ``confirm.csv``: for variants run to 300 k on 3 seeds, the deterministic
  evaluation on U_train and U_test (finished share and progress), mean ± 95 % Student-t
  interval over seeds, next to MAT's and today's COMAT's sweep runs;
* ``screen_curves.png`` / ``confirm_curves.png``: training-rollout progress against env steps
  (mean over seeds; band: min–max over seeds; trailing mean over 3 updates).
"""

from __future__ import annotations

import csv
import io
import math
import re
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
from comat.measure.metrics import (
    current_names,  # files written before issue 32: today's names
    mean_ci,
    read_results,  # an evaluation with its per-episode detail
)

HERE = ROOT / "results" / "ablations"
SWEEP = ROOT / "results" / "sweep"
NAME = re.compile(r"(?P<variant>.+)_(?P<task>hmt|pcp)_s(?P<seed>\d+)_(?P<steps>\d+)$")
LABELS = {
    "mat": "MAT (sweep)",
    "a_control": "(a) COMAT, paper form (sweep)",
    "b_root": "(b) root term",
    "c_embed": "(c) obs embedding + residual",
    "d_embed_small": "(d) (c) + messages at gain 0.01",
    "d2_tblock": "(d2) (d) + per-robot FFN",
    "e_reference": "(e) (d2) + reference HEAT messages",
    "f_world": "(f) (d2) + world-frame edges",
    "g_shared": "(g) (d2) + shared decision trunk",
    "h_gae": "(h) (d2) + GAE(λ) value target",
    "i_reference_shared": "(i) (d2) + (e) + (g)",
}


def _curve(folder: Path) -> dict[str, np.ndarray]:
    with open(folder / "progress.csv") as fh:
        rows = current_names(list(csv.DictReader(fh)))
    return {
        k: np.array([float(r[c]) for r in rows])
        for k, c in (
            ("steps", "env_steps"),
            ("progress", "episode_progress"),
            ("finished", "episode_finished"),
            ("return", "episode_return"),
        )
    }


def _evals(folder: Path) -> list[dict[str, float]]:
    with open(folder / "eval.csv") as fh:
        return [{k: float(v) for k, v in r.items()} for r in current_names(list(csv.DictReader(fh)))]


def _final_eval(folder: Path, algo: str) -> dict[str, dict[str, float]] | None:
    path = folder / "evaluation_unicycle.json"
    if not path.is_file():
        return None
    rows = read_results(path)["rows"]
    return {
        r["set"]: {m: r["metrics"][m]["mean"] for m in ("finished", "progress", "return")}
        for r in rows
        if r["policy"] == algo
    }


def load_runs() -> list[dict]:
    runs = []
    for folder in sorted((HERE / "runs").glob("*")):
        m = NAME.match(folder.name)
        if m and (folder / "progress.csv").is_file():
            runs.append(
                {
                    "variant": m["variant"],
                    "task": m["task"],
                    "seed": int(m["seed"]),
                    "budget": int(m["steps"]),
                    "curve": _curve(folder),
                    "evals": _evals(folder),
                    "final": _final_eval(folder, "comat"),
                }
            )
    for algo, variant in (("mat", "mat"), ("comat", "a_control")):
        for folder in sorted(SWEEP.glob(f"{algo}_*_s*")):
            task, seed = folder.name.split("_")[1], int(folder.name.split("_s")[-1])
            runs.append(
                {
                    "variant": variant,
                    "task": task,
                    "seed": seed,
                    "budget": 300_000,
                    "curve": _curve(folder),
                    "evals": _evals(folder),
                    "final": _final_eval(folder, algo),
                }
            )
    return runs


def _at(curve: dict, key: str, step: float, window: int = 3) -> float:
    """Mean of ``key`` over the ``window`` updates ending at the last update at or before ``step``."""
    idx = int(np.searchsorted(curve["steps"], step, side="right"))
    if idx == 0 or curve["steps"][idx - 1] < 0.9 * step:
        return math.nan
    return float(curve[key][max(0, idx - window) : idx].mean())


def _eval_at(evals: list[dict], step: float, key: str) -> float:
    near = [e for e in evals if abs(e["env_steps"] - step) <= 0.05 * step]
    return near[0][key] if near else math.nan


def _cell(values: list[float], pct: bool = True) -> str:
    values = [v for v in values if not math.isnan(v)]
    if not values:
        return "—"
    scale = 100 if pct else 1
    text = "/".join(f"{scale * v:.0f}" if pct else f"{v:.2f}" for v in values)
    return text


def _order(variants) -> list[str]:
    return [v for v in LABELS if v in variants] + sorted(set(variants) - set(LABELS))


def screen_table(runs: list[dict]) -> str:
    lines = [
        "# Screen: one seed per variant at ~100 k env steps (sweep preset otherwise)",
        "",
        (
            "Training rollouts (stochastic policy, U_train): progress = share of prey captured / material "
            "delivered, finished = share of episodes with every prey captured / all material delivered; "
            "mean of the 3 updates ending at the step. Deterministic evaluation: `eval.csv` (one episode "
            "per U_train coalition) at ~100 k. Several seeds: values per seed, s0/s1/s2. References (a) "
            "and MAT: the first 100 k steps of the sweep's 300 k-step runs (3 seeds, same preset)."
        ),
        "",
    ]
    for task in ("hmt", "pcp"):
        sel = [r for r in runs if r["task"] == task]
        lines += [
            f"## {task.upper()}",
            "",
            "| variant | seeds | progress 25 k | 50 k | 100 k | finished 100 k | eval progress 100 k | eval finished 100 k |",
            "|---|---|---|---|---|---|---|---|",
        ]
        for v in _order({r["variant"] for r in sel}):
            rs = sorted((r for r in sel if r["variant"] == v), key=lambda r: r["seed"])
            cells = [_cell([_at(r["curve"], "progress", s) for r in rs]) for s in (25_000, 50_000, 100_000)]
            cells.append(_cell([_at(r["curve"], "finished", 100_000) for r in rs]))
            cells += [_cell([_eval_at(r["evals"], 100_000, k) for r in rs]) for k in ("progress", "finished")]
            lines.append(f"| {LABELS.get(v, v)} | {len(rs)} | " + " | ".join(cells) + " |")
        lines.append("")
    return "\n".join(lines)


def confirm_table(runs: list[dict]) -> tuple[str, str]:
    buf = io.StringIO()
    writer = csv.writer(buf)
    writer.writerow(["task", "variant", "set", "metric", "seeds", "mean", "ci95_over_seeds", "per_seed"])
    lines = [
        "# Confirmation: 3 seeds at 300 k env steps, deterministic evaluation",
        "",
        (
            "One episode per coalition (20 per set), mean over seeds ± 95 % Student-t interval over seeds "
            "(per-seed values in confirm.csv). Finished = share of episodes with every prey captured / all "
            "material delivered (the paper's completion); progress = share captured / delivered."
        ),
        "",
        "| task | variant | seeds | U_train finished | U_train progress | U_test finished | U_test progress |",
        "|---|---|---|---|---|---|---|",
    ]
    for task in ("pcp", "hmt"):
        sel = [r for r in runs if r["task"] == task and r["budget"] >= 300_000 and r["final"]]
        for v in _order({r["variant"] for r in sel}):
            rs = sorted((r for r in sel if r["variant"] == v), key=lambda r: r["seed"])
            if len(rs) < 3:
                continue
            cells = []
            for split in ("train", "test"):
                for metric in ("finished", "progress"):
                    vals = [r["final"][split][metric] for r in rs]
                    mean, half = mean_ci(vals)
                    writer.writerow(
                        [
                            task,
                            v,
                            split,
                            metric,
                            len(vals),
                            f"{mean:.4f}",
                            f"{half:.4f}",
                            " ".join(f"{x:.4f}" for x in vals),
                        ]
                    )
                    cells.append(f"{100 * mean:.1f}% ± {100 * half:.1f}")
            lines.append(f"| {task.upper()} | {LABELS.get(v, v)} | {len(rs)} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n", buf.getvalue()


def curves(runs: list[dict], path: Path, budget: float, variants: list[str] | None = None, min_budget: int = 0) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(12, 4.2))
    for ax, task in zip(axes, ("hmt", "pcp")):
        sel = [r for r in runs if r["task"] == task and r["budget"] >= min_budget]
        for v in _order({r["variant"] for r in sel}):
            if variants is not None and v not in variants:
                continue
            rs = [r for r in sel if r["variant"] == v and r["curve"]["steps"][-1] >= 0.9 * min(budget, r["budget"])]
            if not rs:
                continue
            end = min(budget, min(r["curve"]["steps"][-1] for r in rs))
            grid = np.linspace(max(r["curve"]["steps"][0] for r in rs), end, 80)
            ys = []
            for r in rs:
                y = r["curve"]["progress"]
                y = np.convolve(y, np.ones(3))[: len(y)] / np.minimum(np.arange(1, len(y) + 1), 3)
                ys.append(np.interp(grid, r["curve"]["steps"], y))
            ys = np.asarray(ys)
            style = "--" if v in ("mat", "a_control") else "-"
            (line,) = ax.plot(grid, ys.mean(0), style, label=f"{LABELS.get(v, v)} ({len(rs)})")
            if len(rs) > 1:
                ax.fill_between(grid, ys.min(0), ys.max(0), color=line.get_color(), alpha=0.15)
        ax.set_title(f"{task.upper()}: training-rollout progress (U_train)")
        ax.set_xlabel("env steps")
        ax.set_ylabel("share of prey captured" if task == "pcp" else "share of material delivered")
        ax.set_ylim(0, 1)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="lower right")
    fig.suptitle(
        "Mean over seeds (number of seeds in brackets); band: min–max over seeds; trailing mean of 3 updates",
        fontsize=9,
    )
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> None:
    runs = load_runs()
    (HERE / "screen.md").write_text(screen_table(runs))
    curves(runs, HERE / "screen_curves.png", 105_000)
    md, table = confirm_table(runs)
    (HERE / "confirm.md").write_text(md)
    (HERE / "confirm.csv").write_text(table)
    finalists = {r["variant"] for r in runs if r["budget"] >= 300_000}
    curves(runs, HERE / "confirm_curves.png", 310_000, sorted(finalists), min_budget=300_000)
    print(f"{len(runs)} runs -> {HERE}/screen.md, confirm.md, confirm.csv, screen_curves.png, confirm_curves.png")


if __name__ == "__main__":
    main()
