#!/usr/bin/env bash
# Issue 50's first look at IPPO and CASH (descriptive): the grid's protocol (results/grid_v3/run.sh:
# the sweep preset, 300 k env steps, fresh seeds 100+, one thread per lane; every set evaluated, 5
# episodes per coalition) at reality off and nominal, kept in results/new_learners/runs/NAME:
#   grep -v '^#' results/new_learners/jobs.txt | xargs -P 2 -L 1 results/new_learners/run.sh
#   .venv/bin/python results/new_learners/table.py
exec env GRID=new_learners LEVELS="off nominal" "$(dirname "$0")/../grid_v3/run.sh" "$@"
