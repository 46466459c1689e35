#!/bin/bash
# The round-8 1-kbp hat curve at 1 pN, bracketed: outward and inward turn sweeps at once (four chains) on the
# command's 2-worker dask LocalCluster, default non-bonded terms (calibrated charge); wall/CPU of the command from
# /usr/bin/time, the load average every minute. Usage: benchmarks/hat_r8/run.sh [ROOT] [DNAROD]
set -u
ROOT=${1:-runs/hat_r8}
DNAROD=${2:-.venv/bin/dnarod}
mkdir -p "$ROOT"
( while true; do echo "$(date -u +%H:%M:%S) $(cut -d' ' -f1-3 /proc/loadavg)" >> "$ROOT/load.log"; sleep 60; done ) &
LOGGER=$!
trap 'kill $LOGGER' EXIT
TURNS=-4.8,-4,-3.2,-2.4,-1.6,-0.8,0,0.8,1.6,2.4,3.2,4
echo "$(date -u +%FT%T) start" >> "$ROOT/times.log"
/usr/bin/time -v -o "$ROOT/time.txt" "$DNAROD" protocol hat --source 1000 --force 1 --turns=$TURNS \
    --start bracket --equilibration 30 --settle 8 --settle-buckled 130 --time 80 -o "$ROOT/curve" \
    > "$ROOT/curve.log" 2>&1
echo "$(date -u +%FT%T) end rc $?" >> "$ROOT/times.log"
