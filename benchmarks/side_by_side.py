"""Two ``comat train`` runs side by side against one alone (issue 32, shared machines).

    .venv/bin/python benchmarks/side_by_side.py [--steps 15360] [--env KEY=VALUE ...] [--out FILE.json]

Runs ``comat train --algo comat --task pcp --preset quick --steps S`` once alone, then twice at the
same time (each its own run folder), and reads each run's env-steps/s from its ``progress.csv``
(updates after the first, whose compile and warm-up would blur the rate). Prints a table and writes
JSON: the alone rate, each side-by-side rate and their ratio to the alone one (the target: each
>= 0.40). ``--env`` sets environment variables of every run (e.g. ``OMP_WAIT_POLICY=ACTIVE`` to
see what spin-waiting threads cost); ``--stagger S`` starts the second run S seconds after the
first, which it then finds registered. Measure with nothing else running.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def _rate(folder: Path) -> float:
    with open(folder / "progress.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))[1:]  # the first update carries the warm-up
    if len(rows) < 2:
        return float("nan")
    # wall_s is the run's own training time so far (its updates), cumulative
    wall = float(rows[-1]["wall_s"]) - float(rows[0]["wall_s"])
    return (float(rows[-1]["env_steps"]) - float(rows[0]["env_steps"])) / wall if wall > 0 else float("nan")


def _start(out: Path, steps: int, env: dict[str, str]) -> subprocess.Popen:
    argv = [
        sys.executable,
        "-m",
        "comat.cli",
        "train",
        "--algo",
        "comat",
        "--task",
        "pcp",
        "--preset",
        "quick",
        "--steps",
        str(steps),
        "--quiet",
        "--out",
        str(out),
        "eval_episodes_per_team=0",
    ]
    return subprocess.Popen(
        argv, env={**os.environ, **env}, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps", type=int, default=15360, help="env steps per run (default: %(default)s)")
    parser.add_argument("--env", nargs="*", default=[], metavar="KEY=VALUE", help="environment of every run")
    parser.add_argument(
        "--stagger",
        type=float,
        default=0.0,
        help="seconds between the two side-by-side starts (the second finds the first registered; default: 0)",
    )
    parser.add_argument(
        "--out", default="benchmarks/results/side_by_side.json", help="JSON output (default: %(default)s)"
    )
    args = parser.parse_args()
    env = dict(e.split("=", 1) for e in args.env)
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        t0 = time.perf_counter()
        alone = _start(root / "alone", args.steps, env)
        first = alone.communicate()[0]
        if alone.returncode:
            raise SystemExit(f"the lone run failed:\n{first[-2000:]}")
        pair = [_start(root / "pair0", args.steps, env)]
        time.sleep(args.stagger)
        pair.append(_start(root / "pair1", args.steps, env))
        outputs = [p.communicate()[0] for p in pair]
        if any(p.returncode for p in pair):
            raise SystemExit("a side-by-side run failed:\n" + "\n".join(o[-2000:] for o in outputs))
        rates = {"alone": _rate(root / "alone"), "pair": [_rate(root / f"pair{k}") for k in range(2)]}
        notes = [line for o in outputs for line in o.splitlines() if "warning" in line.lower()]
    result = {
        "steps": args.steps,
        "env": env,
        "stagger_s": args.stagger,
        "cpus": len(os.sched_getaffinity(0)),
        "alone_env_steps_per_s": rates["alone"],
        "side_by_side_env_steps_per_s": rates["pair"],
        "ratios": [r / rates["alone"] for r in rates["pair"]],
        "target_ratio": 0.40,
        "warnings": notes,
        "wall_s": time.perf_counter() - t0,
    }
    result["pass"] = all(r >= 0.40 for r in result["ratios"])
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(result, indent=2) + "\n")
    print(f"{'run':<14}{'env-steps/s':>12}{'of alone':>10}")
    print(f"{'alone':<14}{rates['alone']:>12.0f}{1.0:>10.2f}")
    for k, (r, q) in enumerate(zip(rates["pair"], result["ratios"])):
        print(f"{'side by side ' + str(k):<14}{r:>12.0f}{q:>10.2f}")
    print(f"target: each side-by-side run >= 0.40 of alone: {'pass' if result['pass'] else 'FAIL'}; wrote {args.out}")
    return 0 if result["pass"] else 1


if __name__ == "__main__":
    sys.exit(main())
