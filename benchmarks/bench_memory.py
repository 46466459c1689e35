"""Peak memory of `dnarod simulate N` by node count and engine: the source of dnarod.run.resources.MEMORY_PER_NODE.

Each run is a fresh process (``dnarod simulate N --engine E --time 0.001 --no-export --no-progress``); its peak
resident memory is read from ``getrusage(RUSAGE_CHILDREN)`` in a wrapper process of its own. Prints a table and
JSON (bytes, and bytes per node from the differences between node counts).

    python benchmarks/bench_memory.py [--nodes 10000 100000] [--engines lax openmm]
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

WRAPPER = ("import resource, subprocess, sys; r = subprocess.run(sys.argv[1:], capture_output=True); "
           "print(r.returncode, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * 1024)")


def peak_rss(n, engine):
    with tempfile.TemporaryDirectory() as d:
        cmd = [str(Path(sys.executable).parent / "dnarod"), "simulate", str(n), "--engine", engine, "--time", "0.001",
               "--no-export", "--no-progress", "-o", f"{d}/run"]
        out = subprocess.run([sys.executable, "-c", WRAPPER, *cmd], capture_output=True, text=True, check=True)
        rc, rss = out.stdout.split()
        if rc != "0":
            raise SystemExit(f"dnarod simulate {n} --engine {engine} failed (exit {rc})")
        return int(rss)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--nodes", type=int, nargs="+", default=[10_000, 100_000])
    ap.add_argument("--engines", nargs="+", default=["lax", "openmm"])
    a = ap.parse_args()
    rows = []
    for e in a.engines:
        prev = None
        for n in sorted(a.nodes):
            rss = peak_rss(n, e)
            per = (rss - prev[1]) / (n - prev[0]) if prev else None
            rows.append(dict(engine=e, nodes=n, peak_rss_bytes=rss, bytes_per_node_from_previous=per))
            prev = (n, rss)
    print(f"{'engine':8s} {'nodes':>9s} {'peak RSS (MB)':>14s} {'B/node (diff)':>14s}")
    for r in rows:
        per = f"{r['bytes_per_node_from_previous']:.0f}" if r["bytes_per_node_from_previous"] else "-"
        print(f"{r['engine']:8s} {r['nodes']:9d} {r['peak_rss_bytes'] / 1e6:14.1f} {per:>14s}")
    print(json.dumps(rows))


if __name__ == "__main__":
    main()
