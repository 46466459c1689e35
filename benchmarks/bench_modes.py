"""Timings of dnarod.physics.modes (Hessian, omega_max), the Lax engine's start-up and the static solver.

Prints a table and writes benchmarks/results/bench_modes.json. Wall and CPU (process) time are given
side by side (the machine may be shared); each figure is the best of ``repeat`` runs.

Usage: python benchmarks/bench_modes.py [--quick]
"""
from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np

from dnarod.physics import modes
from dnarod.core.forcefield import load_forcefield


def timed(fn, repeat=3):
    best = (np.inf, np.inf, None)
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        out = fn()
        t, c = time.perf_counter() - t0, time.process_time() - c0
        if t < best[0]:
            best = (t, c, out)
    return best


def main(quick=False):
    ff = load_forcefield("dna-default")
    rng = np.random.default_rng(0)
    rows = []
    # warm the numba caches
    modes.omega_max(ff.model_from_sequence(n_nodes=12))
    modes.omega_max(ff.model_from_sequence(n_nodes=12, circular=True))
    sizes = (1000, 10000) if quick else (1000, 10000, 100000)
    for n in sizes:
        for circular in (False, True):
            seq = "".join(rng.choice(list("ACGT"), n))
            m = ff.model_from_sequence(seq, circular=circular)
            th, ch, _ = timed(lambda: modes.hessian_blocks(m))
            tw, cw, w = timed(lambda: modes.omega_max(m))
            rows.append(dict(what="omega_max", nodes=n, chain="ring" if circular else "open", sequence="random",
                             hessian_wall_s=th, hessian_cpu_s=ch, omega_max_wall_s=tw, omega_max_cpu_s=cw,
                             omega_max_rad_per_ps=w))
    # Lax engine start-up (SplittingIntegrator with its stability check = one omega_max) at 20,000 nodes
    from dnarod.engines.lax import SplittingIntegrator

    m = ff.model_from_sequence("".join(rng.choice(list("ACGT"), 20000)))
    dt, w = modes.default_time_step(m)
    ti, ci, integ = timed(lambda: SplittingIntegrator(m, dt, temperature=300.0, friction=1.0, seed=1), repeat=2)
    ts, cs, _ = timed(lambda: integ.step(1), repeat=1)
    rows.append(dict(what="lax start (SplittingIntegrator init + first step)", nodes=20000, chain="open",
                     sequence="random", init_wall_s=ti, init_cpu_s=ci, first_step_wall_s=ts, first_step_cpu_s=cs))
    # static solver: cantilever
    from dnarod.physics.loads import Clamp, PullingForce
    from dnarod.physics.statics import solve_static

    for n in ((100,) if quick else (100, 1000)):
        m = ff.model_from_sequence(n_nodes=n)
        a = m.positions[-1] - m.positions[0]
        a /= np.linalg.norm(a)
        side = np.cross(a, [1.0, 0, 0])
        side /= np.linalg.norm(side)
        loads = (Clamp(0), PullingForce(-1, 2.0 * side + 5.0 * a))
        t, c, (ms, info) = timed(lambda: solve_static(m, loads), repeat=1)
        rows.append(dict(what="solve_static cantilever", nodes=n, chain="open", sequence="uniform",
                         wall_s=t, cpu_s=c, iterations=info["iterations"], relative_gradient=info["relative_gradient"]))
    print(f"{'what':48s} {'nodes':>7s} {'chain':>5s}  timings")
    for r in rows:
        rest = {k: (f"{v:.3g}" if isinstance(v, float) else v) for k, v in r.items()
                if k not in ("what", "nodes", "chain", "sequence")}
        print(f"{r['what']:48s} {r['nodes']:7d} {r['chain']:>5s}  {rest}")
    out = Path(__file__).parent / "results" / "bench_modes.json"
    out.parent.mkdir(exist_ok=True)
    tmp = out.with_suffix(".tmp")
    tmp.write_text(json.dumps(dict(rows=rows, quick=quick, time=time.strftime("%Y-%m-%d %H:%M:%S")), indent=1))
    tmp.replace(out)
    print(f"wrote {out}")


if __name__ == "__main__":
    main(quick="--quick" in sys.argv)
