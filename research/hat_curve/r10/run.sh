#!/bin/bash
# The round-10 1-kbp hat curve at 1 pN by replica exchange along the turns: one ladder of 18 rungs, 0.4 turns apart
# across both buckling transitions and through both plateaus (round 9's 0.8-turn end pairs accepted 9-10 % and no
# replica made a round trip), 0.8 apart in the straight middle (round 9: 44-46 % there); round 8's 12 turn values
# are all rungs. Two dask actors on the command's 2-worker LocalCluster, default non-bonded terms; 25 ns
# equilibration + 140 ns production per rung; wall/CPU of the command from /usr/bin/time, the load every minute.
# Usage: research/hat_curve/r10/run.sh [ROOT] [DNAROD]
set -u
ROOT=${1:-runs/hat_r10}
DNAROD=${2:-.venv/bin/dnarod}
TURNS=-4.8,-4.4,-4,-3.6,-3.2,-2.8,-2.4,-1.6,-0.8,0,0.8,1.6,2,2.4,2.8,3.2,3.6,4
"$(dirname "$0")/../timed_run.sh" "$ROOT" "$DNAROD" protocol hat --source 1000 --force 1 --turns=$TURNS \
    --start exchange --equilibration 25 --time 140 --workers 2 -o "$ROOT/curve"
