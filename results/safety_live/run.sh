#!/usr/bin/env bash
# Issue 66, "a shipped loop that is live": the measurements of results/safety_live/ (unicycle tier, seed 0).
set -euo pipefail
cd "$(dirname "$0")/../.."
# liveness beside safety, comat's loop, the live scenarios (off first: the reference)
.venv/bin/comat bench safety --reality off nominal stress --tiers unicycle --episodes 10 \
  --scenarios swap4 swap8 ring20 antipodal16 antipodal20 lanes12 pinch12 --loops comat \
  --out results/safety_live/liveness.json | tee results/safety_live/liveness.log
# the adversarial battery at stress: collisions and braking fallbacks of comat's loop
.venv/bin/comat bench safety --reality stress --tiers unicycle --episodes 10 \
  --scenarios head_on swap4 swap8 converge16 converge32 walls ring20 bangbang16 corner stop_swap4 stop_converge16 \
  dropout_swap4 frozen_stop_swap4 exact_swap4 exact_bangbang16 stall_converge16 stall_bangbang16 --loops comat \
  --out results/safety_live/battery_stress.json | tee results/safety_live/battery_stress.log
# built for X, run in Y
.venv/bin/comat bench safety --mismatch --tiers unicycle --episodes 6 \
  --out results/safety_live/mismatch.json | tee results/safety_live/mismatch.log
# the watch's thresholds (tuning seeds 0-1, held-out 2-3) and the tick cost at stress vs nominal
.venv/bin/python results/safety_live/watch_study.py > results/safety_live/watch_study.txt
.venv/bin/python results/safety_live/tick_cost.py > results/safety_live/tick_cost.txt
