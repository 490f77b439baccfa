#!/bin/bash
# Issue 29 part 5: every kept gap-experiment policy along each component's sweep (that component
# alone at SWEEP_VALUES, every other one off), U_test, 1 episode per coalition (20 per value, the
# same episodes at every value); then one report per task draws the robustness curves with
# intervals over seeds (fig7_robustness, robustness.csv).
# Usage: results/reality/sweeps_all.sh [POLICY_FOLDER ...]   (default: every comat/mat gap policy;
# FORCE=1 redoes sweeps whose files exist)
set -e
cd "$(dirname "$0")/../.."
components="pose_delay_ticks pose_noise_xy_m command_delay_ticks command_loss_prob motor_tau_max_s wheel_disturbance_radps fault_prob"
folders=("$@"); [ ${#folders[@]} -gt 0 ] || folders=(results/policies/{comat,mat}_{pcp,hmt}{,_nominal}_s[01])
for pol in "${folders[@]}"; do
  [ -f "$pol/policy.pt" ] || continue
  for c in $components; do
    [ -f "$pol/evaluation_unicycle_sweep_$c.json" ] && [ -z "$FORCE" ] && continue
    comat eval --policy "$pol/policy.pt" --teams test --episodes 1 --no-references \
      --reality-sweep "$c" --out "$pol" --force
  done
done
