#!/usr/bin/env bash
# A speed change's learning-curve check (issue 48): 25,600 env steps on PCP, paper preset, one
# torch thread, before (BEFORE: a worktree of the commit before the change) and after (this
# checkout); each run's progress.csv is copied to results/speed/curve_${LABEL}_{before,after}_ALGO_SEED.csv.
#   LABEL=softmax BEFORE=../before JOBS="comat 0,comat 1,mat 0" results/speed/curves.sh   # bf87c29
#   LABEL=kernels BEFORE=../before JOBS="comat 0,comat 1" results/speed/curves.sh          # 5bf0fb0
#   LABEL=packed BEFORE=../before JOBS="comat 0,comat 1" results/speed/curves.sh           # 795398a
#   LABEL=chunks BEFORE=../before JOBS="comat 0,comat 1" results/speed/curves.sh           # 862d76a
set -u
: "${BEFORE:?set BEFORE to a worktree of the commit before the change (git worktree add ../before REV)}"
: "${LABEL:?set LABEL, the name of the change in the csv files}"
JOBS=${JOBS:-"comat 0,comat 1,mat 0"}
cd "$(dirname "$0")/../.."
IFS=, read -ra jobs <<< "$JOBS"
for job in "${jobs[@]}"; do
  set -- $job
  for side in before after; do
    code=$PWD; [[ $side == before ]] && code="$BEFORE"
    out=runs/curves_$LABEL/${side}_$1_$2
    [[ -f $out/progress.csv && -f $out/policy.pt ]] && continue
    rm -rf $out && mkdir -p "$(dirname $out)"
    PYTHONPATH=$code OMP_NUM_THREADS=1 .venv/bin/python -P -c "import sys; from comat.cli import main; sys.argv=['comat']+sys.argv[1:]; sys.exit(main())" \
      train --algo $1 --task pcp --preset paper --steps 25600 --seed $2 --out $out --quiet eval_episodes_per_team=0 torch_threads=1 > $out.log 2>&1
    echo "$side $1 $2 done $(date -u +%T)"
    cp "$out/progress.csv" "results/speed/curve_${LABEL}_${side}_$1_$2.csv"
  done
done
