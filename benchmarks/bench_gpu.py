"""Benchmark: the automatic elastic path on a GPU platform (CUDA, HIP or OpenCL), one documented command.

    python benchmarks/bench_gpu.py                     # CUDA if present, else HIP, else OpenCL
    python benchmarks/bench_gpu.py --platform OpenCL --sizes 1000,10000,100000,1000000

For each size (dna-default DNA, LangevinMiddle 300 K, the default time step, each size in its
own process): OpenMM Context creation time (CPU and wall seconds; the first Context in a process
compiles the kernels), then node-steps per wall-second and ns/day for

* ``bonded`` -- the elastic force alone: the compiled plugin's device kernel where it was built for the
  platform, else the portable CustomCompoundBondForce (``elastic`` in the JSON says which);
* ``full``   -- plus excluded volume and Debye-Hueckel (a ``PythonForce`` callback: positions
  are copied off the device every step, so this shows what the callback costs on a GPU);

and the same for a 1 kbp duplex (the README's reference size). Steps are timed between two
``getState`` calls (GPU platforms queue kernels asynchronously). On a CPU-only machine the
OpenCL platform is pocl, which runs the same kernels on the CPU: the figures then show that the
benchmark runs, not GPU speed. JSON to ``benchmarks/results/bench_gpu.json``.

    python benchmarks/bench_gpu.py --compare --platform OpenCL --sizes 1000,10000

compares three device paths, bonded model only (no non-local terms, which are host code on every path):
``plugin`` (the compiled plugin's SMK kernel and its rigid-body integrator's step kernel, no constraints),
``plugin-settle`` (the SMK kernel inside OpenMM's LangevinMiddleIntegrator + SETTLE) and ``portable`` (the
CustomCompoundBondForce in LangevinMiddle + SETTLE), each size and path in its own process. Context creation is timed
cold (a fresh, empty pocl kernel cache: ``POCL_CACHE_DIR`` set to a new directory; OpenMM's OpenCL platform keeps no
cache of its own) and warm (a second Context in the same process, kernels cached; both include building the System and
the first evaluation), then on the warm one the elastic force alone (energy evaluations of its force group) and steps/s.
JSON to ``benchmarks/results/bench_gpu_compare.json``.
"""
from __future__ import annotations

import argparse
import json
import os
import platform as pyplatform
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

import _harness as H
from _harness import ROOT


def _default_platform():
    from dnarod.engines.openmm.platforms import platform_names

    names = platform_names()
    for p in ("CUDA", "HIP", "OpenCL"):
        if p in names:
            return p
    raise SystemExit("no GPU platform (CUDA, HIP, OpenCL) in this OpenMM; install 'dnarod[cuda12]' or pocl")


def _rate(sim, budget):
    """(steps, wall seconds, CPU seconds) of about ``budget`` seconds, synchronised by getState."""
    ctx = sim.context
    sim.integrator.step(5)
    ctx.getState(getPositions=True)
    n = 10
    while True:
        t = time.perf_counter()
        sim.integrator.step(n)
        ctx.getState(getPositions=True)
        dt = time.perf_counter() - t
        if dt > 0.2 * budget or n >= 10**7:
            break
        n *= 4
    steps = max(n, int(n * budget / max(dt, 1e-9)))
    c0, w0 = time.process_time(), time.perf_counter()
    sim.integrator.step(steps)
    ctx.getState(getPositions=True)
    return steps, time.perf_counter() - w0, time.process_time() - c0


def single(n, plat, budget, precision):
    from dnarod.core.forcefield import load_forcefield
    from dnarod.engines.openmm.simulation import RodSimulation

    rng = np.random.default_rng(0)
    model = load_forcefield("dna-default").model_from_sequence("".join(rng.choice(list("ACGT"), n)))
    out = dict(n_nodes=n, platform=plat, precision=precision)
    for name, nb in (("bonded", False), ("full", True)):
        c0, w0 = time.process_time(), time.perf_counter()
        sim = RodSimulation.create(model, temperature=300.0, nonbonded=nb, seed=1, platform=plat, precision=precision)
        out[f"{name}_setup_wall_s"] = time.perf_counter() - w0
        out[f"{name}_setup_cpu_s"] = time.process_time() - c0
        out[f"{name}_context_wall_s"] = sim.context_time
        out["dt_ps"] = sim.dt
        out["elastic"] = sim.rs.elastic
        steps, wall, cpu = _rate(sim, budget)
        out[f"{name}_steps_per_s"] = steps / wall
        out[f"{name}_node_steps_per_s"] = n * steps / wall
        out[f"{name}_node_steps_per_cpu_s"] = n * steps / max(cpu, 1e-9)
        out[f"{name}_ns_per_day"] = steps * sim.dt * 1e-3 / wall * 86400
        del sim
    return out


def _plugin_settle(model, plat, precision):
    """The plugin's SMK device kernel inside OpenMM's LangevinMiddleIntegrator + SETTLE (not the rigid-body
    integrator), shaped like a RodSimulation for _rate."""
    from types import SimpleNamespace

    import openmm

    from dnarod.physics import modes
    from dnarod.engines.openmm.particles import particle_positions
    from dnarod.engines.openmm.platforms import platform_properties
    from dnarod.physics.modes import DEFAULT_OMEGA_DT
    from dnarod.engines.openmm.system import build_system

    rs = build_system(model, plat, "plugin", nonbonded=False)
    dt = DEFAULT_OMEGA_DT / modes.omega_max(model)
    integ = openmm.LangevinMiddleIntegrator(300.0, 1.0, dt)
    integ.setRandomNumberSeed(1)
    t = time.perf_counter()
    ctx = openmm.Context(rs.system, integ, openmm.Platform.getPlatformByName(plat),
                         platform_properties(plat, None, precision))
    ctx.setPositions(particle_positions(model.positions, model.frames, rs.radius))
    ctx.setVelocitiesToTemperature(300.0, 1)
    return SimpleNamespace(context=ctx, integrator=integ, rs=rs, dt=dt, context_time=time.perf_counter() - t)


def compare_single(n, plat, budget, precision, elastic):
    """Cold and warm Context creation and steps/s of one elastic path (bonded model) at n nodes."""
    from dnarod.core.forcefield import load_forcefield
    from dnarod.engines.openmm.simulation import RodSimulation

    rng = np.random.default_rng(0)
    model = load_forcefield("dna-default").model_from_sequence("".join(rng.choice(list("ACGT"), n)))
    out = dict(n_nodes=n, platform=plat, precision=precision, elastic=elastic)
    for phase in ("cold", "warm"):
        c0, w0 = time.process_time(), time.perf_counter()
        if elastic == "plugin-settle":
            sim = _plugin_settle(model, plat, precision)
        else:
            sim = RodSimulation.create(model, temperature=300.0, nonbonded=False, seed=1, platform=plat,
                                precision=precision, elastic=elastic)
        sim.context.getState(getEnergy=True)  # the first evaluation (lazy kernel set-up included)
        out[f"{phase}_context_wall_s"] = time.perf_counter() - w0
        out[f"{phase}_context_cpu_s"] = time.process_time() - c0
        out["device"] = bool(sim.rs.device)
        out["dt_ps"] = sim.dt
        if phase == "cold":
            del sim
    # The elastic force alone: energy evaluations of its force group (only the energy sum leaves the device).
    from dnarod.engines.openmm.forces import GROUPS

    groups = {GROUPS["elastic"]}
    sim.context.getState(getEnergy=True, groups=groups)
    k, c0, w0 = 0, time.process_time(), time.perf_counter()
    while time.perf_counter() - w0 < 0.5 * budget or k < 3:
        sim.context.getState(getEnergy=True, groups=groups)
        k += 1
    wall, cpu = time.perf_counter() - w0, time.process_time() - c0
    out["force_evals_per_s"] = k / wall
    out["force_evals_per_cpu_s"] = k / max(cpu, 1e-9)
    steps, wall, cpu = _rate(sim, budget)
    out["steps_per_s"] = steps / wall
    out["node_steps_per_s"] = n * steps / wall
    out["node_steps_per_cpu_s"] = n * steps / max(cpu, 1e-9)
    out["cpu_per_wall"] = cpu / wall
    out["ns_per_day"] = steps * sim.dt * 1e-3 / wall * 86400
    return out


def compare(args, plat):
    import tempfile

    sizes = sorted({int(s) for s in args.sizes.split(",")})
    results = []
    for n in sizes:
        for elastic in ("plugin", "plugin-settle", "portable"):
            t = time.perf_counter()
            with tempfile.TemporaryDirectory(prefix="pocl-cache-") as cache:
                env = dict(os.environ, POCL_CACHE_DIR=cache)
                p = subprocess.run([sys.executable, __file__, "--compare-single", str(n), "--elastic", elastic,
                                    "--platform", plat, "--budget", str(args.budget), "--precision", args.precision],
                                   capture_output=True, text=True, timeout=7200, env=env)
            if p.returncode != 0:
                results.append(dict(n_nodes=n, elastic=elastic,
                                    error=(p.stderr.strip().splitlines() or ["failed"])[-1]))
            else:
                results.append(json.loads(p.stdout.strip().splitlines()[-1]))
            results[-1]["wall_s"] = time.perf_counter() - t
            print(f"measured {elastic} at {n} nodes in {results[-1]['wall_s']:.0f} s", file=sys.stderr)
    load = os.getloadavg()
    print(f"platform {plat} ({args.precision} precision), bonded model, 300 K, friction 1/ps, default dt; "
          f"load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")
    print(f"{'nodes':>7} {'elastic':>13} {'device':>6} {'cold ctx s':>10} {'warm ctx s':>10} {'force ev/CPU-s':>14} "
          f"{'steps/s':>9} {'node-st/s':>10} {'node-st/CPU-s':>13} {'ns/day':>9}")
    for r in results:
        if "error" in r:
            print(f"{r['n_nodes']:>7} {r['elastic']:>13} error: {r['error']}")
            continue
        print(f"{r['n_nodes']:>7} {r['elastic']:>13} {str(r['device']):>6} {r['cold_context_wall_s']:>10.2f} "
              f"{r['warm_context_wall_s']:>10.2f} {r['force_evals_per_cpu_s']:>14.4g} "
              f"{r['steps_per_s']:>9.4g} {r['node_steps_per_s']:>10.4g} "
              f"{r['node_steps_per_cpu_s']:>13.4g} {r['ns_per_day']:>9.4g}")
    for n in sizes:
        b = next((r for r in results if r["n_nodes"] == n and r["elastic"] == "portable" and "error" not in r), None)
        for name in ("plugin", "plugin-settle"):
            a = next((r for r in results if r["n_nodes"] == n and r["elastic"] == name and "error" not in r), None)
            if not (a and b):
                continue
            print(f"{n} nodes: {name}/portable steps/s {a['steps_per_s'] / b['steps_per_s']:.3g}x, per CPU-second "
                  f"{a['node_steps_per_cpu_s'] / b['node_steps_per_cpu_s']:.3g}x; elastic force alone per "
                  f"CPU-second {a['force_evals_per_cpu_s'] / b['force_evals_per_cpu_s']:.3g}x; cold context "
                  f"{a['cold_context_wall_s']:.1f} s vs {b['cold_context_wall_s']:.1f} s, warm "
                  f"{a['warm_context_wall_s']:.2f} s vs {b['warm_context_wall_s']:.2f} s")
    device = ""
    if plat == "OpenCL":
        from dnarod.engines.openmm.platforms import opencl_gpu_devices

        device = "GPU: " + ", ".join(opencl_gpu_devices()) if opencl_gpu_devices() else "no OpenCL GPU (pocl on CPU)"
        print(device)
    out = dict(benchmark="bench_gpu --compare", platform=plat, device=device, precision=args.precision,
               machine=pyplatform.platform(), cpu_count=os.cpu_count(), load_average=load,
               date=time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), sizes=results)
    path = Path(args.json or ROOT / "benchmarks" / "results" / "bench_gpu_compare.json")
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(out, indent=2))
    print(f"wrote {path}")


def main():
    ap = H.add_common_arguments(argparse.ArgumentParser(description=__doc__.splitlines()[0]), "1000,10000",
                                "bench_gpu", pin=False, budget=3.0)
    ap.add_argument("--platform", default=None, help="CUDA, HIP or OpenCL [default: the first present]")
    ap.add_argument("--precision", default="mixed", choices=["single", "mixed", "double"])
    ap.add_argument("--compare", action="store_true", help="plugin device kernel vs portable force, bonded model "
                                                           "(JSON: benchmarks/results/bench_gpu_compare.json)")
    ap.add_argument("--compare-single", type=int, default=None, help=argparse.SUPPRESS)
    ap.add_argument("--elastic", default="plugin", help=argparse.SUPPRESS)
    args = ap.parse_args()
    plat = args.platform or _default_platform()
    if args.compare_single is not None:
        print(json.dumps(compare_single(args.compare_single, plat, args.budget, args.precision, args.elastic)))
        return
    if args.compare:
        if args.json == str(H.RESULTS / "bench_gpu.json"):
            args.json = str(H.RESULTS / "bench_gpu_compare.json")
        compare(args, plat)
        return
    args.json = args.json or str(ROOT / "benchmarks" / "results" / "bench_gpu.json")
    if args.single is not None:
        print(json.dumps(single(args.single, plat, args.budget, args.precision)))
        return
    sizes = sorted(set(H.parse_sizes(args.sizes)) | {1000})
    load = [os.getloadavg()]
    results = H.run_sizes(__file__, sizes, lambda n: ["--platform", plat, "--budget", args.budget,
                                                      "--precision", args.precision], timeout=7200)
    load.append(os.getloadavg())
    device = ""
    print(f"platform {plat} ({args.precision} precision), elastic path {results[0].get('elastic', '?')}, "
          f"LangevinMiddle 300 K, default dt")
    print(f"{'nodes':>8} {'context s':>9} {'bonded n-st/s':>13} {'full n-st/s':>11} {'bonded ns/day':>13} "
          f"{'full ns/day':>11}")
    for r in results:
        if "error" in r:
            print(f"{r['n_nodes']:>8} error: {r['error']}")
            continue
        print(f"{r['n_nodes']:>8} {r['bonded_context_wall_s']:>9.2f} {r['bonded_node_steps_per_s']:>13.4g} "
              f"{r['full_node_steps_per_s']:>11.4g} {r['bonded_ns_per_day']:>13.4g} {r['full_ns_per_day']:>11.4g}")
    kbp = next((r for r in results if r["n_nodes"] == 1000 and "error" not in r), None)
    if kbp:
        print(f"1 kbp: {kbp['full_ns_per_day']:.4g} ns/day full model, {kbp['bonded_ns_per_day']:.4g} bonded "
              f"(dt {kbp['dt_ps'] * 1000:.1f} fs)")
    if plat == "OpenCL":
        from dnarod.engines.openmm.platforms import opencl_gpu_devices

        device = "GPU: " + ", ".join(opencl_gpu_devices()) if opencl_gpu_devices() else "no OpenCL GPU (pocl on CPU?)"
        print(device)
    H.write_results(args.json, "bench_gpu", platform=plat, device=device, precision=args.precision,
                    load_average_start_end=load, sizes=results)


if __name__ == "__main__":
    main()
