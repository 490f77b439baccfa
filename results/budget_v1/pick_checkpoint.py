"""Stage 1's checkpoint rule (PLAN.md, "Checkpoint"), for one run folder; run.sh calls it:

    python results/budget_v1/pick_checkpoint.py RUN_FOLDER

Reads ``RUN_FOLDER/select/<steps>/evaluation_unicycle.json`` for each candidate of CANDIDATES (the
kept ``policy_<steps>.pt`` played on U_val, 10 episodes per coalition, reality off), takes each
candidate's U_val progress (the mean over the set's coalitions of each coalition's episode mean)
and writes ``RUN_FOLDER/selected.json``: every candidate's value and the one chosen, the highest,
a tie going to the later candidate (the closer to the budget). Prints the chosen env steps.
A missing or partial candidate is an error: the rule needs all four.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from comat.measure.metrics import read_results
from comat.measure.stats import per_seed_means

CANDIDATES = (3_250_000, 3_500_000, 3_750_000, 4_000_000)
"""Env steps of the kept policies the rule chooses among (the run's keep_policies_at)."""
SET = "val"
EPISODES = 10
"""Episodes per coalition each candidate is played for."""


def u_val_progress(path: Path) -> float:
    """A candidate's U_val progress in points (ValueError if the file is not the planned evaluation)."""
    data = read_results(path)
    rows = [r for r in data["rows"] if r["set"] == SET]
    if len(rows) != 1 or data["episodes_per_coalition"] != EPISODES or data["reality"] != "off":
        raise ValueError(
            f"{path}: expected one {SET} row at {EPISODES} episodes per coalition, reality off; got "
            f"{len(rows)} row(s), {data['episodes_per_coalition']} episodes, reality {data['reality']!r}"
        )
    eps = rows[0]["per_episode"]
    return 100 * float(
        per_seed_means([0] * len(eps), [e["coalition"] for e in eps], [e["progress"] for e in eps])[1][0]
    )


def pick(run: Path) -> dict:
    """The rule's record for ``run``: {"candidates": {steps: points}, "selected": steps}."""
    values = {t: u_val_progress(run / "select" / str(t) / "evaluation_unicycle.json") for t in CANDIDATES}
    best = max(values.values())
    selected = max(t for t, v in values.items() if v == best)  # a tie: the later candidate
    return {
        "rule": f"highest U_val progress ({EPISODES} episodes per coalition, reality off), a tie to the later",
        "candidates": {str(t): round(v, 6) for t, v in values.items()},
        "selected": selected,
        "selected_policy": f"policy_{selected}.pt",
    }


def main(argv: list[str]) -> int:
    if len(argv) != 1:
        raise SystemExit("usage: pick_checkpoint.py RUN_FOLDER")
    run = Path(argv[0])
    record = pick(run)
    (run / "selected.json").write_text(json.dumps(record, indent=2) + "\n")
    print(record["selected"])
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
