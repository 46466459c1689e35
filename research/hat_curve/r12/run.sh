#!/bin/bash
# The round-12 1-kbp hat curve at 1 pN by replica exchange along the turns, members on OpenMM's Reference platform.
# 26 rungs: round 11's 22 plus -4.2, -3.8, -3.4 and -3.0, so the rungs are 0.2 turns apart from -4.4 to -2.8 where
# round 11's -4.0 and -3.6 rungs (0.4 apart, swap acceptance 23-31 %, tau_int 8.8-8.9 ns) missed 3 % by 0.2 %;
# 0.2 apart from +2.0 to +3.6 past positive buckling (as round 11), 0.8 in the straight middle. Two dask actors on
# the command's 2-worker LocalCluster, default non-bonded terms; 30 ns equilibration + 210 ns production per rung
# (round 11: 30 + 240 ns on 22 rungs) to stay within 2 h; wall/CPU of the command from /usr/bin/time, the load every
# minute.
# Usage: research/hat_curve/r12/run.sh [ROOT] [DNAROD]
set -u
ROOT=${1:-runs/hat_r12}
DNAROD=${2:-.venv/bin/dnarod}
TURNS=-4.8,-4.4,-4.2,-4,-3.8,-3.6,-3.4,-3.2,-3,-2.8,-2.4,-1.6,-0.8,0,0.8,1.6,2,2.2,2.4,2.6,2.8,3,3.2,3.4,3.6,4
"$(dirname "$0")/../timed_run.sh" "$ROOT" "$DNAROD" protocol hat --source 1000 --force 1 --turns=$TURNS \
    --start exchange --equilibration 30 --time 210 --workers 2 -o "$ROOT/curve"
