"""The report's generalization table (``generalization.csv`` / ``.md``) and the Welch comparisons.

Per (task, algorithm) row: for every composition set present and every endpoint present
(:data:`comat.eval.report.ENDPOINTS`), the mean over seeds of the per-seed means (each seed's
coalitions, each its K episodes averaged first), the 95 % t half-width over seeds (``_ci95``) and
the number of seeds (``_seeds``); progress retention per set other than U_train; and, on every
baseline's row, COMAT − this algorithm on :data:`comat.eval.report.COMPARED` with Welch's test
over per-seed means (:func:`comat.measure.stats.welch`): ``<set>_<key>_comat_diff`` with
``_comat_diff_lo`` / ``_comat_diff_hi`` (95 %, Welch–Satterthwaite df), ``_welch_t``,
``_welch_df``, ``_welch_p``. The test decides a comparison (p < :data:`comat.eval.report.ALPHA`);
two overlapping intervals are not a test and no verdict rests on them. The .md table adds each p
Holm-adjusted over the table's decidable tests (:func:`comat.measure.stats.holm`), and its caption
counts the verdicts that keep p < ALPHA after it.
"""

from __future__ import annotations

import csv
import io
import math

import numpy as np

from comat.eval.figures import algo_label
from comat.eval.runs import ALPHA, COMPARED, PAPER_RETENTION, SET_NAMES, method_text, seed_means
from comat.measure.metrics import interval_text, mean_ci
from comat.measure.stats import holm, welch

__all__ = ["generalization_csv", "generalization_md", "generalization_rows"]

_NOUNS = {"progress": "progress", "finished": "finished share", "progress_auc": "progress AUC"}
_WELCH = ("comat_diff", "comat_diff_lo", "comat_diff_hi", "welch_t", "welch_df", "welch_p")


def generalization_rows(
    groups: dict, tasks: list[str], algos: list[str], sets: list[str], endpoints: list[tuple[str, str]]
) -> list[dict]:
    """One row per (task, algo) in ``algos`` order, with the columns of the module docstring."""
    rows, values = [], {}
    for task in tasks:
        for algo in algos:
            runs = groups.get((algo, task), [])
            row = {"task": task, "algo": algo, "seeds": len([r for r in runs if r["evaluation"]])}
            for split in sets:
                for metric, key in endpoints:
                    vals = values[(task, algo, split, key)] = seed_means(runs, split, metric)
                    mean, half = mean_ci(vals) if vals else (math.nan, math.nan)
                    name = f"{split}_{key}"
                    row[name], row[f"{name}_ci95"], row[f"{name}_seeds"] = mean, half, len(vals)
            for split in (s for s in sets if s != "train"):
                ratios = [
                    un / tr
                    for tr, un in ((_one(r, "train"), _one(r, split)) for r in runs)
                    if tr is not None and un is not None and tr > 0
                ]  # a seed without U_train progress has none
                mean, half = mean_ci(ratios) if ratios else (math.nan, math.nan)
                row[f"{split}_retention"], row[f"{split}_retention_ci95"] = mean, half
                row[f"{split}_retention_seeds"] = len(ratios)
            rows.append(row)
    keys = [k for _, k in endpoints if k in COMPARED]
    for row in rows:
        for split in sets:
            for key in keys:
                mine = values.get((row["task"], "comat", split, key))
                other = values[(row["task"], row["algo"], split, key)]
                test = welch(mine, other) if row["algo"] != "comat" and mine and other else None
                for name, field in zip(_WELCH, ("diff", "lo", "hi", "t", "df", "p")):
                    row[f"{split}_{key}_{name}"] = math.nan if test is None else test[field]
        tr, te = row.get("train_return", math.nan), row.get("test_return", math.nan)
        row["test_return_ratio"] = te / tr if tr > 0 and te >= 0 else math.nan  # the paper's form, where defined
        row["paper_retention_return_ratio"] = PAPER_RETENTION.get((row["task"], row["algo"]), math.nan)
    return rows


def _one(run: dict, split: str) -> float | None:
    vals = seed_means([run], split, "progress")
    return vals[0] if vals else None


def generalization_csv(rows: list[dict]) -> str:
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=list(rows[0]))
    writer.writeheader()
    writer.writerows(rows)
    return buf.getvalue()


def _cell(row: dict, key: str, scale: float = 100.0, digits: int = 1) -> str:
    """``row[key]`` (x ``scale``) ± its ``_ci95`` half-width where there is one, naming the seeds
    where fewer than the row's had it."""
    mean, half = row.get(key, math.nan), row.get(f"{key}_ci95", math.nan)
    if math.isnan(mean):
        return "—"
    share = key.endswith(("_progress", "_finished", "_progress_auc"))  # cut to [0, 1]; not retention or t90
    cell = interval_text(mean, half, share=share, scale=scale, digits=digits)
    n = row.get(f"{key}_seeds", row["seeds"])
    return cell if n in (0, row["seeds"]) else f"{cell} ({n} of {row['seeds']} seeds)"


def _table(rows: list[dict], head: list[str], cells) -> list[str]:
    """A markdown table: task, algorithm and seeds, then ``cells(row)``."""
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for row in rows:
        lines.append(
            "| " + " | ".join([row["task"].upper(), algo_label(row["algo"]), str(row["seeds"]), *cells(row)]) + " |"
        )
    return lines


def generalization_md(
    rows: list[dict], tasks: list[str], algos: list[str], sets: list[str], endpoints: list[tuple[str, str]], k_text: str
) -> str:
    """Progress and retention, the finished share, ``progress_auc`` and ``time_to_90`` where
    present, each per set; then COMAT against each baseline (Welch)."""
    keys = [k for _, k in endpoints]
    unseen = [s for s in sets if s != "train"]
    method = method_text("the Seeds column, or as named", k_text)
    head = [
        "Task",
        "Algorithm",
        "Seeds",
        *(f"{SET_NAMES[s]} progress (%)" for s in sets),
        *(f"{SET_NAMES[s]} retention (%)" for s in unseen),
    ]
    lines = _table(
        rows,
        head,
        lambda row: [*(_cell(row, f"{s}_progress") for s in sets), *(_cell(row, f"{s}_retention") for s in unseen)],
    )
    lines += [
        "",
        (
            "Progress: the task's share of its work done (PCP: prey captured; HMT: material delivered; "
            f"deterministic policy); {method}. "
            "Retention: progress on the set / progress on U_train, per seed, then the same t-interval (undefined "
            "for a seed with no U_train progress, which the cell then names)."
        ),
        "",
    ]
    head = ["Task", "Algorithm", "Seeds", *(f"{SET_NAMES[s]} finished (%)" for s in sets)]
    lines += _table(rows, head, lambda row: [_cell(row, f"{s}_finished") for s in sets])
    lines += [
        "",
        (
            "Finished: share of episodes in which the task was done before the horizon (the paper's "
            f'"completion"); {method}. A binary endpoint: it needs many more seeds than progress to separate '
            "anything, read it as descriptive."
        ),
        "",
    ]
    if "progress_auc" in keys:
        head = ["Task", "Algorithm", "Seeds", *(f"{SET_NAMES[s]} progress AUC (%)" for s in sets)]
        lines += _table(rows, head, lambda row: [_cell(row, f"{s}_progress_auc") for s in sets])
        lines += [
            "",
            (
                "Progress AUC: mean over the horizon's env steps of the progress after each step, the final "
                f"value held after an early finish (finishing sooner scores higher); {method}."
            ),
            "",
        ]
    if "time_to_90" in keys:
        head = ["Task", "Algorithm", "Seeds", *(f"{SET_NAMES[s]} steps to 90 %" for s in sets)]
        lines += _table(rows, head, lambda row: [_cell(row, f"{s}_time_to_90", 1.0) for s in sets])
        lines += [
            "",
            (
                "Steps to 90 %: env steps until progress first reached 90 %, the horizon for an episode that "
                f"never did (censored, so a mean is a lower bound where episodes time out); {method}. "
                "Descriptive: not tested."
            ),
            "",
        ]
    lines += _comparisons(rows, tasks, algos, sets, [k for k in keys if k in COMPARED])
    lines += [
        "",
        (
            "aggregates.csv: per set and metric the same t-interval over seeds, and the mean and interquartile "
            "mean of the seed x coalition cells with hierarchical-bootstrap intervals (seeds, then coalitions "
            "within a seed; it targets the coalition population). That bootstrap is descriptive only: in "
            "calibration (comat/measure/stats.py) its 95 % interval covered 73 % of the time at 3 seeds, 83 % at 5 "
            "and 90 % at 12; no claim rests on it."
        ),
    ]
    return "\n".join(lines) + "\n"


def _p(p: float) -> str:
    return "—" if math.isnan(p) else "< 0.001" if p < 0.001 else f"{p:.3f}"


def _verdict(row: dict, mine: dict, split: str, key: str) -> str:
    """Why there is no test, or what the test says."""
    name = SET_NAMES[split]
    if not mine[f"{split}_{key}_seeds"]:
        return f"COMAT not evaluated on {name}"
    if not row[f"{split}_{key}_seeds"]:
        return f"not evaluated on {name}"
    if min(mine[f"{split}_{key}_seeds"], row[f"{split}_{key}_seeds"]) < 2:
        return "not decidable (needs 2+ seeds each)"
    p = row[f"{split}_{key}_welch_p"]
    if math.isnan(p):
        return "not decidable (no spread over seeds on either side)"
    if p >= ALPHA:
        return f"not separated (p ≥ {ALPHA:g})"
    return f"COMAT {'higher' if row[f'{split}_{key}_comat_diff'] > 0 else 'lower'} (p < {ALPHA:g})"


def _comparisons(rows: list[dict], tasks: list[str], algos: list[str], sets: list[str], keys: list[str]) -> list[str]:
    by = {(r["task"], r["algo"]): r for r in rows}
    lines = ["### COMAT against each baseline: Welch's t-test over per-seed means", ""]
    compared = []
    for task in tasks:
        mine = by.get((task, "comat"))
        others = [by[(task, a)] for a in algos if a != "comat" and by[(task, a)]["seeds"]]
        if mine is None or not mine["seeds"]:
            lines.append(f"* {task.upper()}: no COMAT runs in this report: nothing to compare.")
            continue
        if not others:
            lines.append(f"* {task.upper()}: COMAT alone, no baseline in these runs: nothing to compare.")
            continue
        compared += [(task, split, key, mine, row) for split in sets for key in keys for row in others]
    p = np.array([row[f"{split}_{key}_welch_p"] for _, split, key, _, row in compared])
    adjusted = holm(p)  # over this table's decidable tests: the family a reader scans
    tests, separated, kept = int(np.isfinite(p).sum()), int((p < ALPHA).sum()), int((adjusted < ALPHA).sum())
    if compared:
        lines += [
            (
                "| Task | Set | Endpoint | Baseline | COMAT (%) | Baseline (%) | COMAT − baseline, points [95 %] "
                "| t | df | p | Holm p | Welch verdict (unadjusted p) |"
            ),
            "|" + "---|" * 12,
            *(_comparison_line(*c, h) for c, h in zip(compared, adjusted)),
            "",
            (
                "COMAT − baseline: difference of the means over seeds, in percentage points, with its 95 % "
                "interval (Welch–Satterthwaite df); t and two-sided p of Welch's t-test over the per-seed means "
                "(each seed's coalitions, each its episodes averaged first). The test decides: 'COMAT higher / "
                f"lower' where p < {ALPHA:g}, 'not separated' otherwise; overlapping intervals are not used as a "
                f"test. That verdict's p is not adjusted for multiplicity; Holm p adjusts it over the {tests} tests "
                f"of this table (Holm's step-down, family-wise error {ALPHA:g}): {kept} of the {separated} "
                f"'higher / lower' verdicts keep p < {ALPHA:g} after it. Read an unadjusted p as a single test only "
                "where it was chosen before the results (e.g. HMT U_scale progress, COMAT − MAT)."
            ),
        ]
    return lines


def _comparison_line(task: str, split: str, key: str, mine: dict, row: dict, p_holm: float) -> str:
    """One line of the Welch table: COMAT's and the baseline's cells, the difference, the test
    with its Holm-adjusted p (``p_holm``, nan where there is no test)."""
    name = f"{split}_{key}"
    d, lo, hi = (row[f"{name}_{k}"] for k in ("comat_diff", "comat_diff_lo", "comat_diff_hi"))
    t, df, p = (row[f"{name}_{k}"] for k in ("welch_t", "welch_df", "welch_p"))
    diff = "—" if math.isnan(d) else f"{100 * d:+.1f}"
    diff += "" if math.isnan(lo) else f" [{100 * lo:+.1f}, {100 * hi:+.1f}]"
    cells = [
        task.upper(),
        SET_NAMES[split],
        _NOUNS[key],
        algo_label(row["algo"]),
        _cell(mine, name),
        _cell(row, name),
        diff,
        "—" if math.isnan(t) else f"{t:.2f}",
        "—" if math.isnan(df) else f"{df:.1f}",
        _p(p),
        _p(p_holm),
        _verdict(row, mine, split, key),
    ]
    return "| " + " | ".join(cells) + " |"
