"""Issue 33: PLAN.md's tests, computed from the kept runs (committed with the plan, before any result):

    python results/grid_v3/analyze.py > results/grid_v3/tests.md
    python results/grid_v3/analyze.py RUNS_DIR     # any folder of run folders named as run.sh names them

Run folders are ``<algo>_<task>_<trained reality>_s<seed>[_1000k]`` with ``evaluation_unicycle.json``
(reality off) and ``evaluation_unicycle_nominal.json``. A seed's value on a set is the mean over its
coalitions of each coalition's episode mean; everything over seeds is a Student-t or Welch
statement over those per-seed values. Cells a plan names that have no runs yet are listed, not
skipped silently.
"""

from __future__ import annotations

import math
import re
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[1]))
from comat.measure.metrics import read_results
from comat.measure.stats import per_seed_means, t_interval, welch

NAME = re.compile(
    r"^(?P<algo>comat|mat|mappo|qmix)_(?P<task>hmt|pcp)_(?P<trained>off|nominal)_s(?P<seed>\d+)"
    r"(?:_(?P<k>\d+)k)?$"
)
SETS = {
    "train": "U_train",
    "val": "U_val",
    "test": "U_test",
    "scale": "U_scale",
    "size": "U_size",
    "capability": "U_cap",
}
SESOI = 10.0
"""Smallest effect of interest, progress points."""
ALPHA = 0.05
LEVELS = {"off": "evaluation_unicycle.json", "nominal": "evaluation_unicycle_nominal.json"}


def seed_value(row: dict, key: str) -> float:
    """A run's value on one set: the mean over coalitions of each coalition's episode mean
    (progress, finished and progress_auc in %, time_to_90 in env steps)."""
    eps = row["per_episode"]
    value = float(per_seed_means([0] * len(eps), [e["coalition"] for e in eps], [float(e[key]) for e in eps])[1][0])
    return value if key == "time_to_90" else 100 * value


def paired_change(a: dict, b: dict) -> tuple[np.ndarray, dict] | None:
    """b − a over the seeds both have (S,), with its 95 % t-interval; None with fewer than 2."""
    seeds = sorted(set(a) & set(b))
    if len(seeds) < 2:
        return None
    d = np.array([b[k] - a[k] for k in seeds])
    return d, t_interval(d)


def load(folder: Path) -> dict:
    """{(algo, task, trained, steps_k, level, set, key): {seed: value}} over the kept runs."""
    table: dict[tuple, dict[int, float]] = defaultdict(dict)
    for run in sorted(p for p in folder.iterdir() if p.is_dir()):
        m = NAME.match(run.name)
        if not m or not (run / "summary.json").is_file():
            continue
        for level, file in LEVELS.items():
            if not (run / file).is_file():
                continue
            data = read_results(run / file)
            for row in data["rows"]:
                if row["policy"] != m["algo"]:
                    continue
                for key in ("progress", "finished", "progress_auc", "time_to_90"):
                    cell = (m["algo"], m["task"], m["trained"], int(m["k"] or 300), level, row["set"], key)
                    table[cell][int(m["seed"])] = seed_value(row, key)
    return table


def hedges_g(a: np.ndarray, b: np.ndarray) -> float:
    """Standardized difference with the small-sample correction (pooled SD)."""
    na, nb = a.size, b.size
    pooled = math.sqrt(((na - 1) * a.var(ddof=1) + (nb - 1) * b.var(ddof=1)) / (na + nb - 2))
    return math.nan if pooled == 0 else (a.mean() - b.mean()) / pooled * (1 - 3 / (4 * (na + nb) - 9))


def compare(a: dict, b: dict) -> dict | None:
    """Welch's test of a − b over seeds, with the 90 % interval (two one-sided tests) and Hedges' g."""
    x, y = np.array(list(a.values())), np.array(list(b.values()))
    if x.size < 2 or y.size < 2:
        return None
    w95, w90 = welch(x, y), welch(x, y, confidence=0.90)
    return {**w95, "lo90": w90["lo"], "hi90": w90["hi"], "g": hedges_g(x, y), "a": x, "b": y}


def verdict(c: dict, p_adjusted: float) -> str:
    if math.isnan(c["p"]):
        return "not decidable (no spread)"
    if p_adjusted < ALPHA:
        return "COMAT better" if c["diff"] > 0 else "COMAT worse"
    if -SESOI < c["lo90"] and c["hi90"] < SESOI:
        return f"no difference of {SESOI:g} points or more"
    return "inconclusive"


def holm(ps: list[float]) -> list[float]:
    """Holm-adjusted p-values, in the given order."""
    order = sorted(range(len(ps)), key=lambda i: ps[i])
    out, running = [math.nan] * len(ps), 0.0
    for rank, i in enumerate(order):
        running = max(running, min(1.0, (len(ps) - rank) * ps[i]))
        out[i] = running
    return out


def _fmt(c: dict, unit: str = "") -> str:
    return (
        f"{c['a'].mean():.1f} ({c['a'].size}) | {c['b'].mean():.1f} ({c['b'].size}) | {c['diff']:+.1f}{unit} "
        f"[{c['lo']:+.1f}, {c['hi']:+.1f}] | [{c['lo90']:+.1f}, {c['hi90']:+.1f}] | {c['t']:+.2f} | {c['df']:.1f} | "
        f"{c['p']:.3f} | {c['g']:+.2f}"
    )


HEAD = "| A (seeds) | B (seeds) | A − B [95 %] | [90 %] | t | df | p | Hedges' g |"
"""A: COMAT, or what the row names first; B: the other."""


def primary(table: dict) -> list[str]:
    lines = [
        "## Primary: HMT progress on U_size and U_scale, COMAT − MAT (trained and evaluated at `off`)",
        "",
        "| set " + HEAD + " Holm p | verdict |",
        "|" + "---|" * 11,
    ]
    found = [
        (
            s,
            compare(
                table.get(("comat", "hmt", "off", 300, "off", s, "progress"), {}),
                table.get(("mat", "hmt", "off", 300, "off", s, "progress"), {}),
            ),
        )
        for s in ("size", "scale")
    ]
    tested = [(s, c) for s, c in found if c is not None]
    adjusted = holm([c["p"] if not math.isnan(c["p"]) else 1.0 for _, c in tested])
    for (s, c), p in zip(tested, adjusted):
        lines.append(f"| {SETS[s]} | {_fmt(c)} | {p:.3f} | **{verdict(c, p)}** |")
    lines += [f"| {SETS[s]} | not yet: fewer than 2 seeds of either learner |" for s, c in found if c is None]
    note = (
        f"Verdicts: Holm-adjusted p < {ALPHA:g} decides better/worse; otherwise 'no difference of {SESOI:g} "
        f"points or more' where the 90 % interval lies inside ±{SESOI:g} (two one-sided tests), else inconclusive."
    )
    return [*lines, "", note, ""]


def secondary(table: dict) -> list[str]:
    lines = [
        "## Secondary (no multiplicity correction)",
        "",
        "| task | set | endpoint | other " + HEAD + " verdict |",
        "|" + "---|" * 13,
    ]
    rows = [(t, s, "progress", o) for t in ("hmt", "pcp") for s in ("capability",) for o in ("mat",)]
    rows += [(t, s, "progress", "mappo") for t in ("hmt", "pcp") for s in ("size", "scale", "capability")]
    rows += [
        (t, s, k, "mat")
        for t in ("hmt", "pcp")
        for s in ("size", "scale", "capability")
        for k in ("progress_auc", "time_to_90")
    ]
    for task, s, key, other in rows:
        c = compare(
            table.get(("comat", task, "off", 300, "off", s, key), {}),
            table.get((other, task, "off", 300, "off", s, key), {}),
        )
        if c is not None:
            unit = " steps" if key == "time_to_90" else ""
            v = verdict(c, c["p"]) if key == "progress" else ("p < 0.05" if c["p"] < ALPHA else "not separated")
            lines.append(f"| {task.upper()} | {SETS[s]} | {key} | {other.upper()} | {_fmt(c, unit)} | {v} |")
    return lines + [""]


def reality(table: dict) -> list[str]:
    lines = [
        "## The reality gap (progress, `nominal` − `off`, the same policies)",
        "",
        "| task | set | learner (trained) | seeds | gap, mean [95 % t] |",
        "|---|---|---|---|---|",
    ]
    gaps: dict[tuple, dict[int, float]] = {}
    for task in ("hmt", "pcp"):
        for s, name in SETS.items():
            for algo in ("comat", "mat", "mappo", "qmix"):
                for trained in ("off", "nominal"):
                    off = table.get((algo, task, trained, 300, "off", s, "progress"), {})
                    nom = table.get((algo, task, trained, 300, "nominal", s, "progress"), {})
                    change = paired_change(off, nom)
                    if change is None:
                        continue
                    d, t = change
                    gaps[(task, s, algo, trained)] = dict(zip(sorted(set(off) & set(nom)), d))
                    lines.append(
                        f"| {task.upper()} | {name} | {algo.upper()} ({trained}) | {d.size} | "
                        f"{t['mean']:+.1f} [{t['lo']:+.1f}, {t['hi']:+.1f}] |"
                    )
    note = (
        "COMAT's gap − MAT's (trained at `off`), and what training at `nominal` recovers (at `nominal`, "
        "trained at `nominal` − trained at `off`):"
    )
    lines += ["", note, "", "| task | set | comparison " + HEAD, "|" + "---|" * 11]
    for task in ("hmt", "pcp"):
        for s, name in SETS.items():
            c = compare(gaps.get((task, s, "comat", "off"), {}), gaps.get((task, s, "mat", "off"), {}))
            if c is not None:
                lines.append(f"| {task.upper()} | {name} | gap: COMAT − MAT | {_fmt(c)} |")
            for algo in ("comat", "mat"):
                c = compare(
                    table.get((algo, task, "nominal", 300, "nominal", s, "progress"), {}),
                    table.get((algo, task, "off", 300, "nominal", s, "progress"), {}),
                )
                if c is not None:
                    lines.append(f"| {task.upper()} | {name} | {algo.upper()}: trained nominal − off | {_fmt(c)} |")
    return lines + [""]


def budget(table: dict) -> list[str]:
    lines = [
        "## The budget: 1 M − 300 k env steps within seed (HMT progress, `off`)",
        "",
        "| learner | set | seeds | 300 k | 1 M | change, mean [95 % t] |",
        "|---|---|---|---|---|---|",
    ]
    for algo in ("comat", "mat"):
        for s in ("size", "scale", "train"):
            a = table.get((algo, "hmt", "off", 300, "off", s, "progress"), {})
            b = table.get((algo, "hmt", "off", 1000, "off", s, "progress"), {})
            change = paired_change(a, b)
            if change is None:
                continue
            (d, t), seeds = change, sorted(set(a) & set(b))
            lines.append(
                f"| {algo.upper()} | {SETS[s]} | {d.size} | {np.mean([a[k] for k in seeds]):.1f} | "
                f"{np.mean([b[k] for k in seeds]):.1f} | {t['mean']:+.1f} [{t['lo']:+.1f}, {t['hi']:+.1f}] |"
            )
    return lines + [""]


def missing(folder: Path) -> list[str]:
    """The planned jobs (jobs.txt) with no kept run yet."""
    kept = {p.name for p in folder.iterdir() if (p / "summary.json").is_file()}
    planned = []
    for line in (HERE / "jobs.txt").read_text().splitlines():
        if line.strip() and not line.startswith("#"):
            algo, task, seed, trained, steps = line.split()
            name = f"{algo}_{task}_{trained}_s{seed}" + ("" if steps == "300000" else f"_{int(steps) // 1000}k")
            planned.append(name)
    left = [n for n in planned if n not in kept]
    return [
        f"## Runs: {len(planned) - len(left)} of {len(planned)} planned jobs kept",
        "",
        ("Not yet kept: " + ", ".join(left) + ".") if left else "Every planned job is kept.",
        "",
    ]


def main(folder: Path = HERE / "runs") -> None:
    table = load(folder)
    print("# Issue 33: the plan's tests (`analyze.py`, PLAN.md)\n")
    print(
        "Per-seed values: mean over coalitions of each coalition's 5 episodes; progress in %, time to 90 % "
        "in env steps.\n"
    )
    for part in (
        missing(folder) if folder == HERE / "runs" else [],
        primary(table),
        secondary(table),
        reality(table),
        budget(table),
    ):
        print("\n".join(part))


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else HERE / "runs")
