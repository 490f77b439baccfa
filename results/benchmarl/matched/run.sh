#!/usr/bin/env bash
# Issue 65's matched arm (PLAN.md): comat's MAPPO configured to BenchMARL's choices (matched.yaml) and
# BenchMARL's own MAPPO (../outside.py) on two fixed HMT teams, one job per call (a line of jobs.txt is
# ARM TEAM SEED STEPS):
#   COMAT_CODE=../wt-matched nohup sh -c "grep -v '^#' results/benchmarl/matched/jobs.txt | \
#     xargs -P 2 -L 1 results/benchmarl/matched/run.sh" > runs/benchmarl/matched/queue.log 2>&1 &
#   .venv/bin/python results/benchmarl/matched/analyze.py        # -> comparison.md
# ARM: `comat` (comat train in .venv) or `benchmarl` (outside.py in .venv-benchmarl; `make test-benchmarl`
# builds it). TEAM: 5 or 8 (team5.yaml, team8.yaml). Each run is evaluated right after training (20
# deterministic episodes on episodes.py's seeds, the same for both arms) and its small files are copied
# to results/benchmarl/matched/runs/NAME, where a session commits them; a kept run is skipped, an
# interrupted comat run resumes exactly, an interrupted BenchMARL run starts again. One thread per lane.
#
# COMAT_CODE: a checkout (a git worktree at a fixed commit) whose comat package and scripts the runs use,
# so edits in progress in this tree never reach a run; default: this checkout.
# The pilot (PLAN.md, "Pilot") sets CURVE_EVERY=FRAMES (a deterministic evaluation every so many env steps:
# comat's eval.csv, BenchMARL's kept checkpoints played into eval_curve.csv) and KEEP=results/benchmarl/matched/pilot.
set -euo pipefail
arm=$1 team=$2 seed=$3 steps=$4
root="$(cd "$(dirname "$0")/../../.." && pwd)"
code="$(cd "${COMAT_CODE:-$root}" && pwd)"
curve_every="${CURVE_EVERY:-0}"
name="${arm}_hmt${team}_s${seed}"
run="$root/runs/benchmarl/matched/$name"
keep="$root/${KEEP:-results/benchmarl/matched/runs}/$name"
teamfile="$code/results/benchmarl/matched/team${team}.yaml"
log="$run.log"
export OMP_NUM_THREADS=1 PYTHONPATH="$code"
cd "$root"
if [[ -f "$keep/eval.json" ]]; then echo "done: $name"; exit 0; fi
[[ -f $teamfile ]] || { echo "TEAM must be 5 or 8, got $team" >&2; exit 2; }
mkdir -p runs/benchmarl/matched "$keep.partial"
echo "start: $name $(date -u +%FT%TZ) code $(git -C "$code" rev-parse --short HEAD)"
if [[ $arm == comat ]]; then
  if [[ ! -f $run/policy.pt ]]; then
    args=(); [[ -f $run/checkpoint.pt ]] && args=(--resume)
    every=(eval_every_steps=1000000000)
    [[ $curve_every != 0 ]] && every=(eval_every_steps="$curve_every" eval_episodes_per_team=20)
    .venv/bin/comat train --algo mappo --task hmt --preset "$code/results/benchmarl/matched/matched.yaml" \
      --seed "$seed" --steps "$steps" --out "$run" --quiet "${args[@]}" coalitions="$teamfile" "${every[@]}" \
      >> "$log" 2>&1
  fi
  .venv/bin/python "$code/results/benchmarl/compare.py" eval-comat --run "$run" >> "$log" 2>&1
  files=("$run"/{policy.pt,config.yaml,progress.csv,summary.json,eval.json})
  [[ -f $run/eval.csv ]] && files+=("$run/eval.csv")
  cp "${files[@]}" "$keep.partial"/
elif [[ $arm == benchmarl ]]; then
  if [[ ! -f $run/eval.json ]]; then
    rm -rf "$run"  # BenchMARL's own restore is not used: an interrupted run starts again
    .venv-benchmarl/bin/python "$code/results/benchmarl/outside.py" train --task hmt --team "$teamfile" \
      --seed "$seed" --frames "$steps" --out "$run" --checkpoint-every "$curve_every" --distinct-seeds >> "$log" 2>&1
    if [[ $curve_every != 0 ]]; then
      .venv-benchmarl/bin/python "$code/results/benchmarl/outside.py" eval-checkpoints --run "$run" >> "$log" 2>&1
    fi
  fi
  # Its CSV logs, final checkpoint (networks and optimizers, no buffer) and config.pkl, for `outside.py eval`.
  cp -r "$run"/. "$keep.partial"/
  # The pilot's intermediate checkpoints stay in runs/ (eval_curve.csv holds what they showed).
  final="$(.venv/bin/python -c 'import json, sys; print(json.load(open(sys.argv[1]))["checkpoint"])' "$run/run.json")"
  find "$keep.partial" -name 'checkpoint_*.pt' ! -path "$keep.partial/$final" -delete
else
  echo "ARM must be comat or benchmarl, got $arm" >&2; exit 2
fi
rm -rf "$keep" && mv "$keep.partial" "$keep"
echo "end: $name $(date -u +%FT%TZ)"
