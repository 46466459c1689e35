"""Benchmark: the portable path on a GPU platform (CUDA, HIP or OpenCL), one documented command.

    python benchmarks/bench_gpu.py                     # CUDA if present, else HIP, else OpenCL
    python benchmarks/bench_gpu.py --platform OpenCL --sizes 1000,10000,100000,1000000

For each size (dna-default DNA, LangevinMiddle 300 K, the default time step, each size in its
own process): OpenMM Context creation time (CPU and wall seconds; the first Context in a process
compiles the kernels), then node-steps per wall-second and ns/day for

* ``bonded`` -- the portable elastic force (CustomCompoundBondForce) alone;
* ``full``   -- plus excluded volume and Debye-Hueckel (a ``PythonForce`` callback: positions
  are copied off the device every step, so this shows what the callback costs on a GPU);

and the same for a 1 kbp duplex (the README's reference size). Steps are timed between two
``getState`` calls (GPU platforms queue kernels asynchronously). On a CPU-only machine the
OpenCL platform is pocl, which runs the same kernels on the CPU: the figures then show that the
benchmark runs, not GPU speed. JSON to ``benchmarks/results/bench_gpu.json``.
"""
from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np

import _harness as H


def _default_platform():
    from dnarod.openmm.platforms import platform_names

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
    from dnarod.forcefield import load_forcefield
    from dnarod.openmm.simulation import RodSimulation

    rng = np.random.default_rng(0)
    model = load_forcefield("dna-default").model_from_sequence("".join(rng.choice(list("ACGT"), n)))
    out = dict(n_nodes=n, platform=plat, precision=precision)
    for name, nb in (("bonded", False), ("full", True)):
        c0, w0 = time.process_time(), time.perf_counter()
        sim = RodSimulation(model, temperature=300.0, nonbonded=nb, seed=1, platform=plat, precision=precision)
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


def main():
    ap = H.add_common_arguments(argparse.ArgumentParser(description=__doc__.splitlines()[0]), "1000,10000",
                                "bench_gpu", pin=False, budget=3.0)
    ap.add_argument("--platform", default=None, help="CUDA, HIP or OpenCL [default: the first present]")
    ap.add_argument("--precision", default="mixed", choices=["single", "mixed", "double"])
    args = ap.parse_args()
    plat = args.platform or _default_platform()
    if args.single is not None:
        print(json.dumps(single(args.single, plat, args.budget, args.precision)))
        return
    sizes = sorted(set(H.parse_sizes(args.sizes)) | {1000})
    load = [os.getloadavg()]
    results = H.run_sizes(__file__, sizes, lambda n: ["--platform", plat, "--budget", args.budget,
                                                      "--precision", args.precision], timeout=7200)
    load.append(os.getloadavg())
    device = ""
    print(f"platform {plat} ({args.precision} precision), portable path, LangevinMiddle 300 K, default dt")
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
        from dnarod.openmm.platforms import opencl_gpu_devices

        device = "GPU: " + ", ".join(opencl_gpu_devices()) if opencl_gpu_devices() else "no OpenCL GPU (pocl on CPU?)"
        print(device)
    H.write_results(args.json, "bench_gpu", platform=plat, device=device, precision=args.precision,
                    load_average_start_end=load, sizes=results)


if __name__ == "__main__":
    main()
