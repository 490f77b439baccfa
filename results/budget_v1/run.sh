#!/usr/bin/env bash
# Issue 68's Stage 1 and its forage pilot, as PLAN.md pre-registers them. NOT RUN YET.
#
#   COMAT_CODE=/work/budget_v1_code results/budget_v1/run.sh stage1   # train the 16 runs, then evaluate them
#   COMAT_CODE=/work/budget_v1_code results/budget_v1/run.sh pilot    # the forage pilot (exploratory)
#   results/budget_v1/run.sh status                                   # done / running / left, hours left
#   results/budget_v1/run.sh keep                                     # copy what is to be committed
#
# COMAT_CODE: a clean checkout (git worktree) of the commit PLAN.md names for the runs; every run imports
# comat from it (PYTHONPATH), so edits in this tree never reach a run, and every config.yaml records that
# commit (run.sh refuses a dirty checkout, and checks the commit of every run it evaluates or keeps).
# JOBS: runs side by side (default: this machine's cores; each run takes one: env_workers 1, torch_threads 1).
# Every step resumes: `comat sweep --out DIR` continues a recorded sweep (finished runs skipped, stopped ones
# resumed from their checkpoints), and each evaluation is skipped where its file exists. Run it again after
# any interruption; nothing is run twice. Run nothing else heavy beside it, and no timing measurement.
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
here="$root/results/budget_v1"
stage1="$root/runs/budget_v1/stage1"
pilot="$root/runs/budget_v1/forage_pilot"
refs="$root/runs/budget_v1/references"
logs="$root/runs/budget_v1/logs"  # outside the sweep folders, whose run globs (comat report ROOT/*_s*) it would join
jobs=${JOBS:-$(nproc)}
cd "$root"

code_commit() {  # the clean commit of COMAT_CODE, or exit
  [[ -n ${COMAT_CODE:-} && -d $COMAT_CODE/comat ]] || { echo "set COMAT_CODE to a clean checkout (PLAN.md, 'Code')" >&2; exit 2; }
  if [[ -n $(git -C "$COMAT_CODE" status --porcelain --untracked-files=no) ]]; then
    echo "COMAT_CODE=$COMAT_CODE has uncommitted changes: the runs must record a clean commit" >&2; exit 2
  fi
  git -C "$COMAT_CODE" rev-parse HEAD
}
comat() { OMP_NUM_THREADS=1 PYTHONPATH="${COMAT_CODE:-}" "$root/.venv/bin/comat" "$@"; }
py() { OMP_NUM_THREADS=1 PYTHONPATH="${COMAT_CODE:-}" "$root/.venv/bin/python" "$@"; }
check_commit() {  # RUN_FOLDER COMMIT: the run's config.yaml names COMMIT, clean
  grep -q "^  commit: $2\$" "$1/config.yaml" || { echo "$1: config.yaml does not record commit $2" >&2; exit 3; }
}

# Stage 1: HMT, COMAT and MAT-20 (the sweep preset gives MAT 20 slots), seeds 200-207, 4 M env steps, CPU;
# budget curves on U_val and U_cap every 250 k (one episode per coalition: the preset's); the checkpoint
# rule's candidates kept. --no-eval: the sweep's own evaluation would play the final policy; the plan's
# evaluation plays the selected one (evaluate_run below).
STAGE1=(--algos comat mat --tasks hmt --seeds 200 201 202 203 204 205 206 207 --preset sweep --steps 4000000
  --no-eval --device cpu --out "$stage1"
  eval_every_steps=250000 "eval_sets=[val,capability]" "keep_policies_at=[3250000,3500000,3750000,4000000]")
# The forage pilot: COMAT, MAT-20, MAPPO-20 and CASH (code-faithful), seeds 200-201, 1 M env steps; the final
# policy on all six sets, 10 episodes per coalition, reality off; curves on U_val and U_cap every 100 k.
PILOT=(--algos comat mat mappo cash --tasks forage --seeds 200 201 --preset sweep --steps 1000000
  --eval-sets train val test scale size capability --episodes 10 --device cpu --out "$pilot"
  eval_every_steps=100000 "eval_sets=[val,capability]")

evaluate_run() {  # RUN_FOLDER COMMIT: Stage 1's evaluation of one trained run (PLAN.md, "Evaluation")
  local run=$1 commit=$2 t sel log
  log="$logs/$(basename "$run").eval.log"
  check_commit "$run" "$commit"
  for t in 3250000 3500000 3750000 4000000; do  # the checkpoint rule: each candidate on U_val
    [[ -f $run/select/$t/evaluation_unicycle.json ]] || comat eval --policy "$run/policy_$t.pt" --teams val \
      --episodes 10 --no-references --out "$run/select/$t" >> "$log" 2>&1
  done
  sel=$(py "$here/pick_checkpoint.py" "$run")
  # the selected policy: every set at off (U_cap the primary), U_cap at nominal
  [[ -f $run/final/evaluation_unicycle.json ]] || comat eval --policy "$run/policy_$sel.pt" --teams all \
    --episodes 10 --no-references --out "$run/final" >> "$log" 2>&1
  [[ -f $run/final/evaluation_unicycle_nominal.json ]] || comat eval --policy "$run/policy_$sel.pt" \
    --teams capability --episodes 10 --reality nominal --no-references --out "$run/final" >> "$log" 2>&1
  # the final checkpoint on U_cap (secondary read), where the rule chose another
  if [[ $sel != 4000000 && ! -f $run/last/evaluation_unicycle.json ]]; then
    comat eval --policy "$run/policy_4000000.pt" --teams capability --episodes 10 --no-references \
      --out "$run/last" >> "$log" 2>&1
  fi
  echo "evaluated: $(basename "$run") (selected $sel) $(date -u +%FT%TZ)"
}

case ${1:-} in
  stage1)
    commit=$(code_commit)
    echo "stage 1 at commit $commit: $jobs run(s) side by side on $(nproc) core(s) $(date -u +%FT%TZ)"
    comat sweep "${STAGE1[@]}" --jobs "$jobs"
    # the scripted reference on U_cap at the evaluation's seed and episodes (descriptive: the collapse
    # threshold is fixed in PLAN.md)
    [[ -f $refs/evaluation_unicycle.json ]] || comat eval --policy heuristic --task hmt --teams capability \
      --episodes 10 --out "$refs" > /dev/null
    runs=("$stage1"/*_hmt_s2??)
    [[ ${#runs[@]} == 16 ]] || { echo "expected 16 run folders in $stage1, found ${#runs[@]}" >&2; exit 3; }
    for run in "${runs[@]}"; do [[ -f $run/summary.json ]] || { echo "$run: not finished" >&2; exit 3; }; done
    export -f evaluate_run check_commit comat py
    mkdir -p "$logs"
    export root here logs COMAT_CODE
    printf '%s\n' "${runs[@]}" | xargs -P "$jobs" -I{} bash -c 'set -euo pipefail; evaluate_run "$1" "$2"' _ {} "$commit"
    ;;
  pilot)
    commit=$(code_commit)
    echo "forage pilot at commit $commit: $jobs run(s) side by side on $(nproc) core(s) $(date -u +%FT%TZ)"
    comat sweep "${PILOT[@]}" --jobs "$jobs"
    for run in "$pilot"/*_forage_s2??; do check_commit "$run" "$commit"; done
    ;;
  status)
    for out in "$stage1" "$pilot"; do
      if [[ -d $out ]]; then "$root/.venv/bin/comat" sweep --out "$out" --status; else echo "$out: not started"; fi
    done
    ;;
  keep)  # small files, the kept policies and the evaluations -> results/budget_v1/runs/<name>/
    for run in "$stage1"/*_hmt_s2?? "$pilot"/*_forage_s2??; do
      [[ -f $run/summary.json ]] || continue
      keep="$here/runs/$(basename "$(dirname "$run")")/$(basename "$run")"
      mkdir -p "$keep.partial"
      cp "$run"/{config.yaml,progress.csv,eval.csv,summary.json,policy.pt} "$keep.partial"/
      cp "$run"/eval_*.csv "$keep.partial"/ 2>/dev/null || true
      cp "$run"/evaluation_unicycle* "$keep.partial"/ 2>/dev/null || true  # the pilot's sweep evaluation
      if [[ -f $run/selected.json ]]; then  # Stage 1: the rule's record, the selected policy, every evaluation
        cp "$run/selected.json" "$run/policy_$(py -c "import json,sys; print(json.load(open(sys.argv[1]))['selected'])" \
          "$run/selected.json").pt" "$keep.partial"/
        for sub in select final last; do [[ -d $run/$sub ]] && cp -r "$run/$sub" "$keep.partial"/; done
      fi
      rm -rf "$keep" && mv "$keep.partial" "$keep"
    done
    [[ -d $refs ]] && mkdir -p "$here/runs/references" && cp "$refs"/evaluation_unicycle* "$here/runs/references"/
    ;;
  *)
    echo "usage: COMAT_CODE=CLEAN_CHECKOUT $0 stage1|pilot; $0 status|keep" >&2; exit 2
    ;;
esac
