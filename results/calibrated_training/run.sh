#!/usr/bin/env bash
# The calibrated-training study (issue 66; PLAN.md), one command: the stand-in robot's calibration logs
# and profiles, the two arms' trainings (nominal; the fitted profile's intervals drawn every episode),
# each policy evaluated in the ideal world and under the four held-out layers, then the table and the
# test (analyze.py -> results.md). Re-run after an interruption: a finished step is skipped, an
# interrupted training resumes exactly from its checkpoint.
#
#   results/calibrated_training/run.sh
#
# Settings (environment, defaults in brackets): TASK [hmt], ALGO [comat], STEPS [300000], SEEDS ["0 1 2"],
# ARMS ["nominal calibrated"; "point" trains at the profile's point values], EPISODES [5] per coalition,
# TEAMS [both = U_train and U_test], LANES [2] jobs side by side (one core each), OUT [runs/calibrated_training]
# (the runs), KEEP [results/calibrated_training] (profiles, the runs' small files, results.md).
# COMAT_CODE: a checkout whose comat package the jobs import instead of this tree's (edits in progress
# here then never reach a run). A tiny end-to-end check (minutes, nothing kept in the tree):
#   STEPS=2048 SEEDS=0 EPISODES=1 TEAMS=test LANES=2 OUT=/tmp/ct KEEP=/tmp/ct/keep results/calibrated_training/run.sh
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
here="$root/results/calibrated_training"
TASK=${TASK:-hmt} ALGO=${ALGO:-comat} STEPS=${STEPS:-300000} SEEDS=${SEEDS:-0 1 2}
ARMS=${ARMS:-nominal calibrated} EPISODES=${EPISODES:-5} TEAMS=${TEAMS:-both} LANES=${LANES:-2}
OUT=${OUT:-$root/runs/calibrated_training} KEEP=${KEEP:-$here}
export TASK ALGO STEPS EPISODES TEAMS OUT KEEP
profiles="$KEEP/profiles"
comat() { OMP_NUM_THREADS=1 PYTHONPATH="${COMAT_CODE:-}" "$root/.venv/bin/comat" "$@"; }
cd "$root"

layer() {  # a held-out layer's name -> what --reality takes
  case $1 in
    off | stress) echo "$1" ;;
    truth | shifted) echo "$here/layers/$1.yaml" ;;
    refit_s1) echo "$profiles/refit_s1.yaml" ;;
    *) echo "unknown layer $1" >&2; exit 2 ;;
  esac
}

job() {  # one arm and seed: train (or resume), evaluate under every layer, keep the small files
  local arm=$1 seed=$2 name="$1_s$2" extra=()
  local run="$OUT/$name" keep="$KEEP/runs/$name" log="$OUT/$name.log"
  case $arm in
    nominal) extra=(reality=nominal) ;;
    calibrated) extra=("reality=$profiles/fit_s0.yaml" reality_draw=intervals) ;;
    point) extra=("reality=$profiles/fit_s0.yaml") ;;
    *) echo "unknown arm $arm (nominal, calibrated, point)" >&2; exit 2 ;;
  esac
  echo "start: $name $(date -u +%FT%TZ)"
  if [[ ! -f $run/policy.pt ]]; then
    if [[ -f $run/checkpoint.pt ]]; then extra=(--resume); fi
    comat train --algo "$ALGO" --task "$TASK" --preset sweep --seed "$seed" --steps "$STEPS" --env-workers 1 \
      --out "$run" --quiet "${extra[@]}" >> "$log" 2>&1
  fi
  for held in off truth refit_s1 stress shifted; do
    [[ -n $(compgen -G "$run/eval_$held/evaluation_*.json") ]] && continue
    comat eval --policy "$run" --teams "$TEAMS" --episodes "$EPISODES" --no-references --reality "$(layer "$held")" \
      --out "$run/eval_$held" --force >> "$log" 2>&1
  done
  mkdir -p "$keep.partial"
  cp "$run"/{policy.pt,config.yaml,progress.csv,summary.json} "$keep.partial"/
  for held in off truth refit_s1 stress shifted; do
    mkdir -p "$keep.partial/eval_$held" && cp "$run/eval_$held"/evaluation_*.json "$keep.partial/eval_$held"/
  done
  rm -rf "$keep" && mv "$keep.partial" "$keep"
  echo "end: $name $(date -u +%FT%TZ)"
}

if [[ ${1:-} == job ]]; then job "$2" "$3"; exit 0; fi

fit() {  # seed, profile name: the stand-in robot's four experiments (4 robots) and the profile fitted from them
  local seed=$1 logs="$OUT/logs_s$1"
  [[ -f $profiles/$2.yaml ]] && return 0
  rm -rf "$logs" && mkdir -p "$profiles"
  comat calibrate --simulate "$here/layers/truth.yaml" --robots 4 --seed "$seed" --out "$logs"
  comat calibrate "$logs"/calib_{steps,still,ramp,spin}.npy --truth "$logs/truth.yaml" --out "$profiles/$2.yaml"
}
mkdir -p "$OUT"
fit 0 fit_s0    # what the calibrated arm trains on
fit 1 refit_s1  # a second session's profile: held out, evaluated at its point values
for seed in $SEEDS; do for arm in $ARMS; do echo "$arm $seed"; done; done | xargs -P "$LANES" -L 1 "$0" job
"$root/.venv/bin/python" "$here/analyze.py" "$KEEP" --arms $ARMS
