#!/bin/bash
# Decoding order without training (issue 30): the kept HMT policies on U_train and U_cap with each
# team's robots reversed and slow robots first (the decoder acts in slot order), 5 episodes per
# coalition; compare with the policies' own evaluation_unicycle.json (original order).
set -e
cd "$(dirname "$0")/../../.."
for pol in comat_hmt_s0 mat_hmt_s0; do
  for f in results/stability/orders/hmt_{train,capability}_{reversed,slow_first}.yaml; do
    name=$(basename $f .yaml)
    comat eval --policy results/policies/$pol/policy.pt --teams $f --episodes 5 --no-references \
      --out results/stability/orders/$pol/$name
  done
done
