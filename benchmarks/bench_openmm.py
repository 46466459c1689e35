"""Benchmark: the OpenMM engine with the default (automatic) CPU platform choice.

For 10^2 .. 10^6 nodes of dna-default DNA (LangevinMiddle, 300 K, the default time step),
each size in its own process (clean peak memory; pinned to one core with ``--pin``), on the
platform :func:`dnarod.engines.openmm.platforms.choose_platform` picks (Reference on a machine
without a GPU):

* ``floor``    -- the same particles and constraints with no forces (bare integration);
* ``bonded``   -- the fast elastic path (numba analytic loads through PythonForce);
* ``full``     -- bonded + excluded volume + Debye-Hueckel (the default model);
* ``portable`` -- the CustomCompoundBondForce path on CPU (10^3 and 10^4 nodes only: its
  expression compiles for several seconds);

node-steps per CPU-second of the process (best of interleaved repeats, so machine load hits
all alike; wall-clock figures in the JSON), the ratios to the floor, the time to build a
simulation (fastest-mode estimate, system, OpenMM Context) and the peak resident memory. Then a
1 kbp duplex at 300 K with the default time step, bare and through the run loop (``dnarod.run.simulate_engine``:
trajectory every 1 ps, energies, checkpoints): steps per CPU-second and ns/day, for the default
(``elastic="auto"``), the Python-callback path and the compiled plugin, each in its own process of the same run. No
oxDNA figure is computed here (oxDNA is not run by this script; the README quotes a side-by-side measurement with its
date).

Targets: bonded >= 40% of the floor at 10^4 nodes; full <= 2x bonded cost at 10^4; 1 kbp full
model >= 2000 steps per CPU-second on one core; Context creation < 2 s; 10^6 nodes fit in memory.

Usage: ``python benchmarks/bench_openmm.py [--sizes 100,1000,...] [--budget SECONDS] [--pin CPU] [--json OUT]``.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import tempfile
import time

import numpy as np

import _harness as H

#: The 1 kbp figure is measured for the default (``auto``) and for each path it may pick, in one run.
KBP_PATHS = ("auto", "fast", "plugin")


def _rate(integrator, n_nodes, budget):
    """(node-steps per CPU-second, per wall-second), running about ``budget`` seconds."""
    steps, cpu, wall = H.timed_steps(integrator, budget)
    return n_nodes * steps / max(cpu, 1e-9), n_nodes * steps / wall


def single(n, budget, repeats):
    """Measure one size; returns a dict (run in a fresh process)."""
    import openmm

    from dnarod.core.forcefield import load_forcefield
    from dnarod.engines.openmm.particles import particle_positions
    from dnarod.engines.openmm.platforms import choose_platform
    from dnarod.engines.openmm.simulation import RodSimulation
    from dnarod.physics.modes import omega_max

    ff = load_forcefield("dna-default")
    rng = np.random.default_rng(0)
    model = ff.model_from_sequence("".join(rng.choice(list("ACGT"), n)))
    out = dict(n_nodes=n)
    t = time.perf_counter()
    w = omega_max(model)
    out["omega_max_s"] = time.perf_counter() - t
    out["omega_max"] = w
    sims = {}
    for name, nb in (("bonded", False), ("full", True)):
        t = time.perf_counter()
        sims[name] = RodSimulation.create(model, temperature=300.0, nonbonded=nb, seed=1)
        out[f"{name}_setup_s"] = time.perf_counter() - t
        out[f"{name}_context_s"] = sims[name].context_time
    dt = sims["bonded"].dt
    out["dt_ps"] = dt
    out["platform"] = sims["bonded"].platform_name
    # floor: particles + constraints, no forces
    t = time.perf_counter()
    system = openmm.System()
    for _ in range(3 * n):
        system.addParticle(model.mass[0] / 3)
    side = 0.6 * np.sqrt(3)
    for k in range(n):
        for i, j in ((0, 1), (1, 2), (0, 2)):
            system.addConstraint(3 * k + i, 3 * k + j, side)
    integ = openmm.LangevinMiddleIntegrator(300.0, 1.0, dt)
    integ.setConstraintTolerance(1e-8)
    plat, props, _ = choose_platform(None, n)
    ctx = openmm.Context(system, integ, plat, props)
    ctx.setPositions(particle_positions(model.positions, model.frames, 0.6))
    ctx.setVelocitiesToTemperature(300.0, 1)
    out["floor_setup_s"] = time.perf_counter() - t
    runs = {"floor": integ, "bonded": sims["bonded"].integrator, "full": sims["full"].integrator}
    if n in (1000, 10000):
        t = time.perf_counter()
        sims["portable"] = RodSimulation.create(model, temperature=300.0, nonbonded=False, seed=1, elastic="portable",
                                         dt=dt, platform="CPU")
        out["portable_setup_s"] = time.perf_counter() - t
        out["portable_context_s"] = sims["portable"].context_time
        runs["portable"] = sims["portable"].integrator
    rates = {k: [] for k in runs}
    for _ in range(repeats):
        for k, it in runs.items():
            rates[k].append(_rate(it, n, budget))
    for k, r in rates.items():
        out[f"{k}_node_steps_per_s"], out[f"{k}_node_steps_per_wall_s"] = max(r)
    out["peak_rss_MB"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    return out


def kbp(budget, elastic="auto"):
    """1 kbp duplex, 300 K, default dt, full model, through the run loop with reporters (``elastic`` path)."""
    from dnarod.core.forcefield import load_forcefield
    from dnarod.engines.openmm.simulation import RodSimulation

    rng = np.random.default_rng(1)
    model = load_forcefield("dna-default").model_from_sequence("".join(rng.choice(list("ACGT"), 1000)))
    t = time.perf_counter()
    sim = RodSimulation.create(model, temperature=300.0, seed=2, elastic=elastic)
    setup = time.perf_counter() - t
    fi = max(1, int(round(1.0 / sim.dt)))
    sim.integrator.step(10)
    c, t = time.process_time(), time.perf_counter()
    sim.integrator.step(200)
    per_step = (time.perf_counter() - t) / 200
    n_steps = max(fi, int(budget / per_step) // fi * fi)
    # bare stepping, CPU time (the figure of merit: steps per CPU-second on one core)
    c, t = time.process_time(), time.perf_counter()
    sim.integrator.step(n_steps)
    bare_cpu, bare_wall = time.process_time() - c, time.perf_counter() - t
    with tempfile.TemporaryDirectory() as d:
        from dnarod.run import simulate_engine

        c = time.process_time()
        s = simulate_engine(sim, sim.step + 2 * n_steps, d, frame_interval=fi, checkpoint_interval=100 * fi,
                            progress=False)
        run_cpu = time.process_time() - c
    done = s["steps_this_run"]
    ns_day = done * sim.dt * 1e-3 / s["wall_s"] * 86400
    return dict(n_nodes=1000, requested=elastic, elastic=sim.rs.elastic, dt_ps=sim.dt, platform=sim.platform_name,
                setup_s=setup, context_s=sim.context_time, node_steps_per_cpu_s_bare=1000 * n_steps / bare_cpu,
                steps=done, steps_per_cpu_s_bare=n_steps / bare_cpu, steps_per_wall_s_bare=n_steps / bare_wall,
                ns_per_day_bare=n_steps * sim.dt * 1e-3 / bare_wall * 86400,
                ns_per_day_bare_cpu=n_steps * sim.dt * 1e-3 / bare_cpu * 86400,
                steps_per_cpu_s_with_reporters=done / run_cpu,
                ns_per_day_with_reporters=ns_day,
                ns_per_day_with_reporters_cpu=done * sim.dt * 1e-3 / run_cpu * 86400,
                node_steps_per_cpu_s_with_reporters=1000 * done / run_cpu,
                mean_temperature=float(np.mean(s["temperatures"])))


def main():
    ap = H.add_common_arguments(argparse.ArgumentParser(), "100,1000,10000,100000,1000000", "bench_openmm")
    ap.add_argument("--kbp", default=None, choices=KBP_PATHS, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.single is not None:
        print(json.dumps(single(args.single, args.budget, args.repeats)))
        return
    if args.kbp:
        print(json.dumps(kbp(10 * args.budget, args.kbp)))
        return
    prefix = H.pin_prefix(args.pin)
    load = [os.getloadavg()]
    results = H.run_sizes(__file__, H.parse_sizes(args.sizes),
                          lambda n: ["--budget", args.budget if n <= 100000 else max(args.budget, 3.0),
                                     "--repeats", args.repeats if n <= 100000 else 1], prefix, timeout=1800)
    kbps = {path: H.run_child(__file__, ["--kbp", path, "--budget", args.budget], prefix, timeout=1800, error_lines=3)
            for path in KBP_PATHS}
    load.append(os.getloadavg())

    hdr = (f"{'nodes':>8} {'floor':>10} {'bonded':>10} {'full':>10} {'portable':>10} {'bond/floor':>10} "
           f"{'full/bond':>9} {'setup s':>8} {'context s':>9} {'omega s':>8} {'peak MB':>8} platform")
    pin = f"pinned to core {args.pin}" if prefix else "not pinned"
    print(f"node-steps per CPU-second, automatic platform, LangevinMiddle 300 K, default dt, {pin}")
    print(hdr)
    for r in results:
        if "error" in r:
            print(f"{r['n_nodes']:>8} error: {r['error']}")
            continue
        port = r.get("portable_node_steps_per_s")
        r["bonded_over_floor"] = r["bonded_node_steps_per_s"] / r["floor_node_steps_per_s"]
        r["full_cost_over_bonded"] = r["bonded_node_steps_per_s"] / r["full_node_steps_per_s"]
        print(f"{r['n_nodes']:>8} {r['floor_node_steps_per_s']:>10.3g} {r['bonded_node_steps_per_s']:>10.3g} "
              f"{r['full_node_steps_per_s']:>10.3g} {'-' if port is None else format(port, '.3g'):>10} "
              f"{r['bonded_over_floor']:>10.2f} {r['full_cost_over_bonded']:>9.2f} {r['full_setup_s']:>8.2f} "
              f"{r['full_context_s']:>9.3f} {r['omega_max_s']:>8.2f} {r['peak_rss_MB']:>8.0f} {r['platform']}")
    print()
    for path, k in kbps.items():
        if "error" in k:
            print(f"1 kbp ({path}): error", k["error"])
            continue
        print(f"1 kbp duplex, 300 K, dt {k['dt_ps'] * 1000:.1f} fs, full model, elastic={path} -> {k['elastic']} path, "
              f"{k['platform']} platform: {k['steps_per_cpu_s_bare']:.0f} steps per CPU-second bare "
              f"({k['node_steps_per_cpu_s_bare']:.3g} node-steps/CPU-s) = {k['ns_per_day_bare_cpu']:.0f} ns per "
              f"CPU-day ({k['ns_per_day_bare']:.0f} ns/day wall); with reporters "
              f"{k['steps_per_cpu_s_with_reporters']:.0f} steps per CPU-second = "
              f"{k['node_steps_per_cpu_s_with_reporters']:.3g} node-steps per CPU-second, "
              f"{k['ns_per_day_with_reporters_cpu']:.0f} ns per CPU-day ({k['ns_per_day_with_reporters']:.0f} wall); "
              f"setup {k['setup_s']:.2f} s (Context {k['context_s']:.3f} s); mean T {k['mean_temperature']:.1f} K")
    H.write_results(args.json, "bench_openmm", pinned=bool(prefix), load_average_start_end=load, sizes=results,
                    kbp=kbps, targets=dict(bonded_over_floor_1e4=">= 0.40", full_cost_over_bonded_1e4="<= 2",
                                           kbp_steps_per_cpu_s=">= 2000 (default path)", context_s="< 2",
                                           nodes_1e6="fit in memory"))


if __name__ == "__main__":
    main()
