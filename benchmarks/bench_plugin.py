"""Benchmark: the compiled OpenMM plugin against today's Python-callback path, in one run.

On the CPU platform with one thread (OpenMM ``Threads=1``, numba one thread), dna-default DNA, Langevin
300 K at the default time step:

* ``callback``  -- the Python-callback path: three-particle nodes held by constraints, LangevinMiddle,
  elastic loads by numba through PythonForce (what dnarod used before the plugin);
* ``plugin``    -- the compiled SMKForce and rigid-body integrator (no constraints, loads fused in);

each ``bonded`` (elastic only) and ``full`` (plus excluded volume and Debye-Hueckel, today's PythonForce
kernel in both). Rates are node-steps per CPU-second of this process (``time.process_time``) and per wall
second, best of interleaved repeats. Then a 1 kbp duplex through the run loop with ``dnarod simulate``'s default
reporting (a frame and an energies row every 1 ps, the default checkpoint schedule), full model: ns/day for both
paths. Then the plugin on one and two threads (wall and CPU rates). ``--install`` also times a fresh
``python3 -m venv .venv && .venv/bin/pip install -q -e .`` of a copy of this tree (the plugin build included).

Targets (issue 15): plugin full >= 1.0e7 node-steps per CPU-second at 10^4 nodes; 1 kbp >= 30,000 ns/day;
install with the build <= 120 s.

Usage: ``python benchmarks/bench_plugin.py [--sizes 1000,10000] [--budget S] [--repeats R] [--install]``.
"""
from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

import _harness as H  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def _rate(integrator, n_nodes, budget):
    """(node-steps per CPU-second, per wall second) over about ``budget`` seconds."""
    integrator.step(2)
    t = time.perf_counter()
    integrator.step(2)
    one = max((time.perf_counter() - t) / 2, 1e-6)
    steps = max(4, int(budget / one))
    t, c = time.perf_counter(), time.process_time()
    integrator.step(steps)
    wall, cpu = time.perf_counter() - t, time.process_time() - c
    return n_nodes * steps / cpu, n_nodes * steps / wall


def sizes(ns, budget, repeats):
    from dnarod.core.forcefield import load_forcefield
    from dnarod.engines.openmm.simulation import RodSimulation

    make = getattr(RodSimulation, "create", RodSimulation)  # an older tree (bench_run_overhead) has no create
    ff = load_forcefield("dna-default")
    out = []
    for n in ns:
        rng = np.random.default_rng(0)
        model = ff.model_from_sequence("".join(rng.choice(list("ACGT"), n)))
        sims = {}
        for path, elastic in (("callback", "fast"), ("plugin", "plugin")):
            for kind, nb in (("bonded", False), ("full", True)):
                sims[f"{path}_{kind}"] = make(model, temperature=300.0, nonbonded=nb, seed=1, elastic=elastic,
                                              threads=1)
        rates = {k: [] for k in sims}
        for _ in range(repeats):
            for k, s in sims.items():
                rates[k].append(_rate(s.integrator, n, budget))
        r = dict(n_nodes=n, dt_ps=sims["plugin_full"].dt)
        for k, v in rates.items():
            r[f"{k}_per_cpu_s"] = max(x[0] for x in v)
            r[f"{k}_per_wall_s"] = max(x[1] for x in v)
        r["speedup_full_cpu"] = r["plugin_full_per_cpu_s"] / r["callback_full_per_cpu_s"]
        r["speedup_bonded_cpu"] = r["plugin_bonded_per_cpu_s"] / r["callback_bonded_per_cpu_s"]
        out.append(r)
        print(f"measured {n} nodes", file=sys.stderr)
    return out


def kbp(budget):
    """1 kbp duplex, 300 K, default dt, full model, through the run loop with ``dnarod simulate``'s defaults: the
    automatic platform choice without ``--threads`` (the single-threaded Reference platform), a frame and an
    energies row every 1 ps, the default checkpoint schedule (:func:`dnarod.run.loop.simulate_engine`, as
    :func:`dnarod.run.run` calls it)."""
    from dnarod.core.forcefield import load_forcefield
    from dnarod.engines.openmm.simulation import RodSimulation
    from dnarod.run.loop import simulate_engine

    rng = np.random.default_rng(1)
    model = load_forcefield("dna-default").model_from_sequence("".join(rng.choice(list("ACGT"), 1000)))
    out = {}
    for path, elastic in (("callback", "fast"), ("plugin", "plugin")):
        sim = RodSimulation.create(model, temperature=300.0, seed=2, elastic=elastic)
        fi = max(1, int(round(1.0 / sim.dt)))
        sim.integrator.step(10)
        t, c = time.perf_counter(), time.process_time()
        sim.integrator.step(400)
        per_step = (time.perf_counter() - t) / 400
        bare_cpu = (time.process_time() - c) / 400
        n_steps = max(fi, int(budget / per_step) // fi * fi)
        with tempfile.TemporaryDirectory() as d:
            c0, t0 = time.process_time(), time.perf_counter()
            s = simulate_engine(sim, sim.step + n_steps, d, frame_interval=fi, energy_interval=fi)
            cpu, wall = time.process_time() - c0, time.perf_counter() - t0
        ns = n_steps * sim.dt * 1e-3
        out[path] = dict(platform=sim.platform_name, dt_ps=sim.dt, steps=n_steps, frame_interval_steps=fi,
                         checkpoints=s.get("checkpoints"),
                         ns_per_day_wall=ns / wall * 86400, ns_per_day_bare_cpu=sim.dt * 1e-3 / bare_cpu * 86400,
                         ns_per_day_cpu=ns / cpu * 86400, wall_s=wall, cpu_s=cpu,
                         mean_temperature=float(np.mean(s["temperatures"])))
    out["speedup_cpu"] = out["plugin"]["ns_per_day_cpu"] / out["callback"]["ns_per_day_cpu"]
    return out


def threads(ns, budget, repeats):
    """The plugin (full model) on 1 and 2 threads of the CPU platform: node-steps per wall second and per CPU-second.
    ``default``: the integrator's chunks of ``getNodesPerChunk()`` nodes (at most one thread per chunk, so 10^3
    nodes stay on one thread); ``forced``: chunks of 256 nodes (two threads at every size)."""
    import openmm

    from dnarod.core.forcefield import load_forcefield
    from dnarod.engines.openmm import particles as P
    from dnarod.engines.openmm import plugin
    from dnarod.engines.openmm.simulation import RodSimulation
    from dnarod.engines.openmm.system import build_system

    ff = load_forcefield("dna-default")
    out = []
    for n in ns:
        rng = np.random.default_rng(0)
        model = ff.model_from_sequence("".join(rng.choice(list("ACGT"), n)))
        dt = RodSimulation.create(model, temperature=300.0, seed=1, threads=1).dt
        rs = build_system(model, "CPU", "plugin", True, (), 300.0)
        runs = {}
        for label, nthreads, chunk in (("1", 1, None), ("2_forced", 2, 256), ("2_default", 2, None)):
            integ = plugin.rigid_body_integrator(rs.radius, dt, 300.0, 1.0, 1)
            if chunk is not None:
                integ.setNodesPerChunk(chunk)
            ctx = openmm.Context(rs.system, integ, openmm.Platform.getPlatformByName("CPU"),
                                 {"Threads": str(nthreads)})
            ctx.setPositions(P.particle_positions(model.positions, model.frames, rs.radius))
            ctx.setVelocitiesToTemperature(300.0, 1)
            runs[label] = (ctx, integ)
        rates = {k: [] for k in runs}
        for _ in range(repeats):
            for k, (ctx, integ) in runs.items():
                rates[k].append(_rate(integ, n, budget))
        r = dict(n_nodes=n, nodes_per_chunk=runs["2_default"][1].getNodesPerChunk())
        for k, v in rates.items():
            r[f"threads_{k}_used"] = runs[k][1].getNumThreads()
            r[f"threads_{k}_per_cpu_s"] = max(x[0] for x in v)
            r[f"threads_{k}_per_wall_s"] = max(x[1] for x in v)
        r["wall_speedup_2_forced"] = r["threads_2_forced_per_wall_s"] / r["threads_1_per_wall_s"]
        r["wall_speedup_2_default"] = r["threads_2_default_per_wall_s"] / r["threads_1_per_wall_s"]
        out.append(r)
        print(f"measured threads at {n} nodes", file=sys.stderr)
    return out


def install_time():
    """Wall and CPU seconds of the README's ``python3 -m venv .venv && .venv/bin/pip install -q -e .`` on a fresh
    copy of the tracked files, with the plugin build and (for comparison, same run) with it switched off."""
    out = {}
    for mode, env in (("with_plugin", {}), ("without_plugin", {"DNAROD_BUILD_PLUGIN": "0"})):
        with tempfile.TemporaryDirectory() as d:
            tree = Path(d) / "dnarod"
            files = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True).stdout.split()
            for f in files:
                (tree / f).parent.mkdir(parents=True, exist_ok=True)
                shutil.copy2(ROOT / f, tree / f)
            t = time.perf_counter()
            before = os.times()
            p = subprocess.run("python3 -m venv .venv && .venv/bin/pip install -q -e .", shell=True, cwd=tree,
                               capture_output=True, text=True, env=dict(os.environ, **env))
            after = os.times()
            wall = time.perf_counter() - t
            cpu = (after.children_user - before.children_user) + (after.children_system - before.children_system)
            status = next(iter((tree / "build").glob("*/_build_info.py")), None)
            text = status.read_text() if status else ""
            out[mode] = dict(ok=p.returncode == 0, wall_s=wall, cpu_s=cpu, plugin_built='STATUS = "built"' in text,
                             error=p.stderr[-500:] if p.returncode else "")
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", default="1000,10000,100000")
    ap.add_argument("--budget", type=float, default=2.0, help="seconds per rate measurement")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--kbp-budget", type=float, default=20.0, help="seconds of each 1 kbp run")
    ap.add_argument("--install", action="store_true", help="also time a fresh install")
    ap.add_argument("--thread-sizes", default="1000,10000,100000", help="sizes of the 1-vs-2-thread comparison "
                    "('' to skip)")
    ap.add_argument("--json", default=str(ROOT / "benchmarks" / "results" / "bench_plugin.json"))
    args = ap.parse_args()
    from dnarod.engines.openmm import plugin

    st = plugin.status()
    if not st.available:
        sys.exit(f"the compiled plugin is not usable here: {st.reason}")
    load_start = os.getloadavg()
    res = sizes([int(s) for s in args.sizes.split(",")], args.budget, args.repeats)
    k = kbp(args.kbp_budget)
    thr = threads([int(s) for s in args.thread_sizes.split(",") if s], args.budget, args.repeats)
    inst = install_time() if args.install else None

    print("node-steps per CPU-second (per wall second), CPU platform, one thread, Langevin 300 K, default dt")
    print(f"{'nodes':>7} {'callback bonded':>22} {'plugin bonded':>22} {'callback full':>22} {'plugin full':>22} "
          f"{'full x':>7}")
    for r in res:
        cells = [f"{r[f'{k}_per_cpu_s']:.3g} ({r[f'{k}_per_wall_s']:.3g})"
                 for k in ("callback_bonded", "plugin_bonded", "callback_full", "plugin_full")]
        print(f"{r['n_nodes']:>7} " + " ".join(f"{c:>22}" for c in cells) + f" {r['speedup_full_cpu']:>7.2f}")
    print()
    for path in ("callback", "plugin"):
        q = k[path]
        print(f"1 kbp, full model, dt {q['dt_ps'] * 1000:.1f} fs, with reporters, {path:>8}: "
              f"{q['ns_per_day_cpu']:.0f} ns/day per CPU ({q['ns_per_day_wall']:.0f} ns/day wall); "
              f"bare integrator {q['ns_per_day_bare_cpu']:.0f} ns/day per CPU; "
              f"mean T {q['mean_temperature']:.1f} K")
    print(f"1 kbp speed-up (CPU time): {k['speedup_cpu']:.2f}x")
    if thr:
        print()
        print("plugin, full model, Langevin 300 K: node-steps per wall second (per CPU-second), CPU platform")
        print(f"{'nodes':>7} {'1 thread':>22} {'2 threads (forced)':>22} {'2 threads (default)':>22} "
              f"{'forced x':>9} {'default x':>9}")
        for r in thr:
            cells = [f"{r[f'threads_{k}_per_wall_s']:.3g} ({r[f'threads_{k}_per_cpu_s']:.3g})"
                     for k in ("1", "2_forced", "2_default")]
            print(f"{r['n_nodes']:>7} " + " ".join(f"{c:>22}" for c in cells)
                  + f" {r['wall_speedup_2_forced']:>9.2f} {r['wall_speedup_2_default']:>9.2f}"
                  + f"  (default used {r['threads_2_default_used']} thread(s))")
    if inst is not None:
        for mode, q in inst.items():
            print(f"fresh venv + pip install -e . ({mode.replace('_', ' ')}): {q['wall_s']:.0f} s wall, "
                  f"{q['cpu_s']:.0f} s CPU, ok={q['ok']}, plugin built={q['plugin_built']}")
    H.write_results(args.json, "bench_plugin", plugin=dict(built_against=st.built_against),
                    load_average_start=load_start, sizes=res, kbp=k, threads=thr, install=inst,
                    targets=dict(plugin_full_per_cpu_s_1e4=">= 1e7", kbp_ns_per_day=">= 30000", install_s="<= 120"))


if __name__ == "__main__":
    main()
