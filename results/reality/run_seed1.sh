#!/bin/bash
# Issue 29 part 5, the second seed: COMAT seed 1 trained at off and at nominal on one task, each
# evaluated right after training (off: all sets; nominal-trained: U_train/U_test) and at nominal
# and stress (U_train/U_test), 5 episodes per coalition; small files copied to results/policies/.
# Usage: results/reality/run_seed1.sh pcp|hmt [off|nominal]
# Runs from a snapshot of the code (COMAT_CODE, default: this checkout; python -P, so the current folder
# does not shadow it) with one thread per run,
# so two runs side by side each keep a core.
set -e
task=$1; level=${2:-off}
root="$(cd "$(dirname "$0")/../.." && pwd)"
code=${COMAT_CODE:-$root}
if [ "$level" = off ]; then name=comat_${task}_s1; teams=all; extra=""
else name=comat_${task}_${level}_s1; teams=both; extra="reality=$level"; fi
comat() { PYTHONPATH=$code OMP_NUM_THREADS=1 "$root/.venv/bin/python" -P -c \
  "import sys; from comat.cli import main; sys.argv=['comat']+sys.argv[1:]; sys.exit(main())" "$@"; }
run=$root/runs/gap2/$name
cd "$root"
if [ ! -f "$run/policy.pt" ]; then
  resume=""; [ -f "$run/config.yaml" ] && resume="--resume"
  comat train --algo comat --task "$task" --preset sweep --seed 1 --env-workers 1 --out "$run" $resume $extra
fi
comat eval --policy "$run" --teams $teams --episodes 5 --no-references --out "$run" --force
for lv in nominal stress; do
  comat eval --policy "$run" --teams both --episodes 5 --no-references --reality $lv --out "$run" --force
done
keep=$root/results/policies/$name; mkdir -p "$keep"
cp "$run"/{policy.pt,config.yaml,progress.csv,eval.csv,summary.json} "$run"/evaluation_unicycle*.{json,json.gz,csv} "$keep"/
echo "kept $keep"
