#!/usr/bin/env bash
# The learner-competence queue (issue 65), one lane: every job line of jobs.txt (ALGO TASK SEED STEPS),
# in order, through run.sh; each run kept under results/learnability/runs/NAME is committed (only its own
# folder) as soon as it finishes, so a session that ends loses at most the run in progress (its
# checkpoint stays under runs/learnability/ on this machine and is resumed by the next call).
#   git worktree add --detach ../wt-learn COMMIT   # the code the runs use, fixed
#   COMAT_CODE=../wt-learn nohup results/learnability/queue.sh > runs/learnability/queue.log 2>&1 &
set -uo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
cd "$root"
mkdir -p runs/learnability
grep -v '^#' results/learnability/jobs.txt | grep -v '^ *$' | while read -r algo task seed steps; do
  name="${algo}_${task}_s${seed}"
  keep="results/learnability/runs/$name"
  if [[ ! -f $keep/summary.json ]]; then
    results/learnability/run.sh "$algo" "$task" "$seed" "$steps" || { echo "failed: $name"; continue; }
  fi
  [[ -z $(git status --porcelain -- "$keep") ]] && continue  # kept and committed (or kept by a run before this queue)
  for try in 1 2 3 4 5; do  # other sessions' helpers commit too: wait out a held index lock
    git add "$keep" && git commit -q -m "results/learnability: $name ($steps env steps) trained and evaluated on all six sets" -- "$keep" && break
    sleep 10
  done
done
