#!/bin/bash
# The round-9 1-kbp hat curve at 1 pN by replica exchange along the turns: one ladder of 18 rungs (0.8 turns apart
# where the chain is straight or deep in the plateau, 0.4 across the two buckling transitions, where a first try
# with 0.8 everywhere accepted no swap), two dask actors on the command's 2-worker LocalCluster, default non-bonded
# terms (calibrated charge); wall/CPU of the command from /usr/bin/time, the load average every minute.
# Usage: research/hat_curve/r9/run.sh [ROOT] [DNAROD]
set -u
ROOT=${1:-runs/hat_r9}
DNAROD=${2:-.venv/bin/dnarod}
TURNS=-4.8,-4,-3.6,-3.2,-2.8,-2.4,-2,-1.6,-0.8,0,0.8,1.2,1.6,2,2.4,2.8,3.2,4
"$(dirname "$0")/../timed_run.sh" "$ROOT" "$DNAROD" protocol hat --source 1000 --force 1 --turns=$TURNS \
    --start exchange --equilibration 25 --time 125 --workers 2 -o "$ROOT/curve"
