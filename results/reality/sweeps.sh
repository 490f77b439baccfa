#!/bin/bash
# One component's sweep for the kept PCP policies of seed 0 (issue 29 part 5, a first curve):
# pose delay 0-6 ticks alone (the rest at off), U_test, 2 episodes per coalition; then the report's
# robustness curves.
set -e
cd "$(dirname "$0")/../.."
for pol in comat_pcp_s0 mat_pcp_s0; do
  comat eval --policy results/policies/$pol/policy.pt --teams test --episodes 2 --no-references \
    --reality-sweep pose_delay_ticks --sweep-values 0 2 4 6 --out results/policies/$pol --force
done
comat report results/policies/comat_pcp_s0 results/policies/mat_pcp_s0 --out results/reality/report_pcp_s0 --force
