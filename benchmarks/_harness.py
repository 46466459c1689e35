"""Shared plumbing of the benchmark scripts: timed stepping, one process per size, JSON out.

Each size-scanning script (``bench_openmm``, ``bench_platforms``, ``bench_nonbonded``, ``bench_gpu``)
measures every size in a fresh process (clean peak memory, no state carried between sizes),
optionally pinned to one core with ``taskset``; the child runs the same script with
``--single N`` and prints one JSON line. This module holds that loop, the timed-stepping helper
and the JSON writer (machine, date and load average recorded with every result), so the scripts
differ only in what they measure.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"


def cpu_seconds():
    """CPU seconds of this process (all threads) plus the child processes it has waited for."""
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


def timed_steps(integrator, budget, warmup=2, probe=1, min_steps=2, clock="wall"):
    """Step ``integrator`` for about ``budget`` seconds; returns ``(steps, cpu_s, wall_s)``.

    ``warmup`` steps first, then ``probe`` steps are timed to size the measured run, by wall time
    or (``clock="cpu"``) by CPU time of this process, which keeps the number of measured steps
    independent of the machine's load.
    """
    integrator.step(warmup)
    now = time.process_time if clock == "cpu" else time.perf_counter
    t = now()
    integrator.step(probe)
    one = max((now() - t) / probe, 1e-6)
    steps = max(min_steps, int(budget / one))
    c0, w0 = time.process_time(), time.perf_counter()
    integrator.step(steps)
    return steps, time.process_time() - c0, time.perf_counter() - w0


def pin_prefix(pin):
    """``taskset -c PIN`` (or nothing when ``pin`` is empty or taskset is missing)."""
    return ["taskset", "-c", pin] if pin and shutil.which("taskset") else []


def add_common_arguments(ap, sizes, name, pin=True, budget=2.0, repeats=3):
    """The options every size-scanning script takes (``--sizes --budget --repeats [--pin] --json``,
    hidden ``--single``)."""
    ap.add_argument("--sizes", default=sizes)
    ap.add_argument("--budget", type=float, default=budget, help="seconds per rate measurement")
    ap.add_argument("--repeats", type=int, default=repeats)
    if pin:
        ap.add_argument("--pin", default="0", help="core to pin each measurement to with taskset ('' for none)")
    ap.add_argument("--json", default=str(RESULTS / f"{name}.json"))
    ap.add_argument("--single", type=int, default=None, help=argparse.SUPPRESS)
    return ap


def run_child(script, args, prefix=(), timeout=3600, error_lines=1):
    """Run ``python script *args`` (after ``prefix``) and return its last stdout line as JSON, or
    ``{"error": ...}`` with the last ``error_lines`` lines of stderr."""
    p = subprocess.run(list(prefix) + [sys.executable, str(script)] + [str(a) for a in args], capture_output=True,
                       text=True, timeout=timeout)
    if p.returncode != 0:
        return dict(error=" | ".join((p.stderr.strip().splitlines() or ["failed"])[-error_lines:]))
    return json.loads(p.stdout.strip().splitlines()[-1])


def run_sizes(script, sizes, child_args, prefix=(), timeout=3600, error_lines=1):
    """Measure each size in its own process: ``child_args(n)`` gives the extra arguments after
    ``--single n``. Returns one dict per size (``n_nodes``, ``wall_s`` of the child, or ``error``)."""
    results = []
    for n in sizes:
        t = time.perf_counter()
        r = run_child(script, ["--single", n] + list(child_args(n)), prefix, timeout, error_lines)
        r.setdefault("n_nodes", n)
        r["wall_s"] = time.perf_counter() - t
        results.append(r)
        print(f"measured {n} nodes in {r['wall_s']:.0f} s", file=sys.stderr)
    return results


def parse_sizes(text):
    return [int(s) for s in text.split(",")]


def write_results(path, benchmark, **fields):
    """Write ``fields`` with the benchmark name, machine, Python, date and load average to ``path`` (JSON)."""
    out = dict(benchmark=benchmark, machine=platform.platform(), cpu_count=os.cpu_count(),
               python=platform.python_version(), date=time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
               load_average=os.getloadavg(), **fields)
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(str(path) + ".tmp")
    tmp.write_text(json.dumps(out, indent=2))
    os.replace(tmp, path)
    print(f"wrote {path}")
    return out
