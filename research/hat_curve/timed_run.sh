#!/bin/bash
# The harness of the long hat-curve runs (r8-r12/run.sh): run COMMAND... with its output in
# ROOT/curve.log, its wall and CPU time in ROOT/time.txt (/usr/bin/time -v), its start and end (with the exit
# status) in ROOT/times.log and the load average every minute in ROOT/load.log; exits with the command's status.
# Usage: research/hat_curve/timed_run.sh ROOT COMMAND...
set -u
ROOT=$1
shift
mkdir -p "$ROOT"
( while true; do echo "$(date -u +%H:%M:%S) $(cut -d' ' -f1-3 /proc/loadavg)" >> "$ROOT/load.log"; sleep 60; done ) &
LOGGER=$!
trap 'kill $LOGGER' EXIT
echo "$(date -u +%FT%T) start" >> "$ROOT/times.log"
/usr/bin/time -v -o "$ROOT/time.txt" "$@" > "$ROOT/curve.log" 2>&1
rc=$?
echo "$(date -u +%FT%T) end rc $rc" >> "$ROOT/times.log"
exit $rc
