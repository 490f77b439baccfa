#!/usr/bin/env bash
# Issue 50's outside reference: comat's MAPPO and BenchMARL's MAPPO on the same fixed PCP team, the
# same budget and the same seeds, one job per call (a job line of jobs.txt is IMPL TASK SEED STEPS):
#   grep -v '^#' results/benchmarl/jobs.txt | xargs -P 2 -L 1 results/benchmarl/run.sh
#   .venv/bin/python results/benchmarl/compare.py
# IMPL is `comat` (comat train in .venv, the paper preset's PPO settings with the sweep preset's
# budget and one thread) or `benchmarl` (outside.py in .venv-benchmarl, `make test-benchmarl`
# builds it). Each run is evaluated right after training (20 deterministic episodes, the same seeds
# for both) and its small files are copied to results/benchmarl/runs/NAME, where a session commits
# them; a kept run is skipped. One thread per lane.
set -euo pipefail
impl=$1 task=$2 seed=$3 steps=$4
root="$(cd "$(dirname "$0")/../.." && pwd)"
name="${impl}_${task}_s${seed}"
run="$root/runs/benchmarl/$name"
keep="$root/results/benchmarl/runs/$name"
team="$root/results/benchmarl/${task}_team.yaml"
log="$root/runs/benchmarl/$name.log"
export OMP_NUM_THREADS=1
cd "$root"
if [[ -f "$keep/eval.json" ]]; then echo "done: $name"; exit 0; fi
mkdir -p runs/benchmarl
echo "start: $name $(date -u +%FT%TZ)"
mkdir -p "$keep.partial"
if [[ $impl == comat ]]; then
  if [[ ! -f $run/policy.pt ]]; then
    args=(); [[ -f $run/checkpoint.pt ]] && args=(--resume)
    # The fixed team (coalitions=FILE); 8 robot slots, so the critic's state is the 8-robot state that
    # TorchRL's wrapper of the PettingZoo env gives BenchMARL's critic.
    .venv/bin/comat train --algo mappo --task "$task" --preset sweep --seed "$seed" --steps "$steps" --out "$run" \
      --quiet "${args[@]}" coalitions="$team" models.mappo.max_robots=8 eval_every_steps=1000000000 \
      >> "$log" 2>&1
  fi
  .venv/bin/python results/benchmarl/compare.py eval-comat --run "$run" >> "$log" 2>&1
  cp "$run"/{policy.pt,config.yaml,progress.csv,summary.json,eval.json} "$keep.partial"/
else
  if [[ ! -f $run/eval.json ]]; then
    rm -rf "$run"  # BenchMARL's own restore is not used: an interrupted run starts again
    .venv-benchmarl/bin/python results/benchmarl/outside.py train --task "$task" --team "$team" --seed "$seed" \
      --frames "$steps" --out "$run" >> "$log" 2>&1
  fi
  # Its CSV logs, final checkpoint (networks and optimizers, no buffer) and config.pkl, for `outside.py eval`.
  cp -r "$run"/. "$keep.partial"/
fi
rm -rf "$keep" && mv "$keep.partial" "$keep"
echo "end: $name $(date -u +%FT%TZ)"
