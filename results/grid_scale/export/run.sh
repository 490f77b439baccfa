#!/usr/bin/env bash
# Issue 18 part 5: the grid's COMAT PCP seed-0 checkpoint exported for the first ten U_scale teams
# (10-20 robots) and checked under the legacy rps; the 20-robot team (scale:2) also under the V2
# simulator. Run from the repository root; RPS_V2 = a robotarium_python_simulator checkout.
set -u
CK=${CK:-runs/grid18all/comat_pcp_s0/checkpoint.pt}   # the run of results/grid_scale/runs/comat_pcp_s0
OUT=${OUT:-runs/export18}
mkdir -p "$OUT"
for k in 0 1 2 3 4 5 6 7 8 9; do comat export --policy "$CK" --team scale:$k --out "$OUT/team$k"; done
comat export --check "$OUT/team2" --rps "${RPS_V2:?set RPS_V2 to a V2 simulator checkout}" > "$OUT/check_v2_team2.log" 2>&1
comat export --check "$OUT"/team{0..9} > "$OUT/check_legacy.log" 2>&1
