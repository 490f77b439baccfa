#!/usr/bin/env bash
# The learner-competence runs (issue 65; queue.sh calls it): one job of jobs.txt per call, two lanes:
#   grep -v '^#' results/learnability/jobs.txt | xargs -P 2 -L 1 results/learnability/run.sh
# A job line is ALGO TASK SEED STEPS. It trains with the sweep preset (the grid's; resuming an
# interrupted run exactly), evaluates the policy on all six sets (5 episodes per coalition, reality
# off, unicycle), then copies the run's small files and policy.pt to results/learnability/runs/NAME, where a
# session commits them. A kept run is skipped. One thread per lane.
set -euo pipefail
algo=$1 task=$2 seed=$3 steps=$4
root="$(cd "$(dirname "$0")/../.." && pwd)"
name="${algo}_${task}_s${seed}"
run="$root/runs/learnability/$name"
keep="$root/results/learnability/runs/$name"
log="$root/runs/learnability/$name.log"
# COMAT_CODE: a checkout (e.g. a git worktree at a fixed commit) whose comat package the runs import
# instead of this tree's, so edits in progress here never reach a run (each run records its commit).
comat() { OMP_NUM_THREADS=1 PYTHONPATH="${COMAT_CODE:-}" "$root/.venv/bin/comat" "$@"; }
cd "$root"
if [[ -f "$keep/summary.json" ]]; then echo "done: $name"; exit 0; fi
mkdir -p runs/learnability
echo "start: $name $(date -u +%FT%TZ)"
if [[ ! -f $run/policy.pt ]]; then
  args=(); [[ -f $run/checkpoint.pt ]] && args=(--resume)
  comat train --algo "$algo" --task "$task" --preset sweep --seed "$seed" --steps "$steps" --out "$run" \
    --quiet "${args[@]}" >> "$log" 2>&1
fi
[[ -f $run/evaluation_unicycle.json ]] || comat eval --policy "$run" --teams all --episodes 5 --no-references \
  --out "$run" >> "$log" 2>&1
mkdir -p "$keep.partial"
cp "$run"/{policy.pt,config.yaml,progress.csv,eval.csv,summary.json} "$run"/evaluation_unicycle.{json,json.gz,csv} \
  "$keep.partial"/ 2>/dev/null || cp "$run"/{policy.pt,config.yaml,progress.csv,summary.json} \
  "$run"/evaluation_unicycle.* "$keep.partial"/
rm -rf "$keep" && mv "$keep.partial" "$keep"
echo "end: $name $(date -u +%FT%TZ)"
