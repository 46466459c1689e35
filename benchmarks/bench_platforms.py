"""Benchmark: which OpenMM platform runs the callback (fast) path fastest on the CPU.

For 10^2 .. 10^6 nodes of dna-default DNA (LangevinMiddle, 300 K, the default time step, full
model: fast elastic path + excluded volume + Debye-Hueckel), each size in its own process
(optionally pinned to one core with ``taskset``), the same model is run on

* ``cpu``      -- the CPU platform with OpenMM's default thread count (the old default);
* ``cpu_t1``   -- the CPU platform with ``Threads=1`` (still one worker thread: every step is
  handed from the Python thread to the worker and back);
* ``reference``-- the Reference platform (single thread, no hand-off);
* ``auto``     -- whatever :func:`dnarod.engines.openmm.platforms.choose_platform` picks for this size.

Figures: steps per CPU-second (all threads of the process, ``time.process_time``) and per
wall-second, best of interleaved repeats (so machine load hits all alike; sizes >= 10^5 are run
once each, one simulation at a time, to bound memory), and node-steps per CPU-second.

``--elastic`` picks the elastic path run on every platform (default ``fast``, the Python-callback path
whose thread hand-off this compares; ``plugin`` for the compiled plugin).

Usage: ``python benchmarks/bench_platforms.py [--sizes 100,1000,...] [--budget S] [--pin CPU] [--json OUT]``.
"""
from __future__ import annotations

import argparse
import gc
import json
import os
import time

import numpy as np

import _harness as H

CONFIGS = ("cpu", "cpu_t1", "reference", "auto")


def _rate(integrator, budget):
    """(steps per CPU-second, steps per wall-second) over about ``budget`` seconds."""
    steps, cpu, wall = H.timed_steps(integrator, budget)
    return steps / max(cpu, 1e-9), steps / max(wall, 1e-9)


def _make(model, config, elastic):
    from dnarod.engines.openmm.simulation import RodSimulation

    kw = dict(temperature=300.0, seed=1, elastic=elastic)
    if config == "cpu":
        kw.update(platform="CPU")
    elif config == "cpu_t1":
        kw.update(platform="CPU", threads=1)
    elif config == "reference":
        kw.update(platform="Reference")
    else:
        kw.update(platform=None)
    t = time.perf_counter()
    sim = RodSimulation.create(model, **kw)
    return sim, time.perf_counter() - t


def single(n, budget, repeats, elastic="fast"):
    from dnarod.core.forcefield import load_forcefield

    rng = np.random.default_rng(0)
    model = load_forcefield("dna-default").model_from_sequence("".join(rng.choice(list("ACGT"), n)))
    out = dict(n_nodes=n)
    best = {c: (0.0, 0.0) for c in CONFIGS}
    if n <= 10000:
        sims = {}
        for c in CONFIGS:
            sims[c], out[f"{c}_setup_s"] = _make(model, c, elastic)
        out["auto_choice"] = sims["auto"].platform_name
        out["auto_reason"] = sims["auto"].platform_reason
        for _ in range(repeats):
            for c in CONFIGS:
                r = _rate(sims[c].integrator, budget)
                best[c] = max(best[c], r)
    else:
        for c in CONFIGS:
            sim, out[f"{c}_setup_s"] = _make(model, c, elastic)
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
    ap = H.add_common_arguments(argparse.ArgumentParser(), "100,1000,10000,100000,1000000", "bench_platforms")
    ap.add_argument("--elastic", default="fast", choices=["fast", "plugin", "auto"],
                    help="elastic path measured on every platform (default: the Python-callback path)")
    args = ap.parse_args()
    if args.single is not None:
        print(json.dumps(single(args.single, args.budget, args.repeats, args.elastic)))
        return
    prefix = H.pin_prefix(args.pin)
    load = [os.getloadavg()]
    results = H.run_sizes(__file__, H.parse_sizes(args.sizes),
                          lambda n: ["--budget", args.budget if n <= 100000 else max(args.budget, 3.0),
                                     "--repeats", args.repeats, "--elastic", args.elastic], prefix)
    load.append(os.getloadavg())
    pin = f"pinned to core {args.pin}" if prefix else "not pinned"
    print(f"steps per CPU-second (steps per wall-second), full model, elastic={args.elastic}, LangevinMiddle 300 K, "
          f"default dt, {pin}")
    print(f"{'nodes':>8} " + " ".join(f"{c:>19}" for c in CONFIGS) + "  auto choice  node-steps/CPU-s (auto)")
    for r in results:
        if "error" in r:
            print(f"{r['n_nodes']:>8} error: {r['error']}")
            continue
        cells = [f"{r[f'{c}_steps_per_cpu_s']:>9.4g} ({r[f'{c}_steps_per_wall_s']:>7.4g})" for c in CONFIGS]
        print(f"{r['n_nodes']:>8} " + " ".join(cells)
              + f"  {r['auto_choice']:>11}  {r['auto_node_steps_per_cpu_s']:.3g}")
    H.write_results(args.json, "bench_platforms", elastic=args.elastic, pinned=bool(prefix),
                    load_average_start_end=load, sizes=results)


if __name__ == "__main__":
    main()
