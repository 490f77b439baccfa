"""Issue 65's matched arm: the equivalence test of PLAN.md, and the pilot's curves.

    .venv/bin/python results/benchmarl/matched/analyze.py          # -> comparison.md (the verdict)
    .venv/bin/python results/benchmarl/matched/analyze.py pilot    # -> pilot/curves.md, pilot/curves.png

The primary endpoint (PLAN.md) is each run's final deterministic progress on its fixed team, in percent:
the mean over the 20 episodes ``episodes.py`` plays (the same seeds for both arms), one value per seed.
Per team, comat's matched MAPPO minus BenchMARL's MAPPO is tested for equivalence within the margin
±5 progress points by TOST (two one-sided Welch t-tests, α = 0.05): equivalent when the 90 % interval
of the difference lies inside (−5, +5). Both teams must pass. Secondary endpoints are described with
Welch's 95 % intervals and carry no verdict.
"""

from __future__ import annotations

import csv
import json
import math
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from scipy import stats

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
from compare import curve  # results/benchmarl/compare.py: each arm's training-return curve

from comat.measure.stats import welch

ARMS = ("comat", "benchmarl")
ARM_LABELS = {"comat": "comat MAPPO, matched", "benchmarl": "BenchMARL MAPPO"}
TEAMS = (5, 8)
MARGIN = 5.0
"""The equivalence margin in progress points, set in PLAN.md before any run."""
ALPHA = 0.05
MIN_SEEDS = 8


def tost(a: Sequence[float], b: Sequence[float], margin: float, alpha: float = ALPHA) -> dict[str, float | bool]:
    """Two one-sided Welch t-tests of mean(a) − mean(b) against the margin (−margin, +margin).

    Returns ``diff``, its ``se`` and Welch–Satterthwaite ``df``, the (1 − 2α) interval ``lo``, ``hi``,
    the one-sided p-values ``p_low`` (H0: diff ≤ −margin) and ``p_high`` (H0: diff ≥ +margin), ``p``
    (their maximum) and ``equivalent`` (p < α, the same as the interval lying inside the margin).
    Without spread in either sample (se 0) the difference itself decides, with p 0 or 1."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if a.ndim != 1 or b.ndim != 1 or a.size < 2 or b.size < 2:
        raise ValueError(f"a and b must be 1-D with at least 2 values each, got shapes {a.shape} and {b.shape}")
    if not (margin > 0 and 0 < alpha < 0.5):
        raise ValueError(f"margin must be > 0 and alpha in (0, 0.5), got margin={margin!r}, alpha={alpha!r}")
    diff = float(a.mean() - b.mean())
    va, vb = a.var(ddof=1) / a.size, b.var(ddof=1) / b.size
    se = math.sqrt(va + vb)
    if se == 0.0:
        inside = -margin < diff < margin
        p = 0.0 if inside else 1.0
        return {"diff": diff, "se": 0.0, "df": math.inf, "lo": diff, "hi": diff, "p_low": p, "p_high": p,
                "p": p, "equivalent": inside}  # fmt: skip
    df = (va + vb) ** 2 / (va**2 / (a.size - 1) + vb**2 / (b.size - 1))
    p_low = float(stats.t.sf((diff + margin) / se, df))
    p_high = float(stats.t.cdf((diff - margin) / se, df))
    half = float(stats.t.ppf(1 - alpha, df)) * se
    p = max(p_low, p_high)
    return {"diff": diff, "se": se, "df": float(df), "lo": diff - half, "hi": diff + half, "p_low": p_low,
            "p_high": p_high, "p": p, "equivalent": p < alpha}  # fmt: skip


def verdict(test: dict, margin: float = MARGIN) -> str:
    """What PLAN.md says a result means: equivalent, a difference beyond the margin, or neither."""
    if test["equivalent"]:
        return f"equivalent within ±{margin:g} points"
    if test["lo"] >= margin or test["hi"] <= -margin:
        return f"different by more than {margin:g} points: a defect to find (PLAN.md, 'If equivalence fails')"
    return "not shown equivalent (the interval crosses the margin): PLAN.md, 'If equivalence fails'"


def runs(root: Path = HERE / "runs") -> dict[tuple[str, int], dict[int, Path]]:
    """(arm, team) -> seed -> a finished run's folder (one with eval.json)."""
    found: dict[tuple[str, int], dict[int, Path]] = {(arm, team): {} for arm in ARMS for team in TEAMS}
    for path in sorted(root.glob("*_hmt*_s*")):
        arm, _, rest = path.name.partition("_hmt")
        team, _, seed = rest.partition("_s")
        if (arm, int(team)) in found and (path / "eval.json").is_file():
            found[(arm, int(team))][int(seed)] = path
    return found


def final_entropy(run: Path, arm: str) -> dict[str, float]:
    """Each robot type's policy entropy over the last 10 % of updates, from the run's own log (comat:
    progress.csv's entropy_<type>; BenchMARL: train_<group>_entropy.csv)."""
    out: dict[str, float] = {}
    if arm == "comat":
        with open(run / "progress.csv", newline="") as f:
            rows = list(csv.DictReader(f))
        for key in (k for k in rows[0] if k.startswith("entropy_")):
            values = np.array([float(r[key]) for r in rows])
            out[key[len("entropy_") :]] = float(values[-max(1, len(values) // 10) :].mean())
        return out
    for f in sorted(run.glob("*/*/scalars/train_*_entropy.csv")):
        group = f.name[len("train_") : -len("_entropy.csv")]
        if "loss" in group:
            continue
        with open(f, newline="") as fh:
            values = np.array([float(row[1]) for row in csv.reader(fh)])
        out[group] = float(values[-max(1, len(values) // 10) :].mean())
    return out


def seed_values(found: dict[int, Path], arm: str) -> dict[str, list[float]]:
    """Per seed: the primary endpoint and the secondary ones."""
    out: dict[str, list[float]] = {"progress": [], "finished": [], "eval_return": [], "last_return": []}
    for seed in sorted(found):
        mean = json.loads((found[seed] / "eval.json").read_text())["mean"]
        steps, ret = curve(found[seed], arm)
        out["progress"].append(100.0 * mean["progress"])
        out["finished"].append(100.0 * mean["finished"])
        out["eval_return"].append(mean["return"])
        out["last_return"].append(float(ret[steps >= 0.9 * steps[-1]].mean()))
        for group, h in final_entropy(found[seed], arm).items():
            out.setdefault(f"entropy_{group}", []).append(h)
    return out


SECONDARY = {
    "finished": "finished episodes (eval, %)",
    "eval_return": "return (eval)",
    "last_return": "training return, last 10 % of the run",
    "entropy_fast": "entropy of the fast robots' policy, last 10 % of updates",
    "entropy_slow": "entropy of the slow robots' policy, last 10 % of updates",
}


def _cell(x: np.ndarray) -> str:
    return f"{x.mean():.1f} ± {x.std(ddof=1):.1f} ({', '.join(f'{v:.1f}' for v in x)})"


def team_section(team: int, found: dict[tuple[str, int], dict[int, Path]]) -> tuple[list[str], bool | None]:
    """The table and verdict of one team; None as the verdict while seeds are missing."""
    seeds = sorted(set(found[("comat", team)]) & set(found[("benchmarl", team)]))
    if len(seeds) < MIN_SEEDS:
        have = {arm: sorted(found[(arm, team)]) for arm in ARMS}
        return [f"### {team} robots: waiting for {MIN_SEEDS} seeds in both arms (finished: {have})", ""], None
    values = {arm: seed_values({s: found[(arm, team)][s] for s in seeds}, arm) for arm in ARMS}
    a, b = (np.array(values[arm]["progress"]) for arm in ARMS)
    test = tost(a, b, MARGIN)
    lines = [
        f"### {team} robots (team{team}.yaml): seeds {seeds}",
        "",
        "| endpoint | " + " | ".join(ARM_LABELS[arm] for arm in ARMS) + " | comat − BenchMARL | test |",
        "|---|---|---|---|---|",
        (
            f"| **final progress (eval, %)**, primary | {_cell(a)} | {_cell(b)} | {test['diff']:+.1f}, 90 % CI "
            f"[{test['lo']:+.1f}, {test['hi']:+.1f}] | TOST ±{MARGIN:g}: p = {test['p']:.3f} "
            f"(p_low {test['p_low']:.3f}, p_high {test['p_high']:.3f}, Welch df {test['df']:.1f}) |"
        ),
    ]
    for key, label in SECONDARY.items():
        if key not in values["comat"] or key not in values["benchmarl"]:
            continue
        x, y = (np.array(values[arm][key]) for arm in ARMS)
        w = welch(x, y)
        lines.append(
            f"| {label} | {_cell(x)} | {_cell(y)} | {w['diff']:+.2f}, 95 % CI [{w['lo']:+.2f}, {w['hi']:+.2f}] "
            f"| Welch p = {w['p']:.2f} |"
        )
    lines += ["", f"**Verdict ({team} robots)**: {verdict(test)}.", ""]
    return lines, bool(test["equivalent"])


def report() -> None:
    found = runs()
    text = [
        "# The matched arm: comat's MAPPO with BenchMARL's choices against BenchMARL's MAPPO (generated by analyze.py)",
        "",
        "Plan, margin and test: PLAN.md (committed before the runs). Runs: `jobs.txt` through `run.sh`.",
        "Mean ± seed SD (each seed in brackets). Primary endpoint: TOST, α = 0.05, margin ±5 progress points;",
        "the others are described with Welch's 95 % intervals, no verdict.",
        "",
    ]
    verdicts = []
    for team in TEAMS:
        lines, ok = team_section(team, found)
        text += lines
        verdicts.append(ok)
    if all(v is not None for v in verdicts):
        overall = "equivalent on both teams" if all(verdicts) else "not equivalent on every team (see each team)"
        text += [f"**Verdict (the matched arm)**: {overall}.", ""]
    (HERE / "comparison.md").write_text("\n".join(text))
    print("\n".join(text))


def pilot(root: Path = HERE / "pilot") -> None:
    """The pilot's curves: training return per 20 k env steps, and deterministic progress at each evaluation."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    lines = [
        "# The pilot's curves (generated by `analyze.py pilot`): 5-robot team, seed 0, one run per arm",
        "",
        "Training-episode return, mean per 20 k env steps (bin's upper edge):",
        "",
    ]
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 3.6))
    evals = {}
    for arm, color in zip(ARMS, ("C0", "C3")):
        for run in sorted(root.glob(f"{arm}_hmt*_s*")):
            steps, ret = curve(run, arm)
            edges = np.arange(20_000, steps[-1] + 20_000, 20_000)
            means = [ret[(steps > e - 20_000) & (steps <= e)].mean() for e in edges]
            lines += [f"- {run.name}: " + ", ".join(f"{e // 1000:.0f} k {m:.2f}" for e, m in zip(edges, means))]
            left.plot(steps / 1e3, ret, color=color, lw=1, label=ARM_LABELS[arm])
            evals[run.name] = _eval_curve(run, arm)
            e_steps, e_progress = evals[run.name]
            right.plot(e_steps / 1e3, e_progress, "o-", color=color, label=ARM_LABELS[arm])
    lines += ["", "Deterministic progress (%, 20 episodes) at each evaluation:", ""]
    for name, (e_steps, e_progress) in evals.items():
        lines.append(f"- {name}: " + ", ".join(f"{s / 1e3:.0f} k {p:.1f}" for s, p in zip(e_steps, e_progress)))
    left.set(xlabel="env steps (k)", ylabel="training-episode return", title="HMT, 5 robots, seed 0")
    right.set(xlabel="env steps (k)", ylabel="deterministic progress (%)", title="evaluations during training")
    left.legend(), right.legend()
    fig.tight_layout()
    fig.savefig(root / "curves.png", dpi=100)
    (root / "curves.md").write_text("\n".join([*lines, ""]))
    print("\n".join(lines))


def _eval_curve(run: Path, arm: str) -> tuple[np.ndarray, np.ndarray]:
    """(env steps, progress %) of a pilot run's evaluations during training (comat: eval.csv of the
    training run; BenchMARL: eval_curve.csv from its kept checkpoints)."""
    name, column = ("eval.csv", "progress") if arm == "comat" else ("eval_curve.csv", "progress")
    with open(run / name, newline="") as f:
        rows = [r for r in csv.DictReader(f) if r.get(column, "") != ""]
    return np.array([float(r["env_steps"]) for r in rows]), 100.0 * np.array([float(r[column]) for r in rows])


if __name__ == "__main__":
    pilot() if sys.argv[1:] == ["pilot"] else report()
