"""Benchmark: which OpenMM platform runs the callback (fast) path fastest on the CPU.

For 10^2 .. 10^6 nodes of dna-default DNA (LangevinMiddle, 300 K, the default time step, full
model: fast elastic path + excluded volume + Debye-Hueckel), each size in its own process
(optionally pinned to one core with ``taskset``), the same model is run on

* ``cpu``      -- the CPU platform with OpenMM's default thread count (the old default);
* ``cpu_t1``   -- the CPU platform with ``Threads=1`` (still one worker thread: every step is
  handed from the Python thread to the worker and back);
* ``reference``-- the Reference platform (single thread, no hand-off);
* ``auto``     -- whatever :func:`dnarod.openmm.platforms.choose_platform` picks for this size.

Figures: steps per CPU-second (all threads of the process, ``time.process_time``) and per
wall-second, best of interleaved repeats (so machine load hits all alike; sizes >= 10^5 are run
once each, one simulation at a time, to bound memory), and node-steps per CPU-second.

Usage: ``python benchmarks/bench_platforms.py [--sizes 100,1000,...] [--budget S] [--pin CPU] [--json OUT]``.
"""
from __future__ import annotations

import argparse
import gc
import json
import os
import platform
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CONFIGS = ("cpu", "cpu_t1", "reference", "auto")


def _rate(integrator, budget):
    """(steps per CPU-second, steps per wall-second) over about ``budget`` seconds."""
    integrator.step(2)
    t = time.perf_counter()
    integrator.step(1)
    one = max(time.perf_counter() - t, 1e-5)
    steps = max(2, int(budget / one))
    c0, w0 = time.process_time(), time.perf_counter()
    integrator.step(steps)
    c1, w1 = time.process_time(), time.perf_counter()
    return steps / max(c1 - c0, 1e-9), steps / max(w1 - w0, 1e-9)


def _make(model, config):
    from dnarod.openmm.simulation import RodSimulation

    kw = dict(temperature=300.0, seed=1)
    if config == "cpu":
        kw.update(platform="CPU")
    elif config == "cpu_t1":
        kw.update(platform="CPU", threads=1)
    elif config == "reference":
        kw.update(platform="Reference")
    else:
        kw.update(platform=None)
    t = time.perf_counter()
    sim = RodSimulation(model, **kw)
    return sim, time.perf_counter() - t


def single(n, budget, repeats):
    from dnarod.forcefield import load_forcefield

    rng = np.random.default_rng(0)
    model = load_forcefield("dna-default").model_from_sequence("".join(rng.choice(list("ACGT"), n)))
    out = dict(n_nodes=n)
    best = {c: (0.0, 0.0) for c in CONFIGS}
    if n <= 10000:
        sims = {}
        for c in CONFIGS:
            sims[c], out[f"{c}_setup_s"] = _make(model, c)
        out["auto_choice"] = sims["auto"].platform_name
        out["auto_reason"] = sims["auto"].platform_reason
        for _ in range(repeats):
            for c in CONFIGS:
                r = _rate(sims[c].integrator, budget)
                best[c] = max(best[c], r)
    else:
        for c in CONFIGS:
            sim, out[f"{c}_setup_s"] = _make(model, c)
            if c == "auto":
                out["auto_choice"] = sim.platform_name
                out["auto_reason"] = sim.platform_reason
            best[c] = _rate(sim.integrator, budget)
            del sim
            gc.collect()
    for c in CONFIGS:
        out[f"{c}_steps_per_cpu_s"], out[f"{c}_steps_per_wall_s"] = best[c]
        out[f"{c}_node_steps_per_cpu_s"] = best[c][0] * n
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", default="100,1000,10000,100000,1000000")
    ap.add_argument("--budget", type=float, default=2.0, help="seconds per rate measurement")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--pin", default="0", help="core to pin each measurement to with taskset ('' for none)")
    ap.add_argument("--json", default=str(ROOT / "benchmarks" / "results" / "bench_platforms.json"))
    ap.add_argument("--single", type=int, default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.single is not None:
        print(json.dumps(single(args.single, args.budget, args.repeats)))
        return
    prefix = ["taskset", "-c", args.pin] if args.pin and shutil.which("taskset") else []
    results = []
    for n in [int(s) for s in args.sizes.split(",")]:
        budget = args.budget if n <= 100000 else max(args.budget, 3.0)
        t = time.perf_counter()
        p = subprocess.run(prefix + [sys.executable, __file__, "--single", str(n), "--budget", str(budget),
                                     "--repeats", str(args.repeats)], capture_output=True, text=True, timeout=3600)
        if p.returncode != 0:
            results.append(dict(n_nodes=n, error=(p.stderr.strip().splitlines() or ["failed"])[-1]))
        else:
            results.append(json.loads(p.stdout.strip().splitlines()[-1]))
        results[-1]["wall_s"] = time.perf_counter() - t
        print(f"measured {n} nodes in {results[-1]['wall_s']:.0f} s", file=sys.stderr)
    pin = f"pinned to core {args.pin}" if prefix else "not pinned"
    print(f"steps per CPU-second (steps per wall-second), full model, LangevinMiddle 300 K, default dt, {pin}")
    print(f"{'nodes':>8} " + " ".join(f"{c:>19}" for c in CONFIGS) + "  auto choice")
    for r in results:
        if "error" in r:
            print(f"{r['n_nodes']:>8} error: {r['error']}")
            continue
        cells = [f"{r[f'{c}_steps_per_cpu_s']:>9.4g} ({r[f'{c}_steps_per_wall_s']:>7.4g})" for c in CONFIGS]
        print(f"{r['n_nodes']:>8} " + " ".join(cells) + f"  {r['auto_choice']}")
    out = dict(benchmark="bench_platforms", machine=platform.platform(), cpu_count=os.cpu_count(),
               python=platform.python_version(), pinned=bool(prefix), date=time.strftime("%Y-%m-%d %H:%M UTC",
                                                                                          time.gmtime()),
               sizes=results)
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps(out, indent=2))
    print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
