"""The report's figures (matplotlib, Agg): Fig. 4, Fig. 5 and return / progress against team size.

Every figure draws a learner in its own colour (:func:`algo_colour`, from its entry in
:mod:`comat.learners`) — the same in every figure and every report — and says in its caption
what a line, band or bar is: the statistic, over what (seeds), the interval method and the
env-step budget. Evaluation intervals are the report's: the
95 % Student-t interval over per-seed means, each seed's mean first averaging its K episodes per
coalition, then its coalitions (:mod:`comat.measure.stats`). Progress axes start at 0, and the team-size
figure writes how many coalitions each point averages. Each is written as PNG (200 dpi)
and PDF (vector), atomically.

Inputs are plain dicts built by :mod:`comat.eval.report` (shapes in each function).
"""

from __future__ import annotations

import io
import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from comat.files import write_atomic
from comat.learners import learner_entry, learner_names
from comat.measure.metrics import mean_ci

__all__ = [
    "SET_HATCHES",
    "SIZE_SETS",
    "TRAIN_SIZES",
    "algo_colour",
    "algo_label",
    "fig4",
    "fig5",
    "fig_team_size",
    "save",
]

SET_HATCHES = {"train": "", "val": "\\\\", "test": "//", "scale": "..", "size": "xx", "capability": "oo"}
"""Composition sets are told apart by hatching, never by colour (colour means algorithm)."""
SET_LABELS = {
    "train": "U_train",
    "val": "U_val (validation)",
    "test": "U_test (unseen)",
    "scale": "U_scale (10-20 robots)",
    "size": "U_size (2-20 robots, training capabilities)",
    "capability": "U_cap (capabilities outside training)",
}
SIZE_SETS = ("train", "test", "scale", "size")
"""Sets pooled in the team-size figure: U_val repeats U_train's draw (it is for model selection)
and U_cap varies capability at the training sizes, so neither belongs on a size axis."""


def algo_label(algo: str) -> str:
    """How tables and figures name learner ``algo``: its entry's label (a learner not registered
    here: its name)."""
    return learner_entry(algo).label if algo in learner_names() else algo


def algo_colour(algo: str) -> str:
    """The colour of learner ``algo`` in every figure: its entry's (colour means learner)."""
    return learner_entry(algo).colour


TRAIN_SIZES = (3, 5, 7)
"""Team sizes of U_train (paper §III-D)."""
METRIC_AXES = {
    "return": "episode return (team reward, sum over steps)",
    "progress": "progress (% of the task's work done)",
}
FORMATS = ("png", "pdf")


def save(fig, stem: Path) -> list[str]:
    """Write ``fig`` as ``stem.png`` and ``stem.pdf``; returns the file names. No creation date in
    the PDF, so the same report written twice is the same bytes (a regenerated report shows no diff)."""
    import matplotlib.pyplot as plt

    names = []
    for fmt in FORMATS:
        buf = io.BytesIO()
        fig.savefig(
            buf, format=fmt, dpi=200, bbox_inches="tight", metadata={"CreationDate": None} if fmt == "pdf" else None
        )
        write_atomic(stem.with_suffix(f".{fmt}"), buf.getvalue())
        names.append(f"{stem.name}.{fmt}")
    plt.close(fig)
    return names


def save_captioned(fig, stem: Path, caption: str) -> list[str]:
    """:func:`save` with ``caption`` in small type under the panels (what the marks, bars and bands are)."""
    fig.text(0.01, -0.01, caption, fontsize=7, ha="left", va="top", wrap=True)
    fig.tight_layout()
    return save(fig, stem)


def clipped_err(values, halves, top: float = 100.0) -> np.ndarray:
    """(2, n) lower and upper error-bar lengths of ``values ± halves`` cut to [0, top]: a share's
    interval stays inside its range, as the tables print it (nan: no bar)."""
    v, h = np.asarray(values, float), np.asarray(halves, float)
    return np.stack([np.minimum(h, np.maximum(v, 0.0)), np.minimum(h, np.maximum(top - v, 0.0))])


def empty_figure(text: str, stem: Path) -> list[str]:
    """A figure that only says why it is empty (so a report's files are always the same set)."""
    fig, ax = _plt().subplots(figsize=(6, 1.5))
    ax.axis("off")
    ax.text(0.5, 0.5, text, ha="center", va="center", fontsize=9)
    return save(fig, stem)


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _budget_text(budgets: Mapping[str, Sequence[int]]) -> str:
    """'COMAT 51,200, MAT 102,400 env steps per run' (a range where seeds differ), or '51,200 env
    steps per run, every algorithm' where all runs of several algorithms had the same budget."""
    parts = []
    for algo, b in budgets.items():
        lo, hi = min(b), max(b)
        parts.append(f"{algo_label(algo)} {lo:,}" + ("" if lo == hi else f"-{hi:,}"))
    every = {x for b in budgets.values() for x in b}
    if len(budgets) > 1 and len(every) == 1:
        return f"{every.pop():,} env steps per run, every algorithm (paper: 4,000,000)"
    return ", ".join(parts) + " env steps per run (paper: 4,000,000)"


def fig4(
    curves: Mapping[tuple[str, str], list[tuple[np.ndarray, np.ndarray]]],
    tasks: list[str],
    algos: list[str],
    budgets: Mapping[str, Mapping[str, Sequence[int]]],
    stem: Path,
) -> list[str]:
    """Training return against env steps, one panel per task.

    ``curves[(algo, task)]``: per seed (env_steps (T,), episode return (T,)). Line: mean over
    seeds of the smoothed curves (trailing mean over ~5 % of each run); band: 95 % Student-t
    interval over seeds (no band with one seed)."""
    plt = _plt()
    fig, axes = plt.subplots(len(tasks), 1, figsize=(7, 3.4 * len(tasks)), squeeze=False)
    for ax, task in zip(axes[:, 0], tasks):
        for algo in algos:
            runs = [c for c in curves.get((algo, task), []) if len(c[0]) > 1]
            if not runs:
                continue
            grid = np.linspace(max(x[0] for x, _ in runs), min(x[-1] for x, _ in runs), 100)
            ys = []
            for x, y in runs:
                k = max(1, len(y) // 20)  # trailing mean over ~5 % of the run (no padding at the ends)
                y = np.convolve(y, np.ones(k))[: len(y)] / np.minimum(np.arange(1, len(y) + 1), k)
                ys.append(np.interp(grid, x, y))
            ys = np.asarray(ys)
            mean = ys.mean(0)
            color = algo_colour(algo)
            ax.plot(grid, mean, color=color, label=f"{algo_label(algo)} ({len(runs)} seed{'s' * (len(runs) > 1)})")
            if len(runs) > 1:
                half = np.array([mean_ci(col)[1] for col in ys.T])
                ax.fill_between(grid, mean - half, mean + half, color=color, alpha=0.2, lw=0)
        ax.set_title(
            f"{task.upper()}: training episode return on U_train\n{_budget_text(budgets.get(task, {}))}", fontsize=9
        )
        ax.set_xlabel("env steps")
        ax.set_ylabel("episode return\n(team reward, sum over steps)")
        ax.grid(alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=8)
        else:
            ax.text(
                0.5,
                0.5,
                "no training curve (fewer than two logged points per run)",
                transform=ax.transAxes,
                ha="center",
                va="center",
                fontsize=8,
                color="grey",
            )
    return save_captioned(
        fig,
        stem,
        "Line: mean over seeds of each run's training episode return, smoothed by a trailing mean "
        "over 5 % of the run. Band: 95 % Student-t interval over seeds (none with one seed).",
    )


def _method(k_text: str) -> str:
    return (
        "95 % Student-t interval over per-seed means (none with one seed); each seed's mean first averages its "
        f"{k_text} episode(s) per coalition, then its coalitions"
    )


def _retention_labels(ax, rows: list[dict], split: str, heights: list[float], xs) -> None:
    """Above each bar at ``xs`` (``heights`` tall), its row's progress retention on ``split``
    (progress there / on U_train), where the row has one."""
    for i, r in enumerate(rows):
        ret = r.get(f"{split}_retention", math.nan)
        if not math.isnan(ret):
            top = max(0.0, heights[i]) if not math.isnan(heights[i]) else 0.0
            ax.annotate(
                f"{100 * ret:.0f}%",
                (xs[i], top),
                xytext=(0, 2),
                textcoords="offset points",
                ha="center",
                va="bottom",
                fontsize=6,
                color="black",
            )


def fig5(
    rows: list[dict],
    tasks: list[str],
    algos: list[str],
    sets: list[str],
    budgets: Mapping[str, Mapping[str, Sequence[int]]],
    stem: Path,
    k_text: str = "1",
) -> list[str]:
    """Return and progress per composition set, bars per algorithm; progress retention labels.

    ``rows``: the generalization rows of :mod:`comat.eval.generalization` (``<set>_return``,
    ``<set>_return_ci95``, ``<set>_progress``, ``<set>_progress_ci95``, ``<set>_retention``);
    ``k_text``: episodes per coalition, for the caption."""
    plt = _plt()
    if not sets:  # runs evaluated on teams of their own only: nothing to compare across sets
        return empty_figure("no composition set (U_train, U_val, ...) in these runs' evaluations", stem)
    fig, axes = plt.subplots(
        2, len(tasks), figsize=(len(tasks) * (1.5 + 0.35 * len(algos) * len(sets)) + 1, 6.4), squeeze=False
    )
    width = 0.8 / len(sets)
    for col, task in enumerate(tasks):
        sel = [r for r in rows if r["task"] == task and r["seeds"]]
        x = np.arange(len(sel))
        for row_i, (metric, key) in enumerate((("return", "return"), ("progress", "progress"))):
            ax = axes[row_i, col]
            for k, split in enumerate(sets):
                scale = 100.0 if key == "progress" else 1.0
                vals = [scale * r.get(f"{split}_{key}", math.nan) for r in sel]
                errs = [scale * r.get(f"{split}_{key}_ci95", math.nan) for r in sel]  # nan: no bar (one seed)
                if key == "progress":
                    errs = clipped_err(vals, errs)
                ax.bar(
                    x + (k - (len(sets) - 1) / 2) * width,
                    vals,
                    width,
                    yerr=errs,
                    capsize=2,
                    color=[algo_colour(r["algo"]) for r in sel],
                    hatch=SET_HATCHES[split],
                    edgecolor="white",
                    alpha=1.0 if split == "train" else 0.75,
                    label=SET_LABELS[split],
                )
                if key == "progress" and split != "train":
                    _retention_labels(ax, sel, split, vals, x + (k - (len(sets) - 1) / 2) * width)
            ax.set_xticks(x, [algo_label(r["algo"]) for r in sel])
            ax.set_ylabel(METRIC_AXES[metric], fontsize=8)
            if key == "progress":
                ax.set_ylim(bottom=0)  # a share: its axis starts at 0, so bar heights compare honestly
            ax.axhline(0, color="k", lw=0.5)
            ax.grid(axis="y", alpha=0.3)
            if row_i == 0:
                ax.set_title(
                    f"{task.upper()}: deterministic policy per composition set\n{_budget_text(budgets.get(task, {}))}",
                    fontsize=9,
                )
            # Legend of the sets: hatching, in neutral grey (colour is the algorithm's).
            from matplotlib.patches import Patch

            ax.legend(
                handles=[
                    Patch(facecolor="#bbbbbb", hatch=SET_HATCHES[s], edgecolor="white", label=SET_LABELS[s])
                    for s in sets
                ],
                fontsize=7,
            )
    counts = {r.get(f"{s}_progress_seeds", r["seeds"]) for r in rows if r["seeds"] for s in sets} - {0}
    seeds = f"{counts.pop()} seeds per bar" if len(counts) == 1 else "seeds per bar: generalization.md"
    return save_captioned(
        fig,
        stem,
        f"Bars: mean over seeds ({seeds}) of each seed's mean over the set's coalitions. Error bars: "
        f"{_method(k_text)}. Labels on the progress bars: progress retention = progress on the set / progress on "
        "U_train.",
    )


def _count_labels(ax, counts: Mapping[str, Mapping[int, tuple[str, float]]]) -> None:
    """Write how many coalitions each point averages: once per size along the axis bottom where
    every algorithm's point there has the same count, else next to each algorithm's point."""
    sizes = sorted({n for per in counts.values() for n in per})
    shared = all(len({per[n][0] for per in counts.values() if n in per}) == 1 for n in sizes)
    for k, (algo, per) in enumerate(counts.items()):
        for n, (text, y) in per.items():
            if shared:
                if k == min(i for i, p in enumerate(counts.values()) if n in p):  # first algorithm with this size
                    ax.annotate(
                        text,
                        (n, 0),
                        xycoords=("data", "axes fraction"),
                        xytext=(0, 3),
                        textcoords="offset points",
                        ha="center",
                        fontsize=6,
                        color="dimgrey",
                    )
            else:
                ax.annotate(
                    text,
                    (n, y),
                    xytext=(3, -8 - 6 * k),
                    textcoords="offset points",
                    fontsize=5,
                    color=algo_colour(algo),
                )


def fig_team_size(
    by_size: Mapping[tuple[str, str], dict[int, list[dict[str, float]]]],
    tasks: list[str],
    algos: list[str],
    budgets: Mapping[str, Mapping[str, Sequence[int]]],
    stem: Path,
    sets: Sequence[str] = ("train", "test", "scale"),
    k_text: str = "1",
) -> list[str]:
    """Return and progress against team size, a line per algorithm.

    ``by_size[(algo, task)][n]``: per seed ``{"return": mean, "progress": mean, "coalitions":
    count}``, the mean over that seed's coalitions with n robots in ``sets`` (each coalition its
    episodes' mean). Line: mean over seeds; band: 95 % Student-t interval over seeds; the
    coalitions each point averages per seed, along the bottom (next to each point where the
    algorithms differ, with the seeds where fewer than the legend's); grey bars mark U_train's
    sizes (3, 5, 7)."""
    plt = _plt()
    fig, axes = plt.subplots(2, len(tasks), figsize=(5.2 * len(tasks), 6.4), squeeze=False)
    for col, task in enumerate(tasks):
        for row_i, metric in enumerate(("return", "progress")):
            ax = axes[row_i, col]
            scale = 100.0 if metric == "progress" else 1.0
            for n in TRAIN_SIZES:
                ax.axvspan(n - 0.35, n + 0.35, color="#dddddd", lw=0, zorder=0)
            counts: dict[str, dict[int, tuple[str, float]]] = {}  # algo -> size -> (count text, y)
            for algo in algos:
                sizes = sorted(by_size.get((algo, task), {}))
                if not sizes:
                    continue
                mean, half = [], []
                for n in sizes:
                    vals = [scale * s[metric] for s in by_size[(algo, task)][n]]
                    m, h = mean_ci(vals)
                    mean.append(m)
                    half.append(0.0 if math.isnan(h) else h)
                mean, half = np.asarray(mean), np.asarray(half)
                color = algo_colour(algo)
                seeds = max(len(v) for v in by_size[(algo, task)].values())
                ax.plot(
                    sizes, mean, "o-", color=color, ms=3, label=f"{algo_label(algo)} ({seeds} seed{'s' * (seeds > 1)})"
                )
                low, high = mean - half, mean + half
                if metric == "progress":
                    low, high = np.clip(low, 0.0, 100.0), np.clip(high, 0.0, 100.0)
                ax.fill_between(sizes, low, high, color=color, alpha=0.2, lw=0)
                for n, m in zip(sizes, mean):  # the count behind each point: coalitions (per seed)
                    per = by_size[(algo, task)][n]
                    text = "/".join(map(str, sorted({int(s["coalitions"]) for s in per})))
                    counts.setdefault(algo, {})[n] = (text + ("" if len(per) == seeds else f" ({len(per)} seeds)"), m)
            _count_labels(ax, counts)
            ax.set_xlabel("team size (robots); grey: U_train's sizes 3, 5, 7")
            ax.set_ylabel(METRIC_AXES[metric], fontsize=8)
            if metric == "progress":
                ax.set_ylim(0, 105)  # a share: from 0, so a drop reads at its true size
            ax.grid(alpha=0.3)
            if row_i == 0:
                ax.set_title(
                    f"{task.upper()}: deterministic policy against team size\n{_budget_text(budgets.get(task, {}))}",
                    fontsize=9,
                )
                if ax.get_legend_handles_labels()[0]:
                    ax.legend(fontsize=7)
    names = ", ".join(SET_LABELS[s].split(" ")[0] for s in sets) or "none"
    return save_captioned(
        fig,
        stem,
        "Points: mean over seeds of each seed's mean over its coalitions with that many robots "
        f"(each coalition its episodes' mean; sets pooled: {names}, where evaluated; U_val and U_cap left out). "
        f"Band: {_method(k_text)}. Numbers along the bottom (or, where algorithms differ, next to each point): "
        "coalitions of that size per seed.",
    )
