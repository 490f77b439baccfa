#!/usr/bin/env bash
# Issue 30 screen: one COMAT run of a variant preset (configs/VARIANT.yaml), then its deterministic
# evaluation on U_val (5 episodes per coalition), the set the screen selects on; the small files
# and the policy are copied to results/stability/screen/runs/ right away. Idempotent: a kept run
# is skipped, an interrupted one resumed exactly.
#   results/stability/screen/run.sh VARIANT TASK SEED STEPS [ALGO]   (ALGO: comat, the default, or mat)
# Runs the code of COMAT_CODE (default: this checkout) with python -P (the current folder does not
# shadow it) and one thread, so two runs side by side (xargs -P 2) each keep a core.
set -euo pipefail
variant=$1 task=$2 seed=$3 steps=$4 algo=${5:-comat}
root="$(cd "$(dirname "$0")/../../.." && pwd)"
code=${COMAT_CODE:-$root}
name="${variant}_${task}_s${seed}_${steps}"
[[ $algo == comat ]] || name="${algo}_$name"
study=${STUDY:-screen}  # screen, or confirm (results/stability/confirm/PLAN.md)
run="$root/runs/$study/$name"
keep="$root/results/stability/$study/runs/$name"
comat() { PYTHONPATH=$code OMP_NUM_THREADS=1 "$root/.venv/bin/python" -P -c \
  "import sys; from comat.cli import main; sys.argv=['comat']+sys.argv[1:]; sys.exit(main())" "$@"; }
cd "$root"
if [[ -f "$keep/summary.json" ]]; then echo "done: $name"; exit 0; fi
mkdir -p "runs/$study"
echo "start: $name $(date -u +%FT%TZ)"
if [[ ! -f "$run/policy.pt" ]]; then
  resume=(); [[ -f "$run/checkpoint.pt" ]] && resume=(--resume)
  comat train --algo "$algo" --task "$task" --preset "results/stability/screen/configs/$variant.yaml" \
    --seed "$seed" --steps "$steps" --out "$run" --quiet "${resume[@]}" > "runs/$study/$name.log" 2>&1
fi
comat eval --policy "$run" --teams val --episodes 5 --no-references --out "$run" --force >> "runs/$study/$name.log" 2>&1
mkdir -p "$keep"
cp "$run"/{policy.pt,config.yaml,progress.csv,eval.csv,summary.json,evaluation_unicycle.json,evaluation_unicycle.episodes.json.gz,evaluation_unicycle.csv} "$keep"/
echo "end: $name $(date -u +%FT%TZ)"
