#!/usr/bin/env bash
# Issue 64: the reference ladder (scripted, type_only, blind, constant, random) on every composition set of
# every task, 5 episodes per coalition, unicycle tier, on the held-out evaluation seed 4,000,037, and the
# families each task is in. From the repository root:
#   results/sets/run.sh          about 5 minutes a task on one core (two tasks at once: run it twice with
#                                disjoint --tasks; the summary merges)
# Outputs: results/sets/validity/<task>/evaluation_unicycle.{json,episodes.json.gz,csv},
# results/sets/validity.{md,json}, and the families recorded for `comat tasks` (comat/data/validity.json).
set -euo pipefail
comat validity --out results/sets --episodes 5 --record --force "$@"
