#!/usr/bin/env bash
# Issue 28: the reference policies (scripted heuristic, best constant action, random; issue 49: the
# capability-blind heuristic where a task has one) on every composition set of every task, 5 episodes per coalition, unicycle tier, from the repository root.
#   results/sets/run.sh          evaluate (about 30 min on one core) and write the table
# Outputs: results/sets/references_<task>/evaluation_unicycle.{json,episodes.json.gz,csv} and results/sets/README.md's table
# (written by results/sets/table.py).
set -euo pipefail
HERE=results/sets
for task in pcp hmt forage navigation sensors arctic; do
  comat eval --policy heuristic --task "$task" --teams all --episodes 5 --tier unicycle \
    --out "$HERE/references_$task" --force
done
python "$HERE/table.py"
