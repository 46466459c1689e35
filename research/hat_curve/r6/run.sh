#!/bin/bash
# The round-6 1-kbp hat curve at 1 pN: both turn-sweep directions, one after the other, each on the command's
# 2-worker dask LocalCluster, default non-bonded terms (calibrated charge), nice 8; wall/CPU of each command from
# /usr/bin/time, the load average every minute. Usage: research/hat_curve/r6/run.sh [ROOT] [DIRECTIONS]
set -u
ROOT=${1:-runs/hat_r6}
DIRS=${2:-"sweep sweep-in"}
mkdir -p "$ROOT"
( while true; do echo "$(date -u +%H:%M:%S) $(cut -d' ' -f1-3 /proc/loadavg)" >> "$ROOT/load.log"; sleep 60; done ) &
LOGGER=$!
trap 'kill $LOGGER' EXIT
TURNS=-4.8,-4,-3.2,-2.4,-1.6,-0.8,0,0.8,1.6,2.4,3.2,4
for d in $DIRS; do
  echo "$(date -u +%FT%T) start $d" >> "$ROOT/times.log"
  /usr/bin/time -v -o "$ROOT/time_$d.txt" nice -n 8 .venv/bin/dnarod protocol hat --source 1000 --force 1 \
      --turns=$TURNS --start "$d" --equilibration 30 --settle 8 --settle-buckled 120 --time 50 \
      -o "$ROOT/$d" > "$ROOT/$d.log" 2>&1
  echo "$(date -u +%FT%T) end $d rc $?" >> "$ROOT/times.log"
done
