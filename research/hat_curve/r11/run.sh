#!/bin/bash
# The round-11 1-kbp hat curve at 1 pN by replica exchange along the turns, members on OpenMM's Reference platform
# (round 10 ran them on the CPU platform with Threads=1: 2.0-2.1x the CPU time per ns,
# benchmarks/bench_exchange_platform.py). 22 rungs: round 10's 18 plus +2.2, +2.6, +3.0 and +3.4, so the rungs are
# 0.2 turns apart from +2.0 to +3.6 where round 10's +2.8 and +3.2 rungs missed 3 %; 0.4 apart on the negative side,
# 0.8 in the straight middle. Two dask actors on the command's 2-worker LocalCluster, default non-bonded terms;
# 30 ns equilibration + 240 ns production per rung (round 10: 25 + 140 ns); wall/CPU of the command from /usr/bin/time,
# the load every minute.
# Usage: research/hat_curve/r11/run.sh [ROOT] [DNAROD]
set -u
ROOT=${1:-runs/hat_r11}
DNAROD=${2:-.venv/bin/dnarod}
TURNS=-4.8,-4.4,-4,-3.6,-3.2,-2.8,-2.4,-1.6,-0.8,0,0.8,1.6,2,2.2,2.4,2.6,2.8,3,3.2,3.4,3.6,4
"$(dirname "$0")/../timed_run.sh" "$ROOT" "$DNAROD" protocol hat --source 1000 --force 1 --turns=$TURNS \
    --start exchange --equilibration 30 --time 240 --workers 2 -o "$ROOT/curve"
