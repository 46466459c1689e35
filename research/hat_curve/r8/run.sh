#!/bin/bash
# The round-8 1-kbp hat curve at 1 pN, bracketed: outward and inward turn sweeps at once (four chains) on the
# command's 2-worker dask LocalCluster, default non-bonded terms (calibrated charge); wall/CPU of the command from
# /usr/bin/time, the load average every minute. Usage: research/hat_curve/r8/run.sh [ROOT] [DNAROD]
set -u
ROOT=${1:-runs/hat_r8}
DNAROD=${2:-.venv/bin/dnarod}
TURNS=-4.8,-4,-3.2,-2.4,-1.6,-0.8,0,0.8,1.6,2.4,3.2,4
"$(dirname "$0")/../timed_run.sh" "$ROOT" "$DNAROD" protocol hat --source 1000 --force 1 --turns=$TURNS \
    --start bracket --equilibration 30 --settle 8 --settle-buckled 130 --time 80 -o "$ROOT/curve"
