"""Throughput of the Lax-engine splitting integrator: node-steps per CPU-second, 10^2 to 10^5 nodes.

Compares, in one run, the numpy reference path (dnarod.core.energy.loads + vectorised updates), the
scalar numba kernel and the SIMD-blocked numba kernel (the default), NVE, dt = 0.05 ps, dna-default
rod at 300 K. If PyElastica is importable (``--elastica-python`` may point to another interpreter
that has it), its PositionVerlet on a Cosserat rod with the same number of elements is measured
in the same run for the ratio. Prints a table and writes JSON to benchmarks/results/.

    python benchmarks/bench_lax_splitting.py [--sizes 100 1000 10000 100000] [--seconds 1.5]
"""
from __future__ import annotations

import argparse
import json
import platform
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from dnarod.core.forcefield import load_forcefield
from dnarod.engines.lax.splitting import SplittingIntegrator, maxwell_state

ELASTICA_SNIPPET = r"""
import sys, time, numpy as np
import elastica as ea
n = int(sys.argv[1]); seconds = float(sys.argv[2])
class Sim(ea.BaseSystemCollection, ea.Constraints, ea.Forcing, ea.Damping, ea.CallBacks): pass
sim = Sim()
rod = ea.CosseratRod.straight_rod(n, np.zeros(3), np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]),
                                  n * 0.34, 1.0, 1000.0, youngs_modulus=1e6, shear_modulus=1e6 / 3.0)
sim.append(rod)
sim.finalize()
stepper = ea.PositionVerlet()
dt = 1e-6; t = 0.0
for _ in range(5): t = stepper.step(sim, t, dt)
steps = 0; t0 = time.process_time()
while time.process_time() - t0 < seconds:
    for _ in range(20): t = stepper.step(sim, t, dt)
    steps += 20
print(n * steps / (time.process_time() - t0))
"""


def measure(model, state, fast, seconds):
    integ = SplittingIntegrator(model, 0.05, state, fast=fast, check_stability=False)
    integ.step(2)  # warm-up (and numba compile / cache load)
    steps, chunk = 0, 1
    t0 = time.process_time()
    while True:
        integ.step(chunk)
        steps += chunk
        el = time.process_time() - t0
        if el > seconds:
            break
        chunk = min(chunk * 2, 10000)
    return model.n_nodes * steps / el, steps


def elastica_rate(python, n, seconds):
    try:
        out = subprocess.run([python, "-c", ELASTICA_SNIPPET, str(n), str(seconds)], capture_output=True, text=True,
                             timeout=600)
        return float(out.stdout.strip().splitlines()[-1]) if out.returncode == 0 else None
    except (OSError, ValueError, IndexError, subprocess.TimeoutExpired):
        return None


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[100, 1000, 10000, 100000])
    ap.add_argument("--seconds", type=float, default=1.5, help="CPU seconds per measurement")
    ap.add_argument("--elastica-python", default=sys.executable, help="interpreter with PyElastica installed")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "bench_lax_splitting.json"))
    args = ap.parse_args()
    ff = load_forcefield("dna-default")
    rows = []
    hdr = (f"{'nodes':>8} {'numpy ref':>12} {'numba scalar':>13} {'numba blocked':>14} {'PyElastica':>11} "
           f"{'blocked/ref':>11} {'blocked/Elastica':>16}")
    print("node-steps per CPU-second (NVE, dt = 0.05 ps, dna-default, 300 K)")
    print(hdr)
    for n in args.sizes:
        model = ff.model_from_sequence(n_nodes=n)
        state = maxwell_state(model, 300.0, seed=1)
        ref, _ = measure(model, state, False, args.seconds)
        sca, _ = measure(model, state, "scalar", args.seconds)
        blk, _ = measure(model, state, "blocked", args.seconds)
        ela = elastica_rate(args.elastica_python, n, args.seconds)
        rows.append(dict(nodes=n, numpy_reference=ref, numba_scalar=sca, numba_blocked=blk,
                         pyelastica_position_verlet=ela))
        def fmt(x):
            return f"{x:.3g}" if x else "n/a"
        print(f"{n:>8} {ref:>12.3g} {sca:>13.3g} {blk:>14.3g} {fmt(ela):>11} {blk / ref:>11.1f} "
              f"{(blk / ela if ela else float('nan')):>16.2f}")
    meta = dict(benchmark="lax splitting throughput", unit="node-steps per CPU-second (time.process_time)",
                dt_ps=0.05, forcefield="dna-default", python=platform.python_version(),
                machine=platform.machine(), processor=platform.processor(), numpy=np.__version__,
                pyelastica_note="PyElastica measured in the same run when its interpreter is available; target "
                                "(issue 4): blocked >= 2x PyElastica PositionVerlet (~5e6 element-steps/CPU-s here)")
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(dict(meta=meta, results=rows), indent=2))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
