"""comat's MAPPO against BenchMARL's on the same fixed team, budget and seeds (issue 50).

    .venv/bin/python results/benchmarl/compare.py eval-comat --run runs/benchmarl/comat_pcp_s0
    .venv/bin/python results/benchmarl/compare.py          # -> comparison.md and curves.png here

``eval-comat`` plays a comat run's policy with :func:`episodes.play` (the episodes BenchMARL's
policy plays in ``outside.py``) and writes ``RUN/eval.json``. Without a command, the kept runs
(``runs/IMPL_TASK_sSEED``) are compared per task, seeds as the replicated unit:

* **final progress**: each seed's mean over its 20 deterministic evaluation episodes;
* **the learning curve**: each seed's training-episode return per batch of 32 × horizon env
  steps (comat: ``progress.csv``, BenchMARL: ``curve.csv``), summarized as the mean over the whole
  run (area under the curve) and over its last 10 %.

Each is a Welch test over seeds of comat − BenchMARL with its 95 % interval. "Agree within seed
noise" means every interval contains 0; with 3 seeds an interval is wide, which the table shows.
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path

import numpy as np
from episodes import play, write_eval

import comat
from comat.measure.stats import welch

HERE = Path(__file__).resolve().parent
IMPLS = ("comat", "benchmarl")
EPISODES = 20


def eval_comat(run: Path, episodes: int = EPISODES) -> dict:
    """comat's trained MAPPO (``run``), deterministic, on the run's fixed team: ``run/eval.json``."""
    policy = comat.load_policy(str(run))
    config = policy.config
    if isinstance(config.coalitions, str) or len(config.coalitions) != 1:
        raise ValueError(f"{run}: not a fixed-team run (coalitions={config.coalitions!r:.60})")
    team = config.coalitions[0]
    return write_eval(run, play(policy, config.task, team, config.tier, episodes))


def curve(run: Path, impl: str) -> tuple[np.ndarray, np.ndarray]:
    """(env steps (U,), mean training-episode return (U,)) per batch of one run."""
    name, column = ("progress.csv", "episode_return") if impl == "comat" else ("curve.csv", "return")
    with open(run / name, newline="") as f:
        rows = [r for r in csv.DictReader(f) if r[column] != ""]
    return np.array([float(r["env_steps"]) for r in rows]), np.array([float(r[column]) for r in rows])


def runs_of(task: str, root: Path = HERE / "runs") -> dict[str, dict[int, Path]]:
    found: dict[str, dict[int, Path]] = {impl: {} for impl in IMPLS}
    for path in sorted(root.glob(f"*_{task}_s*")):
        impl, _, seed = path.name.rpartition(f"_{task}_s")
        if impl in found and (path / "eval.json").is_file():
            found[impl][int(seed)] = path
    return found


def seed_values(runs: dict[int, Path], impl: str) -> dict[str, list[float]]:
    """Per seed: final progress, finished share and return (evaluation), curve AUC and last 10 %."""
    out: dict[str, list[float]] = {"progress": [], "finished": [], "eval_return": [], "auc": [], "last": []}
    for seed in sorted(runs):
        mean = json.loads((runs[seed] / "eval.json").read_text())["mean"]
        steps, ret = curve(runs[seed], impl)
        tail = ret[steps >= 0.9 * steps[-1]]
        for key, value in (("progress", mean["progress"]), ("finished", mean["finished"]),
                           ("eval_return", mean["return"]), ("auc", ret.mean()), ("last", tail.mean())):  # fmt: skip
            out[key].append(float(value))
    return out


LABELS = {
    "progress": "final progress (eval, %)",
    "finished": "finished episodes (eval, %)",
    "eval_return": "return (eval)",
    "auc": "training return, mean over the run",
    "last": "training return, last 10 % of the run",
}
PERCENT = {"progress", "finished"}


def compare(task: str) -> tuple[list[str], bool] | None:
    found = runs_of(task)
    if not all(found[impl] for impl in IMPLS):
        return None
    seeds = sorted(set(found["comat"]) & set(found["benchmarl"]))
    values = {impl: seed_values({s: found[impl][s] for s in seeds}, impl) for impl in IMPLS}
    lines = [
        f"### {task.upper()}: seeds {seeds}, {json.loads((found['benchmarl'][seeds[0]] / 'run.json').read_text())['frames']:,} env steps",
        "",
        "| endpoint | comat MAPPO | BenchMARL MAPPO | comat − BenchMARL [95 % CI] | p (Welch) |",
        "|---|---|---|---|---|",
    ]
    agree = True
    for key, label in LABELS.items():
        scale = 100.0 if key in PERCENT else 1.0
        a, b = (np.array(values[impl][key]) * scale for impl in IMPLS)
        w = welch(a, b)
        agree &= not (w["lo"] > 0 or w["hi"] < 0)  # nan (no spread) counts as no evidence of a difference
        cells = [
            f"{x.mean():.1f} ± {x.std(ddof=1) if x.size > 1 else 0:.1f} ({', '.join(f'{v:.1f}' for v in x)})"
            for x in (a, b)
        ]
        lines.append(
            f"| {label} | {cells[0]} | {cells[1]} | {w['diff']:+.1f} [{w['lo']:+.1f}, {w['hi']:+.1f}] | {w['p']:.2f} |"
        )
    lines += ["", "Mean ± seed SD (each seed in brackets)."]
    return lines, agree


def plot(tasks: list[str], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(tasks), figsize=(5.5 * len(tasks), 3.6), squeeze=False)
    for ax, task in zip(axes[0], tasks):
        found = runs_of(task)
        for impl, color in zip(IMPLS, ("C0", "C3")):
            for k, seed in enumerate(sorted(found[impl])):
                steps, ret = curve(found[impl][seed], impl)
                ax.plot(steps / 1e3, ret, color=color, alpha=0.7, lw=1, label=f"{impl} MAPPO" if k == 0 else None)
        ax.set(title=f"{task.upper()}, one fixed team", xlabel="env steps (k)", ylabel="training-episode return")
        ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def report() -> None:
    tasks = [t for t in ("pcp", "hmt") if runs_of(t)["comat"] or runs_of(t)["benchmarl"]]
    text = [
        "# comat's MAPPO against BenchMARL's (generated by compare.py; do not edit)",
        "",
        "Command: `grep -v '^#' results/benchmarl/jobs.txt | xargs -P 2 -L 1 results/benchmarl/run.sh`, then",
        "`.venv/bin/python results/benchmarl/compare.py`. Method and what differs: README.md.",
        "",
    ]
    for task in tasks:
        result = compare(task)
        if result is None:
            text += [f"### {task.upper()}: waiting for both learners' runs", ""]
            continue
        lines, agree = result
        verdict = (
            "every interval contains 0: the two implementations agree within seed noise at this number of seeds"
            if agree
            else "at least one interval excludes 0: the implementations differ (README.md says why)"
        )
        text += [*lines, "", f"**Verdict ({task.upper()})**: {verdict}.", ""]
    (HERE / "comparison.md").write_text("\n".join(text))
    if tasks:
        plot(tasks, HERE / "curves.png")
    print("\n".join(text))


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command")
    e = sub.add_parser("eval-comat", help="play a comat fixed-team run's policy on the comparison's episodes")
    e.add_argument("--run", required=True)
    e.add_argument("--episodes", type=int, default=EPISODES)
    args = parser.parse_args(argv)
    if args.command == "eval-comat":
        mean = eval_comat(Path(args.run), args.episodes)
        print(f"eval ({args.episodes} episodes): " + ", ".join(f"{k} {v:.3f}" for k, v in mean.items()))
    else:
        report()


if __name__ == "__main__":
    sys.exit(main())
