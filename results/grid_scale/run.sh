#!/usr/bin/env bash
# Issue 18 part 4: the grid on U_train, U_test and U_scale, from the repository root.
#   results/grid_scale/run.sh            train + evaluate every run (resumes), COMAT in wheels, report, gap
#   results/grid_scale/run.sh collect    only copy the finished runs' small files here
# SWEEP = the sweep's root (checkpoints stay there; only small files are committed, among them each
# run's policy.pt: the weights to act, so every reported run can be evaluated again).
set -euo pipefail
SWEEP=${SWEEP:-runs/grid18all}
HERE=results/grid_scale

collect() {  # the small files of every finished run and its policy.pt (checkpoints are not committed)
  for run in "$SWEEP"/*_s*/; do
    [ -f "$run/summary.json" ] && [ -f "$run/evaluation_unicycle.json" ] || continue
    [ -f "$run/policy.pt" ] || comat policy "$run"  # a run trained before policy files: from its checkpoint
    dst="$HERE/runs/$(basename "$run")"
    mkdir -p "$dst"
    cp "$run"/{config.yaml,progress.csv,eval.csv,summary.json,policy.pt} "$run"/evaluation_*.{json,json.gz,csv} "$dst/"
  done
}

if [ "${1:-}" = collect ]; then collect; exit 0; fi
comat sweep --algos comat mat mappo qmix --tasks pcp hmt --seeds 0 1 2 --preset sweep --jobs 2 \
  --eval-sets train test scale --out "$SWEEP"
for run in "$SWEEP"/comat_*_s*/; do  # the transfer gap: COMAT trained in unicycle, evaluated with wheels
  [ -f "$run/evaluation_wheels.json" ] || comat eval --policy "$run" --teams all --tier wheels --no-references
done
collect
comat report "$HERE"/runs/*_s* --out "$HERE" --force
# COMAT's wheels report and gap (comat_wheels/); runs whose checkpoints were gone are retrained first
"$(dirname "$0")/retrain_wheels.sh"
