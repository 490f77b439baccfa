"""The competence table (issue 65, ``PLAN.md``): results/learnability/README.md between its table markers,
and ``curves.png``, from each kept run (runs/ALGO_TASK_sSEED: evaluation_unicycle.json, eval.csv) beside
the task's reference ladder (results/sets/validity/<task>/, written by ``comat validity``). No number is
typed by hand.

A learner's cell is the mean over its kept seeds of the run's progress on the set (each run's value its
mean over the set's 20 coalitions × 5 episodes) with a 95 % Student-t interval over seeds (the
replicated unit) once two or more seeds are kept; ``(n)`` says how many. The endpoints follow the plan:
competence (best learner above blind on U_train), COMAT's gap (best − COMAT ≤ 5 on U_train) and the
moonshot (a learner above type_only on U_cap).

    .venv/bin/python results/learnability/table.py
"""

import csv
from pathlib import Path

import numpy as np
from scipy import stats

from comat.eval import SET_NAMES
from comat.files import replace_block
from comat.measure.metrics import read_results

HERE = Path(__file__).resolve().parent
SETS = ("train", "val", "test", "scale", "size", "capability")
ALGOS = ("comat", "mat", "cash")
TASKS = ("forage", "navigation", "sensors", "arctic", "warehouse")
REFERENCES = ("heuristic", "type_only", "blind", "random")
COMAT_MARGIN = 5.0
"""Points: COMAT within this of the best learner on U_train (the issue's target)."""


def _progress(rows: list[dict], policy: str) -> dict[str, float]:
    return {r["set"]: 100 * r["metrics"]["progress"]["mean"] for r in rows if r["policy"] == policy}


def runs_of(algo: str, task: str) -> list[Path]:
    """Kept run folders of one learner on one task, by seed."""
    return sorted(p for p in (HERE / "runs").glob(f"{algo}_{task}_s*") if (p / "evaluation_unicycle.json").is_file())


def seed_values(algo: str, task: str) -> dict[str, list[float]]:
    """Set -> each kept seed's progress % on it."""
    out: dict[str, list[float]] = {s: [] for s in SETS}
    for run in runs_of(algo, task):
        got = _progress(read_results(run / "evaluation_unicycle.json", detail=False)["rows"], algo)
        for s in SETS:
            if s in got:
                out[s].append(got[s])
    return out


def mean_ci(values: list[float]) -> tuple[float, float | None]:
    """Mean and the 95 % t half-width over seeds (None below two seeds)."""
    v = np.asarray(values, dtype=float)
    if v.size < 2:
        return float(v.mean()), None
    return float(v.mean()), float(stats.t.ppf(0.975, v.size - 1) * v.std(ddof=1) / np.sqrt(v.size))


def cell(values: list[float]) -> str:
    if not values:
        return "—"
    m, h = mean_ci(values)
    return f"{m:.1f} (1)" if h is None else f"{m:.1f} ± {h:.1f} ({len(values)})"


def verdicts(task: str, learners: dict[str, dict[str, list[float]]], refs: dict[str, dict[str, float]]) -> list[str]:
    """The plan's endpoints for one task, in words, from the means over seeds."""
    train = {a: mean_ci(v["train"])[0] for a, v in learners.items() if v["train"]}
    if not train:
        return []
    best = max(train, key=train.get)
    blind, type_only = refs["blind"]["train"], refs["type_only"]["capability"]
    seeds = {a: len(v["train"]) for a, v in learners.items()}
    out = [
        f"* competence: best on U_train {best} {train[best]:.1f} against blind {blind:.1f} — "
        + ("above" if train[best] > blind else "**not above**")
        + f" ({seeds[best]} seed(s))"
    ]
    if "comat" in train and best != "comat":
        gap = train[best] - train["comat"]
        out.append(
            f"* COMAT's gap: {gap:.1f} points below {best} on U_train — "
            + ("within" if gap <= COMAT_MARGIN else "**beyond**")
            + f" {COMAT_MARGIN:.0f}"
        )
    elif "comat" in train:
        out.append("* COMAT's gap: COMAT is the best learner on U_train")
    cap = {a: mean_ci(v["capability"])[0] for a, v in learners.items() if v["capability"]}
    above = [f"{a} {cap[a]:.1f}" for a in cap if cap[a] > type_only]
    out.append(f"* moonshot (U_cap above type_only {type_only:.1f}): " + (", ".join(above) if above else "no learner"))
    return out


def curves() -> None:
    """curves.png: each kept run's periodic evaluation progress (eval.csv) against env steps."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from comat.learners import learner_entry

    fig, axes = plt.subplots(1, len(TASKS), figsize=(4 * len(TASKS), 3.2), sharey=True)
    for ax, task in zip(axes, TASKS, strict=True):
        for algo in ALGOS:
            colour = learner_entry(algo).colour
            for k, run in enumerate(runs_of(algo, task)):
                with open(run / "eval.csv") as f:
                    rows = list(csv.DictReader(f))
                x = [float(r["env_steps"]) / 1e6 for r in rows]
                y = [100 * float(r["progress"]) for r in rows]
                ax.plot(x, y, color=colour, alpha=0.8, label=algo if k == 0 else None)
        ax.set_title(task)
        ax.set_xlabel("env steps (M)")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("U_train progress % (training-time eval)")
    handles = {h.get_label(): h for ax in axes for h in ax.get_lines() if not h.get_label().startswith("_")}
    fig.legend(handles.values(), handles.keys(), loc="upper right", fontsize=8)
    fig.tight_layout()
    fig.savefig(HERE / "curves.png", dpi=110)


def main() -> None:
    lines = [
        (
            "Progress % (deterministic policy, 5 episodes per coalition, 20 coalitions per set, reality off, "
            "unicycle; 1 M env steps, `sweep` preset): mean over the kept seeds ± the 95 % t half-width over "
            "seeds, (n) seeds kept. References from `results/sets/validity.md` (planners with the full task "
            "state, their own evaluation seed 4,000,037; the runs' is 2,000,003). A run not yet kept shows as —."
        ),
        "",
    ]
    for task in TASKS:
        ladder = HERE.parent / "sets" / "validity" / task / "evaluation_unicycle.json"
        refs_rows = read_results(ladder, detail=False)["rows"]
        refs = {ref: _progress(refs_rows, ref) for ref in REFERENCES}
        learners = {algo: seed_values(algo, task) for algo in ALGOS}
        lines += [f"### {task}", "", "| policy | " + " | ".join(SET_NAMES[s] for s in SETS) + " |"]
        lines.append("|---|" + "---:|" * len(SETS))
        for algo, values in learners.items():
            lines.append(f"| {algo} | " + " | ".join(cell(values[s]) for s in SETS) + " |")
        for ref in REFERENCES:
            lines.append(f"| {ref} (reference) | " + " | ".join(f"{refs[ref][s]:.1f}" for s in SETS) + " |")
        lines += ["", *verdicts(task, learners, refs), ""]
    replace_block(HERE / "README.md", "table", "\n".join(lines))
    curves()
    print(f"wrote {HERE / 'README.md'} and {HERE / 'curves.png'}")


if __name__ == "__main__":
    main()
