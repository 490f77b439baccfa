#!/usr/bin/env bash
# The learning-curve check of the short-row softmax change (issue 48): 25,600 env steps of COMAT
# (seeds 0, 1) and MAT (seed 0) before (BEFORE: a worktree of bf87c29) and after (this checkout).
set -u
: "${BEFORE:?set BEFORE to a worktree of bf87c29 (git worktree add ../before bf87c29)}"
cd "$(dirname "$0")/../.."
for job in "comat 0" "comat 1" "mat 0"; do
  set -- $job
  for side in before after; do
    code=$PWD; [[ $side == before ]] && code="$BEFORE"
    out=runs/curves/${side}_$1_$2
    [[ -f $out/progress.csv && -f $out/policy.pt ]] && continue
    rm -rf $out
    PYTHONPATH=$code OMP_NUM_THREADS=1 .venv/bin/python -P -c "import sys; from comat.cli import main; sys.argv=['comat']+sys.argv[1:]; sys.exit(main())" \
      train --algo $1 --task pcp --preset paper --steps 25600 --seed $2 --out $out --quiet eval_episodes_per_team=0 torch_threads=1 > $out.log 2>&1
    echo "$side $1 $2 done $(date -u +%T)"
    cp "$out/progress.csv" "results/speed/curve_softmax_${side}_$1_$2.csv"
  done
done
