#!/usr/bin/env bash
# Issue 65's outside-env check: comat's MAPPO and BenchMARL's MAPPO on PettingZoo's simple_spread_v3
# (mpe2), the same budget and seeds, one job per call (a line of jobs.txt is IMPL SEED STEPS):
#   COMAT_CODE=../wt-outside grep -v '^#' results/benchmarl/outside_env/jobs.txt | xargs -L 1 results/benchmarl/outside_env/run.sh
#   .venv/bin/python results/benchmarl/outside_env/compare.py
# IMPL is `comat` (comat train --task outside:mpe2.simple_spread_v3 in .venv: the sweep preset, one
# torch thread, the PPO settings of results/benchmarl/README.md's table, which are PPOConfig's defaults)
# or `benchmarl` (benchmarl_mpe.py in .venv-benchmarl; `make test-benchmarl` builds it, and
# `pip install 'comat[outside]'` there adds mpe2). COMAT_CODE: a checkout (a git worktree at a fixed
# commit) whose comat the runs import, so that edits in progress in the tree never reach a run. Each run is
# evaluated right after training (mpe.play: 100 deterministic episodes, the same seeds for both) and
# its small files are copied to results/benchmarl/outside_env/runs/IMPL_sSEED; a kept run is skipped.
set -euo pipefail
impl=$1 seed=$2 steps=$3
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../../.." && pwd)"
name="${impl}_s${seed}"
run="$root/runs/benchmarl/outside_env/$name"
keep="$here/runs/$name"
log="$root/runs/benchmarl/outside_env/$name.log"
export OMP_NUM_THREADS=1
cd "$root"
if [[ -f "$keep/eval.json" ]]; then echo "done: $name"; exit 0; fi
mkdir -p runs/benchmarl/outside_env "$keep.partial"
echo "start: $name $(date -u +%FT%TZ)"
if [[ $impl == comat ]]; then
  if [[ ! -f $run/policy.pt ]]; then
    args=(); [[ -f $run/checkpoint.pt ]] && args=(--resume)
    PYTHONPATH="${COMAT_CODE:-}" .venv/bin/comat train --algo mappo --task outside:mpe2.simple_spread_v3 --preset sweep \
      --seed "$seed" --steps "$steps" --out "$run" --quiet "${args[@]}" eval_every_steps=1000000000 \
      eval_episodes_per_team=32 >> "$log" 2>&1
  fi
  PYTHONPATH="${COMAT_CODE:-}" .venv/bin/python "$here/compare.py" eval-comat --run "$run" >> "$log" 2>&1
  cp "$run"/{policy.pt,config.yaml,progress.csv,summary.json,eval.json} "$keep.partial"/
else
  if [[ ! -f $run/eval.json ]]; then
    rm -rf "$run"  # BenchMARL's own restore is not used: an interrupted run starts again
    .venv-benchmarl/bin/python "$here/benchmarl_mpe.py" train --seed "$seed" --frames "$steps" --out "$run" >> "$log" 2>&1
  fi
  cp -r "$run"/. "$keep.partial"/
fi
rm -rf "$keep" && mv "$keep.partial" "$keep"
echo "end: $name $(date -u +%FT%TZ)"
