#!/usr/bin/env bash
# Issue 33's grid (PLAN.md): one job of jobs.txt per call, as xargs gives them; two lanes side by side:
#   grep -v '^#' results/grid_v3/jobs.txt | xargs -P 2 -L 1 results/grid_v3/run.sh
# A job line is ALGO TASK SEED REALITY STEPS. It trains (resuming an interrupted run exactly),
# evaluates the policy on every set at reality off and nominal (and stress for seeds 100-102 at
# 300 k), then copies the run's small files and policy.pt to results/grid_v3/runs/NAME, where a
# session commits them. A kept run is skipped. A 1 M job (the budget check) starts from a copy of
# the same seed's 300 k run folder and resumes it to 1 M env steps, leaving the 300 k run as it is.
# Runs the code of COMAT_CODE (default: this checkout) with python -P and one thread per lane.
# Another experiment on the same protocol sets GRID (its folder under results/ and runs/, default
# grid_v3) and LEVELS (the reality levels it evaluates, default as above): results/new_learners/run.sh.
set -euo pipefail
algo=$1 task=$2 seed=$3 reality=$4 steps=$5
root="$(cd "$(dirname "$0")/../.." && pwd)"
code=${COMAT_CODE:-$root}
grid=${GRID:-grid_v3}
name="${algo}_${task}_${reality}_s${seed}"
[[ $steps == 300000 ]] || name="${name}_$((steps / 1000))k"
run="$root/runs/$grid/$name"
keep="$root/results/$grid/runs/$name"
log="$root/runs/$grid/$name.log"
comat() { PYTHONPATH=$code OMP_NUM_THREADS=1 "$root/.venv/bin/python" -P -c \
  "import sys; from comat.cli import main; sys.argv=['comat']+sys.argv[1:]; sys.exit(main())" "$@"; }
cd "$root"
if [[ -f "$keep/summary.json" ]]; then echo "done: $name"; exit 0; fi
mkdir -p "runs/$grid"
echo "start: $name $(date -u +%FT%TZ)"
extra=()
[[ $reality == off ]] || extra+=("reality=$reality")
[[ $algo == qmix ]] && extra+=("models.qmix.max_robots=8")  # the paper's Table I row: 8 slots
if [[ $steps != 300000 && ! -d $run ]]; then  # the budget check continues a copy of the 300 k run
  base="$root/runs/$grid/${algo}_${task}_${reality}_s${seed}"
  if [[ -f $base/checkpoint.pt && -f $base/policy.pt ]]; then
    cp -r "$base" "$run.partial"
    rm -f "$run.partial"/{policy.pt,summary.json} "$run.partial"/evaluation_*
    mv "$run.partial" "$run"
  else  # the 300 k checkpoint is gone (a fresh machine): train 1 M from the start instead. Same result: the
    # sweep preset's learning rate is constant, and a run extended by --resume equals one run straight
    # through (tests/test_rl.py::test_resume_continues_exactly); it costs the 300 k steps once more.
    echo "$name: no 300 k checkpoint at $base: training 1 M from the start" | tee -a "$log" >&2
  fi
fi
if [[ ! -f $run/policy.pt ]]; then
  # a resumed run keeps the settings its config.yaml holds (comat train refuses overrides with --resume)
  args=("${extra[@]}"); [[ -f $run/checkpoint.pt ]] && args=(--resume)
  comat train --algo "$algo" --task "$task" --preset sweep --seed "$seed" --steps "$steps" --out "$run" \
    --quiet "${args[@]}" >> "$log" 2>&1
fi
teams=all; [[ $algo == qmix ]] && teams=both  # QMIX's 8 slots: U_train and U_test only
levels=(off nominal); [[ $steps == 300000 && $seed -le 102 ]] && levels+=(stress)
[[ -n ${LEVELS:-} ]] && read -r -a levels <<< "$LEVELS"
for level in "${levels[@]}"; do
  file=evaluation_unicycle.json; [[ $level == off ]] || file=evaluation_unicycle_$level.json
  [[ -f $run/$file ]] || comat eval --policy "$run" --teams "$teams" --episodes 5 --reality "$level" \
    --no-references --out "$run" >> "$log" 2>&1
done
mkdir -p "$keep.partial"
cp "$run"/{policy.pt,config.yaml,progress.csv,eval.csv,summary.json} "$run"/evaluation_unicycle*.{json,json.gz,csv} "$keep.partial"/
rm -rf "$keep" && mv "$keep.partial" "$keep"
echo "end: $name $(date -u +%FT%TZ)"
