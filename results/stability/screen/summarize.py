"""Issue 30 screen: the table of PLAN.md's endpoints from the kept runs (``runs/``), and the
selection rule applied. Reads only U_val (the final evaluation) and U_train (the periodic ones):

    python results/stability/screen/summarize.py > results/stability/screen/screen.md
    python results/stability/screen/summarize.py results/stability/confirm/runs   # the confirmation's table
"""

from __future__ import annotations

import csv
import re
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
from diagnose import _team_slow_payload

from comat.measure.metrics import read_results
from comat.measure.stats import t_interval

NAME = re.compile(r"^(?:(?P<algo>mat)_)?(?P<variant>[a-z_]+?)_(?P<task>hmt|pcp)_s(?P<seed>\d+)_(?P<steps>\d+)$")


def first_at(path: Path, level: float = 0.95) -> str:
    """The first periodic U_train evaluation (deterministic) at >= ``level`` progress, in k env steps."""
    steps = first_step(path, level)
    return "never" if steps is None else f"{steps / 1000:.0f} k"


def one_run(folder: Path) -> dict:
    m = NAME.match(folder.name)
    data = read_results(folder / "evaluation_unicycle.json")
    row = next(r for r in data["rows"] if r["set"] == "val" and r["policy"] not in ("heuristic", "constant", "random"))
    eps = row["per_episode"]
    y = np.array([100 * e["progress"] for e in eps])
    slope = float("nan")
    if m["task"] == "hmt":
        x = np.array([_team_slow_payload("hmt", "val", e["coalition"]) for e in eps])
        slope = float(np.polyfit((x - x.mean()) / x.std(), y, 1)[0])
    return {
        "algo": m["algo"] or "comat",
        "variant": m["variant"],
        "task": m["task"],
        "seed": int(m["seed"]),
        "progress": float(y.mean()),
        "finished": 100 * float(np.mean([e["finished"] for e in eps])),
        "slope": slope,
        "t95": first_at(folder / "eval.csv"),
        "folder": str(folder),
    }


def first_step(path: Path, level: float = 0.95) -> int | None:
    """The env steps of the first periodic U_train evaluation at >= ``level`` progress (None: never)."""
    with open(path) as fh:
        return next((int(r["env_steps"]) for r in csv.DictReader(fh) if float(r["progress"]) >= level), None)


def judge(groups: dict) -> None:
    """confirm/PLAN.md's targets, COMAT (the selected variant) against MAT, each said whether or not it holds."""
    from scipy import stats

    comat = [g for k, g in groups.items() if k[:2] == ("hmt", "comat")]
    mat = groups.get(("hmt", "mat", "control"))
    if len(comat) != 1 or not mat:
        print("\nThe targets need COMAT's and MAT's HMT runs.")
        return
    comat = sorted(comat[0], key=lambda r: r["seed"])
    mat = sorted(mat, key=lambda r: r["seed"])
    c, m = np.array([r["progress"] for r in comat]), np.array([r["progress"] for r in mat])
    sc, sm = np.array([r["slope"] for r in comat]), np.array([r["slope"] for r in mat])
    print(f"\n## The issue's targets (PLAN.md), HMT on U_val: {c.size} COMAT and {m.size} MAT seeds\n")
    if c.size < 5 or m.size < 5:
        print("*Interim: the targets are judged at 5 seeds each.*\n")
    say = {True: "**holds**", False: "**does not hold**"}
    limit = max(2 * m.std(ddof=1), 3.0)
    print(
        f"1. Seed SD: COMAT {c.std(ddof=1):.1f} ≤ max(2 × MAT's {m.std(ddof=1):.1f}, 3) = {limit:.1f}: "
        f"{say[bool(c.std(ddof=1) <= limit)]}."
    )
    steps = [first_step(Path(r["folder"]) / "eval.csv") for r in comat]
    early = sum(s is not None and s <= 151_000 for s in steps)
    print(
        f"2. ≥ 95 % U_train progress by the 150 k evaluation: {early} of {len(steps)} COMAT seeds "
        f"(need ≥ 4 of 5): {say[early >= 4]}."
    )
    lo, hi = (t_interval(m)[k] for k in ("lo", "hi"))
    print(
        f"3. COMAT mean {c.mean():.1f} ≥ the lower end of MAT's 95 % t-interval [{lo:.1f}, {hi:.1f}]: "
        f"{say[bool(c.mean() >= lo)]}."
    )
    slo, shi = (t_interval(sm)[k] for k in ("lo", "hi"))
    print(
        f"4. COMAT's slow-share slope {sc.mean():+.2f} within MAT's 95 % t-interval [{slo:+.2f}, {shi:+.2f}]: "
        f"{say[bool(slo <= sc.mean() <= shi)]}."
    )
    welch = stats.ttest_ind(c, m, equal_var=False)
    print(
        f"\nDescriptive: COMAT − MAT HMT progress {c.mean() - m.mean():+.2f} points, Welch t {welch.statistic:+.2f}, "
        f"p = {welch.pvalue:.2f} (not powered for less than ~10 points at 5 seeds)."
    )
    for task in ("pcp",):
        pc, pm = groups.get((task, "comat", comat[0]["variant"])), groups.get((task, "mat", "control"))
        if pc and pm:
            a, b = np.array([r["progress"] for r in pc]), np.array([r["progress"] for r in pm])
            print(
                f"PCP progress: COMAT {a.mean():.1f} (SD {a.std(ddof=1):.1f}, {a.size} seeds), "
                f"MAT {b.mean():.1f} (SD {b.std(ddof=1):.1f}, {b.size} seeds)."
            )


def main(folder: Path = HERE / "runs") -> None:
    runs = [one_run(f) for f in sorted(folder.iterdir()) if (f / "summary.json").is_file()]
    groups: dict[tuple, list[dict]] = {}
    for r in runs:
        groups.setdefault((r["task"], r["algo"], r["variant"]), []).append(r)
    print(f"# Issue 30, {folder.parent.name}: U_val (deterministic, 5 episodes per coalition)\n")
    print("Per seed, in seed order; SD over seeds. *first ≥ 95 %*: the first periodic U_train evaluation")
    print("(every 25 k, 1 episode per coalition) at ≥ 95 % progress. *slope*: HMT progress points per SD")
    print("of the slow robots' payload share over U_val's episodes, mean over seeds.\n")
    print(
        "| task | learner | variant | seeds | progress % per seed | mean | SD | worst | finished % (mean) "
        "| first ≥ 95 % per seed | slope |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for (task, algo, variant), rs in sorted(groups.items()):
        rs = sorted(rs, key=lambda r: r["seed"])
        p = np.array([r["progress"] for r in rs])
        sd = float(p.std(ddof=1)) if p.size > 1 else float("nan")
        slope = np.nanmean([r["slope"] for r in rs]) if task == "hmt" else float("nan")
        print(
            f"| {task} | {algo} | {variant} | {len(rs)} | {' / '.join(f'{v:.1f}' for v in p)} | {p.mean():.1f} | "
            f"{sd:.1f} | {p.min():.1f} | {np.mean([r['finished'] for r in rs]):.1f} | "
            f"{' / '.join(r['t95'] for r in rs)} | {'' if np.isnan(slope) else f'{slope:+.1f}'} |"
        )
    if folder != HERE / "runs":
        judge(groups)  # the confirmation (confirm/PLAN.md): the four targets
        return
    print("\n## The selection rule (PLAN.md)\n")
    worst = {k: min(r["progress"] for r in rs) for k, rs in groups.items()}
    mean = {k: float(np.mean([r["progress"] for r in rs])) for k, rs in groups.items()}
    control = ("hmt", "comat", "control")
    if control not in worst:
        print("No control runs yet.")
        return
    chosen, best = "control", worst[control]
    seeds = {k: {r["seed"] for r in rs} for k, rs in groups.items()}
    for (task, algo, variant), w in sorted(worst.items()):
        if task != "hmt" or algo != "comat" or variant == "control":
            continue
        if seeds[(task, algo, variant)] != seeds[control]:
            print(
                f"* {variant}: {len(seeds[(task, algo, variant)])} of the control's {len(seeds[control])} seeds so far: "
                "not compared yet"
            )
            continue
        pcp = ("pcp", "comat", variant)
        if pcp in seeds and seeds[pcp] != seeds.get(("pcp", "comat", "control")):
            mean.pop(pcp)  # not on the control's seeds yet: not compared
        pcp_ok = (
            pcp in mean and ("pcp", "comat", "control") in mean and mean[pcp] >= mean[("pcp", "comat", "control")] - 2
        )
        print(
            f"* {variant}: worst HMT seed {w:.1f} vs control {worst[control]:.1f} "
            f"({w - worst[control]:+.1f} points); PCP mean "
            + (
                f"{mean[pcp]:.1f} vs control {mean[('pcp', 'comat', 'control')]:.1f} ({'within' if pcp_ok else 'more than'} 2 points below)"
                if pcp in mean and ("pcp", "comat", "control") in mean
                else "not on all the control's seeds yet"
            )
        )
        mat, mat_control = ("hmt", "mat", variant), ("hmt", "mat", "control")
        if mat in worst and mat_control in worst:
            print(
                f"  * the same change for MAT: worst HMT seed {worst[mat]:.1f} vs MAT's control {worst[mat_control]:.1f} "
                f"({worst[mat] - worst[mat_control]:+.1f} points): COMAT's gain minus MAT's "
                f"{(w - worst[control]) - (worst[mat] - worst[mat_control]):+.1f} points (COMAT alone if >= +2)"
            )
        if pcp_ok and w >= best + 1:
            chosen, best = variant, w
    print(
        f"\n**Selected for the confirmation: {chosen}** (the highest worst HMT seed, at least 1 point above "
        "the control's, PCP mean no more than 2 points below the control's; otherwise the control)."
    )


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else HERE / "runs")
