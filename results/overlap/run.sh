#!/usr/bin/env bash
# Issue 48's overlap study (PLAN.md): one COMAT run of an arm (configs/ARM.yaml), then its
# deterministic evaluation on U_val (5 episodes per coalition); the small files and the policy
# are copied to results/overlap/runs/ right away. Idempotent: a kept run is skipped, an
# interrupted one resumed exactly. Run one at a time (each uses both cores):
#   results/overlap/run.sh ARM SEED [TASK]      ARM: sequential or overlap; TASK: pcp (default)
set -euo pipefail
arm=$1 seed=$2 task=${3:-pcp}
root="$(cd "$(dirname "$0")/../.." && pwd)"
name="${arm}_${task}_s${seed}"
run="$root/runs/overlap/$name"
keep="$root/results/overlap/runs/$name"
cd "$root"
if [[ -f "$keep/summary.json" ]]; then echo "done: $name"; exit 0; fi
mkdir -p runs/overlap
echo "start: $name $(date -u +%FT%TZ)"
if [[ ! -f "$run/policy.pt" ]]; then
  resume=(); [[ -f "$run/checkpoint.pt" ]] && resume=(--resume)
  .venv/bin/comat train --algo comat --task "$task" --preset "results/overlap/configs/$arm.yaml" \
    --seed "$seed" --out "$run" --quiet "${resume[@]}" > "runs/overlap/$name.log" 2>&1
fi
.venv/bin/comat eval --policy "$run" --teams val --episodes 5 --no-references --out "$run" --force \
  >> "runs/overlap/$name.log" 2>&1
mkdir -p "$keep"
cp "$run"/{policy.pt,config.yaml,progress.csv,eval.csv,summary.json,evaluation_unicycle.json,evaluation_unicycle.episodes.json.gz,evaluation_unicycle.csv} "$keep"/
echo "end: $name $(date -u +%FT%TZ)"
