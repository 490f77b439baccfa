#!/usr/bin/env bash
# One ablation run: train COMAT with a variant preset, then keep its small files under
# results/ablations/runs/. Idempotent: a finished run is skipped, an interrupted one resumed.
#   results/ablations/run.sh VARIANT TASK SEED STEPS
# Run from the repository root with the project's venv (make setup); the screen and the
# confirmation grid call this through xargs -P 2 (two jobs, one CPU each, as the sweep).
set -euo pipefail
variant=$1 task=$2 seed=$3 steps=$4
name="${variant}_${task}_s${seed}_${steps}"
run="runs/ablations/$name"
keep="results/ablations/runs/$name"
comat=${COMAT:-.venv/bin/comat}
if [[ -f "$keep/summary.json" ]]; then echo "done: $name"; exit 0; fi
args=(--algo comat --task "$task" --preset "results/ablations/configs/$variant.yaml" --seed "$seed"
      --steps "$steps" --out "$run" --quiet)
if [[ -f "$run/checkpoint.pt" ]]; then args+=(--resume); elif [[ -e "$run" ]]; then rm -rf "$run"; fi
mkdir -p runs/ablations
echo "start: $name $(date -u +%FT%TZ)"
"$comat" train "${args[@]}" > "runs/ablations/$name.log" 2>&1
# Deterministic evaluation on U_train and U_test (one episode per coalition), as the sweep's runs.
"$comat" eval --checkpoint "$run/checkpoint.pt" --set both --no-references >> "runs/ablations/$name.log" 2>&1
mkdir -p "$keep"
cp "$run"/{config.yaml,progress.csv,eval.csv,summary.json,evaluation_unicycle.json,evaluation_unicycle.episodes.json.gz,evaluation_unicycle.csv} "$keep"/
echo "end: $name $(date -u +%FT%TZ)"
