#!/usr/bin/env bash
# Issue 18: COMAT in the wheels tier for grid runs whose checkpoints are gone (runs/ is not kept).
#   results/grid_scale/retrain_wheels.sh [comat_<task>_s<seed> ...]   (default: every COMAT run here
#   without evaluation_wheels.json), from the repository root, with comat and python on PATH.
# Each run is retrained with its seed and the grid's preset in $WORK (resumes), then compared with
# the committed run: progress.csv, eval.csv (all but the wall-clock columns) and the final U_train
# evaluation. Equal bit for bit: it is the same policy, so its wheels evaluation is copied next to the
# committed unicycle one. Not equal (another CPU rounds the learner's sums differently, README
# "Same seed, same run"): the retrain is its own policy, evaluated in both tiers and kept whole
# under comat_wheels/runs/ — the gap is always measured on one checkpoint.
set -euo pipefail
WORK=${WORK:-runs/retrain}
HERE=results/grid_scale
mkdir -p "$WORK"
names=("$@")
if [ ${#names[@]} -eq 0 ]; then
  for run in "$HERE"/runs/comat_*_s*/; do
    name=$(basename "$run")
    [ -f "$run/evaluation_wheels.json" ] || [ -f "$HERE/comat_wheels/runs/$name/evaluation_wheels.json" ] || names+=("$name")
  done
fi
for name in "${names[@]}"; do
  task=${name#comat_}; task=${task%_s*}; seed=${name##*_s}; out=$WORK/$name
  if [ ! -f "$out/summary.json" ]; then
    if [ -f "$out/checkpoint.pt" ]; then comat train --out "$out" --resume --quiet
    else comat train --algo comat --task "$task" --preset sweep --seed "$seed" --out "$out" --quiet; fi
  fi
  [ -f "$out/evaluation_wheels.json" ] || comat eval --policy "$out" --teams all --tier wheels --no-references
  if python - "$out" "$HERE/runs/$name" <<'EOF'
import csv, json, sys
new, old = sys.argv[1:]
def rows(folder, name):
    with open(f"{folder}/{name}") as f:
        return [{k: v for k, v in r.items() if "wall" not in k and "per_s" not in k} for r in csv.DictReader(f)]
def final(folder):
    with open(f"{folder}/summary.json") as f:
        return json.load(f)["eval_train"]
same = all(rows(new, n) == rows(old, n) for n in ("progress.csv", "eval.csv")) and final(new) == final(old)
print(f"{new} vs {old}: {'equal bit for bit' if same else 'NOT equal'}")
sys.exit(0 if same else 1)
EOF
  then
    cp "$out"/evaluation_wheels.{json,episodes.json.gz,csv} "$HERE/runs/$name/"
  else
    [ -f "$out/evaluation_unicycle.json" ] || comat eval --policy "$out" --teams all --tier unicycle --no-references
    mkdir -p "$HERE/comat_wheels/runs/$name"
    cp "$out"/{config.yaml,progress.csv,eval.csv,summary.json} "$out"/evaluation_*.{json,json.gz,csv} "$HERE/comat_wheels/runs/$name/"
  fi
done
# the wheels report and the gap over one checkpoint per run: the retrain where it is kept, else the grid's run
folders=()
for run in "$HERE"/runs/comat_*_s*; do
  kept="$HERE/comat_wheels/runs/$(basename "$run")"
  if [ -d "$kept" ]; then folders+=("$kept"); else folders+=("$run"); fi
done
comat report "${folders[@]}" --tier wheels --out "$HERE/comat_wheels" --force
python "$HERE/wheels_gap.py"
