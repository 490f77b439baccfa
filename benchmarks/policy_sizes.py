"""What one policy file weighs per algorithm and task with the grid's model config (the ``sweep``
preset: the models' defaults, the baselines with 20 robot slots).

    python benchmarks/policy_sizes.py [--preset sweep] [--out benchmarks/results/policy_sizes.json]

Writes the rows as JSON and prints the markdown table docs/policies.md shows (tests/test_policy_file.py
checks that table against a fresh measurement).
"""

from __future__ import annotations

import argparse
import json

from comat.files import write_atomic
from comat.learners import learner_entry
from comat.rl import format_size, policy_weights


def table(rows: list[dict]) -> str:
    """The docs' table (docs/policies.md): one row per algorithm; per task the file's size and the parameters it
    keeps (in brackets: all of the learner's, critic or mixer included)."""
    tasks = list(dict.fromkeys(r["task"] for r in rows))
    by = {(r["algo"], r["task"]): r for r in rows}
    lines = [
        "| algorithm | kept to act | "
        + " | ".join(f"{t.upper()} policy.pt | {t.upper()} parameters (learner)" for t in tasks)
        + " |",
        "|---|---|" + "---:|---:|" * len(tasks),
    ]
    for algo in dict.fromkeys(r["algo"] for r in rows):
        cells = [
            f"{format_size(by[algo, t]['bytes'])} | {by[algo, t]['parameters']:,} "
            f"({by[algo, t]['learner_parameters']:,})"
            for t in tasks
        ]
        entry = learner_entry(algo)
        lines.append(f"| {entry.label} | {entry.keeps} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--preset", default="sweep", help="preset whose model config is measured (default: %(default)s)"
    )
    parser.add_argument(
        "--out", default="benchmarks/results/policy_sizes.json", help="JSON output (default: %(default)s)"
    )
    args = parser.parse_args()
    rows = policy_weights(args.preset)
    write_atomic(args.out, json.dumps({"preset": args.preset, "rows": rows}, indent=2))
    print(table(rows))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
