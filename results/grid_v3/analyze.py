"""Issue 33: PLAN.md's tests, computed from the kept runs (committed with the plan, before any result):

    python results/grid_v3/analyze.py > results/grid_v3/tests.md
    python results/grid_v3/analyze.py RUNS_DIR     # any folder of run folders named as run.sh names them

Run folders are ``<algo>_<task>_<trained reality>_s<seed>[_1000k]`` with ``evaluation_unicycle.json``
(reality off) and ``evaluation_unicycle_nominal.json``. A seed's value on a set is the mean over its
coalitions of each coalition's episode mean; everything over seeds is a Student-t or Welch
statement over those per-seed values. Cells a plan names that have no runs yet are listed, not
skipped silently. The last section, the verdict in numbers, is worded by ``grid_v3_sentences.py``
from the numbers computed here (``FACTS``); the by-team-size section (issue 68) is descriptive.
"""

from __future__ import annotations

import math
import re
import sys
from collections import defaultdict
from functools import cache
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parents[1]), str(HERE)]
from grid_v3_sentences import verdict_text

from comat.measure.metrics import read_results
from comat.measure.stats import holm, per_seed_means, t_interval, welch
from comat.team import SET_LABELS

NAME = re.compile(
    r"^(?P<algo>comat|mat|mappo|qmix)_(?P<task>hmt|pcp)_(?P<trained>off|nominal)_s(?P<seed>\d+)"
    r"(?:_(?P<k>\d+)k)?$"
)
SETS = SET_LABELS
"""Set key -> report name, in the order every table lists them."""
SESOI = 10.0
"""Smallest effect of interest, progress points."""
LEVEL = SESOI / 5
"""A per-team-size difference within ±LEVEL points is called level (descriptive, not a test)."""
ALPHA = 0.05
LEVELS = {"off": "evaluation_unicycle.json", "nominal": "evaluation_unicycle_nominal.json"}
FACTS: dict = {"adjusted_gap": {}}
"""The numbers the generated verdict (``grid_v3_sentences.verdict_text``) quotes, filled as the
sections are made; a secondary test is there with both readings (:func:`readings`)."""


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
            data = _evaluation(run / file)
            for row in data["rows"]:
                if row["policy"] != m["algo"]:
                    continue
                for key in ("progress", "finished", "progress_auc", "time_to_90"):
                    cell = (m["algo"], m["task"], m["trained"], int(m["k"] or 300), level, row["set"], key)
                    table[cell][int(m["seed"])] = seed_value(row, key)
    return table


@cache
def _evaluation(path: Path) -> dict:
    """An evaluation file with its per-episode detail, read once per run (load and by_size share it)."""
    return read_results(path)


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


def readings(c: dict, p_holm: float, key: str = "progress") -> dict:
    """A secondary test read both ways: by the plan's rule on its unadjusted p (``plan``) and on its
    Holm-adjusted p (``after_holm``). Progress has the plan's three verdicts; the timing endpoints
    (AUC, steps to 90 %) have no smallest effect, only separated or not."""
    if key == "progress":
        return {"c": c, "holm": p_holm, "plan": verdict(c, c["p"]), "after_holm": verdict(c, p_holm)}
    plan, after = (("p < 0.05" if p < ALPHA else "not separated") for p in (c["p"], p_holm))
    return {"c": c, "holm": p_holm, "plan": plan, "after_holm": after}


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
        FACTS.setdefault("primary", {})[s] = (c, p)
    lines += [f"| {SETS[s]} | not yet: fewer than 2 seeds of either learner |" for s, c in found if c is None]
    note = (
        f"Verdicts: Holm-adjusted p < {ALPHA:g} decides better/worse; otherwise 'no difference of {SESOI:g} "
        f"points or more' where the 90 % interval lies inside ±{SESOI:g} (two one-sided tests), else inconclusive."
    )
    return [*lines, "", note, ""]


def secondary(table: dict) -> list[str]:
    lines = [
        "## Secondary (the plan's verdicts are unadjusted; the Holm column adjusts over these 20 tests)",
        "",
        "| task | set | endpoint | other " + HEAD + " Holm p (20) | verdict (unadjusted, as planned) |",
        "|" + "---|" * 14,
    ]
    rows = [(t, s, "progress", o) for t in ("hmt", "pcp") for s in ("capability",) for o in ("mat",)]
    rows += [(t, s, "progress", "mappo") for t in ("hmt", "pcp") for s in ("size", "scale", "capability")]
    rows += [
        (t, s, k, "mat")
        for t in ("hmt", "pcp")
        for s in ("size", "scale", "capability")
        for k in ("progress_auc", "time_to_90")
    ]
    found = []
    for task, s, key, other in rows:
        c = compare(
            table.get(("comat", task, "off", 300, "off", s, key), {}),
            table.get((other, task, "off", 300, "off", s, key), {}),
        )
        if c is not None:
            found.append((task, s, key, other, c))
    adjusted = holm([c["p"] if not math.isnan(c["p"]) else 1.0 for *_, c in found])
    for (task, s, key, other, c), p in zip(found, adjusted):
        unit = " steps" if key == "time_to_90" else ""
        r = FACTS.setdefault("secondary", {})[(task, s, key, other)] = readings(c, p, key)
        lines.append(
            f"| {task.upper()} | {SETS[s]} | {key} | {other.upper()} | {_fmt(c, unit)} | {p:.3f} | {r['plan']} |"
        )
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
    lines += ["", note, "", "| task | set | comparison " + HEAD + " Holm p (12 gap tests) |", "|" + "---|" * 12]
    gap_tests = {
        (task, s): compare(gaps.get((task, s, "comat", "off"), {}), gaps.get((task, s, "mat", "off"), {}))
        for task in ("hmt", "pcp")
        for s in SETS
    }
    gap_tests = {k: c for k, c in gap_tests.items() if c is not None}
    gap_holm = dict(zip(gap_tests, holm([c["p"] if not math.isnan(c["p"]) else 1.0 for c in gap_tests.values()])))
    FACTS["gap_tests"] = {k: readings(c, gap_holm[k]) for k, c in gap_tests.items()}
    for task in ("hmt", "pcp"):
        for s, name in SETS.items():
            c = gap_tests.get((task, s))
            if c is not None:
                lines.append(f"| {task.upper()} | {name} | gap: COMAT − MAT | {_fmt(c)} | {gap_holm[(task, s)]:.3f} |")
            for algo in ("comat", "mat"):
                c = compare(
                    table.get((algo, task, "nominal", 300, "nominal", s, "progress"), {}),
                    table.get((algo, task, "off", 300, "nominal", s, "progress"), {}),
                )
                if c is not None:
                    FACTS.setdefault("recover", {})[(task, s, algo)] = c
                    lines.append(f"| {task.upper()} | {name} | {algo.upper()}: trained nominal − off | {_fmt(c)} | |")
    return lines + [""] + adjusted_gap(table)


def ancova(gap: np.ndarray, off: np.ndarray, comat: np.ndarray) -> dict:
    """Least squares gap = b0 + b1 · off + b2 · [COMAT] over seeds: COMAT's gap at equal `off`
    competence (b2, its 95 % t-interval and p with n − 3 degrees of freedom), and r(off, gap)."""
    from scipy import stats

    X = np.column_stack([np.ones_like(off), off, comat])
    beta, *_ = np.linalg.lstsq(X, gap, rcond=None)
    df = gap.size - 3
    s2 = float(((gap - X @ beta) ** 2).sum() / df)
    se = math.sqrt(s2 * np.linalg.inv(X.T @ X)[2, 2])
    t = float(beta[2] / se)
    half = float(stats.t.ppf(0.975, df) * se)
    return {
        "b": float(beta[2]),
        "lo": float(beta[2]) - half,
        "hi": float(beta[2]) + half,
        "p": float(2 * stats.t.sf(abs(t), df)),
        "slope": float(beta[1]),
        "r": float(np.corrcoef(off, gap)[0, 1]),
        "n": int(gap.size),
    }


def adjusted_gap(table: dict) -> list[str]:
    """COMAT's gap − MAT's at equal competence: weaker policies lose more at `nominal`, and COMAT's
    seeds are the weaker ones on the sets where the gap appears (exploratory; not in the plan)."""
    lines = [
        "### The gap at equal competence (exploratory, not in the plan)",
        "",
        (
            "Per seed of COMAT and MAT (trained at `off`, 300 k): gap = `nominal` − `off` progress against the "
            "`off` progress, gap = b0 + b1 · off + b2 · [COMAT] by least squares; b2 is COMAT's gap at equal `off` "
            "competence, r the correlation of `off` progress and gap over both learners' seeds."
        ),
        "",
        "| task | set | seeds | r(off, gap) | b1 (gap per point of off) | COMAT's gap − MAT's, raw | at equal competence [95 %] | p |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for task in ("hmt", "pcp"):
        for s, name in SETS.items():
            rows = []
            for algo in ("comat", "mat"):
                off = table.get((algo, task, "off", 300, "off", s, "progress"), {})
                nom = table.get((algo, task, "off", 300, "nominal", s, "progress"), {})
                rows += [(nom[k] - off[k], off[k], algo == "comat") for k in sorted(set(off) & set(nom))]
            if len(rows) < 5 or len({r[2] for r in rows}) < 2:
                continue
            gap, off, comat = (np.array(col, dtype=float) for col in zip(*rows))
            if np.ptp(off) == 0:
                continue
            a = ancova(gap, off, comat)
            raw = gap[comat == 1].mean() - gap[comat == 0].mean()
            FACTS["adjusted_gap"][(task, s)] = {**a, "raw": raw}
            lines.append(
                f"| {task.upper()} | {name} | {a['n']} | {a['r']:+.2f} | {a['slope']:+.2f} | {raw:+.1f} | "
                f"{a['b']:+.1f} [{a['lo']:+.1f}, {a['hi']:+.1f}] | {a['p']:.3f} |"
            )
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


def exploratory(table: dict) -> list[str]:
    """Comparisons the plan did not name, every set, unadjusted: COMAT − MAT at 1 M (3 seeds, one
    final checkpoint each), each learner's 1 M − 300 k change on every set, and at `nominal` (300 k,
    trained at `off`) COMAT − MAT and COMAT − MAPPO(-20)."""
    lines = [
        "## Exploratory (not in the plan; unadjusted; read as leads, not results)",
        "",
        "### COMAT − MAT at 1 M env steps (HMT, 3 seeds each, one final checkpoint per seed)",
        "",
        (
            "MAT's periodic evaluations swing by several points between checkpoints late in training "
            "(`eval.csv`): one final checkpoint per seed is a noisy read of a learner at 1 M."
        ),
        "",
        "| level | set | endpoint " + HEAD,
        "|" + "---|" * 11,
    ]
    for level in ("off", "nominal"):
        for s, name in SETS.items():
            for key in ("progress", "finished"):
                c = compare(
                    table.get(("comat", "hmt", "off", 1000, level, s, key), {}),
                    table.get(("mat", "hmt", "off", 1000, level, s, key), {}),
                )
                if c is not None:
                    FACTS.setdefault("at_1m", {})[(level, s, key)] = c
                    lines.append(f"| `{level}` | {name} | {key} | {_fmt(c)} |")
    lines += [
        "",
        "### 1 M − 300 k within seed, every set (HMT, `off`)",
        "",
        "| learner | set | endpoint | seeds | 300 k | 1 M | change, mean [95 % t] | per seed |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for algo in ("comat", "mat"):
        for s, name in SETS.items():
            for key in ("progress", "finished"):
                a = table.get((algo, "hmt", "off", 300, "off", s, key), {})
                b = table.get((algo, "hmt", "off", 1000, "off", s, key), {})
                change = paired_change(a, b)
                if change is None:
                    continue
                (d, t), seeds = change, sorted(set(a) & set(b))
                before, after = np.mean([a[k] for k in seeds]), np.mean([b[k] for k in seeds])
                FACTS.setdefault("budget_all", {})[(algo, s, key)] = (before, after, d)
                lines.append(
                    f"| {algo.upper()} | {name} | {key} | {d.size} | {before:.1f} | {after:.1f} | "
                    f"{t['mean']:+.1f} [{t['lo']:+.1f}, {t['hi']:+.1f}] | {', '.join(f'{x:+.0f}' for x in d)} |"
                )
    lines += [
        "",
        "### COMAT − MAT and COMAT − MAPPO at both levels, progress and finished (300 k, trained at `off`)",
        "",
        (
            "The plan compares progress at `off`; these rows add `nominal` and the finished share, which the "
            "plan left unpowered."
        ),
        "",
        "| level | task | set | endpoint | other " + HEAD,
        "|" + "---|" * 13,
    ]
    for level in ("off", "nominal"):
        for task in ("hmt", "pcp"):
            for s, name in SETS.items():
                for key, other in (
                    ("progress", "mat"),
                    ("finished", "mat"),
                    ("progress", "mappo"),
                    ("finished", "mappo"),
                ):
                    if level == "off" and key == "progress":
                        continue  # the plan's own rows, above
                    c = compare(
                        table.get(("comat", task, "off", 300, level, s, key), {}),
                        table.get((other, task, "off", 300, level, s, key), {}),
                    )
                    if c is not None:
                        FACTS.setdefault("at_level", {})[(level, task, s, key, other)] = c
                        lines.append(f"| `{level}` | {task.upper()} | {name} | {key} | {other.upper()} | {_fmt(c)} |")
    return lines + [""]


PRIMARY_SETS = ("size", "scale")
FIGURE_SETS = ("train", "test", "scale", "size")
"""The sets ``fig6_team_size.png`` pools (comat.eval.figures.SIZE_SETS)."""


def size_cells(folder: Path, algo: str, sets: tuple[str, ...]) -> tuple[dict, dict]:
    """HMT progress by team size, trained and evaluated at `off`, 300 k: ({size: {seed: %}},
    {size: coalitions}): a seed's value at a size is the mean over its coalitions of that size in
    ``sets`` of each coalition's episode mean (the figure's per-seed point)."""
    values: dict[int, dict[int, float]] = defaultdict(dict)
    counts: dict[int, int] = {}
    for run in sorted(p for p in folder.iterdir() if p.is_dir()):
        m = NAME.match(run.name)
        file = run / LEVELS["off"]
        if not m or (m["algo"], m["task"], m["trained"], m["k"]) != (algo, "hmt", "off", None) or not file.is_file():
            continue
        if not (run / "summary.json").is_file():
            continue
        cells: dict[int, dict[tuple, list[float]]] = defaultdict(lambda: defaultdict(list))
        for row in _evaluation(file)["rows"]:
            if row["policy"] == algo and row["set"] in sets:
                for e in row["per_episode"]:
                    cells[int(e["team_size"])][(row["set"], e["coalition"])].append(float(e["progress"]))
        for n, coalitions in cells.items():
            values[n][int(m["seed"])] = 100 * float(np.mean([np.mean(v) for v in coalitions.values()]))
            counts[n] = len(coalitions)
    return values, counts


def by_team_size(folder: Path) -> list[str]:
    """COMAT − MAT per team size on the primary sets (descriptive: one unadjusted Welch test per
    size, read as a profile, not as findings), beside the figure's pooling."""
    prim, counts = size_cells(folder, "comat", PRIMARY_SETS)
    mat, _ = size_cells(folder, "mat", PRIMARY_SETS)
    fig = {a: size_cells(folder, a, FIGURE_SETS)[0] for a in ("comat", "mat")}
    lines = [
        "## By team size (descriptive; HMT progress, COMAT − MAT, 300 k, trained and evaluated at `off`)",
        "",
        (
            "Per seed: the mean over its coalitions of that size (each its 5 episodes' mean) on U_size and U_scale "
            "pooled, the primary sets; Welch over seeds, unadjusted, one test per size. The last column pools "
            "U_train and U_test too, as `fig6_team_size.png` does."
        ),
        "",
        "| robots | coalitions | " + HEAD.removeprefix("| ") + " fig. 6's sets: A − B [95 %] |",
        "|" + "---|" * 12,
    ]
    for n in sorted(set(prim) & set(mat)):
        c, f = compare(prim[n], mat[n]), compare(fig["comat"].get(n, {}), fig["mat"].get(n, {}))
        if c is None:
            continue
        FACTS.setdefault("by_size", {})[n] = (c, f)
        pooled = "—" if f is None else f"{f['diff']:+.1f} [{f['lo']:+.1f}, {f['hi']:+.1f}]"
        lines.append(f"| {n} | {counts[n]} | {_fmt(c)} | {pooled} |")
    return [*lines, ""]


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
        by_team_size(folder),
        exploratory(table),
    ):
        print("\n".join(part))
    print("\n".join(verdict_text(FACTS, SESOI, LEVEL)))


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else HERE / "runs")
